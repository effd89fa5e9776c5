//! Rolling-LiDAR throughput: rays/s and scans/s with 1 and 2 rayon threads on
//! a scene with an undulating ground, 50 static boxes (plus poles and trees)
//! and 30 moving agents, and on the built-in urban and highway worlds. A plain timing main:
//! `cargo bench -p limot-sim --bench lidar`.

use limot_estimator::input::ObjectClass;
use limot_sim::scene::{
    Agent, Ego, Ground, STATIC_INSTANCE_ID, Scene, Shape, StaticKind, StaticObject, Undulation,
};
use limot_sim::scene::{Jet, Knot, Trajectory};
use limot_sim::sensors::LidarConfig;
use limot_sim::sensors::LidarSimulator;
use limot_sim::sensors::World;
use limot_sim::sensors::hdl64::NUM_LASERS;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector2, Vector3};
use std::time::Instant;

/// Straight-line motion along `heading` at `speed_mps`, over [0, duration_s].
fn straight(start: Vector3<f64>, heading: f64, speed_mps: f64, duration_s: f64) -> Trajectory {
    let dt = 0.1;
    let n = (duration_s / dt).ceil() as usize + 1;
    let (s, c) = heading.sin_cos();
    let knots = (0..n)
        .map(|i| {
            let t = i as f64 * dt;
            Knot {
                position: [
                    Jet::new(start.x + c * speed_mps * t, c * speed_mps, 0.0),
                    Jet::new(start.y + s * speed_mps * t, s * speed_mps, 0.0),
                    Jet::new(start.z, 0.0, 0.0),
                ],
                euler: [Jet::new(heading, 0.0, 0.0), Jet::default(), Jet::default()],
            }
        })
        .collect();
    Trajectory::new(0.0, dt, knots)
}

fn bench_scene() -> Scene {
    let duration_s = 20.0;
    let ground = Ground {
        base_height_m: 0.0,
        slope: Vector2::new(0.002, 0.0),
        undulations: vec![Undulation {
            amplitude_m: 0.3,
            wave_vector: Vector2::new(0.03, 0.01),
            phase_rad: 0.2,
        }],
        ..Ground::flat(0.0)
    };
    // a street: building boxes on both sides, poles and trees between
    let mut statics = Vec::new();
    for i in 0..25 {
        for side in [-1.0, 1.0] {
            let x = -100.0 + i as f64 * 9.0;
            statics.push(StaticObject {
                kind: StaticKind::Building,
                shape: Shape::Cuboid {
                    half_extents_m: Vector3::new(4.0, 5.0, 6.0 + (i % 3) as f64),
                },
                t_world_object: Isometry3::from_parts(
                    Translation3::new(x, side * 20.0, 6.0),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, 0.05 * side),
                ),
            });
        }
    }
    for i in 0..20 {
        let x = -95.0 + i as f64 * 10.0;
        statics.push(StaticObject {
            kind: StaticKind::Pole,
            shape: Shape::Cylinder {
                radius_m: 0.15,
                half_height_m: 3.0,
            },
            t_world_object: Isometry3::translation(x, -11.0, 3.0),
        });
        statics.push(StaticObject {
            kind: StaticKind::TreeCrown,
            shape: Shape::Ball { radius_m: 2.0 },
            t_world_object: Isometry3::translation(x + 5.0, 12.0, 4.5),
        });
    }
    let agents = (0..30)
        .map(|i| {
            let lane = [-7.0, -3.5, 3.5, 7.0][i % 4];
            let heading = if lane < 0.0 {
                0.0
            } else {
                std::f64::consts::PI
            };
            let class = [
                ObjectClass::Car,
                ObjectClass::Car,
                ObjectClass::Truck,
                ObjectClass::Cyclist,
            ][i % 4];
            let size = match class {
                ObjectClass::Truck => Vector3::new(10.0, 2.5, 3.5),
                ObjectClass::Cyclist => Vector3::new(1.8, 0.6, 1.7),
                _ => Vector3::new(4.5, 1.8, 1.5),
            };
            Agent {
                id: i as u32 + 1,
                class,
                size_lwh_m: size,
                parked: false,
                trajectory: straight(
                    Vector3::new(-90.0 + 6.5 * i as f64, lane, size.z / 2.0),
                    heading,
                    8.0 + (i % 5) as f64,
                    duration_s,
                ),
                presence: limot_sim::scene::Presence::ALWAYS,
                labelled: limot_sim::scene::Labelling::Seen,
            }
        })
        .collect();
    Scene {
        duration_s,
        ground,
        statics,
        agents,
        ego: Ego {
            trajectory: straight(Vector3::new(-20.0, 0.0, 1.73), 0.0, 12.0, duration_s),
            size_lwh_m: Vector3::new(4.5, 1.8, 1.5),
            box_center_lidar_m: Vector3::new(0.0, 0.0, -0.98),
            t_lidar_imu: Isometry3::identity(),
        },
    }
}

/// Scans/s of the built-in scenarios' own worlds (rough crowned ground,
/// roadside and streetscape), sweeps 10..30 of a 5 s drive.
fn bench_builtin(name: &str, pool: &rayon::ThreadPool) -> Result<(), Box<dyn std::error::Error>> {
    let mut spec = limot_sim::scenario::ScenarioSpec::builtin(name).ok_or("no such scenario")?;
    spec.duration_s = 5.0;
    let scene = spec.build()?;
    let world = World::new(&scene);
    let lidar = LidarSimulator::new(spec.lidar.clone(), 7)?;
    let rays_per_scan = (lidar.config().azimuth_steps * NUM_LASERS) as f64;
    pool.install(|| lidar.scan(&scene, &world, 9, 0.9));
    let start = Instant::now();
    let mut points = 0usize;
    for frame in 10..30 {
        let sweep = pool.install(|| lidar.scan(&scene, &world, frame, frame as f64 * 0.1));
        points += sweep.scan.points.len();
    }
    let seconds = start.elapsed().as_secs_f64();
    println!(
        "  {name} ({} statics, {} agents): {:.1} scans/s, {:.2} M rays/s, {:.0} points/scan",
        scene.statics.len(),
        scene.agents.len(),
        20.0 / seconds,
        rays_per_scan * 20.0 / seconds / 1e6,
        points as f64 / 20.0
    );
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let scene = bench_scene();
    let world = World::new(&scene);
    let config = LidarConfig::default();
    let rays_per_scan = (config.azimuth_steps * NUM_LASERS) as f64;
    let lidar = LidarSimulator::new(config, 7)?;
    println!(
        "scene: {} statics, {} agents; {} columns x {} beams",
        scene.statics.len(),
        scene.agents.len(),
        lidar.config().azimuth_steps,
        NUM_LASERS
    );
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()?;
        let scans = 20;
        // warm-up
        pool.install(|| lidar.scan(&scene, &world, 0, 0.0));
        let start = Instant::now();
        let mut points = 0usize;
        let mut agent_points = 0usize;
        for frame in 0..scans {
            let sweep = pool.install(|| lidar.scan(&scene, &world, frame, frame as f64 * 0.1));
            points += sweep.scan.points.len();
            agent_points += sweep
                .labels
                .iter()
                .filter(|&&l| l != STATIC_INSTANCE_ID)
                .count();
        }
        let seconds = start.elapsed().as_secs_f64();
        println!(
            "{threads} thread(s): {:.1} scans/s, {:.2} M rays/s, {:.0} points/scan ({:.0} on agents)",
            scans as f64 / seconds,
            rays_per_scan * scans as f64 / seconds / 1e6,
            points as f64 / scans as f64,
            agent_points as f64 / scans as f64,
        );
        for name in ["urban", "highway"] {
            bench_builtin(name, &pool)?;
        }
    }
    Ok(())
}
