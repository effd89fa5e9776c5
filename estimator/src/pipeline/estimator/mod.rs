//! [`Estimator`]: the streaming LiDAR(-inertial) odometry pipeline.
//!
//! Per frame (IMU mode): preintegrate the IMU from the previous state to the
//! scan start and predict the new state; de-skew the sweep with poses
//! propagated through the IMU at several instants of the sweep; extract LOAM
//! features; match them to the local map starting from the prediction; add
//! the new state with IMU, bias random-walk and LiDAR odometry factors to the
//! sliding window; optimise; marginalise the oldest state by Schur complement
//! when the window is full; add a keyframe to the map after enough motion.
//!
//! States live at scan START times, and the de-skew reference is the scan
//! start too, so the detections (also stamped within the sweep) and the
//! ground truth boxes (at scan start) refer to the same instant.
//!
//! Files: `inertial.rs` (the per-frame stages above), `frontend.rs` (the
//! sweep: motion, de-skew, features, object removal, matching, map),
//! `bootstrap.rs` (LiDAR-only start and inertial initialization),
//! `lidar_only.rs` (odometry without an IMU), `tracks.rs` (the tracker's side),
//! `error.rs`.

mod bootstrap;
mod error;
mod frontend;
mod inertial;
mod lidar_only;
mod tracks;

pub use error::EstimatorError;

use super::config::{EstimatorConfig, Mode, Variant};
use super::estimate::{DeskewedSweep, FrameEstimate};
use super::objects::ObjectGraph;
use crate::graph::{Key, SlidingWindowSmoother, Variable};
use crate::imu::ImuBias;
use crate::input::{Detection, Extrinsics, Frame, ImuSample, InputError, LidarPoint};
use crate::lidar::Deskewer;
use crate::lidar::FeatureExtractor;
use crate::lidar::LocalMap;
use crate::lidar::VoxelDownsampler;
use crate::tracking::Tracker;
use nalgebra::{Isometry3, Vector3};
use std::collections::VecDeque;

/// The latest optimised ego state.
#[derive(Debug, Clone, Copy)]
struct EgoState {
    frame_index: u64,
    t_s: f64,
    t_world_imu: Isometry3<f64>,
    velocity_world_mps: Vector3<f64>,
    bias: ImuBias,
}

/// The sizes of what an [`Estimator`] keeps between frames. Each is bounded
/// by the configuration and the scene around the ego (keyframes within the
/// map radius, the sliding window, the objects in view), never by how long
/// it has run: `benches/long_drive.rs` follows them over a long drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Footprint {
    /// IMU samples buffered for preintegration and initialisation.
    pub imu_samples: usize,
    /// Keyframes in the local map.
    pub map_keyframes: usize,
    /// Edge plus planar points of the local map.
    pub map_points: usize,
    /// Frames in the sliding window.
    pub window_frames: usize,
    /// Live tracks.
    pub tracks: usize,
    /// Tracks kept for revival.
    pub lost_tracks: usize,
    /// Objects in the joint graph.
    pub objects: usize,
    /// LiDAR-only frames held until the inertial initialisation.
    pub bootstrap_frames: usize,
}

/// The streaming estimator. Feed IMU samples in time order with
/// [`Estimator::push_imu`] and frames with [`Estimator::push_frame`] once the
/// IMU covers the sweep (the IMU is extrapolated, with a flag, when it does not).
///
/// # Example
///
/// A sensor standing still in a box-shaped room: after the inertial
/// initialization every frame has its estimate, and the LiDAR stays at the
/// world origin.
///
/// ```
/// use limot_estimator::{
///     Estimator, EstimatorConfig, Extrinsics, Frame, ImuSample, LidarPoint, LidarScan,
/// };
/// use nalgebra::Vector3;
///
/// // 32 rings × 360 columns in a 20 m × 14 m × 6 m room.
/// fn room_scan(t_s: f64) -> LidarScan {
///     let walls = [
///         (Vector3::x(), 12.0),
///         (-Vector3::x(), 8.0),
///         (Vector3::y(), 6.0),
///         (-Vector3::y(), 8.0),
///         (-Vector3::z(), 1.7),
///         (Vector3::z(), 4.3),
///     ];
///     let mut points = Vec::new();
///     for column in 0..360 {
///         let az = column as f64 / 360.0 * std::f64::consts::TAU;
///         for ring in 0..32u16 {
///             let el = (-24.0 + 26.0 * ring as f64 / 31.0_f64).to_radians();
///             let d = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
///             let range = walls
///                 .iter()
///                 .filter(|(n, _)| d.dot(n) > 1e-9)
///                 .map(|(n, offset)| offset / d.dot(n))
///                 .fold(f64::INFINITY, f64::min);
///             let p = d * range;
///             points.push(LidarPoint {
///                 x: p.x as f32,
///                 y: p.y as f32,
///                 z: p.z as f32,
///                 intensity: 0.5,
///                 ring,
///                 time_offset_s: (column as f64 / 360.0 * 0.1) as f32,
///             });
///         }
///     }
///     LidarScan { t_s, sweep_duration_s: 0.1, num_rings: 32, points }
/// }
///
/// let mut estimator = Estimator::new(EstimatorConfig::default(), Extrinsics::default())?;
/// let mut estimates = Vec::new();
/// let mut next_sample = 0;
/// for k in 0..8 {
///     // 100 Hz of a still IMU through the end of the sweep.
///     while next_sample <= 10 * (k + 1) {
///         estimator.push_imu(ImuSample {
///             t_s: next_sample as f64 * 0.01,
///             accel_mps2: Vector3::new(0.0, 0.0, 9.80511),
///             gyro_radps: Vector3::zeros(),
///         })?;
///         next_sample += 1;
///     }
///     let frame = Frame { scan: room_scan(k as f64 * 0.1), detections: Vec::new() };
///     estimates.extend(estimator.push_frame(&frame)?);
/// }
/// assert!(estimator.is_initialized());
/// assert_eq!(estimates.len(), 8);
/// for estimate in &estimates {
///     assert!(estimate.t_world_lidar.translation.vector.norm() < 0.02);
/// }
/// # Ok::<(), limot_estimator::EstimatorError>(())
/// ```
pub struct Estimator {
    config: EstimatorConfig,
    t_lidar_imu: Isometry3<f64>,
    t_imu_lidar: Isometry3<f64>,
    imu: Vec<ImuSample>,
    last_scan_t_s: Option<f64>,
    next_frame_index: u64,
    map: LocalMap,
    last_keyframe_t_world_lidar: Option<Isometry3<f64>>,
    // Inertial mode.
    smoother: SlidingWindowSmoother,
    window_frames: VecDeque<u64>,
    latest: Option<EgoState>,
    // LiDAR-only mode: the last two (t_s, t_world_lidar).
    lidar_only_history: VecDeque<(f64, Isometry3<f64>)>,
    /// Mid-sweep LiDAR-only poses of a moving start (IMU mode).
    bootstrap_mids: Vec<(f64, Isometry3<f64>)>,
    /// Index of the first bootstrap pose after the last degenerate match.
    bootstrap_usable_from: usize,
    /// LiDAR-only estimates of the sweeps before the inertial
    /// initialisation, LiDAR-only world.
    bootstrap_estimates: Vec<FrameEstimate>,
    // Per-sweep scratch, kept so that a sweep does not allocate its buffers
    // (about a dozen of the scan's size) again.
    deskewer: Deskewer,
    deskewed: Vec<Vector3<f64>>,
    /// Of the sweep in `deskewed`: its frame, times, motion, dropped features.
    last_sweep: Option<frontend::LastSweep>,
    feature_extractor: FeatureExtractor,
    downsampler: VoxelDownsampler,
    /// One feature class's de-skewed points, gathered for the downsampler.
    gathered: Vec<Vector3<f64>>,
    /// The valid detections of the frame being processed.
    frame_detections: Vec<Detection>,
    tracker: Tracker,
    /// Objects in the joint graph (`limot`).
    objects: ObjectGraph,
    invalid_detections: u64,
}

impl Estimator {
    /// An estimator that has seen no data yet.
    ///
    /// # Errors
    /// [`EstimatorError::FilterConfig`] or [`EstimatorError::Tracker`] for
    /// invalid object-removal or tracker settings;
    /// [`EstimatorError::LimotNeedsImu`] for `limot` in LiDAR-only mode.
    pub fn new(
        config: EstimatorConfig,
        extrinsics: Extrinsics,
    ) -> Result<Estimator, EstimatorError> {
        config
            .filter
            .validate()
            .map_err(EstimatorError::FilterConfig)?;
        if config.variant == Variant::Limot && config.mode == Mode::LidarOnly {
            return Err(EstimatorError::LimotNeedsImu);
        }
        let tracker = Tracker::new(config.tracker.clone()).map_err(EstimatorError::Tracker)?;
        let map = LocalMap::new(config.local_map);
        let objects = ObjectGraph::new(config.objects.clone());
        let feature_extractor = FeatureExtractor::new(config.features.clone());
        Ok(Estimator {
            t_lidar_imu: extrinsics.t_lidar_imu,
            t_imu_lidar: extrinsics.t_lidar_imu.inverse(),
            config,
            imu: Vec::new(),
            last_scan_t_s: None,
            next_frame_index: 0,
            map,
            last_keyframe_t_world_lidar: None,
            smoother: SlidingWindowSmoother::new(),
            window_frames: VecDeque::new(),
            latest: None,
            lidar_only_history: VecDeque::new(),
            bootstrap_mids: Vec::new(),
            bootstrap_usable_from: 0,
            bootstrap_estimates: Vec::new(),
            deskewer: Deskewer::new(),
            deskewed: Vec::new(),
            last_sweep: None,
            feature_extractor,
            downsampler: VoxelDownsampler::default(),
            gathered: Vec::new(),
            frame_detections: Vec::new(),
            tracker,
            objects,
            invalid_detections: 0,
        })
    }

    /// Gravity in the world frame, m/s²: the window's estimate once it
    /// holds one (`EstimatorConfig::estimate_gravity`), else along -z.
    fn gravity_world(&self) -> Vector3<f64> {
        match self.smoother.values().get(&Key::Gravity) {
            Some(Variable::Vector3(g)) => *g,
            _ => Vector3::new(0.0, 0.0, -self.config.gravity_mps2),
        }
    }

    /// The configuration it runs with.
    pub fn config(&self) -> &EstimatorConfig {
        &self.config
    }

    /// Detections skipped so far as invalid (non-finite, non-positive size,
    /// score outside [0, 1]).
    pub fn invalid_detections(&self) -> u64 {
        self.invalid_detections
    }

    /// How much state the estimator holds now (see [`Footprint`]).
    pub fn footprint(&self) -> Footprint {
        Footprint {
            imu_samples: self.imu.len(),
            map_keyframes: self.map.keyframe_count(),
            map_points: self.map.edge_cloud().len() + self.map.planar_cloud().len(),
            window_frames: self.window_frames.len(),
            tracks: self.tracker.tracks().len(),
            lost_tracks: self.tracker.lost_tracks().len(),
            objects: self.objects.len(),
            bootstrap_frames: self.bootstrap_estimates.len() + self.bootstrap_mids.len(),
        }
    }

    /// The last sweep as it was de-skewed and filtered (`None` before the
    /// first): what a recording of the run shows of each frame, read after
    /// [`Estimator::push_frame`] and before the next.
    pub fn deskewed_sweep(&self) -> Option<DeskewedSweep<'_>> {
        self.last_sweep.as_ref().map(|last| DeskewedSweep {
            frame_index: last.frame_index,
            t_s: last.t_s,
            t_ref_s: last.t_ref_s,
            points_lidar: &self.deskewed,
            removed_feature_indices: &last.removed,
            motion: &last.motion,
        })
    }

    /// True once the ego state is initialised (always, in LiDAR-only mode).
    pub fn is_initialized(&self) -> bool {
        match self.config.mode {
            Mode::LidarOnly => true,
            Mode::LidarInertial => self.latest.is_some(),
        }
    }

    /// Adds one IMU sample. Samples must be finite and strictly increasing in time.
    ///
    /// # Errors
    /// [`EstimatorError::Input`] for a non-finite sample or one not after
    /// the previous sample.
    pub fn push_imu(&mut self, sample: ImuSample) -> Result<(), EstimatorError> {
        sample.validate()?;
        if let Some(last) = self.imu.last()
            && sample.t_s <= last.t_s
        {
            return Err(InputError::ImuTimeNotIncreasing {
                t_s: sample.t_s,
                previous_t_s: last.t_s,
            }
            .into());
        }
        self.imu.push(sample);
        self.prune_imu();
        Ok(())
    }

    /// Processes one frame and returns the estimates it completes, in frame
    /// order: this frame's, except while the inertial state initialises
    /// (IMU mode). Those sweeps run LiDAR-only; nothing is returned for them
    /// until the initialisation, which returns their LiDAR-only estimates
    /// (re-expressed in the gravity-aligned world) before its own. Every
    /// frame gets exactly one estimate unless an error ends the run.
    /// Non-finite points are dropped (a driver's "no return"); a scan must
    /// start after the previous one.
    ///
    /// # Errors
    /// [`EstimatorError::Input`] for a non-finite scan time or duration or a
    /// scan not after the previous one; otherwise the error of the stage
    /// that failed (IMU coverage, de-skew, factors, window, map, tracker),
    /// naming the frame.
    pub fn push_frame(&mut self, frame: &Frame) -> Result<Vec<FrameEstimate>, EstimatorError> {
        let scan = &frame.scan;
        if !scan.t_s.is_finite() {
            return Err(InputError::ScanNotFinite {
                t_s: scan.t_s,
                field: "t_s",
            }
            .into());
        }
        if !scan.sweep_duration_s.is_finite() || scan.sweep_duration_s < 0.0 {
            return Err(InputError::ScanNotFinite {
                t_s: scan.t_s,
                field: "sweep_duration_s",
            }
            .into());
        }
        if let Some(previous) = self.last_scan_t_s
            && scan.t_s <= previous
        {
            return Err(InputError::ScanTimeNotIncreasing {
                t_s: scan.t_s,
                previous_t_s: previous,
            }
            .into());
        }
        self.last_scan_t_s = Some(scan.t_s);
        let frame_index = self.next_frame_index;
        // Detections no detector can produce are skipped (and counted).
        self.frame_detections.clear();
        for (index, detection) in frame.detections.iter().enumerate() {
            if detection
                .validate_in_sweep(scan.t_s, index, scan.sweep_duration_s)
                .is_ok()
            {
                self.frame_detections.push(*detection);
            } else {
                self.invalid_detections += 1;
            }
        }
        self.next_frame_index += 1;
        let finite;
        let scan = if scan.points.iter().all(finite_point) {
            scan
        } else {
            let mut copy = scan.clone();
            copy.points.retain(finite_point);
            finite = copy;
            &finite
        };
        match self.config.mode {
            Mode::LidarOnly => self.process_lidar_only(frame_index, scan).map(|e| vec![e]),
            Mode::LidarInertial => {
                if self.latest.is_none() {
                    self.try_initialize(frame_index, scan)
                } else {
                    self.process_inertial(frame_index, scan).map(|e| vec![e])
                }
            }
        }
    }

    /// Drops IMU samples no future frame needs.
    fn prune_imu(&mut self) {
        if self.imu.len() < 4096 {
            return;
        }
        let keep_from_s = match self.latest {
            Some(state) => state.t_s - 1.0,
            None => self.imu.last().map_or(0.0, |s| s.t_s) - 2.0 * self.config.init_window_s,
        };
        let cut = self.imu.partition_point(|s| s.t_s < keep_from_s);
        // Keep one sample before the cut for interpolation.
        let cut = cut.saturating_sub(1);
        if cut > 0 {
            self.imu.drain(..cut);
        }
    }
}

/// A return the estimator can use (drivers mark "no return" with NaN).
fn finite_point(p: &LidarPoint) -> bool {
    p.x.is_finite() && p.y.is_finite() && p.z.is_finite() && p.time_offset_s.is_finite()
}
