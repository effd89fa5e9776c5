//! The report of a suite (`crate::experiments::suite`): tables shaped like the paper's
//! (ego ATE per sequence × variant, CLEAR-MOT, per-object TP/ATE, timing per
//! module) and SVG plots per sequence (ego trajectories vs truth, ego error
//! over time, moving objects' estimated vs true trajectories and speeds).
//!
//! Tables come from `results.json` alone; plots also read the run outputs
//! (`poses_tum.txt`, `tracks.csv`) and the datasets' ground truth, so a report
//! re-rendered from the same suite directory is identical. A plot whose files
//! are gone is left out with a note rather than failing the report.

use crate::experiments::{Ablation, SequenceResult, SuiteError, SuiteResults, VariantMetrics};
use crate::experiments::{EgoEvalOptions, evaluate_trajectories, load_estimate, load_truth};
use crate::metrics::Alignment;
use crate::report::plot::Series2D;
use crate::report::table::{
    Better, BoldRule, Cell, EgoAte, EgoAteRow, ObjectMetrics, ObjectRow, Table, TimingRow,
    TrackingRow, ego_ate_table, object_table, timing_table, tracking_table,
};
use crate::report::{Plot, PlotKind, Report, Section, write_report};

use limot_estimator::Variant;
use limot_sim::record::Dataset;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

mod plots;

use plots::{ego_plots, object_plots};

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

/// The sequences that were simulated: one that was not has no figures for
/// any variant (it is listed under Failures), so it would only blank the means.
fn simulated(results: &SuiteResults) -> impl Iterator<Item = &SequenceResult> {
    results.sequences.iter().filter(|s| s.error.is_none())
}

/// Paper Table "tab_ego_track": Seq | per variant ATE_T \[m\], ATE_R \[rad\];
/// best per row in bold; a mean row; simulated sequences only.
///
/// # Errors
///
/// [`SuiteError::Report`] when the table cannot be built.
pub fn ego_table(results: &SuiteResults) -> Result<Table> {
    let rows: Vec<EgoAteRow> = simulated(results)
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

/// Where the ego error lies: per sequence and variant, ATE_T split along
/// and across the true direction of travel, and the share of degenerate scan
/// matches (a direction left to the IMU). Runs scored before these were
/// measured have empty cells.
///
/// # Errors
///
/// [`SuiteError::Report`] when the table cannot be built.
pub fn ego_error_split_table(results: &SuiteResults) -> Result<Table> {
    let header = [
        "Seq",
        "Variant",
        "ATE_T [m]",
        "along the path [m]",
        "across [m]",
        "degenerate matches [%]",
    ]
    .map(String::from)
    .to_vec();
    let mut table = Table::new(
        "Ego error along and across the path, and degenerate scan matches",
        header,
    );
    table.set_decimals(5, 1);
    for s in simulated(results) {
        for r in &s.variants {
            let Some(e) = r.metrics.as_ref().map(|m| &m.ego) else {
                continue;
            };
            let across = e
                .ate_along_m
                .map(|along| (e.ate_t_m.powi(2) - along.powi(2)).max(0.0).sqrt());
            table.push_row(vec![
                Cell::from(s.name.as_str()),
                Cell::from(r.variant.label()),
                e.ate_t_m.into(),
                e.ate_along_m.into(),
                across.into(),
                e.degenerate_match_share.map(|x| 100.0 * x).into(),
            ])?;
        }
    }
    Ok(table)
}

/// CLEAR-MOT per sequence × variant at one IoU kind ("3D"/"BEV"), thresholds 0.25 and 0.5.
///
/// # Errors
///
/// [`SuiteError::Report`] when the table cannot be built.
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
/// 0.5, mean over the simulated sequences; the best in bold.
///
/// # Errors
///
/// [`SuiteError::Report`] when the table cannot be built.
pub fn motp_table(results: &SuiteResults) -> Result<Table> {
    let header = ["Method", "MOTP [%] (IoU 0.25)", "MOTP [%] (IoU 0.5)"]
        .map(String::from)
        .to_vec();
    let mut table = Table::new("MOTP, 3D IoU, mean over sequences", header);
    table.set_decimals(1, 2);
    table.set_decimals(2, 2);
    for v in variants_with_metrics(results) {
        let motp = |threshold: f64| {
            let per_seq: Vec<Option<f64>> = simulated(results)
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
/// (per-point labels), the share of static objects' features removed, and
/// for the trajectory-based filters the moving objects' features kept, by
/// cause ([`crate::experiments::KeptMovingCauses`]), as shares of all
/// features on moving objects.
///
/// # Errors
///
/// [`SuiteError::Report`] when the table cannot be built.
pub fn filtering_table(results: &SuiteResults) -> Result<Table> {
    let header = [
        "Seq",
        "Variant",
        "precision [%]",
        "recall [%]",
        "static-object features removed [%]",
        "kept moving: untracked [%]",
        "tentative static [%]",
        "confirmed static [%]",
        "dynamic, outside box [%]",
    ]
    .map(String::from)
    .to_vec();
    let mut table = Table::new(
        "Dynamic-feature filtering vs per-point labels (LiDAR features)",
        header,
    );
    for column in 2..9 {
        table.set_decimals(column, 1);
    }
    for s in &results.sequences {
        for r in &s.variants {
            let Some(f) = r.metrics.as_ref().and_then(|m| m.filtering) else {
                continue;
            };
            let score = f.score();
            let percent = |x: Option<f64>| x.map(|v| 100.0 * v).into();
            let of_moving = |n: Option<usize>| {
                percent(
                    n.filter(|_| f.moving_features > 0)
                        .map(|n| n as f64 / f.moving_features as f64),
                )
            };
            let causes = f.kept_moving_causes;
            table.push_row(vec![
                Cell::from(s.name.as_str()),
                Cell::from(r.variant.label()),
                percent(score.precision),
                percent(score.recall),
                percent(f.static_object_removed_fraction()),
                of_moving(causes.map(|c| c.untracked)),
                of_moving(causes.map(|c| c.tentative_static)),
                of_moving(causes.map(|c| c.confirmed_static)),
                of_moving(causes.map(|c| c.dynamic_outside_box)),
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
///
/// # Errors
///
/// [`SuiteError::Report`] when the table cannot be built.
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

/// What the ablation section compares.
const ABLATION_TEXT: &str = "LIMOT is the variant as the suite runs it: dynamic objects are \
    conditioned on the optimised ego (solved after it, so they cannot move it; static objects \
    do inform it). LIMOT (joint) is the same system in the fully joint form \
    (`dynamic_objects_inform_ego = true`): dynamic objects' motion factors are optimised together \
    with the ego and can pull it. Object columns are at 3D IoU 0.25; the moving objects are those \
    of the object table; best of each sequence in bold, means only where every sequence has a value.";

/// One run's row of the ablation table: ego ATE_T, ATE_R, MOTA and MOTP at
/// 3D IoU 0.25, and TP and ATE_T of `objects` (mean over those it has).
fn ablation_figures(m: Option<&VariantMetrics>, objects: &[u64]) -> [Option<f64>; 6] {
    let Some(m) = m else {
        return [None; 6];
    };
    let mot = m.mot("3D", 0.25).map(|x| &x.counts);
    let mean = |values: Vec<f64>| {
        (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
    };
    let scored: Vec<_> = m
        .objects
        .iter()
        .filter(|o| objects.contains(&o.gt_id))
        .collect();
    [
        Some(m.ego.ate_t_m),
        Some(m.ego.ate_r_rad),
        mot.and_then(|c| c.mota).map(|x| 100.0 * x),
        mot.and_then(|c| c.motp).map(|x| 100.0 * x),
        mean(scored.iter().map(|o| o.tp_percent).collect()),
        mean(scored.iter().filter_map(|o| o.ate_t_m).collect()),
    ]
}

/// The ablations beside the variant each changes: per sequence one row for
/// the variant and one per ablation of it (ego ATE, CLEAR-MOT at 3D IoU
/// 0.25, TP and ATE_T of the moving objects of the object table), then the
/// mean rows over the simulated sequences; the better of each sequence in
/// bold. `None` without ablations.
///
/// # Errors
///
/// [`SuiteError::Report`] when the table cannot be built.
pub fn ablation_table(results: &SuiteResults) -> Result<Option<Table>> {
    if results.ablations.is_empty() {
        return Ok(None);
    }
    let header = [
        "Seq",
        "Run",
        "ATE_T [m]",
        "ATE_R [rad]",
        "MOTA [%] (3D 0.25)",
        "MOTP [%] (3D 0.25)",
        "moving objects TP [%]",
        "moving objects ATE_T [m]",
    ]
    .map(String::from)
    .to_vec();
    let mut table = Table::new("Ablation: conditioned vs fully joint", header);
    table.set_decimals(3, 4);
    for column in 4..7 {
        table.set_decimals(column, 1);
    }
    // the compared runs: each ablated variant, then its ablations
    let mut runs: Vec<(String, Option<Ablation>, Variant)> = Vec::new();
    for &a in &results.ablations {
        let v = a.variant();
        if !runs.iter().any(|(_, ab, rv)| ab.is_none() && *rv == v) {
            runs.push((v.label().to_string(), None, v));
        }
        runs.push((a.label(), Some(a), v));
    }
    let mut per_run: Vec<Vec<[Option<f64>; 6]>> = vec![Vec::new(); runs.len()];
    for s in simulated(results) {
        let objects: Vec<u64> = longest_moving_objects(s)
            .into_iter()
            .take(OBJECTS_PER_SEQUENCE)
            .collect();
        for (i, (label, ablation, variant)) in runs.iter().enumerate() {
            let m = match ablation {
                None => s.metrics(*variant),
                Some(a) => s.ablation_metrics(*a),
            };
            let figures = ablation_figures(m, &objects);
            per_run[i].push(figures);
            let mut row = vec![Cell::from(s.name.as_str()), Cell::from(label.as_str())];
            row.extend(figures.map(Cell::from));
            table.push_row(row)?;
        }
    }
    for (i, (label, _, _)) in runs.iter().enumerate() {
        let mut row = vec![Cell::from("mean"), Cell::from(label.as_str())];
        row.extend((0..6).map(|k| {
            let column: Vec<Option<f64>> = per_run[i].iter().map(|f| f[k]).collect();
            Cell::from(mean_of_all(&column))
        }));
        table.push_row(row)?;
    }
    table.bold = [
        (2, Better::Lower),
        (3, Better::Lower),
        (4, Better::Higher),
        (5, Better::Higher),
        (6, Better::Higher),
        (7, Better::Lower),
    ]
    .map(|(column, better)| BoldRule::BestInColumn {
        column,
        better,
        group_by: vec![0],
    })
    .to_vec();
    Ok(Some(table))
}

/// Paper Table "tab_time_consume" for one variant: per-stage mean / p95 ms
/// and FPS, pooled over every frame of every sequence.
///
/// # Errors
///
/// [`SuiteError::Report`] when the table cannot be built.
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

/// Every run of a sequence, the variants', then the ablations', with its label.
fn runs_of(s: &SequenceResult) -> impl Iterator<Item = (String, &Option<VariantMetrics>)> {
    let variants = s
        .variants
        .iter()
        .map(|r| (r.variant.label().to_string(), &r.metrics));
    let ablations = s.ablations.iter().map(|r| (r.ablation.label(), &r.metrics));
    variants.chain(ablations)
}

/// Seq | Variant | frames | before init | ATE max | RPE | wall FPS | status.
///
/// # Errors
///
/// [`SuiteError::Report`] when the table cannot be built.
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
        for (label, metrics) in runs_of(s) {
            let mut row = vec![
                Cell::from(s.name.as_str()),
                Cell::from(label),
                Cell::from(s.frames),
            ];
            match metrics {
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
        let variants = s
            .variants
            .iter()
            .map(|r| (r.variant.label().to_string(), &r.error));
        let ablations = s.ablations.iter().map(|r| (r.ablation.label(), &r.error));
        for (label, error) in variants.chain(ablations) {
            if let Some(e) = error {
                out.push(format!("- {} / {label}: not available: {e}", s.name));
            }
        }
    }
    out
}

/// The whole report; `suite_dir` is where the results' relative paths start.
///
/// # Errors
///
/// [`SuiteError`] when a table cannot be built (missing plot inputs become notes).
pub fn build_report(results: &SuiteResults, suite_dir: &Path) -> Result<Report> {
    let variant_names: Vec<&str> = results.variants.iter().map(|v| v.name()).collect();
    let seeds: Vec<String> = results.seeds.iter().map(u64::to_string).collect();
    let failed = failures(results);
    let families = results.given_families();
    let twin_options = results.twins.as_ref().map_or_else(String::new, |t| {
        let mut options = format!(
            " --training {} --sequences {}",
            t.training.display(),
            crate::experiments::format_sequences(&t.sequences)
        );
        if let Some(d) = &t.detections {
            let _ = write!(options, " --detections {}", d.display());
        }
        options
    });
    let ablation_names: Vec<&str> = results.ablations.iter().map(|a| a.name()).collect();
    let (ablations_text, ablation_option) = if ablation_names.is_empty() {
        (String::new(), String::new())
    } else {
        (
            format!("; ablations {}", ablation_names.join(", ")),
            format!(" --ablation {}", ablation_names.join(",")),
        )
    };
    let mut overview = format!(
        "Families {}, seeds {}, {} s each at most; variants {}{ablations_text}. Regenerate with \
         `limot eval suite --families {}{twin_options} --seeds {} --duration {} --variants {}{ablation_option}`.",
        families.join(", "),
        seeds.join(", "),
        results.duration_s,
        variant_names.join(", "),
        families.join(","),
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
    let mut sections = vec![Section {
        heading: "Suite".into(),
        text: overview,
        tables: vec![runs_table(results)?],
        plots: Vec::new(),
    }];
    sections.extend(crate::report::twins_section(results)?);
    sections.extend([
        Section {
            heading: "Ego-pose accuracy".into(),
            text: "RMSE of the absolute trajectory error after SE(3) alignment of the \
                   estimated LiDAR poses to the truth; best variant per sequence in bold, \
                   mean row only where every sequence has a value. The second table splits \
                   ATE_T along and across the true direction of travel and gives the share of \
                   scan matches that left a direction to the IMU (degenerate: fewer than \
                   ~100 points constrain it, e.g. along a road whose sides look alike); \
                   there the error is the IMU's drift along the road."
                .into(),
            tables: vec![ego_table(results)?, ego_error_split_table(results)?],
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
    ]);
    if let Some(table) = ablation_table(results)? {
        sections.push(Section {
            heading: "Ablation: conditioned vs fully joint".into(),
            text: ABLATION_TEXT.into(),
            tables: vec![table],
            plots: Vec::new(),
        });
    }
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
///
/// # Errors
///
/// [`SuiteError`] when the report cannot be built or written.
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
