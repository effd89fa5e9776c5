//! Signal plans of the urban intersections: red phases of the main street,
//! the cross streets and the walk lines, and the stop lines they apply to.

use super::{
    EARLIEST_RED_S, EGO_RED_LEAD_S, LaneKind, PEDESTRIAN_LENGTH_MAX_M, STOP_LINE_SETBACK_M, Street,
    WALK_STOP_SETBACK_M,
};
use crate::scenario::common::uniform;
use crate::scenario::{ScenarioSpec, URBAN_ALL_RED_S, UrbanParams};
use crate::traffic::StopLine;
use rand_chacha::ChaCha8Rng;

/// Signal plans of all intersections (in `crossings` order) and the stop
/// lines before them on the main street's lanes. Phases are random, except
/// at the ego's first intersection, which turns red shortly before the ego
/// could arrive there at the earliest and stays red for `red_s`, so every run
/// has a stop-and-go of the ego. Pedestrians stop only where a cross street
/// has traffic.
pub(super) fn signals(
    street: &Street,
    spec: &ScenarioSpec,
    ego_speed_mps: f64,
    rng: &mut ChaCha8Rng,
) -> (Vec<SignalPlan>, Vec<StopLine>) {
    let u = &street.u;
    let half = 0.5 * u.cross_street_width_m;
    let walk_clear = walk_clearance_s(u);
    let mut plans = Vec::new();
    let mut lines = Vec::new();
    for (k, &c) in street.crossings.iter().enumerate() {
        let first_red = if k == street.ego_crossing {
            let distance = c - half - STOP_LINE_SETBACK_M - 0.5 * spec.ego.size_lwh_m[0];
            let arrival = spec.ego.depart_s
                + earliest_travel_time_s(
                    distance,
                    ego_speed_mps,
                    crate::traffic::DriverParams::car().max_accel_mps2,
                );
            (arrival - EGO_RED_LEAD_S).max(EARLIEST_RED_S)
        } else {
            uniform(rng, EARLIEST_RED_S, EARLIEST_RED_S + u.signal_cycle_s)
        };
        if street.give_way[k] {
            // no lights: the main street drives on; the cross street's give-way
            // lines get their red from the simulated main street
            plans.push(SignalPlan::default());
            continue;
        }
        let plan = signal_plan(first_red, u, spec.duration_s, walk_clear);
        let has_cross_traffic = street.cross_streets.iter().any(|x| x.crossing == k);
        for (index, lane) in street.lanes.iter().enumerate() {
            let sign = if lane.forward { -1.0 } else { 1.0 };
            let (line_x, red) = match lane.kind {
                LaneKind::Car | LaneKind::Bike => {
                    (c + sign * (half + STOP_LINE_SETBACK_M), &plan.main_red)
                }
                // pedestrians wait at the cross street's carriageway while
                // it has green
                LaneKind::Walk if has_cross_traffic => (
                    c + sign * (u.lane_width_m + WALK_STOP_SETBACK_M),
                    &plan.walk_red,
                ),
                LaneKind::Walk => continue,
            };
            let s = street.s_of(lane.forward, line_x);
            if !red.is_empty() && s > 0.0 && s < lane.path.length_m() {
                lines.push(StopLine {
                    lane: index,
                    s_m: s,
                    red_intervals_s: red.clone(),
                });
            }
        }
        plans.push(plan);
    }
    (plans, lines)
}

/// Red intervals of one intersection's approaches (none at all for an
/// intersection without lights).
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct SignalPlan {
    /// Main-street car and bike lanes.
    pub(super) main_red: Vec<(f64, f64)>,
    /// Cross-street lanes: green only inside each main red [T, T + red_s),
    /// `URBAN_ALL_RED_S` after its start and before its end.
    pub(super) cross_red: Vec<(f64, f64)>,
    /// Pedestrians along the main street (they cross the cross street): red
    /// from `walk_clear_s` before each main red to its end, so those already
    /// on the crossing leave it before the cross street's green.
    pub(super) walk_red: Vec<(f64, f64)>,
}

/// The signal plan of an intersection whose main street first turns red at
/// `first_red_s`. The cross street is red until `walk_clear_s` +
/// `URBAN_ALL_RED_S`: whoever stands inside the intersection at t = 0 has
/// left it by then.
pub(super) fn signal_plan(
    first_red_s: f64,
    u: &UrbanParams,
    duration_s: f64,
    walk_clear_s: f64,
) -> SignalPlan {
    let main_red = red_intervals(first_red_s, u.red_s, u.signal_cycle_s, duration_s);
    let earliest_green = walk_clear_s + URBAN_ALL_RED_S;
    let mut cross_red = Vec::new();
    let mut walk_red = Vec::new();
    let mut red_from = 0.0;
    for &(start, _) in &main_red {
        let end = start + u.red_s;
        walk_red.push(((start - walk_clear_s).max(0.0), end.min(duration_s)));
        let green = (
            (start + URBAN_ALL_RED_S).max(earliest_green),
            (end - URBAN_ALL_RED_S).min(duration_s),
        );
        if green.1 - green.0 >= 1.0 {
            if green.0 > red_from {
                cross_red.push((red_from, green.0));
            }
            red_from = green.1;
        }
    }
    // red to beyond the end of the run
    cross_red.push((red_from, duration_s + URBAN_ALL_RED_S));
    SignalPlan {
        main_red,
        cross_red,
        walk_red,
    }
}

/// How long a pedestrian who could not stop at the walk red needs to cross a
/// cross street's carriageway: the slowest walking speed over the carriageway,
/// both setbacks and a body length, plus the time to reach the line.
pub(super) fn walk_clearance_s(u: &UrbanParams) -> f64 {
    let crossing = 2.0 * u.lane_width_m + 2.0 * WALK_STOP_SETBACK_M + PEDESTRIAN_LENGTH_MAX_M;
    let decel = crate::traffic::DriverParams::pedestrian().comfortable_decel_mps2;
    crossing / u.pedestrian_speed_min_mps + u.pedestrian_speed_max_mps / (2.0 * decel)
}

/// Red intervals [first + j cycle, first + j cycle + red) inside [0, duration].
pub(super) fn red_intervals(
    first_s: f64,
    red_s: f64,
    cycle_s: f64,
    duration_s: f64,
) -> Vec<(f64, f64)> {
    if red_s <= 0.0 {
        return Vec::new();
    }
    (0..)
        .map(|j| first_s + j as f64 * cycle_s)
        .take_while(|&t| t < duration_s)
        .map(|t| (t, (t + red_s).min(duration_s)))
        .collect()
}

/// Time to cover `distance_m` from rest accelerating at `accel` up to `speed`.
pub(super) fn earliest_travel_time_s(distance_m: f64, speed_mps: f64, accel_mps2: f64) -> f64 {
    let accel_distance = speed_mps * speed_mps / (2.0 * accel_mps2);
    if distance_m <= accel_distance {
        (2.0 * distance_m / accel_mps2).sqrt()
    } else {
        speed_mps / accel_mps2 + (distance_m - accel_distance) / speed_mps
    }
}
