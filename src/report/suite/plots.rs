//! The plots of one suite sequence: ego trajectories and error over time,
//! moving objects' estimated and true trajectories and speeds; they read the
//! run outputs (`poses_tum.txt`, `tracks.csv`) and the dataset's ground truth.

use super::*;

/// One row of `tracks.csv` (world frame of the estimate).
#[derive(Debug, Clone, PartialEq)]
pub struct TrackCsvRow {
    pub frame: u64,
    pub t_s: f64,
    pub id: u64,
    pub center_world: Vector3<f64>,
    pub velocity_world_mps: Vector3<f64>,
}

/// Reads the columns of `tracks.csv` the plots need, by header name.
///
/// # Errors
///
/// [`SuiteError`] when the file cannot be read or lacks a needed column.
pub fn read_tracks_csv(path: &Path) -> Result<Vec<TrackCsvRow>> {
    let text = std::fs::read_to_string(path).map_err(|source| SuiteError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut lines = text.lines().enumerate();
    let header: Vec<&str> = match lines.next() {
        Some((_, h)) => h.split(',').map(str::trim).collect(),
        None => return Ok(Vec::new()),
    };
    let wanted = ["frame", "t_s", "id", "x", "y", "z", "vx", "vy", "vz"];
    let mut columns = [0usize; 9];
    for (slot, name) in columns.iter_mut().zip(wanted) {
        *slot = header
            .iter()
            .position(|h| *h == name)
            .ok_or_else(|| SuiteError::Parse {
                path: path.to_path_buf(),
                line: 1,
                field: name.to_string(),
                why: "column missing from the header".into(),
            })?;
    }
    let mut rows = Vec::new();
    for (index, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').collect();
        let parse_err = |k: usize, why: String| SuiteError::Parse {
            path: path.to_path_buf(),
            line: index + 1,
            field: wanted[k].to_string(),
            why,
        };
        let mut values = [0.0f64; 9];
        for (k, (&col, value)) in columns.iter().zip(values.iter_mut()).enumerate() {
            let raw = fields
                .get(col)
                .ok_or_else(|| parse_err(k, "missing".into()))?;
            *value = raw
                .trim()
                .parse::<f64>()
                .map_err(|e| parse_err(k, format!("`{raw}`: {e}")))?;
            if !value.is_finite() {
                return Err(parse_err(k, format!("`{raw}` is not finite")));
            }
        }
        for k in [0, 2] {
            if values[k] < 0.0 || values[k].fract() != 0.0 {
                return Err(parse_err(k, format!("`{}` is not an index", values[k])));
            }
        }
        rows.push(TrackCsvRow {
            frame: values[0] as u64,
            t_s: values[1],
            id: values[2] as u64,
            center_world: Vector3::new(values[3], values[4], values[5]),
            velocity_world_mps: Vector3::new(values[6], values[7], values[8]),
        });
    }
    Ok(rows)
}

/// Evenly thins `points` to at most `max` (keeping the last one).
pub(super) fn thin<T: Clone>(points: &[T], max: usize) -> Vec<T> {
    if points.len() <= max || max < 2 {
        return points.to_vec();
    }
    let step = points.len().div_ceil(max - 1);
    let mut out: Vec<T> = points.iter().step_by(step).cloned().collect();
    if !(points.len() - 1).is_multiple_of(step)
        && let Some(last) = points.last()
    {
        out.push(last.clone());
    }
    out
}

/// Ego XY plot, error-over-time plot and each variant's ATE alignment.
pub(super) struct EgoPlots {
    pub(super) plots: Vec<Plot>,
    pub(super) alignments: BTreeMap<Variant, Alignment>,
    pub(super) notes: Vec<String>,
}

pub(super) fn ego_plots(s: &SequenceResult, suite_dir: &Path) -> EgoPlots {
    let mut out = EgoPlots {
        plots: Vec::new(),
        alignments: BTreeMap::new(),
        notes: Vec::new(),
    };
    let opts = EgoEvalOptions::default();
    let truth = match load_truth(&suite_dir.join(&s.dataset_dir), &opts) {
        Ok(t) => t,
        Err(e) => {
            out.notes.push(format!(
                "ego plots left out: {}",
                crate::experiments::error_chain(&e)
            ));
            return out;
        }
    };
    let truth_xy: Vec<(f64, f64)> = truth
        .poses
        .iter()
        .map(|(_, p)| (p.translation.vector.x, p.translation.vector.y))
        .collect();
    let mut xy = vec![Series2D::truth("truth", thin(&truth_xy, MAX_TRUTH_POINTS))];
    let mut errors = Vec::new();
    for r in s.variants.iter().filter(|r| r.metrics.is_some()) {
        let path = suite_dir.join(&r.run_dir).join("poses_tum.txt");
        let evaluated = load_estimate(&path, &truth, &opts)
            .and_then(|est| evaluate_trajectories(&truth, &est, &opts).map(|e| (est, e)));
        let (estimate, evaluation) = match evaluated {
            Ok(x) => x,
            Err(e) => {
                out.notes.push(format!(
                    "{} left out of the ego plots: {}",
                    r.variant.label(),
                    crate::experiments::error_chain(&e)
                ));
                continue;
            }
        };
        let alignment = evaluation.ate.alignment;
        let points = estimate
            .poses
            .iter()
            .map(|(_, p)| {
                let q = alignment.transform_pose(p).translation.vector;
                (q.x, q.y)
            })
            .collect();
        let rgb = variant_rgb(r.variant);
        xy.push(Series2D::line(r.variant.label(), points).with_rgb(rgb));
        let error_points = evaluation
            .ate
            .per_pose
            .iter()
            .map(|&(t, e_m, _)| (t, e_m))
            .collect();
        errors.push(Series2D::line(r.variant.label(), error_points).with_rgb(rgb));
        out.alignments.insert(r.variant, alignment);
    }
    if errors.is_empty() {
        return out;
    }
    out.plots.push(Plot {
        file_name: format!("{}_ego_xy.svg", s.name),
        title: format!(
            "{}: ego trajectory, top view (aligned estimates vs truth)",
            s.name
        ),
        kind: PlotKind::TrajectoriesXy { series: xy },
    });
    out.plots.push(Plot {
        file_name: format!("{}_ego_error.svg", s.name),
        title: format!("{}: ego translation error over time", s.name),
        kind: PlotKind::ErrorOverTime {
            y_desc: "translation error [m]".into(),
            series: errors,
        },
    });
    out
}

/// Trajectory and speed plots of the longest-tracked moving objects, from
/// the preferred variant's `tracks.csv` moved by its ego alignment.
pub(super) fn object_plots(
    s: &SequenceResult,
    suite_dir: &Path,
    alignments: &BTreeMap<Variant, Alignment>,
) -> (Vec<Plot>, Vec<String>) {
    let mut notes = Vec::new();
    let Some((variant, metrics, alignment)) = TRACK_PLOT_PREFERENCE.iter().find_map(|&v| {
        let m = s.metrics(v)?;
        Some((v, m, alignments.get(&v)?))
    }) else {
        return (Vec::new(), notes);
    };
    let moving: BTreeSet<u64> = s.moving_objects.iter().copied().collect();
    let mut candidates: Vec<_> = metrics
        .objects
        .iter()
        .filter(|o| moving.contains(&o.gt_id) && o.track_id.is_some())
        .collect();
    candidates.sort_by(|a, b| {
        b.tracked_frames
            .cmp(&a.tracked_frames)
            .then(a.gt_id.cmp(&b.gt_id))
    });
    candidates.truncate(OBJECT_PLOTS_PER_SEQUENCE);
    if candidates.is_empty() {
        return (Vec::new(), notes);
    }
    let run_dir = s
        .variant(variant)
        .map_or_else(PathBuf::new, |r| suite_dir.join(&r.run_dir));
    let loaded = read_tracks_csv(&run_dir.join("tracks.csv")).and_then(|rows| {
        let truth = Dataset::open(&suite_dir.join(&s.dataset_dir))
            .and_then(|d| d.box_truth())
            .map_err(|e| SuiteError::Data(crate::experiments::error_chain(&e)))?;
        Ok((rows, truth))
    });
    let (rows, truth) = match loaded {
        Ok(x) => x,
        Err(e) => {
            notes.push(format!(
                "object plots left out: {}",
                crate::experiments::error_chain(&e)
            ));
            return (Vec::new(), notes);
        }
    };
    let rgb = variant_rgb(variant);
    let mut plots = Vec::new();
    for o in candidates {
        let Some(track_id) = o.track_id else {
            continue;
        };
        let gt_id = o.gt_id;
        let true_boxes: Vec<_> = truth
            .iter()
            .flatten()
            .filter(|b| u64::from(b.id) == gt_id)
            .collect();
        let est_rows: Vec<&TrackCsvRow> = rows.iter().filter(|r| r.id == track_id).collect();
        if true_boxes.is_empty() || est_rows.is_empty() {
            notes.push(format!(
                "object {gt_id} (track {track_id}) left out: no truth boxes or track rows"
            ));
            continue;
        }
        let true_xy = true_boxes
            .iter()
            .map(|b| (b.t_world_box.translation.x, b.t_world_box.translation.y))
            .collect();
        let true_speed = true_boxes
            .iter()
            .map(|b| (b.t_s, b.velocity_world_mps.xy().norm()))
            .collect();
        let est_xy = est_rows
            .iter()
            .map(|r| {
                let pose = Isometry3::from_parts(
                    Translation3::from(r.center_world),
                    UnitQuaternion::identity(),
                );
                let c = alignment.transform_pose(&pose).translation.vector;
                (c.x, c.y)
            })
            .collect();
        let est_speed = est_rows
            .iter()
            .map(|r| {
                (
                    r.t_s,
                    (alignment.rotation * r.velocity_world_mps).xy().norm(),
                )
            })
            .collect();
        let label = format!("{} track {track_id}", variant.label());
        let what = format!("{} {gt_id} ({})", s.name, o.class);
        plots.push(Plot {
            file_name: format!("{}_obj{gt_id}_xy.svg", s.name),
            title: format!("{what}: estimated vs true trajectory, top view"),
            kind: PlotKind::ObjectTracks {
                truth: vec![Series2D::truth(format!("truth {gt_id}"), true_xy)],
                est: vec![Series2D::line(label.clone(), est_xy).with_rgb(rgb)],
            },
        });
        plots.push(Plot {
            file_name: format!("{}_obj{gt_id}_speed.svg", s.name),
            title: format!("{what}: estimated vs true speed"),
            kind: PlotKind::Speed {
                series: vec![
                    Series2D::truth(format!("truth {gt_id}"), true_speed),
                    Series2D::line(label, est_speed).with_rgb(rgb),
                ],
            },
        });
    }
    (plots, notes)
}
