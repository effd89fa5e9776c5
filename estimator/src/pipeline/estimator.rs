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

use super::config::{EstimatorConfig, Mode, Variant};
use super::estimate::{FrameEstimate, ModuleTimings, ScanMatchSummary};
use super::initialization::{MIN_STATIC_SAMPLES, NotStatic, moving_init, static_init};
use super::objects::{ObjectGraph, yaw_of};
use crate::filter::{BoxAtTime, FilterError, OrientedBox, all_boxes_mask, dynamic_feature_mask};
use crate::graph::{
    BiasRandomWalkFactor, ImuFactor, PriorFactor, SlidingWindowSmoother, WindowError,
};
use crate::graph::{FactorError, Key, NoiseModel, Variable};
use crate::imu::ImuBias;
use crate::imu::preintegration::{ImuTrajectory, Preintegration, PreintegrationError};
use crate::input::{Detection, Extrinsics, Frame, ImuSample, InputError, LidarPoint, LidarScan};
use crate::lidar::deskew::{DeskewError, Deskewer, SweepMotion};
use crate::lidar::features::{FeatureExtractor, ScanFeatures};
use crate::lidar::local_map::{LocalMap, LocalMapError};
use crate::lidar::scan_matching::{ScanMatchResult, match_scan};
use crate::lidar::voxel::VoxelDownsampler;
use crate::lie;
use crate::tracking::track::{Lifecycle, Motion, Track};
use crate::tracking::tracker::{TrackOutput, Tracker, TrackerError, WorldDetection};
use nalgebra::{DMatrix, Isometry3, Matrix6, SymmetricEigen, Vector3, Vector6};
use std::collections::VecDeque;
use std::time::Instant;

/// Why the estimator rejected input or could not process a frame.
#[derive(Debug, thiserror::Error)]
pub enum EstimatorError {
    #[error(transparent)]
    Input(#[from] InputError),
    #[error("frame {frame_index} at t={t_s}: IMU data: {source}")]
    Imu {
        frame_index: u64,
        t_s: f64,
        #[source]
        source: PreintegrationError,
    },
    #[error("frame {frame_index} at t={t_s}: de-skew: {source}")]
    Deskew {
        frame_index: u64,
        t_s: f64,
        #[source]
        source: DeskewError,
    },
    #[error("object filter configuration: {0}")]
    FilterConfig(#[source] FilterError),
    #[error(
        "variant limot needs the IMU: its joint graph is the IMU sliding window (LiDAR-only runs take lio, allfilt or dynafilt)"
    )]
    LimotNeedsImu,
    #[error("tracker: {0}")]
    Tracker(#[source] TrackerError),
    #[error("frame {frame_index} at t={t_s}: local map: {source}")]
    Map {
        frame_index: u64,
        t_s: f64,
        #[source]
        source: LocalMapError,
    },
    #[error("frame {frame_index} at t={t_s}: cannot build a factor: {source}")]
    Factor {
        frame_index: u64,
        t_s: f64,
        #[source]
        source: FactorError,
    },
    #[error("frame {frame_index} at t={t_s}: sliding-window optimisation failed: {source}")]
    Graph {
        frame_index: u64,
        t_s: f64,
        #[source]
        source: WindowError,
    },
}

/// The latest optimised ego state.
#[derive(Debug, Clone, Copy)]
struct EgoState {
    frame_index: u64,
    t_s: f64,
    t_world_imu: Isometry3<f64>,
    velocity_world_mps: Vector3<f64>,
    bias: ImuBias,
}

/// A dynamic track's box at any time, from its trajectory fit.
struct TrackBox(Track);

impl BoxAtTime for TrackBox {
    fn box_at(&self, t_s: f64) -> OrientedBox {
        let p = self.0.predict(t_s);
        OrientedBox {
            center_world: p.center_world,
            yaw_rad: p.yaw_rad,
            size_lwh: self.0.size_lwh(),
        }
    }
}

/// Prior sigmas on the first inertial state.
#[derive(Debug, Clone, Copy)]
struct InitSigmas {
    tilt_rad: f64,
    velocity_mps: f64,
}

/// Features of one de-skewed sweep, LiDAR frame at the scan start.
struct SweepFeatures {
    edge_lidar: Vec<Vector3<f64>>,
    planar_lidar: Vec<Vector3<f64>>,
    /// Indices (into the scan's points) of features dropped as object points.
    removed: Vec<u32>,
    /// Every feature index before the filter, when `record_feature_indices`.
    all_indices: Vec<u32>,
}

/// Which feature points to drop before matching (the variants).
enum FeatureFilter {
    /// `lio`: keep everything.
    Keep,
    /// `allfilt`: every detected box, fixed, in the world frame.
    AllBoxes(Vec<OrientedBox>),
    /// `dynafilt`: boxes of dynamic tracks, each at the point's own time.
    Moving(Vec<Box<dyn BoxAtTime>>),
}

/// The streaming estimator. Feed IMU samples in time order with
/// [`Estimator::push_imu`] and frames with [`Estimator::push_frame`] once the
/// IMU covers the sweep (the IMU is extrapolated, with a flag, when it does not).
/// The sizes of what an [`Estimator`] keeps between frames. Each is bounded
/// by the configuration and the scene around the ego (keyframes within the
/// map radius, the sliding window, the objects in view), never by how long
/// it has run: `benches/long_drive.rs` follows them over a long drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Footprint {
    /// IMU samples buffered for preintegration and initialisation.
    pub imu_samples: usize,
    pub map_keyframes: usize,
    /// Edge plus planar points of the local map.
    pub map_points: usize,
    /// Frames in the sliding window.
    pub window_frames: usize,
    pub tracks: usize,
    /// Tracks kept for revival.
    pub lost_tracks: usize,
    /// Objects in the joint graph.
    pub objects: usize,
    /// LiDAR-only frames held until the inertial initialisation.
    pub bootstrap_frames: usize,
}

pub struct Estimator {
    config: EstimatorConfig,
    t_lidar_imu: Isometry3<f64>,
    t_imu_lidar: Isometry3<f64>,
    gravity_world: Vector3<f64>,
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
    /// Fails when a part of the configuration is invalid.
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
            gravity_world: Vector3::new(0.0, 0.0, -config.gravity_mps2),
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
            feature_extractor,
            downsampler: VoxelDownsampler::default(),
            gathered: Vec::new(),
            frame_detections: Vec::new(),
            tracker,
            objects,
            invalid_detections: 0,
        })
    }

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

    /// True once the ego state is initialised (always, in LiDAR-only mode).
    pub fn is_initialized(&self) -> bool {
        match self.config.mode {
            Mode::LidarOnly => true,
            Mode::LidarInertial => self.latest.is_some(),
        }
    }

    /// Adds one IMU sample. Samples must be finite and strictly increasing in time.
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

    /// Before the inertial state exists every sweep runs through LiDAR-only
    /// odometry. The IMU alone cannot tell standing still from driving at a
    /// constant speed, so the static initialisation also needs the LiDAR
    /// poses to stand still; otherwise, after `bootstrap_frames` sweeps,
    /// gravity, velocity and gyroscope bias come from the LiDAR poses and the
    /// IMU ([`moving_init`]). Their estimates wait in `bootstrap_estimates`
    /// and are returned, moved into the inertial world, with the first
    /// inertial estimate.
    fn try_initialize(
        &mut self,
        frame_index: u64,
        scan: &LidarScan,
    ) -> Result<Vec<FrameEstimate>, EstimatorError> {
        let lidar_only = self.process_lidar_only(frame_index, scan)?;
        let t_lidarworld_lidar = lidar_only.t_world_lidar;
        if let Some(&mid) = self.lidar_only_history.back() {
            self.bootstrap_mids.push(mid);
        }
        // A degenerate match (a straight highway with guard rails only) leaves
        // the along-track motion, hence the velocity, unobserved: a moving
        // initialisation may only use the sweeps after it.
        if lidar_only
            .scan_match
            .is_some_and(|m| m.degenerate_directions > 0)
        {
            self.bootstrap_usable_from = self.bootstrap_mids.len();
        }
        self.bootstrap_estimates.push(lidar_only);
        let t0 = scan.t_s - self.config.init_window_s;
        let covered = self.imu.first().is_some_and(|s| s.t_s <= t0 + 0.02);
        if !covered || self.bootstrap_mids.len() < 3 {
            return Ok(Vec::new());
        }
        let lidar_still = {
            let recent = &self.bootstrap_mids[self.bootstrap_mids.len() - 3..];
            let moved = (recent[2].1.translation.vector - recent[0].1.translation.vector).norm();
            moved < self.config.init_max_lidar_motion_m
        };
        let to = self.imu.partition_point(|s| s.t_s <= scan.t_s);
        // The last `init_window_s`, or as many samples back as a static
        // test needs from a slow IMU (KITTI tracking's 10 Hz OXTS: 1 s).
        let from = self
            .imu
            .partition_point(|s| s.t_s < t0)
            .min(to.saturating_sub(MIN_STATIC_SAMPLES));
        let imu_still = static_init(
            &self.imu[from..to],
            &self.t_lidar_imu,
            self.config.gravity_mps2,
            self.config.init_max_accel_std_mps2,
            self.config.init_max_gyro_radps,
        );
        let state = match imu_still {
            Ok(init) if lidar_still => {
                // World origin at this LiDAR pose, z up, LiDAR heading along x.
                let r_world_imu = nalgebra::UnitQuaternion::from_rotation_matrix(&init.r_world_imu);
                let p_world_imu = -(r_world_imu * self.t_imu_lidar.translation.vector);
                let sigmas = InitSigmas {
                    tilt_rad: self.config.init_tilt_sigma_rad,
                    velocity_mps: self.config.init_velocity_sigma_mps,
                };
                let state = EgoState {
                    frame_index,
                    t_s: scan.t_s,
                    t_world_imu: Isometry3::from_parts(p_world_imu.into(), r_world_imu),
                    velocity_world_mps: Vector3::zeros(),
                    bias: ImuBias {
                        accel_mps2: Vector3::zeros(),
                        gyro_radps: init.gyro_bias_radps,
                    },
                };
                (state, sigmas)
            }
            Err(NotStatic::TooFewSamples { .. }) => return Ok(Vec::new()),
            _ => {
                let needed = self.config.bootstrap_frames.max(3);
                if self.bootstrap_mids.len() < self.bootstrap_usable_from + needed {
                    return Ok(Vec::new());
                }
                let first = self.bootstrap_mids.len() - needed;
                let Some(init) = moving_init(
                    &self.bootstrap_mids[first..],
                    &self.imu,
                    &self.t_lidar_imu,
                    self.config.gravity_mps2,
                    self.config.bootstrap_gravity_tolerance_mps2,
                ) else {
                    return Ok(Vec::new());
                };
                let align = Isometry3::from_parts(
                    nalgebra::Translation3::identity(),
                    nalgebra::UnitQuaternion::from_rotation_matrix(&init.r_world_lidarworld),
                );
                let sigmas = InitSigmas {
                    tilt_rad: self.config.bootstrap_tilt_sigma_rad,
                    velocity_mps: self.config.bootstrap_velocity_sigma_mps,
                };
                let state = EgoState {
                    frame_index,
                    t_s: scan.t_s,
                    t_world_imu: align * t_lidarworld_lidar * self.t_lidar_imu,
                    velocity_world_mps: init.r_world_lidarworld * init.velocity_lidarworld_mps,
                    bias: ImuBias {
                        accel_mps2: Vector3::zeros(),
                        gyro_radps: init.gyro_bias_radps,
                    },
                };
                (state, sigmas)
            }
        };
        // Start the inertial map afresh in the gravity-aligned world.
        self.map.clear();
        self.last_keyframe_t_world_lidar = None;
        self.lidar_only_history.clear();
        self.bootstrap_mids.clear();
        self.bootstrap_usable_from = 0;
        let mut first = self.start_inertial(state.0, scan, state.1)?;
        // Everything of the LiDAR-only sweeps, this one's tracks included,
        // moves into the inertial world; the tracker keeps its tracks.
        let t_world_lidarworld = first.t_world_lidar * t_lidarworld_lidar.inverse();
        let clock = Instant::now();
        self.tracker
            .transform_world(&t_world_lidarworld)
            .map_err(EstimatorError::Tracker)?;
        let mut estimates: Vec<FrameEstimate> = self
            .bootstrap_estimates
            .drain(..)
            .map(|e| e.transformed(&t_world_lidarworld))
            .collect();
        // This sweep's LiDAR-only estimate is superseded by the inertial
        // one, which takes its tracks and the time spent tracking them.
        if let Some(this) = estimates.pop() {
            first.tracks = this.tracks;
            first.timings.tracking = this.timings.tracking;
        }
        first.timings.tracking += clock.elapsed();
        estimates.push(first);
        Ok(estimates)
    }

    /// Puts the first inertial state into the window with its priors and
    /// starts the map with this sweep. The estimate has no tracks: the
    /// tracker already took this sweep's detections in the LiDAR-only world.
    fn start_inertial(
        &mut self,
        state: EgoState,
        scan: &LidarScan,
        sigmas: InitSigmas,
    ) -> Result<FrameEstimate, EstimatorError> {
        let frame_index = state.frame_index;
        let mut timings = ModuleTimings::default();
        let motion = self.imu_sweep_motion(&state, scan, &mut timings);
        let motion = motion.map_err(|source| EstimatorError::Deskew {
            frame_index,
            t_s: scan.t_s,
            source,
        })?;
        let filter = self.feature_filter(scan, &motion);
        let features = self.sweep_features(scan, &motion, scan.t_s, &filter, &mut timings);
        let t_world_lidar = state.t_world_imu * self.t_imu_lidar;
        let clock = Instant::now();
        self.update_map(frame_index, scan.t_s, &t_world_lidar, &features, true)?;
        timings.map_update = clock.elapsed();
        // The map starts with this sweep at the initial pose, but a sweep
        // matched to a map built from itself lands a few mm away (lines and
        // planes fitted through the downsampled points of curved or sloped
        // structure): 1.7 mm lateral, 1.0 mm vertical on the sloped highway.
        // Every later match of the still-standing ego carries that offset, so
        // a gauge at the initial pose would contradict all of them, and the
        // window would explain the step with velocity and accelerometer-bias
        // errors (0.017 m/s² lateral). Along a degenerate road direction
        // nothing corrects those later, and they leak into the along-track
        // bias. The first state therefore starts where the matcher puts its
        // own sweep.
        let mut state = state;
        if let Some(m) = self.match_features(&features, &t_world_lidar) {
            state.t_world_imu = m.t_world_lidar * self.t_lidar_imu;
        }
        let t_world_lidar = state.t_world_imu * self.t_imu_lidar;
        let t_world_imu = state.t_world_imu;
        let window_error = |source| EstimatorError::Graph {
            frame_index,
            t_s: scan.t_s,
            source,
        };
        let c = self.config.clone();
        self.smoother
            .add_variable(Key::EgoPose(frame_index), Variable::Pose(t_world_imu))
            .map_err(&window_error)?;
        self.smoother
            .add_variable(
                Key::EgoVelocity(frame_index),
                Variable::Vector3(state.velocity_world_mps),
            )
            .map_err(&window_error)?;
        self.smoother
            .add_variable(Key::EgoBias(frame_index), Variable::Bias(state.bias))
            .map_err(&window_error)?;
        // The gauge (position, yaw) is fixed tightly; roll and pitch come from gravity.
        let gauge = 1e-3;
        self.smoother
            .add_factor(Box::new(PriorFactor::new(
                Key::EgoPose(frame_index),
                Variable::Pose(t_world_imu),
                NoiseModel::diagonal_sigmas(&[
                    gauge,
                    gauge,
                    gauge,
                    sigmas.tilt_rad,
                    sigmas.tilt_rad,
                    gauge,
                ]),
            )))
            .map_err(&window_error)?;
        self.smoother
            .add_factor(Box::new(PriorFactor::new(
                Key::EgoVelocity(frame_index),
                Variable::Vector3(state.velocity_world_mps),
                NoiseModel::diagonal_sigmas(&[sigmas.velocity_mps; 3]),
            )))
            .map_err(&window_error)?;
        let ab = c.init_accel_bias_sigma_mps2;
        let gb = c.init_gyro_bias_sigma_radps;
        self.smoother
            .add_factor(Box::new(PriorFactor::new(
                Key::EgoBias(frame_index),
                Variable::Bias(state.bias),
                NoiseModel::diagonal_sigmas(&[ab, ab, ab, gb, gb, gb]),
            )))
            .map_err(&window_error)?;
        self.window_frames.push_back(frame_index);
        self.latest = Some(state);
        Ok(FrameEstimate {
            frame_index,
            t_s: scan.t_s,
            t_world_lidar,
            velocity_world_mps: state.velocity_world_mps,
            bias: state.bias,
            scan_match: None,
            removed_feature_indices: features.removed.clone(),
            feature_indices: features.all_indices.clone(),
            tracks: Vec::new(),
            timings,
        })
    }

    fn process_inertial(
        &mut self,
        frame_index: u64,
        scan: &LidarScan,
    ) -> Result<FrameEstimate, EstimatorError> {
        let previous = self.latest.expect("initialised");
        let mut timings = ModuleTimings::default();
        let t_s = scan.t_s;
        let imu_error = |source| EstimatorError::Imu {
            frame_index,
            t_s,
            source,
        };

        let clock = Instant::now();
        let preintegration = Preintegration::from_samples(
            &self.imu,
            previous.t_s,
            t_s,
            previous.bias,
            self.config.imu_noise,
            self.config.max_imu_gap_s,
        )
        .map_err(imu_error)?;
        let (t_world_imu_pred, velocity_pred) = preintegration.predict(
            &previous.t_world_imu,
            &previous.velocity_world_mps,
            &previous.bias,
            &self.gravity_world,
        );
        let predicted = EgoState {
            frame_index,
            t_s,
            t_world_imu: t_world_imu_pred,
            velocity_world_mps: velocity_pred,
            bias: previous.bias,
        };
        timings.imu_prediction = clock.elapsed();

        let motion = self
            .imu_sweep_motion(&predicted, scan, &mut timings)
            .map_err(|source| EstimatorError::Deskew {
                frame_index,
                t_s,
                source,
            })?;
        let filter = self.feature_filter(scan, &motion);
        let features = self.sweep_features(scan, &motion, scan.t_s, &filter, &mut timings);

        let clock = Instant::now();
        let initial_t_world_lidar = t_world_imu_pred * self.t_imu_lidar;
        let matched = self.match_features(&features, &initial_t_world_lidar);
        timings.scan_matching = clock.elapsed();

        let clock = Instant::now();
        let j = previous.frame_index;
        let k = frame_index;
        let window_error = |source| EstimatorError::Graph {
            frame_index,
            t_s,
            source,
        };
        self.smoother
            .add_variable(Key::EgoPose(k), Variable::Pose(t_world_imu_pred))
            .map_err(&window_error)?;
        self.smoother
            .add_variable(Key::EgoVelocity(k), Variable::Vector3(velocity_pred))
            .map_err(&window_error)?;
        self.smoother
            .add_variable(Key::EgoBias(k), Variable::Bias(previous.bias))
            .map_err(&window_error)?;
        let dt_s = preintegration.delta_t_s();
        let factor_error = |source| EstimatorError::Factor {
            frame_index,
            t_s,
            source,
        };
        let imu_factor =
            ImuFactor::new(j, k, preintegration, self.gravity_world).map_err(factor_error)?;
        let bias_factor =
            BiasRandomWalkFactor::new(j, k, dt_s, &self.config.imu_noise).map_err(factor_error)?;
        self.smoother
            .add_factor(Box::new(imu_factor))
            .map_err(&window_error)?;
        self.smoother
            .add_factor(Box::new(bias_factor))
            .map_err(&window_error)?;
        if let Some(result) = &matched {
            // LiDAR odometry (the paper's r_odo): the scan-to-map result is a
            // pose in the map, i.e. world, frame, so it constrains this state
            // directly (with the map's keyframe poses held fixed, r_odo between
            // the map anchor and this frame reduces to it). Relative factors
            // between consecutive matches would let the estimate drift from
            // the map; relative to the previous *estimate* they would feed its
            // own corrections back as measurements (unstable).
            let t_world_imu_matched = result.t_world_lidar * self.t_lidar_imu;
            if let Some(noise) = self.odometry_noise(result) {
                self.smoother
                    .add_factor(Box::new(PriorFactor::new(
                        Key::EgoPose(k),
                        Variable::Pose(t_world_imu_matched),
                        noise,
                    )))
                    .map_err(&window_error)?;
            }
        }
        // limot: the tracker runs before the graph (on the matched pose) so
        // the confirmed objects join this frame's optimization.
        let mut joint_tracks = None;
        if self.config.variant == Variant::Limot {
            let clock = Instant::now();
            let guess = matched
                .as_ref()
                .map_or(initial_t_world_lidar, |m| m.t_world_lidar);
            let tracks = self.track_objects(t_s, &guess, &motion)?;
            self.objects
                .add_frame(
                    &mut self.smoother,
                    k,
                    self.window_frames.back().copied(),
                    t_s,
                    &tracks,
                    &self.frame_detections,
                    &motion,
                    &guess,
                    &self.t_imu_lidar,
                )
                .map_err(&window_error)?;
            joint_tracks = Some((tracks, clock.elapsed()));
        }
        self.window_frames.push_back(k);
        if joint_tracks.is_some() && !self.config.objects.dynamic_objects_inform_ego {
            // Dynamic objects do not move the ego, so the window splits into
            // independent parts: the ego's (with static objects) is solved
            // first, the dynamic objects' observations are then conditioned
            // on that estimate, and each object is solved on its own.
            let has_ego = |keys: &[Key]| keys.iter().any(|k| matches!(k, Key::EgoPose(_)));
            self.smoother
                .optimize_parts(&self.config.solver, has_ego)
                .map_err(&window_error)?;
            self.smoother.refresh_conditioned();
            self.smoother
                .optimize_parts(&self.config.objects.solver, |keys| !has_ego(keys))
                .map_err(&window_error)?;
        } else {
            self.smoother
                .optimize(&self.config.solver)
                .map_err(&window_error)?;
        }
        while self.window_frames.len() > self.config.window_size.max(2) {
            let oldest = self.window_frames.pop_front().expect("non-empty window");
            self.objects
                .condition_oldest(&mut self.smoother, oldest)
                .map_err(&window_error)?;
            self.smoother
                .marginalize_frame(oldest)
                .map_err(&window_error)?;
            self.objects
                .after_marginalize(&mut self.smoother, oldest)
                .map_err(&window_error)?;
        }
        let values = self.smoother.values();
        let state = EgoState {
            frame_index: k,
            t_s,
            t_world_imu: *values.pose(&Key::EgoPose(k)),
            velocity_world_mps: *values.vector3(&Key::EgoVelocity(k)),
            bias: *values.bias(&Key::EgoBias(k)),
        };
        self.latest = Some(state);
        timings.graph = clock.elapsed();

        let t_world_lidar = state.t_world_imu * self.t_imu_lidar;
        let clock = Instant::now();
        self.update_map(frame_index, scan.t_s, &t_world_lidar, &features, false)?;
        timings.map_update = clock.elapsed();
        let clock = Instant::now();
        let tracks = match joint_tracks {
            Some((tracks, tracking_time)) => {
                timings.tracking = tracking_time;
                self.with_object_estimates(tracks, k, t_s)
            }
            None => {
                let tracks = self.track_objects(t_s, &t_world_lidar, &motion)?;
                timings.tracking = clock.elapsed();
                tracks
            }
        };
        Ok(FrameEstimate {
            frame_index,
            t_s,
            t_world_lidar,
            velocity_world_mps: state.velocity_world_mps,
            bias: state.bias,
            scan_match: matched.as_ref().map(|m| summary(m, &features)),
            removed_feature_indices: features.removed.clone(),
            feature_indices: features.all_indices.clone(),
            tracks,
            timings,
        })
    }

    fn process_lidar_only(
        &mut self,
        frame_index: u64,
        scan: &LidarScan,
    ) -> Result<FrameEstimate, EstimatorError> {
        let mut timings = ModuleTimings::default();
        let t_s = scan.t_s;
        let clock = Instant::now();
        // Without an IMU the sweep is de-skewed to its MIDDLE and matched
        // there, and the constant-velocity model runs on mid-sweep poses: a
        // velocity error then distorts the cloud symmetrically instead of
        // shifting it, which would feed the error back through the
        // prediction (an oscillation that grows).
        let half_s = 0.5 * scan.sweep_duration_s.max(1e-3);
        let mid_s = t_s + half_s;
        let (predicted_mid, twist_per_s) = match (
            self.lidar_only_history.front(),
            self.lidar_only_history.back(),
        ) {
            (Some(&(t_a, pose_a)), Some(&(t_b, pose_b))) if t_b > t_a => {
                let twist = lie::se3_log(&(pose_a.inverse() * pose_b)) / (t_b - t_a);
                (pose_b * lie::se3_exp(&(twist * (mid_s - t_b))), twist)
            }
            (_, Some(&(_, pose_b))) => (pose_b, Vector6::zeros()),
            _ => (Isometry3::identity(), Vector6::zeros()),
        };
        timings.imu_prediction = clock.elapsed();
        // When the match moves far from the prediction (start-up, sudden
        // acceleration), the de-skew used the wrong velocity: redo it with the
        // velocity the match implies and match again.
        let mut guess_mid = predicted_mid;
        let mut twist_per_s = twist_per_s;
        let mut features;
        let mut matched;
        let mut rounds = 0;
        loop {
            let motion = SweepMotion::constant_velocity(
                t_s,
                guess_mid * lie::se3_exp(&(-twist_per_s * half_s)),
                mid_s + half_s,
                guess_mid * lie::se3_exp(&(twist_per_s * half_s)),
            )
            .map_err(|source| EstimatorError::Deskew {
                frame_index,
                t_s,
                source,
            })?;
            let filter = self.feature_filter(scan, &motion);
            features = self.sweep_features(scan, &motion, mid_s, &filter, &mut timings);
            let clock = Instant::now();
            matched = self.match_features(&features, &guess_mid);
            timings.scan_matching += clock.elapsed();
            rounds += 1;
            let (Some(m), Some(&(t_b, pose_b))) = (&matched, self.lidar_only_history.back()) else {
                break;
            };
            let change = lie::se3_log(&(guess_mid.inverse() * m.t_world_lidar));
            let small = lie::xi_rho(&change).norm() < self.config.redeskew_translation_m
                && lie::xi_phi(&change).norm() < self.config.redeskew_rotation_rad;
            if small || rounds > self.config.max_redeskew_rounds || mid_s <= t_b {
                break;
            }
            twist_per_s = lie::se3_log(&(pose_b.inverse() * m.t_world_lidar)) / (mid_s - t_b);
            guess_mid = m.t_world_lidar;
        }
        let t_world_lidar_mid = matched.as_ref().map_or(predicted_mid, |m| m.t_world_lidar);
        // The reported state is at the scan start, like the IMU mode's.
        let t_world_lidar = t_world_lidar_mid * lie::se3_exp(&(-twist_per_s * half_s));
        let velocity_world_mps = match self.lidar_only_history.back() {
            Some(&(t_b, pose_b)) if mid_s > t_b => {
                (t_world_lidar_mid.translation.vector - pose_b.translation.vector) / (mid_s - t_b)
            }
            _ => Vector3::zeros(),
        };
        self.lidar_only_history
            .push_back((mid_s, t_world_lidar_mid));
        while self.lidar_only_history.len() > 2 {
            self.lidar_only_history.pop_front();
        }
        let clock = Instant::now();
        self.update_map(frame_index, scan.t_s, &t_world_lidar_mid, &features, false)?;
        timings.map_update = clock.elapsed();
        let clock = Instant::now();
        let final_motion = SweepMotion::constant_velocity(
            t_s,
            t_world_lidar,
            t_s + 2.0 * half_s,
            t_world_lidar * lie::se3_exp(&(twist_per_s * 2.0 * half_s)),
        )
        .map_err(|source| EstimatorError::Deskew {
            frame_index,
            t_s,
            source,
        })?;
        let tracks = self.track_objects(t_s, &t_world_lidar, &final_motion)?;
        timings.tracking = clock.elapsed();
        Ok(FrameEstimate {
            frame_index,
            t_s,
            t_world_lidar,
            velocity_world_mps,
            bias: ImuBias::default(),
            scan_match: matched.as_ref().map(|m| summary(m, &features)),
            removed_feature_indices: features.removed.clone(),
            feature_indices: features.all_indices.clone(),
            tracks,
            timings,
        })
    }

    /// LiDAR poses over the sweep from IMU propagation of `start` (a state at
    /// the scan start). Instants past the end of the IMU data are left out;
    /// [`SweepMotion`] extrapolates with the last segment's velocity there.
    fn imu_sweep_motion(
        &self,
        start: &EgoState,
        scan: &LidarScan,
        timings: &mut ModuleTimings,
    ) -> Result<SweepMotion, DeskewError> {
        let clock = Instant::now();
        let n = self.config.deskew_samples.max(2);
        let last_imu_s = self.imu.last().map_or(start.t_s, |s| s.t_s);
        let sweep_end_s = (start.t_s + scan.sweep_duration_s).min(last_imu_s);
        let mut samples = vec![(start.t_s, start.t_world_imu * self.t_imu_lidar)];
        if sweep_end_s > start.t_s
            && let Ok(trajectory) = ImuTrajectory::propagate(
                &self.imu,
                start.t_s,
                sweep_end_s,
                &start.t_world_imu,
                &start.velocity_world_mps,
                &start.bias,
                &self.gravity_world,
                self.config.max_imu_gap_s,
            )
        {
            for i in 1..n {
                let t = start.t_s + (sweep_end_s - start.t_s) * i as f64 / (n - 1) as f64;
                if let Ok(t_world_imu) = trajectory.pose_at(t) {
                    samples.push((t, t_world_imu * self.t_imu_lidar));
                }
            }
        }
        if samples.len() == 1 {
            // No IMU inside the sweep: constant velocity from the state.
            let end_s = start.t_s + scan.sweep_duration_s.max(1e-3);
            let mut t_end = start.t_world_imu;
            t_end.translation.vector += start.velocity_world_mps * (end_s - start.t_s);
            samples.push((end_s, t_end * self.t_imu_lidar));
        }
        let motion = SweepMotion::from_poses(samples);
        timings.imu_prediction += clock.elapsed();
        motion
    }

    /// De-skews to the scan start, extracts LOAM features and downsamples them.
    fn sweep_features(
        &mut self,
        scan: &LidarScan,
        motion: &SweepMotion,
        t_ref_s: f64,
        filter: &FeatureFilter,
        timings: &mut ModuleTimings,
    ) -> SweepFeatures {
        let clock = Instant::now();
        self.deskewed.clear();
        self.deskewer
            .deskew(scan, motion, t_ref_s, &mut self.deskewed);
        timings.deskew = clock.elapsed();

        let clock = Instant::now();
        let mut features = self.feature_extractor.extract(&self.deskewed, scan);
        timings.features = clock.elapsed();

        let all_indices = if self.config.record_feature_indices {
            let mut all: Vec<u32> = features
                .edge_indices
                .iter()
                .chain(&features.planar_indices)
                .map(|&i| i as u32)
                .collect();
            all.sort_unstable();
            all
        } else {
            Vec::new()
        };
        let clock = Instant::now();
        let removed = self.filter_features(scan, motion, filter, &mut features);
        timings.filter = clock.elapsed();

        let clock = Instant::now();
        let deskewed = &self.deskewed;
        self.gathered.clear();
        self.gathered
            .extend(features.edge_indices.iter().map(|&i| deskewed[i]));
        let edge_lidar = self
            .downsampler
            .downsample(&self.gathered, self.config.edge_voxel_m);
        self.gathered.clear();
        self.gathered
            .extend(features.planar_indices.iter().map(|&i| deskewed[i]));
        let planar_lidar = self
            .downsampler
            .downsample(&self.gathered, self.config.planar_voxel_m);
        let result = SweepFeatures {
            edge_lidar,
            planar_lidar,
            removed,
            all_indices,
        };
        timings.downsample = clock.elapsed();
        result
    }

    /// The variant's object boxes for this sweep.
    fn feature_filter(&self, scan: &LidarScan, motion: &SweepMotion) -> FeatureFilter {
        match self.config.variant {
            Variant::Lio => FeatureFilter::Keep,
            Variant::Allfilt => FeatureFilter::AllBoxes(
                self.frame_detections
                    .iter()
                    .map(|d| {
                        OrientedBox::from_detection(d, &motion.pose_at(scan.t_s + d.time_offset_s))
                    })
                    .collect(),
            ),
            Variant::Dynafilt | Variant::Limot => FeatureFilter::Moving(
                self.tracker
                    .tracks()
                    .iter()
                    .filter(|t| {
                        t.motion() == Motion::Dynamic
                            && (t.lifecycle() == Lifecycle::Confirmed
                                || !self.config.filter_confirmed_only)
                    })
                    .map(|t| Box::new(TrackBox(t.clone())) as Box<dyn BoxAtTime>)
                    .collect(),
            ),
        }
    }

    /// The tracks with the joint graph's smoothed pose and velocity for the
    /// objects it holds at frame `frame` (moved from each node's detection
    /// time to the frame time `t_s` with its velocity).
    fn with_object_estimates(
        &self,
        mut tracks: Vec<TrackOutput>,
        frame: u64,
        t_s: f64,
    ) -> Vec<TrackOutput> {
        let estimates = self.objects.estimates(&self.smoother, frame, t_s);
        for track in &mut tracks {
            if let Some(e) = estimates.get(&track.id) {
                // A chain's first node has no pose change yet: the tracker's
                // velocity moves it to the frame time.
                let v = e.velocity_world_mps.unwrap_or(track.velocity_world_mps);
                track.center_world = e.t_world_object.translation.vector - v * (e.t_s - t_s);
                track.yaw_rad = yaw_of(&e.t_world_object);
                track.velocity_world_mps = v;
            }
        }
        tracks
    }

    /// Moves the frame's detections into the world with the pose of the
    /// LiDAR when it saw each of them (`t_world_lidar` at the scan start,
    /// moved within the sweep by `motion`) and updates the tracker.
    fn track_objects(
        &mut self,
        t_s: f64,
        t_world_lidar: &Isometry3<f64>,
        motion: &SweepMotion,
    ) -> Result<Vec<TrackOutput>, EstimatorError> {
        let start_inv = motion.pose_at(t_s).inverse();
        let detections: Vec<WorldDetection> = self
            .frame_detections
            .iter()
            .map(|d| {
                let pose = t_world_lidar * start_inv * motion.pose_at(t_s + d.time_offset_s);
                let heading = pose.rotation * Vector3::new(d.yaw_rad.cos(), d.yaw_rad.sin(), 0.0);
                WorldDetection {
                    center_world: (pose * nalgebra::Point3::from(d.center_lidar)).coords,
                    size_lwh: d.size_lwh,
                    yaw_rad: heading.y.atan2(heading.x),
                    class: d.class,
                    score: d.score,
                    time_offset_s: d.time_offset_s,
                }
            })
            .collect();
        self.tracker
            .update(t_s, &detections)
            .map_err(EstimatorError::Tracker)
    }

    /// Drops the feature points that lie in the variant's object boxes,
    /// testing each RAW point at its own time against the box then (the
    /// ego pose comes from the sweep motion). Returns the dropped indices.
    fn filter_features(
        &self,
        scan: &LidarScan,
        motion: &SweepMotion,
        filter: &FeatureFilter,
        features: &mut ScanFeatures,
    ) -> Vec<u32> {
        if matches!(filter, FeatureFilter::Keep) {
            return Vec::new();
        }
        // Edge features first, then planar: mask[..n_edge] belongs to the
        // edge list, mask[n_edge..] to the planar list.
        let n_edge = features.edge_indices.len();
        let indices = || features.edge_indices.iter().chain(&features.planar_indices);
        let points: Vec<Vector3<f64>> = indices().map(|&i| scan.points[i].position()).collect();
        let times: Vec<f64> = indices()
            .map(|&i| scan.t_s + f64::from(scan.points[i].time_offset_s))
            .collect();
        let pose_at = |t: f64| motion.pose_at(t);
        let mask = match filter {
            FeatureFilter::Keep => return Vec::new(),
            FeatureFilter::AllBoxes(boxes) => {
                all_boxes_mask(&points, &times, &pose_at, boxes, &self.config.filter)
            }
            FeatureFilter::Moving(boxes) => {
                let refs: Vec<&dyn BoxAtTime> = boxes.iter().map(|b| b.as_ref()).collect();
                dynamic_feature_mask(&points, &times, &pose_at, &refs, &self.config.filter)
            }
        };
        // The inputs are finite and equally long and the config is
        // validated at construction, so the filter cannot fail here.
        let mask = mask.unwrap_or_else(|_| vec![false; points.len()]);
        if !mask.contains(&true) {
            return Vec::new();
        }
        let mut removed: Vec<u32> = indices()
            .zip(&mask)
            .filter(|(_, drop)| **drop)
            .map(|(&i, _)| i as u32)
            .collect();
        removed.sort_unstable();
        removed.dedup();
        // The mask depends on a point's position and time only, so an index
        // listed twice gets the same verdict at both places.
        let (edge_mask, planar_mask) = mask.split_at(n_edge);
        let mut edge_drop = edge_mask.iter();
        features
            .edge_indices
            .retain(|_| !edge_drop.next().copied().unwrap_or(false));
        let mut planar_drop = planar_mask.iter();
        features
            .planar_indices
            .retain(|_| !planar_drop.next().copied().unwrap_or(false));
        removed
    }

    fn match_features(
        &self,
        features: &SweepFeatures,
        initial_t_world_lidar: &Isometry3<f64>,
    ) -> Option<ScanMatchResult> {
        if self.map.is_empty() {
            return None;
        }
        match_scan(
            &self.map,
            &features.edge_lidar,
            &features.planar_lidar,
            initial_t_world_lidar,
            &self.config.scan_match,
        )
        .ok()
    }

    /// The matching information moved to the IMU pose tangent, scaled by the
    /// point sigma and inflation, with degenerate directions floored.
    fn odometry_noise(&self, result: &ScanMatchResult) -> Option<NoiseModel> {
        let c = &self.config;
        let scale = 1.0 / (c.point_sigma_m * c.point_sigma_m * c.odometry_information_inflation);
        // ξ_lidar = Ad(T_lidar_imu)·ξ_imu for a right perturbation of t_world_imu.
        let ad = lie::se3_adjoint(&self.t_lidar_imu);
        let info_imu: Matrix6<f64> = ad.transpose() * (result.information * scale) * ad;
        let sym = (info_imu + info_imu.transpose()) * 0.5;
        let eigen = SymmetricEigen::new(sym);
        let floored = eigen.eigenvalues.map(|v| v.max(c.odometry_min_information));
        let info =
            eigen.eigenvectors * Matrix6::from_diagonal(&floored) * eigen.eigenvectors.transpose();
        NoiseModel::from_information(&DMatrix::from_column_slice(6, 6, info.as_slice()))
    }

    /// Adds the sweep's features to the local map when it is a keyframe
    /// (enough motion since the last one) or when `force`d (the first sweep).
    fn update_map(
        &mut self,
        frame_index: u64,
        t_s: f64,
        t_world_lidar: &Isometry3<f64>,
        features: &SweepFeatures,
        force: bool,
    ) -> Result<(), EstimatorError> {
        if !force && !self.is_keyframe(t_world_lidar) {
            return Ok(());
        }
        self.add_keyframe(t_world_lidar, features)
            .map_err(|source| EstimatorError::Map {
                frame_index,
                t_s,
                source,
            })
    }

    fn is_keyframe(&self, t_world_lidar: &Isometry3<f64>) -> bool {
        match &self.last_keyframe_t_world_lidar {
            None => true,
            Some(last) => {
                let delta = last.inverse() * t_world_lidar;
                delta.translation.vector.norm() >= self.config.keyframe_distance_m
                    || delta.rotation.angle() >= self.config.keyframe_angle_rad
            }
        }
    }

    fn add_keyframe(
        &mut self,
        t_world_lidar: &Isometry3<f64>,
        features: &SweepFeatures,
    ) -> Result<(), LocalMapError> {
        if features.edge_lidar.is_empty() && features.planar_lidar.is_empty() {
            return Ok(());
        }
        self.map
            .add_keyframe(t_world_lidar, &features.edge_lidar, &features.planar_lidar)?;
        self.last_keyframe_t_world_lidar = Some(*t_world_lidar);
        Ok(())
    }
}

/// A return the estimator can use (drivers mark "no return" with NaN).
fn finite_point(p: &LidarPoint) -> bool {
    p.x.is_finite() && p.y.is_finite() && p.z.is_finite() && p.time_offset_s.is_finite()
}

fn summary(result: &ScanMatchResult, features: &SweepFeatures) -> ScanMatchSummary {
    ScanMatchSummary {
        edge_features: features.edge_lidar.len(),
        planar_features: features.planar_lidar.len(),
        edge_matches: result.edge_matches,
        planar_matches: result.planar_matches,
        iterations: result.iterations,
        converged: result.converged,
        degenerate_directions: result.degenerate_directions,
        rms_residual_m: result.rms_residual_m,
    }
}
