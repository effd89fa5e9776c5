//! Static initialization from the first IMU samples: gravity direction
//! (roll, pitch) and gyroscope bias while the vehicle stands still.

use crate::input::ImuSample;
use nalgebra::{Isometry3, Rotation3, UnitQuaternion, Vector3};

/// What a static IMU interval tells about the initial state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticInit {
    /// Rotation world ← IMU with the world z axis against gravity and the
    /// LiDAR heading (x axis projected on the ground) along world x.
    pub r_world_imu: Rotation3<f64>,
    /// Mean angular rate: the gyroscope bias while static.
    pub gyro_bias_radps: Vector3<f64>,
    /// Mean specific-force norm, m/s² (≈ g).
    pub mean_specific_force_mps2: f64,
}

/// Why an IMU interval does not allow a static initialization.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NotStatic {
    TooFewSamples {
        count: usize,
    },
    Moving {
        accel_std_mps2: f64,
        gyro_mean_radps: f64,
    },
}

/// Tries a static initialization from `samples` (the IMU history of the
/// last `init_window_s`). `t_lidar_imu` fixes the yaw convention.
pub fn static_init(
    samples: &[ImuSample],
    t_lidar_imu: &Isometry3<f64>,
    gravity_mps2: f64,
    max_accel_std_mps2: f64,
    max_gyro_radps: f64,
) -> Result<StaticInit, NotStatic> {
    let n = samples.len();
    if n < 10 {
        return Err(NotStatic::TooFewSamples { count: n });
    }
    let count = n as f64;
    let mean_accel = samples.iter().map(|s| s.accel_mps2).sum::<Vector3<f64>>() / count;
    let mean_gyro = samples.iter().map(|s| s.gyro_radps).sum::<Vector3<f64>>() / count;
    let accel_var = samples
        .iter()
        .map(|s| (s.accel_mps2 - mean_accel).norm_squared())
        .sum::<f64>()
        / count;
    let accel_std = accel_var.sqrt();
    let norm = mean_accel.norm();
    let moving = accel_std > max_accel_std_mps2
        || mean_gyro.norm() > max_gyro_radps
        || (norm - gravity_mps2).abs() > 3.0 * max_accel_std_mps2.max(0.1);
    if moving {
        return Err(NotStatic::Moving {
            accel_std_mps2: accel_std,
            gyro_mean_radps: mean_gyro.norm(),
        });
    }
    // At rest the specific force points up: rotate it onto +z.
    let tilt = UnitQuaternion::rotation_between(&mean_accel, &Vector3::z())
        .unwrap_or_else(|| {
            // Upside down: any half turn about a horizontal axis.
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
        })
        .to_rotation_matrix();
    // Remove the yaw of the LiDAR so that the output world starts heading along +x.
    let r_imu_lidar = t_lidar_imu.rotation.inverse().to_rotation_matrix();
    let lidar_x_world = tilt * r_imu_lidar * Vector3::x();
    let yaw = lidar_x_world.y.atan2(lidar_x_world.x);
    let r_world_imu = Rotation3::from_axis_angle(&Vector3::z_axis(), -yaw) * tilt;
    Ok(StaticInit {
        r_world_imu,
        gyro_bias_radps: mean_gyro,
        mean_specific_force_mps2: norm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Translation3;

    fn samples(r_world_imu: &Rotation3<f64>, gyro_bias: Vector3<f64>) -> Vec<ImuSample> {
        (0..50)
            .map(|i| ImuSample {
                t_s: i as f64 * 0.01,
                accel_mps2: r_world_imu.inverse() * Vector3::new(0.0, 0.0, 9.81),
                gyro_radps: gyro_bias,
            })
            .collect()
    }

    #[test]
    fn recovers_tilt_and_gyro_bias_and_zeroes_lidar_yaw() {
        let r_world_imu = Rotation3::from_euler_angles(0.05, -0.03, 1.2);
        let bias = Vector3::new(0.001, -0.002, 0.0005);
        let t_lidar_imu = Isometry3::from_parts(
            Translation3::new(-0.81, 0.32, -0.8),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3),
        );
        let init = static_init(&samples(&r_world_imu, bias), &t_lidar_imu, 9.81, 0.2, 0.05)
            .expect("static");
        assert!((init.gyro_bias_radps - bias).norm() < 1e-12);
        // Gravity direction is exact.
        let up = init.r_world_imu * (r_world_imu.inverse() * Vector3::z());
        assert!((up - Vector3::z()).norm() < 1e-12);
        // The LiDAR heads along world x.
        let r_world_lidar = init.r_world_imu * t_lidar_imu.rotation.inverse().to_rotation_matrix();
        let x = r_world_lidar * Vector3::x();
        assert!(x.y.abs() < 1e-12 && x.x > 0.0);
    }

    #[test]
    fn rejects_motion_and_short_histories() {
        let mut s = samples(&Rotation3::identity(), Vector3::zeros());
        assert!(matches!(
            static_init(&s[..5], &Isometry3::identity(), 9.81, 0.2, 0.05),
            Err(NotStatic::TooFewSamples { count: 5 })
        ));
        for (i, sample) in s.iter_mut().enumerate() {
            sample.accel_mps2.x = if i % 2 == 0 { 1.0 } else { -1.0 };
        }
        assert!(matches!(
            static_init(&s, &Isometry3::identity(), 9.81, 0.2, 0.05),
            Err(NotStatic::Moving { .. })
        ));
    }
}
