//! The recording of a dataset and, optionally, of a run on it: what goes on
//! which topic, frame by frame.

use super::messages::{
    BoxStyle, box_entity, point_cloud, poses_path, replace_scene, rgba, time_ns, track_entity,
    transform,
};
use super::writer::{FrameError, McapError, McapFile, McapStats};
use crate::io::Source;
use foxglove::schemas::{FrameTransforms, SceneEntity};
use limot_estimator::geometry::OrientedBox;
use limot_estimator::lidar::{Deskewer, SweepMotion};
use limot_estimator::pipeline::FrameEstimate;
use limot_sim::record::{BoxTruth, EgoTruth};
use nalgebra::Isometry3;
use std::collections::BTreeMap;
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
/// `foxglove.PointCloud`: the sweep de-skewed to its start (LiDAR frame),
/// with the `removed` flag on the feature points the filter dropped, thinned
/// to [`McapInput::max_cloud_points`].
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

/// What to record.
pub struct McapInput<'a> {
    /// The frames' sweeps and detections; a limot dataset adds its ground
    /// truth (`gt/ego.csv`, `gt/boxes.csv`).
    pub source: &'a Source,
    /// The source frames to record.
    pub frames: Range<usize>,
    /// The run's estimates (in frame order). Empty: the dataset alone, placed
    /// and de-skewed with its ground-truth ego poses. Otherwise only frames
    /// with an estimate are recorded.
    pub estimates: &'a [FrameEstimate],
    /// At most this many cloud points per sweep besides the removed ones
    /// (see [`point_cloud`](super::messages::point_cloud)); `None`: every point.
    pub max_cloud_points: Option<usize>,
}

/// A recording the CLI asks for: the file, and the points a sweep keeps.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct McapRequest {
    /// The MCAP file to write.
    pub path: PathBuf,
    /// [`McapInput::max_cloud_points`].
    pub max_cloud_points: Option<usize>,
}

/// The ground truth a limot dataset carries.
struct Truth {
    ego: Vec<EgoTruth>,
    boxes: Vec<Vec<BoxTruth>>,
}

/// Writes `input` to the MCAP file `path` (see [`crate::io::mcap`] for the
/// topics): one message per topic and frame, logged at the sweep's start
/// time of the data's clock. The sweep is de-skewed to its start with the
/// estimator's [`Deskewer`] along the recorded poses (the estimates, or the
/// truth), interpolated between frames.
///
/// # Errors
/// A frame or ground-truth file that cannot be read, poses that are not in
/// time order, a time an MCAP cannot hold, or a file that cannot be written
/// (each names the file); the file is then not created.
pub fn write_mcap(path: &Path, input: &McapInput) -> Result<McapStats, McapError> {
    let input_error = |message: String| McapError::Input {
        path: path.to_path_buf(),
        message,
    };
    let truth = match input.source {
        Source::Dataset(dataset) => Some(Truth {
            ego: dataset
                .ego_truth()
                .map_err(|e| input_error(e.to_string()))?,
            boxes: dataset
                .box_truth()
                .map_err(|e| input_error(e.to_string()))?,
        }),
        Source::Kitti { .. } | Source::Bag(_) => None,
    };
    let truth_pose_at = |t_s: f64| {
        truth.as_ref().and_then(|truth| {
            crate::metrics::pose_at(&truth.ego, t_s, |e| (e.t_s, e.t_world_lidar))
        })
    };
    let estimates: BTreeMap<u64, &FrameEstimate> =
        input.estimates.iter().map(|e| (e.frame_index, e)).collect();
    let pose_samples: Vec<(f64, Isometry3<f64>)> = match (&truth, input.estimates.is_empty()) {
        (_, false) => input
            .estimates
            .iter()
            .map(|e| (e.t_s, e.t_world_lidar))
            .collect(),
        (Some(truth), true) => truth.ego.iter().map(|e| (e.t_s, e.t_world_lidar)).collect(),
        (None, true) => {
            return Err(input_error(
                "nothing places the sweeps: no estimates and no ground truth".into(),
            ));
        }
    };
    let motion = SweepMotion::from_poses(pose_samples)
        .map_err(|e| input_error(format!("the poses to de-skew with: {e}")))?;
    // world -> world_truth: the truth's frame, where the first estimate meets it
    let t_world_world_truth = input
        .estimates
        .first()
        .and_then(|e| truth_pose_at(e.t_s).map(|truth| e.t_world_lidar * truth.inverse()))
        .unwrap_or_else(Isometry3::identity);
    let t_lidar_imu = input.source.imu().map(|(_, e)| e.t_lidar_imu);

    let mut file = McapFile::create(path)?;
    let mut deskewer = Deskewer::new();
    let mut deskewed = Vec::new();
    let mut path_world = Vec::new();
    let mut truth_path = Vec::new();
    input
        .source
        .for_each_frame(
            input.frames.clone(),
            |index, frame| -> Result<(), FrameError> {
                let estimate = estimates.get(&(index as u64)).copied();
                if estimate.is_none() && !input.estimates.is_empty() {
                    return Ok(());
                }
                let t_s = estimate.map_or(frame.scan.t_s, |e| e.t_s);
                let t_ns = time_ns(t_s).ok_or_else(|| McapError::Time {
                    path: path.to_path_buf(),
                    frame: index,
                    t_s,
                })?;
                let t_world_lidar =
                    estimate.map_or_else(|| motion.pose_at(t_s), |e| e.t_world_lidar);

                let mut transforms =
                    vec![transform(t_ns, FRAME_WORLD, FRAME_LIDAR, &t_world_lidar)];
                if let Some(t_lidar_imu) = &t_lidar_imu {
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
                file.write(TOPIC_TF, t_ns, &FrameTransforms { transforms })?;

                deskewed.clear();
                deskewer.deskew(&frame.scan, &motion, t_s, &mut deskewed);
                let removed = estimate.map_or(&[][..], |e| &e.removed_feature_indices[..]);
                file.write(
                    TOPIC_CLOUD,
                    t_ns,
                    &point_cloud(
                        t_ns,
                        FRAME_LIDAR,
                        &deskewed,
                        removed,
                        input.max_cloud_points,
                    ),
                )?;

                // each detection moved from the LiDAR frame of its instant to the sweep start's
                let t_lidar_world = t_world_lidar.inverse();
                let detections = frame
                    .detections
                    .iter()
                    .enumerate()
                    .map(|(i, d)| {
                        let t_lidar_lidar_then =
                            t_lidar_world * motion.pose_at(t_s + d.time_offset_s);
                        box_entity(
                            t_ns,
                            FRAME_LIDAR,
                            &d.box_lidar.transformed(&t_lidar_lidar_then),
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
                file.write(TOPIC_DETECTIONS, t_ns, &replace_scene(t_ns, detections))?;

                if let Some(e) = estimate {
                    let tracks = e
                        .tracks
                        .iter()
                        .map(|t| track_entity(t_ns, FRAME_WORLD, t))
                        .collect();
                    file.write(TOPIC_TRACKS, t_ns, &replace_scene(t_ns, tracks))?;
                    path_world.push(e.t_world_lidar);
                    file.write(
                        TOPIC_PATH,
                        t_ns,
                        &poses_path(t_ns, FRAME_WORLD, &path_world),
                    )?;
                }

                if let Some(truth) = &truth {
                    let boxes = truth
                        .boxes
                        .get(index)
                        .map_or(&[][..], |b| &b[..])
                        .iter()
                        .map(|b| truth_entity(t_ns, b))
                        .collect();
                    file.write(TOPIC_TRUTH_BOXES, t_ns, &replace_scene(t_ns, boxes))?;
                    if let Some(pose) = truth_pose_at(t_s) {
                        truth_path.push(pose);
                        file.write(
                            TOPIC_TRUTH_PATH,
                            t_ns,
                            &poses_path(t_ns, FRAME_WORLD_TRUTH, &truth_path),
                        )?;
                    }
                }
                Ok(())
            },
        )
        .map_err(|e| e.into_mcap(path))?;
    file.finish()
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
