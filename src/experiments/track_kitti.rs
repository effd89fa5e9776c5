//! The tracker alone on real KITTI tracking data.
//!
//! Per sequence: AB3DMOT's PointRCNN detection CSV → LiDAR-frame boxes (via
//! the sequence's calibration) → world frame with the OXTS ego pose of the
//! LiDAR at that frame → [`Tracker::update`] at `t = frame / 10 s` → the
//! confirmed tracks back into the LiDAR and camera frames → KITTI tracking
//! result lines (with the 2D box of the 3D box projected through P2).
//!
//! Frames: the devkit's OXTS poses are `T_world_imu` (world = first IMU frame);
//! calib's `Tr_imu_velo` is `T_velo_imu`, so the LiDAR pose is
//! `T_world_lidar = T_world_imu · T_velo_imu⁻¹`.
//!
//! Evaluation: [`evaluate_sequences`] (our tracks) and [`score_results`] (any
//! result files, e.g. AB3DMOT's) score every sequence of a seqmap against
//! `label_02` for class Car, with TrackEval's KITTI 2D box benchmark (image
//! IoU ≥ 0.5, [`kitti_2d_clear_mot`]), with a 3D CLEAR-MOT
//! ([`kitti_3d_clear_mot`]: TrackEval's KITTI preprocessing on the image
//! boxes, then 3D IoU ≥ 0.25) and with AB3DMOT's own evaluate.py
//! ([`ab3dmot_evaluate`]: sAMOTA, AMOTA, MOTA at the best score threshold).
//! Result lines carry the detector's raw score (a logit for PointRCNN).
//!
//! The tracker is online; [`ResultPolicy::offline_track_score`]
//! optionally adds AB3DMOT's offline post-processing (whole tracks removed
//! by their mean score over the sequence), which AB3DMOT's thresholded
//! output, the peer of docs/tracking-kitti.md, has been through.

use crate::io::kitti::calib::Calib;
use crate::io::kitti::detections::{ScoreMap, detections_by_frame, read_ab3dmot_csv};
use crate::io::kitti::labels::{TrackingLabel, read_labels};
use crate::io::kitti::oxts::{oxts_to_poses, read_oxts};
use crate::io::kitti::results::{ImageSize, TrackBox, track_to_label};
use crate::io::kitti::seqmap::SeqmapEntry;
use crate::io::kitti::{KITTI_FRAME_PERIOD_S, KittiError, sequence_file};
use crate::metrics::EvalError;
use crate::metrics::{Ab3dmotEvalConfig, Ab3dmotResult, Ab3dmotSequence, ab3dmot_evaluate};
use crate::metrics::{ClearMotResult, combine_sequences};
use crate::metrics::{KittiEvalClass, kitti_2d_clear_mot, kitti_3d_clear_mot};
use limot_estimator::geometry::{OrientedBox, wrap_angle_rad};
use limot_estimator::input::Detection;
use limot_estimator::tracking::{
    Extrapolation, HeadingRule, Lifecycle, TrackOutput, Tracker, TrackerConfig, TrackerError,
    WorldDetection,
};
use nalgebra::{Isometry3, Vector3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Tracker settings for KITTI with PointRCNN detections (the paper's
/// defaults otherwise), chosen by two-fold cross-validation over the val
/// split (see docs/tracking-kitti.md and `cross_validate_kitti_settings` in
/// tests/kitti_tracking.rs):
/// - `min_score` 0.6 (sigmoid of the PointRCNN logit, i.e. logit > 0.41):
///   most false detections start no track;
/// - `init_frames` 3 (AB3DMOT's `min_hits`) instead of the paper's 5;
/// - `max_misses` 2: shorter coasting cuts wrong re-associations;
/// - `d_thres_m` 3: the cubic prediction of a car seen again after a miss
///   can be more than 2 m off;
/// - heading from motion or the majority of detections (not tuned: a box
///   turned by π is the same box, so no overlap score changes; it turns
///   parked cars whose first PointRCNN box faced backwards).
pub fn kitti_val_tuned_config() -> TrackerConfig {
    TrackerConfig {
        min_score: 0.6,
        init_frames: 3,
        max_misses: 2,
        d_thres_m: 3.0,
        heading_rule: HeadingRule::MotionOrMajority,
        ..TrackerConfig::default()
    }
}

/// The KITTI output settings that go with [`kitti_val_tuned_config`]:
/// matched tentative tracks written in the first 3 frames (AB3DMOT's start-up
/// rule) and tracks written once the mean raw score (logit) of their matched
/// detections reaches 1.5.
pub fn kitti_val_tuned_options() -> TrackKittiOptions {
    TrackKittiOptions {
        tracker: kitti_val_tuned_config(),
        result: ResultPolicy {
            startup_frames: 3,
            min_track_score: 1.5,
            ..ResultPolicy::default()
        },
        ..TrackKittiOptions::default()
    }
}

/// The KITTI settings with AB3DMOT's offline post-processing allowed,
/// chosen by the same cross-validation among online and offline settings:
/// every detection used (`min_score` 0, as AB3DMOT does), confirmation
/// after 2 hits, constant-velocity extrapolation, lost tracks revivable for
/// 2 frames, coasting boxes written for 1 frame, and whole tracks whose mean
/// logit over the sequence is below 3 removed afterwards
/// (`offline_track_score`; AB3DMOT's own threshold is 3.24). Not causal:
/// use [`kitti_val_tuned_options`] for an online tracker.
pub fn kitti_val_offline_options() -> TrackKittiOptions {
    let mut o = kitti_val_tuned_options();
    o.tracker.min_score = 0.0;
    o.tracker.init_frames = 2;
    o.tracker.extrapolation = Extrapolation::ConstantVelocity;
    o.tracker.revive_frames = 2;
    o.result.output = OutputPolicy::CoastingUpTo(1);
    o.result.min_track_score = f64::NEG_INFINITY;
    o.result.offline_track_score = 3.0;
    o
}

/// Errors of the KITTI tracking run and its evaluation.
#[derive(Debug, thiserror::Error)]
pub enum TrackKittiError {
    #[error(transparent)]
    /// A KITTI file could not be read.
    Kitti(#[from] KittiError),
    #[error("sequence {sequence:04}: tracker: {source}")]
    /// The tracker rejected its input.
    Tracker {
        /// Sequence number.
        sequence: u32,
        #[source]
        /// The cause.
        source: TrackerError,
    },
    #[error("sequence {sequence:04}: evaluation: {source}")]
    /// A metric could not be computed.
    Eval {
        /// Sequence number.
        sequence: u32,
        #[source]
        /// The cause.
        source: EvalError,
    },
    #[error("{}: {why}", path.display())]
    /// An input is missing or malformed.
    Input {
        /// The input.
        path: PathBuf,
        /// What is wrong with it.
        why: String,
    },
}

pub type Result<T> = std::result::Result<T, TrackKittiError>;

/// Which tracks are written at a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OutputPolicy {
    /// Confirmed tracks that were matched to a detection this frame (what
    /// AB3DMOT writes: it outputs only associated confirmed tracks).
    #[default]
    MatchedConfirmed,
    /// Every confirmed track, including those coasting on their prediction.
    AllConfirmed,
    /// Confirmed tracks matched this frame or coasting for at most this many
    /// frames (AB3DMOT writes a track for one frame after a miss).
    CoastingUpTo(usize),
}

impl OutputPolicy {
    /// Whether a confirmed track that has missed `misses` frames in a row is written.
    pub fn writes(self, misses: usize) -> bool {
        match self {
            OutputPolicy::MatchedConfirmed => misses == 0,
            OutputPolicy::AllConfirmed => true,
            OutputPolicy::CoastingUpTo(n) => misses <= n,
        }
    }
}

/// Which box a written track carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BoxSource {
    /// The tracker's state: fitted (smoothed) centre and yaw, mean size.
    #[default]
    Fitted,
    /// The matched detection's centre and yaw (the fitted box when coasting),
    /// with the track's mean size.
    Detection,
}

/// Which of a tracker's boxes become KITTI result lines, per frame and
/// over the sequence (AB3DMOT's conventions). The tracker alone
/// ([`track_sequence_with`]) and the estimator's runs on KITTI
/// (`run::kitti_track_labels`) both write through a [`ResultWriter`] with it,
/// so their result files compare like with like.
#[derive(Debug, Clone, PartialEq)]
pub struct ResultPolicy {
    /// Which tracks are written each frame.
    pub output: OutputPolicy,
    /// During the first `startup_frames` frames of a sequence, tentative
    /// tracks matched this frame are written too: the objects in view when
    /// the sequence starts were not just born (AB3DMOT's `frame_count <=
    /// min_hits` rule). 0 = off.
    pub startup_frames: u32,
    /// A track is written only while the mean raw detector score (the CSV's
    /// score: a logit for PointRCNN) of its matched detections so far is at
    /// least this: weak detections may extend a track without starting a
    /// written one (AB3DMOT gates whole tracks on this mean afterwards).
    /// `-inf` = off.
    pub min_track_score: f64,
    /// A coasting track is written (see [`OutputPolicy`]) only once it has
    /// been matched this many times in all.
    pub coast_min_hits: usize,
    /// Offline post-processing (AB3DMOT's `trk_conf_threshold`, which its
    /// thresholded output has been through): after the whole sequence, every
    /// box of a track whose mean raw score over all its matched detections
    /// (future ones included) is below this is removed. Not causal; `-inf`
    /// = off (the online tracker's output).
    pub offline_track_score: f64,
}

impl Default for ResultPolicy {
    /// Confirmed tracks matched this frame, no score gates.
    fn default() -> Self {
        ResultPolicy {
            output: OutputPolicy::default(),
            startup_frames: 0,
            min_track_score: f64::NEG_INFINITY,
            coast_min_hits: 0,
            offline_track_score: f64::NEG_INFINITY,
        }
    }
}

/// A [`ResultPolicy`] applied to one sequence, frame after frame: it keeps
/// each track's matches and scores so far (track ids are never reused
/// within a sequence).
#[derive(Debug, Clone)]
pub struct ResultWriter {
    policy: ResultPolicy,
    tracks: HashMap<u64, TrackRecord>,
}

/// What a [`ResultWriter`] knows of one track.
#[derive(Debug, Clone, Copy, Default)]
struct TrackRecord {
    /// Raw score of the latest matched detection (coasting boxes keep it).
    last_score: Option<f64>,
    /// Sum and count of the raw scores of every matched detection so far.
    score_sum: f64,
    hits: usize,
    /// Frames in a row the track was output without a match.
    misses: usize,
}

impl ResultWriter {
    /// A writer with no track seen yet.
    pub fn new(policy: ResultPolicy) -> Self {
        ResultWriter {
            policy,
            tracks: HashMap::new(),
        }
    }

    /// Records one track output of frame `frame` (`raw_score`: the raw score
    /// of the detection it matched this frame, `None` when coasting) and
    /// says whether it is written, with the raw score its line carries.
    /// Call it for every output of a frame, frames in order.
    pub fn record(
        &mut self,
        frame: u32,
        output: &TrackOutput,
        raw_score: Option<f64>,
    ) -> Option<f64> {
        let r = self.tracks.entry(output.id).or_default();
        match raw_score {
            Some(score) => {
                r.last_score = Some(score);
                r.score_sum += score;
                r.hits += 1;
                r.misses = 0;
            }
            None => r.misses += 1,
        }
        let policy = &self.policy;
        let coasting_written = r.misses == 0 || r.hits >= policy.coast_min_hits;
        let startup = frame < policy.startup_frames && !output.predicted;
        let mean_score = if r.hits == 0 {
            f64::NEG_INFINITY
        } else {
            r.score_sum / r.hits as f64
        };
        let write = ((output.lifecycle == Lifecycle::Confirmed
            && coasting_written
            && policy.output.writes(r.misses))
            || startup)
            && (policy.min_track_score == f64::NEG_INFINITY
                || mean_score >= policy.min_track_score);
        write.then(|| r.last_score.unwrap_or(1.0))
    }

    /// Whether the offline gate keeps track `id` (always, when it is off):
    /// call after the last frame.
    pub fn keeps(&self, id: u64) -> bool {
        self.policy.offline_track_score == f64::NEG_INFINITY
            || self.tracks.get(&id).is_some_and(|r| {
                r.hits > 0 && r.score_sum / r.hits as f64 >= self.policy.offline_track_score
            })
    }
}

/// Options of [`track_sequence_with`].
#[derive(Debug, Clone, PartialEq)]
pub struct TrackKittiOptions {
    /// The tracker's settings.
    pub tracker: TrackerConfig,
    /// Which tracks become result lines.
    pub result: ResultPolicy,
    /// Which box a written track carries.
    pub box_source: BoxSource,
    /// How the CSV's raw detector score becomes a [0, 1] score (the tracker's
    /// `min_score` applies to the mapped score). PointRCNN scores are logits.
    pub score_map: ScoreMap,
    /// Image size, for the 2D boxes.
    pub image: ImageSize,
}

impl Default for TrackKittiOptions {
    fn default() -> Self {
        TrackKittiOptions {
            tracker: TrackerConfig::default(),
            result: ResultPolicy::default(),
            box_source: BoxSource::default(),
            score_map: ScoreMap::Sigmoid,
            image: ImageSize::KITTI_DEFAULT,
        }
    }
}

/// The tracker's output of one sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceTracks {
    /// Sequence number.
    pub sequence: u32,
    /// Written tracks per frame (LiDAR frame, the raw score of the latest
    /// matched detection), `frames` entries.
    pub per_frame: Vec<Vec<TrackBox>>,
    /// KITTI result lines of the tracks with a 2D box in the image.
    pub labels: Vec<TrackingLabel>,
    /// Tracks dropped for having no 2D box (behind the camera or off-image).
    pub outside_image: usize,
    /// Detections the tracker skipped as garbage / below `min_score`.
    pub garbage_detections: u64,
    /// Detections below the tracker's `min_score`.
    pub low_score_detections: u64,
}

/// `T_world_lidar` of every frame from the OXTS poses and the calibration.
pub fn lidar_poses(oxts_poses: &[Isometry3<f64>], calib: &Calib) -> Vec<Isometry3<f64>> {
    let t_imu_velo = calib.t_velo_imu.inverse();
    oxts_poses
        .iter()
        .map(|t_world_imu| t_world_imu * t_imu_velo)
        .collect()
}

/// A LiDAR-frame detection in the world frame.
pub fn detection_to_world(det: &Detection, t_world_lidar: &Isometry3<f64>) -> WorldDetection {
    let box_world = det.box_lidar.transformed(t_world_lidar);
    WorldDetection {
        box_world,
        class: det.class,
        score: det.score,
        // Placed with the frame's pose (OXTS at the frame time, when the
        // camera the labels come from fired): it joins the track at the
        // frame time, whatever part of the sweep saw it.
        time_offset_s: 0.0,
    }
}

/// A world-frame box back in the LiDAR frame (yaw wrapped to (-π, π]).
pub fn world_box_to_lidar(
    center_world: &Vector3<f64>,
    size_lwh: &Vector3<f64>,
    yaw_world_rad: f64,
    t_world_lidar: &Isometry3<f64>,
) -> OrientedBox {
    let box_world = OrientedBox::new(*center_world, *size_lwh, yaw_world_rad);
    let mut box_lidar = box_world.transformed(&t_world_lidar.inverse());
    box_lidar.yaw_rad = wrap_angle_rad(box_lidar.yaw_rad);
    box_lidar
}

/// Runs the tracker over one sequence with default options apart from the
/// tracker configuration.
///
/// # Errors
///
/// [`TrackKittiError`] when an input cannot be read or the tracker rejects a detection.
pub fn track_sequence(
    training_dir: &Path,
    detections_dir: &Path,
    sequence: u32,
    config: &TrackerConfig,
) -> Result<SequenceTracks> {
    let options = TrackKittiOptions {
        tracker: config.clone(),
        ..TrackKittiOptions::default()
    };
    track_sequence_with(training_dir, detections_dir, sequence, &options)
}

/// Runs the tracker over one sequence: `training_dir/{calib,oxts}/NNNN.txt`
/// and `detections_dir/NNNN.txt` (AB3DMOT CSV). The sequence has as many
/// frames as OXTS records; a detection of a later frame is an error.
///
/// # Errors
///
/// [`TrackKittiError`] when an input cannot be read or the tracker rejects a detection.
pub fn track_sequence_with(
    training_dir: &Path,
    detections_dir: &Path,
    sequence: u32,
    options: &TrackKittiOptions,
) -> Result<SequenceTracks> {
    let calib = Calib::read(&sequence_file(&training_dir.join("calib"), sequence))?;
    let oxts_path = sequence_file(&training_dir.join("oxts"), sequence);
    let oxts = read_oxts(&oxts_path)?;
    if oxts.is_empty() {
        return Err(TrackKittiError::Input {
            path: oxts_path,
            why: "no OXTS records".to_string(),
        });
    }
    let t_world_lidar = lidar_poses(&oxts_to_poses(&oxts), &calib);
    let det_path = sequence_file(detections_dir, sequence);
    let camera_dets = read_ab3dmot_csv(&det_path)?;
    if let Some(late) = camera_dets.iter().find(|d| d.frame as usize >= oxts.len()) {
        return Err(TrackKittiError::Input {
            path: det_path,
            why: format!(
                "detection at frame {} but the sequence has {} OXTS frames",
                late.frame,
                oxts.len()
            ),
        });
    }
    let frames = detections_by_frame(&camera_dets, &calib, options.score_map, oxts.len());

    let tracker_error = |source| TrackKittiError::Tracker { sequence, source };
    let mut tracker = Tracker::new(options.tracker.clone()).map_err(tracker_error)?;
    let mut writer = ResultWriter::new(options.result.clone());
    let mut out = SequenceTracks {
        sequence,
        per_frame: Vec::with_capacity(frames.len()),
        labels: Vec::new(),
        outside_image: 0,
        garbage_detections: 0,
        low_score_detections: 0,
    };
    for (frame, (dets, pose)) in frames.iter().zip(&t_world_lidar).enumerate() {
        let world: Vec<WorldDetection> = dets.iter().map(|d| detection_to_world(d, pose)).collect();
        let t_s = frame as f64 * KITTI_FRAME_PERIOD_S;
        let outputs = tracker.update(t_s, &world).map_err(tracker_error)?;
        let mut written = Vec::new();
        for o in &outputs {
            let matched_det = if o.predicted {
                None
            } else {
                matched_detection(&tracker, o, &world)
            };
            let raw_score = matched_det.map(|d| options.score_map.invert(d.score));
            let Some(score) = writer.record(frame as u32, o, raw_score) else {
                continue;
            };
            let (center_world, yaw_world) = match (options.box_source, matched_det) {
                (BoxSource::Detection, Some(d)) => (d.box_world.center, d.box_world.yaw_rad),
                _ => (o.center_world, o.yaw_rad),
            };
            let track_id = u32::try_from(o.id).map_err(|_| TrackKittiError::Input {
                path: det_path.clone(),
                why: format!("track id {} does not fit a KITTI result line", o.id),
            })?;
            written.push(TrackBox {
                frame: frame as u32,
                track_id,
                class: o.class,
                lidar_box: world_box_to_lidar(&center_world, &o.size_lwh, yaw_world, pose),
                score,
            });
        }
        out.per_frame.push(written);
    }
    // The offline gate needs the whole sequence; the labels follow it.
    for boxes in &mut out.per_frame {
        boxes.retain(|b| writer.keeps(u64::from(b.track_id)));
        for tb in boxes.iter() {
            match track_to_label(tb, &calib, options.image) {
                // The detector's own scale: a sigmoid saturates to 1.0 for
                // confident detections, which ties the track scores that
                // AB3DMOT's evaluation ranks.
                Some(mut label) => {
                    label.score = Some(tb.score);
                    out.labels.push(label)
                }
                None => out.outside_image += 1,
            }
        }
    }
    out.garbage_detections = tracker.garbage_detections();
    out.low_score_detections = tracker.low_score_detections();
    Ok(out)
}

/// The detection a track was matched to this frame: the tracker stores the
/// matched detection's centre unchanged as the track's latest measured box.
fn matched_detection<'a>(
    tracker: &Tracker,
    output: &TrackOutput,
    detections: &'a [WorldDetection],
) -> Option<&'a WorldDetection> {
    let track = tracker.tracks().iter().find(|t| t.id() == output.id)?;
    let last = track.last_box().center_world;
    detections
        .iter()
        .find(|d| d.class == output.class && d.box_world.center == last)
}

/// Scores of one sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceScores {
    /// Sequence number.
    pub sequence: u32,
    /// TrackEval KITTI 2D box benchmark (image IoU ≥ 0.5).
    pub image_iou_50: ClearMotResult,
    /// AB3DMOT-style 3D evaluation at 3D IoU ≥ 0.25.
    pub iou3d_25: ClearMotResult,
}

/// Scores of every sequence and their combination (counts summed, MOTA and
/// MOTP recomputed, as the devkit and TrackEval combine sequences).
#[derive(Debug, Clone, PartialEq)]
pub struct TrackingEvaluation {
    /// One entry per sequence.
    pub per_sequence: Vec<SequenceScores>,
    /// All sequences combined, image IoU ≥ 0.5.
    pub total_image_iou_50: ClearMotResult,
    /// All sequences combined, 3D IoU ≥ 0.25.
    pub total_iou3d_25: ClearMotResult,
    /// AB3DMOT's own evaluate.py over all sequences together (3D IoU ≥ 0.25):
    /// sAMOTA, AMOTA, AMOTP and MOTA/MOTP at the best track-score threshold.
    pub ab3dmot_3d: Ab3dmotResult,
}

/// One sequence's KITTI result rows, e.g. from [`track_sequence_with`] or a
/// result file.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceResults {
    /// Sequence number.
    pub sequence: u32,
    /// Result rows.
    pub labels: Vec<TrackingLabel>,
}

/// Tracks every sequence of `seqmap` and scores it against
/// `training_dir/label_02` for class Car. Returns the tracks too (for writing).
///
/// # Errors
///
/// [`TrackKittiError`] when a sequence cannot be read, tracked or scored.
pub fn evaluate_sequences(
    training_dir: &Path,
    detections_dir: &Path,
    seqmap: &[SeqmapEntry],
    options: &TrackKittiOptions,
) -> Result<(Vec<SequenceTracks>, TrackingEvaluation)> {
    let all_tracks = seqmap
        .iter()
        .map(|e| track_sequence_with(training_dir, detections_dir, e.sequence, options))
        .collect::<Result<Vec<_>>>()?;
    let results: Vec<SequenceResults> = all_tracks
        .iter()
        .map(|t| SequenceResults {
            sequence: t.sequence,
            labels: t.labels.clone(),
        })
        .collect();
    let evaluation = score_results(training_dir, seqmap, &results)?;
    Ok((all_tracks, evaluation))
}

/// Reads `results_dir/NNNN.txt` (KITTI tracking result format) of every
/// sequence of `seqmap`.
///
/// # Errors
///
/// [`TrackKittiError`] when a result file is missing or malformed.
pub fn read_results_dir(
    results_dir: &Path,
    seqmap: &[SeqmapEntry],
) -> Result<Vec<SequenceResults>> {
    seqmap
        .iter()
        .map(|e| {
            Ok(SequenceResults {
                sequence: e.sequence,
                labels: read_labels(&sequence_file(results_dir, e.sequence))?,
            })
        })
        .collect()
}

/// Scores result rows (one entry per `seqmap` entry, same order) against
/// `training_dir/label_02` for class Car: the TrackEval 2D benchmark, the 3D
/// CLEAR-MOT at IoU 0.25 and AB3DMOT's evaluate.py (see [`ab3dmot_evaluate`]).
///
/// # Errors
///
/// [`TrackKittiError`] when labels cannot be read or a sequence cannot be scored.
pub fn score_results(
    training_dir: &Path,
    seqmap: &[SeqmapEntry],
    results: &[SequenceResults],
) -> Result<TrackingEvaluation> {
    if results.len() != seqmap.len()
        || results
            .iter()
            .zip(seqmap)
            .any(|(r, e)| r.sequence != e.sequence)
    {
        return Err(TrackKittiError::Input {
            path: training_dir.to_path_buf(),
            why: "results do not follow the seqmap's sequences".to_string(),
        });
    }
    let mut per_sequence = Vec::with_capacity(seqmap.len());
    let mut gts = Vec::with_capacity(seqmap.len());
    let mut kept = Vec::with_capacity(seqmap.len());
    for (entry, seq_results) in seqmap.iter().zip(results) {
        let sequence = entry.sequence;
        let gt = read_labels(&sequence_file(&training_dir.join("label_02"), sequence))?;
        let calib = Calib::read(&sequence_file(&training_dir.join("calib"), sequence))?;
        let eval_error = |source| TrackKittiError::Eval { sequence, source };
        // The seqmap's frame count bounds the evaluation (the devkit's rule).
        let num_frames = entry.end_frame;
        let results: Vec<TrackingLabel> = seq_results
            .labels
            .iter()
            .filter(|l| l.frame < num_frames)
            .cloned()
            .collect();
        let image_iou_50 = kitti_2d_clear_mot(&gt, &results, num_frames, KittiEvalClass::Car)
            .map_err(eval_error)?;
        let iou3d_25 =
            kitti_3d_clear_mot(&gt, &results, num_frames, KittiEvalClass::Car, &calib, 0.25)
                .map_err(eval_error)?;
        per_sequence.push(SequenceScores {
            sequence,
            image_iou_50,
            iou3d_25,
        });
        gts.push((gt, entry.end_frame));
        kept.push(results);
    }
    let sequences: Vec<Ab3dmotSequence<'_>> = gts
        .iter()
        .zip(&kept)
        .map(|((gt, num_frames), results)| Ab3dmotSequence {
            gt,
            results,
            num_frames: *num_frames,
        })
        .collect();
    let ab3dmot_3d = ab3dmot_evaluate(
        &sequences,
        KittiEvalClass::Car,
        &Ab3dmotEvalConfig::default(),
    )
    .map_err(|source| TrackKittiError::Eval {
        sequence: seqmap.first().map_or(0, |e| e.sequence),
        source,
    })?;
    let total_image_iou_50 = combine_sequences(
        &per_sequence
            .iter()
            .map(|s| s.image_iou_50.clone())
            .collect::<Vec<_>>(),
    );
    let total_iou3d_25 = combine_sequences(
        &per_sequence
            .iter()
            .map(|s| s.iou3d_25.clone())
            .collect::<Vec<_>>(),
    );
    Ok(TrackingEvaluation {
        per_sequence,
        total_image_iou_50,
        total_iou3d_25,
        ab3dmot_3d,
    })
}

/// One table row: MOTA/MOTP in percent, then IDSW, FP, FN, matches, GT.
fn row(name: &str, r: &ClearMotResult) -> String {
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{:.2}", 100.0 * x));
    format!(
        "{name:>6} {:>7} {:>7} {:>5} {:>6} {:>6} {:>6} {:>6}\n",
        pct(r.mota),
        pct(r.motp),
        r.id_switches,
        r.false_positives,
        r.false_negatives,
        r.matches,
        r.gt_count
    )
}

impl TrackingEvaluation {
    /// Plain-text tables (per sequence and total) for both evaluations.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        let header = format!(
            "{:>6} {:>7} {:>7} {:>5} {:>6} {:>6} {:>6} {:>6}\n",
            "seq", "MOTA", "MOTP", "IDSW", "FP", "FN", "TP", "GT"
        );
        type Pick = fn(&SequenceScores) -> &ClearMotResult;
        let tables: [(&str, Pick, &ClearMotResult); 2] = [
            (
                "Car, KITTI 2D box benchmark (TrackEval), image IoU >= 0.5",
                |s| &s.image_iou_50,
                &self.total_image_iou_50,
            ),
            (
                "Car, 3D IoU >= 0.25 (AB3DMOT-style, TrackEval preprocessing)",
                |s| &s.iou3d_25,
                &self.total_iou3d_25,
            ),
        ];
        for (title, pick, total) in tables {
            out.push_str(title);
            out.push('\n');
            out.push_str(&header);
            for s in &self.per_sequence {
                out.push_str(&row(&format!("{:04}", s.sequence), pick(s)));
            }
            out.push_str(&row("all", total));
            out.push('\n');
        }
        let a = &self.ab3dmot_3d;
        let b = &a.best;
        let pct = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{:.2}", 100.0 * x));
        out.push_str(&format!(
            "Car, AB3DMOT evaluate.py, 3D IoU >= 0.25, all sequences\n\
             sAMOTA {:.2}  AMOTA {:.2}  AMOTP {:.2}\n\
             best threshold {:.4}: MOTA {} MOTP {:.2} IDSW {} FP {} FN {} TP {} GT {}\n",
            100.0 * a.samota,
            100.0 * a.amota,
            100.0 * a.amotp,
            b.score_threshold,
            pct(b.mota),
            100.0 * b.motp,
            b.id_switches,
            b.false_positives,
            b.false_negatives,
            b.true_positives,
            b.gt_count
        ));
        out
    }
}

#[cfg(test)]
mod tests;
