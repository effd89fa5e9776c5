//! `limot eval tracks`: KITTI-format tracking results (label_02 lines with an
//! optional score column, one file for the dataset's single sequence) against
//! the ground-truth boxes of a limot dataset.
//!
//! Frames and conversions:
//! - result boxes are in KITTI's rectified camera frame; they go to the LiDAR
//!   frame with the dataset's calibration (`kitti/calib/NNNN.txt` when the
//!   KITTI-style copy exists, else the same synthetic calibration the copy
//!   would hold, [`crate::io::kitti::export::synthetic_calib`]);
//! - then to the world frame with the GROUND-TRUTH ego pose `t_world_lidar` at
//!   the frame's sweep start (the instant `gt/boxes.csv` boxes the objects).
//!   CLEAR-MOT and the per-object ATE are computed in the world frame, so the
//!   object ATE measures the tracker's object poses alone, not ego drift (a
//!   result file carries no ego estimate to map it with).
//!
//! Ground truth restriction ([`GtFilter`]): a KITTI-format result can only hold
//! boxes with a 2D box in the left colour image (the devkit evaluates in the
//! image), so by default the truth is restricted the way the KITTI-style copy
//! labels it (`kitti_export`): within 80 m of the LiDAR in the horizontal
//! plane, hit by at least one LiDAR point of the sweep unless its label is a
//! recording's annotation (a twin's box is truth where KITTI labelled it,
//! even where the twin's scene hides it), and with a 2D box in the image.
//! `GtFilter::All` scores against every ground-truth box. Either way only
//! labelled boxes are truth (`gt/boxes.csv`'s `labelled` column: a KITTI
//! twin's parked car is in the world for the whole drive, in the truth only
//! where KITTI labelled it).
//!
//! Metrics: class-agnostic and per-class CLEAR-MOT ([`crate::metrics::clear_mot`])
//! at 3D and BEV IoU ≥ 0.25 and 0.5; per-object TP % and ATE
//! ([`crate::metrics::object_scores`]) at 3D IoU ≥ 0.25 (the paper's threshold).

use super::json::{Json, obj};
use super::{EvaluateError, Result, dataset_frame_times};
use crate::io::kitti::calib::Calib;
use crate::io::kitti::detections::{camera_box_to_lidar, lidar_box_to_camera};
use crate::io::kitti::export::{is_label_candidate, synthetic_calib};
use crate::io::kitti::labels::TrackingLabel;
use crate::io::kitti::results::{ImageSize, image_box};
use crate::io::kitti::{LineCtx, content_lines, read_text, sequence_file};
use crate::metrics::IouKind;
use crate::metrics::pose_at;
use crate::metrics::{
    ClearMotConfig, ClearMotResult, MotFrame, PAPER_IOU_THRESHOLDS, TrackedBox, clear_mot,
    clear_mot_per_class,
};
use crate::metrics::{ObjectScore, object_scores};
use crate::report::{Cell, Table};
use limot_estimator::geometry::OrientedBox;
use limot_estimator::input::ObjectClass;
use limot_sim::record::{BoxTruth, Dataset, EgoTruth, instances_hit};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Which ground-truth boxes are scored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GtFilter {
    /// Every labelled box of `gt/boxes.csv`.
    All,
    /// The boxes the KITTI-style copy labels (see the module docs).
    #[default]
    CameraVisible,
}

impl std::str::FromStr for GtFilter {
    type Err = EvaluateError;
    fn from_str(s: &str) -> Result<GtFilter> {
        match s.to_ascii_lowercase().as_str() {
            "all" => Ok(GtFilter::All),
            "camera" | "camera-visible" => Ok(GtFilter::CameraVisible),
            _ => Err(EvaluateError::Argument(format!(
                "ground-truth filter `{s}`: expected camera or all"
            ))),
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
/// Options of `limot eval tracks`.
pub struct TrackEvalOptions {
    /// Which ground-truth boxes are scored.
    pub gt_filter: GtFilter,
    /// Sequence number of the calibration file in `DATASET/kitti/calib/`.
    pub sequence: u32,
    /// CLEAR-MOT IoU thresholds (each at 3D and BEV IoU).
    pub thresholds: Vec<f64>,
    /// 3D IoU threshold of the per-object TP % / ATE.
    pub object_threshold: f64,
}

impl Default for TrackEvalOptions {
    fn default() -> Self {
        TrackEvalOptions {
            gt_filter: GtFilter::CameraVisible,
            sequence: 0,
            thresholds: PAPER_IOU_THRESHOLDS.to_vec(),
            object_threshold: 0.25,
        }
    }
}

/// Result boxes of a file, per frame, in the LiDAR frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ResultBoxes {
    /// Per frame: `(track id, class, box)`.
    pub per_frame: Vec<Vec<(u64, ObjectClass, OrientedBox)>>,
    /// Result lines of types we do not track (Tram, Misc), skipped.
    pub skipped_types: usize,
    /// DontCare lines, skipped (results carry none normally).
    pub dont_care: usize,
}

/// Reads a KITTI tracking result file into LiDAR-frame boxes for a sequence
/// of `frame_count` frames. Errors name the file and line: a frame outside the
/// sequence, a negative track id on a real object, a track id twice in a frame.
///
/// # Errors
///
/// [`EvaluateError`] when the file cannot be read or a line is malformed.
pub fn read_results(path: &Path, frame_count: usize, calib: &Calib) -> Result<ResultBoxes> {
    let text = read_text(path)?;
    let mut out = ResultBoxes {
        per_frame: vec![Vec::new(); frame_count],
        ..ResultBoxes::default()
    };
    let mut seen: BTreeSet<(u32, i64)> = BTreeSet::new();
    for (line_no, line) in content_lines(&text) {
        let ctx = LineCtx::new(path, line_no);
        let label = TrackingLabel::parse_line(line, ctx)?;
        if label.is_dont_care() {
            out.dont_care += 1;
            continue;
        }
        let Some(class) = label.class() else {
            out.skipped_types += 1;
            continue;
        };
        if label.frame as usize >= frame_count {
            return Err(ctx
                .field_error(
                    1,
                    "frame",
                    format!(
                        "frame {} but the dataset has {frame_count} frames",
                        label.frame
                    ),
                )
                .into());
        }
        if label.track_id < 0 {
            return Err(ctx
                .field_error(
                    2,
                    "track_id",
                    format!("{} on a {} box", label.track_id, label.type_name),
                )
                .into());
        }
        if !seen.insert((label.frame, label.track_id)) {
            return Err(ctx
                .field_error(
                    2,
                    "track_id",
                    format!(
                        "track {} appears twice in frame {}",
                        label.track_id, label.frame
                    ),
                )
                .into());
        }
        let dims = label.cam_box.dims_hwl;
        if dims.iter().any(|&d| d < 0.0) {
            return Err(ctx
                .field_error(11, "h", format!("negative box size {dims:?}"))
                .into());
        }
        let lidar_box = camera_box_to_lidar(&label.cam_box, calib);
        out.per_frame[label.frame as usize].push((label.track_id as u64, class, lidar_box));
    }
    Ok(out)
}

/// `t_world_lidar` at `t_s` from the ground-truth samples (sorted by time):
/// linear in translation, slerp in rotation; exact at a sample.
///
/// # Errors
///
/// [`EvaluateError`] when the ego truth cannot be read or does not cover `t_s`.
pub fn ego_pose_at(truth: &[EgoTruth], t_s: f64, path: &Path) -> Result<Isometry3<f64>> {
    pose_at(truth, t_s, |e| (e.t_s, e.t_world_lidar)).ok_or_else(|| EvaluateError::Input {
        path: path.to_path_buf(),
        why: format!(
            "no ground-truth ego pose around t = {t_s} s (samples cover [{}, {}] s)",
            truth.first().map_or(f64::NAN, |e| e.t_s),
            truth.last().map_or(f64::NAN, |e| e.t_s)
        ),
    })
}

/// A LiDAR-frame box (yaw about LiDAR z) as a world box.
fn lidar_box_to_world(t_world_lidar: &Isometry3<f64>, b: &OrientedBox) -> OrientedBox {
    let t_lidar_box = Isometry3::from_parts(
        Translation3::from(b.center),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), b.yaw_rad),
    );
    OrientedBox::from_pose(&(t_world_lidar * t_lidar_box), b.size_lwh)
}

/// Whether the KITTI-style copy labels this box: a label candidate
/// ([`is_label_candidate`]) with a 2D box in the left colour image.
fn camera_visible(b: &BoxTruth, t_lidar_box: &Isometry3<f64>, hit: bool, calib: &Calib) -> bool {
    if !is_label_candidate(b, t_lidar_box, hit) {
        return false;
    }
    let r = t_lidar_box.rotation.to_rotation_matrix();
    let lidar_box = OrientedBox {
        center: t_lidar_box.translation.vector,
        size_lwh: b.size_lwh_m,
        yaw_rad: r[(1, 0)].atan2(r[(0, 0)]),
    };
    image_box(
        &lidar_box_to_camera(&lidar_box, calib),
        calib,
        ImageSize::KITTI_DEFAULT,
    )
    .is_some()
}

/// The dataset's calibration: the KITTI copy's file, else the synthetic one.
///
/// # Errors
///
/// [`EvaluateError`] when no calibration can be read.
pub fn dataset_calib(dataset: &Dataset, sequence: u32) -> Result<(Calib, String)> {
    let path = sequence_file(&dataset.dir.join("kitti").join("calib"), sequence);
    if path.is_file() {
        return Ok((Calib::read(&path)?, path.display().to_string()));
    }
    Ok((
        synthetic_calib(&dataset.meta.t_lidar_imu()),
        "synthetic KITTI-like calibration (no kitti/ copy)".to_string(),
    ))
}

/// The ground truth a result file is scored against (see the module docs),
/// frame by frame, with the true ego pose that places a LiDAR-frame box in
/// the truth's world frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ScoredTruth {
    /// Ground-truth boxes per frame (world frame, after [`GtFilter`]).
    pub gt: Vec<Vec<TrackedBox>>,
    /// True `t_world_lidar` at each frame's time.
    pub t_world_lidar: Vec<Isometry3<f64>>,
    /// The dataset's calibration.
    pub calib: Calib,
    /// Where the calibration came from.
    pub calib_source: String,
    /// Ground-truth boxes dropped by the filter.
    pub gt_filtered_out: usize,
}

impl ScoredTruth {
    /// A box of frame `frame`'s LiDAR frame (yaw about LiDAR z) in the
    /// truth's world frame. `frame` must be below the frame count.
    pub fn lidar_box_to_world(&self, frame: usize, b: &OrientedBox) -> OrientedBox {
        lidar_box_to_world(&self.t_world_lidar[frame], b)
    }

    /// Reads the ground truth of a dataset, filtered by `opts.gt_filter`.
    ///
    /// # Errors
    ///
    /// [`EvaluateError`] when the dataset cannot be read.
    pub fn read(dataset_dir: &Path, opts: &TrackEvalOptions) -> Result<ScoredTruth> {
        let dataset = Dataset::open(dataset_dir)?;
        let (calib, calib_source) = dataset_calib(&dataset, opts.sequence)?;
        let times = dataset_frame_times(&dataset)?;
        let mut ego = dataset.ego_truth()?;
        ego.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        let ego_path = dataset_dir.join("gt").join("ego.csv");
        let boxes = dataset.box_truth()?;
        let mut truth = ScoredTruth {
            gt: Vec::with_capacity(times.len()),
            t_world_lidar: Vec::with_capacity(times.len()),
            calib,
            calib_source,
            gt_filtered_out: 0,
        };
        for (index, t_s) in times.iter().enumerate() {
            let t_world_lidar = ego_pose_at(&ego, *t_s, &ego_path)?;
            let hit: BTreeSet<u32> = match opts.gt_filter {
                GtFilter::All => BTreeSet::new(),
                GtFilter::CameraVisible => instances_hit(&dataset.frame_labels(index)?),
            };
            let mut gt = Vec::new();
            // an unlabelled box is in the world, not in the tracking truth
            for b in boxes
                .get(index)
                .into_iter()
                .flatten()
                .filter(|b| b.labelled)
            {
                let keep = match opts.gt_filter {
                    GtFilter::All => true,
                    GtFilter::CameraVisible => camera_visible(
                        b,
                        &(t_world_lidar.inverse() * b.t_world_box),
                        hit.contains(&b.id),
                        &truth.calib,
                    ),
                };
                if keep {
                    gt.push(TrackedBox::from_box_truth(b));
                } else {
                    truth.gt_filtered_out += 1;
                }
            }
            truth.gt.push(gt);
            truth.t_world_lidar.push(t_world_lidar);
        }
        Ok(truth)
    }

    /// The CLEAR-MOT frames of a result file against this truth.
    ///
    /// # Errors
    ///
    /// [`EvaluateError`] when the results cannot be read.
    pub fn tracking_input(&self, results: &Path) -> Result<TrackingInput> {
        let result_boxes = read_results(results, self.gt.len(), &self.calib)?;
        let frames = self
            .gt
            .iter()
            .enumerate()
            .map(|(index, gt)| MotFrame {
                gt: gt.clone(),
                tracks: result_boxes.per_frame[index]
                    .iter()
                    .map(|(id, class, b)| TrackedBox {
                        id: *id,
                        class: *class,
                        bbox: self.lidar_box_to_world(index, b),
                    })
                    .collect(),
                dont_care: Vec::new(),
            })
            .collect();
        Ok(TrackingInput {
            frames,
            calib_source: self.calib_source.clone(),
            skipped_types: result_boxes.skipped_types,
            dont_care: result_boxes.dont_care,
            gt_filtered_out: self.gt_filtered_out,
        })
    }
}

/// The CLEAR-MOT frames (world frame) of a dataset and a result file.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackingInput {
    /// CLEAR-MOT frames.
    pub frames: Vec<MotFrame>,
    /// Where the calibration came from.
    pub calib_source: String,
    /// Result lines of types we do not track, skipped.
    pub skipped_types: usize,
    /// DontCare result lines, skipped.
    pub dont_care: usize,
    /// Ground-truth boxes dropped by the filter.
    pub gt_filtered_out: usize,
}

/// Builds the per-frame ground truth and tracks (see the module docs).
///
/// # Errors
///
/// [`EvaluateError`] when the dataset or the results cannot be read.
pub fn tracking_input(
    dataset_dir: &Path,
    results: &Path,
    opts: &TrackEvalOptions,
) -> Result<TrackingInput> {
    ScoredTruth::read(dataset_dir, opts)?.tracking_input(results)
}

/// CLEAR-MOT of one IoU kind and threshold, over all classes and per class.
#[derive(Debug, Clone, PartialEq)]
pub struct MotScore {
    /// 3D or BEV IoU.
    pub iou_kind: IouKind,
    /// The IoU threshold.
    pub iou_threshold: f64,
    /// Over all classes.
    pub all: ClearMotResult,
    /// Per ground-truth class.
    pub per_class: BTreeMap<ObjectClass, ClearMotResult>,
}

/// Everything `limot eval tracks` reports.
#[derive(Debug, Clone, PartialEq)]
pub struct TracksEvaluation {
    /// The dataset directory.
    pub dataset: PathBuf,
    /// The result file.
    pub results: PathBuf,
    /// Which ground-truth boxes were scored.
    pub gt_filter: GtFilter,
    /// Where the calibration came from.
    pub calib_source: String,
    /// Frames scored.
    pub frames: usize,
    /// Result lines of types we do not track, skipped.
    pub skipped_types: usize,
    /// Ground-truth boxes dropped by the filter.
    pub gt_filtered_out: usize,
    /// CLEAR-MOT per IoU kind and threshold.
    pub scores: Vec<MotScore>,
    /// 3D IoU threshold of the per-object scores.
    pub object_threshold: f64,
    /// Per-object TP % and ATE.
    pub objects: Vec<ObjectScore>,
    /// Ground-truth class of every scored object.
    pub object_classes: BTreeMap<u64, ObjectClass>,
}

/// Reads a dataset and a result file and scores the results.
///
/// # Errors
///
/// As [`tracking_input`]; [`EvaluateError::Eval`] when a metric fails.
pub fn evaluate_tracks(
    dataset_dir: &Path,
    results: &Path,
    opts: &TrackEvalOptions,
) -> Result<TracksEvaluation> {
    let input = tracking_input(dataset_dir, results, opts)?;
    let mut scores = Vec::new();
    for iou_kind in [IouKind::ThreeD, IouKind::Bev] {
        for &iou_threshold in &opts.thresholds {
            let cfg = ClearMotConfig {
                iou_threshold,
                iou_kind,
                ..ClearMotConfig::default()
            };
            scores.push(MotScore {
                iou_kind,
                iou_threshold,
                all: clear_mot(&input.frames, &cfg)?,
                per_class: clear_mot_per_class(&input.frames, &cfg)?,
            });
        }
    }
    let object_cfg = ClearMotConfig {
        iou_threshold: opts.object_threshold,
        iou_kind: IouKind::ThreeD,
        ..ClearMotConfig::default()
    };
    let objects = object_scores(&input.frames, &object_cfg)?;
    let object_classes = input
        .frames
        .iter()
        .flat_map(|f| f.gt.iter().map(|g| (g.id, g.class)))
        .collect();
    Ok(TracksEvaluation {
        dataset: dataset_dir.to_path_buf(),
        results: results.to_path_buf(),
        gt_filter: opts.gt_filter,
        calib_source: input.calib_source,
        frames: input.frames.len(),
        skipped_types: input.skipped_types,
        gt_filtered_out: input.gt_filtered_out,
        scores,
        object_threshold: opts.object_threshold,
        objects,
        object_classes,
    })
}

fn kind_name(kind: IouKind) -> &'static str {
    match kind {
        IouKind::ThreeD => "3D",
        IouKind::Bev => "BEV",
    }
}

fn pct(v: Option<f64>) -> Cell {
    v.map(|x| 100.0 * x).into()
}

fn mot_row(kind: IouKind, thr: f64, class: &str, r: &ClearMotResult) -> Vec<Cell> {
    vec![
        Cell::from(kind_name(kind)),
        Cell::Num(thr),
        Cell::from(class),
        pct(r.mota),
        pct(r.motp),
        r.id_switches.into(),
        r.false_positives.into(),
        r.false_negatives.into(),
        r.matches.into(),
        r.gt_count.into(),
    ]
}

fn mot_json(r: &ClearMotResult) -> Json {
    obj([
        ("mota", r.mota.into()),
        ("motp", r.motp.into()),
        ("id_switches", r.id_switches.into()),
        ("false_positives", r.false_positives.into()),
        ("false_negatives", r.false_negatives.into()),
        ("matches", r.matches.into()),
        ("fragmentations", r.fragmentations.into()),
        ("gt_count", r.gt_count.into()),
        ("track_count", r.track_count.into()),
        ("gt_objects", r.gt_objects.into()),
        ("mostly_tracked", r.mostly_tracked.into()),
        ("partially_tracked", r.partially_tracked.into()),
        ("mostly_lost", r.mostly_lost.into()),
    ])
}

impl TracksEvaluation {
    /// The class-agnostic result of one IoU kind and threshold.
    pub fn score(&self, kind: IouKind, threshold: f64) -> Option<&ClearMotResult> {
        self.scores
            .iter()
            .find(|s| s.iou_kind == kind && s.iou_threshold == threshold)
            .map(|s| &s.all)
    }

    /// One line per IoU kind and threshold: `MOTA … % MOTP … % (3D IoU ≥ 0.5) …`.
    pub fn summary_lines(&self) -> Vec<String> {
        self.scores
            .iter()
            .map(|s| {
                let r = &s.all;
                format!(
                    "{} IoU >= {}: MOTA {:.2} %, MOTP {:.2} %, IDSW {}, FP {}, FN {} ({} matches of {} ground-truth boxes)",
                    kind_name(s.iou_kind),
                    s.iou_threshold,
                    r.mota.map_or(f64::NAN, |m| 100.0 * m),
                    r.motp.map_or(f64::NAN, |m| 100.0 * m),
                    r.id_switches,
                    r.false_positives,
                    r.false_negatives,
                    r.matches,
                    r.gt_count
                )
            })
            .collect()
    }

    /// IoU | thr | class | MOTA [%] | MOTP [%] | IDSW | FP | FN | TP | GT.
    ///
    /// # Errors
    ///
    /// [`EvaluateError::Report`] when the table cannot be built.
    pub fn clear_mot_table(&self) -> Result<Table> {
        let header = [
            "IoU", "thr", "Class", "MOTA [%]", "MOTP [%]", "IDSW", "FP", "FN", "TP", "GT",
        ]
        .map(String::from)
        .to_vec();
        let mut table = Table::new("CLEAR-MOT (world frame)", header);
        table.set_decimals(1, 2);
        table.set_decimals(3, 2);
        table.set_decimals(4, 2);
        for s in &self.scores {
            table.push_row(mot_row(s.iou_kind, s.iou_threshold, "all", &s.all))?;
            if s.per_class.len() > 1 {
                for (class, r) in &s.per_class {
                    table.push_row(mot_row(s.iou_kind, s.iou_threshold, class.name(), r))?;
                }
            }
        }
        Ok(table)
    }

    /// Obj | Class | GT frames | TP [%] | Track | ATE_T \[m\] | ATE_R \[rad\].
    ///
    /// # Errors
    ///
    /// [`EvaluateError::Report`] when the table cannot be built.
    pub fn object_table(&self) -> Result<Table> {
        let header = [
            "Obj",
            "Class",
            "GT frames",
            "TP [%]",
            "Track",
            "ATE_T [m]",
            "ATE_R [rad]",
        ]
        .map(String::from)
        .to_vec();
        let mut table = Table::new(
            format!(
                "Per object (3D IoU >= {}, world frame, ground-truth ego poses)",
                self.object_threshold
            ),
            header,
        );
        table.set_decimals(3, 2);
        for o in &self.objects {
            let class = self.object_classes.get(&o.gt_id).map_or("?", |c| c.name());
            table.push_row(vec![
                Cell::Int(i64::try_from(o.gt_id).unwrap_or(i64::MAX)),
                Cell::from(class),
                o.gt_frames.into(),
                Cell::Num(o.tp_percent),
                o.track_id.map_or(Cell::Missing, |t| {
                    Cell::Int(i64::try_from(t).unwrap_or(i64::MAX))
                }),
                o.ate_t_rmse_m.into(),
                o.ate_r_rmse_rad.into(),
            ])?;
        }
        Ok(table)
    }

    /// The evaluation as markdown tables.
    ///
    /// # Errors
    ///
    /// [`EvaluateError::Report`] when a table cannot be built.
    pub fn to_markdown(&self) -> Result<String> {
        let filter = match self.gt_filter {
            GtFilter::All => "all ground-truth boxes",
            GtFilter::CameraVisible => {
                "camera-visible ground truth (as the KITTI-style copy labels it: <= 80 m, \
                 hit by LiDAR unless annotated, 2D box in the left image)"
            }
        };
        let mut out = format!(
            "# limot eval tracks\n\n- dataset: `{}`\n- results: `{}`\n- calibration: {}\n\
             - ground truth: {filter}; {} boxes filtered out\n- frames: {}\n",
            self.dataset.display(),
            self.results.display(),
            self.calib_source,
            self.gt_filtered_out,
            self.frames
        );
        if self.skipped_types > 0 {
            out.push_str(&format!(
                "- {} result lines of untracked types (Tram, Misc) skipped\n",
                self.skipped_types
            ));
        }
        out.push('\n');
        for line in self.summary_lines() {
            out.push_str(&format!("- {line}\n"));
        }
        out.push('\n');
        out.push_str(&self.clear_mot_table()?.to_markdown()?);
        out.push('\n');
        out.push_str(&self.object_table()?.to_markdown()?);
        Ok(out)
    }

    /// The evaluation as a JSON summary.
    pub fn to_json(&self) -> Json {
        let scores = self
            .scores
            .iter()
            .map(|s| {
                let per_class = s
                    .per_class
                    .iter()
                    .map(|(c, r)| (c.name().to_string(), mot_json(r)))
                    .collect();
                obj([
                    ("iou", kind_name(s.iou_kind).into()),
                    ("threshold", s.iou_threshold.into()),
                    ("all", mot_json(&s.all)),
                    ("per_class", Json::Obj(per_class)),
                ])
            })
            .collect();
        let objects = self
            .objects
            .iter()
            .map(|o| {
                obj([
                    ("id", o.gt_id.into()),
                    (
                        "class",
                        self.object_classes
                            .get(&o.gt_id)
                            .map_or(Json::Null, |c| c.name().into()),
                    ),
                    ("gt_frames", o.gt_frames.into()),
                    ("tracked_frames", o.tracked_frames.into()),
                    ("tp_percent", o.tp_percent.into()),
                    ("track_id", o.track_id.map_or(Json::Null, Json::from)),
                    ("ate_frames", o.ate_frames.into()),
                    ("ate_t_rmse_m", o.ate_t_rmse_m.into()),
                    ("ate_r_rmse_rad", o.ate_r_rmse_rad.into()),
                ])
            })
            .collect();
        obj([
            ("dataset", self.dataset.display().to_string().into()),
            ("results", self.results.display().to_string().into()),
            (
                "gt_filter",
                match self.gt_filter {
                    GtFilter::All => "all",
                    GtFilter::CameraVisible => "camera",
                }
                .into(),
            ),
            ("calibration", self.calib_source.clone().into()),
            ("frames", self.frames.into()),
            ("gt_filtered_out", self.gt_filtered_out.into()),
            ("skipped_result_lines", self.skipped_types.into()),
            ("clear_mot", Json::Arr(scores)),
            ("object_threshold", self.object_threshold.into()),
            ("objects", Json::Arr(objects)),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t_s: f64, x: f64, yaw: f64) -> EgoTruth {
        EgoTruth {
            t_s,
            t_world_lidar: Isometry3::new(Vector3::new(x, 0.0, 0.0), Vector3::new(0.0, 0.0, yaw)),
            velocity_world_mps: Vector3::zeros(),
        }
    }

    #[test]
    fn ego_interpolation_is_exact_at_samples_and_linear_between() {
        let truth = vec![sample(0.0, 0.0, 0.0), sample(1.0, 2.0, 0.4)];
        let p = Path::new("ego.csv");
        let mid = ego_pose_at(&truth, 0.25, p).unwrap();
        assert!((mid.translation.vector.x - 0.5).abs() < 1e-12);
        assert!((mid.rotation.angle() - 0.1).abs() < 1e-12);
        assert_eq!(ego_pose_at(&truth, 1.0, p).unwrap(), truth[1].t_world_lidar);
        let err = ego_pose_at(&truth, 1.5, p).unwrap_err().to_string();
        assert!(err.contains("ego.csv") && err.contains("1.5"), "{err}");
    }

    #[test]
    fn lidar_box_maps_to_world_with_the_ego_pose() {
        let t_world_lidar =
            Isometry3::new(Vector3::new(10.0, 5.0, 1.0), Vector3::new(0.0, 0.0, 0.5));
        let b = OrientedBox {
            center: Vector3::new(3.0, 0.0, 0.0),
            size_lwh: Vector3::new(4.0, 2.0, 1.5),
            yaw_rad: 0.2,
        };
        let w = lidar_box_to_world(&t_world_lidar, &b);
        let expected = Vector3::new(10.0 + 3.0 * 0.5f64.cos(), 5.0 + 3.0 * 0.5f64.sin(), 1.0);
        assert!((w.center - expected).norm() < 1e-12);
        assert!((w.yaw_rad - 0.7).abs() < 1e-12);
        assert_eq!(w.size_lwh, b.size_lwh);
    }
}
