//! Bad input to the streaming estimator: clear errors or documented
//! recoveries, never a panic.

use limot_estimator::geometry::OrientedBox;
use limot_estimator::input::{
    Detection, Extrinsics, Frame, ImuSample, LidarPoint, LidarScan, ObjectClass,
};
use limot_estimator::pipeline::{Estimator, EstimatorConfig, EstimatorError, Variant};
use limot_estimator::tracking::{Lifecycle, Motion};
use nalgebra::Vector3;

/// A still sensor in a 20 m × 14 m × 6 m room: 64 rings × 720 columns.
fn room_scan(t_s: f64) -> LidarScan {
    let mut points = Vec::new();
    for column in 0..720 {
        let az = column as f64 / 720.0 * std::f64::consts::TAU;
        for ring in 0..64u16 {
            let el = (-24.0 + 26.0 * ring as f64 / 63.0).to_radians();
            let d = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
            // Distance to the room's walls, floor (z = -1.7) and ceiling (z = 4.3).
            let mut range = f64::INFINITY;
            for (n, offset) in [
                (Vector3::x(), 12.0),
                (-Vector3::x(), 8.0),
                (Vector3::y(), 6.0),
                (-Vector3::y(), 8.0),
                (-Vector3::z(), 1.7),
                (Vector3::z(), 4.3),
            ] {
                let c = d.dot(&n);
                if c > 1e-9 {
                    range = range.min(offset / c);
                }
            }
            let p = d * range;
            points.push(LidarPoint {
                x: p.x as f32,
                y: p.y as f32,
                z: p.z as f32,
                intensity: 0.5,
                ring,
                time_offset_s: (column as f64 / 720.0 * 0.1) as f32,
            });
        }
    }
    LidarScan {
        t_s,
        sweep_duration_s: 0.1,
        num_rings: 64,
        points,
    }
}

fn still_imu(t_s: f64) -> ImuSample {
    ImuSample {
        t_s,
        accel_mps2: Vector3::new(0.0, 0.0, 9.80511),
        gyro_radps: Vector3::zeros(),
    }
}

fn frame(t_s: f64) -> Frame {
    Frame {
        scan: room_scan(t_s),
        detections: Vec::new(),
    }
}

#[test]
fn still_room_initialises_and_stays_put() {
    let mut est = Estimator::new(EstimatorConfig::default(), Extrinsics::default()).unwrap();
    let mut estimates = Vec::new();
    let mut first_inertial = None;
    let mut next_sample = 0;
    for k in 0..15 {
        let t = k as f64 * 0.1;
        // IMU through the end of the sweep, at 100 Hz on an integer grid.
        while next_sample <= 10 * (k + 1) {
            est.push_imu(still_imu(next_sample as f64 * 0.01)).unwrap();
            next_sample += 1;
        }
        let scan = frame(t);
        let completed = est.push_frame(&scan).unwrap();
        if first_inertial.is_none() && !completed.is_empty() {
            first_inertial = Some(k as u64);
        }
        // The sweep as the estimator used it: de-skewed to the scan start
        // once inertial, to the sweep's middle while LiDAR-only; standing
        // still, the points are where the sensor saw them.
        let sweep = est.deskewed_sweep().unwrap();
        assert_eq!((sweep.frame_index, sweep.t_s), (k as u64, t));
        let t_ref_s = if first_inertial.is_some() {
            t
        } else {
            t + 0.05
        };
        assert!((sweep.t_ref_s - t_ref_s).abs() < 1e-12, "{}", sweep.t_ref_s);
        assert_eq!(sweep.points_lidar.len(), scan.scan.points.len());
        for (p, raw) in sweep.points_lidar.iter().zip(&scan.scan.points) {
            assert!((p - raw.position()).norm() < 0.02, "{p} vs {raw:?}");
        }
        assert!(sweep.t_lidar_lidar_at(t) == nalgebra::Isometry3::identity());
        estimates.extend(completed);
    }
    assert!(est.is_initialized());
    let first_inertial = first_inertial.unwrap();
    assert!(
        first_inertial > 0,
        "a static start waits for the IMU window"
    );
    // Every frame has its estimate, the LiDAR-only ones before the
    // initialisation included, in frame order.
    let indices: Vec<u64> = estimates.iter().map(|e| e.frame_index).collect();
    assert_eq!(indices, (0..15).collect::<Vec<u64>>());
    for e in &estimates {
        // The LiDAR-only sweeps creep by mm per sweep, and their velocities
        // are pose differences over 0.1 s: mm of match noise are cm/s.
        let lidar_only = e.frame_index < first_inertial;
        let max_offset_m = if lidar_only { 0.02 } else { 0.01 };
        let max_speed_mps = if lidar_only { 0.1 } else { 0.05 };
        assert!(
            e.t_world_lidar.translation.vector.norm() < max_offset_m,
            "{e:?}"
        );
        assert!(
            e.velocity_world_mps.norm() < max_speed_mps,
            "frame {}: {}",
            e.frame_index,
            e.velocity_world_mps
        );
    }
}

#[test]
fn imu_and_scan_errors_name_what_is_wrong() {
    let mut est = Estimator::new(EstimatorConfig::default(), Extrinsics::default()).unwrap();
    est.push_imu(still_imu(1.0)).unwrap();
    let err = est.push_imu(still_imu(0.5)).unwrap_err();
    assert!(err.to_string().contains("not after"), "{err}");
    let mut nan = still_imu(2.0);
    nan.gyro_radps.y = f64::NAN;
    let err = est.push_imu(nan).unwrap_err();
    assert!(err.to_string().contains("gyro_radps"), "{err}");

    est.push_frame(&frame(1.0)).unwrap();
    let err = est.push_frame(&frame(0.9)).unwrap_err();
    assert!(err.to_string().contains("not after"), "{err}");
    let mut bad = frame(3.0);
    bad.scan.t_s = f64::NAN;
    let err = est.push_frame(&bad).unwrap_err();
    assert!(err.to_string().contains("t_s"), "{err}");
}

#[test]
fn nan_points_are_dropped_and_empty_scans_do_not_panic() {
    let mut est = Estimator::new(EstimatorConfig::lidar_only(), Extrinsics::default()).unwrap();
    let mut f = frame(0.0);
    for p in f.scan.points.iter_mut().step_by(7) {
        p.x = f32::NAN;
    }
    let first = est.push_frame(&f).unwrap();
    assert_eq!(first.len(), 1, "LiDAR-only estimates at once");
    let finite = f.scan.points.iter().filter(|p| p.x.is_finite()).count();
    assert_eq!(est.deskewed_sweep().unwrap().points_lidar.len(), finite);
    let first = &first[0];
    assert!(first.t_world_lidar.translation.vector.norm() < 1e-9);
    // An empty sweep: no features, no match; the pose is the prediction.
    let empty = Frame {
        scan: LidarScan {
            t_s: 0.1,
            sweep_duration_s: 0.1,
            num_rings: 64,
            points: Vec::new(),
        },
        detections: Vec::new(),
    };
    let e = est.push_frame(&empty).unwrap().remove(0);
    assert!(e.scan_match.is_none());
    let e = est.push_frame(&frame(0.2)).unwrap().remove(0);
    assert!(e.scan_match.is_some_and(|m| m.converged));
    assert!(e.t_world_lidar.translation.vector.norm() < 0.01);
}

#[test]
fn an_imu_gap_is_an_error_naming_the_frame() {
    let mut est = Estimator::new(EstimatorConfig::default(), Extrinsics::default()).unwrap();
    let mut k = 0;
    while !est.is_initialized() {
        let t = k as f64 * 0.1;
        for i in 0..=10 {
            est.push_imu(still_imu(t + i as f64 * 0.01)).ok();
        }
        est.push_frame(&frame(t)).unwrap();
        k += 1;
        assert!(k < 30, "never initialised");
    }
    // Half a second without IMU samples.
    let t_gap = k as f64 * 0.1 + 0.5;
    for i in 0..=10 {
        est.push_imu(still_imu(t_gap + i as f64 * 0.01)).unwrap();
    }
    let err = est.push_frame(&frame(t_gap)).unwrap_err();
    assert!(matches!(err, EstimatorError::Imu { .. }), "{err}");
    let text = err.to_string();
    assert!(text.contains(&format!("frame {k}")), "{text}");
}

/// A parked car's box in the room (LiDAR frame) and five boxes no detector
/// can produce.
fn detections_with_garbage() -> Vec<Detection> {
    let car = Detection {
        box_lidar: OrientedBox {
            center: Vector3::new(6.0, 3.0, -0.95),
            size_lwh: Vector3::new(4.5, 1.8, 1.5),
            yaw_rad: 0.3,
        },
        class: ObjectClass::Car,
        score: 0.9,
        time_offset_s: 0.02,
    };
    let mut garbage = vec![car; 5];
    garbage[0].box_lidar.center.x = f64::NAN;
    garbage[1].box_lidar.size_lwh.y = -1.8;
    garbage[2].score = 2.0;
    garbage[3].box_lidar.yaw_rad = f64::INFINITY;
    garbage[4].time_offset_s = 0.5;
    let mut all = vec![car];
    all.extend(garbage);
    all
}

#[test]
fn garbage_detections_are_skipped_and_counted_in_every_variant() {
    for variant in [Variant::Allfilt, Variant::Dynafilt, Variant::Limot] {
        let config = EstimatorConfig {
            variant,
            ..EstimatorConfig::default()
        };
        let mut est = Estimator::new(config, Extrinsics::default()).unwrap();
        let mut next_sample = 0;
        let mut last = None;
        let frames = 15;
        for k in 0..frames {
            while next_sample <= 10 * (k + 1) {
                est.push_imu(still_imu(next_sample as f64 * 0.01)).unwrap();
                next_sample += 1;
            }
            let f = Frame {
                scan: room_scan(k as f64 * 0.1),
                detections: detections_with_garbage(),
            };
            if let Some(e) = est.push_frame(&f).unwrap().pop() {
                last = Some(e);
            }
        }
        assert_eq!(est.invalid_detections(), 5 * frames as u64, "{variant:?}");
        let last = last.expect("estimates after initialisation");
        // The one valid box became a confirmed, static track where it is.
        assert_eq!(last.tracks.len(), 1, "{variant:?}: {:?}", last.tracks);
        let track = &last.tracks[0];
        assert_eq!(track.lifecycle, Lifecycle::Confirmed, "{variant:?}");
        assert_eq!(track.motion, Motion::Static, "{variant:?}");
        assert!(
            (track.center_world - Vector3::new(6.0, 3.0, -0.95)).norm() < 0.05,
            "{variant:?}: {:?}",
            track.center_world
        );
        assert!(track.velocity_world_mps.norm() < 0.05, "{variant:?}");
        assert!(last.t_world_lidar.translation.vector.norm() < 0.01);
    }
}

#[test]
fn limot_without_an_imu_is_refused_with_a_reason() {
    let config = EstimatorConfig {
        variant: Variant::Limot,
        ..EstimatorConfig::lidar_only()
    };
    let Err(err) = Estimator::new(config, Extrinsics::default()) else {
        panic!("limot without an IMU was accepted");
    };
    assert!(matches!(err, EstimatorError::LimotNeedsImu), "{err}");
    assert!(err.to_string().contains("needs the IMU"), "{err}");
    // The filtering variants run without one.
    for variant in [Variant::Lio, Variant::Allfilt, Variant::Dynafilt] {
        let config = EstimatorConfig {
            variant,
            ..EstimatorConfig::lidar_only()
        };
        assert!(Estimator::new(config, Extrinsics::default()).is_ok());
    }
}
