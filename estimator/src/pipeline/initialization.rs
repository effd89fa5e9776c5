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

/// Samples a static initialization needs at least.
pub const MIN_STATIC_SAMPLES: usize = 10;

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
    if n < MIN_STATIC_SAMPLES {
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

/// What the first LiDAR-only sweeps of a moving start tell about the
/// inertial state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MovingInit {
    /// Rotation world ← LiDAR-only world that makes gravity point along -z.
    pub r_world_lidarworld: Rotation3<f64>,
    /// Gravity as measured in the LiDAR-only world, m/s².
    pub gravity_lidarworld: Vector3<f64>,
    pub gyro_bias_radps: Vector3<f64>,
    /// LiDAR velocity at the last pair of sweeps, LiDAR-only world.
    pub velocity_lidarworld_mps: Vector3<f64>,
}

/// Gravity, gyroscope bias and velocity from mid-sweep LiDAR poses
/// `(t_s, t_lidarworld_lidar)` of a moving start and the IMU over them.
///
/// The LiDAR velocity change between the first and the last pair of sweeps
/// equals the integral of the rotated specific force plus gravity:
/// `g = (v_b − v_a − ∫ R·f dt) / (t_b − t_a)`. The gyroscope bias is the
/// mean difference between the gyro-integrated and the LiDAR rotation. The
/// lever arm (ω × r) is neglected, which is fine while the yaw rate is small.
/// `None` when the poses are too few or the recovered gravity magnitude is
/// off by more than `tolerance_mps2` (the poses or the IMU are unreliable).
pub fn moving_init(
    mids: &[(f64, Isometry3<f64>)],
    samples: &[ImuSample],
    t_lidar_imu: &Isometry3<f64>,
    gravity_mps2: f64,
    tolerance_mps2: f64,
) -> Option<MovingInit> {
    let n = mids.len();
    if n < 3 {
        return None;
    }
    let velocity = |a: &(f64, Isometry3<f64>), b: &(f64, Isometry3<f64>)| {
        (b.1.translation.vector - a.1.translation.vector) / (b.0 - a.0)
    };
    let t_a = 0.5 * (mids[0].0 + mids[1].0);
    let t_b = 0.5 * (mids[n - 2].0 + mids[n - 1].0);
    let v_a = velocity(&mids[0], &mids[1]);
    let v_b = velocity(&mids[n - 2], &mids[n - 1]);
    let r_lidar_imu = t_lidar_imu.rotation;
    let rotation_at = |t: f64| -> UnitQuaternion<f64> {
        let i = mids.partition_point(|m| m.0 <= t).clamp(1, n - 1);
        let (t0, p0) = &mids[i - 1];
        let (t1, p1) = &mids[i];
        let s = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
        p0.rotation.slerp(&p1.rotation, s)
    };
    let mut integral = Vector3::zeros();
    let mut covered = 0.0;
    for pair in samples.windows(2) {
        let (s0, s1) = (&pair[0], &pair[1]);
        let lo = s0.t_s.max(t_a);
        let hi = s1.t_s.min(t_b);
        if hi <= lo {
            continue;
        }
        let t_m = 0.5 * (lo + hi);
        let w = (t_m - s0.t_s) / (s1.t_s - s0.t_s);
        let f = s0.accel_mps2 * (1.0 - w) + s1.accel_mps2 * w;
        integral += (rotation_at(t_m) * r_lidar_imu) * f * (hi - lo);
        covered += hi - lo;
    }
    if covered < 0.9 * (t_b - t_a) {
        return None;
    }
    let gravity = (v_b - v_a - integral) / (t_b - t_a);
    if (gravity.norm() - gravity_mps2).abs() > tolerance_mps2 {
        return None;
    }
    let r_world_lidarworld =
        UnitQuaternion::rotation_between(&gravity, &-Vector3::z())?.to_rotation_matrix();
    // Gyro bias: mean rate difference between the gyroscope and the LiDAR.
    let (t_first, t_last) = (mids[0].0, mids[n - 1].0);
    let mut gyro_sum = Vector3::zeros();
    let mut gyro_time = 0.0;
    for pair in samples.windows(2) {
        let lo = pair[0].t_s.max(t_first);
        let hi = pair[1].t_s.min(t_last);
        if hi > lo {
            gyro_sum += 0.5 * (pair[0].gyro_radps + pair[1].gyro_radps) * (hi - lo);
            gyro_time += hi - lo;
        }
    }
    let r_first = mids[0].1.rotation * r_lidar_imu;
    let r_last = mids[n - 1].1.rotation * r_lidar_imu;
    let lidar_rotation = crate::lie::so3_log_quat(&(r_first.inverse() * r_last));
    let gyro_bias_radps = if gyro_time > 0.0 {
        (gyro_sum - lidar_rotation) / gyro_time
    } else {
        Vector3::zeros()
    };
    Some(MovingInit {
        r_world_lidarworld,
        gravity_lidarworld: gravity,
        gyro_bias_radps,
        velocity_lidarworld_mps: v_b,
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

    #[test]
    fn moving_init_recovers_gravity_velocity_and_gyro_bias() {
        // LiDAR world tilted against gravity; constant acceleration along x
        // and a constant yaw rate.
        let r_tilt = UnitQuaternion::from_euler_angles(0.03, -0.02, 0.4);
        let g_world = Vector3::new(0.0, 0.0, -9.81);
        let g_lw = r_tilt.inverse() * g_world;
        let accel_lw = Vector3::new(0.8, 0.1, 0.0);
        let v0 = Vector3::new(10.0, 0.0, 0.0);
        let yaw_rate = 0.05;
        let gyro_bias = Vector3::new(0.002, -0.001, 0.003);
        let t_lidar_imu = Isometry3::from_parts(
            Translation3::new(-0.8, 0.3, -0.8),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.1),
        );
        let r_lidar_imu = t_lidar_imu.rotation;
        let rot = |t: f64| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_rate * t);
        let mids: Vec<(f64, Isometry3<f64>)> = (0..10)
            .map(|i| {
                let t = 0.05 + 0.1 * i as f64;
                let p: Vector3<f64> = v0 * t + accel_lw * (0.5 * t * t);
                (t, Isometry3::from_parts(p.into(), rot(t)))
            })
            .collect();
        let samples: Vec<ImuSample> = (0..=100)
            .map(|i| {
                let t = 0.01 * i as f64;
                let r_lw_imu = rot(t) * r_lidar_imu;
                ImuSample {
                    t_s: t,
                    accel_mps2: r_lw_imu.inverse() * (accel_lw - g_lw),
                    gyro_radps: r_lidar_imu.inverse() * Vector3::new(0.0, 0.0, yaw_rate)
                        + gyro_bias,
                }
            })
            .collect();
        let init = moving_init(&mids, &samples, &t_lidar_imu, 9.81, 0.5).expect("init");
        assert!(
            (init.gravity_lidarworld - g_lw).norm() < 1e-3,
            "{:?}",
            init.gravity_lidarworld
        );
        assert!(
            (init.gyro_bias_radps - gyro_bias).norm() < 1e-6,
            "{:?}",
            init.gyro_bias_radps
        );
        let t_b = 0.5 * (mids[8].0 + mids[9].0);
        assert!((init.velocity_lidarworld_mps - (v0 + accel_lw * t_b)).norm() < 1e-9);
        let down = init.r_world_lidarworld * g_lw.normalize();
        assert!((down + Vector3::z()).norm() < 1e-3);
        // A wrong gravity magnitude (bad poses) is refused.
        assert!(moving_init(&mids, &samples, &t_lidar_imu, 12.0, 0.5).is_none());
    }
}
