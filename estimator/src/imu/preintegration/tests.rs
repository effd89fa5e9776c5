//! Unit tests of IMU preintegration and propagation.

use super::*;

fn sample(t_s: f64, a: [f64; 3], w: [f64; 3]) -> ImuSample {
    ImuSample {
        t_s,
        accel_mps2: Vector3::from(a),
        gyro_radps: Vector3::from(w),
    }
}

#[test]
fn knots_interpolate_the_ends_and_keep_inner_samples() {
    let samples = [
        sample(0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
        sample(1.0, [1.0, 2.0, 3.0], [0.1, 0.2, 0.3]),
        sample(2.0, [3.0, 2.0, 1.0], [0.3, 0.2, 0.1]),
    ];
    let knots = interval_knots(&samples, 0.5, 1.5, 2.0).unwrap();
    assert_eq!(knots.len(), 3);
    assert!((knots[0].accel_mps2 - Vector3::new(0.5, 1.0, 1.5)).norm() < 1e-15);
    assert_eq!(knots[1].t_s, 1.0);
    assert!((knots[2].gyro_radps - Vector3::new(0.2, 0.2, 0.2)).norm() < 1e-15);
    // Interval ends exactly on samples: no duplicate knots.
    let knots = interval_knots(&samples, 0.0, 2.0, 2.0).unwrap();
    assert_eq!(knots.len(), 3);
}

#[test]
fn constant_rotation_rate_gives_exact_delta_rotation() {
    let w = Vector3::new(0.3, -0.2, 0.5);
    let mut pre = Preintegration::new(ImuBias::default(), ImuNoise::default());
    for _ in 0..100 {
        pre.integrate(&Vector3::zeros(), &w, 0.01);
    }
    let err = lie::so3_log(&(lie::so3_exp(&w).inverse() * pre.delta_rotation())).norm();
    assert!(err < 1e-12, "{err}");
    assert!((pre.delta_t_s() - 1.0).abs() < 1e-12);
}

#[test]
fn constant_specific_force_without_rotation_is_exact() {
    let a = Vector3::new(0.5, -1.0, 2.0);
    let mut pre = Preintegration::new(ImuBias::default(), ImuNoise::default());
    for _ in 0..37 {
        pre.integrate(&a, &Vector3::zeros(), 0.01);
    }
    let t = pre.delta_t_s();
    assert!((pre.delta_velocity() - a * t).norm() < 1e-12);
    assert!((pre.delta_position() - a * (0.5 * t * t)).norm() < 1e-12);
}

#[test]
fn try_integrate_rejects_bad_steps() {
    let mut pre = Preintegration::new(ImuBias::default(), ImuNoise::default());
    let z = Vector3::zeros();
    assert!(pre.try_integrate(&z, &z, 0.0).is_err());
    assert!(pre.try_integrate(&z, &z, f64::NAN).is_err());
    assert!(
        pre.try_integrate(&Vector3::new(f64::INFINITY, 0.0, 0.0), &z, 0.01)
            .is_err()
    );
    assert!(pre.try_integrate(&z, &z, 0.01).is_ok());
}

#[test]
fn trajectory_end_equals_prediction() {
    let samples: Vec<ImuSample> = (0..=30)
        .map(|k| {
            let t = k as f64 * 0.01;
            sample(
                t,
                [1.0 + t, -0.5 * t, 9.7 + 0.2 * t],
                [0.1 * t, 0.3, -0.2 + t],
            )
        })
        .collect();
    let bias = ImuBias {
        accel_mps2: Vector3::new(0.02, -0.01, 0.03),
        gyro_radps: Vector3::new(0.001, 0.002, -0.003),
    };
    let g = Vector3::new(0.0, 0.0, -9.80511);
    let start = Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.1, -0.2, 0.3));
    let v0 = Vector3::new(3.0, 0.5, -0.1);
    let pre = Preintegration::from_samples(&samples, 0.013, 0.271, bias, ImuNoise::default(), 0.05)
        .unwrap();
    let (pose_j, v_j) = pre.predict(&start, &v0, &bias, &g);
    let traj =
        ImuTrajectory::propagate(&samples, 0.013, 0.271, &start, &v0, &bias, &g, 0.05).unwrap();
    let (end_pose, end_v) = traj.end_state();
    assert!((end_pose.translation.vector - pose_j.translation.vector).norm() < 1e-12);
    assert!(end_pose.rotation.angle_to(&pose_j.rotation) < 1e-12);
    assert!((end_v - v_j).norm() < 1e-12);
    // pose_at agrees with the knots and with the end.
    let at_end = traj.pose_at(0.271).unwrap();
    assert!((at_end.translation.vector - pose_j.translation.vector).norm() < 1e-12);
    let at_start = traj.pose_at(0.013).unwrap();
    assert!((at_start.translation.vector - start.translation.vector).norm() < 1e-15);
    // A query between knots equals a fresh propagation that ends there.
    let mid = 0.1234;
    let sub = ImuTrajectory::propagate(&samples, 0.013, mid, &start, &v0, &bias, &g, 0.05)
        .unwrap()
        .end_state()
        .0;
    let q = traj.pose_at(mid).unwrap();
    assert!((q.translation.vector - sub.translation.vector).norm() < 1e-12);
    assert!(q.rotation.angle_to(&sub.rotation) < 1e-12);
    assert!(matches!(
        traj.pose_at(0.3),
        Err(PreintegrationError::TimeOutside { .. })
    ));
    assert_eq!(traj.poses_at(&[0.2, 0.1]).unwrap().len(), 2);
}
