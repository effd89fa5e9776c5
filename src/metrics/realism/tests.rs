//! Unit tests of `realism`.

use super::*;
use crate::io::kitti::velodyne::KITTI_RING_ELEVATION_DEG;
use nalgebra::Isometry3;

const HEIGHT_M: f64 = 1.73;
const AZIMUTHS: usize = 720;
/// A wall across the track beyond the near rings' ground.
const WALL: Option<(char, f64)> = Some(('x', 40.0));

/// A sweep of the 64 KITTI rings (720 azimuths) from a sensor at
/// `HEIGHT_M` over the plane z = 0 with attitude `roll`, `pitch` (rad),
/// seeing the ground and, optionally, a wall: the plane x = `wall_x` (a
/// wall across the track) or y = `wall_y` (along it), 0..4 m high.
fn sweep(roll: f64, pitch: f64, wall: Option<(char, f64)>) -> Vec<LidarPoint> {
    let r = UnitQuaternion::from_euler_angles(roll, pitch, 0.0);
    let origin = Vector3::new(0.0, 0.0, HEIGHT_M);
    let mut points = Vec::new();
    for (ring, elevation_deg) in KITTI_RING_ELEVATION_DEG.iter().enumerate() {
        let e = elevation_deg.to_radians();
        for k in 0..AZIMUTHS {
            let az = (k as f64 + 0.5) / AZIMUTHS as f64 * TAU - PI;
            let d_lidar = Vector3::new(e.cos() * az.cos(), e.cos() * az.sin(), e.sin());
            let d = r * d_lidar;
            let mut best: Option<f64> = None;
            if d.z < 0.0 {
                best = Some(HEIGHT_M / -d.z);
            }
            if let Some((axis, at)) = wall {
                let (o, dd) = if axis == 'x' { (0.0, d.x) } else { (0.0, d.y) };
                let t = (at - o) / dd;
                if t > 0.0 && best.is_none_or(|b| t < b) {
                    let hit = origin + t * d;
                    if (0.0..4.0).contains(&hit.z) {
                        best = Some(t);
                    }
                }
            }
            let Some(t) = best else { continue };
            if t > 120.0 {
                continue;
            }
            let p = t * d_lidar;
            points.push(LidarPoint {
                x: p.x as f32,
                y: p.y as f32,
                z: p.z as f32,
                intensity: 0.3,
                ring: ring as u16,
                time_offset_s: 0.0,
            });
        }
    }
    points
}

/// Roll, pitch (rad) and wall of a synthetic sweep.
type SweepSpec = (f64, f64, Option<(char, f64)>);

/// The statistics of synthetic sweeps taken 0.5 m apart (the sweeps
/// themselves do not move: the statistics only need the positions to
/// tell moving from standing).
fn stats_of(sweeps: &[SweepSpec]) -> RealismStats {
    let mut acc = RealismAccumulator::new(RealismConfig::default()).unwrap();
    for (i, &(roll, pitch, wall)) in sweeps.iter().enumerate() {
        let attitude = UnitQuaternion::from_euler_angles(roll, pitch, 0.0);
        acc.add_sweep(
            &sweep(roll, pitch, wall),
            &attitude,
            &Vector3::new(0.5 * i as f64, 0.0, 0.0),
            &UnitQuaternion::identity(),
        )
        .unwrap();
    }
    acc.finish().unwrap()
}

#[test]
fn standing_pairs_are_left_out_of_the_motion_statistics() {
    let step = 0.3f64.to_radians();
    let mut acc = RealismAccumulator::new(RealismConfig::default()).unwrap();
    // moving 1 m, then standing while the attitude swings (a car
    // rocking at a light), then moving again with 0.1 deg changes
    let frames = [
        (0.0, 0.0),
        (1.0, 0.0),
        (1.0, step),
        (1.0, 0.0),
        (2.0, 0.0),
        (3.0, 0.1f64.to_radians()),
    ];
    for &(x, pitch) in &frames {
        let attitude = UnitQuaternion::from_euler_angles(0.0, pitch, 0.0);
        acc.add_sweep(
            &sweep(0.0, pitch, WALL),
            &attitude,
            &Vector3::new(x, 0.0, 0.0),
            &UnitQuaternion::identity(),
        )
        .unwrap();
    }
    let s = acc.finish().unwrap();
    assert_eq!(s.standing_pairs, 2);
    assert_eq!(s.pitch_change_deg.n, 3);
    assert!(
        (s.pitch_change_deg.mean - 0.1 / 3.0).abs() < 1e-9,
        "{:?}",
        s.pitch_change_deg
    );
    assert_eq!(s.ground_ring_displacement_m.n, 3);
}

#[test]
fn ground_plane_of_a_tilted_sensor() {
    let (roll, pitch) = (0.01, -0.02);
    let points = sweep(roll, pitch, None);
    let plane = fit_ground_plane(&points, &RealismConfig::default()).unwrap();
    // the plane z = 0 seen from the sensor: z_lidar = a + b x + c y with
    // (a, b, c) from the world normal expressed in the sensor frame
    let t = Isometry3::from_parts(
        Vector3::new(0.0, 0.0, HEIGHT_M).into(),
        UnitQuaternion::from_euler_angles(roll, pitch, 0.0),
    );
    let n = t.rotation.inverse() * Vector3::z();
    let d = -HEIGHT_M; // plane n·p = d in the sensor frame
    let (a, b, c) = (d / n.z, -n.x / n.z, -n.y / n.z);
    assert!((plane.a - a).abs() < 2e-3, "{plane:?} vs {a}");
    assert!(
        (plane.b - b).abs() < 1e-4 && (plane.c - c).abs() < 1e-4,
        "{plane:?}"
    );
}

#[test]
fn steady_tilt_keeps_the_ground_rings_and_a_tilt_change_moves_them() {
    let steady = stats_of(&[(0.01, 0.02, WALL), (0.01, 0.02, WALL), (0.01, 0.02, WALL)]);
    assert!(steady.ground_ring_displacement_m.median < 1e-4);
    assert!(steady.roll_change_deg.mean < 1e-9 && steady.pitch_change_deg.p95 < 1e-9);

    // 0.1 deg of pitch per frame: the ring at elevation e meets the
    // ground at h / sin(e), moving by about h cos(e) / sin(e)^2 per rad
    let step = 0.1f64.to_radians();
    let moving = stats_of(&[(0.0, 0.0, WALL), (0.0, step, WALL), (0.0, 2.0 * step, WALL)]);
    assert!((moving.pitch_change_deg.mean - 0.1).abs() < 1e-9);
    assert!(moving.roll_change_deg.p95 < 1e-9);
    let d = moving.ground_ring_displacement_m.median;
    // over the near rings (-23.5..-8.1 deg): 0.011..0.10 m per 0.1 deg
    assert!((0.01..0.1).contains(&d), "{d}");
    assert_eq!(moving.ground_pairs_skipped, 0);
}

#[test]
fn a_wall_across_the_track_is_all_along_track_information_and_one_along_none() {
    let across = stats_of(&[(0.0, 0.0, Some(('x', 12.0))), (0.0, 0.0, Some(('x', 12.0)))]);
    assert!(across.information_points > 100);
    assert!(
        across.information_share_pct[0] > 99.0,
        "{:?}",
        across.information_share_pct
    );
    let along = stats_of(&[(0.0, 0.0, Some(('y', 6.0))), (0.0, 0.0, Some(('y', 6.0)))]);
    assert!(
        along.information_share_pct[0] < 1.0,
        "{:?}",
        along.information_share_pct
    );
    assert!(along.information_share_pct[1] > 99.0);
    // the vehicle frame counts: a sensor mounted yawed by 90 deg turns one into the other
    let mut acc = RealismAccumulator::new(RealismConfig::default()).unwrap();
    let yawed = UnitQuaternion::from_euler_angles(0.0, 0.0, PI / 2.0);
    for _ in 0..2 {
        let points = sweep(0.0, 0.0, Some(('y', 6.0)));
        let moved = Vector3::new(acc.sweeps as f64, 0.0, 0.0);
        acc.add_sweep(&points, &UnitQuaternion::identity(), &moved, &yawed)
            .unwrap();
    }
    assert!(acc.finish().unwrap().information_share_pct[0] > 99.0);
}

#[test]
fn histograms_medians_and_counts() {
    let s = stats_of(&[(0.0, 0.0, WALL), (0.0, 0.0, WALL)]);
    let sum: f64 = s.range_histogram.fractions.iter().sum();
    assert!((sum - 1.0).abs() < 1e-12);
    assert!((s.intensity_histogram.fractions[6] - 1.0).abs() < 1e-12); // 0.3 in [0.30, 0.35)
    assert!((s.intensity_median - 0.3).abs() < 1e-3);
    // ground ranges: median over the lower 50 rings
    assert!(s.range_median_m > 3.0 && s.range_median_m < 40.0);
    assert!(s.points_per_sweep_mean > 30_000.0);
    assert_eq!(s.sweeps, 2);
}

#[test]
fn bad_sweeps_are_errors_naming_the_sweep() {
    let mut acc = RealismAccumulator::new(RealismConfig::default()).unwrap();
    let id = UnitQuaternion::identity();
    let origin = Vector3::zeros();
    let err = acc
        .add_sweep(&[], &id, &origin, &id)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("sweep[0]") && err.contains("no points"),
        "{err}"
    );
    let mut points = sweep(0.0, 0.0, None);
    points[7].y = f32::NAN;
    let err = acc
        .add_sweep(&points, &id, &origin, &id)
        .unwrap_err()
        .to_string();
    assert!(err.contains("point 7"), "{err}");
    let nan = Vector3::new(0.0, f64::NAN, 0.0);
    let err = acc
        .add_sweep(&sweep(0.0, 0.0, None), &id, &nan, &id)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("sweep[0]") && err.contains("attitude"),
        "{err}"
    );
    // one sweep is not a sequence, nor are sweeps that never move
    acc.add_sweep(&sweep(0.0, 0.0, None), &id, &origin, &id)
        .unwrap();
    acc.add_sweep(&sweep(0.0, 0.0, None), &id, &origin, &id)
        .unwrap();
    assert!(acc.finish().is_err());
    let bad = RealismConfig {
        ground_tolerance_m: f64::NAN,
        ..RealismConfig::default()
    };
    assert!(RealismAccumulator::new(bad).is_err());
}

#[test]
fn comparison_ratios() {
    let s = stats_of(&[
        (0.0, 0.0, Some(('x', 12.0))),
        (0.0, 0.001, Some(('x', 12.0))),
    ]);
    let same = compare_realism(&s, &s);
    assert!(
        same.iter().all(|c| c.ratio == 1.0 && c.within_factor_2),
        "{same:?}"
    );
    let mut half = s.clone();
    half.points_per_sweep_mean /= 3.0;
    let c = compare_realism(&half, &s);
    let pts = c
        .iter()
        .find(|c| c.statistic.starts_with("points per sweep"))
        .unwrap();
    assert!((pts.ratio - 1.0 / 3.0).abs() < 1e-12 && !pts.within_factor_2);
}

#[test]
fn spread_percentiles_match_numpy() {
    let s = Spread::of(&[1.0, 2.0, 3.0, 4.0, 10.0]).unwrap();
    assert_eq!(s.median, 3.0);
    assert!((s.p95 - 8.8).abs() < 1e-12);
    assert!((s.p5 - 1.2).abs() < 1e-12);
    assert!(Spread::of(&[]).is_none());
}
