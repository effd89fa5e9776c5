//! The recording of a dataset and, optionally, of a run on it: what goes on
//! which topic, frame by frame.

use super::messages::{
    BoxStyle, box_entity, point_cloud, poses_path, replace_scene, rgba, time_ns, track_entity,
    transform,
};
use super::writer::{FrameError, McapError, McapFile, McapStats};
use crate::io::Source;
use foxglove::schemas::{FrameTransforms, PointCloud, SceneEntity, SceneUpdate};
use limot_estimator::geometry::OrientedBox;
use limot_estimator::input::Frame;
use limot_estimator::lidar::{Deskewer, SweepMotion};
use limot_estimator::pipeline::{DeskewedSweep, FrameEstimate};
use limot_sim::record::{BoxTruth, EgoTruth};
use nalgebra::Isometry3;
use std::collections::VecDeque;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The world frame of the poses the cloud is placed with: the run's
/// estimate, or the ground truth's world when a dataset is recorded alone.
pub const FRAME_WORLD: &str = "world";
/// The LiDAR frame at each sweep's start (x forward, y left, z up).
pub const FRAME_LIDAR: &str = "lidar";
/// The IMU frame, fixed to the LiDAR by the extrinsics.
pub const FRAME_IMU: &str = "imu";
/// The ground truth's world. A run's `world` is placed so the first
/// estimated pose coincides with the truth at its time; alone, it is `world`.
pub const FRAME_WORLD_TRUTH: &str = "world_truth";

/// `foxglove.FrameTransforms`: `world -> lidar`, `lidar -> imu` (with an IMU)
/// and `world -> world_truth` (with ground truth), every frame.
pub const TOPIC_TF: &str = "/tf";
/// `foxglove.PointCloud`: the sweep as the estimator de-skewed it (LiDAR
/// frame; the cloud's pose places the instant it was de-skewed to), with the
/// `removed` flag on the feature points the filter dropped, thinned to
/// [`McapRequest::max_cloud_points`].
pub const TOPIC_CLOUD: &str = "/lidar/points";
/// `foxglove.SceneUpdate`: the sweep's detections (LiDAR frame).
pub const TOPIC_DETECTIONS: &str = "/detections";
/// `foxglove.SceneUpdate`: the live tracks after the frame (world frame).
pub const TOPIC_TRACKS: &str = "/tracks";
/// `foxglove.PosesInFrame`: the estimated LiDAR path up to the frame (world).
pub const TOPIC_PATH: &str = "/ego/path";
/// `foxglove.SceneUpdate`: the ground-truth boxes at the sweep start (`world_truth`).
pub const TOPIC_TRUTH_BOXES: &str = "/truth/boxes";
/// `foxglove.PosesInFrame`: the true LiDAR path up to the frame (`world_truth`).
pub const TOPIC_TRUTH_PATH: &str = "/truth/path";

/// A recording the CLI asks for: the file, and the points a sweep keeps.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct McapRequest {
    /// The MCAP file to write.
    pub path: PathBuf,
    /// At most this many cloud points per sweep besides the removed ones
    /// (see `point_cloud`); `None`: every point.
    pub max_cloud_points: Option<usize>,
}

/// The ground truth a limot dataset carries.
struct Truth {
    ego: Vec<EgoTruth>,
    boxes: Vec<Vec<BoxTruth>>,
}

impl Truth {
    /// The dataset's truth; `None` for sources without one (KITTI, bags).
    fn of(source: &Source, path: &Path) -> Result<Option<Truth>, McapError> {
        let input_error = |message: String| McapError::Input {
            path: path.to_path_buf(),
            message,
        };
        match source {
            Source::Dataset(dataset) => Ok(Some(Truth {
                ego: dataset
                    .ego_truth()
                    .map_err(|e| input_error(e.to_string()))?,
                boxes: dataset
                    .box_truth()
                    .map_err(|e| input_error(e.to_string()))?,
            })),
            Source::Kitti { .. } | Source::Bag(_) => Ok(None),
        }
    }

    /// The true `t_world_lidar` at `t_s`; `None` outside the truth's span.
    fn pose_at(&self, t_s: f64) -> Option<Isometry3<f64>> {
        crate::metrics::pose_at(&self.ego, t_s, |e| (e.t_s, e.t_world_lidar))
    }
}

/// A sweep's messages, waiting for the pose that places its frame.
struct PendingSweep {
    /// The estimator's frame index (the dataset's source index when recorded alone).
    frame_index: u64,
    /// The frame's index in the source.
    source_index: usize,
    /// Scan start, s, and in ns (the log time).
    t_s: f64,
    t_ns: u64,
    cloud: PointCloud,
    detections: SceneUpdate,
}

/// A recording being written, frame by frame (see [`crate::io::mcap`] for
/// the topics): one message per topic and frame, logged at the sweep's start
/// time of the data's clock.
///
/// During a run, [`McapRecorder::sweep`] takes each sweep as the estimator
/// de-skewed and filtered it, right after the estimator took the frame, and
/// [`McapRecorder::estimates`] the estimates the frame completed; a frame is
/// written when its estimate arrives (the sweeps before the inertial
/// initialisation wait for it). [`record_dataset`] records a dataset alone.
pub struct McapRecorder {
    file: McapFile,
    max_cloud_points: Option<usize>,
    t_lidar_imu: Option<Isometry3<f64>>,
    truth: Option<Truth>,
    /// `world -> world_truth`, fixed by the first frame written.
    t_world_world_truth: Option<Isometry3<f64>>,
    path_world: Vec<Isometry3<f64>>,
    truth_path: Vec<Isometry3<f64>>,
    pending: VecDeque<PendingSweep>,
}

impl McapRecorder {
    /// Starts the recording of `request` of frames of `source` (a limot
    /// dataset's ground truth is read now).
    ///
    /// # Errors
    /// Ground truth that cannot be read, or a file that cannot be created
    /// (each names the file).
    pub fn create(request: &McapRequest, source: &Source) -> Result<McapRecorder, McapError> {
        let truth = Truth::of(source, &request.path)?;
        Ok(McapRecorder {
            file: McapFile::create(&request.path)?,
            max_cloud_points: request.max_cloud_points,
            t_lidar_imu: source.imu().map(|(_, e)| e.t_lidar_imu),
            truth,
            t_world_world_truth: None,
            path_world: Vec::new(),
            truth_path: Vec::new(),
            pending: VecDeque::new(),
        })
    }

    /// Takes source frame `source_index` (`frame`) as `sweep` shows it: the
    /// cloud exactly as de-skewed (f32, LiDAR frame at `sweep.t_ref_s`,
    /// placed by the cloud's pose in the frame at the scan start) with the
    /// `removed` flags, and the detections moved along `sweep.motion` to the
    /// scan start. Both wait for the frame's pose.
    ///
    /// # Errors
    /// [`McapError::Time`] for a scan time an MCAP cannot hold.
    pub fn sweep(
        &mut self,
        source_index: usize,
        frame: &Frame,
        sweep: &DeskewedSweep,
    ) -> Result<(), McapError> {
        let messages = self.sweep_messages(source_index, frame, sweep)?;
        self.pending.push_back(messages);
        Ok(())
    }

    /// The messages of [`McapRecorder::sweep`].
    fn sweep_messages(
        &self,
        source_index: usize,
        frame: &Frame,
        sweep: &DeskewedSweep,
    ) -> Result<PendingSweep, McapError> {
        let t_ns = time_ns(sweep.t_s).ok_or_else(|| McapError::Time {
            path: self.file.path().to_path_buf(),
            frame: source_index,
            t_s: sweep.t_s,
        })?;
        let mut cloud = point_cloud(
            t_ns,
            FRAME_LIDAR,
            sweep.points_lidar,
            sweep.removed_feature_indices,
            self.max_cloud_points,
        );
        cloud.pose = Some(super::messages::pose(
            &sweep.t_lidar_lidar_at(sweep.t_ref_s),
        ));
        // each detection moved from the LiDAR frame of its instant to the sweep start's
        let detections = frame
            .detections
            .iter()
            .enumerate()
            .map(|(i, d)| {
                box_entity(
                    t_ns,
                    FRAME_LIDAR,
                    &d.box_lidar
                        .transformed(&sweep.t_lidar_lidar_at(sweep.t_s + d.time_offset_s)),
                    None,
                    BoxStyle {
                        id: format!("detection {i}"),
                        color: rgba(0.2, 0.9, 0.3, 0.25),
                        label: format!("{} {:.2}", d.class, d.score),
                        metadata: vec![
                            ("class", d.class.to_string()),
                            ("score", format!("{:.3}", d.score)),
                        ],
                    },
                )
            })
            .collect();
        Ok(PendingSweep {
            frame_index: sweep.frame_index,
            source_index,
            t_s: sweep.t_s,
            t_ns,
            cloud,
            detections: replace_scene(t_ns, detections),
        })
    }

    /// Writes the frames of `completed` (estimates in frame order, as
    /// [`Estimator::push_frame`](limot_estimator::Estimator::push_frame)
    /// returns them), each with its sweep; a sweep that no estimate comes
    /// for is left out.
    ///
    /// # Errors
    /// An estimate whose sweep was not given to [`McapRecorder::sweep`], or
    /// a write that fails.
    pub fn estimates(&mut self, completed: &[FrameEstimate]) -> Result<(), McapError> {
        for estimate in completed {
            while self
                .pending
                .front()
                .is_some_and(|s| s.frame_index < estimate.frame_index)
            {
                self.pending.pop_front();
            }
            let sweep = self
                .pending
                .pop_front()
                .filter(|s| s.frame_index == estimate.frame_index)
                .ok_or_else(|| McapError::Input {
                    path: self.file.path().to_path_buf(),
                    message: format!(
                        "the estimate of frame {} came without its sweep",
                        estimate.frame_index
                    ),
                })?;
            self.write_frame(sweep, &estimate.t_world_lidar, Some(estimate))?;
        }
        Ok(())
    }

    /// Writes the summary and renames the file to its name (see
    /// [`McapFile::finish`]).
    ///
    /// # Errors
    /// A write or rename that fails.
    pub fn finish(self) -> Result<McapStats, McapError> {
        self.file.finish()
    }

    /// Writes one frame: `sweep`'s messages placed at `t_world_lidar`, with
    /// the estimate's tracks and path when there is one, and the truth.
    fn write_frame(
        &mut self,
        sweep: PendingSweep,
        t_world_lidar: &Isometry3<f64>,
        estimate: Option<&FrameEstimate>,
    ) -> Result<(), McapError> {
        let t_ns = sweep.t_ns;
        let truth = self.truth.as_ref();
        // world -> world_truth: the truth's frame, where the first estimate meets it
        let t_world_world_truth = *self.t_world_world_truth.get_or_insert_with(|| {
            estimate
                .and_then(|e| {
                    let truth = truth?.pose_at(e.t_s)?;
                    Some(e.t_world_lidar * truth.inverse())
                })
                .unwrap_or_else(Isometry3::identity)
        });
        let mut transforms = vec![transform(t_ns, FRAME_WORLD, FRAME_LIDAR, t_world_lidar)];
        if let Some(t_lidar_imu) = &self.t_lidar_imu {
            transforms.push(transform(t_ns, FRAME_LIDAR, FRAME_IMU, t_lidar_imu));
        }
        if truth.is_some() {
            transforms.push(transform(
                t_ns,
                FRAME_WORLD,
                FRAME_WORLD_TRUTH,
                &t_world_world_truth,
            ));
        }
        let file = &mut self.file;
        file.write(TOPIC_TF, t_ns, &FrameTransforms { transforms })?;
        file.write(TOPIC_CLOUD, t_ns, &sweep.cloud)?;
        file.write(TOPIC_DETECTIONS, t_ns, &sweep.detections)?;
        if let Some(e) = estimate {
            let tracks = e
                .tracks
                .iter()
                .map(|t| track_entity(t_ns, FRAME_WORLD, t))
                .collect();
            file.write(TOPIC_TRACKS, t_ns, &replace_scene(t_ns, tracks))?;
            self.path_world.push(e.t_world_lidar);
            file.write(
                TOPIC_PATH,
                t_ns,
                &poses_path(t_ns, FRAME_WORLD, &self.path_world),
            )?;
        }
        if let Some(truth) = truth {
            let boxes = truth
                .boxes
                .get(sweep.source_index)
                .map_or(&[][..], |b| &b[..])
                .iter()
                .map(|b| truth_entity(t_ns, b))
                .collect();
            file.write(TOPIC_TRUTH_BOXES, t_ns, &replace_scene(t_ns, boxes))?;
            if let Some(pose) = truth.pose_at(sweep.t_s) {
                self.truth_path.push(pose);
                file.write(
                    TOPIC_TRUTH_PATH,
                    t_ns,
                    &poses_path(t_ns, FRAME_WORLD_TRUTH, &self.truth_path),
                )?;
            }
        }
        Ok(())
    }
}

/// Records `frames` of the limot dataset `source` alone, with no run, as
/// the MCAP file of `request`: every sweep de-skewed to its start with the
/// estimator's [`Deskewer`] along the true ego poses (interpolated between
/// frames) and placed by them, its detections, and the ground truth.
///
/// # Errors
/// A source without ground truth, a frame or truth file that cannot be read,
/// true poses not in time order, a time an MCAP cannot hold, or a file that
/// cannot be written (each names the file); the file is then not created.
pub fn record_dataset(
    request: &McapRequest,
    source: &Source,
    frames: Range<usize>,
) -> Result<McapStats, McapError> {
    let path = &request.path;
    let input_error = |message: String| McapError::Input {
        path: path.to_path_buf(),
        message,
    };
    let mut recorder = McapRecorder::create(request, source)?;
    let truth = recorder.truth.as_ref().ok_or_else(|| {
        input_error("nothing places the sweeps: the source has no ground truth".into())
    })?;
    let motion =
        SweepMotion::from_poses(truth.ego.iter().map(|e| (e.t_s, e.t_world_lidar)).collect())
            .map_err(|e| input_error(format!("the true poses to de-skew with: {e}")))?;
    let mut deskewer = Deskewer::new();
    let mut deskewed = Vec::new();
    source
        .for_each_frame(frames, |index, frame| -> Result<(), FrameError> {
            let t_s = frame.scan.t_s;
            deskewed.clear();
            deskewer.deskew(&frame.scan, &motion, t_s, &mut deskewed);
            let sweep = DeskewedSweep {
                frame_index: index as u64,
                t_s,
                t_ref_s: t_s,
                points_lidar: &deskewed,
                removed_feature_indices: &[],
                motion: &motion,
            };
            let messages = recorder.sweep_messages(index, &frame, &sweep)?;
            recorder.write_frame(messages, &motion.pose_at(t_s), None)?;
            Ok(())
        })
        .map_err(|e| e.into_mcap(path))?;
    recorder.finish()
}

/// A ground-truth box (`world_truth`) as a grey entity labelled `id class`,
/// `parked` or `moving`, with its velocity arrow.
fn truth_entity(t_ns: u64, b: &BoxTruth) -> SceneEntity {
    let state = if b.parked { "parked" } else { "moving" };
    box_entity(
        t_ns,
        FRAME_WORLD_TRUTH,
        &OrientedBox::from_pose(&b.t_world_box, b.size_lwh_m),
        Some(b.velocity_world_mps),
        BoxStyle {
            id: format!("truth {}", b.id),
            color: rgba(0.85, 0.85, 0.85, 0.2),
            label: format!("{} {} {state}", b.id, b.class),
            metadata: vec![
                ("id", b.id.to_string()),
                ("class", b.class.to_string()),
                ("state", state.to_string()),
            ],
        },
    )
}
