use super::*;
use crate::scene::{Ego, StaticObject, Undulation};
use crate::trajectory::{Jet, Knot};
use nalgebra::{Translation3, UnitQuaternion, Vector2};

pub(crate) fn scene_with(ground: Ground, statics: Vec<StaticObject>) -> Scene {
    Scene {
        duration_s: 1.0,
        ground,
        statics,
        agents: Vec::new(),
        ego: Ego {
            trajectory: Trajectory::stationary(0.0, 1.0, &Isometry3::identity()),
            size_lwh_m: Vector3::new(4.5, 1.8, 1.5),
            box_center_lidar_m: Vector3::new(0.0, 0.0, -0.9),
            t_lidar_imu: Isometry3::identity(),
        },
    }
}

fn unit(x: f64, y: f64, z: f64) -> Unit<Vector3<f64>> {
    Unit::new_normalize(Vector3::new(x, y, z))
}

#[test]
fn ray_against_flat_ground_returns_the_exact_range() {
    let world = World::new(&scene_with(Ground::flat(0.0), Vec::new()));
    let snap = world.snapshot(0.0);
    let origin = Point3::new(12.0, -3.0, 1.73);
    for elevation_deg in [-24.8_f64, -10.0, -2.0, -0.5] {
        let el = elevation_deg.to_radians();
        let az = 0.7_f64;
        let dir = unit(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
        let hit = snap.cast_ray(&origin, &dir, 1000.0).expect("hit");
        let expected = 1.73 / (-el).sin();
        assert!((hit.range_m - expected).abs() < 1e-9, "{elevation_deg}");
        assert_eq!(hit.surface, Surface::Ground);
        assert_eq!(hit.instance_id, 0);
        assert!((hit.normal_world.z - 1.0).abs() < 1e-12);
        // max range respected
        assert!(snap.cast_ray(&origin, &dir, expected - 1e-3).is_none());
    }
    // upward ray never hits a flat ground
    assert!(snap.cast_ray(&origin, &unit(1.0, 0.0, 0.01), 1e4).is_none());
}

#[test]
fn ray_against_undulating_ground_lands_on_the_surface() {
    let ground = Ground {
        base_height_m: 0.3,
        slope: Vector2::new(0.01, -0.02),
        undulations: vec![
            Undulation {
                amplitude_m: 0.6,
                wave_vector: Vector2::new(0.05, 0.02),
                phase_rad: 0.3,
            },
            Undulation {
                amplitude_m: 0.2,
                wave_vector: Vector2::new(-0.01, 0.2),
                phase_rad: 1.0,
            },
        ],
        ..Ground::flat(0.0)
    };
    let world = World::new(&scene_with(ground.clone(), Vec::new()));
    let snap = world.snapshot(0.0);
    let origin = Point3::new(5.0, 2.0, ground.height(5.0, 2.0) + 1.73);
    let mut hits = 0;
    for i in 0..400 {
        let az = i as f64 * 0.157;
        let el = -(0.005 + 0.4 * (i as f64 / 400.0));
        let dir = unit(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
        let Some(hit) = snap.cast_ray(&origin, &dir, 200.0) else {
            continue;
        };
        hits += 1;
        let p = origin + dir.as_ref() * hit.range_m;
        assert!((p.z - ground.height(p.x, p.y)).abs() < 1e-6);
        // no earlier crossing: the ray stays above ground before the hit
        for k in 1..200 {
            let q = origin + dir.as_ref() * (hit.range_m * k as f64 / 200.0);
            assert!(q.z - ground.height(q.x, q.y) > -1e-9);
        }
    }
    assert!(hits > 300, "{hits}");
}

#[test]
fn ray_against_crowned_rough_ground_lands_on_the_first_crossing() {
    use crate::roughness::Roughness;
    use crate::scene::Crown;
    use rand::SeedableRng;
    let ground = Ground {
        base_height_m: 0.3,
        slope: Vector2::new(0.01, -0.02),
        undulations: vec![Undulation {
            amplitude_m: 0.6,
            wave_vector: Vector2::new(0.05, 0.02),
            phase_rad: 0.3,
        }],
        crown: Some(Crown {
            axis_point: Vector2::new(0.0, 1.0),
            lateral: Vector2::new(0.0, 1.0),
            height_m: 0.25,
            width_m: 8.0,
        }),
        // ISO class C, rougher than any built-in road
        roughness: Some(Roughness::iso8608(
            &mut rand_chacha::ChaCha8Rng::seed_from_u64(4),
            256e-6,
            0.3,
            20.0,
        )),
    };
    let world = World::new(&scene_with(ground.clone(), Vec::new()));
    let snap = world.snapshot(0.0);
    let mut hits = 0;
    let mut first_crossing_checked = 0;
    for origin_xy in [(5.0, 2.0), (-40.0, -3.5), (2500.0, 4.0)] {
        let origin = Point3::new(
            origin_xy.0,
            origin_xy.1,
            ground.height(origin_xy.0, origin_xy.1) + 1.73,
        );
        for i in 0..600 {
            let az = i as f64 * 0.157;
            let el = -(0.01 + 0.42 * (i as f64 / 600.0));
            let dir = unit(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
            let Some(hit) = snap.cast_ray(&origin, &dir, 120.0) else {
                continue;
            };
            hits += 1;
            let p = origin + dir.as_ref() * hit.range_m;
            assert!(
                (p.z - ground.height(p.x, p.y)).abs() < 1e-6,
                "{el} {az} {origin_xy:?} range {} f {}",
                hit.range_m,
                p.z - ground.height(p.x, p.y)
            );
            // the normal of the surface there, up to the polish's last
            // step (either side of a texture cell edge it may have crossed)
            let normal_at = |q: Point3<f64>| {
                let (_, gx, gy) = ground.height_and_gradient(q.x, q.y);
                Vector3::new(-gx, -gy, 1.0).normalize()
            };
            let n = hit.normal_world.into_inner();
            let q = p - dir.as_ref() * 1e-6;
            assert!((n - normal_at(p)).norm() < 1e-3 || (n - normal_at(q)).norm() < 1e-3);
            // steeper than every slope of the surface: nothing earlier
            if dir.z < -0.12 {
                first_crossing_checked += 1;
                for k in 1..400 {
                    let q = origin + dir.as_ref() * (hit.range_m * k as f64 / 400.0);
                    assert!(q.z - ground.height(q.x, q.y) > -1e-9, "{el} {az} {k}");
                }
            }
        }
    }
    assert!(
        hits > 1500 && first_crossing_checked > 300,
        "{hits} {first_crossing_checked}"
    );
}

fn placed(kind: StaticKind, shape: Shape, x: f64, y: f64, z: f64, yaw: f64) -> StaticObject {
    StaticObject {
        kind,
        shape,
        t_world_object: Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        ),
    }
}

#[test]
fn rays_against_box_cylinder_and_ball_return_exact_ranges() {
    let statics = [
        // wall facing the origin: front face at x = 20 - 0.5
        placed(
            StaticKind::Wall,
            Shape::Cuboid {
                half_extents_m: Vector3::new(0.5, 5.0, 2.0),
            },
            20.0,
            0.0,
            2.0,
            0.0,
        ),
        placed(
            StaticKind::Pole,
            Shape::Cylinder {
                radius_m: 0.3,
                half_height_m: 3.0,
            },
            0.0,
            15.0,
            3.0,
            0.4,
        ),
        placed(
            StaticKind::TreeCrown,
            Shape::Ball { radius_m: 2.0 },
            -30.0,
            0.0,
            1.73,
            0.0,
        ),
    ];
    // far from the origin, as late in a long drive: f64 must keep exactness
    let offset = Vector3::new(3000.0, -2500.0, 0.0);
    let shifted: Vec<StaticObject> = statics
        .iter()
        .map(|s| StaticObject {
            t_world_object: Isometry3::from_parts(
                Translation3::from(s.t_world_object.translation.vector + offset),
                s.t_world_object.rotation,
            ),
            ..*s
        })
        .collect();
    let world = World::new(&scene_with(Ground::flat(-100.0), shifted));
    let snap = world.snapshot(0.0);
    let origin = Point3::new(0.0, 0.0, 1.73) + offset;
    // box: oblique ray in the xz plane
    let el = 0.05_f64;
    let dir = unit(el.cos(), 0.0, el.sin());
    let hit = snap.cast_ray(&origin, &dir, 120.0).expect("wall");
    assert!((hit.range_m - 19.5 / el.cos()).abs() < 1e-9);
    assert_eq!(hit.surface, Surface::Static(StaticKind::Wall));
    assert!((hit.normal_world.x + 1.0).abs() < 1e-12);
    assert!(snap.cast_ray(&origin, &dir, 19.0).is_none());
    // cylinder: horizontal ray offset 0.1 m from the axis
    let o2 = origin + Vector3::new(0.1, 0.0, 0.0);
    let hit = snap
        .cast_ray(&o2, &unit(0.0, 1.0, 0.0), 120.0)
        .expect("pole");
    let expected = 15.0 - (0.3f64 * 0.3 - 0.1 * 0.1).sqrt();
    assert!((hit.range_m - expected).abs() < 1e-9, "{}", hit.range_m);
    assert_eq!(hit.surface, Surface::Static(StaticKind::Pole));
    assert!((hit.normal_world.z).abs() < 1e-12 && hit.normal_world.y < 0.0);
    // cylinder top cap from above
    let o3 = origin + Vector3::new(0.05, 15.0, 10.0);
    let hit = snap
        .cast_ray(&o3, &unit(0.0, 0.0, -1.0), 120.0)
        .expect("cap");
    assert!((hit.range_m - (10.0 + 1.73 - 6.0)).abs() < 1e-9);
    assert!((hit.normal_world.z - 1.0).abs() < 1e-12);
    // ball straight behind
    let hit = snap
        .cast_ray(&origin, &unit(-1.0, 0.0, 0.0), 120.0)
        .expect("crown");
    assert!((hit.range_m - 28.0).abs() < 1e-9);
    assert_eq!(hit.instance_id, 0);
    assert_eq!(hit.surface, Surface::Static(StaticKind::TreeCrown));
    // nothing to the right
    assert!(
        snap.cast_ray(&origin, &unit(0.0, -1.0, 0.0), 120.0)
            .is_none()
    );
}

fn moving_agent(id: u32, x0: f64, speed_mps: f64) -> crate::scene::Agent {
    let knots = (0..11)
        .map(|i| {
            let t = i as f64 * 0.1;
            Knot {
                position: [
                    Jet::new(x0 + speed_mps * t, speed_mps, 0.0),
                    Jet::new(0.0, 0.0, 0.0),
                    Jet::new(0.75, 0.0, 0.0),
                ],
                euler: [Jet::default(); 3],
            }
        })
        .collect();
    crate::scene::Agent {
        id,
        class: ObjectClass::Car,
        size_lwh_m: Vector3::new(4.0, 2.0, 1.5),
        parked: false,
        trajectory: Trajectory::new(0.0, 0.1, knots),
        presence: crate::scene::Presence::ALWAYS,
        labelled: crate::scene::Labelling::Seen,
    }
}

#[test]
fn agents_are_hit_where_they_are_at_the_snapshot_time() {
    let mut scene = scene_with(Ground::flat(0.0), Vec::new());
    scene.agents.push(moving_agent(7, 10.0, 10.0));
    let mut world = World::new(&scene);
    let origin = Point3::new(0.0, 0.0, 0.75);
    let dir = unit(1.0, 0.0, 0.0);
    for t in [0.0, 0.3, 0.55] {
        let hit = world.snapshot(t).cast_ray(&origin, &dir, 120.0).unwrap();
        assert!((hit.range_m - (10.0 + 10.0 * t - 2.0)).abs() < 1e-9);
        assert_eq!(hit.instance_id, 7);
        assert_eq!(hit.surface, Surface::Agent(ObjectClass::Car));
    }
    // rapier body follows set_time
    world.set_time(0.5);
    let body = &world.rigid_bodies()[world.agents[0].body];
    assert!((body.translation().x - 15.0).abs() < 1e-5);
    let collider = &world.colliders()[world.agents[0].collider];
    assert_eq!(collider.user_data, 7);
}

#[test]
fn analytic_shapes_agree_with_parry() {
    use parry3d::query::RayCast;
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let shapes = [
        Shape::Cuboid {
            half_extents_m: Vector3::new(1.0, 0.5, 2.0),
        },
        Shape::Cylinder {
            radius_m: 0.8,
            half_height_m: 1.5,
        },
        Shape::Ball { radius_m: 1.2 },
    ];
    let mut compared = 0;
    let mut normals_agree = 0;
    for _ in 0..3000 {
        let shape = shapes[rng.random_range(0..3)];
        let pose = Isometry3::from_parts(
            Translation3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            ),
            UnitQuaternion::from_euler_angles(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-3.0..3.0),
            ),
        );
        let origin = Point3::new(
            rng.random_range(-10.0..10.0),
            rng.random_range(-10.0..10.0),
            rng.random_range(-10.0..10.0),
        );
        // aim near the shape so most rays hit, some graze or miss
        let target = Point3::from(pose.translation.vector)
            + Vector3::new(
                rng.random_range(-1.5..1.5),
                rng.random_range(-1.5..1.5),
                rng.random_range(-1.5..1.5),
            );
        let dir = Unit::new_normalize(target - origin);
        let ours = intersect_shape(&shape, &Placement::of(&pose), &origin, &dir, 100.0);
        // parry in the local frame of the ray origin
        let rel = Isometry3::from_parts(
            Translation3::from(pose.translation.vector - origin.coords),
            pose.rotation,
        );
        let ray = parry3d::query::Ray::new(
            parry3d::math::Vector::ZERO,
            parry3d::math::Vector::new(dir.x as f32, dir.y as f32, dir.z as f32),
        );
        let theirs = match shape {
            Shape::Cuboid { half_extents_m: h } => parry3d::shape::Cuboid::new(
                parry3d::math::Vector::new(h.x as f32, h.y as f32, h.z as f32),
            )
            .cast_ray_and_get_normal(&to_glam_pose(&rel), &ray, 100.0, false),
            Shape::Cylinder {
                radius_m,
                half_height_m,
            } => parry3d::shape::Cylinder::new(half_height_m as f32, radius_m as f32)
                .cast_ray_and_get_normal(
                    &to_glam_pose(
                        &(rel * Isometry3::rotation(Vector3::x() * std::f64::consts::FRAC_PI_2)),
                    ),
                    &ray,
                    100.0,
                    false,
                ),
            Shape::Ball { radius_m } => parry3d::shape::Ball::new(radius_m as f32)
                .cast_ray_and_get_normal(&to_glam_pose(&rel), &ray, 100.0, false),
        };
        match (ours, theirs) {
            (Some((r, n)), Some(hit)) => {
                compared += 1;
                assert!(
                    (r - hit.time_of_impact as f64).abs() < 2e-3,
                    "{shape:?} {r} {hit:?}"
                );
                let pn = Vector3::new(
                    hit.normal.x as f64,
                    hit.normal.y as f64,
                    hit.normal.z as f64,
                );
                // normals may differ on edges/rims (either face is right
                // there); parry's GJK cylinder normals are off by ~5e-3
                if (n.into_inner() - pn).norm() < 2e-2 {
                    normals_agree += 1;
                }
            }
            (None, None) => {}
            (ours, theirs) => {
                // parry (solid = false) reports the exit of a ray starting
                // inside; we report nothing there
                let local = pose.inverse_transform_point(&origin);
                let inside = match shape {
                    Shape::Cuboid { half_extents_m: h } => (0..3).all(|i| local[i].abs() <= h[i]),
                    Shape::Cylinder {
                        radius_m,
                        half_height_m,
                    } => local.xy().coords.norm() <= radius_m && local.z.abs() <= half_height_m,
                    Shape::Ball { radius_m } => local.coords.norm() <= radius_m,
                };
                assert!(
                    inside && ours.is_none(),
                    "{shape:?} {local}: ours {ours:?}, parry {theirs:?}"
                );
            }
        }
    }
    assert!(compared > 1000, "{compared}");
    assert!(
        normals_agree as f64 > 0.99 * compared as f64,
        "{normals_agree}/{compared}"
    );
}

#[test]
fn candidate_statics_skip_the_bvh_only_when_none_is_hit_and_their_bounds_hold_them() {
    let shapes = [
        Shape::Cuboid {
            half_extents_m: Vector3::new(2.0, 1.0, 3.0),
        },
        Shape::Cylinder {
            radius_m: 0.4,
            half_height_m: 2.5,
        },
        Shape::Ball { radius_m: 1.5 },
    ];
    let statics: Vec<StaticObject> = shapes
        .iter()
        .enumerate()
        .map(|(i, &shape)| StaticObject {
            kind: StaticKind::Building,
            shape,
            t_world_object: Isometry3::from_parts(
                Translation3::new(12.0, -5.0 + 5.0 * i as f64, 2.0),
                UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7 * i as f64),
            ),
        })
        .collect();
    let world = World::new(&scene_with(Ground::flat(0.0), statics.clone()));
    assert_eq!(world.static_count(), 3);
    let snap = world.snapshot(0.0);
    let origin = Point3::new(0.0, 0.0, 1.5);
    let mut hits = [0; 3];
    for i in 0..2000 {
        let az = -0.6 + 1.2 * i as f64 / 2000.0;
        let el = -0.2 + 0.3 * ((i * 7) % 2000) as f64 / 2000.0;
        let dir = unit(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
        let bvh = snap.cast_ray(&origin, &dir, 100.0);
        assert_eq!(
            bvh,
            snap.cast_ray_with_candidates(&origin, &dir, 100.0, &[0, 1, 2])
        );
        // no candidates: no static is hit
        let ground_only = snap.cast_ray_with_candidates(&origin, &dir, 100.0, &[]);
        assert!(ground_only.is_none_or(|h| h.surface == Surface::Ground));
        let Some(hit) = bvh.filter(|h| h.surface != Surface::Ground) else {
            assert_eq!(ground_only, bvh);
            continue;
        };
        // the static hit: the one whose shape the hit point lies on
        let p = origin + dir.as_ref() * hit.range_m;
        let index = (0..3)
            .find(|&k| {
                let local = statics[k].t_world_object.inverse_transform_point(&p);
                match statics[k].shape {
                    Shape::Cuboid { half_extents_m: h } => {
                        (0..3).all(|a| local[a].abs() <= h[a] + 1e-9)
                    }
                    Shape::Cylinder {
                        radius_m,
                        half_height_m,
                    } => {
                        local.coords.xy().norm() <= radius_m + 1e-9
                            && local.z.abs() <= half_height_m + 1e-9
                    }
                    Shape::Ball { radius_m } => local.coords.norm() <= radius_m + 1e-9,
                }
            })
            .expect("the hit lies on a static");
        hits[index] += 1;
        // the candidate alone gives the hit; its bounding sphere and box hold it
        assert_eq!(
            snap.cast_ray_with_candidates(&origin, &dir, 100.0, &[index]),
            Some(hit)
        );
        let (centre, radius) = world.static_bounding_spheres()[index];
        assert!((p - centre).norm() <= radius + 1e-9);
        let pose = statics[index].t_world_object;
        let corners = world.static_bounding_corners()[index];
        let local = corners.map(|c| pose.inverse_transform_point(&c));
        let q = pose.inverse_transform_point(&p);
        for axis in 0..3 {
            let extent = local.iter().map(|c| c[axis].abs()).fold(0.0, f64::max);
            assert!(q[axis].abs() <= extent + 1e-9);
        }
    }
    assert!(hits.iter().all(|&n| n > 20), "{hits:?}");
}

#[test]
fn cyclists_and_pedestrians_are_thinner_than_their_boxes() {
    // agents at rest 10 m ahead, their boxes centred at height 0.85 m
    let agent = |id: u32, class: ObjectClass, size: Vector3<f64>| {
        let mut a = moving_agent(id, 10.0, 0.0);
        a.class = class;
        a.size_lwh_m = size;
        a.trajectory = Trajectory::stationary(0.0, 1.0, &Isometry3::translation(10.0, 0.0, 0.85));
        a
    };
    let hit = |a: crate::scene::Agent, y: f64, z: f64| {
        let mut scene = scene_with(Ground::flat(-5.0), Vec::new());
        scene.agents.push(a);
        let world = World::new(&scene);
        world
            .snapshot(0.5)
            .cast_ray(&Point3::new(0.0, y, z), &unit(1.0, 0.0, 0.0), 50.0)
            .map(|h| h.range_m)
    };
    let size = Vector3::new(1.8, 0.8, 1.7);
    let cyclist = || agent(3, ObjectClass::Cyclist, size);
    // the bicycle: the box's length, a wheel's width, up to the saddle
    assert!((hit(cyclist(), 0.0, 0.3).unwrap() - 9.1).abs() < 1e-9);
    assert_eq!(hit(cyclist(), 0.2, 0.3), None);
    // the rider: a third of the length, shoulder-wide, above the saddle
    assert!((hit(cyclist(), 0.2, 1.5).unwrap() - 9.7).abs() < 1e-9);
    assert_eq!(hit(cyclist(), 0.3, 1.5), None);
    // a pedestrian: a column 0.3 m deep and 0.45 m wide, the box's height
    let walker = || agent(4, ObjectClass::Pedestrian, Vector3::new(0.8, 0.6, 1.7));
    assert!((hit(walker(), 0.2, 1.6).unwrap() - 9.85).abs() < 1e-9);
    assert_eq!(hit(walker(), 0.25, 1.0), None);
    // a car fills its box
    assert!((hit(agent(5, ObjectClass::Car, size), 0.35, 0.3).unwrap() - 9.1).abs() < 1e-9);
}

#[test]
fn clears_ground_is_tight_on_flat_ground_and_sound_on_undulations() {
    use super::ground::clears_ground;
    let origin = Point3::new(5.0, -2.0, 1.73);
    // flat: a ray descending 2 % meets the ground at 86.5 m
    let flat = Ground::flat(0.0);
    let sample = flat.terrain_height_and_gradient(origin.x, origin.y);
    let dir = unit(1.0, 0.0, -0.02);
    let crossing_m = 1.73 / -dir.z;
    assert!(clears_ground(
        &flat,
        &sample,
        &origin,
        &dir,
        crossing_m - 1e-3
    ));
    assert!(!clears_ground(
        &flat,
        &sample,
        &origin,
        &dir,
        crossing_m + 1e-3
    ));
    assert!(clears_ground(
        &flat,
        &sample,
        &origin,
        &unit(1.0, 0.5, 0.01),
        1e4
    ));
    // undulations and a crown: whenever it clears, the ray stays above
    let ground = Ground {
        undulations: vec![
            Undulation {
                amplitude_m: 0.4,
                wave_vector: Vector2::new(0.05, 0.02),
                phase_rad: 0.3,
            },
            Undulation {
                amplitude_m: 0.2,
                wave_vector: Vector2::new(-0.01, 0.04),
                phase_rad: -1.1,
            },
        ],
        crown: Some(crate::scene::Crown {
            axis_point: Vector2::new(0.0, 1.0),
            lateral: Vector2::new(0.0, 1.0),
            height_m: -0.3,
            width_m: 2.0,
        }),
        ..Ground::flat(0.0)
    };
    let sample = ground.terrain_height_and_gradient(origin.x, origin.y);
    let mut bounded = 0;
    for k in 0..100 {
        let azimuth = 0.37 * k as f64;
        let dir = unit(azimuth.cos(), azimuth.sin(), -0.05 + 0.0007 * k as f64);
        // the farthest range (whole metres) it clears: the ray must stay
        // above the surface up to there
        let Some(cleared_m) = (1..=150)
            .map(f64::from)
            .take_while(|&r| clears_ground(&ground, &sample, &origin, &dir, r))
            .last()
        else {
            continue;
        };
        bounded += usize::from(cleared_m < 150.0);
        let steps = (cleared_m / 0.01) as usize;
        for i in 0..=steps {
            let p = origin + dir.as_ref() * (cleared_m * i as f64 / steps as f64);
            assert!(p.z > ground.height(p.x, p.y), "ray {k} crosses at {p}");
        }
    }
    // most rays meet the bound within 150 m, so the check above is not vacuous
    assert!(bounded > 50, "{bounded}");
}
