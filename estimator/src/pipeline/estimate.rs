//! What the estimator reports per frame.

use crate::imu::ImuBias;
use crate::lidar::SweepMotion;
use crate::tracking::TrackOutput;
use nalgebra::{Isometry3, Vector3};
use std::time::Duration;

/// The estimate of one frame, at its scan start time, as known right after
/// the frame was processed (the window may refine it later). In LiDAR-only
/// mode the very first pose is the first sweep's middle: no velocity is known
/// yet to move it to the sweep start.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameEstimate {
    /// 0-based index of the frame in the input stream.
    pub frame_index: u64,
    /// Scan start time, s (the state's time).
    pub t_s: f64,
    /// LiDAR pose in the world frame at `t_s`.
    pub t_world_lidar: Isometry3<f64>,
    /// Velocity of the IMU in the world frame (LiDAR-only: of the LiDAR,
    /// from consecutive poses).
    pub velocity_world_mps: Vector3<f64>,
    /// Estimated IMU biases (zero in LiDAR-only mode).
    pub bias: ImuBias,
    /// `None` when matching was impossible (empty map or scan) and the pose
    /// is the motion prediction.
    pub scan_match: Option<ScanMatchSummary>,
    /// Feature points (indices into the sweep's points) dropped as object
    /// points by the variant's filter; empty for `lio`.
    pub removed_feature_indices: Vec<u32>,
    /// Every feature point before the filter (indices into the sweep's
    /// points), only with `EstimatorConfig::record_feature_indices`: what
    /// filter precision/recall are measured against.
    pub feature_indices: Vec<u32>,
    /// The edge features among `feature_indices` (ascending), under the
    /// same setting.
    pub edge_feature_indices: Vec<u32>,
    /// Every live track after this frame (world frame), sorted by id.
    pub tracks: Vec<TrackOutput>,
    /// Time spent per stage on this frame.
    pub timings: ModuleTimings,
}

impl FrameEstimate {
    /// The same estimate in another world frame (`t_new_old` maps old world
    /// coordinates to new ones): pose, velocity and tracks move, the rest is
    /// frame-free.
    pub fn transformed(&self, t_new_old: &Isometry3<f64>) -> FrameEstimate {
        FrameEstimate {
            t_world_lidar: t_new_old * self.t_world_lidar,
            velocity_world_mps: t_new_old.rotation * self.velocity_world_mps,
            tracks: self
                .tracks
                .iter()
                .map(|t| t.transformed(t_new_old))
                .collect(),
            ..self.clone()
        }
    }
}

/// The sweep the estimator processed last, as it used it: its points
/// de-skewed, the feature points its filter dropped and the motion it
/// de-skewed with. A borrow of the estimator's own buffers, valid until the
/// next frame ([`Estimator::deskewed_sweep`](super::Estimator::deskewed_sweep)).
#[derive(Debug, Clone, Copy)]
pub struct DeskewedSweep<'a> {
    /// 0-based index of the frame in the input stream.
    pub frame_index: u64,
    /// Scan start time, s.
    pub t_s: f64,
    /// The instant the points are de-skewed to, s: the scan start, or the
    /// sweep's middle where the sweep ran through LiDAR-only odometry.
    pub t_ref_s: f64,
    /// The scan's finite points in their order (what the feature indices
    /// index), in the LiDAR frame at `t_ref_s`, m.
    pub points_lidar: &'a [Vector3<f64>],
    /// The feature points the variant's filter dropped (indices into
    /// `points_lidar`), as in the frame's [`FrameEstimate`].
    pub removed_feature_indices: &'a [u32],
    /// The LiDAR motion over the sweep the points were de-skewed with (in
    /// the world of the prediction: only its relative poses mean anything).
    pub motion: &'a SweepMotion,
}

impl DeskewedSweep<'_> {
    /// `t_lidar_lidar_then`: the LiDAR frame at `t_then_s` in the LiDAR
    /// frame at the scan start, along [`DeskewedSweep::motion`]; the
    /// identity at the scan start.
    pub fn t_lidar_lidar_at(&self, t_then_s: f64) -> Isometry3<f64> {
        if t_then_s == self.t_s {
            return Isometry3::identity();
        }
        self.motion.pose_at(self.t_s).inverse() * self.motion.pose_at(t_then_s)
    }
}

/// Diagnostics of the scan-to-map match of one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanMatchSummary {
    /// Edge features matched (after downsampling).
    pub edge_features: usize,
    /// Planar features matched (after downsampling).
    pub planar_features: usize,
    /// Edge features with a line correspondence in the last iteration.
    pub edge_matches: usize,
    /// Planar features with a plane correspondence in the last iteration.
    pub planar_matches: usize,
    /// Gauss–Newton iterations of the match.
    pub iterations: usize,
    /// The match met its convergence tolerance.
    pub converged: bool,
    /// Number of weakly constrained directions (0 = well conditioned).
    pub degenerate_directions: usize,
    /// RMS point-to-line/plane residual of the last iteration, m.
    pub rms_residual_m: f64,
}

/// Wall-clock time per pipeline stage for one frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ModuleTimings {
    /// IMU preintegration and the sweep's motion (LiDAR-only: the motion model).
    pub imu_prediction: Duration,
    /// De-skewing the sweep.
    pub deskew: Duration,
    /// LOAM feature extraction.
    pub features: Duration,
    /// Dropping object features (`allfilt`, `dynafilt`).
    pub filter: Duration,
    /// Voxel downsampling of the features.
    pub downsample: Duration,
    /// Scan-to-map matching.
    pub scan_matching: Duration,
    /// Sliding-window factors, optimization and marginalization (`limot`: with
    /// the tracking that runs before the graph).
    pub graph: Duration,
    /// Adding a keyframe to the local map.
    pub map_update: Duration,
    /// Tracking the detections.
    pub tracking: Duration,
}

impl ModuleTimings {
    /// Sum of every stage.
    pub fn total(&self) -> Duration {
        self.imu_prediction
            + self.deskew
            + self.features
            + self.filter
            + self.downsample
            + self.scan_matching
            + self.graph
            + self.map_update
            + self.tracking
    }

    /// Stage names and durations, in pipeline order (for tables).
    pub fn stages(&self) -> [(&'static str, Duration); 9] {
        [
            ("imu_prediction", self.imu_prediction),
            ("deskew", self.deskew),
            ("features", self.features),
            ("filter", self.filter),
            ("downsample", self.downsample),
            ("scan_matching", self.scan_matching),
            ("graph", self.graph),
            ("map_update", self.map_update),
            ("tracking", self.tracking),
        ]
    }
}
