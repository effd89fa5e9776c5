//! KITTI tracking results: one label_02-format file per sequence, with a
//! score column, as the devkit's `evaluate_tracking` reads them.
//!
//! The devkit evaluates in the image, so every result needs the 2D box of
//! the left colour camera: the 8 corners of the 3D box projected with P2
//! (the devkit's `computeBox3D`), clipped to the image. Boxes with a corner
//! less than 0.1 m in front of the camera, or outside the image, have no 2D
//! box and are not written.

use super::calib::Calib;
use super::detections::{lidar_box_to_camera, observation_angle_rad};
use super::labels::{CameraBox, TrackingLabel};
use super::{Result, sequence_file, write_text};
use limot_estimator::geometry::OrientedBox;
use limot_estimator::input::ObjectClass;
use nalgebra::{Matrix3, Vector3};
use std::path::{Path, PathBuf};

/// Image size of the left colour camera (pixels); KITTI sequences use
/// 1224..1242 × 370..376.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageSize {
    /// Width (pixels).
    pub width: f64,
    /// Height (pixels).
    pub height: f64,
}

impl ImageSize {
    /// The most common KITTI tracking image size.
    pub const KITTI_DEFAULT: ImageSize = ImageSize {
        width: 1242.0,
        height: 375.0,
    };
}

/// One tracked object at one frame, in the LiDAR frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackBox {
    /// Frame index.
    pub frame: u32,
    /// Track id.
    pub track_id: u32,
    /// Object class.
    pub class: ObjectClass,
    /// The box in the frame's LiDAR frame.
    pub lidar_box: OrientedBox,
    /// Score written in the result line.
    pub score: f64,
}

/// The 8 corners of a camera box in the rectified camera frame (devkit order).
pub fn box_corners_rect(cam: &CameraBox) -> [Vector3<f64>; 8] {
    let (h, w, l) = (cam.dims_hwl.x, cam.dims_hwl.y, cam.dims_hwl.z);
    let (s, c) = cam.rotation_y_rad.sin_cos();
    let r = Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c);
    let xs = [l, l, -l, -l, l, l, -l, -l].map(|v| v / 2.0);
    let ys = [0.0, 0.0, 0.0, 0.0, -h, -h, -h, -h];
    let zs = [w, -w, -w, w, w, -w, -w, w].map(|v| v / 2.0);
    std::array::from_fn(|i| r * Vector3::new(xs[i], ys[i], zs[i]) + cam.bottom_center_rect)
}

/// 2D box (left, top, right, bottom) of a camera box in the left colour
/// image, clipped to it; `None` if a corner is less than 0.1 m in front of
/// the camera or nothing is left after clipping.
pub fn image_box(cam: &CameraBox, calib: &Calib, image: ImageSize) -> Option<[f64; 4]> {
    let corners = box_corners_rect(cam);
    if corners.iter().any(|c| c.z < 0.1) {
        return None;
    }
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for c in &corners {
        let px = calib.project_rect_to_image(c)?;
        b = [
            b[0].min(px.x),
            b[1].min(px.y),
            b[2].max(px.x),
            b[3].max(px.y),
        ];
    }
    let clipped = [
        b[0].max(0.0),
        b[1].max(0.0),
        b[2].min(image.width - 1.0),
        b[3].min(image.height - 1.0),
    ];
    (clipped[2] > clipped[0] && clipped[3] > clipped[1]).then_some(clipped)
}

/// The result line of a track box; `None` when it has no 2D box.
pub fn track_to_label(track: &TrackBox, calib: &Calib, image: ImageSize) -> Option<TrackingLabel> {
    let cam_box = lidar_box_to_camera(&track.lidar_box, calib);
    let bbox_2d = image_box(&cam_box, calib, image)?;
    Some(TrackingLabel {
        frame: track.frame,
        track_id: i64::from(track.track_id),
        type_name: track.class.name().to_string(),
        truncated: 0.0,
        occluded: 0,
        alpha_rad: observation_angle_rad(&cam_box),
        bbox_2d,
        cam_box,
        score: Some(track.score),
    })
}

/// Formats a sequence's results, sorted by frame then track id.
pub fn write_results(labels: &[TrackingLabel]) -> String {
    let mut sorted: Vec<&TrackingLabel> = labels.iter().collect();
    sorted.sort_by_key(|l| (l.frame, l.track_id));
    sorted.iter().map(|l| l.to_line() + "\n").collect()
}

/// Writes `dir/00NN.txt` for one sequence; returns the path.
///
/// # Errors
/// The file cannot be written (named).
pub fn write_results_file(dir: &Path, sequence: u32, labels: &[TrackingLabel]) -> Result<PathBuf> {
    let path = sequence_file(dir, sequence);
    write_text(&path, &write_results(labels))?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::kitti::detections::camera_box_to_lidar;
    use crate::io::kitti::labels::parse_labels;

    #[test]
    fn label_survives_lidar_round_trip_into_a_result_line() {
        let calib = crate::io::kitti::calib::tests::sample();
        // A real label of sequence 0001 (frame 0, a Van 13 m ahead-left).
        let text = "0 0 Van 0 0 -1.793451 296.744956 161.752147 455.226042 292.372804 2.000000 1.823255 4.433886 -4.552284 1.858523 13.410495 -2.115488\n";
        let label = parse_labels(text, Path::new("l.txt")).unwrap().remove(0);
        let track = TrackBox {
            frame: 0,
            track_id: 0,
            class: ObjectClass::Car,
            lidar_box: camera_box_to_lidar(&label.cam_box, &calib),
            score: 0.9,
        };
        let result = track_to_label(&track, &calib, ImageSize::KITTI_DEFAULT).unwrap();
        assert!(
            (result.cam_box.bottom_center_rect - label.cam_box.bottom_center_rect).norm() < 1e-9
        );
        // KITTI's annotated alpha differs from rot_y − atan2(x, z) by a few
        // mrad (it appears to be measured from camera 2, 6 cm to the side).
        assert!((result.alpha_rad - label.alpha_rad).abs() < 1e-2);
        // The projected 3D box matches the annotated 2D box to a few pixels.
        for k in 0..4 {
            assert!(
                (result.bbox_2d[k] - label.bbox_2d[k]).abs() < 6.0,
                "{:?} vs {:?}",
                result.bbox_2d,
                label.bbox_2d
            );
        }
        let out = write_results(std::slice::from_ref(&result));
        assert!(out.starts_with("0 0 Car 0 0 "));
        assert_eq!(
            parse_labels(&out, Path::new("r.txt")).unwrap(),
            vec![result]
        );
    }

    #[test]
    fn boxes_behind_the_camera_are_not_written() {
        let calib = crate::io::kitti::calib::tests::sample();
        let track = TrackBox {
            frame: 3,
            track_id: 7,
            class: ObjectClass::Pedestrian,
            lidar_box: OrientedBox {
                center: Vector3::new(-10.0, 0.0, -0.8),
                size_lwh: Vector3::new(0.8, 0.6, 1.7),
                yaw_rad: 0.0,
            },
            score: 0.5,
        };
        assert!(track_to_label(&track, &calib, ImageSize::KITTI_DEFAULT).is_none());
    }

    #[test]
    fn results_are_sorted_and_written_per_sequence() {
        let calib = crate::io::kitti::calib::tests::sample();
        let mk = |frame, track_id, x: f64| TrackBox {
            frame,
            track_id,
            class: ObjectClass::Car,
            lidar_box: OrientedBox {
                center: Vector3::new(x, 1.0, -0.9),
                size_lwh: Vector3::new(4.0, 1.7, 1.5),
                yaw_rad: 0.3,
            },
            score: 0.7,
        };
        let labels: Vec<TrackingLabel> = [mk(2, 1, 20.0), mk(0, 5, 15.0), mk(0, 2, 30.0)]
            .iter()
            .filter_map(|t| track_to_label(t, &calib, ImageSize::KITTI_DEFAULT))
            .collect();
        assert_eq!(labels.len(), 3);
        let dir = std::env::temp_dir().join(format!("limot_results_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = write_results_file(&dir, 7, &labels).unwrap();
        assert!(path.ends_with("0007.txt"));
        let back = crate::io::kitti::labels::read_labels(&path).unwrap();
        let keys: Vec<(u32, i64)> = back.iter().map(|l| (l.frame, l.track_id)).collect();
        assert_eq!(keys, vec![(0, 2), (0, 5), (2, 1)]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
