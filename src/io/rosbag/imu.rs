//! `sensor_msgs/Imu` as an [`ImuSample`] and back: the angular rate and the
//! linear acceleration (specific force, as ROS defines it: an IMU at rest
//! reads +9.81 m/s² up); the orientation is neither read nor written.

use super::msgs::{Fixed, Header, Imu, Quaternion, Time, Vector3, ns_to_s};
use limot_estimator::input::ImuSample;

/// The sample of `imu`, at its `header.stamp`.
pub fn imu_sample(imu: &Imu) -> ImuSample {
    let v = |v: &Vector3| nalgebra::Vector3::new(v.x, v.y, v.z);
    ImuSample {
        t_s: ns_to_s(imu.header.stamp.ns()),
        accel_mps2: v(&imu.linear_acceleration),
        gyro_radps: v(&imu.angular_velocity),
    }
}

/// `sample` as an `Imu` message stamped `stamp` in `frame_id`, with no
/// orientation estimate (`orientation_covariance[0] = -1`, as ROS asks) and
/// unknown covariances (zeros).
pub fn imu_message(stamp: Time, frame_id: &str, sample: &ImuSample) -> Imu {
    let v = |v: &nalgebra::Vector3<f64>| Vector3 {
        x: v.x,
        y: v.y,
        z: v.z,
    };
    let mut no_orientation = [0.0; 9];
    no_orientation[0] = -1.0;
    Imu {
        header: Header {
            stamp,
            frame_id: frame_id.to_string(),
        },
        orientation: Quaternion::default(),
        orientation_covariance: Fixed(no_orientation),
        angular_velocity: v(&sample.gyro_radps),
        angular_velocity_covariance: Fixed::default(),
        linear_acceleration: v(&sample.accel_mps2),
        linear_acceleration_covariance: Fixed::default(),
    }
}
