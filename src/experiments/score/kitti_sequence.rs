//! Scores of a run on a KITTI tracking sequence against the sequence's own
//! truth, as `limot run DIR --sequence N` and `limot eval kitti` report them.
//!
//! Ego: the estimated LiDAR poses against the OXTS poses moved into the LiDAR
//! frame (`t_world_lidar = t_world_imu · Tr_imu_velo⁻¹`, [`super::ego`]), at
//! KITTI's 10 Hz frame times. ATE_T / ATE_R after SE(3) alignment (the paper's
//! figures), ATE_T after Sim(3) alignment with its scale beside it, and RPE
//! over one frame and over 10 m of path (all pairs, path measured on the
//! truth). OXTS frames whose `pos_accuracy` exceeds
//! [`KittiScoreOptions::max_truth_pos_accuracy_m`] are left out of the truth;
//! the mean and largest `pos_accuracy` of the frames used are reported, since
//! they bound what an ATE against this truth can resolve.
//!
//! Tracks: the run's KITTI result lines (camera frame) against `label_02`,
//! class Car: TrackEval's KITTI 2D box benchmark (image IoU ≥ 0.5), the
//! AB3DMOT-style 3D CLEAR-MOT at 3D IoU ≥ 0.25 and 0.5, and TP % / object ATE
//! ([`crate::metrics::objects`], 3D IoU ≥ 0.25) of the ground-truth cars with the
//! most labelled frames (the paper's Table III protocol). Result boxes were
//! placed with the estimated ego pose and are compared in each frame's LiDAR
//! frame, so the object ATE includes the ego's error relative to the scene.

use super::ego::{EgoEvalOptions, Trajectory, evaluate_trajectories};
use super::filtering::FilterEvaluation;
use super::kitti_filter::score_filter_on_labels;
use super::{EvaluateError, Result};
use crate::experiments::ResultPolicy;
use crate::experiments::lidar_poses;
use crate::io::kitti::calib::Calib;
use crate::io::kitti::detections::ScoreMap;
use crate::io::kitti::detections::camera_box_to_lidar;
use crate::io::kitti::labels::{TrackingLabel, read_labels};
use crate::io::kitti::oxts::{oxts_to_poses, read_oxts};
use crate::io::kitti::raw::{declared_elevation_correction_rad, tracking_frame_times};
use crate::io::kitti::sequence_file;
use crate::metrics::IouKind;
use crate::metrics::kitti_3d_clear_mot;
use crate::metrics::object_scores;
use crate::metrics::{AlignMode, RpeDelta, pose_at};
use crate::metrics::{ClearMotConfig, MotFrame, MotSummary, TrackedBox};
use crate::metrics::{KittiEvalClass, kitti_2d_clear_mot};
use crate::run::{LabelFrame, RunOutput, kitti_track_labels, write_kitti_tracks};
use limot_estimator::geometry::OrientedBox;
use limot_estimator::input::ObjectClass;
use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Path length of the RPE's distance-based segments (KITTI odometry uses
/// 100-800 m; tracking sequences are often shorter than 100 m).
pub const RPE_PATH_DELTA_M: f64 = 10.0;

/// How a KITTI tracking run is scored.
#[derive(Debug, Clone, PartialEq)]
pub struct KittiScoreOptions {
    /// OXTS frames less accurate than this (field `pos_accuracy`) are not used
    /// as ego truth.
    pub max_truth_pos_accuracy_m: f64,
    /// How many ground-truth cars (most labelled frames first) a summary
    /// lists with their TP % and ATE (the paper's Table III protocol).
    pub longest_objects: usize,
    /// Which tracks the result file holds (the tracker alone's rules, so the
    /// two compare like with like).
    pub result: ResultPolicy,
    /// How the detections' raw scores were mapped (inverted for the lines).
    pub score_map: ScoreMap,
}

impl Default for KittiScoreOptions {
    fn default() -> Self {
        KittiScoreOptions {
            max_truth_pos_accuracy_m: 1.0,
            longest_objects: 3,
            result: ResultPolicy::default(),
            score_map: ScoreMap::Sigmoid,
        }
    }
}

/// Ego accuracy of one run (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EgoScores {
    /// Estimated poses scored (associated with a truth pose).
    pub poses: usize,
    /// Length of the true path over the scored poses, m.
    pub path_length_m: f64,
    /// SE(3)-aligned ATE, m and rad.
    pub ate_t_m: f64,
    /// SE(3)-aligned ATE_R, rad.
    pub ate_r_rad: f64,
    /// Sim(3)-aligned ATE_T and the scale that aligns the estimate.
    pub sim3_ate_t_m: f64,
    /// Sim(3) scale.
    pub sim3_scale: f64,
    /// RPE RMSE over consecutive frames.
    pub rpe_frame_t_m: Option<f64>,
    /// RPE rotation RMSE over consecutive frames, rad.
    pub rpe_frame_r_rad: Option<f64>,
    /// RPE RMSE over [`RPE_PATH_DELTA_M`] of path.
    pub rpe_10m_t_m: Option<f64>,
    /// RPE rotation RMSE over [`RPE_PATH_DELTA_M`] of path, rad.
    pub rpe_10m_r_rad: Option<f64>,
    /// OXTS `pos_accuracy` of the truth frames used: mean and largest, m.
    pub truth_pos_accuracy_mean_m: f64,
    /// Largest OXTS `pos_accuracy` of the truth frames used, m.
    pub truth_pos_accuracy_max_m: f64,
    /// Truth frames left out for their `pos_accuracy`.
    pub truth_frames_gated: usize,
}

/// TP % and ATE of one ground-truth object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectSummary {
    /// Ground-truth track id.
    pub gt_id: u64,
    /// Frames it is labelled in.
    pub gt_frames: usize,
    /// Share of those frames it is tracked in, %.
    pub tp_percent: f64,
    /// ATE_T of its track, m.
    pub ate_t_m: Option<f64>,
    /// ATE_R of its track, rad.
    pub ate_r_rad: Option<f64>,
}

/// Tracking scores of one run, class Car.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrackScores {
    /// TrackEval KITTI 2D box benchmark (image IoU ≥ 0.5).
    pub image_iou_50: MotSummary,
    /// AB3DMOT-style 3D evaluation at 3D IoU ≥ 0.25 and ≥ 0.5.
    pub iou3d_25: MotSummary,
    /// 3D IoU ≥ 0.5.
    pub iou3d_50: MotSummary,
    /// Every labelled car, most labelled frames first (ties: smaller id).
    pub objects: Vec<ObjectSummary>,
}

/// Poses and OXTS accuracy of a KITTI sequence's ego truth.
pub struct KittiEgoTruth {
    /// LiDAR poses from OXTS.
    pub trajectory: Trajectory,
    /// OXTS `pos_accuracy` per frame, m.
    pub pos_accuracy_m: Vec<f64>,
    /// Frames left out for their `pos_accuracy`.
    pub gated: usize,
}

/// Reads the sequence's ego truth: LiDAR poses at the frames' times
/// ([`tracking_frame_times`]: on KITTI the camera trigger, half a sweep after
/// the sweep start that limot stamps its poses with), without the frames
/// that fail the accuracy gate.
///
/// # Errors
///
/// [`EvaluateError`] when the OXTS or calibration files cannot be read.
pub fn read_ego_truth(
    training: &Path,
    sequence: u32,
    opts: &KittiScoreOptions,
) -> Result<KittiEgoTruth> {
    let oxts_path = sequence_file(&training.join("oxts"), sequence);
    let records = read_oxts(&oxts_path)?;
    if records.is_empty() {
        return Err(EvaluateError::Input {
            path: oxts_path,
            why: "no OXTS records".into(),
        });
    }
    let calib = Calib::read(&sequence_file(&training.join("calib"), sequence))?;
    let timing = tracking_frame_times(training, records.len())?;
    if timing.sweep_starts_s.len() != records.len() {
        return Err(EvaluateError::TimesLength {
            poses_path: oxts_path,
            poses: records.len(),
            times_path: training.join("times.txt"),
            times: timing.sweep_starts_s.len(),
        });
    }
    let t_world_lidar = lidar_poses(&oxts_to_poses(&records), &calib);
    let mut poses = Vec::with_capacity(records.len());
    let mut pos_accuracy_m = Vec::with_capacity(records.len());
    for ((record, pose), start_s) in records
        .iter()
        .zip(t_world_lidar)
        .zip(&timing.sweep_starts_s)
    {
        if record.pos_accuracy_m <= opts.max_truth_pos_accuracy_m {
            poses.push((start_s + timing.frame_delay_s, pose));
            pos_accuracy_m.push(record.pos_accuracy_m);
        }
    }
    Ok(KittiEgoTruth {
        gated: records.len() - poses.len(),
        trajectory: Trajectory {
            path: oxts_path,
            kind: "KITTI OXTS poses in the LiDAR frame".into(),
            poses,
            frame_times: None,
        },
        pos_accuracy_m,
    })
}

/// Scores estimated `(t_s, t_world_lidar)` poses against the sequence's truth.
///
/// # Errors
/// Unreadable OXTS or calibration files (named), or too few poses that
/// overlap the truth in time.
pub fn score_ego(
    training: &Path,
    sequence: u32,
    estimate: &[(f64, Isometry3<f64>)],
    opts: &KittiScoreOptions,
) -> Result<EgoScores> {
    let truth = read_ego_truth(training, sequence, opts)?;
    if truth.trajectory.poses.len() < 2 {
        return Err(EvaluateError::Input {
            path: truth.trajectory.path.clone(),
            why: format!(
                "{} OXTS frames within pos_accuracy <= {} m: too few to score against",
                truth.trajectory.poses.len(),
                opts.max_truth_pos_accuracy_m
            ),
        });
    }
    // The truth at the estimate's times (sweep starts), where it covers them.
    let truth_at_estimates = Trajectory {
        poses: estimate
            .iter()
            .filter_map(|(t, _)| Some((*t, pose_at(&truth.trajectory.poses, *t, |s| *s)?)))
            .collect(),
        path: truth.trajectory.path.clone(),
        kind: truth.trajectory.kind.clone(),
        frame_times: None,
    };
    let estimate = Trajectory {
        path: training.join("estimate"),
        kind: "estimate".into(),
        poses: estimate.to_vec(),
        frame_times: None,
    };
    let se3_opts = EgoEvalOptions {
        sequence,
        ..EgoEvalOptions::default()
    };
    let se3 = evaluate_trajectories(&truth_at_estimates, &estimate, &se3_opts)?;
    let sim3 = evaluate_trajectories(
        &truth_at_estimates,
        &estimate,
        &EgoEvalOptions {
            align: AlignMode::Sim3,
            ..se3_opts.clone()
        },
    )?;
    let rpe_10m = evaluate_trajectories(
        &truth_at_estimates,
        &estimate,
        &EgoEvalOptions {
            rpe_delta: RpeDelta::Meters {
                delta_m: RPE_PATH_DELTA_M,
                path_tolerance_m: 0.1 * RPE_PATH_DELTA_M,
            },
            rpe_all_pairs: true,
            ..se3_opts.clone()
        },
    )?
    .rpe;
    // The true path over the scored poses.
    let path_length_m = truth_at_estimates
        .poses
        .windows(2)
        .map(|w| (w[1].1.translation.vector - w[0].1.translation.vector).norm())
        .sum();
    let n_acc = truth.pos_accuracy_m.len().max(1) as f64;
    Ok(EgoScores {
        poses: se3.ate.n,
        path_length_m,
        ate_t_m: se3.ate.ate_t_rmse_m,
        ate_r_rad: se3.ate.ate_r_rmse_rad,
        sim3_ate_t_m: sim3.ate.ate_t_rmse_m,
        sim3_scale: sim3.ate.alignment.scale,
        rpe_frame_t_m: se3.rpe.map(|r| r.trans_rmse_m),
        rpe_frame_r_rad: se3.rpe.map(|r| r.rot_rmse_rad),
        rpe_10m_t_m: rpe_10m.map(|r| r.trans_rmse_m),
        rpe_10m_r_rad: rpe_10m.map(|r| r.rot_rmse_rad),
        truth_pos_accuracy_mean_m: truth.pos_accuracy_m.iter().sum::<f64>() / n_acc,
        truth_pos_accuracy_max_m: truth.pos_accuracy_m.iter().copied().fold(0.0, f64::max),
        truth_frames_gated: truth.gated,
    })
}

/// Everything a run on a KITTI tracking sequence is scored on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KittiRunScores {
    /// Sequence number.
    pub sequence: u32,
    /// Ego scores.
    pub ego: EgoScores,
    /// `None` when the sequence has no `label_02` file or the variant does
    /// not track (lio).
    pub tracks: Option<TrackScores>,
    /// The filter judged by the labelled boxes (`super::kitti_filter`);
    /// `None` without `label_02`, for lio, or when the run recorded no
    /// features.
    #[serde(default)]
    pub filter: Option<FilterEvaluation>,
}

/// Writes the run's tracks as `results_dir/SSSS.txt` (KITTI tracking format,
/// the sequence's camera) and scores the run against the sequence's truth
/// (its tracks only when the variant tracks objects).
/// Returns the scores and the result file.
///
/// # Errors
/// Unreadable or malformed OXTS, calibration or label files (named), too
/// few poses overlapping the truth, an unwritable `results_dir`.
pub fn score_run(
    training: &Path,
    sequence: u32,
    output: &RunOutput,
    results_dir: &Path,
    opts: &KittiScoreOptions,
) -> Result<(KittiRunScores, PathBuf)> {
    let calib = Calib::read(&sequence_file(&training.join("calib"), sequence))?;
    let num_frames = read_oxts(&sequence_file(&training.join("oxts"), sequence))?.len();
    let label_frame = LabelFrame {
        delay_s: tracking_frame_times(training, num_frames)?.frame_delay_s,
        elevation_correction_rad: declared_elevation_correction_rad(training)?,
    };
    let labels = kitti_track_labels(output, &calib, label_frame, &opts.result, opts.score_map)
        .map_err(Box::new)?;
    let results_file = write_kitti_tracks(results_dir, sequence, &labels).map_err(Box::new)?;
    let estimate: Vec<(f64, Isometry3<f64>)> = output
        .estimates
        .iter()
        .map(|e| (e.t_s, e.t_world_lidar))
        .collect();
    let ego = score_ego(training, sequence, &estimate, opts)?;
    let gt = read_sequence_labels(training, sequence)?;
    let (tracks, filter) = match &gt {
        Some(gt) if output.variant.tracks_objects() => (
            Some(score_tracks(gt, &labels, num_frames as u32, &calib)?),
            score_filter_on_labels(training, sequence, output, gt, &calib)?,
        ),
        _ => (None, None),
    };
    Ok((
        KittiRunScores {
            sequence,
            ego,
            tracks,
            filter,
        },
        results_file,
    ))
}

/// The sequence's `label_02` file, or `None` when it has none.
///
/// # Errors
///
/// [`EvaluateError`] when the label file exists but cannot be read.
pub fn read_sequence_labels(training: &Path, sequence: u32) -> Result<Option<Vec<TrackingLabel>>> {
    let path = sequence_file(&training.join("label_02"), sequence);
    if !path.is_file() {
        return Ok(None);
    }
    Ok(Some(read_labels(&path)?))
}

/// Car ground truth and result boxes per frame in the LiDAR frame, for the
/// per-object scores. DontCare and other classes are left out.
fn car_frames(
    gt: &[TrackingLabel],
    results: &[TrackingLabel],
    num_frames: u32,
    calib: &Calib,
) -> Vec<MotFrame> {
    let mut frames: Vec<MotFrame> = (0..num_frames)
        .map(|_| MotFrame {
            gt: Vec::new(),
            tracks: Vec::new(),
            dont_care: Vec::new(),
        })
        .collect();
    let as_box = |l: &TrackingLabel| -> TrackedBox {
        let b = camera_box_to_lidar(&l.cam_box, calib);
        TrackedBox {
            id: l.track_id as u64,
            class: ObjectClass::Car,
            bbox: OrientedBox::new(b.center, b.size_lwh, b.yaw_rad),
        }
    };
    let is_car = |l: &&TrackingLabel| {
        l.track_id >= 0 && l.frame < num_frames && KittiEvalClass::Car.is_class(&l.type_name)
    };
    for l in gt.iter().filter(is_car) {
        frames[l.frame as usize].gt.push(as_box(l));
    }
    for l in results.iter().filter(is_car) {
        frames[l.frame as usize].tracks.push(as_box(l));
    }
    frames
}

/// Scores KITTI result lines of one sequence against its labels (class Car).
///
/// # Errors
/// Result or label boxes the evaluators reject (named by frame and id), an
/// unreadable calibration file.
pub fn score_tracks(
    gt: &[TrackingLabel],
    results: &[TrackingLabel],
    num_frames: u32,
    calib: &Calib,
) -> Result<TrackScores> {
    let results: Vec<TrackingLabel> = results
        .iter()
        .filter(|l| l.frame < num_frames)
        .cloned()
        .collect();
    let image = kitti_2d_clear_mot(gt, &results, num_frames, KittiEvalClass::Car)?;
    let iou3d = |threshold| {
        kitti_3d_clear_mot(
            gt,
            &results,
            num_frames,
            KittiEvalClass::Car,
            calib,
            threshold,
        )
    };
    let (iou3d_25, iou3d_50) = (iou3d(0.25)?, iou3d(0.5)?);
    let frames = car_frames(gt, &results, num_frames, calib);
    let object_cfg = ClearMotConfig {
        iou_threshold: 0.25,
        iou_kind: IouKind::ThreeD,
        ..ClearMotConfig::default()
    };
    let mut objects = object_scores(&frames, &object_cfg)?;
    // Most labelled frames first; ties to the smaller id (the sort is stable).
    objects.sort_by_key(|o| std::cmp::Reverse(o.gt_frames));
    let objects = objects
        .iter()
        .map(|o| ObjectSummary {
            gt_id: o.gt_id,
            gt_frames: o.gt_frames,
            tp_percent: o.tp_percent,
            ate_t_m: o.ate_t_rmse_m,
            ate_r_rad: o.ate_r_rmse_rad,
        })
        .collect();
    Ok(TrackScores {
        image_iou_50: MotSummary::from(&image),
        iou3d_25: MotSummary::from(&iou3d_25),
        iou3d_50: MotSummary::from(&iou3d_50),
        objects,
    })
}

impl EgoScores {
    /// `ATE_T … m (SE(3)), ATE_R … rad; Sim(3) … m at scale …; RPE …`.
    pub fn summary_line(&self) -> String {
        let opt = |v: Option<f64>, d: usize| v.map_or("-".to_string(), |x| format!("{x:.d$}"));
        format!(
            "ATE_T {:.3} m, ATE_R {:.4} rad (SE(3)); ATE_T {:.3} m at scale {:.4} (Sim(3)); \
             RPE 1 frame {} m / {} rad, 10 m {} m / {} rad; {} poses over {:.1} m \
             (OXTS pos_accuracy mean {:.2} m, max {:.2} m, {} frames gated)",
            self.ate_t_m,
            self.ate_r_rad,
            self.sim3_ate_t_m,
            self.sim3_scale,
            opt(self.rpe_frame_t_m, 4),
            opt(self.rpe_frame_r_rad, 5),
            opt(self.rpe_10m_t_m, 3),
            opt(self.rpe_10m_r_rad, 4),
            self.poses,
            self.path_length_m,
            self.truth_pos_accuracy_mean_m,
            self.truth_pos_accuracy_max_m,
            self.truth_frames_gated
        )
    }
}

/// One printed line of a CLEAR-MOT summary.
fn mot_line(m: &MotSummary, name: &str) -> String {
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{:.2} %", 100.0 * x));
    format!(
        "{name}: MOTA {}, MOTP {}, IDSW {}, FP {}, FN {} ({} matches of {})",
        pct(m.mota),
        pct(m.motp),
        m.id_switches,
        m.false_positives,
        m.false_negatives,
        m.matches,
        m.gt_count
    )
}

impl TrackScores {
    /// One line per evaluation, then one for each of the `longest` cars with
    /// the most labelled frames.
    pub fn summary_lines(&self, longest: usize) -> Vec<String> {
        let mut lines = vec![
            mot_line(&self.image_iou_50, "Car, 2D (TrackEval, image IoU >= 0.5)"),
            mot_line(&self.iou3d_25, "Car, 3D IoU >= 0.25"),
            mot_line(&self.iou3d_50, "Car, 3D IoU >= 0.5"),
        ];
        for o in self.objects.iter().take(longest) {
            let opt = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.3}"));
            lines.push(format!(
                "car {} ({} frames): TP {:.1} %, ATE_T {} m, ATE_R {} rad",
                o.gt_id,
                o.gt_frames,
                o.tp_percent,
                opt(o.ate_t_m),
                opt(o.ate_r_rad)
            ));
        }
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::kitti::labels::parse_labels;

    const CALIB: &str = "P0: 7.215377e+02 0 6.095593e+02 0 0 7.215377e+02 1.728540e+02 0 0 0 1 0
P1: 7.215377e+02 0 6.095593e+02 -3.875744e+02 0 7.215377e+02 1.728540e+02 0 0 0 1 0
P2: 7.215377e+02 0 6.095593e+02 4.485728e+01 0 7.215377e+02 1.728540e+02 2.163791e-01 0 0 1 2.745884e-03
P3: 7.215377e+02 0 6.095593e+02 -3.395242e+02 0 7.215377e+02 1.728540e+02 2.199936e+00 0 0 1 2.729905e-03
R_rect 9.999239e-01 9.837760e-03 -7.445048e-03 -9.869795e-03 9.999421e-01 -4.278459e-03 7.402527e-03 4.351614e-03 9.999631e-01
Tr_velo_cam 7.533745e-03 -9.999714e-01 -6.166020e-04 -4.069766e-03 1.480249e-02 7.280733e-04 -9.998902e-01 -7.631618e-02 9.998621e-01 7.523790e-03 1.480755e-02 -2.717806e-01
Tr_imu_velo 9.999976e-01 7.553071e-04 -2.035826e-03 -8.086759e-01 -7.854027e-04 9.998898e-01 -1.482298e-02 3.195559e-01 2.024406e-03 1.482454e-02 9.998881e-01 -7.997231e-01
";

    /// A car (id `id`) straight ahead at `z` m in every frame of `frames`.
    fn car_line(frame: u32, id: i64, z: f64, score: Option<f64>) -> String {
        let s = score.map_or(String::new(), |s| format!(" {s}"));
        format!("{frame} {id} Car 0 0 -1.57 500 150 700 250 1.5 1.6 3.9 0.5 1.6 {z} -1.57{s}")
    }

    fn labels(lines: &[String]) -> Vec<TrackingLabel> {
        parse_labels(&lines.join("\n"), Path::new("labels.txt")).unwrap()
    }

    #[test]
    fn perfect_tracks_score_full_marks_and_the_longest_car_first() {
        let calib = Calib::parse(CALIB, Path::new("calib.txt")).unwrap();
        let mut gt = Vec::new();
        for f in 0..10 {
            gt.push(car_line(f, 0, 15.0, None));
        }
        for f in 0..4 {
            gt.push(car_line(f, 1, 30.0, None));
        }
        let gt = labels(&gt);
        let results: Vec<TrackingLabel> = gt
            .iter()
            .map(|l| TrackingLabel {
                track_id: l.track_id + 7,
                score: Some(0.9),
                ..l.clone()
            })
            .collect();
        let s = score_tracks(&gt, &results, 10, &calib).unwrap();
        for m in [&s.image_iou_50, &s.iou3d_25, &s.iou3d_50] {
            assert_eq!(m.mota, Some(1.0));
            assert_eq!(
                (m.false_positives, m.false_negatives, m.id_switches),
                (0, 0, 0)
            );
            assert_eq!(m.matches, 14);
        }
        assert_eq!(s.objects.len(), 2);
        let o = &s.objects[0];
        assert_eq!((o.gt_id, o.gt_frames), (0, 10));
        assert_eq!(o.tp_percent, 100.0);
        assert!(o.ate_t_m.unwrap() < 1e-9);
    }

    #[test]
    fn combined_sequences_sum_counts_and_weight_motp_by_matches() {
        let part = |matches, fp, fn_, motp| MotSummary {
            mota: None,
            motp: Some(motp),
            id_switches: 1,
            false_positives: fp,
            false_negatives: fn_,
            matches,
            gt_count: matches + fn_,
        };
        let total = MotSummary::combine(&[part(10, 2, 5, 0.8), part(30, 1, 0, 0.4)]);
        assert_eq!(total.gt_count, 45);
        assert_eq!(total.matches, 40);
        assert!((total.mota.unwrap() - (1.0 - 10.0 / 45.0)).abs() < 1e-12);
        assert!((total.motp.unwrap() - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_shifted_car_counts_in_its_object_ate_and_a_missing_one_as_misses() {
        let calib = Calib::parse(CALIB, Path::new("calib.txt")).unwrap();
        let gt = labels(
            &(0..10)
                .map(|f| car_line(f, 0, 15.0, None))
                .collect::<Vec<_>>(),
        );
        // Tracked in the first half only, 0.3 m too far.
        let results = labels(
            &(0..5)
                .map(|f| car_line(f, 3, 15.3, Some(0.8)))
                .collect::<Vec<_>>(),
        );
        let s = score_tracks(&gt, &results, 10, &calib).unwrap();
        assert_eq!(s.iou3d_25.false_negatives, 5);
        assert_eq!(s.iou3d_25.matches, 5);
        let o = &s.objects[0];
        assert_eq!(o.tp_percent, 50.0);
        assert!((o.ate_t_m.unwrap() - 0.3).abs() < 1e-6, "{:?}", o.ate_t_m);
    }
}
