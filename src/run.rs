//! `limot run`: feeds a dataset to the estimator and writes its trajectory.
//!
//! Sources: a limot dataset (LiDAR, IMU, detections, extrinsics), a KITTI raw
//! drive (`velodyne_points/` + `oxts/`; the IMU is used when the date
//! directory's `calib_imu_to_velo.txt` is next to the drive) or a directory
//! of bare KITTI scans (LiDAR only). Outputs in OUT: `poses_tum.txt` (LiDAR
//! poses, for evo / `limot eval ego`), `poses_kitti.txt` + `times.txt`,
//! `estimates.csv` (velocity, biases, match diagnostics) and `timings.csv`.

use crate::kitti::KittiError;
use crate::kitti::calib::Calib;
use crate::kitti::detections::{ScoreMap, detections_by_frame, read_ab3dmot_csv};
use crate::kitti::poses::{StampedPose, write_kitti_poses, write_tum};
use crate::kitti::raw::{RawCalib, RawDrive};
use crate::kitti::velodyne::{raise_elevation, sweep_time_offset_s};
use crate::report::Variant;
use crate::simulate::frame_progress_bar;
use limot_estimator::input::{Detection, Extrinsics, Frame, ImuSample};
use limot_estimator::pipeline::{
    Estimator, EstimatorConfig, EstimatorError, FrameEstimate, Mode, Variant as EstimatorVariant,
};
use limot_estimator::tracking::TrackerConfig;
use limot_sim::record::{Dataset, RecordError};
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error(transparent)]
    Dataset(#[from] RecordError),
    #[error("track id {id} does not fit the KITTI results' 32-bit track id")]
    TrackIdOverflow { id: u64 },
    #[error(transparent)]
    Kitti(#[from] KittiError),
    #[error("{path}: {source}")]
    Estimator {
        path: PathBuf,
        #[source]
        source: EstimatorError,
    },
    #[error(
        "{path}: not a limot dataset (meta.toml), a KITTI raw drive (velodyne_points/) or a directory of KITTI .bin scans"
    )]
    UnknownSource { path: PathBuf },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "{path}: the estimator produced no pose (it never initialised: no static interval at the start?)"
    )]
    NoEstimate { path: PathBuf },
}

/// Where the frames come from.
pub enum Source {
    Dataset(Box<Dataset>),
    Kitti {
        drive: Box<RawDrive>,
        imu: Vec<ImuSample>,
        extrinsics: Option<Extrinsics>,
        /// Detections per frame (LiDAR frame), empty when none were given.
        detections: Vec<Vec<Detection>>,
    },
}

impl Source {
    /// Detects the kind of `path` and opens it.
    pub fn open(path: &Path) -> Result<Source, RunError> {
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
            .map_err(|source| RunError::Io {
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
        Err(RunError::UnknownSource {
            path: path.to_path_buf(),
        })
    }

    /// Sequence `sequence` of a KITTI tracking directory (see
    /// [`RawDrive::open_tracking_sequence`]): scans, the OXTS IMU (10 Hz),
    /// `calib/SSSS.txt` for the IMU-LiDAR extrinsics and the detections'
    /// frame, and AB3DMOT-format detections (camera frame) from
    /// `detections`, or from `DIR/detections/SSSS.txt` when that exists.
    /// Each detection is placed at the time the laser swept its centre.
    pub fn open_kitti_tracking(
        dir: &Path,
        sequence: u32,
        detections: Option<&Path>,
        score_map: ScoreMap,
    ) -> Result<Source, RunError> {
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
                    return Err(RunError::Kitti(KittiError::Invalid {
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
                    d.center_lidar =
                        raise_elevation(&d.center_lidar, drive.elevation_correction_rad);
                    d.time_offset_s = sweep_time_offset_s(&d.center_lidar);
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

    pub fn frame_count(&self) -> usize {
        match self {
            Source::Dataset(d) => d.frame_count(),
            Source::Kitti { drive, .. } => drive.num_scans(),
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
        }
    }

    pub fn frame(&self, index: usize) -> Result<Frame, RunError> {
        Ok(match self {
            Source::Dataset(d) => d.input_frame(index)?,
            Source::Kitti {
                drive, detections, ..
            } => Frame {
                scan: drive.scan(index)?,
                detections: detections.get(index).cloned().unwrap_or_default(),
            },
        })
    }
}

/// The estimator settings for a KITTI tracking sequence with `tracker`:
/// on real 0000 the odometry drifts against the detections (cm per frame),
/// so a parked car's static node rests on the window's observations only
/// (chosen on 0000: docs/kitti-real-data.md).
pub fn kitti_tracking_config(tracker: TrackerConfig) -> EstimatorConfig {
    let mut config = EstimatorConfig {
        tracker,
        ..EstimatorConfig::default()
    };
    config.objects.static_keeps_old_observations = false;
    config
}

/// How to run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    pub variant: Variant,
    /// Ignore the IMU even when the source has one.
    pub lidar_only: bool,
    /// Start at this frame (the IMU from half a second before it is used).
    pub first_frame: usize,
    /// Process at most this many frames.
    pub max_frames: Option<usize>,
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
    pub variant: Variant,
    pub mode: Mode,
    pub estimates: Vec<FrameEstimate>,
    /// Frames before the inertial state initialised (IMU mode): their
    /// estimates are LiDAR-only odometry, re-expressed in the inertial world.
    pub frames_before_init: usize,
    /// Detections the estimator skipped: non-finite or non-positive fields,
    /// scores outside [0, 1], times outside their sweep.
    pub invalid_detections: u64,
    pub wall_time: Duration,
}

impl RunOutput {
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

/// Runs the estimator over `source`.
pub fn run(
    source: &Source,
    source_path: &Path,
    options: &RunOptions,
    config: Option<EstimatorConfig>,
) -> Result<RunOutput, RunError> {
    let variant = match options.variant {
        Variant::Lio => EstimatorVariant::Lio,
        Variant::Allfilt => EstimatorVariant::Allfilt,
        Variant::Dynafilt => EstimatorVariant::Dynafilt,
        Variant::Limot => EstimatorVariant::Limot,
    };
    let imu = if options.lidar_only {
        None
    } else {
        source.imu()
    };
    let mut config = config.unwrap_or_default();
    config.variant = variant;
    if imu.is_none() {
        config.mode = Mode::LidarOnly;
    }
    let mode = config.mode;
    let extrinsics = imu.map_or(Extrinsics::default(), |(_, e)| e);
    let samples: &[ImuSample] = imu.map_or(&[], |(s, _)| s);
    // A slower IMU (KITTI tracking's 10 Hz OXTS) has proportionally longer
    // steps between samples, which are no gaps.
    let times: Vec<f64> = samples.iter().map(|s| s.t_s).collect();
    if let Some(period_s) = crate::kitti::raw::nominal_period_s(&times) {
        config.max_imu_gap_s = config.max_imu_gap_s.max(1.5 * period_s);
    }
    let mut estimator =
        Estimator::new(config, extrinsics).map_err(|source| RunError::Estimator {
            path: source_path.to_path_buf(),
            source,
        })?;
    let first = options.first_frame.min(source.frame_count());
    let end = options.max_frames.map_or(source.frame_count(), |m| {
        (first + m).min(source.frame_count())
    });
    let frames = end - first;
    let bar = frame_progress_bar(frames, options.progress, options.variant.name());
    let estimator_error = |source| RunError::Estimator {
        path: source_path.to_path_buf(),
        source,
    };
    let started = Instant::now();
    let mut next_imu = 0;
    let mut estimates = Vec::with_capacity(frames);
    let mut frames_before_init = 0;
    // A reader thread decodes frame k + 1 (KITTI .bin parsing, ring and
    // time recovery) while the estimator works on frame k; frames arrive in
    // order, so the run is the same as a serial one.
    std::thread::scope(|scope| -> Result<(), RunError> {
        let (to_estimator, frames_read) = std::sync::mpsc::sync_channel(2);
        scope.spawn(move || {
            for index in first..end {
                let frame = source.frame(index);
                let failed = frame.is_err();
                if to_estimator.send((index, frame)).is_err() || failed {
                    // the estimator stopped, or it will report this error
                    break;
                }
            }
        });
        for (index, frame) in frames_read {
            let frame = frame?;
            if index == first {
                // IMU history for the initialisation, not the whole past.
                let from_s = frame.scan.t_s - 0.6;
                while next_imu < samples.len() && samples[next_imu].t_s < from_s {
                    next_imu += 1;
                }
            }
            // Everything the IMU measured up to the end of this sweep.
            let sweep_end_s = frame.scan.t_s + frame.scan.sweep_duration_s;
            while next_imu < samples.len() && samples[next_imu].t_s <= sweep_end_s + 1e-9 {
                estimator
                    .push_imu(samples[next_imu])
                    .map_err(estimator_error)?;
                next_imu += 1;
            }
            let completed = estimator.push_frame(&frame).map_err(estimator_error)?;
            if estimates.is_empty() && completed.len() > 1 {
                frames_before_init = completed.len() - 1;
            }
            estimates.extend(completed);
            bar.inc(1);
        }
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
        wall_time: started.elapsed(),
    })
}

/// Writes the trajectory (TUM, KITTI + times), the per-frame estimates and timings.
pub fn write_output(out_dir: &Path, output: &RunOutput) -> Result<(), RunError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| RunError::Io { path, source }
    };
    fs::create_dir_all(out_dir).map_err(io(out_dir))?;
    let poses = output.stamped_poses();
    let write = |name: &str, text: String| {
        let path = out_dir.join(name);
        fs::write(&path, text).map_err(io(&path))
    };
    write("poses_tum.txt", write_tum(&poses))?;
    write(
        "poses_kitti.txt",
        write_kitti_poses(&poses.iter().map(|p| p.pose).collect::<Vec<_>>()),
    )?;
    let mut times = String::new();
    for p in &poses {
        let _ = writeln!(times, "{}", p.t_s);
    }
    write("times.txt", times)?;

    let mut csv = String::from(
        "frame,t_s,x,y,z,qx,qy,qz,qw,vx,vy,vz,bax,bay,baz,bgx,bgy,bgz,removed_features,edge_features,planar_features,edge_matches,planar_matches,iterations,converged,degenerate_directions,rms_residual_m\n",
    );
    for e in &output.estimates {
        let t = e.t_world_lidar.translation.vector;
        let q = e.t_world_lidar.rotation.quaternion();
        let v = e.velocity_world_mps;
        let (ba, bg) = (e.bias.accel_mps2, e.bias.gyro_radps);
        let _ = write!(
            csv,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            e.frame_index,
            e.t_s,
            t.x,
            t.y,
            t.z,
            q.i,
            q.j,
            q.k,
            q.w,
            v.x,
            v.y,
            v.z,
            ba.x,
            ba.y,
            ba.z,
            bg.x,
            bg.y,
            bg.z,
            e.removed_feature_indices.len()
        );
        match &e.scan_match {
            Some(m) => {
                let _ = writeln!(
                    csv,
                    ",{},{},{},{},{},{},{},{}",
                    m.edge_features,
                    m.planar_features,
                    m.edge_matches,
                    m.planar_matches,
                    m.iterations,
                    m.converged,
                    m.degenerate_directions,
                    m.rms_residual_m
                );
            }
            None => {
                let _ = writeln!(csv, ",,,,,,,,");
            }
        }
    }
    write("estimates.csv", csv)?;

    let mut timings = String::from("frame");
    let names = output.estimates[0].timings.stages().map(|(n, _)| n);
    for name in names {
        let _ = write!(timings, ",{name}_ms");
    }
    timings.push_str(",total_ms\n");
    for e in &output.estimates {
        let _ = write!(timings, "{}", e.frame_index);
        for (_, d) in e.timings.stages() {
            let _ = write!(timings, ",{:.3}", d.as_secs_f64() * 1e3);
        }
        let _ = writeln!(timings, ",{:.3}", e.timings.total().as_secs_f64() * 1e3);
    }
    write("timings.csv", timings)?;

    // Tracks per frame: the box in the world frame and in the frame's LiDAR
    // frame (our format; KITTI tracking results need a camera calibration,
    // see `write_kitti_tracks`).
    let mut tracks = String::from(
        "frame,t_s,id,class,x,y,z,yaw_rad,l,w,h,vx,vy,vz,lifecycle,motion,predicted,\
         x_lidar,y_lidar,z_lidar,yaw_lidar_rad\n",
    );
    for e in &output.estimates {
        for t in &e.tracks {
            let c = t.center_world;
            let v = t.velocity_world_mps;
            let lidar = crate::experiments::world_box_to_lidar(
                &t.center_world,
                &t.size_lwh,
                t.yaw_rad,
                &e.t_world_lidar,
            );
            let _ = writeln!(
                tracks,
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{:?},{:?},{},{},{},{},{}",
                e.frame_index,
                e.t_s,
                t.id,
                t.class,
                c.x,
                c.y,
                c.z,
                t.yaw_rad,
                t.size_lwh.x,
                t.size_lwh.y,
                t.size_lwh.z,
                v.x,
                v.y,
                v.z,
                t.lifecycle,
                t.motion,
                t.predicted,
                lidar.center_lidar.x,
                lidar.center_lidar.y,
                lidar.center_lidar.z,
                lidar.yaw_rad
            );
        }
    }
    write("tracks.csv", tracks)?;
    Ok(())
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
/// [`crate::kitti_export::synthetic_calib`]). Boxes outside the camera image
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
    calib: &crate::kitti::calib::Calib,
    label_frame: LabelFrame,
    result: &crate::experiments::ResultPolicy,
    score_map: crate::kitti::detections::ScoreMap,
) -> Result<Vec<crate::kitti::labels::TrackingLabel>, RunError> {
    let frame_delay_s = label_frame.delay_s;
    use crate::experiments::world_box_to_lidar;
    use crate::kitti::results::{ImageSize, TrackBox, track_to_label};
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
            lidar_box.center_lidar = raise_elevation(
                &lidar_box.center_lidar,
                -label_frame.elevation_correction_rad,
            );
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
pub fn write_dataset_kitti_tracks(
    dir: &Path,
    output: &RunOutput,
    calib: &crate::kitti::calib::Calib,
) -> Result<PathBuf, RunError> {
    let labels = kitti_track_labels(
        output,
        calib,
        LabelFrame::default(),
        &crate::experiments::ResultPolicy::default(),
        crate::kitti::detections::ScoreMap::Clamp01,
    )?;
    write_kitti_tracks(dir, 0, &labels)
}

/// Writes `labels` as the KITTI tracking result file `DIR/SSSS.txt` of
/// `sequence`. Returns the file.
pub fn write_kitti_tracks(
    dir: &Path,
    sequence: u32,
    labels: &[crate::kitti::labels::TrackingLabel],
) -> Result<PathBuf, RunError> {
    fs::create_dir_all(dir).map_err(|source| RunError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    Ok(crate::kitti::results::write_results_file(
        dir, sequence, labels,
    )?)
}
