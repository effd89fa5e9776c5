//! `limot run`: feeds a [`Source`] to the estimator and writes its outputs.
//!
//! The pipeline: open a source ([`Source::open`],
//! [`Source::open_kitti_tracking`]) -> [`run`] (each sweep after the IMU
//! samples due before it, [`ImuFeed`]) -> [`write_output`] (the files of
//! [`write_run_files`]) and, for tracking, KITTI result files
//! ([`kitti_track_labels`], [`write_kitti_tracks`]). [`run_recorded`] also
//! records the run for Foxglove as it goes ([`McapRecorder`]), from each
//! sweep as the estimator de-skewed it ([`run_observed`]).
use crate::cli::frame_progress_bar;
use crate::io::kitti::KittiError;
use crate::io::kitti::poses::StampedPose;
use crate::io::kitti::velodyne::raise_elevation;
use crate::io::mcap::{McapError, McapRecorder, McapRequest, McapStats};
use crate::io::{
    ImuFeed, Source, SourceError, WriteError, imu_gap_limit_s, imu_noise_for_rate,
    imu_resolves_gravity, write_run_files,
};
use limot_estimator::input::{Extrinsics, Frame, ImuSample};
use limot_estimator::pipeline::{
    DeskewedSweep, Estimator, EstimatorConfig, EstimatorError, FrameEstimate, Mode, Variant,
};
use limot_estimator::tracking::TrackerConfig;
use std::fs;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The source could not be opened or a frame of it read.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// A track id does not fit KITTI's result format.
    #[error("track id {id} does not fit the KITTI results' 32-bit track id")]
    TrackIdOverflow {
        /// The estimator's track id.
        id: u64,
    },
    /// A KITTI result file could not be written.
    #[error(transparent)]
    Kitti(#[from] KittiError),
    /// The estimator refused its settings or a frame.
    #[error("{path}: {source}")]
    Estimator {
        /// The source.
        path: PathBuf,
        /// The estimator's error.
        #[source]
        source: EstimatorError,
    },
    /// An output file or directory could not be written.
    #[error(transparent)]
    Write(#[from] WriteError),
    /// The recording of the run could not be written.
    #[error(transparent)]
    Mcap(#[from] McapError),
    /// A directory of KITTI result files could not be created.
    #[error("{path}: {source}")]
    Io {
        /// The directory.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The estimator never produced a pose.
    #[error(
        "{path}: the estimator produced no pose: it never initialised (it needs a static interval, or, moving, LiDAR-only matches that constrain every direction; a straight corridor of guard rails leaves the motion along it unobserved)"
    )]
    NoEstimate {
        /// The source.
        path: PathBuf,
    },
}

/// The estimator settings for `variant` on a KITTI tracking sequence with
/// `tracker`: on real 0000 the odometry drifts against the detections (cm
/// per frame), so a parked car's static node rests on the window's
/// observations only (chosen on 0000: docs/kitti-real-data.md); a filtering
/// variant records its features for the filter's score against the labels.
pub fn kitti_tracking_config(tracker: TrackerConfig, variant: Variant) -> EstimatorConfig {
    let mut config = EstimatorConfig {
        tracker,
        record_feature_indices: variant != Variant::Lio,
        ..EstimatorConfig::default()
    };
    config.objects.static_keeps_old_observations = false;
    config
}

/// How to run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// System variant to run.
    pub variant: Variant,
    /// Ignore the IMU even when the source has one.
    pub lidar_only: bool,
    /// Start at this frame (the IMU from [`IMU_LOOKBACK_S`](crate::io::IMU_LOOKBACK_S)
    /// before it is used).
    pub first_frame: usize,
    /// Process at most this many frames.
    pub max_frames: Option<usize>,
    /// Show a progress bar.
    pub progress: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            variant: Variant::Lio,
            lidar_only: false,
            first_frame: 0,
            max_frames: None,
            progress: false,
        }
    }
}

/// Everything a run produced.
#[derive(Debug, Clone)]
pub struct RunOutput {
    /// The variant that ran.
    pub variant: Variant,
    /// LiDAR-inertial or LiDAR-only.
    pub mode: Mode,
    /// One estimate per frame, in order.
    pub estimates: Vec<FrameEstimate>,
    /// Frames before the inertial state initialised (IMU mode): their
    /// estimates are LiDAR-only odometry, re-expressed in the inertial world.
    pub frames_before_init: usize,
    /// Detections the estimator skipped: non-finite or non-positive fields,
    /// scores outside [0, 1], times outside their sweep.
    pub invalid_detections: u64,
    /// Wall time of the frames' loop, less the time an observer of
    /// [`run_observed`] took.
    pub wall_time: Duration,
}

impl RunOutput {
    /// The LiDAR pose of every frame at its sweep start.
    pub fn stamped_poses(&self) -> Vec<StampedPose> {
        self.estimates
            .iter()
            .map(|e| StampedPose {
                t_s: e.t_s,
                pose: e.t_world_lidar,
            })
            .collect()
    }

    /// Mean time per stage over the frames, and the mean total.
    pub fn mean_timings(&self) -> Vec<(&'static str, Duration)> {
        let n = self.estimates.len().max(1) as u32;
        let mut sums: Vec<(&'static str, Duration)> = Vec::new();
        for e in &self.estimates {
            for (i, (name, d)) in e.timings.stages().into_iter().enumerate() {
                if sums.len() <= i {
                    sums.push((name, Duration::ZERO));
                }
                sums[i].1 += d;
            }
        }
        let total: Duration = self.estimates.iter().map(|e| e.timings.total()).sum();
        sums.push(("total", total));
        sums.into_iter().map(|(name, d)| (name, d / n)).collect()
    }
}

/// One frame of a run as [`run_observed`] shows it, right after the
/// estimator took it.
pub struct RunStep<'a> {
    /// The frame's index in the source.
    pub source_index: usize,
    /// The frame as read.
    pub frame: &'a Frame,
    /// The sweep as the estimator de-skewed and filtered it
    /// ([`Estimator::deskewed_sweep`]).
    pub sweep: DeskewedSweep<'a>,
    /// The estimates the frame completed ([`Estimator::push_frame`]).
    pub completed: &'a [FrameEstimate],
}

/// Runs the estimator over `source` (read from `source_path`, named in
/// errors) with `config` (default: [`EstimatorConfig::default`]) set to
/// `options`' variant, LiDAR-only when the source has no usable IMU or
/// `options.lidar_only`.
///
/// # Errors
/// A frame that cannot be read, settings or a frame the estimator refuses,
/// or no pose at all ([`RunError::NoEstimate`]).
pub fn run(
    source: &Source,
    source_path: &Path,
    options: &RunOptions,
    config: Option<EstimatorConfig>,
) -> Result<RunOutput, RunError> {
    run_observed(source, source_path, options, config, |_| Ok(()))
}

/// [`run`], recording it as it goes into the MCAP file of `request`
/// ([`McapRecorder`]): each frame's sweep as the estimator de-skewed it,
/// with its estimate.
///
/// # Errors
/// As [`run`], or a recording that cannot be written (then no file is left).
pub fn run_recorded(
    source: &Source,
    source_path: &Path,
    options: &RunOptions,
    config: Option<EstimatorConfig>,
    request: &McapRequest,
) -> Result<(RunOutput, McapStats), RunError> {
    let mut recorder = McapRecorder::create(request, source)?;
    let output = run_observed(source, source_path, options, config, |step| {
        recorder.sweep(step.source_index, step.frame, &step.sweep)?;
        recorder.estimates(step.completed)?;
        Ok(())
    })?;
    Ok((output, recorder.finish()?))
}

/// [`run`], showing `observe` every frame ([`RunStep`]) after the estimator
/// took it; the time `observe` takes is not in the output's wall time.
///
/// # Errors
/// As [`run`], or the first error of `observe`.
pub fn run_observed(
    source: &Source,
    source_path: &Path,
    options: &RunOptions,
    config: Option<EstimatorConfig>,
    mut observe: impl FnMut(&RunStep) -> Result<(), RunError>,
) -> Result<RunOutput, RunError> {
    let imu = if options.lidar_only {
        None
    } else {
        source.imu()
    };
    let samples: &[ImuSample] = imu.map_or(&[], |(s, _)| s);
    let extrinsics = imu.map_or(Extrinsics::default(), |(_, e)| e);
    let config = estimator_config(config, options.variant, imu.is_some(), samples);
    let mode = config.mode;
    let estimator_error = |source| RunError::Estimator {
        path: source_path.to_path_buf(),
        source,
    };
    let mut estimator = Estimator::new(config, extrinsics).map_err(estimator_error)?;
    let frames = source.frame_range(options.first_frame, options.max_frames);
    let bar = frame_progress_bar(frames.len(), options.progress, options.variant.name());
    let started = Instant::now();
    let mut observing = Duration::ZERO;
    let mut imu_feed = ImuFeed::new(samples);
    let mut estimates = Vec::with_capacity(frames.len());
    let mut frames_before_init = 0;
    source.for_each_frame(frames, |index, frame| -> Result<(), RunError> {
        for &sample in imu_feed.due_before(&frame) {
            estimator.push_imu(sample).map_err(estimator_error)?;
        }
        let completed = estimator.push_frame(&frame).map_err(estimator_error)?;
        if let Some(sweep) = estimator.deskewed_sweep() {
            let clock = Instant::now();
            observe(&RunStep {
                source_index: index,
                frame: &frame,
                sweep,
                completed: &completed,
            })?;
            observing += clock.elapsed();
        }
        if estimates.is_empty() && completed.len() > 1 {
            frames_before_init = completed.len() - 1;
        }
        estimates.extend(completed);
        bar.inc(1);
        Ok(())
    })?;
    bar.finish_and_clear();
    if estimates.is_empty() {
        return Err(RunError::NoEstimate {
            path: source_path.to_path_buf(),
        });
    }
    Ok(RunOutput {
        variant: options.variant,
        mode,
        estimates,
        frames_before_init,
        invalid_detections: estimator.invalid_detections(),
        wall_time: started.elapsed().saturating_sub(observing),
    })
}

/// `config` (or the default) for `variant`: LiDAR-only without an IMU, an
/// IMU-gap limit fitted to the rate of `imu_samples`, and for an IMU too
/// slow to resolve a sweep gravity held along -z ([`imu_resolves_gravity`])
/// and noise densities widened by what its samples miss
/// ([`imu_noise_for_rate`]).
fn estimator_config(
    config: Option<EstimatorConfig>,
    variant: Variant,
    has_imu: bool,
    imu_samples: &[ImuSample],
) -> EstimatorConfig {
    let mut config = config.unwrap_or_default();
    config.variant = variant;
    if !has_imu {
        config.mode = Mode::LidarOnly;
    }
    config.max_imu_gap_s = imu_gap_limit_s(imu_samples, config.max_imu_gap_s);
    config.estimate_gravity &= imu_resolves_gravity(imu_samples);
    config.imu_noise = imu_noise_for_rate(imu_samples, config.imu_noise);
    config
}

/// Writes the files of [`write_run_files`] for `output` into `out_dir`.
///
/// # Errors
/// A directory or file that cannot be written (named).
pub fn write_output(out_dir: &Path, output: &RunOutput) -> Result<(), RunError> {
    Ok(write_run_files(out_dir, &output.estimates)?)
}

/// Where and when a source's labels were taken, relative to the scans the
/// estimator saw. Limot datasets: at the sweep start, in the scans' frame
/// (the default). Real KITTI: at the camera trigger, half a sweep after the
/// sweep start, in the stored points before their elevation correction.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LabelFrame {
    /// Time of a frame's labels after its sweep start, s.
    pub delay_s: f64,
    /// Elevation correction the scans (and detections) got, rad.
    pub elevation_correction_rad: f64,
}

/// The tracks `result` writes (by default, as AB3DMOT: the confirmed
/// tracks that matched a detection this frame) as KITTI tracking result
/// lines carrying the raw detector score (`score_map` inverted): boxes moved
/// back into each frame's LiDAR frame with the estimated pose and projected
/// through `calib` (the dataset's KITTI copy uses
/// [`crate::io::kitti::export::synthetic_calib`]). Boxes outside the camera image
/// have no KITTI line. The tracker alone writes through the same
/// [`ResultWriter`](crate::experiments::ResultWriter).
///
/// Boxes are given where the labels were taken ([`LabelFrame`]): moved along
/// their velocity to the label time, placed with the ego pose of that
/// instant (interpolated between the sweeps' poses, extrapolated with the
/// velocity after the last one) and returned to the stored points' elevation.
///
/// # Errors
/// A track id beyond the result format's 32 bits.
pub fn kitti_track_labels(
    output: &RunOutput,
    calib: &crate::io::kitti::calib::Calib,
    label_frame: LabelFrame,
    result: &crate::experiments::ResultPolicy,
    score_map: crate::io::kitti::detections::ScoreMap,
) -> Result<Vec<crate::io::kitti::labels::TrackingLabel>, RunError> {
    let frame_delay_s = label_frame.delay_s;
    use crate::experiments::world_box_to_lidar;
    use crate::io::kitti::results::{ImageSize, TrackBox, track_to_label};
    let mut writer = crate::experiments::ResultWriter::new(result.clone());
    let poses: Vec<(f64, nalgebra::Isometry3<f64>)> = output
        .estimates
        .iter()
        .map(|e| (e.t_s, e.t_world_lidar))
        .collect();
    let mut labels = Vec::new();
    for e in &output.estimates {
        let t_frame_s = e.t_s + frame_delay_s;
        let t_world_lidar =
            crate::metrics::pose_at(&poses, t_frame_s, |p| *p).unwrap_or_else(|| {
                let mut pose = e.t_world_lidar;
                pose.translation.vector += e.velocity_world_mps * frame_delay_s;
                pose
            });
        for t in &e.tracks {
            let raw_score =
                (!t.predicted).then(|| score_map.invert(t.detection_score.unwrap_or(1.0)));
            let Some(score) = writer.record(e.frame_index as u32, t, raw_score) else {
                continue;
            };
            let mut lidar_box = world_box_to_lidar(
                &(t.center_world + t.velocity_world_mps * frame_delay_s),
                &t.size_lwh,
                t.yaw_rad,
                &t_world_lidar,
            );
            lidar_box.center =
                raise_elevation(&lidar_box.center, -label_frame.elevation_correction_rad);
            let track = TrackBox {
                frame: e.frame_index as u32,
                track_id: u32::try_from(t.id)
                    .map_err(|_| RunError::TrackIdOverflow { id: t.id })?,
                class: t.class,
                lidar_box,
                score,
            };
            if let Some(label) = track_to_label(&track, calib, ImageSize::KITTI_DEFAULT) {
                labels.push(label);
            }
        }
    }
    // The offline gate needs the whole sequence.
    labels.retain(|l| l.track_id >= 0 && writer.keeps(l.track_id as u64));
    Ok(labels)
}

/// The KITTI tracking result file `dir/0000.txt` of a run on a limot
/// dataset (whose KITTI copy is sequence 0 with `calib`): the tracks
/// [`kitti_track_labels`] writes by default; the simulated detector's scores
/// are probabilities already. Returns the file.
///
/// # Errors
/// A track id beyond 32 bits, or a result file that cannot be written.
pub fn write_dataset_kitti_tracks(
    dir: &Path,
    output: &RunOutput,
    calib: &crate::io::kitti::calib::Calib,
) -> Result<PathBuf, RunError> {
    let labels = kitti_track_labels(
        output,
        calib,
        LabelFrame::default(),
        &crate::experiments::ResultPolicy::default(),
        crate::io::kitti::detections::ScoreMap::Clamp01,
    )?;
    write_kitti_tracks(dir, 0, &labels)
}

/// Writes `labels` as the KITTI tracking result file `DIR/SSSS.txt` of
/// `sequence`. Returns the file.
///
/// # Errors
/// The directory or file cannot be written (named).
pub fn write_kitti_tracks(
    dir: &Path,
    sequence: u32,
    labels: &[crate::io::kitti::labels::TrackingLabel],
) -> Result<PathBuf, RunError> {
    fs::create_dir_all(dir).map_err(|source| RunError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    Ok(crate::io::kitti::results::write_results_file(
        dir, sequence, labels,
    )?)
}
