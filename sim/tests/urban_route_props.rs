//! Property tests of the urban ego's turning routes (`urban.ego_route`):
//! over generated streets the ego turns right or left into the cross street
//! and follows it, or turns round into the oncoming kerb lane and drives
//! back; nobody overlaps anybody (ego included: a left turn crosses the
//! oncoming lanes and the far side's pedestrians and cyclists, a U-turn the
//! ego's other lane and the oncoming ones), and the ego's yaw rate and
//! lateral acceleration stay within a car's limits.

use limot_estimator::geometry::wrap_angle_rad;
use limot_sim::scenario::{EgoRoute, ScenarioSpec};
use limot_sim::scene::Scene;
use limot_sim::traffic::{DriverParams, first_overlap};
use nalgebra::Vector3;
use proptest::prelude::*;

/// Comfortable lateral acceleration of a car, m/s^2.
const LATERAL_ACCEL_MAX_MPS2: f64 = 3.0;
/// Wheelbase of the ego in the traffic model (0.6 of its length), m.
fn ego_wheelbase_m(spec: &ScenarioSpec) -> f64 {
    0.6 * spec.ego.size_lwh_m[0]
}

/// Peaks over the run, sampled every 0.01 s.
#[derive(Debug)]
struct TurnFigures {
    /// |yaw rate|, rad/s.
    yaw_rate_radps: f64,
    /// |yaw rate| allowed by the steering limit at the speed of that moment, rad/s.
    yaw_rate_limit_radps: f64,
    /// Horizontal acceleration across the heading, m/s^2.
    lateral_accel_mps2: f64,
    /// Speed while the yaw rate is above half its peak (in the turn), m/s.
    turn_speed_max_mps: f64,
    /// Heading at the end of the run (0 = +x), rad.
    final_heading_rad: f64,
}

fn turn_figures(spec: &ScenarioSpec, scene: &Scene) -> TurnFigures {
    let max_steer = DriverParams::car().max_steer_rad;
    let wheelbase = ego_wheelbase_m(spec);
    let n = (scene.duration_s / 0.01).round() as usize;
    let states: Vec<_> = (0..=n)
        .map(|k| scene.ego.trajectory.state_at(k as f64 * 0.01))
        .collect();
    let mut f = TurnFigures {
        yaw_rate_radps: 0.0,
        yaw_rate_limit_radps: f64::INFINITY,
        lateral_accel_mps2: 0.0,
        turn_speed_max_mps: 0.0,
        final_heading_rad: 0.0,
    };
    for s in &states {
        let forward = s.t_world_body.rotation * Vector3::x();
        let left = Vector3::new(-forward.y, forward.x, 0.0).normalize();
        let speed = s.velocity_world_mps.xy().norm();
        let yaw_rate = s.angular_velocity_body_radps.z.abs();
        f.lateral_accel_mps2 = f
            .lateral_accel_mps2
            .max(s.accel_world_mps2.dot(&left).abs());
        if yaw_rate > f.yaw_rate_radps {
            f.yaw_rate_radps = yaw_rate;
            f.yaw_rate_limit_radps = speed * max_steer.tan() / wheelbase;
        }
    }
    for s in &states {
        if s.angular_velocity_body_radps.z.abs() > 0.5 * f.yaw_rate_radps {
            f.turn_speed_max_mps = f.turn_speed_max_mps.max(s.velocity_world_mps.xy().norm());
        }
    }
    let forward = states.last().unwrap().t_world_body.rotation * Vector3::x();
    f.final_heading_rad = forward.y.atan2(forward.x);
    f
}

/// The default street with the given route, from the lane the route needs
/// (the kerb lane for a right turn, the inner lane otherwise).
fn route_spec(seed: u64, duration_s: f64, lanes: usize, route: EgoRoute) -> ScenarioSpec {
    let mut spec = ScenarioSpec::builtin("urban").unwrap();
    spec.seed = seed;
    spec.duration_s = duration_s;
    let u = spec.urban.as_mut().unwrap();
    u.lanes_per_direction = lanes;
    u.ego_route = route;
    spec.ego.lane = match route {
        EgoRoute::TurnRight | EgoRoute::UTurn => 0,
        EgoRoute::Straight | EgoRoute::TurnLeft => lanes - 1,
    };
    spec
}

fn check_turn(spec: &ScenarioSpec, scene: &Scene) -> Result<TurnFigures, TestCaseError> {
    let f = turn_figures(spec, scene);
    let route = spec.urban_params().ego_route;
    println!("seed {} {route:?}: {f:?}", spec.seed);
    // it has turned and follows the cross street away from the main street
    let heading = match route {
        EgoRoute::TurnRight => -0.5 * std::f64::consts::PI,
        EgoRoute::TurnLeft => 0.5 * std::f64::consts::PI,
        EgoRoute::UTurn => std::f64::consts::PI,
        EgoRoute::Straight => 0.0,
    };
    prop_assert!(
        wrap_angle_rad(f.final_heading_rad - heading).abs() < 3f64.to_radians(),
        "seed {} {route:?}: final heading {} deg",
        spec.seed,
        f.final_heading_rad.to_degrees()
    );
    prop_assert!(
        f.lateral_accel_mps2 <= LATERAL_ACCEL_MAX_MPS2,
        "seed {}: lateral acceleration {} m/s^2",
        spec.seed,
        f.lateral_accel_mps2
    );
    prop_assert!(
        f.yaw_rate_radps <= f.yaw_rate_limit_radps,
        "seed {}: yaw rate {} rad/s beyond the steering limit {}",
        spec.seed,
        f.yaw_rate_radps,
        f.yaw_rate_limit_radps
    );
    // a tight corner at low speed
    prop_assert!(f.turn_speed_max_mps < 6.0, "seed {}: {f:?}", spec.seed);
    let overlap = first_overlap(scene, 0.05);
    prop_assert!(overlap.is_none(), "seed {}: {overlap:?}", spec.seed);
    Ok(f)
}

#[test]
fn default_urban_ego_turns_right_at_its_first_crossing() {
    let spec = ScenarioSpec::builtin("urban").unwrap();
    assert_eq!(spec.urban_params().ego_route, EgoRoute::TurnRight);
    let scene = spec.build().unwrap();
    let f = check_turn(&spec, &scene).unwrap();
    // a real turn: a quarter circle of 8 m at a few m/s
    assert!(f.yaw_rate_radps > 0.3, "{f:?}");
    // the same seed gives the same scene
    assert_eq!(scene, spec.build().unwrap());
}

#[test]
fn urban_left_ego_turns_left_at_its_first_crossing() {
    let spec = ScenarioSpec::builtin("urban-left").unwrap();
    assert_eq!(spec.urban_params().ego_route, EgoRoute::TurnLeft);
    let scene = spec.build().unwrap();
    let f = check_turn(&spec, &scene).unwrap();
    assert!(f.yaw_rate_radps > 0.3, "{f:?}");
    // the same street as the default urban scenario's, the other way
    let right = ScenarioSpec::builtin("urban").unwrap().build().unwrap();
    assert_eq!(scene.ground, right.ground);
    assert_eq!(scene, spec.build().unwrap());
}

/// The U-turn: from the kerb lane half round into the oncoming kerb lane at
/// the first light, then back along the main street (-x), past its start.
#[test]
fn u_turn_ego_turns_round_at_its_first_crossing_and_drives_back() {
    let spec = route_spec(2, 45.0, 2, EgoRoute::UTurn);
    let scene = spec.build().unwrap();
    let f = check_turn(&spec, &scene).unwrap();
    assert!(f.yaw_rate_radps > 0.3, "{f:?}");
    // in the oncoming kerb lane (y = +1.5 lane widths) at the end, heading
    // back, and behind the point where it turned
    let u = spec.urban_params();
    let end = scene
        .ego
        .trajectory
        .pose_at(spec.duration_s)
        .translation
        .vector;
    assert!((end.y - 1.5 * u.lane_width_m).abs() < 0.3, "ends at {end}");
    let turned_at = (0..=(spec.duration_s * 10.0) as usize)
        .map(|k| {
            scene
                .ego
                .trajectory
                .pose_at(k as f64 * 0.1)
                .translation
                .vector
                .x
        })
        .fold(f64::MIN, f64::max);
    assert!(
        end.x < turned_at - 30.0,
        "ends at {end}, turned at x = {turned_at}"
    );
}

#[test]
fn straight_route_never_turns() {
    let spec = route_spec(2, 40.0, 2, EgoRoute::Straight);
    let scene = spec.build().unwrap();
    let f = turn_figures(&spec, &scene);
    assert!(f.final_heading_rad.abs() < 3f64.to_radians(), "{f:?}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 8, ..ProptestConfig::default() })]

    #[test]
    fn urban_routes_turn_without_overlaps_within_car_limits(
        seed in 0u64..1_000_000,
        lanes in 1usize..=2,
        route in 0usize..3,
    ) {
        // a U-turn needs two lanes per direction
        let route = match route {
            0 => EgoRoute::TurnLeft,
            2 if lanes == 2 => EgoRoute::UTurn,
            _ => EgoRoute::TurnRight,
        };
        let spec = route_spec(seed, 40.0, lanes, route);
        let scene = spec.build().unwrap();
        check_turn(&spec, &scene)?;
    }
}
