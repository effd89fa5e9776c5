//! Pieces shared by the highway and urban generators: ground, placing things
//! on it, the ego, and assembling traffic results into agents.

use super::{EgoSpec, GroundParams, ScenarioError};
use crate::roughness::Roughness;
use crate::scene::{Agent, Crown, Ego, Ground, Shape, StaticKind, StaticObject, Undulation};
use crate::traffic::{
    DriverParams, LanePath, PlanarSample, PlanarTrack, Suspension, TrafficSpec, VehicleSpec,
    lift_to_ground, simulate_traffic_lifted,
};
use crate::trajectory::{Jet, Knot, Trajectory};
use limot_estimator::input::ObjectClass;
use nalgebra::{Isometry3, Point2, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::{PI, TAU};

/// Traffic id of the ego vehicle (agents are numbered from 1).
pub(crate) const EGO_TRAFFIC_ID: u32 = u32::MAX;

/// Uniform draw from [lo, hi]; returns lo when the interval is empty.
pub(crate) fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo).max(0.0) * rng.random::<f64>()
}

/// A plane with a small slope in a random direction plus a few sinusoidal
/// undulations; each undulation's amplitude is capped so its own grade
/// (2 pi A / wavelength) stays below `undulation_grade_max_percent`. The
/// road's crown runs along `road_axis` (a point and a heading), and the
/// roughness texture comes from the scenario seed's own ChaCha stream, so
/// it never shifts the generator's other draws.
pub(crate) fn generate_ground(
    rng: &mut ChaCha8Rng,
    g: &GroundParams,
    seed: u64,
    road_axis: (Point2<f64>, f64),
) -> Ground {
    let slope = uniform(rng, g.slope_min_percent, g.slope_max_percent) / 100.0;
    let slope_dir = uniform(rng, 0.0, TAU);
    let undulations = (0..g.undulations)
        .map(|_| {
            let wavelength_m = uniform(rng, g.wavelength_min_m, g.wavelength_max_m);
            let grade_cap_m = g.undulation_grade_max_percent / 100.0 * wavelength_m / TAU;
            let amplitude_m = uniform(rng, g.amplitude_min_m, g.amplitude_max_m).min(grade_cap_m);
            let dir = uniform(rng, 0.0, TAU);
            Undulation {
                amplitude_m,
                wave_vector: Vector2::new(dir.cos(), dir.sin()) * (TAU / wavelength_m),
                phase_rad: uniform(rng, -PI, PI),
            }
        })
        .collect();
    let crown = (g.crown_height_m > 0.0).then(|| {
        let (point, heading) = road_axis;
        Crown {
            axis_point: point.coords,
            lateral: Vector2::new(-heading.sin(), heading.cos()),
            height_m: g.crown_height_m,
            width_m: g.crown_width_m,
        }
    });
    let roughness = road_roughness(g, seed);
    Ground {
        base_height_m: 0.0,
        slope: Vector2::new(slope_dir.cos(), slope_dir.sin()) * slope,
        undulations,
        crown,
        roughness,
    }
}

/// ChaCha stream (of the scenario seed) of the road roughness texture; the
/// generators' main stream is 0.
const ROUGHNESS_STREAM: u64 = 0x0052_4f55_4748; // "ROUGH" in ASCII

/// The road roughness texture of `g` (none for a zero PSD), drawn from the
/// scenario seed's own ChaCha stream.
pub(crate) fn road_roughness(g: &GroundParams, seed: u64) -> Option<Roughness> {
    (g.roughness_psd_m3 > 0.0).then(|| {
        let mut stream = ChaCha8Rng::seed_from_u64(seed);
        stream.set_stream(ROUGHNESS_STREAM);
        Roughness::iso8608(
            &mut stream,
            g.roughness_psd_m3,
            g.roughness_wavelength_min_m,
            g.roughness_wavelength_max_m,
        )
    })
}

/// An upright static object whose base sits `sink_m` below the ground at
/// (x, y) (so it never floats on a slope), rotated by `yaw` about z.
pub(crate) fn upright_static(
    ground: &Ground,
    kind: StaticKind,
    shape: Shape,
    xy: Point2<f64>,
    base_height_m: f64,
    yaw_rad: f64,
) -> StaticObject {
    let half_height = match shape {
        Shape::Cuboid { half_extents_m } => half_extents_m.z,
        Shape::Cylinder { half_height_m, .. } => half_height_m,
        Shape::Ball { radius_m } => radius_m,
    };
    let z = ground.height(xy.x, xy.y) + base_height_m + half_height;
    StaticObject {
        kind,
        shape,
        t_world_object: Isometry3::from_parts(
            Translation3::new(xy.x, xy.y, z),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad),
        ),
    }
}

/// A pole (a vertical cylinder of `radius_m`) standing `height_m` above the
/// ground at `xy`, its foot set 0.2 m into the ground.
pub(crate) fn pole(ground: &Ground, xy: Point2<f64>, radius_m: f64, height_m: f64) -> StaticObject {
    upright_static(
        ground,
        StaticKind::Pole,
        Shape::Cylinder {
            radius_m,
            half_height_m: 0.5 * height_m,
        },
        xy,
        -0.2,
        0.0,
    )
}

/// A cuboid of length `|p1 - p0|` from p0 to p1 spanning heights
/// `bottom_m..top_m` above the ground, pitched to follow the ground between
/// its ends (guard rails).
pub(crate) fn cuboid_between(
    ground: &Ground,
    kind: StaticKind,
    p0: Point2<f64>,
    p1: Point2<f64>,
    width_m: f64,
    (bottom_m, top_m): (f64, f64),
) -> StaticObject {
    let height_m = top_m - bottom_m;
    let d = p1 - p0;
    let length = d.norm();
    let yaw = d.y.atan2(d.x);
    let (z0, z1) = (ground.height(p0.x, p0.y), ground.height(p1.x, p1.y));
    // R = Rz Ry: positive pitch points the nose down
    let pitch = (z0 - z1).atan2(length);
    let mid = nalgebra::center(&p0, &p1);
    StaticObject {
        kind,
        shape: Shape::Cuboid {
            half_extents_m: Vector3::new(0.5 * length, 0.5 * width_m, 0.5 * height_m),
        },
        t_world_object: Isometry3::from_parts(
            Translation3::new(mid.x, mid.y, 0.5 * (z0 + z1) + bottom_m + 0.5 * height_m),
            UnitQuaternion::from_euler_angles(0.0, pitch, yaw),
        ),
    }
}

/// A cuboid of `half_extents_m` lying on the ground at `xy`: yawed by
/// `yaw_rad`, then tilted with the untextured ground's slope there, its
/// bottom face `sink_m` below the ground (so the texture never shows a gap
/// under it): kerbed sidewalks, embankment slabs, wall footings.
pub(crate) fn box_on_ground(
    ground: &Ground,
    kind: StaticKind,
    xy: Point2<f64>,
    yaw_rad: f64,
    half_extents_m: Vector3<f64>,
    sink_m: f64,
) -> StaticObject {
    let (_, gx, gy) = ground.terrain_height_and_gradient(xy.x, xy.y);
    let crown = ground.crown.map_or((0.0, Vector2::zeros()), |c| {
        c.height_and_gradient(xy.x, xy.y)
    });
    let up = Vector3::new(-(gx + crown.1.x), -(gy + crown.1.y), 1.0).normalize();
    let tilt = UnitQuaternion::rotation_between(&Vector3::z(), &up).unwrap_or_default();
    let rotation = tilt * UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad);
    let base = Vector3::new(xy.x, xy.y, ground.untextured_height(xy.x, xy.y) - sink_m);
    StaticObject {
        kind,
        shape: Shape::Cuboid { half_extents_m },
        t_world_object: Isometry3::from_parts(
            Translation3::from(base + up * half_extents_m.z),
            rotation,
        ),
    }
}

/// Buildings reach this far below the lowest ground point of their footprint.
pub(crate) const BUILDING_SINK_M: f64 = 0.5;

/// A building: an axis-aligned box of `height_m` over the footprint
/// `centre` +- (`half_x_m`, `half_y_m`), its base below the lowest corner of
/// the footprint by [`BUILDING_SINK_M`].
pub(crate) fn building(
    ground: &Ground,
    centre: Point2<f64>,
    half_x_m: f64,
    half_y_m: f64,
    height_m: f64,
) -> StaticObject {
    let lowest = [-half_x_m, half_x_m]
        .iter()
        .flat_map(|&dx| [-half_y_m, half_y_m].map(|dy| (centre.x + dx, centre.y + dy)))
        .map(|(x, y)| ground.height(x, y))
        .fold(f64::INFINITY, f64::min);
    let base = lowest - BUILDING_SINK_M - ground.height(centre.x, centre.y);
    upright_static(
        ground,
        StaticKind::Building,
        Shape::Cuboid {
            half_extents_m: Vector3::new(half_x_m, half_y_m, 0.5 * (height_m + BUILDING_SINK_M)),
        },
        centre,
        base,
        0.0,
    )
}

/// A tree: a trunk cylinder and a crown ball half a crown radius above its
/// top, sized within `trunk_height_m`, `trunk_radius_m`, `crown_radius_m`.
pub(crate) fn tree(
    ground: &Ground,
    at: Point2<f64>,
    trunk_height_m: (f64, f64),
    trunk_radius_m: (f64, f64),
    crown_radius_m: (f64, f64),
    rng: &mut ChaCha8Rng,
) -> [StaticObject; 2] {
    let trunk_height = uniform(rng, trunk_height_m.0, trunk_height_m.1);
    let trunk_radius = uniform(rng, trunk_radius_m.0, trunk_radius_m.1);
    let crown_radius = uniform(rng, crown_radius_m.0, crown_radius_m.1);
    let trunk = upright_static(
        ground,
        StaticKind::TreeTrunk,
        Shape::Cylinder {
            radius_m: trunk_radius,
            half_height_m: 0.5 * (trunk_height + 0.2),
        },
        at,
        -0.2,
        0.0,
    );
    let crown = upright_static(
        ground,
        StaticKind::TreeCrown,
        Shape::Ball {
            radius_m: crown_radius,
        },
        at,
        trunk_height - 0.5 * crown_radius,
        0.0,
    );
    [trunk, crown]
}

/// A bush: a ball of radius in `radius_m` sunk by a third of its radius.
pub(crate) fn bush(
    ground: &Ground,
    at: Point2<f64>,
    radius_m: (f64, f64),
    rng: &mut ChaCha8Rng,
) -> StaticObject {
    let r = uniform(rng, radius_m.0, radius_m.1);
    upright_static(
        ground,
        StaticKind::Shrub,
        Shape::Ball { radius_m: r },
        at,
        -r / 3.0,
        0.0,
    )
}

/// A point beside a lane path: `lateral_m` to the left of arc length `s_m`.
pub(crate) fn beside(path: &LanePath, s_m: f64, lateral_m: f64) -> Point2<f64> {
    let h = path.heading_at(s_m);
    path.point_at(s_m) + Vector2::new(-h.sin(), h.cos()) * lateral_m
}

/// A parked vehicle: at rest for the whole run, resting on the ground with
/// the same attitude rule as moving vehicles (`lift_to_ground`).
pub(crate) fn parked_agent(
    ground: &Ground,
    id: u32,
    class: ObjectClass,
    size_lwh_m: Vector3<f64>,
    xy: Point2<f64>,
    yaw_rad: f64,
    duration_s: f64,
) -> Agent {
    let sample = PlanarSample::at_rest(xy.x, xy.y, yaw_rad);
    let track = PlanarTrack {
        id,
        t0_s: 0.0,
        dt_s: duration_s.max(1e-3),
        samples: vec![sample, sample],
    };
    let pose = lift_to_ground(
        &track,
        ground,
        &size_lwh_m,
        Suspension::for_class(class).as_ref(),
    )
    .pose_at(0.0);
    Agent {
        id,
        class,
        size_lwh_m,
        parked: true,
        trajectory: Trajectory::stationary(0.0, duration_s, &pose),
        presence: crate::scene::Presence::ALWAYS,
        labelled: crate::scene::Labelling::Seen,
    }
}

/// Size and driver model of a road user drawn per class.
pub(crate) fn draw_body(rng: &mut ChaCha8Rng, class: ObjectClass) -> (Vector3<f64>, DriverParams) {
    match class {
        ObjectClass::Car => (
            Vector3::new(
                uniform(rng, 4.0, 4.9),
                uniform(rng, 1.7, 1.95),
                uniform(rng, 1.4, 1.75),
            ),
            DriverParams::car(),
        ),
        ObjectClass::Truck => (
            Vector3::new(
                uniform(rng, 9.0, super::HIGHWAY_TRUCK_LENGTH_M),
                uniform(rng, 2.45, 2.55),
                uniform(rng, 3.2, 4.0),
            ),
            DriverParams::truck(),
        ),
        ObjectClass::Cyclist => (
            Vector3::new(
                uniform(rng, 1.6, 1.9),
                uniform(rng, 0.55, 0.7),
                uniform(rng, 1.6, 1.85),
            ),
            DriverParams::cyclist(),
        ),
        ObjectClass::Pedestrian => (
            Vector3::new(
                uniform(rng, 0.4, 0.6),
                uniform(rng, 0.5, 0.7),
                uniform(rng, 1.55, 1.9),
            ),
            DriverParams::pedestrian(),
        ),
    }
}

/// The ego's steering looks this far ahead (at least) through a tight
/// manoeuvre at walking pace: a car's default 5 m cuts a corner of about
/// 5 m by decimetres on the way in and swings out on the way out (into the
/// next lane after a U-turn, askew into a parking bay), m.
pub(crate) const MANOEUVRE_LOOKAHEAD_M: f64 = 2.5;

/// The ego as a traffic participant: a car held at rest until `depart_s`.
pub(crate) fn ego_vehicle(
    ego: &EgoSpec,
    lane: usize,
    start_s_m: f64,
    speed_mps: f64,
) -> VehicleSpec {
    VehicleSpec {
        id: EGO_TRAFFIC_ID,
        class: ObjectClass::Car,
        size_lwh_m: Vector3::from(ego.size_lwh_m),
        lane,
        start_s_m,
        start_speed_mps: 0.0,
        desired_speed_mps: speed_mps,
        depart_s: ego.depart_s,
        lane_changes: Vec::new(),
        driver: DriverParams::car(),
    }
}

/// Box centre of the ego car in the LiDAR frame: the LiDAR sits
/// `lidar_ahead_of_center_m` ahead of the centre at `lidar_height_m` above the
/// ground, and the box centre is at half the body height.
pub(crate) fn box_center_lidar_m(ego: &EgoSpec) -> Vector3<f64> {
    Vector3::new(
        -ego.lidar_ahead_of_center_m,
        0.0,
        0.5 * ego.size_lwh_m[2] - ego.lidar_height_m,
    )
}

/// Moves a rigid-body trajectory from one body point to another: knot by
/// knot, p' = p + R d, v' = v + R (w x d), a' = a + R (alpha x d + w x (w x d))
/// with d the new origin in the body frame; the attitude is unchanged.
pub(crate) fn shift_body_origin(traj: &Trajectory, d_body: &Vector3<f64>) -> Trajectory {
    let knots = traj
        .knots()
        .enumerate()
        .map(|(i, knot)| {
            let t = traj.t0_s + i as f64 * traj.dt_s;
            let st = traj.state_at(t.min(traj.end_s()));
            let r = st.t_world_body.rotation;
            let (w, alpha) = (st.angular_velocity_body_radps, st.angular_accel_body_radps2);
            let p = st.t_world_body.translation.vector + r * d_body;
            let v = st.velocity_world_mps + r * w.cross(d_body);
            let a = st.accel_world_mps2 + r * (alpha.cross(d_body) + w.cross(&w.cross(d_body)));
            Knot {
                position: [
                    Jet::new(p.x, v.x, a.x),
                    Jet::new(p.y, v.y, a.y),
                    Jet::new(p.z, v.z, a.z),
                ],
                euler: knot.euler,
            }
        })
        .collect();
    Trajectory::new(traj.t0_s, traj.dt_s, knots)
}

/// The scene's ego from its box-centre trajectory.
pub(crate) fn make_ego(ego: &EgoSpec, box_trajectory: &Trajectory) -> Ego {
    let box_center_lidar = box_center_lidar_m(ego);
    Ego {
        trajectory: shift_body_origin(box_trajectory, &(-box_center_lidar)),
        size_lwh_m: Vector3::from(ego.size_lwh_m),
        box_center_lidar_m: box_center_lidar,
        t_lidar_imu: Isometry3::from_parts(
            Translation3::from(Vector3::from(ego.imu_in_lidar_m)),
            UnitQuaternion::identity(),
        ),
    }
}

/// Runs the traffic simulation (the ego is the last vehicle) and lifts every
/// track onto the ground raised by `raised(x, y)` (sidewalks): agents get
/// ids 1..=N in `vehicles` order.
pub(crate) fn run_traffic(
    spec: &super::ScenarioSpec,
    ground: &Ground,
    raised: &dyn Fn(f64, f64) -> f64,
    traffic: &TrafficSpec,
) -> Result<(Vec<Agent>, Ego), ScenarioError> {
    let trajectories = simulate_traffic_lifted(traffic, ground, raised)
        .map_err(|e| super::traffic_error(spec, e))?;
    let mut agents = Vec::with_capacity(trajectories.len());
    let mut ego_scene = None;
    for (vehicle, trajectory) in traffic.vehicles.iter().zip(trajectories) {
        if vehicle.id == EGO_TRAFFIC_ID {
            ego_scene = Some(make_ego(&spec.ego, &trajectory));
        } else {
            agents.push(Agent {
                id: vehicle.id,
                class: vehicle.class,
                size_lwh_m: vehicle.size_lwh_m,
                parked: false,
                trajectory,
                presence: crate::scene::Presence::ALWAYS,
                labelled: crate::scene::Labelling::Seen,
            });
        }
    }
    let ego_scene = ego_scene.ok_or_else(|| ScenarioError::Build {
        scenario: spec.name.clone(),
        message: "the traffic simulation returned no ego track".into(),
    })?;
    Ok((agents, ego_scene))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// A vehicle-like trajectory with yaw, pitch and roll all moving.
    fn wobbly_trajectory() -> Trajectory {
        let dt = 0.05;
        let knots = (0..80)
            .map(|i| {
                let t = i as f64 * dt;
                Knot {
                    position: [
                        Jet::new(3.0 * t + 0.2 * t * t, 3.0 + 0.4 * t, 0.4),
                        Jet::new(0.5 * t.sin(), 0.5 * t.cos(), -0.5 * t.sin()),
                        Jet::new(0.1 * t, 0.1, 0.0),
                    ],
                    euler: [
                        Jet::new(0.3 * t * t, 0.6 * t, 0.6),
                        Jet::new(
                            0.05 * (2.0 * t).sin(),
                            0.1 * (2.0 * t).cos(),
                            -0.2 * (2.0 * t).sin(),
                        ),
                        Jet::new(0.04 * t.cos(), -0.04 * t.sin(), -0.04 * t.cos()),
                    ],
                }
            })
            .collect();
        Trajectory::new(0.0, dt, knots)
    }

    #[test]
    fn shifted_origin_is_rigid_and_its_derivatives_match_finite_differences() {
        let body = wobbly_trajectory();
        let d = Vector3::new(0.27, -0.1, 0.98);
        let shifted = shift_body_origin(&body, &d);
        for &t in &[0.5, 1.23, 2.0, 3.31] {
            // rigid: the new origin is the body point d (exact at knots, close between)
            let want = body.pose_at(t) * Translation3::from(d);
            let got = shifted.pose_at(t);
            let tol = if (t / body.dt_s).fract().abs() < 1e-9 {
                1e-12
            } else {
                1e-5
            };
            assert!(
                (got.translation.vector - want.translation.vector).norm() < tol,
                "t {t}"
            );
            assert!(got.rotation.angle_to(&want.rotation) < 1e-12);
            // velocity and acceleration against central differences of the
            // rigidly moved point
            let h = 1e-4;
            let p = |t: f64| (body.pose_at(t) * Translation3::from(d)).translation.vector;
            let v_fd = (p(t + h) - p(t - h)) / (2.0 * h);
            let a_fd = (p(t + h) - 2.0 * p(t) + p(t - h)) / (h * h);
            let st = shifted.state_at(t);
            assert!((st.velocity_world_mps - v_fd).norm() < 1e-3, "v {t}");
            assert!((st.accel_world_mps2 - a_fd).norm() < 2e-2, "a {t}");
        }
    }

    #[test]
    fn ground_grades_stay_gentle() {
        let params = GroundParams::default();
        for seed in 0..20 {
            let ground = generate_ground(
                &mut ChaCha8Rng::seed_from_u64(seed),
                &params,
                seed,
                (Point2::origin(), 0.0),
            );
            let slope = ground.slope.norm();
            assert!((0.01..=0.02).contains(&slope), "slope {slope}");
            assert_eq!(ground.undulations.len(), 3);
            for u in &ground.undulations {
                let wavelength = TAU / u.wave_vector.norm();
                assert!((100.0..=400.0).contains(&wavelength));
                assert!(
                    u.amplitude_m <= 1.0 && u.amplitude_m * u.wave_vector.norm() <= 0.02 + 1e-12
                );
            }
            for k in 0..100 {
                let x = k as f64 * 37.0 - 1800.0;
                assert!(ground.gradient(x, 0.3 * x).norm() < 0.02 + 3.0 * 0.02 + 1e-9);
            }
        }
    }
}
