//! The detector model scored as an oracle-associated tracker against the
//! truth the tracks are scored on, so its MOTA is their ceiling.
//!
//! The tracks' truth ([`ScoredTruth`], camera-visible boxes at each sweep's
//! start) fixes WHICH objects count in a frame. Each detection, though, boxes
//! its object at the instant the rotating head passed it, in the LiDAR frame
//! of that instant; the detector is scored against the truth box of that
//! same instant ([`Detector::sighted_box`]), so its figure holds detection
//! noise only, not the object's motion within the sweep, which the tracker
//! predicts away. Detections are kept, as track boxes are, only where their
//! box falls in the camera image (a KITTI result line needs one).

use crate::experiments::ScoredTruth;
use crate::io::kitti::detections::lidar_box_to_camera;
use crate::io::kitti::results::{ImageSize, image_box};
use crate::metrics::{MotFrame, TrackedBox};
use limot_estimator::geometry::OrientedBox;
use limot_sim::SimulatedFrame;
use limot_sim::record::instances_hit;
use limot_sim::scene::Scene;
use limot_sim::sensors::{Detector, LidarConfig};
use std::collections::BTreeMap;

/// Id offset of false-positive detections (they have no ground-truth id).
const FALSE_POSITIVE_ID_BASE: u64 = 1 << 40;

/// One sweep as the detector saw it, kept while simulating.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectorFrame {
    /// The noise-free sighted box of every agent with a LiDAR return, by id.
    pub sighted: BTreeMap<u64, TrackedBox>,
    /// The detections, ids = truth ids (false positives get unique ids).
    pub detections: Vec<TrackedBox>,
    /// The truth id of each detection (`None`: a false positive).
    pub truth_ids: Vec<Option<u64>>,
}

impl DetectorFrame {
    /// What the detector saw of `frame` of the scene.
    pub fn new(scene: &Scene, lidar: &LidarConfig, frame: &SimulatedFrame) -> Self {
        let hit = instances_hit(&frame.recorded.labels);
        let sighted = scene
            .agents
            .iter()
            .filter(|a| hit.contains(&a.id))
            .map(|a| {
                let d = Detector::sighted_box(a, &scene.ego, frame.t_s, lidar);
                let b = d.box_lidar;
                (
                    u64::from(a.id),
                    TrackedBox {
                        id: u64::from(a.id),
                        class: d.class,
                        bbox: OrientedBox::new(b.center, b.size_lwh, b.yaw_rad),
                    },
                )
            })
            .collect();
        let truth_ids = frame
            .recorded
            .detections
            .iter()
            .map(|d| d.truth_id.map(u64::from))
            .collect();
        let detections = frame
            .recorded
            .detections
            .iter()
            .enumerate()
            .map(|(k, d)| {
                let b = d.detection.box_lidar;
                TrackedBox {
                    id: d.truth_id.map_or(
                        FALSE_POSITIVE_ID_BASE + (frame.index as u64) * 1000 + k as u64,
                        u64::from,
                    ),
                    class: d.detection.class,
                    bbox: OrientedBox::new(b.center, b.size_lwh, b.yaw_rad),
                }
            })
            .collect();
        DetectorFrame {
            sighted,
            detections,
            truth_ids,
        }
    }
}

/// The detector's CLEAR-MOT frames against `truth`: per frame, the sighted
/// boxes of the truth's objects and the detections inside the camera image.
/// A truth object without a sighted box (no LiDAR return) keeps its truth
/// box moved into the LiDAR frame (it cannot be detected anyway).
pub fn detector_frames(frames: &[DetectorFrame], truth: &ScoredTruth) -> Vec<MotFrame> {
    frames
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let gt = truth.gt.get(k).map_or(&[][..], Vec::as_slice);
            MotFrame {
                gt: gt
                    .iter()
                    .map(|g| {
                        f.sighted.get(&g.id).copied().unwrap_or_else(|| TrackedBox {
                            bbox: g.bbox.transformed(&truth.t_world_lidar[k].inverse()),
                            ..*g
                        })
                    })
                    .collect(),
                tracks: f
                    .detections
                    .iter()
                    .filter(|d| in_image(&d.bbox, truth))
                    .copied()
                    .collect(),
                dont_care: Vec::new(),
            }
        })
        .collect()
}

/// Whether a LiDAR-frame box projects into the camera image.
fn in_image(b: &OrientedBox, truth: &ScoredTruth) -> bool {
    image_box(
        &lidar_box_to_camera(b, &truth.calib),
        &truth.calib,
        ImageSize::KITTI_DEFAULT,
    )
    .is_some()
}
