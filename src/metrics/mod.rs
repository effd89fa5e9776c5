//! Evaluation metrics: ego trajectory (ATE, RPE, alignment), 3D boxes (IoU),
//! multi-object tracking (CLEAR-MOT, the KITTI 2D/3D benchmarks, AB3DMOT's
//! sAMOTA, per-object TP % and ATE), dynamic-point filtering (precision/recall),
//! realism statistics of LiDAR sequences, agreement of rankings and timing.
//!
//! The metric functions take plain inputs (timestamped poses, oriented boxes,
//! masks) so the KITTI reader and the simulator feed them alike. Conventions
//! follow evo (ATE/RPE, Zhang & Scaramuzza 2018) and the KITTI tracking devkit /
//! TrackEval (CLEAR-MOT, Bernardin & Stiefelhagen 2008).
//!
//! Entry points: [`ate`] / [`ate_with`], [`rpe`], [`iou_3d`] / [`iou_bev`] /
//! [`iou_image`], [`clear_mot`], [`kitti_2d_clear_mot`] / [`kitti_3d_clear_mot`],
//! [`ab3dmot_evaluate`] (sAMOTA), [`mot_loss`] (a tracker's errors by cause),
//! [`object_scores`], [`filter_precision_recall`],
//! [`RealismAccumulator`], [`kendall_tau_b`] and [`TimingAccumulator`].
mod align;
mod assignment;
mod ate;
mod clear_mot;
mod filtering;
mod interpolate;
mod iou;
mod kitti_mot;
mod mot_loss;
mod objects;
mod ranking;
mod realism;
mod rpe;
mod samota;
mod straight_path;
mod timing;

pub use align::{Alignment, umeyama};
pub use assignment::{Assignment, min_cost_assignment};
pub use ate::{AlignMode, AteResult, associate, ate, ate_with, ego_trajectory};
pub use clear_mot::{
    ClearMotConfig, ClearMotResult, FrameMatch, IdSwitchRule, MatchingRule, MotFrame, MotSummary,
    PAPER_IOU_THRESHOLDS, TrackedBox, clear_mot, clear_mot_per_class, combine_sequences,
};
pub use filtering::{FilterScore, filter_precision_recall};
pub use interpolate::pose_at;
pub use iou::{Box2, IouKind, MotBox, iou, iou_3d, iou_bev, iou_image, validate_box};
pub use kitti_mot::{
    KittiEvalClass, KittiMotFrames, KittiPreprocessConfig, KittiPreprocessStats,
    kitti_2d_clear_mot, kitti_2d_frames, kitti_3d_clear_mot,
};
pub use mot_loss::{FnCauses, FpCauses, LiveTrack, MotLoss, TookDetection, mot_loss};
pub use objects::{ObjectScore, object_scores};
pub use ranking::{best_items, kendall_tau_b};
pub use realism::{
    GroundPlane, Histogram, RealismAccumulator, RealismConfig, RealismStats, Spread,
    StatComparison, compare_realism, fit_ground_plane, roll_pitch_rad, surface_normals,
};
pub use rpe::{RpeDelta, RpeResult, rpe};
pub use samota::{
    Ab3dmotCounts, Ab3dmotEvalConfig, Ab3dmotResult, Ab3dmotSequence, ab3dmot_evaluate,
};
pub use straight_path::{AlignmentFix, STATIC_SCATTER_M2, STRAIGHT_PATH_RATIO, complete_alignment};
pub use timing::{TimingAccumulator, TimingStats};

/// Why a metric could not be computed from its inputs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EvalError {
    #[error("{what}: input is empty")]
    /// An input list is empty.
    Empty {
        /// The input.
        what: &'static str,
    },
    #[error("{what}: lengths differ ({left} vs {right})")]
    /// Two inputs that must pair up have different lengths.
    LengthMismatch {
        /// The inputs.
        what: &'static str,
        /// Length of the first.
        left: usize,
        /// Length of the second.
        right: usize,
    },
    #[error("{what}[{index}]: field `{field}` is not finite")]
    /// An entry holds a NaN or infinite value.
    NotFinite {
        /// The input.
        what: &'static str,
        /// Index of the offending entry.
        index: usize,
        /// The offending field.
        field: &'static str,
    },
    #[error("{what}[{index}]: field `{field}` is invalid ({why})")]
    /// An entry is out of its domain (e.g. a negative box size).
    Invalid {
        /// The input.
        what: &'static str,
        /// Index of the offending entry.
        index: usize,
        /// The offending field.
        field: &'static str,
        /// Why it is invalid.
        why: String,
    },
    #[error("{what}: {why}")]
    /// A parameter (threshold, delta, ...) is out of range.
    BadParameter {
        /// The parameter.
        what: &'static str,
        /// Why it is out of range.
        why: String,
    },
    #[error("{what}: only {got} samples could be used, need at least {need}")]
    /// Too few samples remained after association.
    TooFew {
        /// The metric.
        what: &'static str,
        /// Samples that could be used.
        got: usize,
        /// Samples needed.
        need: usize,
    },
}

/// Checks that every value is finite, naming the first offender.
pub(crate) fn check_finite(
    what: &'static str,
    index: usize,
    field: &'static str,
    values: &[f64],
) -> Result<(), EvalError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(EvalError::NotFinite { what, index, field })
    }
}

/// Checks that every entry of a pose is finite and its quaternion is unit.
pub(crate) fn check_pose(
    what: &'static str,
    index: usize,
    t_s: f64,
    pose: &nalgebra::Isometry3<f64>,
) -> Result<(), EvalError> {
    check_finite(what, index, "t_s", &[t_s])?;
    let t = pose.translation.vector;
    check_finite(what, index, "translation", &[t.x, t.y, t.z])?;
    let q = pose.rotation.quaternion();
    check_finite(what, index, "rotation", &[q.i, q.j, q.k, q.w])?;
    Ok(())
}

/// Summary statistics of a non-empty list of non-negative errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorStats {
    /// Root mean square.
    pub rmse: f64,
    /// Mean.
    pub mean: f64,
    /// Median (mean of the middle two for an even count).
    pub median: f64,
    /// Largest value.
    pub max: f64,
    /// Number of values.
    pub n: usize,
}

impl ErrorStats {
    /// `None` for an empty list.
    pub fn of(errors: &[f64]) -> Option<ErrorStats> {
        if errors.is_empty() {
            return None;
        }
        let n = errors.len();
        let mut sorted = errors.to_vec();
        sorted.sort_by(f64::total_cmp);
        let median = if n % 2 == 1 {
            sorted[n / 2]
        } else {
            0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
        };
        let mean = errors.iter().sum::<f64>() / n as f64;
        let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt();
        Some(ErrorStats {
            rmse,
            mean,
            median,
            max: sorted[n - 1],
            n,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_stats_hand_case() {
        let s = ErrorStats::of(&[3.0, 1.0, 4.0, 2.0]).unwrap();
        assert_eq!(s.median, 2.5);
        assert_eq!(s.max, 4.0);
        assert!((s.mean - 2.5).abs() < 1e-15);
        assert!((s.rmse - (30.0f64 / 4.0).sqrt()).abs() < 1e-15);
        assert!(ErrorStats::of(&[]).is_none());
    }
}
