//! `vision_msgs/Detection3DArray` as a sweep's [`Detection`]s and back.
//!
//! A detection's box is `bbox` (centre, yaw of its orientation about z,
//! size = length, width, height along the box axes); its class and score
//! are those of its best-scoring hypothesis; it was seen at its own
//! `header.stamp` (the array's when that is zero).

use super::msgs::{
    BoundingBox3D, Detection3D, Detection3DArray, Fixed, Header, ObjectHypothesisWithPose, Pose,
    Quaternion, Time, Vector3, ns_to_s,
};
use limot_estimator::geometry::OrientedBox;
use limot_estimator::input::{Detection, ObjectClass};

/// The detections of `array` with times relative to the sweep start `t_s`,
/// and the number skipped for a class limot does not track (or none).
///
/// # Errors
/// A detection whose stamp gives no finite time; the text names the
/// detection and the field.
pub fn detections(array: &Detection3DArray, t_s: f64) -> Result<(Vec<Detection>, usize), String> {
    let mut out = Vec::with_capacity(array.detections.len());
    let mut skipped = 0;
    for (i, d) in array.detections.iter().enumerate() {
        let best = d
            .results
            .iter()
            .filter(|h| !h.score.is_nan())
            .max_by(|a, b| a.score.total_cmp(&b.score));
        let Some(class) = best.and_then(|h| ObjectClass::parse(&h.class_id)) else {
            skipped += 1;
            continue;
        };
        let score = best.map_or(0.0, |h| h.score);
        let q = &d.bbox.center.orientation;
        let yaw_rad = (2.0 * (q.w * q.z + q.x * q.y)).atan2(1.0 - 2.0 * (q.y * q.y + q.z * q.z));
        let stamp = if d.header.stamp == Time::default() {
            array.header.stamp
        } else {
            d.header.stamp
        };
        let p = &d.bbox.center.position;
        let s = &d.bbox.size;
        let detection = Detection {
            box_lidar: OrientedBox::new(
                nalgebra::Vector3::new(p.x, p.y, p.z),
                nalgebra::Vector3::new(s.x, s.y, s.z),
                yaw_rad,
            ),
            class,
            score,
            time_offset_s: ns_to_s(stamp.ns()) - t_s,
        };
        if !detection.time_offset_s.is_finite() {
            return Err(format!("detections[{i}].header.stamp: not a finite time"));
        }
        out.push(detection);
    }
    Ok((out, skipped))
}

/// `detections` of the sweep stamped `stamp` as an array in `frame_id`;
/// each detection is stamped `stamp_of(time_offset_s)`.
pub fn detection_array(
    stamp: Time,
    frame_id: &str,
    detections: &[Detection],
    stamp_of: impl Fn(f64) -> Time,
) -> Detection3DArray {
    let header = |stamp| Header {
        stamp,
        frame_id: frame_id.to_string(),
    };
    Detection3DArray {
        header: header(stamp),
        detections: detections
            .iter()
            .map(|d| {
                let b = &d.box_lidar;
                let (sin, cos) = (0.5 * b.yaw_rad).sin_cos();
                let center = Pose {
                    position: Vector3 {
                        x: b.center.x,
                        y: b.center.y,
                        z: b.center.z,
                    },
                    orientation: Quaternion {
                        x: 0.0,
                        y: 0.0,
                        z: sin,
                        w: cos,
                    },
                };
                Detection3D {
                    header: header(stamp_of(d.time_offset_s)),
                    results: vec![ObjectHypothesisWithPose {
                        class_id: d.class.name().to_string(),
                        score: d.score,
                        pose: center,
                        covariance: Fixed::default(),
                    }],
                    bbox: BoundingBox3D {
                        center,
                        size: Vector3 {
                            x: b.size_lwh.x,
                            y: b.size_lwh.y,
                            z: b.size_lwh.z,
                        },
                    },
                    id: String::new(),
                }
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detections_round_trip() {
        let d = Detection {
            box_lidar: OrientedBox::new(
                nalgebra::Vector3::new(10.0, -2.0, 0.8),
                nalgebra::Vector3::new(4.5, 1.9, 1.6),
                2.5,
            ),
            class: ObjectClass::Truck,
            score: 0.75,
            time_offset_s: 0.04,
        };
        let stamp = Time { sec: 1, nanosec: 0 };
        let array = detection_array(stamp, "lidar", &[d], |dt| {
            Time::from_ns(1_000_000_000 + (dt * 1e9).round() as i64).unwrap()
        });
        let (back, skipped) = detections(&array, 1.0).unwrap();
        assert_eq!(skipped, 0);
        let b = &back[0];
        assert_eq!((b.class, b.score), (d.class, d.score));
        assert_eq!(b.box_lidar.center, d.box_lidar.center);
        assert!((b.box_lidar.yaw_rad - 2.5).abs() < 1e-12);
        assert!((b.time_offset_s - 0.04).abs() < 1e-9);
    }

    #[test]
    fn unknown_classes_are_skipped() {
        let mut array = detection_array(Time::default(), "lidar", &[], |_| Time::default());
        array.detections.push(Detection3D {
            header: Header::default(),
            results: vec![ObjectHypothesisWithPose {
                class_id: "traffic_sign".into(),
                score: 0.9,
                pose: Pose::default(),
                covariance: Fixed::default(),
            }],
            bbox: BoundingBox3D::default(),
            id: String::new(),
        });
        assert_eq!(detections(&array, 0.0).unwrap(), (vec![], 1));
    }
}
