//! A dataset opened for the estimator, and the order in which its IMU
//! samples and scans reach it.
//!
//! Sources: a limot dataset (LiDAR, IMU, detections, extrinsics), a KITTI raw
//! drive (`velodyne_points/` + `oxts/`; the IMU is used when the date
//! directory's `calib_imu_to_velo.txt` is next to the drive), a directory of
//! bare KITTI scans (LiDAR only), a sequence of a KITTI tracking directory
//! (scans, 10 Hz OXTS, detections) or a ROS 2 bag ([`RosBag`]).

use crate::io::kitti::KittiError;
use crate::io::kitti::calib::Calib;
use crate::io::kitti::detections::{ScoreMap, detections_by_frame, read_ab3dmot_csv};
use crate::io::kitti::raw::{RawCalib, RawDrive, nominal_period_s};
use crate::io::kitti::velodyne::{raise_elevation, sweep_time_offset_s};
use crate::io::rosbag::{BagError, BagOptions, RosBag};
use limot_estimator::imu::ImuNoise;
use limot_estimator::input::{Detection, Extrinsics, Frame, ImuSample};
use limot_sim::record::{Dataset, RecordError};
use std::fs;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// IMU history handed to the estimator before the first frame, s: enough
/// for the initialisation, not the whole past (when a run starts mid-sequence).
pub const IMU_LOOKBACK_S: f64 = 0.6;

/// Slack on a sweep's end time when deciding which IMU samples are due
/// before the sweep, s: a sample stamped at the sweep end up to rounding
/// of the stored times still belongs to it.
pub const SWEEP_END_TOLERANCE_S: f64 = 1e-9;

/// The IMU-gap limit is at least this many nominal IMU periods (see
/// [`imu_gap_limit_s`]).
pub const IMU_GAP_PERIODS: f64 = 1.5;

/// Why a source could not be opened or a frame of it read.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// The limot dataset could not be read.
    #[error(transparent)]
    Dataset(#[from] RecordError),
    /// A KITTI file could not be read (it names the file, line and field).
    #[error(transparent)]
    Kitti(#[from] KittiError),
    /// A ROS 2 bag could not be read (it names the topic, message and field).
    #[error(transparent)]
    Bag(#[from] BagError),
    /// The path is none of the known layouts.
    #[error(
        "{path}: not a limot dataset (meta.toml), a KITTI raw drive (velodyne_points/) or a directory of KITTI .bin scans"
    )]
    UnknownSource {
        /// The directory given.
        path: PathBuf,
    },
    /// The directory could not be listed.
    #[error("{path}: {source}")]
    Io {
        /// The directory.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
}

/// Where the frames come from.
pub enum Source {
    /// A limot dataset (`limot simulate`'s output).
    Dataset(Box<Dataset>),
    /// A KITTI raw drive, a directory of bare scans or a KITTI tracking sequence.
    Kitti {
        /// The scans and OXTS records.
        drive: Box<RawDrive>,
        /// The OXTS records as IMU samples (empty for bare scans).
        imu: Vec<ImuSample>,
        /// IMU-LiDAR extrinsics, when a calibration was found.
        extrinsics: Option<Extrinsics>,
        /// Detections per frame (LiDAR frame), empty when none were given.
        detections: Vec<Vec<Detection>>,
    },
    /// A ROS 2 bag (MCAP).
    Bag(Box<RosBag>),
}

impl Source {
    /// Detects the kind of `path` and opens it: a limot dataset (`meta.toml`),
    /// a KITTI raw drive (`velodyne_points/`) or a directory of `.bin`/`.txt` scans.
    ///
    /// # Errors
    /// An unreadable or malformed dataset or drive (named), or a directory of
    /// none of these kinds ([`SourceError::UnknownSource`]).
    pub fn open(path: &Path) -> Result<Source, SourceError> {
        if path.join("meta.toml").is_file() {
            return Ok(Source::Dataset(Box::new(Dataset::open(path)?)));
        }
        if path.join("velodyne_points").is_dir() {
            let drive = RawDrive::open(path)?;
            let extrinsics = path
                .parent()
                .filter(|date| date.join(RawCalib::IMU_TO_VELO).is_file())
                .map(RawCalib::read)
                .transpose()?
                .map(|calib| Extrinsics {
                    t_lidar_imu: calib.t_velo_imu,
                });
            let imu = drive.imu_samples();
            return Ok(Source::Kitti {
                drive: Box::new(drive),
                imu,
                extrinsics,
                detections: Vec::new(),
            });
        }
        let has_scans = fs::read_dir(path)
            .map_err(|source| SourceError::Io {
                path: path.to_path_buf(),
                source,
            })?
            .filter_map(|e| e.ok())
            .any(|e| {
                e.path()
                    .extension()
                    .is_some_and(|x| x == "bin" || x == "txt")
            });
        if has_scans {
            let drive = RawDrive::open_bare_scans(path)?;
            return Ok(Source::Kitti {
                drive: Box::new(drive),
                imu: Vec::new(),
                extrinsics: None,
                detections: Vec::new(),
            });
        }
        Err(SourceError::UnknownSource {
            path: path.to_path_buf(),
        })
    }

    /// Sequence `sequence` of a KITTI tracking directory (see
    /// [`RawDrive::open_tracking_sequence`]): scans, the OXTS IMU (10 Hz),
    /// `calib/SSSS.txt` for the IMU-LiDAR extrinsics and the detections'
    /// frame, and AB3DMOT-format detections (camera frame) from
    /// `detections`, or from `DIR/detections/SSSS.txt` when that exists.
    /// Each detection is placed at the time the laser swept its centre.
    ///
    /// # Errors
    /// A missing or malformed scan, OXTS, calibration or detection file
    /// (named), or detections for frames beyond the scans.
    pub fn open_kitti_tracking(
        dir: &Path,
        sequence: u32,
        detections: Option<&Path>,
        score_map: ScoreMap,
    ) -> Result<Source, SourceError> {
        let drive = RawDrive::open_tracking_sequence(dir, sequence)?;
        let calib = Calib::read(&dir.join("calib").join(format!("{sequence:04}.txt")))?;
        let default_detections = dir.join("detections").join(format!("{sequence:04}.txt"));
        let detections_path = match detections {
            Some(p) if p.is_dir() => Some(p.join(format!("{sequence:04}.txt"))),
            Some(p) => Some(p.to_path_buf()),
            None => default_detections.is_file().then_some(default_detections),
        };
        let detections = match detections_path {
            Some(path) => {
                let camera = read_ab3dmot_csv(&path)?;
                let mut frames = detections_by_frame(&camera, &calib, score_map, drive.num_scans());
                if frames.len() > drive.num_scans() {
                    return Err(SourceError::Kitti(KittiError::Invalid {
                        path,
                        why: format!(
                            "detections for frame {} but the sequence has {} scans",
                            frames.len() - 1,
                            drive.num_scans()
                        ),
                    }));
                }
                for d in frames.iter_mut().flatten() {
                    // The boxes were found in the stored points: they get the
                    // scans' elevation correction too.
                    d.box_lidar.center =
                        raise_elevation(&d.box_lidar.center, drive.elevation_correction_rad);
                    d.time_offset_s = sweep_time_offset_s(&d.box_lidar.center);
                }
                frames
            }
            None => Vec::new(),
        };
        let imu = drive.imu_samples();
        Ok(Source::Kitti {
            drive: Box::new(drive),
            imu,
            extrinsics: Some(Extrinsics {
                t_lidar_imu: calib.t_velo_imu,
            }),
            detections,
        })
    }

    /// The ROS 2 bag `path` with the topics and extrinsic of `options`
    /// (see [`RosBag::open`]).
    ///
    /// # Errors
    /// As [`RosBag::open`].
    pub fn open_bag(path: &Path, options: &BagOptions) -> Result<Source, SourceError> {
        Ok(Source::Bag(Box::new(RosBag::open(path, options)?)))
    }

    /// Number of frames (LiDAR sweeps).
    pub fn frame_count(&self) -> usize {
        match self {
            Source::Dataset(d) => d.frame_count(),
            Source::Kitti { drive, .. } => drive.num_scans(),
            Source::Bag(bag) => bag.frame_count(),
        }
    }

    /// IMU samples and extrinsics, or `None` when the source has no usable IMU.
    pub fn imu(&self) -> Option<(&[ImuSample], Extrinsics)> {
        match self {
            Source::Dataset(d) => Some((&d.imu, d.extrinsics())),
            Source::Kitti {
                imu, extrinsics, ..
            } => match extrinsics {
                Some(e) if !imu.is_empty() => Some((imu, *e)),
                _ => None,
            },
            Source::Bag(bag) => (!bag.imu().is_empty()).then(|| (bag.imu(), bag.extrinsics())),
        }
    }

    /// Frame `index`: its scan and detections (a bag is streamed up to it:
    /// [`Source::for_each_frame`] reads many at once).
    ///
    /// # Errors
    /// An unreadable or malformed scan (named).
    pub fn frame(&self, index: usize) -> Result<Frame, SourceError> {
        Ok(match self {
            Source::Dataset(d) => d.input_frame(index)?,
            Source::Kitti {
                drive, detections, ..
            } => Frame {
                scan: drive.scan(index)?,
                detections: detections.get(index).cloned().unwrap_or_default(),
            },
            Source::Bag(bag) => bag.frame(index)?,
        })
    }

    /// The frames `first .. first + max_frames` that exist (all from `first`
    /// when `max_frames` is `None`).
    pub fn frame_range(&self, first: usize, max_frames: Option<usize>) -> Range<usize> {
        let first = first.min(self.frame_count());
        let end = max_frames.map_or(self.frame_count(), |m| (first + m).min(self.frame_count()));
        first..end
    }

    /// Calls `consume(index, frame)` for every frame of `frames`, in order.
    /// A reader thread decodes frame k + 1 (KITTI .bin parsing, ring and
    /// time recovery) while `consume` works on frame k, so a run is the same
    /// as a serial one.
    ///
    /// # Errors
    /// The first error of `consume`, or of reading a frame (converted into
    /// `E`); no frame after it is consumed.
    pub fn for_each_frame<E: From<SourceError>>(
        &self,
        frames: Range<usize>,
        mut consume: impl FnMut(usize, Frame) -> Result<(), E>,
    ) -> Result<(), E> {
        std::thread::scope(|scope| -> Result<(), E> {
            let (to_consumer, frames_read) = std::sync::mpsc::sync_channel(2);
            scope.spawn(move || {
                if let Source::Bag(bag) = self {
                    // one pass over the file for all the frames
                    let streamed = bag.for_each_frame(frames, |index, frame| {
                        to_consumer.send((index, Ok(frame))).is_ok()
                    });
                    if let Err(e) = streamed {
                        let _ = to_consumer.send((usize::MAX, Err(e.into())));
                    }
                    return;
                }
                for index in frames {
                    let frame = self.frame(index);
                    let failed = frame.is_err();
                    if to_consumer.send((index, frame)).is_err() || failed {
                        // the consumer stopped, or it will report this error
                        break;
                    }
                }
            });
            for (index, frame) in frames_read {
                consume(index, frame?)?;
            }
            Ok(())
        })
    }
}

/// The IMU-gap limit for `samples`: `configured_s`, or [`IMU_GAP_PERIODS`]
/// nominal sample periods when that is longer. A slower IMU (KITTI
/// tracking's 10 Hz OXTS) has proportionally longer steps between samples,
/// which are no gaps.
pub fn imu_gap_limit_s(samples: &[ImuSample], configured_s: f64) -> f64 {
    let times: Vec<f64> = samples.iter().map(|s| s.t_s).collect();
    match nominal_period_s(&times) {
        Some(period_s) => configured_s.max(IMU_GAP_PERIODS * period_s),
        None => configured_s,
    }
}

/// The slowest IMU whose gravity the estimator estimates (50 Hz), s per sample.
pub const GRAVITY_ESTIMATION_MAX_IMU_PERIOD_S: f64 = 0.02;

/// Whether `samples` come fast enough (at most
/// [`GRAVITY_ESTIMATION_MAX_IMU_PERIOD_S`] apart) for the estimator to
/// estimate gravity's direction (`EstimatorConfig::estimate_gravity`). An
/// IMU at the sweep rate (KITTI tracking's 10 Hz OXTS records) integrates a
/// sweep in one or two steps; their error, not a tilt, would move the
/// estimated gravity (docs/kitti-real-data.md).
///
/// ```
/// use limot::io::imu_resolves_gravity;
/// use limot_estimator::input::ImuSample;
/// use nalgebra::Vector3;
/// let at = |rate_hz: f64| -> Vec<ImuSample> {
///     (0..50)
///         .map(|i| ImuSample {
///             t_s: i as f64 / rate_hz,
///             accel_mps2: Vector3::new(0.0, 0.0, 9.81),
///             gyro_radps: Vector3::zeros(),
///         })
///         .collect()
/// };
/// assert!(imu_resolves_gravity(&at(100.0)));
/// assert!(!imu_resolves_gravity(&at(10.0))); // KITTI tracking's OXTS records
/// assert!(!imu_resolves_gravity(&[]));
/// ```
pub fn imu_resolves_gravity(samples: &[ImuSample]) -> bool {
    let times: Vec<f64> = samples.iter().map(|s| s.t_s).collect();
    nominal_period_s(&times).is_some_and(|period_s| period_s <= GRAVITY_ESTIMATION_MAX_IMU_PERIOD_S)
}

/// `noise` widened for an IMU too slow to resolve a sweep's motion (samples
/// more than [`GRAVITY_ESTIMATION_MAX_IMU_PERIOD_S`] apart, e.g. KITTI
/// tracking's 10 Hz OXTS records); `noise` unchanged otherwise.
///
/// Preintegration treats the samples as linear in time between them. At 10
/// Hz a vehicle's vibration and manoeuvres change the signal between two
/// samples by far more than a sensor's white noise, so the preintegrated
/// deltas are less certain than the densities say and the IMU factors would
/// outweigh the LiDAR. That error is measured from the samples themselves:
/// per axis, half the mean square difference of consecutive samples is the
/// variance `σ²` of what a sample misses of its interval; as a density over
/// the period `dt` it adds `σ²·dt` to the density squared, for the
/// accelerometer and the gyroscope alike (each with the mean of its axes'
/// `σ²`). Bias random walks are kept.
///
/// ```
/// use limot::io::imu_noise_for_rate;
/// use limot_estimator::imu::ImuNoise;
/// use limot_estimator::input::ImuSample;
/// use nalgebra::Vector3;
/// // specific force alternating by ±0.2 m/s² on every axis
/// let at = |rate_hz: f64| -> Vec<ImuSample> {
///     (0..50)
///         .map(|i| ImuSample {
///             t_s: i as f64 / rate_hz,
///             accel_mps2: Vector3::new(0.0, 0.0, 9.81).add_scalar(if i % 2 == 0 { 0.2 } else { -0.2 }),
///             gyro_radps: Vector3::zeros(),
///         })
///         .collect()
/// };
/// let noise = ImuNoise::default();
/// assert_eq!(imu_noise_for_rate(&at(100.0), noise), noise);
/// let slow = imu_noise_for_rate(&at(10.0), noise);
/// // σ² = 0.4² / 2 = 0.08 (m/s²)², over 0.1 s
/// let expected = (noise.accel_noise_density.powi(2) + 0.08 * 0.1).sqrt();
/// assert!((slow.accel_noise_density - expected).abs() < 1e-12);
/// assert_eq!(slow.gyro_noise_density, noise.gyro_noise_density);
/// assert_eq!(slow.accel_bias_random_walk, noise.accel_bias_random_walk);
/// ```
pub fn imu_noise_for_rate(samples: &[ImuSample], noise: ImuNoise) -> ImuNoise {
    let times: Vec<f64> = samples.iter().map(|s| s.t_s).collect();
    let Some(period_s) = nominal_period_s(&times) else {
        return noise;
    };
    if period_s <= GRAVITY_ESTIMATION_MAX_IMU_PERIOD_S || samples.len() < 2 {
        return noise;
    }
    let pairs = (samples.len() - 1) as f64;
    let (mut accel_sq, mut gyro_sq) = (0.0, 0.0);
    for pair in samples.windows(2) {
        accel_sq += (pair[1].accel_mps2 - pair[0].accel_mps2).norm_squared();
        gyro_sq += (pair[1].gyro_radps - pair[0].gyro_radps).norm_squared();
    }
    // per axis: half the mean square difference, averaged over the 3 axes
    let accel_var = accel_sq / (pairs * 6.0);
    let gyro_var = gyro_sq / (pairs * 6.0);
    let widen = |density: f64, var: f64| {
        let widened = (density * density + var * period_s).sqrt();
        if widened.is_finite() {
            widened
        } else {
            density
        }
    };
    ImuNoise {
        accel_noise_density: widen(noise.accel_noise_density, accel_var),
        gyro_noise_density: widen(noise.gyro_noise_density, gyro_var),
        ..noise
    }
}

/// Hands out the IMU samples of a source in time order, the ones due before
/// each sweep at a time: everything measured up to the end of the sweep
/// (within [`SWEEP_END_TOLERANCE_S`]). Before the first frame it skips the
/// history older than [`IMU_LOOKBACK_S`].
///
/// ```
/// use limot::io::{IMU_LOOKBACK_S, ImuFeed};
/// use limot_estimator::input::{Frame, ImuSample, LidarScan};
/// use nalgebra::Vector3;
/// // 100 Hz from t = 0 s; a 0.1 s sweep starting at t = 1 s
/// let samples: Vec<ImuSample> = (0..300)
///     .map(|i| ImuSample {
///         t_s: i as f64 * 0.01,
///         accel_mps2: Vector3::new(0.0, 0.0, 9.81),
///         gyro_radps: Vector3::zeros(),
///     })
///     .collect();
/// let sweep = |t_s: f64| Frame {
///     scan: LidarScan { t_s, sweep_duration_s: 0.1, ..LidarScan::default() },
///     ..Frame::default()
/// };
/// let mut feed = ImuFeed::new(&samples);
/// let first = feed.due_before(&sweep(1.0));
/// assert!(first[0].t_s >= 1.0 - IMU_LOOKBACK_S - 1e-12);
/// assert!((first.last().unwrap().t_s - 1.1).abs() < 1e-12);
/// let next = feed.due_before(&sweep(1.1));
/// assert_eq!(next.len(), 10); // 1.11 ..= 1.2 s
/// ```
#[derive(Debug, Clone)]
pub struct ImuFeed<'a> {
    samples: &'a [ImuSample],
    next: usize,
    started: bool,
}

impl<'a> ImuFeed<'a> {
    /// A feed over `samples` (sorted by time).
    pub fn new(samples: &'a [ImuSample]) -> Self {
        ImuFeed {
            samples,
            next: 0,
            started: false,
        }
    }

    /// The samples due before `frame`'s sweep ends, not yet handed out. On
    /// the first call, samples older than [`IMU_LOOKBACK_S`] before the
    /// sweep start are dropped.
    pub fn due_before(&mut self, frame: &Frame) -> &'a [ImuSample] {
        let samples = self.samples;
        if !self.started {
            self.started = true;
            let from_s = frame.scan.t_s - IMU_LOOKBACK_S;
            while self.next < samples.len() && samples[self.next].t_s < from_s {
                self.next += 1;
            }
        }
        let sweep_end_s = frame.scan.t_s + frame.scan.sweep_duration_s;
        let start = self.next;
        while self.next < samples.len()
            && samples[self.next].t_s <= sweep_end_s + SWEEP_END_TOLERANCE_S
        {
            self.next += 1;
        }
        &samples[start..self.next]
    }
}
