//! The sensor contract: what any data source delivers to the estimator.
//!
//! Frames: the LiDAR frame is the ego frame (x forward, y left, z up).
//! Times are seconds on one clock shared by all streams. Units are SI.

use crate::geometry::OrientedBox;
use nalgebra::{Isometry3, Vector3};
use std::fmt;

/// One IMU sample in the IMU body frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// Time of the sample, s.
    pub t_s: f64,
    /// Specific force (acceleration minus gravity), body frame.
    pub accel_mps2: Vector3<f64>,
    /// Angular rate, body frame.
    pub gyro_radps: Vector3<f64>,
}

/// One LiDAR return, in the LiDAR frame at the time the point was measured
/// (raw, not motion-compensated).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LidarPoint {
    /// Position, LiDAR frame, m.
    pub x: f32,
    /// See [`LidarPoint::x`].
    pub y: f32,
    /// See [`LidarPoint::x`].
    pub z: f32,
    /// Return intensity, as the sensor reports it.
    pub intensity: f32,
    /// Laser index, 0 = lowest beam.
    pub ring: u16,
    /// Time of the measurement relative to [`LidarScan::t_s`], in seconds.
    pub time_offset_s: f32,
}

impl LidarPoint {
    /// The position `(x, y, z)` as `f64`, LiDAR frame, m.
    pub fn position(&self) -> Vector3<f64> {
        Vector3::new(self.x as f64, self.y as f64, self.z as f64)
    }
}

/// One LiDAR sweep.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LidarScan {
    /// Sweep start time; every point's own time is `t_s + time_offset_s`.
    pub t_s: f64,
    /// Nominal sweep duration (0.1 s for a 10 Hz spinning LiDAR).
    pub sweep_duration_s: f64,
    /// Number of lasers (rings) of the sensor.
    pub num_rings: u16,
    /// The returns, in the order the sensor delivered them.
    pub points: Vec<LidarPoint>,
}

/// Object classes shared by detector, tracker and evaluation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ObjectClass {
    /// A car or van.
    Car,
    /// A truck or bus.
    Truck,
    /// A cyclist with the bicycle.
    Cyclist,
    /// A person on foot.
    Pedestrian,
}

impl ObjectClass {
    /// Every class, in index order.
    pub const ALL: [ObjectClass; 4] = [
        ObjectClass::Car,
        ObjectClass::Truck,
        ObjectClass::Cyclist,
        ObjectClass::Pedestrian,
    ];

    /// The class name as KITTI writes it (`Car`, `Truck`, ...).
    pub fn name(self) -> &'static str {
        match self {
            ObjectClass::Car => "Car",
            ObjectClass::Truck => "Truck",
            ObjectClass::Cyclist => "Cyclist",
            ObjectClass::Pedestrian => "Pedestrian",
        }
    }

    /// Parses the class names used by KITTI and by our own files
    /// (case-insensitive; KITTI's `Van` counts as a car).
    pub fn parse(name: &str) -> Option<ObjectClass> {
        match name.to_ascii_lowercase().as_str() {
            "car" | "van" => Some(ObjectClass::Car),
            "truck" => Some(ObjectClass::Truck),
            "cyclist" => Some(ObjectClass::Cyclist),
            "pedestrian" | "person" | "person_sitting" => Some(ObjectClass::Pedestrian),
            _ => None,
        }
    }
}

impl fmt::Display for ObjectClass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A 3D bounding box detection in the LiDAR frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// The box, LiDAR frame (heading about the LiDAR z axis, 0 = along +x).
    pub box_lidar: OrientedBox,
    /// Detected class.
    pub class: ObjectClass,
    /// Detector confidence in [0, 1].
    pub score: f64,
    /// When the sweep saw the object, relative to the scan's `t_s`
    /// (the box is where the raw points put it, in the LiDAR frame at that time).
    pub time_offset_s: f64,
}

/// Everything that arrives with one LiDAR sweep.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Frame {
    /// The sweep.
    pub scan: LidarScan,
    /// The detector's boxes of this sweep.
    pub detections: Vec<Detection>,
}

/// Fixed sensor extrinsics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extrinsics {
    /// Maps IMU-frame points into the LiDAR frame.
    pub t_lidar_imu: Isometry3<f64>,
}

impl Default for Extrinsics {
    fn default() -> Self {
        Extrinsics {
            t_lidar_imu: Isometry3::identity(),
        }
    }
}

/// Why a piece of input was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InputError {
    /// An IMU sample has a non-finite field.
    #[error("IMU sample at t={t_s}: field `{field}` is not finite")]
    ImuNotFinite {
        /// Time of the sample, s.
        t_s: f64,
        /// The field.
        field: &'static str,
    },
    /// IMU samples out of order.
    #[error("IMU sample at t={t_s} is not after the previous one at t={previous_t_s}")]
    ImuTimeNotIncreasing {
        /// Time of the sample, s.
        t_s: f64,
        /// Time of the sample before it, s.
        previous_t_s: f64,
    },
    /// A scan's time or sweep duration is not finite (or negative).
    #[error("scan at t={t_s}: field `{field}` is not finite")]
    ScanNotFinite {
        /// Scan start time, s.
        t_s: f64,
        /// The field.
        field: &'static str,
    },
    /// Scans out of order.
    #[error("scan at t={t_s} is not after the previous scan at t={previous_t_s}")]
    ScanTimeNotIncreasing {
        /// Scan start time, s.
        t_s: f64,
        /// Start time of the scan before it, s.
        previous_t_s: f64,
    },
    /// A detection no detector can produce.
    #[error("detection {index} of the scan at t={t_s}: field `{field}` is invalid ({why})")]
    BadDetection {
        /// Scan start time, s.
        t_s: f64,
        /// Index of the detection in its frame.
        index: usize,
        /// The field.
        field: &'static str,
        /// What is wrong with it.
        why: &'static str,
    },
}

impl ImuSample {
    /// Rejects non-finite values.
    ///
    /// # Errors
    /// [`InputError::ImuNotFinite`] naming the first non-finite field.
    pub fn validate(&self) -> Result<(), InputError> {
        let t_s = self.t_s;
        if !t_s.is_finite() {
            return Err(InputError::ImuNotFinite { t_s, field: "t_s" });
        }
        if !self.accel_mps2.iter().all(|v| v.is_finite()) {
            return Err(InputError::ImuNotFinite {
                t_s,
                field: "accel_mps2",
            });
        }
        if !self.gyro_radps.iter().all(|v| v.is_finite()) {
            return Err(InputError::ImuNotFinite {
                t_s,
                field: "gyro_radps",
            });
        }
        Ok(())
    }
}

impl Detection {
    /// Rejects boxes no detector can produce: non-finite values, non-positive
    /// sizes, scores outside [0, 1].
    ///
    /// # Errors
    /// [`InputError::BadDetection`] naming the field and why.
    pub fn validate(&self, t_s: f64, index: usize) -> Result<(), InputError> {
        let bad = |field, why| InputError::BadDetection {
            t_s,
            index,
            field,
            why,
        };
        if !self.box_lidar.center.iter().all(|v| v.is_finite()) {
            return Err(bad("center_lidar", "not finite"));
        }
        if !self
            .box_lidar
            .size_lwh
            .iter()
            .all(|v| v.is_finite() && *v > 0.0)
        {
            return Err(bad("size_lwh", "not finite and positive"));
        }
        if !self.box_lidar.yaw_rad.is_finite() {
            return Err(bad("yaw_rad", "not finite"));
        }
        if !(0.0..=1.0).contains(&self.score) {
            return Err(bad("score", "outside [0, 1]"));
        }
        if !self.time_offset_s.is_finite() {
            return Err(bad("time_offset_s", "not finite"));
        }
        Ok(())
    }

    /// [`Detection::validate`], and the box must have been seen during its
    /// sweep (`0 ≤ time_offset_s ≤ sweep_duration_s`, to a microsecond).
    ///
    /// # Errors
    /// As [`Detection::validate`], and [`InputError::BadDetection`] for a time
    /// offset outside the sweep.
    pub fn validate_in_sweep(
        &self,
        t_s: f64,
        index: usize,
        sweep_duration_s: f64,
    ) -> Result<(), InputError> {
        self.validate(t_s, index)?;
        let slack_s = 1e-6;
        if !(-slack_s..=sweep_duration_s + slack_s).contains(&self.time_offset_s) {
            return Err(InputError::BadDetection {
                t_s,
                index,
                field: "time_offset_s",
                why: "outside the sweep",
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn class_names_round_trip() {
        for class in ObjectClass::ALL {
            assert_eq!(ObjectClass::parse(class.name()), Some(class));
        }
        assert_eq!(ObjectClass::parse("Van"), Some(ObjectClass::Car));
        assert_eq!(ObjectClass::parse("DontCare"), None);
    }

    #[test]
    fn detection_validation_names_the_field() {
        let mut det = Detection {
            box_lidar: OrientedBox {
                center: Vector3::new(10.0, 0.0, 0.0),
                size_lwh: Vector3::new(4.0, 1.8, 1.5),
                yaw_rad: 0.0,
            },
            class: ObjectClass::Car,
            score: 0.9,
            time_offset_s: 0.05,
        };
        assert!(det.validate(0.0, 0).is_ok());
        det.box_lidar.size_lwh.x = -1.0;
        let err = det.validate(1.5, 3).unwrap_err();
        assert!(err.to_string().contains("size_lwh"), "{err}");
        det.box_lidar.size_lwh.x = 4.0;
        det.box_lidar.center.y = f64::NAN;
        let err = det.validate(1.5, 3).unwrap_err();
        assert!(err.to_string().contains("center_lidar"), "{err}");
    }

    #[test]
    fn imu_validation_rejects_nan() {
        let sample = ImuSample {
            t_s: 0.0,
            accel_mps2: Vector3::new(0.0, f64::NAN, 9.8),
            gyro_radps: Vector3::zeros(),
        };
        assert!(matches!(
            sample.validate(),
            Err(InputError::ImuNotFinite {
                field: "accel_mps2",
                ..
            })
        ));
    }
}
