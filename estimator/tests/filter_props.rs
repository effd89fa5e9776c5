//! Tests of `limot_estimator::filter`: the box test against an independent
//! brute-force polygon test, a synthetic rolling-shutter sweep with a car
//! crossing at 15 m/s (per-point time vs scan-start time), the stats on hand
//! cases, and a timing print for a full-size sweep.

use limot_estimator::geometry::OrientedBox;
use limot_estimator::object_removal::*;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};
use proptest::prelude::*;
use std::f64::consts::PI;
use std::time::Instant;

use limot_test_support::SplitMix64 as Rng;

/// Brute force: the inflated footprint's four world corners form a convex
/// polygon; the point is inside when it is left of (or on) every edge walked
/// counter-clockwise, and within the inflated height range.
fn brute_force_contains(b: &OrientedBox, p: &Vector3<f64>, inflate_m: f64) -> bool {
    let hl = 0.5 * b.size_lwh.x + inflate_m;
    let hw = 0.5 * b.size_lwh.y + inflate_m;
    let hh = 0.5 * b.size_lwh.z + inflate_m;
    if hl < 0.0 || hw < 0.0 || hh < 0.0 {
        return false;
    }
    let heading = Vector2::new(b.yaw_rad.cos(), b.yaw_rad.sin());
    let left = Vector2::new(-heading.y, heading.x);
    let c = b.center.xy();
    let corners = [
        c + heading * hl + left * hw,
        c - heading * hl + left * hw,
        c - heading * hl - left * hw,
        c + heading * hl - left * hw,
    ];
    let q = p.xy();
    let inside_xy = (0..4).all(|i| {
        let a = corners[i];
        let e = corners[(i + 1) % 4] - a;
        let r = q - a;
        e.x * r.y - e.y * r.x >= -1e-9
    });
    inside_xy && (p.z - b.center.z).abs() <= hh
}

/// Distance from p to the nearest face of the inflated box (to skip points
/// where the two tests may legitimately disagree by round-off).
fn face_distance(b: &OrientedBox, p: &Vector3<f64>, inflate_m: f64) -> f64 {
    let d = p - b.center;
    let (s, c) = b.yaw_rad.sin_cos();
    let x = c * d.x + s * d.y;
    let y = -s * d.x + c * d.y;
    let h = 0.5 * b.size_lwh.add_scalar(2.0 * inflate_m);
    (x.abs() - h.x)
        .abs()
        .min((y.abs() - h.y).abs())
        .min((d.z.abs() - h.z).abs())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn contains_matches_brute_force_polygon(
        cx in -50.0..50.0f64, cy in -50.0..50.0f64, cz in -2.0..2.0f64,
        yaw in -2.0 * PI..2.0 * PI,
        l in 0.3..15.0f64, w in 0.3..4.0f64, h in 0.3..4.0f64,
        inflate in -0.1..0.6f64,
        offsets in prop::collection::vec((-10.0..10.0f64, -10.0..10.0f64, -3.0..3.0f64), 64),
    ) {
        let b = OrientedBox {
            center: Vector3::new(cx, cy, cz),
            yaw_rad: yaw,
            size_lwh: Vector3::new(l, w, h),
        };
        for (dx, dy, dz) in offsets {
            let p = b.center + Vector3::new(dx, dy, dz) * 0.5;
            if face_distance(&b, &p, inflate) < 1e-7 {
                continue;
            }
            let fast = b.contains(&p, inflate);
            prop_assert_eq!(fast, brute_force_contains(&b, &p, inflate), "p {:?}", p);
        }
        // the centre is always inside (the box is never shrunk to nothing here)
        prop_assert!(b.contains(&b.center, inflate));
    }

    /// The mask of LiDAR-frame points under an arbitrary ego pose equals the
    /// brute-force world test when there is a single time (no binning error).
    #[test]
    fn mask_matches_world_test_under_any_pose(
        tx in -20.0..20.0f64, ty in -20.0..20.0f64,
        roll in -0.1..0.1f64, pitch in -0.1..0.1f64, yaw_ego in -PI..PI,
        yaw_box in -PI..PI,
        pts in prop::collection::vec((-12.0..12.0f64, -12.0..12.0f64, -3.0..2.0f64), 128),
    ) {
        let pose = Isometry3::from_parts(
            Translation3::new(tx, ty, 1.7),
            UnitQuaternion::from_euler_angles(roll, pitch, yaw_ego),
        );
        let b = OrientedBox {
            center: (pose * Point3::new(6.0, 2.0, -0.9)).coords,
            yaw_rad: yaw_box,
            size_lwh: Vector3::new(4.5, 1.9, 1.6),
        };
        let points: Vec<Vector3<f64>> = pts.iter().map(|&(x, y, z)| Vector3::new(x, y, z)).collect();
        let times = vec![3.0; points.len()];
        let cfg = FilterConfig { inflate_bottom_m: 0.3, ..FilterConfig::default() };
        let boxes: [&dyn BoxAtTime; 1] = [&b];
        let mask = dynamic_feature_mask(&points, &times, &|_| pose, &boxes, &cfg).unwrap();
        for (p, m) in points.iter().zip(mask) {
            let p_world = (pose * Point3::from(*p)).coords;
            if face_distance(&b, &p_world, cfg.inflate_m) < 1e-7 {
                continue;
            }
            prop_assert_eq!(m, brute_force_contains(&b, &p_world, cfg.inflate_m));
        }
    }
}

// ---------------------------------------------------------------------------
// Synthetic rolling-shutter sweep
// ---------------------------------------------------------------------------

/// Ray parameter where the ray `o + s*d` (world) enters box `b`, if it does.
fn ray_box(b: &OrientedBox, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<f64> {
    let (sy, cy) = b.yaw_rad.sin_cos();
    let to_box = |v: &Vector3<f64>| Vector3::new(cy * v.x + sy * v.y, -sy * v.x + cy * v.y, v.z);
    let ob = to_box(&(o - b.center));
    let db = to_box(d);
    let half = 0.5 * b.size_lwh;
    let (mut s_in, mut s_out) = (0.0f64, f64::INFINITY);
    for k in 0..3 {
        if db[k].abs() < 1e-12 {
            if ob[k].abs() > half[k] {
                return None;
            }
        } else {
            let s1 = (-half[k] - ob[k]) / db[k];
            let s2 = (half[k] - ob[k]) / db[k];
            s_in = s_in.max(s1.min(s2));
            s_out = s_out.min(s1.max(s2));
        }
    }
    (s_in <= s_out && s_in > 0.0).then_some(s_in)
}

#[derive(Clone, Copy, PartialEq)]
enum Hit {
    Ground,
    Wall,
    MovingCar,
    ParkedCar,
}

struct Sweep {
    points_lidar: Vec<Vector3<f64>>,
    times_s: Vec<f64>,
    hits: Vec<Hit>,
}

const SWEEP_S: f64 = 0.1;

/// Ego: 10 m/s forward, yawing at 0.3 rad/s, LiDAR 1.73 m above the ground.
fn ego_pose(t_s: f64) -> Isometry3<f64> {
    let yaw = 0.3 * t_s;
    Isometry3::from_parts(
        Translation3::new(10.0 * t_s, 0.5 * 0.3 * 10.0 * t_s * t_s, 1.73),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
    )
}

/// A car behind-left of the ego crossing at 15 m/s along +y (its heading),
/// seen around mid-sweep; a parked car just beyond its tail.
fn moving_car() -> ConstantVelocityBox {
    ConstantVelocityBox {
        box_ref: OrientedBox {
            center: Vector3::new(-10.0, -4.0, 0.75),
            yaw_rad: PI / 2.0,
            size_lwh: Vector3::new(4.5, 1.8, 1.5),
        },
        t_ref_s: 0.0,
        velocity_world_mps: Vector3::new(0.0, 15.0, 0.0),
        yaw_rate_radps: 0.0,
    }
}

fn parked_car() -> OrientedBox {
    OrientedBox {
        center: Vector3::new(-10.0, -9.3, 0.75),
        yaw_rad: PI / 2.0,
        size_lwh: Vector3::new(4.5, 1.8, 1.5),
    }
}

/// 64 beams from -24.8 to +2 degrees, 2000 columns, 2 cm range noise; each
/// point is measured at its own time and stored in the LiDAR frame of that
/// time.
fn synthetic_sweep() -> Sweep {
    let mut rng = Rng(42);
    let car = moving_car();
    let parked = parked_car();
    let (mut points_lidar, mut times_s, mut hits) = (Vec::new(), Vec::new(), Vec::new());
    let columns = 2000;
    for col in 0..columns {
        let t_s = SWEEP_S * col as f64 / columns as f64;
        let azimuth = 2.0 * PI * col as f64 / columns as f64;
        let pose = ego_pose(t_s);
        let car_now = car.box_at(t_s);
        for ring in 0..64 {
            let elevation = (-24.8 + 26.8 * ring as f64 / 63.0).to_radians();
            let dir_lidar = Vector3::new(
                elevation.cos() * azimuth.cos(),
                elevation.cos() * azimuth.sin(),
                elevation.sin(),
            );
            let o = pose.translation.vector;
            let d = pose.rotation * dir_lidar;
            let mut best: Option<(f64, Hit)> = None;
            let mut consider = |s: Option<f64>, hit: Hit| {
                if let Some(s) = s
                    && s > 0.0
                    && best.is_none_or(|(b, _)| s < b)
                {
                    best = Some((s, hit));
                }
            };
            consider((d.z < 0.0).then(|| -o.z / d.z), Hit::Ground);
            // a 4 m high wall along y at world x = -16
            let s_wall = (d.x.abs() > 1e-12).then(|| (-16.0 - o.x) / d.x);
            consider(s_wall.filter(|&s| (o.z + s * d.z) <= 4.0), Hit::Wall);
            consider(ray_box(&car_now, &o, &d), Hit::MovingCar);
            consider(ray_box(&parked, &o, &d), Hit::ParkedCar);
            if let Some((s, hit)) = best
                && s < 80.0
            {
                let range = s + 0.02 * rng.normal();
                points_lidar.push(dir_lidar * range);
                times_s.push(t_s);
                hits.push(hit);
            }
        }
    }
    Sweep {
        points_lidar,
        times_s,
        hits,
    }
}

/// Box that stays where another box was at `t_frozen_s` (the "scan start
/// time only" baseline).
struct Frozen(OrientedBox);
impl BoxAtTime for Frozen {
    fn box_at(&self, _t_s: f64) -> OrientedBox {
        self.0
    }
}

#[test]
fn per_point_time_removes_the_crossing_car_and_keeps_static_points() {
    let sweep = synthetic_sweep();
    let labels: Vec<bool> = sweep.hits.iter().map(|&h| h == Hit::MovingCar).collect();
    let on_parked = sweep.hits.iter().filter(|&&h| h == Hit::ParkedCar).count();
    let moving = labels.iter().filter(|&&l| l).count();
    assert!(
        moving > 300,
        "the moving car must be well sampled: {moving}"
    );
    assert!(
        on_parked > 100,
        "the parked car must be visible: {on_parked}"
    );
    let cfg = FilterConfig::default();
    let car = moving_car();

    let boxes: [&dyn BoxAtTime; 1] = [&car];
    let mask =
        dynamic_feature_mask(&sweep.points_lidar, &sweep.times_s, &ego_pose, &boxes, &cfg).unwrap();
    let stats = filter_stats(&mask, &labels).unwrap();
    let parked_removed = mask
        .iter()
        .zip(&sweep.hits)
        .filter(|&(&m, &h)| m && h == Hit::ParkedCar)
        .count();
    let ground_removed = mask
        .iter()
        .zip(&sweep.hits)
        .filter(|&(&m, &h)| m && h == Hit::Ground)
        .count();
    println!(
        "per-point time: {} points, {} on the moving car, {} on the parked car; removed {} \
         precision {:.4} recall {:.4} (parked removed {}, ground removed {})",
        stats.total,
        moving,
        on_parked,
        stats.removed,
        stats.precision,
        stats.recall,
        parked_removed,
        ground_removed
    );
    assert!(stats.recall >= 0.995, "recall {}", stats.recall);
    assert!(stats.precision >= 0.95, "precision {}", stats.precision);
    assert_eq!(parked_removed, 0);

    // Baseline: the box at the scan start time only (ego motion still exact).
    let frozen = Frozen(car.box_at(0.0));
    let boxes: [&dyn BoxAtTime; 1] = [&frozen];
    let mask0 =
        dynamic_feature_mask(&sweep.points_lidar, &sweep.times_s, &ego_pose, &boxes, &cfg).unwrap();
    let stats0 = filter_stats(&mask0, &labels).unwrap();
    let missed = 1.0 - stats0.recall;
    println!(
        "scan-start time only: removed {} precision {:.4} recall {:.4} -> misses {:.1}% of the \
         moving car's points",
        stats0.removed,
        stats0.precision,
        stats0.recall,
        100.0 * missed
    );
    assert!(missed > 0.1, "stale box should miss >10%: {missed}");

    // Same sweep de-skewed to the scan start: constant pose, same mask.
    let t_world_lidar0 = ego_pose(0.0);
    let deskewed: Vec<Vector3<f64>> = sweep
        .points_lidar
        .iter()
        .zip(&sweep.times_s)
        .map(|(p, &t)| {
            let p_world = ego_pose(t) * Point3::from(*p);
            t_world_lidar0.inverse_transform_point(&p_world).coords
        })
        .collect();
    let boxes: [&dyn BoxAtTime; 1] = [&car];
    let mask_deskewed =
        dynamic_feature_mask(&deskewed, &sweep.times_s, &|_| t_world_lidar0, &boxes, &cfg).unwrap();
    let differing = mask
        .iter()
        .zip(&mask_deskewed)
        .filter(|(a, b)| a != b)
        .count();
    println!(
        "raw vs de-skewed input: {differing} of {} decisions differ",
        mask.len()
    );
    // only points within the per-bin ego-motion error (<= 5 cm) of a face can differ
    assert!(differing <= moving / 50, "{differing}");

    // allfilt drops the parked car too
    let all = all_boxes_mask(
        &sweep.points_lidar,
        &sweep.times_s,
        &ego_pose,
        &[car.box_at(0.05), parked_car()],
        &cfg,
    )
    .unwrap();
    let parked_removed_all = all
        .iter()
        .zip(&sweep.hits)
        .filter(|&(&m, &h)| m && h == Hit::ParkedCar)
        .count();
    println!("allfilt: parked-car points removed {parked_removed_all} of {on_parked}");
    assert_eq!(parked_removed_all, on_parked);
}

#[test]
fn filter_stats_hand_cases() {
    // nothing removed, nothing moving: vacuous precision and recall
    let s = filter_stats(&[false; 4], &[false; 4]).unwrap();
    assert_eq!(
        (s.removed, s.moving, s.precision, s.recall),
        (0, 0, 1.0, 1.0)
    );
    // everything removed, half moving
    let s = filter_stats(&[true; 4], &[true, false, true, false]).unwrap();
    assert_eq!((s.precision, s.recall), (0.5, 1.0));
    assert_eq!((s.false_positive, s.false_negative), (2, 0));
    // all moving points kept
    let s = filter_stats(&[false, true], &[true, false]).unwrap();
    assert_eq!((s.precision, s.recall, s.true_positive), (0.0, 0.0, 0));
    let err = filter_stats(&[true], &[true, false]).unwrap_err();
    assert!(err.to_string().contains("mask has 1"), "{err}");
}

/// Timing print (not asserted): 120k points, 30 moving boxes, 10 bins; once
/// as a rolling sweep (azimuth follows time, as from a spinning LiDAR) and
/// once with random azimuths (the worst case for the per-bin culling).
#[test]
fn timing_120k_points_30_boxes() {
    let mut rng = Rng(7);
    let n = 120_000;
    let times: Vec<f64> = (0..n).map(|i| SWEEP_S * i as f64 / n as f64).collect();
    let mut point_at = |azimuth: f64| {
        let r = 2.0 + 60.0 * rng.uniform();
        Vector3::new(
            r * azimuth.cos(),
            r * azimuth.sin(),
            -1.73 + 3.0 * rng.uniform(),
        )
    };
    let rolling: Vec<Vector3<f64>> = (0..n)
        .map(|i| point_at(2.0 * PI * i as f64 / n as f64))
        .collect();
    let mut rng2 = Rng(8);
    let random: Vec<Vector3<f64>> = (0..n)
        .map(|_| point_at(2.0 * PI * rng2.uniform()))
        .collect();
    let cars: Vec<ConstantVelocityBox> = (0..30)
        .map(|i| {
            let a = 2.0 * PI * i as f64 / 30.0;
            let r = 8.0 + 1.5 * i as f64;
            ConstantVelocityBox {
                box_ref: OrientedBox {
                    center: Vector3::new(r * a.cos(), r * a.sin(), 0.75),
                    yaw_rad: a,
                    size_lwh: Vector3::new(4.5, 1.8, 1.5),
                },
                t_ref_s: 0.0,
                velocity_world_mps: Vector3::new(15.0 * a.cos(), 15.0 * a.sin(), 0.0),
                yaw_rate_radps: 0.0,
            }
        })
        .collect();
    let boxes: Vec<&dyn BoxAtTime> = cars.iter().map(|c| c as &dyn BoxAtTime).collect();
    let cfg = FilterConfig::default();
    for (name, points) in [("rolling sweep", &rolling), ("random azimuth", &random)] {
        let mut best_ms = f64::INFINITY;
        let mut removed = 0;
        for _ in 0..5 {
            let start = Instant::now();
            let mask = dynamic_feature_mask(points, &times, &ego_pose, &boxes, &cfg).unwrap();
            best_ms = best_ms.min(start.elapsed().as_secs_f64() * 1e3);
            removed = mask.iter().filter(|&&m| m).count();
        }
        println!(
            "timing ({name}): {n} points x {} boxes: best of 5 {best_ms:.2} ms ({removed} removed)",
            boxes.len()
        );
        assert!(removed > 0);
    }
}

/// Sensitivity of the synthetic sweep's precision/recall to the inflation,
/// the number of time bins and a box error like the detector's (centre
/// 0.15 m off along and across the car, 0.03 rad yaw). The default config must
/// meet the filter targets (recall >= 0.9, precision >= 0.8) with that error.
#[test]
fn sensitivity_to_inflation_bins_and_box_error() {
    let sweep = synthetic_sweep();
    let labels: Vec<bool> = sweep.hits.iter().map(|&h| h == Hit::MovingCar).collect();
    let exact = moving_car();
    let mut noisy = exact;
    noisy.box_ref.center += Vector3::new(0.15, -0.15, 0.05);
    noisy.box_ref.yaw_rad += 0.03;
    let parked_removed = |mask: &[bool]| {
        mask.iter()
            .zip(&sweep.hits)
            .filter(|&(&m, &h)| m && h == Hit::ParkedCar)
            .count()
    };
    println!("box    inflate bottom bins  precision recall  parked-removed");
    for (box_name, car) in [("exact", &exact), ("noisy", &noisy)] {
        for inflate_m in [0.0, 0.15, 0.3, 0.5] {
            for (inflate_bottom_m, time_bins) in [(0.0, 10), (0.0, 1), (-0.05, 10)] {
                let cfg = FilterConfig {
                    inflate_m,
                    inflate_bottom_m,
                    time_bins,
                    ..FilterConfig::default()
                };
                let boxes: [&dyn BoxAtTime; 1] = [car];
                let mask = dynamic_feature_mask(
                    &sweep.points_lidar,
                    &sweep.times_s,
                    &ego_pose,
                    &boxes,
                    &cfg,
                )
                .unwrap();
                let s = filter_stats(&mask, &labels).unwrap();
                println!(
                    "{box_name}  {inflate_m:5.2}  {inflate_bottom_m:5.2}  {time_bins:4}  \
                     {:9.4} {:7.4}  {}",
                    s.precision,
                    s.recall,
                    parked_removed(&mask)
                );
                if cfg == FilterConfig::default() {
                    assert!(s.recall >= 0.9, "{box_name}: recall {}", s.recall);
                    assert!(s.precision >= 0.8, "{box_name}: precision {}", s.precision);
                    assert_eq!(parked_removed(&mask), 0, "{box_name}");
                }
            }
        }
    }
}
