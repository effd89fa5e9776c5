//! The report of `limot eval kitti`: our figures on real KITTI tracking data
//! in the shapes of the paper's Tables I-III, with the paper's published rows
//! for the same sequences beside them (values copied from the paper, cited
//! per table; rows of methods we do not run are marked as such); and the
//! same shapes for the KITTI twins of a suite ([`twins_section`]).

use crate::experiments::{EgoScores, ObjectSummary, TrackScores};
use crate::experiments::{KittiSequenceResult, KittiSuiteResults, TRACKER_ALONE};
use crate::metrics::MotSummary;
use crate::report::table::{Better, BoldRule, Cell, Table};
use crate::report::{Report, ReportError, Section, write_report};

use limot_estimator::Variant;
use std::path::{Path, PathBuf};

mod paper;
mod twins;

pub use twins::{DIVERGED_ATE_PER_PATH, STATIC_EGO_PATH_M, twins_section};

use paper::{
    PAPER_EGO_METHODS, PAPER_OBJECT_METHODS, PAPER_TABLE_I, PAPER_TABLE_III, paper_table_ii_rows,
};

/// How many of each scanned sequence's longest-labelled cars the object table lists.
const LONGEST_OBJECTS: usize = 3;

fn header(names: &[&str]) -> Vec<String> {
    names.iter().map(|s| s.to_string()).collect()
}

fn seq_cell(sequence: u32) -> Cell {
    Cell::from(format!("{sequence:02}"))
}

fn ego_cells(e: Option<&EgoScores>) -> Vec<Cell> {
    match e {
        Some(e) => vec![
            e.ate_t_m.into(),
            e.ate_r_rad.into(),
            e.sim3_ate_t_m.into(),
            e.sim3_scale.into(),
            e.rpe_frame_t_m.into(),
            e.rpe_10m_t_m.into(),
        ],
        None => vec![Cell::Missing; 6],
    }
}

/// Table I's shape: per scanned sequence, the paper's rows and ours.
///
/// # Errors
///
/// [`ReportError`] when the table cannot be built.
pub fn ego_table(results: &KittiSuiteResults) -> Result<Table, ReportError> {
    let mut table = Table::new(
        "Ego: ATE (SE(3)) as in the paper's Table I, Sim(3) ATE and scale, RPE (RMSE) over 1 frame and 10 m",
        header(&[
            "Seq",
            "Method",
            "Source",
            "ATE_T [m]",
            "ATE_R [rad]",
            "Sim(3) ATE_T [m]",
            "scale",
            "RPE 1 frame [m]",
            "RPE 10 m [m]",
            "frames",
            "ms/frame",
        ]),
    );
    for (c, d) in [(4, 4), (6, 4), (7, 4), (10, 1)] {
        table.set_decimals(c, d);
    }
    for s in results.sequences.iter().filter(|s| s.has_scans) {
        let paper = PAPER_TABLE_I.iter().find(|(seq, _)| *seq == s.sequence);
        for (i, (name, variant)) in PAPER_EGO_METHODS.iter().enumerate() {
            if let Some((_, row)) = paper {
                let (t, r) = row[i];
                let source = if variant.is_some() {
                    "paper, Table I"
                } else {
                    "paper, Table I (not run here)"
                };
                let mut cells = vec![seq_cell(s.sequence), Cell::from(*name), Cell::from(source)];
                cells.extend([t.into(), r.into()]);
                cells.extend(vec![Cell::Missing; 6]);
                table.push_row(cells)?;
            }
            let Some(run) = variant.and_then(|v| s.run(v)) else {
                continue;
            };
            let label = format!("{} (limot)", run.variant.label());
            let mut cells = vec![seq_cell(s.sequence), Cell::from(label), Cell::from("ours")];
            cells.extend(ego_cells(run.scores.as_ref().map(|x| &x.ego)));
            cells.push(run.frames_estimated.into());
            cells.push(if run.error.is_some() {
                Cell::Missing
            } else {
                run.mean_frame_ms.into()
            });
            table.push_row(cells)?;
        }
        for peer in &s.ego_peers {
            let mut cells = vec![
                seq_cell(s.sequence),
                Cell::from(peer.name.as_str()),
                Cell::from("peer, scored here"),
            ];
            cells.extend(ego_cells(peer.scores.as_ref()));
            cells.push(
                peer.scores
                    .as_ref()
                    .map_or(Cell::Missing, |e| e.poses.into()),
            );
            cells.push(Cell::Missing);
            table.push_row(cells)?;
        }
    }
    Ok(table)
}

fn mot_cells(m: &[MotSummary; 3]) -> Vec<Cell> {
    let pct = |v: Option<f64>| Cell::from(v.map(|x| 100.0 * x));
    let [image, d25, d50] = m;
    vec![
        pct(image.mota),
        pct(d25.mota),
        pct(d25.motp),
        pct(d50.mota),
        pct(d50.motp),
        image.id_switches.into(),
        image.false_positives.into(),
        image.false_negatives.into(),
        image.gt_count.into(),
    ]
}

/// Combined scores of `pick` over `sequences`, `None` when one is missing.
fn combined<'a>(
    sequences: &[&'a KittiSequenceResult],
    pick: impl Fn(&'a KittiSequenceResult) -> Option<&'a TrackScores>,
) -> Option<[MotSummary; 3]> {
    let scores: Option<Vec<&TrackScores>> = sequences.iter().map(|s| pick(s)).collect();
    let scores = scores.filter(|v| !v.is_empty())?;
    Some([
        MotSummary::combine(scores.iter().map(|s| &s.image_iou_50)),
        MotSummary::combine(scores.iter().map(|s| &s.iou3d_25)),
        MotSummary::combine(scores.iter().map(|s| &s.iou3d_50)),
    ])
}

fn seq_list(sequences: &[&KittiSequenceResult]) -> String {
    sequences
        .iter()
        .map(|s| format!("{:02}", s.sequence))
        .collect::<Vec<_>>()
        .join(" ")
}

fn tracker(s: &KittiSequenceResult) -> Option<&TrackScores> {
    s.tracker.as_ref()?.scores.as_ref()
}

fn peer(s: &KittiSequenceResult) -> Option<&TrackScores> {
    s.tracking_peer.as_ref()?.scores.as_ref()
}

fn run_tracks(s: &KittiSequenceResult, variant: Variant) -> Option<&TrackScores> {
    s.run(variant)?.scores.as_ref()?.tracks.as_ref()
}

/// Table II's shape, widened to CLEAR-MOT: the paper's MOTP rows, then ours
/// and the peer's on the same sequences.
///
/// # Errors
///
/// [`ReportError`] when the table cannot be built.
pub fn tracking_table(results: &KittiSuiteResults) -> Result<Table, ReportError> {
    let mut table = Table::new(
        "Tracking, class Car: 2D MOTA (TrackEval, image IoU 0.5) and 3D CLEAR-MOT at IoU 0.25 / 0.5 as in the paper's Table II [%]; IDSW / FP / FN of the 2D evaluation",
        header(&[
            "Method",
            "Source",
            "Sequences",
            "2D MOTA",
            "3D MOTA@0.25",
            "MOTP@0.25",
            "3D MOTA@0.5",
            "MOTP@0.5",
            "IDSW",
            "FP",
            "FN",
            "GT",
        ]),
    );
    for c in 3..8 {
        table.set_decimals(c, 2);
    }
    for cells in paper_table_ii_rows("paper, Table II (CenterPoint detections)", true) {
        table.push_row(cells)?;
    }
    let mut push =
        |name: &str, source: &str, seqs: &[&KittiSequenceResult], m: Option<[MotSummary; 3]>| {
            if let Some(m) = m {
                let mut cells = vec![
                    Cell::from(name),
                    Cell::from(source),
                    Cell::from(seq_list(seqs)),
                ];
                cells.extend(mot_cells(&m));
                table.push_row(cells)
            } else {
                Ok(())
            }
        };
    if let Some(peer_name) = &results.tracking_peer {
        let both: Vec<&KittiSequenceResult> = results
            .sequences
            .iter()
            .filter(|s| peer(s).is_some() && tracker(s).is_some())
            .collect();
        push(
            peer_name,
            "peer's result files, scored here",
            &both,
            combined(&both, peer),
        )?;
        push(
            TRACKER_ALONE,
            "ours, OXTS ego",
            &both,
            combined(&both, tracker),
        )?;
    }
    let all: Vec<&KittiSequenceResult> = results
        .sequences
        .iter()
        .filter(|s| tracker(s).is_some())
        .collect();
    push(
        TRACKER_ALONE,
        "ours, OXTS ego",
        &all,
        combined(&all, tracker),
    )?;
    let scanned: Vec<&KittiSequenceResult> =
        results.sequences.iter().filter(|s| s.has_scans).collect();
    for &variant in results.variants.iter().filter(|v| v.tracks_objects()) {
        let label = format!("{} (limot)", variant.label());
        let runs = combined(&scanned, |s| run_tracks(s, variant));
        push(&label, "ours, estimated ego", &scanned, runs)?;
    }
    if results.variants.iter().any(|v| v.tracks_objects()) {
        push(
            TRACKER_ALONE,
            "ours, OXTS ego",
            &scanned,
            combined(&scanned, tracker),
        )?;
    }
    Ok(table)
}

/// The filtering variants' feature removal judged by label_02's boxes
/// (`experiments::score::kitti_filter`), per scanned sequence [%].
///
/// # Errors
///
/// [`ReportError`] when the table cannot be built.
pub fn filter_table(results: &KittiSuiteResults) -> Result<Table, ReportError> {
    let mut table = Table::new(
        "Dynamic-feature filter against label_02's boxes: the share of all LiDAR features removed, and the features on the labelled moving and standing objects with the share of them removed [%]",
        header(&[
            "Seq",
            "Variant",
            "features removed",
            "features on moving objects",
            "moving removed",
            "features on standing objects",
            "standing removed",
        ]),
    );
    for c in [2, 4, 6] {
        table.set_decimals(c, 1);
    }
    let percent = |x: Option<f64>| -> Cell { x.map(|v| 100.0 * v).into() };
    for s in results.sequences.iter().filter(|s| s.has_scans) {
        for &variant in &results.variants {
            let Some(f) = s
                .run(variant)
                .and_then(|r| r.scores.as_ref())
                .and_then(|sc| sc.filter.as_ref())
            else {
                continue;
            };
            table.push_row(vec![
                seq_cell(s.sequence),
                Cell::from(variant.label()),
                percent(f.removed_fraction()),
                f.moving_features.into(),
                percent(f.score().recall),
                f.static_object_features.into(),
                percent(f.static_object_removed_fraction()),
            ])?;
        }
    }
    Ok(table)
}

/// AB3DMOT's evaluate.py rows (sAMOTA, AMOTA, AMOTP, MOTA/MOTP at the best
/// threshold, [%]).
///
/// # Errors
///
/// [`ReportError`] when the table cannot be built.
pub fn ab3dmot_table(results: &KittiSuiteResults) -> Result<Table, ReportError> {
    let mut table = Table::new(
        "Tracking, class Car: AB3DMOT's evaluate.py (3D IoU 0.25) [%]",
        header(&[
            "Method",
            "Sequences",
            "sAMOTA",
            "AMOTA",
            "AMOTP",
            "MOTA (best thr)",
            "MOTP (best thr)",
        ]),
    );
    for c in 2..7 {
        table.set_decimals(c, 2);
    }
    for r in &results.ab3dmot_eval {
        let sequences = r
            .sequences
            .iter()
            .map(|s| format!("{s:02}"))
            .collect::<Vec<_>>()
            .join(" ");
        table.push_row(vec![
            Cell::from(r.name.as_str()),
            Cell::from(sequences),
            (100.0 * r.samota).into(),
            (100.0 * r.amota).into(),
            (100.0 * r.amotp).into(),
            r.best_mota.map(|m| 100.0 * m).into(),
            (100.0 * r.best_motp).into(),
        ])?;
    }
    Ok(table)
}

fn object_cells(o: Option<&ObjectSummary>) -> Vec<Cell> {
    match o {
        Some(o) => vec![o.tp_percent.into(), o.ate_t_m.into(), o.ate_r_rad.into()],
        None => vec![Cell::Missing; 3],
    }
}

/// Table III's shape: the paper's objects (its rows and our tracker alone on
/// them), then the longest-labelled cars of each scanned sequence.
///
/// # Errors
///
/// [`ReportError`] when the table cannot be built.
pub fn object_table(results: &KittiSuiteResults) -> Result<Table, ReportError> {
    let mut table = Table::new(
        "Objects as in the paper's Table III: TP [%] at 3D IoU 0.25, ATE_T [m], ATE_R [rad] of the associated track",
        header(&[
            "Seq / Obj",
            "Method",
            "Source",
            "TP [%]",
            "ATE_T [m]",
            "ATE_R [rad]",
        ]),
    );
    table.set_decimals(3, 2);
    let find = |sequence: u32| results.sequences.iter().find(|s| s.sequence == sequence);
    let object_of = |scores: Option<&TrackScores>, id: u64| -> Option<ObjectSummary> {
        scores?.objects.iter().find(|o| o.gt_id == id).cloned()
    };
    for (sequence, id, rows) in PAPER_TABLE_III {
        let key = format!("{sequence:02} / {id}");
        for (name, (tp, t, r)) in PAPER_OBJECT_METHODS.iter().zip(rows) {
            let mut cells = vec![
                Cell::from(key.as_str()),
                Cell::from(*name),
                Cell::from("paper, Table III"),
            ];
            cells.extend([tp.into(), t.into(), r.into()]);
            table.push_row(cells)?;
        }
        let ours = find(sequence)
            .and_then(|s| s.tracker.as_ref())
            .and_then(|t| object_of(t.scores.as_ref(), id));
        let mut cells = vec![
            Cell::from(key.as_str()),
            Cell::from(TRACKER_ALONE),
            Cell::from(if ours.is_some() {
                "ours, OXTS ego"
            } else {
                "ours: no detections or no such car here"
            }),
        ];
        cells.extend(object_cells(ours.as_ref()));
        table.push_row(cells)?;
    }
    for s in results.sequences.iter().filter(|s| s.has_scans) {
        let tracker_scores = s.tracker.as_ref().and_then(|t| t.scores.as_ref());
        let longest: Vec<u64> = tracker_scores
            .or_else(|| {
                s.runs
                    .iter()
                    .find_map(|r| r.scores.as_ref()?.tracks.as_ref())
            })
            .map(|t| {
                t.objects
                    .iter()
                    .take(LONGEST_OBJECTS)
                    .map(|o| o.gt_id)
                    .collect()
            })
            .unwrap_or_default();
        for id in longest {
            let key = format!("{:02} / {id}", s.sequence);
            for run in s.runs.iter().filter(|r| r.variant.tracks_objects()) {
                let tracks = run.scores.as_ref().and_then(|x| x.tracks.as_ref());
                let mut cells = vec![
                    Cell::from(key.as_str()),
                    Cell::from(format!("{} (limot)", run.variant.label())),
                    Cell::from("ours, estimated ego"),
                ];
                cells.extend(object_cells(object_of(tracks, id).as_ref()));
                table.push_row(cells)?;
            }
            let mut cells = vec![
                Cell::from(key.as_str()),
                Cell::from(TRACKER_ALONE),
                Cell::from("ours, OXTS ego"),
            ];
            cells.extend(object_cells(object_of(tracker_scores, id).as_ref()));
            table.push_row(cells)?;
        }
    }
    table.bold.push(BoldRule::BestInColumn {
        column: 4,
        better: Better::Lower,
        group_by: vec![0],
    });
    Ok(table)
}

/// Failed runs and sequences, one line each.
fn errors(results: &KittiSuiteResults) -> Vec<String> {
    let mut lines = Vec::new();
    for s in &results.sequences {
        for r in &s.runs {
            if let Some(e) = &r.error {
                lines.push(format!("{:04} / {}: {e}", s.sequence, r.variant.name()));
            }
        }
        for (what, t) in [("tracker", &s.tracker), ("tracking peer", &s.tracking_peer)] {
            if let Some(e) = t.as_ref().and_then(|t| t.error.as_ref()) {
                lines.push(format!("{:04} / {what}: {e}", s.sequence));
            }
        }
        for peer in &s.ego_peers {
            if let Some(e) = &peer.error {
                lines.push(format!("{:04} / {}: {e}", s.sequence, peer.name));
            }
        }
    }
    lines
}

/// The report as sections.
///
/// # Errors
///
/// [`ReportError`] when a table cannot be built.
pub fn kitti_report(results: &KittiSuiteResults) -> Result<Report, ReportError> {
    let scanned: Vec<String> = results
        .sequences
        .iter()
        .filter(|s| s.has_scans)
        .map(|s| format!("{:04}", s.sequence))
        .collect();
    let intro = format!(
        "Real KITTI tracking data: `{}`, detections `{}`. Variants ran on the sequences \
         with scans ({}); the tracker alone ran on every sequence with detections, placed \
         with the OXTS ego poses. Ego truth: OXTS poses in the LiDAR frame \
         (`Tr_imu_velo`), 10 Hz frame times; tracks: `label_02`, class Car. The paper used \
         CenterPoint detections on every sequence; rows marked \"not run here\" are methods \
         we do not run. Metric definitions: `docs/metrics.md`.",
        results.training.display(),
        results
            .detections
            .as_ref()
            .map_or("none".to_string(), |d| d.display().to_string()),
        if scanned.is_empty() {
            "none".to_string()
        } else {
            scanned.join(", ")
        }
    );
    let mut sections = vec![
        Section {
            heading: "Ego pose (Table I)".into(),
            text: intro,
            tables: vec![ego_table(results)?],
            plots: Vec::new(),
        },
        Section {
            heading: "Tracking (Table II)".into(),
            text: String::new(),
            tables: vec![tracking_table(results)?, ab3dmot_table(results)?],
            plots: Vec::new(),
        },
        Section {
            heading: "Dynamic-feature filter".into(),
            text: "Real scans have no per-point labels: a feature is an object's when it \
                   lies in the object's label_02 box, and the object moves when its \
                   labelled centre does (docs/metrics.md). Labels cover the camera's view \
                   only, so removals beside and behind the car are judged by nothing and \
                   no precision is given."
                .into(),
            tables: vec![filter_table(results)?],
            plots: Vec::new(),
        },
        Section {
            heading: "Objects (Table III)".into(),
            text: "The paper's objects are the ten with the longest tracks over its \
                   sequences; for each sequence with scans we list the cars with the most \
                   labelled frames."
                .into(),
            tables: vec![object_table(results)?],
            plots: Vec::new(),
        },
    ];
    let errors = errors(results);
    if !errors.is_empty() {
        sections.push(Section {
            heading: "Failed runs".into(),
            text: errors
                .iter()
                .map(|e| format!("- {e}"))
                .collect::<Vec<_>>()
                .join("\n"),
            tables: Vec::new(),
            plots: Vec::new(),
        });
    }
    Ok(Report {
        title: "limot on real KITTI tracking data".into(),
        sections,
    })
}

/// Writes `report_dir/README.md`. Returns its path.
///
/// # Errors
/// An unwritable directory, a malformed table.
pub fn write_kitti_report(
    report_dir: &Path,
    results: &KittiSuiteResults,
) -> Result<PathBuf, ReportError> {
    write_report(report_dir, &kitti_report(results)?)
}
