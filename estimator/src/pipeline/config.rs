//! Estimator configuration with the paper's / LIO-SAM's defaults.

use super::objects::ObjectGraphConfig;
use crate::graph::SolverConfig;
use crate::imu::ImuNoise;
use crate::lidar::FeatureConfig;
use crate::lidar::LocalMapConfig;
use crate::lidar::ScanMatchConfig;
use crate::object_removal::FilterConfig;
use crate::tracking::TrackerConfig;

/// Which sensors drive the ego estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// IMU preintegration and LiDAR odometry in the sliding-window smoother.
    LidarInertial,
    /// Scan-to-map matching with a constant-velocity motion model, for sources
    /// without an IMU (e.g. bare KITTI scans).
    LidarOnly,
}

/// How object points are treated (the paper's ablation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Variant {
    /// LiDAR-inertial odometry, no object handling.
    Lio,
    /// Drop every feature inside any detected box.
    Allfilt,
    /// Drop the features inside the boxes of dynamic tracks, each point
    /// tested against its track's predicted box at the point's own time.
    Dynafilt,
    /// `dynafilt` plus the joint graph: confirmed objects' poses and pose
    /// changes are optimized with the ego states (the paper's LIMOT).
    Limot,
}

impl Variant {
    /// Every variant, in the paper's order.
    pub const ALL: [Variant; 4] = [
        Variant::Lio,
        Variant::Allfilt,
        Variant::Dynafilt,
        Variant::Limot,
    ];

    /// Machine name, as on the command line and in file names.
    pub fn name(self) -> &'static str {
        match self {
            Variant::Lio => "lio",
            Variant::Allfilt => "allfilt",
            Variant::Dynafilt => "dynafilt",
            Variant::Limot => "limot",
        }
    }

    /// Display name, as in the paper's tables.
    pub fn label(self) -> &'static str {
        match self {
            Variant::Lio => "LIO",
            Variant::Allfilt => "LIO-Allfilt",
            Variant::Dynafilt => "LIO-Dynafilt",
            Variant::Limot => "LIMOT",
        }
    }

    /// Whether the variant uses the tracker's objects (every variant but
    /// `lio`).
    pub fn tracks_objects(self) -> bool {
        self != Variant::Lio
    }
}

/// A string that names no [`Variant`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown variant {name:?} (expected lio, allfilt, dynafilt or limot)")]
pub struct ParseVariantError {
    /// The string as given.
    pub name: String,
}

impl std::str::FromStr for Variant {
    type Err = ParseVariantError;

    /// Accepts the machine name or the display name, in any case, with
    /// surrounding whitespace ignored.
    ///
    /// # Errors
    /// [`ParseVariantError`] naming the string when it is no variant's name.
    fn from_str(s: &str) -> Result<Variant, ParseVariantError> {
        let t = s.trim();
        Variant::ALL
            .into_iter()
            .find(|v| t.eq_ignore_ascii_case(v.name()) || t.eq_ignore_ascii_case(v.label()))
            .ok_or_else(|| ParseVariantError {
                name: s.to_string(),
            })
    }
}

impl std::fmt::Display for Variant {
    /// The machine name ([`Variant::name`]).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[derive(Debug, Clone)]
/// Everything the [`Estimator`](super::Estimator) is configured by; the
/// defaults are the paper's / LIO-SAM's.
pub struct EstimatorConfig {
    /// Which sensors drive the ego estimate.
    pub mode: Mode,
    /// How object points are treated.
    pub variant: Variant,
    /// Box inflation and time bins of the object filter.
    pub filter: FilterConfig,
    /// The multi-object tracker.
    pub tracker: TrackerConfig,
    /// Noise of the object factors (`limot`).
    pub objects: ObjectGraphConfig,
    /// `dynafilt` uses only confirmed tracks (the paper's initialised
    /// objects); `false` also uses tentative tracks already judged dynamic,
    /// which catches objects in their first frames.
    pub filter_confirmed_only: bool,
    /// `dynafilt` / `limot` also drop the points in this sweep's detections
    /// that no confirmed static track explains (see
    /// `FilterConfig::detection_track_gate_m`): objects too new to be judged
    /// static or dynamic, and the measured position of moving ones, which
    /// the prediction from the previous sweep may miss. `false` filters with
    /// the dynamic tracks' predicted boxes only (the paper's rule).
    pub filter_unsettled_detections: bool,
    /// `dynafilt` / `limot` also filter the tracks that have been dynamic and
    /// stand now (a car in a queue or at a red light after driving, which
    /// moves again; its speed alone makes it static). `false` filters by the
    /// tracks' present state only (the paper's rule).
    pub filter_stopped_movers: bool,
    /// `dynafilt` / `limot` also drop the edge features inside the boxes of
    /// confirmed static tracks (parked cars), keeping their planar ones. A
    /// vehicle's edges are mostly silhouettes, whose points the viewpoint and
    /// the sampling move over its body, so they bias the match along the
    /// street as the ego drives past (docs/estimator-notes.md). `false` keeps
    /// every feature of a static track (the paper's rule).
    pub filter_static_edges: bool,
    /// Report every feature index per frame (for filter evaluation).
    pub record_feature_indices: bool,
    /// Ego states in the sliding window (the paper uses 5).
    pub window_size: usize,
    /// Gravity magnitude, m/s² (the world z axis points up).
    pub gravity_mps2: f64,
    /// Estimate gravity in the world frame with the states (one variable
    /// for the run, prior along -z) instead of holding it along -z. The
    /// world's tilt starts as the first state's, and an accelerometer
    /// bias the start cannot tell from a tilt (the ego has not yet turned)
    /// stays in it; with gravity estimated, the first turn separates the two.
    /// Needs an IMU that resolves a sweep's motion (`limot::run` holds
    /// gravity for one slower than 50 Hz).
    pub estimate_gravity: bool,
    /// With `estimate_gravity`: prior sigma of gravity's direction, rad.
    pub gravity_tilt_sigma_rad: f64,
    /// IMU noise densities and bias random walks.
    pub imu_noise: ImuNoise,
    /// Largest tolerated hole in the IMU stream, s; longer gaps are errors.
    pub max_imu_gap_s: f64,
    /// IMU history used for the static initialization, s.
    pub init_window_s: f64,
    /// Static test: standard deviation of the accelerometer norm, m/s².
    pub init_max_accel_std_mps2: f64,
    /// Static test: largest mean angular rate, rad/s.
    pub init_max_gyro_radps: f64,
    /// Prior sigmas on the first state: roll/pitch (from gravity), rad.
    pub init_tilt_sigma_rad: f64,
    /// Prior sigma on the initial velocity (the ego stands still), m/s.
    pub init_velocity_sigma_mps: f64,
    /// Prior sigma on the initial accelerometer bias, m/s².
    pub init_accel_bias_sigma_mps2: f64,
    /// Prior sigma on the initial gyroscope bias, rad/s.
    pub init_gyro_bias_sigma_radps: f64,
    /// Static test on the LiDAR: largest motion over the last three sweeps, m.
    pub init_max_lidar_motion_m: f64,
    /// Moving start: LiDAR-only sweeps used to find gravity and velocity.
    pub bootstrap_frames: usize,
    /// Moving start: largest error of the recovered gravity magnitude, m/s².
    pub bootstrap_gravity_tolerance_mps2: f64,
    /// Moving start: prior sigma on the first state's roll and pitch, rad.
    pub bootstrap_tilt_sigma_rad: f64,
    /// Moving start: prior sigma on the first state's velocity, m/s.
    pub bootstrap_velocity_sigma_mps: f64,
    /// Poses sampled per sweep for the IMU-driven de-skew.
    pub deskew_samples: usize,
    /// LOAM feature extraction.
    pub features: FeatureConfig,
    /// Voxel size for the edge features before matching, m.
    pub edge_voxel_m: f64,
    /// Voxel size for the planar features, m (edges: `edge_voxel_m`).
    pub planar_voxel_m: f64,
    /// The local map of keyframes.
    pub local_map: LocalMapConfig,
    /// Scan-to-map matching.
    pub scan_match: ScanMatchConfig,
    /// Std of one point-to-line/plane residual, m; scales the matching
    /// information into the odometry factor.
    pub point_sigma_m: f64,
    /// Matching residuals are correlated (neighbouring points share map
    /// structure); the information is divided by this factor.
    pub odometry_information_inflation: f64,
    /// Eigenvalues of the odometry information are floored here, so
    /// degenerate directions are left to the IMU instead of being singular.
    pub odometry_min_information: f64,
    /// A new keyframe enters the local map after this translation, m (or
    /// `keyframe_angle_rad` of rotation).
    pub keyframe_distance_m: f64,
    /// Rotation since the last keyframe that makes a new one, rad.
    pub keyframe_angle_rad: f64,
    /// Levenberg–Marquardt of the ego window.
    pub solver: SolverConfig,
    /// LiDAR-only: when the match lands farther than this from the
    /// constant-velocity prediction, the sweep is de-skewed again with the
    /// matched velocity and re-matched (at most `max_redeskew_rounds` times).
    pub redeskew_translation_m: f64,
    /// LiDAR-only: the rotation threshold of the re-de-skew, rad.
    pub redeskew_rotation_rad: f64,
    /// LiDAR-only: re-de-skews per sweep at most.
    pub max_redeskew_rounds: usize,
    /// LiDAR-only: the second sweep has no velocity to predict from, so it
    /// is matched from forward speeds `0, step, 2 step, …` up to this, m/s,
    /// and the speed explaining the most of the scene is kept.
    pub start_max_speed_mps: f64,
    /// The step of that search, m/s: small enough that one sweep at half
    /// the step stays well inside the correspondence distance.
    pub start_speed_step_mps: f64,
    /// Scan-matching iterations each speed of that search gets at most (the
    /// matcher's own limit caps it): the speeds whose match converged within
    /// them compete (see `Estimator`'s LiDAR-only start).
    pub start_speed_max_iterations: usize,
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        EstimatorConfig {
            mode: Mode::LidarInertial,
            variant: Variant::Lio,
            // 0.6 m rather than a "slight" inflation: it has to absorb the
            // detector's box noise (~0.15 m) and the one-frame trajectory
            // prediction error (~0.3 m RMS); see docs/estimator-notes.md.
            filter: FilterConfig {
                inflate_m: 0.6,
                ..FilterConfig::default()
            },
            tracker: TrackerConfig::default(),
            objects: ObjectGraphConfig::default(),
            record_feature_indices: false,
            filter_confirmed_only: false,
            filter_unsettled_detections: true,
            filter_stopped_movers: true,
            filter_static_edges: true,
            window_size: 5,
            gravity_mps2: 9.80511,
            estimate_gravity: true,
            gravity_tilt_sigma_rad: 0.01,
            imu_noise: ImuNoise::default(),
            max_imu_gap_s: 0.05,
            init_window_s: 0.5,
            init_max_accel_std_mps2: 0.2,
            init_max_gyro_radps: 0.05,
            init_tilt_sigma_rad: 0.01,
            init_velocity_sigma_mps: 0.05,
            init_accel_bias_sigma_mps2: 0.1,
            init_gyro_bias_sigma_radps: 0.01,
            init_max_lidar_motion_m: 0.05,
            bootstrap_frames: 10,
            bootstrap_gravity_tolerance_mps2: 0.5,
            bootstrap_tilt_sigma_rad: 0.02,
            bootstrap_velocity_sigma_mps: 0.3,
            deskew_samples: 11,
            features: FeatureConfig::default(),
            edge_voxel_m: 0.2,
            planar_voxel_m: 0.4,
            local_map: LocalMapConfig::default(),
            scan_match: ScanMatchConfig::default(),
            point_sigma_m: 0.05,
            odometry_information_inflation: 10.0,
            odometry_min_information: 1e-2,
            keyframe_distance_m: 1.0,
            keyframe_angle_rad: 0.2,
            // A window of 5 frames converges in a few iterations from the IMU
            // prediction; tighter tolerances only burn time.
            redeskew_translation_m: 0.03,
            redeskew_rotation_rad: 0.003,
            max_redeskew_rounds: 2,
            // motorway speeds; 5 m/s puts the nearest speed at most 0.25 m
            // from the truth in a 0.1 s sweep, inside the 1 m match distance
            start_max_speed_mps: 40.0,
            start_speed_step_mps: 5.0,
            // a speed within half a step of the truth settled in 6-10 on
            // KITTI 0000; the far ones would run to the matcher's 30
            start_speed_max_iterations: 10,
            // Gauss-Newton from the IMU prediction converges quadratically:
            // a step that gains less than 1e-5 of the cost leaves the next
            // one sub-millimetre (docs/speed.md)
            solver: SolverConfig {
                max_iterations: 10,
                function_tolerance: 1e-5,
                gradient_tolerance: 1e-9,
                step_tolerance: 1e-6,
                ..SolverConfig::default()
            },
        }
    }
}

impl EstimatorConfig {
    /// LiDAR-only defaults.
    pub fn lidar_only() -> EstimatorConfig {
        EstimatorConfig {
            mode: Mode::LidarOnly,
            ..EstimatorConfig::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variant_names_and_labels_parse_back() {
        for v in Variant::ALL {
            assert_eq!(v.name().parse::<Variant>(), Ok(v));
            assert_eq!(v.label().to_lowercase().parse::<Variant>(), Ok(v));
            assert_eq!(v.to_string(), v.name());
        }
        assert_eq!(" LIMOT ".parse::<Variant>(), Ok(Variant::Limot));
        let err = "lidar".parse::<Variant>().unwrap_err();
        assert_eq!(err.name, "lidar");
        let message = err.to_string();
        assert!(message.contains("\"lidar\"") && message.contains("dynafilt"));
        assert!(!Variant::Lio.tracks_objects() && Variant::Allfilt.tracks_objects());
    }
}
