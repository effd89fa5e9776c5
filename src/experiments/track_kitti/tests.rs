//! Unit tests of `track_kitti`.

use super::*;
use limot_estimator::input::ObjectClass;

fn pose() -> Isometry3<f64> {
    Isometry3::new(Vector3::new(5.0, -3.0, 0.4), Vector3::new(0.02, -0.01, 1.1))
}

fn output(id: u64, lifecycle: Lifecycle, predicted: bool) -> TrackOutput {
    TrackOutput {
        id,
        class: ObjectClass::Car,
        center_world: Vector3::zeros(),
        yaw_rad: 0.0,
        size_lwh: Vector3::new(4.0, 1.8, 1.5),
        velocity_world_mps: Vector3::zeros(),
        lifecycle,
        motion: limot_estimator::tracking::Motion::Static,
        speed_mps: 0.0,
        predicted,
        detection_index: (!predicted).then_some(0),
        detection_score: None,
    }
}

#[test]
fn result_writer_applies_the_policy_frame_by_frame() {
    use Lifecycle::{Confirmed, Tentative};
    // Defaults: confirmed and matched only, with the matched raw score.
    let mut w = ResultWriter::new(ResultPolicy::default());
    assert_eq!(w.record(0, &output(1, Tentative, false), Some(2.0)), None);
    assert_eq!(
        w.record(1, &output(1, Confirmed, false), Some(4.0)),
        Some(4.0)
    );
    assert_eq!(w.record(2, &output(1, Confirmed, true), None), None);
    assert!(w.keeps(1) && w.keeps(99));

    // Start-up frames write matched tentative tracks; coasting up to one
    // frame keeps the last matched score; the running mean gates.
    let mut w = ResultWriter::new(ResultPolicy {
        output: OutputPolicy::CoastingUpTo(1),
        startup_frames: 2,
        min_track_score: 1.5,
        ..ResultPolicy::default()
    });
    assert_eq!(
        w.record(0, &output(1, Tentative, false), Some(2.0)),
        Some(2.0)
    );
    assert_eq!(
        w.record(1, &output(1, Confirmed, false), Some(1.6)),
        Some(1.6)
    );
    assert_eq!(w.record(2, &output(1, Confirmed, true), None), Some(1.6));
    assert_eq!(w.record(3, &output(1, Confirmed, true), None), None);
    // mean (2 + 1.6 + 0) / 3 < 1.5: a weak match stops the writing
    assert_eq!(w.record(4, &output(1, Confirmed, false), Some(0.0)), None);
    assert_eq!(
        w.record(5, &output(1, Confirmed, false), Some(3.0)),
        Some(3.0)
    );

    // The offline gate judges the whole track afterwards.
    let mut w = ResultWriter::new(ResultPolicy {
        offline_track_score: 3.0,
        ..ResultPolicy::default()
    });
    for (frame, score) in [(0, 5.0), (1, 2.0)] {
        w.record(frame, &output(1, Confirmed, false), Some(score));
        w.record(frame, &output(2, Confirmed, false), Some(score - 2.5));
    }
    w.record(2, &output(3, Confirmed, true), None);
    assert!(w.keeps(1) && !w.keeps(2) && !w.keeps(3) && !w.keeps(4));
}

#[test]
fn world_round_trip_is_exact_for_level_boxes() {
    let t_world_lidar = pose();
    let det = Detection {
        box_lidar: OrientedBox {
            center: Vector3::new(12.0, -2.5, -0.8),
            size_lwh: Vector3::new(4.2, 1.7, 1.5),
            yaw_rad: 0.7,
        },
        class: ObjectClass::Car,
        score: 0.8,
        time_offset_s: 0.05,
    };
    let world = detection_to_world(&det, &t_world_lidar);
    // The centre really is the transformed point; the yaw about 1.1 rad more.
    let expected = t_world_lidar.rotation * det.box_lidar.center + t_world_lidar.translation.vector;
    assert!((world.box_world.center - expected).norm() < 1e-12);
    assert!((wrap_angle_rad(world.box_world.yaw_rad - 0.7 - 1.1)).abs() < 0.01);
    let back = world_box_to_lidar(
        &world.box_world.center,
        &world.box_world.size_lwh,
        world.box_world.yaw_rad,
        &t_world_lidar,
    );
    assert!((back.center - det.box_lidar.center).norm() < 1e-12);
    // Projecting the heading onto the level plane twice loses a little
    // with 0.02 rad of tilt; far below anything the metrics see.
    assert!(wrap_angle_rad(back.yaw_rad - det.box_lidar.yaw_rad).abs() < 1e-3);
}

#[test]
fn output_policies_write_coasting_tracks_as_documented() {
    assert!(OutputPolicy::MatchedConfirmed.writes(0));
    assert!(!OutputPolicy::MatchedConfirmed.writes(1));
    assert!(OutputPolicy::AllConfirmed.writes(5));
    assert!(OutputPolicy::CoastingUpTo(1).writes(1));
    assert!(!OutputPolicy::CoastingUpTo(1).writes(2));
}

#[test]
fn lidar_pose_composes_imu_pose_and_calibration() {
    let calib = crate::io::kitti::calib::tests::sample();
    let t_world_imu = pose();
    let t_world_lidar = lidar_poses(&[t_world_imu], &calib)[0];
    // A LiDAR point goes to the world through the IMU frame.
    let p_lidar = Vector3::new(3.0, 1.0, -0.5);
    let via_imu = t_world_imu
        .transform_point(&calib.velo_to_imu(&p_lidar).into())
        .coords;
    let direct = t_world_lidar.transform_point(&p_lidar.into()).coords;
    assert!((via_imu - direct).norm() < 1e-12);
}
