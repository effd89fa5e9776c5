//! The report of a suite (`crate::experiments::suite`): tables shaped like the paper's
//! (ego ATE per sequence × variant, CLEAR-MOT, per-object TP/ATE, timing per
//! module) and SVG plots per sequence (ego trajectories vs truth, ego error
//! over time, moving objects' estimated vs true trajectories and speeds).
//!
//! Tables come from `results.json` alone; plots also read the run outputs
//! (`poses_tum.txt`, `tracks.csv`) and the datasets' ground truth, so a report
//! re-rendered from the same suite directory is identical. A plot whose files
//! are gone is left out with a note rather than failing the report.

use crate::metrics::Alignment;
use crate::experiments::{EgoEvalOptions, evaluate_trajectories, load_estimate, load_truth};
use crate::report::plot::Series2D;
use crate::report::table::{
    Better, BoldRule, Cell, EgoAte, EgoAteRow, ObjectMetrics, ObjectRow, Table, TimingRow,
    TrackingRow, ego_ate_table, object_table, timing_table, tracking_table,
};
use crate::report::{Plot, PlotKind, Report, Section, Variant, write_report};
use crate::experiments::{SequenceResult, SuiteError, SuiteResults, VariantMetrics};
use limot_sim::record::Dataset;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

type Result<T, E = SuiteError> = std::result::Result<T, E>;

/// Moving objects per sequence in the per-object table (longest in view first).
pub const OBJECTS_PER_SEQUENCE: usize = 5;
/// Moving objects per sequence drawn as trajectory and speed plots.
pub const OBJECT_PLOTS_PER_SEQUENCE: usize = 3;
/// The variant whose tracks are drawn, in order of preference (limot's
/// are the jointly optimized ones).
const TRACK_PLOT_PREFERENCE: [Variant; 4] = [
    Variant::Limot,
    Variant::Dynafilt,
    Variant::Allfilt,
    Variant::Lio,
];
/// Ground-truth ego poses drawn per trajectory plot at most (IMU-rate truth
/// would make large SVGs for no visible gain).
const MAX_TRUTH_POINTS: usize = 2000;

/// One colour per variant across every plot (Tableau 10).
fn variant_rgb(v: Variant) -> (u8, u8, u8) {
    match v {
        Variant::Lio => (31, 119, 180),
        Variant::Allfilt => (255, 127, 14),
        Variant::Dynafilt => (44, 160, 44),
        Variant::Limot => (214, 39, 40),
    }
}

/// Variants with figures in any sequence, in the suite's order.
fn variants_with_metrics(results: &SuiteResults) -> Vec<Variant> {
    results
        .variants
        .iter()
        .copied()
        .filter(|&v| results.sequences.iter().any(|s| s.metrics(v).is_some()))
        .collect()
}

/// Paper Table "tab_ego_track": Seq | per variant ATE_T [m], ATE_R [rad];
/// best per row in bold; a mean row.
pub fn ego_table(results: &SuiteResults) -> Result<Table> {
    let rows: Vec<EgoAteRow> = results
        .sequences
        .iter()
        .map(|s| EgoAteRow {
            sequence: s.name.clone(),
            per_variant: s
                .variants
                .iter()
                .filter_map(|r| {
                    r.metrics.as_ref().map(|m| {
                        (
                            r.variant,
                            EgoAte {
                                ate_t_m: m.ego.ate_t_m,
                                ate_r_rad: m.ego.ate_r_rad,
                            },
                        )
                    })
                })
                .collect(),
        })
        .collect();
    let mut table = ego_ate_table(
        "Ego-pose RMSE of ATE_T [m] and ATE_R [rad] (SE(3)-aligned)",
        &rows,
    )?;
    // Simulated rotations are accurate to a few mrad: three decimals of a
    // radian would print most of them as 0.001.
    for column in (2..table.header.len()).step_by(2) {
        table.set_decimals(column, 4);
    }
    Ok(table)
}

/// CLEAR-MOT per sequence × variant at one IoU kind ("3D"/"BEV"), thresholds 0.25 and 0.5.
pub fn tracking_table_of(results: &SuiteResults, kind: &str) -> Result<Table> {
    let mut rows = Vec::new();
    for s in &results.sequences {
        for threshold in [0.25, 0.5] {
            for r in &s.variants {
                let Some(mot) = r.metrics.as_ref().and_then(|m| m.mot(kind, threshold)) else {
                    continue;
                };
                rows.push(TrackingRow {
                    sequence: s.name.clone(),
                    variant: r.variant,
                    iou_threshold: threshold,
                    mota_percent: mot.counts.mota.map(|x| 100.0 * x),
                    motp_percent: mot.counts.motp.map(|x| 100.0 * x),
                    idsw: mot.counts.id_switches,
                    fp: mot.counts.false_positives,
                    fn_: mot.counts.false_negatives,
                });
            }
        }
    }
    Ok(tracking_table(
        &format!("CLEAR-MOT per sequence, {kind} IoU (class-agnostic)"),
        &rows,
    )?)
}

/// Mean of `values` when every sequence has one (a mean over a subset would
/// not compare across variants).
fn mean_of_all(values: &[Option<f64>]) -> Option<f64> {
    if values.is_empty() || values.iter().any(|v| v.is_none_or(|x| !x.is_finite())) {
        return None;
    }
    Some(values.iter().flatten().sum::<f64>() / values.len() as f64)
}

/// Paper Table "tab_ab3dmot_compare": Method | MOTP [%] at 3D IoU 0.25 and
/// 0.5, mean over the sequences; the best in bold.
pub fn motp_table(results: &SuiteResults) -> Result<Table> {
    let header = ["Method", "MOTP [%] (IoU 0.25)", "MOTP [%] (IoU 0.5)"]
        .map(String::from)
        .to_vec();
    let mut table = Table::new("MOTP, 3D IoU, mean over sequences", header);
    table.set_decimals(1, 2);
    table.set_decimals(2, 2);
    for v in variants_with_metrics(results) {
        let motp = |threshold: f64| {
            let per_seq: Vec<Option<f64>> = results
                .sequences
                .iter()
                .map(|s| {
                    s.metrics(v)
                        .and_then(|m| m.mot("3D", threshold))
                        .and_then(|m| m.counts.motp)
                        .map(|x| 100.0 * x)
                })
                .collect();
            mean_of_all(&per_seq)
        };
        table.push_row(vec![
            Cell::from(v.label()),
            motp(0.25).into(),
            motp(0.5).into(),
        ])?;
    }
    table.bold = [1, 2]
        .map(|column| BoldRule::BestInColumn {
            column,
            better: Better::Higher,
            group_by: vec![],
        })
        .to_vec();
    Ok(table)
}

/// Dynamic-feature filtering per sequence × filtering variant: precision
/// and recall of the removed features against the points of moving objects
/// (per-point labels), and the share of static objects' features removed.
pub fn filtering_table(results: &SuiteResults) -> Result<Table> {
    let header = [
        "Seq",
        "Variant",
        "precision [%]",
        "recall [%]",
        "static-object features removed [%]",
    ]
    .map(String::from)
    .to_vec();
    let mut table = Table::new(
        "Dynamic-feature filtering vs per-point labels (LiDAR features)",
        header,
    );
    for column in 2..5 {
        table.set_decimals(column, 1);
    }
    for s in &results.sequences {
        for r in &s.variants {
            let Some(f) = r.metrics.as_ref().and_then(|m| m.filtering) else {
                continue;
            };
            let score = f.score();
            let percent = |x: Option<f64>| x.map(|v| 100.0 * v).into();
            table.push_row(vec![
                Cell::from(s.name.as_str()),
                Cell::from(r.variant.label()),
                percent(score.precision),
                percent(score.recall),
                percent(f.static_object_removed_fraction()),
            ])?;
        }
    }
    Ok(table)
}

/// The moving objects of a sequence in view longest (most ground-truth
/// frames in any variant's scoring), ties to the smaller id.
fn longest_moving_objects(s: &SequenceResult) -> Vec<u64> {
    let moving: BTreeSet<u64> = s.moving_objects.iter().copied().collect();
    let mut frames: BTreeMap<u64, usize> = BTreeMap::new();
    for m in s.variants.iter().filter_map(|r| r.metrics.as_ref()) {
        for o in m.objects.iter().filter(|o| moving.contains(&o.gt_id)) {
            let f = frames.entry(o.gt_id).or_default();
            *f = (*f).max(o.gt_frames);
        }
    }
    let mut ids: Vec<(u64, usize)> = frames.into_iter().collect();
    ids.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    ids.into_iter().map(|(id, _)| id).collect()
}

/// Paper Table "tab_obj_track": Seq / Obj | per variant TP [%], ATE_T, ATE_R
/// for the [`OBJECTS_PER_SEQUENCE`] longest-seen moving objects of each sequence.
pub fn objects_table(results: &SuiteResults) -> Result<Table> {
    let mut rows = Vec::new();
    for s in &results.sequences {
        for id in longest_moving_objects(s)
            .into_iter()
            .take(OBJECTS_PER_SEQUENCE)
        {
            let per_variant = s
                .variants
                .iter()
                .filter_map(|r| {
                    let m = r.metrics.as_ref()?;
                    let o = m.objects.iter().find(|o| o.gt_id == id)?;
                    Some((
                        r.variant,
                        ObjectMetrics {
                            tp_percent: o.tp_percent,
                            ate_t_m: o.ate_t_m,
                            ate_r_rad: o.ate_r_rad,
                        },
                    ))
                })
                .collect();
            rows.push(ObjectRow {
                sequence: s.name.clone(),
                object_id: id,
                per_variant,
            });
        }
    }
    Ok(object_table(
        "Moving objects: TP [%] (3D IoU ≥ 0.25) and ATE of the associated track",
        &rows,
    )?)
}

/// Paper Table "tab_time_consume" for one variant: per-stage mean / p95 ms
/// and FPS, pooled over every frame of every sequence.
pub fn timing_table_of(results: &SuiteResults, variant: Variant) -> Result<Option<Table>> {
    let runs: Vec<&VariantMetrics> = results
        .sequences
        .iter()
        .filter_map(|s| s.metrics(variant))
        .collect();
    let Some(first) = runs.first() else {
        return Ok(None);
    };
    let mut acc = first.timing_accumulator();
    for m in &runs[1..] {
        acc.merge(&m.timing_accumulator());
    }
    // stages in pipeline order, as the first run lists them
    let rows: Vec<TimingRow> = first
        .timings
        .iter()
        .filter_map(|s| TimingRow::from_accumulator(&acc, &s.stage))
        .collect();
    Ok(Some(timing_table(
        &format!("{}: time per scan by module", variant.label()),
        &rows,
    )?))
}

/// Seq | Variant | frames | before init | ATE max | RPE | wall FPS | status.
pub fn runs_table(results: &SuiteResults) -> Result<Table> {
    let header = [
        "Seq",
        "Variant",
        "frames",
        "estimated",
        "before init",
        "ATE_T max [m]",
        "RPE_T [m]",
        "RPE_R [rad]",
        "wall FPS",
        "status",
    ]
    .map(String::from)
    .to_vec();
    let mut table = Table::new("Runs", header);
    table.set_decimals(7, 4);
    table.set_decimals(8, 1);
    for s in &results.sequences {
        for r in &s.variants {
            let mut row = vec![
                Cell::from(s.name.as_str()),
                Cell::from(r.variant.label()),
                Cell::from(s.frames),
            ];
            match &r.metrics {
                Some(m) => row.extend([
                    Cell::from(m.frames_estimated),
                    Cell::from(m.frames_before_init),
                    Cell::Num(m.ego.ate_max_m),
                    m.ego.rpe_t_m.into(),
                    m.ego.rpe_r_rad.into(),
                    Cell::Num(m.fps),
                    Cell::from("ok"),
                ]),
                None => {
                    row.extend(std::iter::repeat_n(Cell::Missing, 6));
                    row.push(Cell::from("not available"));
                }
            }
            table.push_row(row)?;
        }
    }
    Ok(table)
}

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
fn thin<T: Clone>(points: &[T], max: usize) -> Vec<T> {
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
struct EgoPlots {
    plots: Vec<Plot>,
    alignments: BTreeMap<Variant, Alignment>,
    notes: Vec<String>,
}

fn ego_plots(s: &SequenceResult, suite_dir: &Path) -> EgoPlots {
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
fn object_plots(
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

/// The section of one sequence: its plots, and notes on what could not be drawn.
fn sequence_section(s: &SequenceResult, suite_dir: &Path) -> Section {
    let mut text = format!(
        "Family `{}`, seed {}, {} frames; dataset `{}`; {} moving objects.",
        s.family,
        s.seed,
        s.frames,
        s.dataset_dir.display(),
        s.moving_objects.len()
    );
    if let Some(e) = &s.error {
        let _ = write!(text, "\n\nNot available: {e}");
        return Section {
            heading: format!("Sequence {}", s.name),
            text,
            ..Section::default()
        };
    }
    let ego = ego_plots(s, suite_dir);
    let (objects, object_notes) = object_plots(s, suite_dir, &ego.alignments);
    for note in ego.notes.iter().chain(&object_notes) {
        let _ = write!(text, "\n\nNote: {note}");
    }
    Section {
        heading: format!("Sequence {}", s.name),
        text,
        tables: Vec::new(),
        plots: ego.plots.into_iter().chain(objects).collect(),
    }
}

/// One bullet per failed sequence or variant.
fn failures(results: &SuiteResults) -> Vec<String> {
    let mut out = Vec::new();
    for s in &results.sequences {
        if let Some(e) = &s.error {
            out.push(format!("- {}: not available: {e}", s.name));
        }
        for r in &s.variants {
            if let Some(e) = &r.error {
                out.push(format!(
                    "- {} / {}: not available: {e}",
                    s.name,
                    r.variant.label()
                ));
            }
        }
    }
    out
}

/// The whole report; `suite_dir` is where the results' relative paths start.
pub fn build_report(results: &SuiteResults, suite_dir: &Path) -> Result<Report> {
    let variant_names: Vec<&str> = results.variants.iter().map(|v| v.name()).collect();
    let seeds: Vec<String> = results.seeds.iter().map(u64::to_string).collect();
    let failed = failures(results);
    let mut overview = format!(
        "Families {}, seeds {}, {} s each; variants {}. Regenerate with \
         `limot eval suite --families {} --seeds {} --duration {} --variants {}`.",
        results.families.join(", "),
        seeds.join(", "),
        results.duration_s,
        variant_names.join(", "),
        results.families.join(","),
        seeds.join(","),
        results.duration_s,
        variant_names.join(","),
    );
    if !failed.is_empty() {
        let _ = write!(
            overview,
            "\n\n{} run(s) not available (see Failures).",
            failed.len()
        );
    }
    let mut sections = vec![
        Section {
            heading: "Suite".into(),
            text: overview,
            tables: vec![runs_table(results)?],
            plots: Vec::new(),
        },
        Section {
            heading: "Ego-pose accuracy".into(),
            text: "RMSE of the absolute trajectory error after SE(3) alignment of the \
                   estimated LiDAR poses to the truth; best variant per sequence in bold, \
                   mean row only where every sequence has a value."
                .into(),
            tables: vec![ego_table(results)?],
            plots: Vec::new(),
        },
        Section {
            heading: "Multi-object tracking".into(),
            text: "Confirmed tracks matched to a detection in the frame, scored against the \
                   camera-visible ground-truth boxes in the true world frame."
                .into(),
            tables: vec![
                motp_table(results)?,
                tracking_table_of(results, "3D")?,
                tracking_table_of(results, "BEV")?,
            ],
            plots: Vec::new(),
        },
        Section {
            heading: "Object pose accuracy".into(),
            text: format!(
                "The {OBJECTS_PER_SEQUENCE} moving objects (not parked, ≥ {} m/s at some \
                 frame) of each sequence seen in the most frames. TP = frames matched at 3D \
                 IoU ≥ 0.25 over frames in view; ATE of the track matched most often.",
                crate::experiments::MOVING_SPEED_MPS
            ),
            tables: vec![objects_table(results)?],
            plots: Vec::new(),
        },
        Section {
            heading: "Dynamic-feature filtering".into(),
            text: format!(
                "Of the edge and planar features each variant extracted, those it dropped \
                 as object points, against the per-point instance labels: a feature is \
                 positive when it lies on an object moving faster than {} m/s in that \
                 frame (the paper's v_thres); parked and stopped objects are static.",
                crate::experiments::FILTER_MOVING_SPEED_MPS
            ),
            tables: vec![filtering_table(results)?],
            plots: Vec::new(),
        },
    ];
    let mut timing = Vec::new();
    for &v in &results.variants {
        if let Some(t) = timing_table_of(results, v)? {
            timing.push(t);
        }
    }
    sections.push(Section {
        heading: "Running time".into(),
        text: "Wall time per scan of each pipeline stage over every frame of every sequence \
               (FPS = 1000 / mean). Machine-dependent: compare variants within one report."
            .into(),
        tables: timing,
        plots: Vec::new(),
    });
    for s in &results.sequences {
        sections.push(sequence_section(s, suite_dir));
    }
    if !failed.is_empty() {
        sections.push(Section {
            heading: "Failures".into(),
            text: failed.join("\n"),
            ..Section::default()
        });
    }
    Ok(Report {
        title: "limot evaluation suite".into(),
        sections,
    })
}

/// Builds the report of `results` (paths relative to `suite_dir`) and writes
/// it into `report_dir` (README.md + SVGs). Returns the README path.
pub fn write_suite_report(
    report_dir: &Path,
    results: &SuiteResults,
    suite_dir: &Path,
) -> Result<PathBuf> {
    let report = build_report(results, suite_dir)?;
    Ok(write_report(report_dir, &report)?)
}

#[cfg(test)]
mod tests;
