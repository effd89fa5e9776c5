//! Properties of the rolling LiDAR simulator: points lie on the surfaces
//! they are labelled with (at their own firing time), sweeps are
//! deterministic whatever the thread count, and ego motion distorts the
//! sweep by exactly the distance driven.

use limot_estimator::input::{LidarScan, ObjectClass};
use limot_sim::scene::{
    Agent, Ego, Ground, STATIC_INSTANCE_ID, Scene, Shape, StaticKind, StaticObject, Undulation,
};
use limot_sim::scene::{Jet, Knot, Trajectory};
use limot_sim::sensors::LidarConfig;
use limot_sim::sensors::World;
use limot_sim::sensors::hdl64::NUM_LASERS;
use limot_sim::sensors::{GROUND_RANGE_TOLERANCE_M, Surface};
use limot_sim::sensors::{LidarSimulator, SimulatedScan};
use nalgebra::{Isometry3, Point3, Vector2, Vector3};
use proptest::prelude::*;
use std::collections::HashMap;

/// Constant velocity along `heading` (with constant yaw rate, pitch and roll).
fn moving(
    start: Vector3<f64>,
    heading: f64,
    speed_mps: f64,
    yaw_rate_radps: f64,
    pitch_roll: (f64, f64),
) -> Trajectory {
    let dt = 0.1;
    let (s, c) = heading.sin_cos();
    let knots = (0..12)
        .map(|i| {
            let t = i as f64 * dt;
            Knot {
                position: [
                    Jet::new(start.x + c * speed_mps * t, c * speed_mps, 0.0),
                    Jet::new(start.y + s * speed_mps * t, s * speed_mps, 0.0),
                    Jet::new(start.z, 0.0, 0.0),
                ],
                euler: [
                    Jet::new(heading + yaw_rate_radps * t, yaw_rate_radps, 0.0),
                    Jet::new(pitch_roll.0, 0.0, 0.0),
                    Jet::new(pitch_roll.1, 0.0, 0.0),
                ],
            }
        })
        .collect();
    Trajectory::new(0.0, dt, knots)
}

fn ego(trajectory: Trajectory) -> Ego {
    Ego {
        trajectory,
        size_lwh_m: Vector3::new(4.5, 1.8, 1.5),
        box_center_lidar_m: Vector3::new(0.0, 0.0, -0.98),
        t_lidar_imu: Isometry3::identity(),
    }
}

fn exact_config(azimuth_steps: usize) -> LidarConfig {
    LidarConfig {
        azimuth_steps,
        range_noise_sigma_m: 0.0,
        dropout_probability: 0.0,
        ..LidarConfig::default()
    }
}

/// Points in the world frame, each through the ego pose at its own time.
fn world_points(scene: &Scene, scan: &LidarScan) -> Vec<(Point3<f64>, f64)> {
    scan.points
        .iter()
        .map(|p| {
            let t_s = scan.t_s + p.time_offset_s as f64;
            let t_world_lidar = scene.ego.trajectory.pose_at(t_s);
            (t_world_lidar * Point3::from(p.position()), t_s)
        })
        .collect()
}

fn scan_bytes(sweep: &SimulatedScan) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(&sweep.scan.t_s.to_le_bytes());
    for (p, label) in sweep.scan.points.iter().zip(&sweep.labels) {
        for v in [p.x, p.y, p.z, p.intensity, p.time_offset_s] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&p.ring.to_le_bytes());
        out.extend_from_slice(&label.to_le_bytes());
    }
    out
}

#[derive(Debug, Clone)]
struct BoxSpec {
    x: f64,
    y: f64,
    yaw: f64,
    size: (f64, f64, f64),
    speed_mps: f64,
    heading: f64,
}

fn box_spec() -> impl Strategy<Value = BoxSpec> {
    (
        -40.0..40.0f64,
        -40.0..40.0f64,
        -3.2..3.2f64,
        (1.0..6.0f64, 0.8..2.5f64, 1.0..3.0f64),
        0.0..15.0f64,
        -3.2..3.2f64,
    )
        .prop_map(|(x, y, yaw, size, speed_mps, heading)| BoxSpec {
            x,
            y,
            yaw,
            size,
            speed_mps,
            heading,
        })
}

fn ground_spec() -> impl Strategy<Value = Ground> {
    (
        -1.0..1.0f64,
        (-0.02..0.02f64, -0.02..0.02f64),
        0.0..0.5f64,
        (-0.1..0.1f64, -0.1..0.1f64),
    )
        .prop_map(|(base, slope, amplitude, k)| Ground {
            base_height_m: base,
            slope: Vector2::new(slope.0, slope.1),
            undulations: vec![Undulation {
                amplitude_m: amplitude,
                wave_vector: Vector2::new(k.0, k.1),
                phase_rad: 0.4,
            }],
            ..Ground::flat(0.0)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(8))]

    #[test]
    fn points_lie_on_the_surfaces_they_claim(
        ground in ground_spec(),
        boxes in prop::collection::vec(box_spec(), 1..6),
        ego_yaw in -3.2..3.2f64,
        ego_speed in 0.0..20.0f64,
        ego_yaw_rate in -0.5..0.5f64,
        pitch_roll in (-0.03..0.03f64, -0.03..0.03f64),
    ) {
        // The ego must not drive through an agent (a box over the LiDAR hides
        // the whole sweep), so boxes that come near its path are left out.
        let (ego_sin, ego_cos) = ego_yaw.sin_cos();
        let clear_of_ego = |b: &BoxSpec| {
            let half_diagonal_m = 0.5 * b.size.0.hypot(b.size.1);
            (0..=10).all(|i| {
                let t = 0.25 + 0.02 * i as f64;
                let ego_xy = Vector2::new(ego_cos, ego_sin) * ego_speed * t;
                let box_xy = Vector2::new(b.x, b.y)
                    + Vector2::new(b.heading.cos(), b.heading.sin()) * b.speed_mps * t;
                (box_xy - ego_xy).norm() > half_diagonal_m + 4.0
            })
        };
        let mut agents: Vec<Agent> = boxes
            .iter()
            .filter(|b| clear_of_ego(b))
            .enumerate()
            .map(|(i, b)| {
                let size = Vector3::new(b.size.0, b.size.1, b.size.2);
                let along_heading = moving(
                    Vector3::new(b.x, b.y, ground.height(b.x, b.y) + size.z / 2.0),
                    b.heading,
                    b.speed_mps,
                    0.0,
                    (0.0, 0.0),
                );
                // boxes face their own yaw, not their direction of travel
                let knots = along_heading
                    .knots()
                    .map(|mut k| {
                        k.euler[0].value = b.yaw;
                        k
                    })
                    .collect();
                let trajectory = Trajectory::new(along_heading.t0_s, along_heading.dt_s, knots);
                Agent {
                    id: i as u32 + 1,
                    class: ObjectClass::Car,
                    size_lwh_m: size,
                    parked: b.speed_mps == 0.0,
                    trajectory,
                    presence: limot_sim::scene::Presence::ALWAYS,
                    labelled: limot_sim::scene::Labelling::Seen,
                }
            })
            .collect();
        // One agent that is surely seen: it overtakes the ego 6 m to its left,
        // 12 m/s faster (parallel to the ego's initial heading, so the two
        // never meet whatever the ego's speed).
        let near_id = agents.len() as u32 + 1;
        let near_start_xy = Vector2::new(-3.0 * ego_cos - 6.0 * ego_sin, -3.0 * ego_sin + 6.0 * ego_cos);
        agents.push(Agent {
            id: near_id,
            class: ObjectClass::Car,
            size_lwh_m: Vector3::new(4.5, 1.8, 1.5),
            parked: false,
            trajectory: moving(
                Vector3::new(
                    near_start_xy.x,
                    near_start_xy.y,
                    ground.height(near_start_xy.x, near_start_xy.y) + 0.75,
                ),
                ego_yaw,
                ego_speed + 12.0,
                0.0,
                (0.0, 0.0),
            ),
            presence: limot_sim::scene::Presence::ALWAYS,
            labelled: limot_sim::scene::Labelling::Seen,
        });
        let statics = vec![StaticObject {
            kind: StaticKind::Pole,
            shape: Shape::Cylinder { radius_m: 0.2, half_height_m: 4.0 },
            t_world_object: Isometry3::translation(-8.0, -5.0, ground.height(-8.0, -5.0) + 3.0),
        }];
        let scene = Scene {
            duration_s: 1.0,
            ground: ground.clone(),
            statics: statics.clone(),
            agents: agents.clone(),
            ego: ego(moving(
                Vector3::new(0.0, 0.0, ground.height(0.0, 0.0) + 1.73),
                ego_yaw,
                ego_speed,
                ego_yaw_rate,
                pitch_roll,
            )),
        };
        let world = World::new(&scene);
        let config = exact_config(500);
        let lidar = LidarSimulator::new(config.clone(), 3).unwrap();
        let t_start = 0.3;
        let sweep = lidar.scan(&scene, &world, 3, t_start);
        prop_assert_eq!(sweep.labels.len(), sweep.scan.points.len());
        prop_assert!(sweep.scan.points.len() > 500 * NUM_LASERS / 4);
        let mut near_points = 0;
        for ((p_world, t_s), (point, &label)) in world_points(&scene, &sweep.scan)
            .into_iter()
            .zip(sweep.scan.points.iter().zip(&sweep.labels))
        {
            let range = point.position().norm();
            prop_assert!(range >= config.min_range_m - 1e-4 && range <= config.max_range_m + 1e-4);
            prop_assert!((point.ring as usize) < NUM_LASERS);
            prop_assert!((0.0..0.1).contains(&(point.time_offset_s as f64)));
            prop_assert!((0.0..=1.0).contains(&point.intensity));
            if label == STATIC_INSTANCE_ID {
                let on_ground = (p_world.z - ground.height(p_world.x, p_world.y)).abs() < 1e-4;
                let on_pole = {
                    let local = statics[0].t_world_object.inverse_transform_point(&p_world);
                    local.xy().coords.norm() < 0.2 + 1e-4 && local.z.abs() < 4.0 + 1e-4
                };
                prop_assert!(on_ground || on_pole, "static point {} off every surface", p_world);
            } else {
                let agent = &agents[label as usize - 1];
                prop_assert!(
                    agent.box_at(t_s).contains(&p_world, 0.01),
                    "point {} labelled {} is off its box at t={}", p_world, label, t_s
                );
                if label == near_id {
                    near_points += 1;
                }
            }
        }
        prop_assert!(near_points > 50, "{near_points}");
    }
}

fn busy_scene() -> Scene {
    let ground = Ground {
        base_height_m: 0.0,
        slope: Vector2::new(0.01, 0.0),
        undulations: vec![Undulation {
            amplitude_m: 0.2,
            wave_vector: Vector2::new(0.05, 0.0),
            phase_rad: 0.0,
        }],
        ..Ground::flat(0.0)
    };
    let agents = (0..6)
        .map(|i| Agent {
            id: i + 1,
            class: ObjectClass::Car,
            size_lwh_m: Vector3::new(4.5, 1.8, 1.5),
            parked: false,
            trajectory: moving(
                Vector3::new(
                    -20.0 + 8.0 * i as f64,
                    if i % 2 == 0 { 4.0 } else { -4.0 },
                    0.75,
                ),
                0.0,
                5.0 + i as f64,
                0.0,
                (0.0, 0.0),
            ),
            presence: limot_sim::scene::Presence::ALWAYS,
            labelled: limot_sim::scene::Labelling::Seen,
        })
        .collect();
    Scene {
        duration_s: 1.0,
        ground,
        statics: vec![StaticObject {
            kind: StaticKind::Building,
            shape: Shape::Cuboid {
                half_extents_m: Vector3::new(10.0, 3.0, 5.0),
            },
            t_world_object: Isometry3::translation(5.0, 15.0, 5.0),
        }],
        agents,
        ego: ego(moving(
            Vector3::new(0.0, 0.0, 1.73),
            0.2,
            15.0,
            0.1,
            (0.0, 0.0),
        )),
    }
}

#[test]
fn scans_are_byte_identical_across_runs_and_thread_counts() -> Result<(), Box<dyn std::error::Error>>
{
    let scene = busy_scene();
    let world = World::new(&scene);
    // noise and dropouts on: the random streams must not depend on scheduling
    let lidar = LidarSimulator::new(LidarConfig::default(), 11)?;
    let run = |threads: usize| -> Result<Vec<u8>, rayon::ThreadPoolBuildError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()?;
        Ok(pool.install(|| scan_bytes(&lidar.scan(&scene, &world, 4, 0.4))))
    };
    let one = run(1)?;
    assert_eq!(one, run(1)?);
    assert_eq!(one, run(2)?);
    assert_eq!(one, run(3)?);
    // another frame index draws other noise
    let other = scan_bytes(&lidar.scan(&scene, &world, 5, 0.4));
    assert_ne!(one, other);
    Ok(())
}

#[test]
fn noise_and_dropouts_have_the_configured_statistics() {
    let scene = busy_scene();
    let world = World::new(&scene);
    let exact = LidarSimulator::new(exact_config(2000), 1).unwrap();
    let noisy_cfg = LidarConfig {
        range_noise_sigma_m: 0.02,
        dropout_probability: 0.1,
        ..exact_config(2000)
    };
    let noisy = LidarSimulator::new(noisy_cfg, 1).unwrap();
    let a = exact.scan(&scene, &world, 0, 0.0);
    let b = noisy.scan(&scene, &world, 0, 0.0);
    let key = |p: &limot_estimator::input::LidarPoint| (p.time_offset_s.to_bits(), p.ring);
    let exact_range: HashMap<_, f64> = a
        .scan
        .points
        .iter()
        .map(|p| (key(p), p.position().norm()))
        .collect();
    let kept = b.scan.points.len() as f64 / a.scan.points.len() as f64;
    assert!((kept - 0.9).abs() < 0.01, "kept {kept}");
    let errors: Vec<f64> = b
        .scan
        .points
        .iter()
        .filter_map(|p| exact_range.get(&key(p)).map(|r| p.position().norm() - r))
        .collect();
    let n = errors.len() as f64;
    let mean = errors.iter().sum::<f64>() / n;
    let sigma = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
    assert!(mean.abs() < 5e-4, "mean {mean}");
    assert!((sigma - 0.02).abs() < 1e-3, "sigma {sigma}");
}

/// Ego driving at 20 m/s between two walls perpendicular to its path: a
/// column fired at tau sees the walls 20 m/s * tau closer (front) or
/// farther (rear) than a static ego would, up to 2 m at the end of the
/// sweep, while the flat ground looks the same.
#[test]
fn ego_motion_distorts_the_sweep_by_the_distance_driven() {
    let speed_mps = 20.0;
    let wall = |x: f64| StaticObject {
        kind: StaticKind::Wall,
        shape: Shape::Cuboid {
            half_extents_m: Vector3::new(0.5, 60.0, 10.0),
        },
        t_world_object: Isometry3::translation(x, 0.0, 5.0),
    };
    let scene_for = |speed: f64| Scene {
        duration_s: 1.0,
        ground: Ground::flat(0.0),
        statics: vec![wall(30.0), wall(-30.0)],
        agents: Vec::new(),
        ego: ego(moving(
            Vector3::new(0.0, 0.0, 1.73),
            0.0,
            speed,
            0.0,
            (0.0, 0.0),
        )),
    };
    let lidar = LidarSimulator::new(exact_config(2000), 0).unwrap();
    let sweep = |scene: &Scene| {
        let world = World::new(scene);
        lidar.scan(scene, &world, 0, 0.0)
    };
    let (moving_scene, static_scene) = (scene_for(speed_mps), scene_for(0.0));
    let (moving_sweep, static_sweep) = (sweep(&moving_scene), sweep(&static_scene));
    let static_points: HashMap<_, _> = static_sweep
        .scan
        .points
        .iter()
        .map(|p| ((p.time_offset_s.to_bits(), p.ring), *p))
        .collect();
    let (mut wall_pairs, mut ground_pairs) = (0, 0);
    let mut max_shift: f64 = 0.0;
    for p in &moving_sweep.scan.points {
        let Some(q) = static_points.get(&(p.time_offset_s.to_bits(), p.ring)) else {
            continue;
        };
        let tau = p.time_offset_s as f64;
        let (pm, ps) = (p.position(), q.position());
        if (ps.z + 1.73).abs() < 1e-4 && (pm.z + 1.73).abs() < 1e-4 {
            // ground point: flat ground is invariant under the ego's motion
            assert!((pm - ps).norm() < 1e-3, "tau {tau} {pm} {ps}");
            ground_pairs += 1;
        } else if ps.x.abs() > 27.0 && pm.x.abs() > 27.0 && ps.z > -1.72 && pm.z > -1.72 {
            // wall point: x in the LiDAR frame shifts by the distance driven
            let expected = -speed_mps * tau;
            assert!(
                (pm.x - ps.x - expected).abs() < 1e-3,
                "tau {tau}: {} vs {}",
                pm.x - ps.x,
                expected
            );
            max_shift = max_shift.max((pm.x - ps.x).abs());
            wall_pairs += 1;
        }
    }
    assert!(wall_pairs > 10_000 && ground_pairs > 10_000);
    // the rear wall is seen at both ends of the sweep: ~2 m of distortion
    assert!(max_shift > 1.95 && max_shift <= 2.0, "{max_shift}");
}

/// The simulator also culls the statics per column and beam and tests the
/// rest directly; on the built-in streets (every static shape, a rough
/// crowned road, a moving and turning ego) the points are those of casting
/// every beam through the statics' BVH: the same surfaces, exactly the same
/// points off the ground, and ground points within the ground's range
/// tolerance (the sweep starts each beam's ground search at the range of the
/// column before) and one f32 rounding.
#[test]
fn culled_statics_give_the_points_of_the_bvh() {
    for (name, t_start) in [("urban", 6.3), ("highway", 4.1)] {
        let mut spec = limot_sim::ScenarioSpec::builtin(name).unwrap();
        spec.duration_s = 8.0;
        let scene = spec.build().unwrap();
        let world = World::new(&scene);
        let config = exact_config(500);
        let lidar = LidarSimulator::new(config.clone(), 0).unwrap();
        let sweep = lidar.scan(&scene, &world, 0, t_start);
        let table = limot_sim::sensors::hdl64::elevation_table_rad();
        let mut reference = Vec::new();
        for column in 0..config.azimuth_steps {
            let tau = lidar.column_time_offset_s(column);
            let (sin_az, cos_az) = config.azimuth_at(tau).sin_cos();
            let pose = scene.ego.trajectory.pose_at(t_start + tau);
            let origin = Point3::from(pose.translation.vector);
            let snapshot = world.snapshot(t_start + tau);
            for (beam, el) in table.iter().enumerate() {
                let (cos_el, sin_el) = (el.cos(), el.sin());
                let dir_lidar = Vector3::new(cos_el * cos_az, cos_el * sin_az, sin_el);
                let dir_world = nalgebra::Unit::new_unchecked(pose.rotation * dir_lidar);
                if let Some(hit) = snapshot.cast_ray(&origin, &dir_world, config.max_range_m)
                    && hit.range_m >= config.min_range_m
                {
                    let p = dir_lidar * hit.range_m;
                    let ring = limot_sim::sensors::hdl64::ring_of_beam(beam);
                    let ground = hit.surface == Surface::Ground;
                    let point = [p.x as f32, p.y as f32, p.z as f32];
                    reference.push((point, ring, hit.instance_id, ground));
                }
            }
        }
        assert_eq!(reference.len(), sweep.scan.points.len(), "{name}");
        let mut static_points = 0;
        for ((p, ring, id, ground), (q, label)) in reference
            .iter()
            .zip(sweep.scan.points.iter().zip(&sweep.labels))
        {
            assert_eq!((*ring, *id), (q.ring, *label), "{name}");
            if *ground {
                for (a, b) in p.iter().zip([q.x, q.y, q.z]) {
                    let bound = 2.0 * GROUND_RANGE_TOLERANCE_M as f32 + f32::EPSILON * a.abs();
                    assert!((a - b).abs() <= bound, "{name}: {p:?} vs {q:?}");
                }
            } else {
                assert_eq!(*p, [q.x, q.y, q.z], "{name}");
            }
            static_points += usize::from(*id == STATIC_INSTANCE_ID && q.z > -1.0);
        }
        assert!(
            static_points > 2000,
            "{name}: {static_points} points above the road"
        );
    }
}

/// The simulator culls agents per column; a brute-force sweep that casts
/// every beam against the full snapshot must give the same points.
#[test]
fn culled_sweep_matches_a_brute_force_reference() {
    let scene = busy_scene();
    let world = World::new(&scene);
    let config = exact_config(720);
    let lidar = LidarSimulator::new(config.clone(), 0).unwrap();
    let t_start = 0.25;
    let sweep = lidar.scan(&scene, &world, 0, t_start);
    let table = limot_sim::sensors::hdl64::elevation_table_rad();
    let mut reference = Vec::new();
    for column in 0..config.azimuth_steps {
        let tau = lidar.column_time_offset_s(column);
        let az = config.azimuth_at(tau);
        let pose = scene.ego.trajectory.pose_at(t_start + tau);
        let snapshot = world.snapshot(t_start + tau);
        for (beam, el) in table.iter().enumerate() {
            let dir_lidar = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
            let dir_world = nalgebra::Unit::new_normalize(pose.rotation * dir_lidar);
            let origin = Point3::from(pose.translation.vector);
            if let Some(hit) = snapshot.cast_ray(&origin, &dir_world, config.max_range_m)
                && hit.range_m >= config.min_range_m
            {
                reference.push((
                    limot_sim::sensors::hdl64::ring_of_beam(beam),
                    tau as f32,
                    dir_lidar * hit.range_m,
                    hit.instance_id,
                ));
            }
        }
    }
    assert_eq!(reference.len(), sweep.scan.points.len());
    let mut agent_points = 0;
    for ((ring, tau, p, id), (q, label)) in reference
        .iter()
        .zip(sweep.scan.points.iter().zip(&sweep.labels))
    {
        assert_eq!((*ring, *tau, *id), (q.ring, q.time_offset_s, *label));
        assert!((p - q.position()).norm() < 1e-5);
        agent_points += usize::from(*id != STATIC_INSTANCE_ID);
    }
    assert!(agent_points > 1000, "{agent_points}");
}

/// A sweep scanned into the buffers of another is the sweep scanned afresh.
#[test]
fn scanning_into_used_buffers_gives_the_fresh_sweep() {
    let scene = busy_scene();
    let world = World::new(&scene);
    let lidar = LidarSimulator::new(LidarConfig::default(), 3).unwrap();
    let mut reused = lidar.scan(&scene, &world, 1, 0.1);
    for (frame, t_s) in [(4, 0.4), (0, 0.0), (7, 0.7)] {
        lidar.scan_into(&scene, &world, frame, t_s, &mut reused);
        assert_eq!(reused, lidar.scan(&scene, &world, frame, t_s));
    }
}
