//! The ground's ray intersection against a slow, safe reference: on random
//! grounds (plane, undulations, crown, roughness texture) and random rays,
//! the range the ray caster finds, from the tangent plane under the sensor
//! (`cast_ray`) or from a neighbouring ray's range (`cast_ray_next_to`), is
//! the first crossing of the ray with the surface to within
//! `GROUND_RANGE_TOLERANCE_M`; and with a wall across a shallow ray (which
//! meets the objects first and the ground only when it may be nearer), the
//! hit is the nearer of the two.

use limot_sim::scene::{
    Crown, Ground, Roughness, Scene, Shape, StaticKind, StaticObject, Undulation,
};
use limot_sim::sensors::{GROUND_RANGE_TOLERANCE_M, Surface, World};
use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector2, Vector3};
use proptest::prelude::*;
use rand::SeedableRng;

const MAX_RANGE_M: f64 = 120.0;

/// Rays descending more steeply than this (sin of the depression) start
/// from a neighbour's range; shallower ones do not.
const STEEP_DESCENT: f64 = 0.05;

/// Grounds of the scenarios' envelope: a plane up to 2 % steep, up to three
/// undulations of 100-400 m wavelength each at most 2 % steep, a crown up to
/// 0.3 m high and an ISO 8608 texture from class A to C (rougher than any
/// built-in road).
fn ground_spec() -> impl Strategy<Value = Ground> {
    (
        (-1.0..1.0f64, 0.0..0.02f64, -3.2..3.2f64),
        prop::collection::vec(
            (0.0..1.0f64, 100.0..400.0f64, -3.2..3.2f64, -3.2..3.2f64),
            0..4,
        ),
        prop::option::of((0.05..0.3f64, 5.0..10.0f64, -3.2..3.2f64)),
        prop::option::of((0u64..1000, 16e-6..256e-6f64)),
    )
        .prop_map(
            |((base, slope, slope_dir), waves, crown, roughness)| Ground {
                base_height_m: base,
                slope: Vector2::new(slope_dir.cos(), slope_dir.sin()) * slope,
                undulations: waves
                    .into_iter()
                    .map(|(amplitude_m, wavelength_m, dir, phase_rad)| Undulation {
                        amplitude_m: amplitude_m.min(0.02 * wavelength_m / std::f64::consts::TAU),
                        wave_vector: Vector2::new(dir.cos(), dir.sin())
                            * (std::f64::consts::TAU / wavelength_m),
                        phase_rad,
                    })
                    .collect(),
                crown: crown.map(|(height_m, width_m, angle)| Crown {
                    axis_point: Vector2::new(3.0, -2.0),
                    lateral: Vector2::new(angle.cos(), angle.sin()),
                    height_m,
                    width_m,
                }),
                roughness: roughness.map(|(seed, psd)| {
                    Roughness::iso8608(
                        &mut rand_chacha::ChaCha8Rng::seed_from_u64(seed),
                        psd,
                        0.3,
                        20.0,
                    )
                }),
            },
        )
}

/// The first crossing of the ray with the ground within `max_range_m`, by
/// steps that cannot pass one (each the height gap over a bound of the rate
/// at which the gap can shrink), then bisection to 1e-12 m.
fn reference_range(
    ground: &Ground,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    max_range_m: f64,
) -> Option<f64> {
    let gap = |s: f64| {
        let p = origin + dir * s;
        p.z - ground.height(p.x, p.y)
    };
    let terrain_slope_bound = ground.slope.norm()
        + ground
            .undulations
            .iter()
            .map(|u| u.amplitude_m.abs() * u.wave_vector.norm())
            .sum::<f64>();
    let rate_bound =
        dir.z.abs() + (terrain_slope_bound + ground.detail_slope_bound()) * dir.xy().norm();
    let mut s = 0.0;
    let mut f = gap(s);
    assert!(f > 0.0, "the origin is above the ground");
    // safe steps until the gap is below 1e-9 m: the crossing is beyond s
    while f > 1e-9 {
        s += f / rate_bound;
        if s > max_range_m + 1.0 {
            return None;
        }
        f = gap(s);
    }
    // the first point below the surface, a micrometre step at a time
    let mut hi = s;
    while gap(hi) > 0.0 {
        hi += 1e-6;
    }
    let mut lo = s.min(hi - 1e-6).max(0.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if gap(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let s = 0.5 * (lo + hi);
    (s <= max_range_m).then_some(s)
}

/// A scene of `ground` and `statics` alone.
fn scene(ground: &Ground, statics: Vec<StaticObject>) -> Scene {
    Scene {
        duration_s: 1.0,
        ground: ground.clone(),
        statics,
        agents: Vec::new(),
        ego: limot_sim::scene::Ego {
            trajectory: limot_sim::scene::Trajectory::stationary(0.0, 1.0, &Isometry3::identity()),
            size_lwh_m: Vector3::new(4.5, 1.8, 1.5),
            box_center_lidar_m: Vector3::zeros(),
            t_lidar_imu: Isometry3::identity(),
        },
    }
}

fn unit(azimuth: f64, elevation: f64) -> Unit<Vector3<f64>> {
    Unit::new_normalize(Vector3::new(
        elevation.cos() * azimuth.cos(),
        elevation.cos() * azimuth.sin(),
        elevation.sin(),
    ))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn ground_ranges_are_the_first_crossing_from_any_start(
        ground in ground_spec(),
        origin_xy in (-3000.0..3000.0f64, -3000.0..3000.0f64),
        height_m in 1.2..2.5f64,
        azimuth in -3.2..3.2f64,
        // the HDL-64E's beams descend at most 25 degrees
        elevations in prop::collection::vec(-0.44..-0.001f64, 24),
        start_offsets_m in prop::collection::vec(-3.0..3.0f64, 24),
    ) {
        let world = World::new(&scene(&ground, Vec::new()));
        let snap = world.snapshot(0.0);
        let (x, y) = origin_xy;
        let origin = Point3::new(x, y, ground.height(x, y) + height_m);
        for (&elevation, &offset_m) in elevations.iter().zip(&start_offsets_m) {
            let dir = unit(azimuth, elevation);
            let cold = snap.cast_ray(&origin, &dir, MAX_RANGE_M);
            let cold_range = cold.map(|hit| {
                prop_assert_eq!(hit.surface, Surface::Ground);
                Ok(hit.range_m)
            }).transpose()?;
            // the same ray started from a neighbour's range (here: the
            // reference's, moved by up to 3 m) and from none
            let exact = reference_range(&ground, &origin, &dir, MAX_RANGE_M);
            for start_m in [exact.map_or(f64::NAN, |s| s + offset_m), f64::NAN, 1.0] {
                let mut ground_range_m = start_m;
                let warm = snap.cast_ray_next_to(&origin, &dir, MAX_RANGE_M, &[], &mut ground_range_m);
                let warm_range = warm.map(|hit| hit.range_m);
                prop_assert_eq!(warm_range.unwrap_or(f64::NAN).to_bits(), ground_range_m.to_bits());
                if dir.z >= -STEEP_DESCENT {
                    // shallow rays ignore the start
                    prop_assert_eq!(warm_range, cold_range);
                    continue;
                }
                match (exact, warm_range, cold_range) {
                    (Some(e), Some(w), Some(c)) => {
                        prop_assert!(
                            (w - e).abs() <= GROUND_RANGE_TOLERANCE_M
                                && (c - e).abs() <= GROUND_RANGE_TOLERANCE_M,
                            "origin {origin:?}, elevation {elevation}: reference {e}, from {start_m}: {w} ({:e}), cold {c} ({:e})",
                            w - e,
                            c - e
                        );
                    }
                    (None, None, None) => {}
                    // a crossing within a micrometre of the maximum range
                    (Some(e), None, None) => prop_assert!(e > MAX_RANGE_M - 1e-6),
                    (None, Some(w), Some(c)) => prop_assert!(w.min(c) > MAX_RANGE_M - 1e-6),
                    other => prop_assert!(
                        false,
                        "origin {origin:?}, elevation {elevation}: reference, from {start_m}, cold: {other:?}"
                    ),
                }
            }
        }
    }

    #[test]
    fn a_shallow_ray_meets_the_nearer_of_the_ground_and_a_wall(
        ground in ground_spec(),
        origin_xy in (-3000.0..3000.0f64, -3000.0..3000.0f64),
        height_m in 1.2..2.5f64,
        azimuth in -3.2..3.2f64,
        // shallow: descending less steeply than STEEP_DESCENT, or rising
        elevations in prop::collection::vec(-0.05..0.02f64, 8),
        // the wall's distance, as a multiple of the ground crossing's
        wall_factors in prop::collection::vec(0.5..1.5f64, 8),
    ) {
        let (x, y) = origin_xy;
        let origin = Point3::new(x, y, ground.height(x, y) + height_m);
        for (&elevation, &factor) in elevations.iter().zip(&wall_factors) {
            let dir = unit(azimuth, elevation);
            let exact = reference_range(&ground, &origin, &dir, MAX_RANGE_M);
            // a wall across the ray, 1 m thick, far taller and wider than
            // the ray's reach, its front face `horizontal_m` ahead
            let horizontal_m = exact.map_or(80.0, |e| e * dir.xy().norm()) * factor;
            let centre = origin.xy() + Vector2::new(azimuth.cos(), azimuth.sin()) * (horizontal_m + 0.5);
            let wall = StaticObject {
                kind: StaticKind::Wall,
                shape: Shape::Cuboid { half_extents_m: Vector3::new(0.5, 20.0, 60.0) },
                t_world_object: Isometry3::from_parts(
                    Translation3::new(centre.x, centre.y, origin.z),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, azimuth),
                ),
            };
            let wall_range_m = horizontal_m / dir.xy().norm();
            let world = World::new(&scene(&ground, vec![wall]));
            let hit = world.snapshot(0.0).cast_ray(&origin, &dir, MAX_RANGE_M);
            let ground_nearer = exact.is_some_and(|e| e < wall_range_m);
            if exact.is_some_and(|e| (e - wall_range_m).abs() < 1e-6) {
                continue; // a tie to the tolerance: either is right
            }
            match hit {
                Some(hit) if ground_nearer => {
                    let e = exact.unwrap();
                    prop_assert_eq!(hit.surface, Surface::Ground);
                    prop_assert!((hit.range_m - e).abs() <= GROUND_RANGE_TOLERANCE_M, "{} vs {}", hit.range_m, e);
                }
                Some(hit) if wall_range_m <= MAX_RANGE_M => {
                    prop_assert_eq!(hit.surface, Surface::Static(StaticKind::Wall));
                    prop_assert!((hit.range_m - wall_range_m).abs() < 1e-9, "{} vs {}", hit.range_m, wall_range_m);
                }
                None => prop_assert!(wall_range_m > MAX_RANGE_M - 1e-6 && !ground_nearer),
                other => prop_assert!(false, "elevation {}: reference {:?}, wall {}: {:?}", elevation, exact, wall_range_m, other),
            }
        }
    }
}
