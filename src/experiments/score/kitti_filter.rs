//! The dynamic-feature filter of a run on a KITTI tracking sequence, judged
//! by the sequence's labels (`label_02`), since real scans have no per-point
//! labels. A point is an object's when it lies in the object's labelled box
//! (LiDAR frame, grown by [`LABEL_BOX_MARGIN_M`] on the sides and the top,
//! its bottom raised by [`LABEL_BOX_GROUND_CLEARANCE_M`] so that the road
//! under and around it stays road). An object moves at a frame when its
//! labelled centre, carried into the world by the OXTS poses, moves faster
//! than [`FILTER_MOVING_SPEED_MPS`] between the first and the last of its
//! labelled frames within [`SPEED_WINDOW_FRAMES`] of that frame (a window
//! that averages the labels' decimetre scatter); an object labelled at that
//! one frame only is neither moving nor standing. An object standing at
//! every labelled frame where its speed is known is parked.
//!
//! Labels cover the camera's view only, so the figures describe the labelled
//! objects: the share of moving objects' features removed (recall) and of
//! standing objects' features removed mean what they say; removals elsewhere
//! (objects beside or behind the ego) count as removed features of no object,
//! so precision is not reported. A KITTI twin's copy carries KITTI's own
//! labels (annotated truth), so the figure on the real scans and on the
//! twin's compare like with like.

use super::filtering::{FILTER_MOVING_SPEED_MPS, FilterEvaluation, FrameObjects};
use super::{EvaluateError, Result};
use crate::experiments::lidar_poses;
use crate::io::kitti::calib::Calib;
use crate::io::kitti::detections::camera_box_to_lidar;
use crate::io::kitti::labels::TrackingLabel;
use crate::io::kitti::oxts::oxts_to_poses;
use crate::io::kitti::raw::RawDrive;
use crate::run::RunOutput;
use limot_estimator::geometry::OrientedBox;
use nalgebra::Vector3;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// A labelled box is grown by this on its sides and top to take in the
/// points on its surface, m (labels fit the points to a decimetre or so).
pub const LABEL_BOX_MARGIN_M: f64 = 0.2;
/// The bottom of a labelled box is raised by this, m: labels stand on the
/// road, whose points are not the object's.
pub const LABEL_BOX_GROUND_CLEARANCE_M: f64 = 0.15;
/// Half-width of the window of labelled frames an object's speed is taken
/// over, frames (±0.5 s at 10 Hz).
pub const SPEED_WINDOW_FRAMES: usize = 5;

/// One labelled object at one frame.
struct LabelledBox {
    /// `track_id + 1` (0 is "no object").
    id: u32,
    lidar_box: OrientedBox,
}

/// Scores `output` (run with `EstimatorConfig::record_feature_indices`) on
/// sequence `sequence` of the KITTI tracking directory `training` against
/// `labels` (see the module docs). `None` when the run recorded no features.
///
/// # Errors
/// Unreadable or malformed scans or OXTS (named), or an estimate of a frame
/// the sequence does not have.
pub fn score_filter_on_labels(
    training: &Path,
    sequence: u32,
    output: &RunOutput,
    labels: &[TrackingLabel],
    calib: &Calib,
) -> Result<Option<FilterEvaluation>> {
    if output
        .estimates
        .iter()
        .all(|e| e.feature_indices.is_empty())
    {
        return Ok(None);
    }
    let drive = RawDrive::open_tracking_sequence(training, sequence)?;
    let frames = drive.num_scans();
    let t_world_lidar = lidar_poses(&oxts_to_poses(&drive.oxts_records()), calib);
    let times_s: Vec<f64> = drive.velodyne.iter().map(|f| f.t_start_s).collect();
    let mut boxes: Vec<Vec<LabelledBox>> = (0..frames).map(|_| Vec::new()).collect();
    // world centres of each object at its labelled frames, in frame order
    let mut centres: BTreeMap<u32, Vec<(usize, Vector3<f64>)>> = BTreeMap::new();
    for l in labels {
        let frame = l.frame as usize;
        if l.is_dont_care() || l.track_id < 0 || frame >= frames {
            continue;
        }
        let Ok(id) = u32::try_from(l.track_id + 1) else {
            continue;
        };
        let lidar_box = camera_box_to_lidar(&l.cam_box, calib);
        let centre_world = t_world_lidar[frame] * nalgebra::Point3::from(lidar_box.center);
        centres
            .entry(id)
            .or_default()
            .push((frame, centre_world.coords));
        boxes[frame].push(LabelledBox { id, lidar_box });
    }
    for c in centres.values_mut() {
        c.sort_by_key(|(frame, _)| *frame);
    }
    // parked: standing at every labelled frame where its speed is known
    let parked: BTreeSet<u32> = centres
        .iter()
        .filter(|(_, c)| {
            let speeds: Vec<f64> = c
                .iter()
                .filter_map(|&(frame, _)| speed_mps(c, frame, &times_s))
                .collect();
            !speeds.is_empty() && speeds.iter().all(|&v| v <= FILTER_MOVING_SPEED_MPS)
        })
        .map(|(&id, _)| id)
        .collect();
    let mut total = FilterEvaluation::empty();
    for e in output
        .estimates
        .iter()
        .filter(|e| !e.feature_indices.is_empty())
    {
        let frame = e.frame_index as usize;
        let Some(frame_boxes) = boxes.get(frame) else {
            return Err(EvaluateError::Input {
                path: training.join("velodyne").join(format!("{sequence:04}")),
                why: format!("the run estimated frame {frame}, the sequence has {frames}"),
            });
        };
        let scan = drive.scan(frame)?;
        let mut objects = FrameObjects {
            point_labels: vec![0; scan.points.len()],
            ..FrameObjects::default()
        };
        for &i in &e.feature_indices {
            let Some(p) = scan.points.get(i as usize) else {
                continue;
            };
            let p = Vector3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
            if let Some(b) = frame_boxes.iter().find(|b| {
                b.lidar_box
                    .contains_inflated(&p, LABEL_BOX_MARGIN_M, -LABEL_BOX_GROUND_CLEARANCE_M)
            }) {
                objects.point_labels[i as usize] = b.id;
            }
        }
        for b in frame_boxes {
            match speed_mps(&centres[&b.id], frame, &times_s) {
                Some(v) if v > FILTER_MOVING_SPEED_MPS => objects.moving.insert(b.id),
                Some(_) => objects.standing.insert(b.id),
                None => false,
            };
            if parked.contains(&b.id) && objects.standing.contains(&b.id) {
                objects.parked.insert(b.id);
            }
        }
        total.add_frame(e, &objects);
    }
    Ok(Some(total))
}

/// Speed of an object at `frame` from its labelled centres within
/// [`SPEED_WINDOW_FRAMES`] (the first and the last of them); `None` with
/// fewer than two.
fn speed_mps(centres: &[(usize, Vector3<f64>)], frame: usize, times_s: &[f64]) -> Option<f64> {
    let window = frame.saturating_sub(SPEED_WINDOW_FRAMES)..=frame + SPEED_WINDOW_FRAMES;
    let mut inside = centres.iter().filter(|(f, _)| window.contains(f));
    let first = inside.next()?;
    let last = inside.next_back()?;
    let dt_s = times_s[last.0] - times_s[first.0];
    (dt_s > 0.0).then(|| (last.1 - first.1).norm() / dt_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_is_taken_over_the_labelled_frames_in_the_window() {
        let times: Vec<f64> = (0..40).map(|k| 0.1 * k as f64).collect();
        // 1.5 m/s along x, labelled at every other frame, 2-20
        let centres: Vec<(usize, Vector3<f64>)> = (2..=20)
            .step_by(2)
            .map(|f| (f, Vector3::new(0.15 * f as f64, 3.0, 0.0)))
            .collect();
        let v = speed_mps(&centres, 10, &times).unwrap();
        assert!((v - 1.5).abs() < 1e-9, "{v}");
        // at the track's end the window holds frames 16-20
        let v = speed_mps(&centres, 21, &times).unwrap();
        assert!((v - 1.5).abs() < 1e-9, "{v}");
        // one labelled frame in the window: unknown
        assert_eq!(speed_mps(&centres[..1], 2, &times), None);
        assert_eq!(speed_mps(&centres, 30, &times), None);
    }
}
