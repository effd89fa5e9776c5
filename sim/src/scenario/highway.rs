//! Highway generator: one carriageway of 3-5 lanes, a long straight followed
//! by gentle alternating curves, guard rails on both sides, sparse light
//! poles and signs, and 20-50 cars and trucks at highway speeds with lane
//! changes. The ego changes lanes too, at the requested times once the
//! target lane's gap is safe (the traffic model's own lane-change logic).
//! The long straight with parallel rails is the LiDAR-degenerate case.
//! Optionally the ego starts on an on-ramp's acceleration lane and merges
//! (`[highway.on_ramp]`), leaves by an off-ramp that curves away from the
//! carriageway (`[highway.off_ramp]`), and jam heads ahead of it make the
//! traffic stop and go (`[highway.jam]`).

use super::common::{
    beside, cuboid_between, draw_body, ego_vehicle, generate_ground, pole, run_traffic, uniform,
    upright_static,
};
use super::roadside::{CrossSection, roadside};
use super::{
    HIGHWAY_EGO_FREE_SLOTS, HighwayParams, OffRampParams, ScenarioError, ScenarioSpec,
    highway_min_spacing_m, traffic_error,
};
use crate::scene::{Ego, Scene, Shape, StaticKind, StaticObject};
use crate::traffic::{JamFront, LaneChange, LanePath, PathPiece, TrafficSpec, VehicleSpec};
use limot_estimator::input::ObjectClass;
use nalgebra::{Point2, Vector3};
use rand::RngExt;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

/// Road before the first spawn slot, m.
const START_MARGIN_M: f64 = 30.0;
/// Road after the farthest point any vehicle can reach: vehicles brake for
/// the end of a lane (IDM standing leader), so leave more than a braking
/// distance at 33 m/s plus headway.
const END_MARGIN_M: f64 = 400.0;
/// Shoulders between the outer lane edges and the guard rails, m.
const RIGHT_SHOULDER_M: f64 = 3.0;
const LEFT_SHOULDER_M: f64 = 1.2;
const RAIL_WIDTH_M: f64 = 0.3;
const RAIL_HEIGHT_M: f64 = 0.75;
/// Bottom of a rail's beam when it stands on posts, m.
const RAIL_BEAM_BOTTOM_M: f64 = 0.45;
/// Light poles stand this far outside the right rail.
const POLE_OUTSIDE_RAIL_M: f64 = 1.5;
const POLE_RADIUS_M: f64 = 0.12;
const POLE_HEIGHT_M: f64 = 10.0;
/// Every this many pole spacings (on average) a sign stands between two poles.
const SIGN_EVERY_POLES: f64 = 8.0;
/// Lengths of the curves and of the straights between them, m.
const CURVE_LENGTH_M: (f64, f64) = (250.0, 600.0);
const STRAIGHT_BETWEEN_CURVES_M: (f64, f64) = (150.0, 400.0);
/// Lane-change requests start after this and stop this long before the end, s.
const LANE_CHANGE_START_S: f64 = 3.0;
const LANE_CHANGE_END_MARGIN_S: f64 = 10.0;
/// Minimum time between two lane-change requests of one vehicle, s.
const LANE_CHANGE_SPACING_S: f64 = 8.0;
/// The off-ramp turns away from the carriageway by this angle, rad (30 deg).
const OFF_RAMP_TURN_RAD: f64 = std::f64::consts::FRAC_PI_6;
/// The ego keeps speed^2 * curvature near this on an off-ramp's curve, m/s^2.
const OFF_RAMP_LATERAL_ACCEL_MPS2: f64 = 1.5;
/// Past the diverge point by this much, the ego must be on the ramp, m.
const OFF_RAMP_CHECK_AFTER_M: f64 = 30.0;

/// The ego's off-ramp: its lane's index among the traffic lanes (the
/// deceleration lane beside lane 0, then the ramp's curve and straight; the
/// last lane) and where it leaves the carriageway.
struct OffRamp {
    lane: usize,
    /// Arc length of the diverge point, on the lane and on the reference line.
    diverge_s_m: f64,
}

/// The whole highway scene for a validated spec.
pub(crate) fn build(spec: &ScenarioSpec, rng: &mut ChaCha8Rng) -> Result<Scene, ScenarioError> {
    let (ground, statics, traffic, exit) = layout(spec, rng)?;
    let (agents, ego) = run_traffic(spec, &ground, &|_, _| 0.0, &traffic)?;
    if let (Some(exit), Some(params)) = (&exit, &spec.highway_params().off_ramp) {
        check_ego_took_the_exit(spec, &traffic.lanes, exit, params, &ego)?;
    }
    Ok(Scene {
        duration_s: spec.duration_s,
        ground,
        statics,
        agents,
        ego,
    })
}

/// The road and everything on it before the traffic runs: ground, statics,
/// and the traffic spec (lanes, vehicles with their lane changes, the ego last).
type Layout = (
    crate::scene::Ground,
    Vec<StaticObject>,
    TrafficSpec,
    Option<OffRamp>,
);

fn layout(spec: &ScenarioSpec, rng: &mut ChaCha8Rng) -> Result<Layout, ScenarioError> {
    let h = spec.highway_params();
    // the main street and the highway's initial straight run along +x through the origin
    let ground = generate_ground(rng, &spec.ground, spec.seed, (Point2::origin(), 0.0));
    let ego_s = START_MARGIN_M + h.spawn_behind_m;
    let road_length = ego_s + h.spawn_ahead_m + h.speed_max_mps * spec.duration_s + END_MARGIN_M;
    let pieces = road_pieces(&h, road_length, rng);
    let path = |offset_m| {
        LanePath::from_pieces(Point2::origin(), 0.0, &pieces, offset_m)
            .map_err(|e| traffic_error(spec, e))
    };
    let reference = path(0.0)?;
    let mut lanes = (0..h.lanes)
        .map(|i| path(lane_offset_m(&h, i)))
        .collect::<Result<Vec<_>, _>>()?;
    // the acceleration lane (index h.lanes) to where the on-ramp ends
    if let Some(ramp) = &h.on_ramp {
        let ramp_pieces = pieces_up_to(&pieces, ego_s + ramp.length_m);
        lanes.push(
            LanePath::from_pieces(Point2::origin(), 0.0, &ramp_pieces, ramp_lane_offset_m(&h))
                .map_err(|e| traffic_error(spec, e))?,
        );
    }

    // the off-ramp's lane after the acceleration lane (if any)
    let exit = match &h.off_ramp {
        None => None,
        Some(params) => {
            let diverge_s_m = ego_s + params.diverge_ahead_m;
            lanes.push(
                off_ramp_lane(&h, &pieces, diverge_s_m, road_length, params)
                    .map_err(|e| traffic_error(spec, e))?,
            );
            Some(OffRamp {
                lane: lanes.len() - 1,
                diverge_s_m,
            })
        }
    };

    let mut statics = guard_rails(&h, &reference, &ground);
    statics.extend(poles_and_signs(&h, &reference, &ground, rng));
    // the roadside where the ego's LiDAR can see it
    let view = spec.lidar.max_range_m + 30.0;
    let reach = ego_s + h.speed_max_mps.max(spec.ego_speed_mps()) * spec.duration_s;
    statics.extend(roadside(
        &h,
        &reference,
        &ground,
        &cross_section(&h),
        (ego_s - view, reach + view),
        spec.seed,
    ));
    if let Some(exit) = &exit {
        clear_off_ramp(&h, &lanes[exit.lane], exit.diverge_s_m, &mut statics);
        let rail = off_ramp_rail(
            &h,
            &lanes[exit.lane],
            exit.diverge_s_m,
            reach + view,
            &ground,
        );
        statics.extend(rail);
    }

    let mut vehicles = place_vehicles(&h, spec.ego.lane, ego_s, rng);
    let fronts = jam_fronts(&h, ego_s);
    // nobody starts so close behind (or beside) a head that it cannot follow it
    let clear_m = highway_min_spacing_m(&h);
    vehicles.retain(|v| {
        fronts
            .iter()
            .all(|f| f.lane != v.lane || (v.start_s_m - f.start_s_m).abs() >= clear_m)
    });
    // ids stay 1..=N in placement order
    for (k, v) in vehicles.iter_mut().enumerate() {
        v.id = k as u32 + 1;
    }
    add_lane_changes(&h, spec.duration_s, &mut vehicles, rng);
    let start_lane = if h.on_ramp.is_some() {
        h.lanes
    } else {
        spec.ego.lane
    };
    let mut ego = ego_vehicle(&spec.ego, start_lane, ego_s, spec.ego_speed_mps());
    let merge = h.on_ramp.iter().map(|ramp| LaneChange {
        t_s: ramp.merge_request_s,
        to_lane: spec.ego.lane,
        cooperative: true,
    });
    let leave = h.off_ramp.iter().zip(&exit).map(|(ramp, exit)| LaneChange {
        t_s: ramp.exit_request_s,
        to_lane: exit.lane,
        cooperative: true,
    });
    // traffic makes room for the ego's changes (the route must happen)
    ego.lane_changes = merge
        .chain(h.ego_lane_changes.iter().map(|change| LaneChange {
            cooperative: true,
            ..change.clone()
        }))
        .chain(leave)
        .collect();
    if exit.is_some() {
        // it slows down for the ramp's curve
        ego.driver.curve_lateral_accel_mps2 = Some(OFF_RAMP_LATERAL_ACCEL_MPS2);
    }
    vehicles.push(ego);
    let traffic = TrafficSpec {
        lanes,
        vehicles,
        stop_lines: Vec::new(),
        jam_fronts: fronts,
        duration_s: spec.duration_s,
    };
    Ok((ground, statics, traffic, exit))
}

/// The off-ramp's lane: the deceleration lane one lane width right of lane 0
/// up to the diverge point, then a right curve of the ramp's radius through
/// `OFF_RAMP_TURN_RAD` and a straight to the road's end.
fn off_ramp_lane(
    h: &HighwayParams,
    pieces: &[PathPiece],
    diverge_s_m: f64,
    road_length_m: f64,
    params: &OffRampParams,
) -> Result<LanePath, crate::traffic::TrafficError> {
    let offset_m = ramp_lane_offset_m(h);
    let mut ramp = pieces_up_to(pieces, diverge_s_m);
    // a lane `offset_m` (< 0) right of the reference line's curve has
    // radius `reference - |offset_m|`: the reference's curve is that much wider
    let reference_radius_m = params.curve_radius_m - offset_m;
    ramp.push(PathPiece::Arc {
        length_m: OFF_RAMP_TURN_RAD * reference_radius_m,
        curvature_1pm: -1.0 / reference_radius_m,
    });
    ramp.push(PathPiece::Straight {
        length_m: (road_length_m - diverge_s_m).max(END_MARGIN_M),
    });
    LanePath::from_pieces(Point2::origin(), 0.0, &ramp, offset_m)
}

/// Half the ramp's clear corridor: its lane, shoulder and rail, and a margin, m.
fn off_ramp_clearance_m(h: &HighwayParams) -> f64 {
    0.5 * h.lane_width_m + RIGHT_SHOULDER_M + RAIL_WIDTH_M + 0.5
}

/// Removes the statics in the ramp's way past its diverge point (the gore):
/// everything whose footprint circle comes within the ramp's clear corridor.
/// A thing and what it carries go together (a crown stands over its trunk,
/// a board over its pole, a gantry's beam or an overpass's deck reaches over
/// the carriageway and is wider than the corridor's distance to it).
fn clear_off_ramp(
    h: &HighwayParams,
    ramp: &LanePath,
    diverge_s_m: f64,
    statics: &mut Vec<StaticObject>,
) {
    let clear_m = off_ramp_clearance_m(h);
    statics.retain(|s| {
        let radius_m = match s.shape {
            Shape::Cuboid { half_extents_m } => half_extents_m.xy().norm(),
            Shape::Cylinder { radius_m, .. } | Shape::Ball { radius_m } => radius_m,
        };
        let c = s.t_world_object.translation.vector;
        match ramp.project_near(&Point2::new(c.x, c.y), clear_m + radius_m + 1.0) {
            Some((s_m, d_m)) => s_m < diverge_s_m - radius_m || d_m.abs() >= clear_m + radius_m,
            None => true,
        }
    });
}

/// The guard rail along the ramp's right side, from the diverge point to
/// `end_s_m` (or the ramp's end).
fn off_ramp_rail(
    h: &HighwayParams,
    ramp: &LanePath,
    diverge_s_m: f64,
    end_s_m: f64,
    ground: &crate::scene::Ground,
) -> Vec<StaticObject> {
    let offset = -(0.5 * h.lane_width_m + RIGHT_SHOULDER_M + 0.5 * RAIL_WIDTH_M);
    let end = end_s_m.min(ramp.length_m());
    let mut rails = Vec::new();
    let mut s0 = diverge_s_m;
    while s0 + h.guard_rail_segment_m <= end {
        rails.push(rail_segment(h, ground, ramp, s0, offset));
        s0 += h.guard_rail_segment_m;
    }
    rails
}

/// The ego, once past the diverge point, must be on the ramp: if it had not
/// changed into the deceleration lane by then it drove on along the
/// carriageway, which the scenario did not ask for.
fn check_ego_took_the_exit(
    spec: &ScenarioSpec,
    lanes: &[LanePath],
    exit: &OffRamp,
    params: &OffRampParams,
    ego: &Ego,
) -> Result<(), ScenarioError> {
    let end = ego.trajectory.pose_at(spec.duration_s).translation.vector;
    let end = Point2::new(end.x, end.y);
    let (s_m, _) = lanes[0].project(&end);
    let (_, off_ramp_m) = lanes[exit.lane].project(&end);
    if s_m > exit.diverge_s_m + OFF_RAMP_CHECK_AFTER_M && off_ramp_m.abs() > 1.5 {
        return Err(ScenarioError::Build {
            scenario: spec.name.clone(),
            message: format!(
                "the ego passed the off-ramp's diverge point (highway.off_ramp.diverge_ahead_m \
                 = {} m) before changing into its deceleration lane (requested at \
                 highway.off_ramp.exit_request_s = {} s): request the exit earlier or move \
                 the diverge point further ahead",
                params.diverge_ahead_m, params.exit_request_s
            ),
        });
    }
    Ok(())
}

/// The jam's heads (if any), one per lane.
fn jam_fronts(h: &HighwayParams, ego_s_m: f64) -> Vec<JamFront> {
    h.jam
        .iter()
        .flat_map(|jam| (0..h.lanes).map(move |lane| jam.front(lane, ego_s_m)))
        .collect()
}

/// Pieces of the carriageway centre line: the initial straight, then curves
/// of random radius, mostly alternating in direction, separated by straights,
/// until the road is at least `length_m` long.
fn road_pieces(h: &HighwayParams, length_m: f64, rng: &mut ChaCha8Rng) -> Vec<PathPiece> {
    let mut pieces = Vec::new();
    let mut total = 0.0;
    if h.straight_length_m > 0.0 {
        pieces.push(PathPiece::Straight {
            length_m: h.straight_length_m,
        });
        total += h.straight_length_m;
    }
    let mut left = rng.random_bool(0.5);
    while total < length_m {
        let radius = uniform(rng, h.curve_radius_min_m, h.curve_radius_max_m);
        let curve = uniform(rng, CURVE_LENGTH_M.0, CURVE_LENGTH_M.1);
        let sign = if left { 1.0 } else { -1.0 };
        pieces.push(PathPiece::Arc {
            length_m: curve,
            curvature_1pm: sign / radius,
        });
        let straight = uniform(
            rng,
            STRAIGHT_BETWEEN_CURVES_M.0,
            STRAIGHT_BETWEEN_CURVES_M.1,
        );
        pieces.push(PathPiece::Straight { length_m: straight });
        total += curve + straight;
        left = if rng.random_bool(0.8) { !left } else { left };
    }
    pieces
}

/// Lateral offset (+ = left) of lane `i` (0 = rightmost) from the centre line.
fn lane_offset_m(h: &HighwayParams, i: usize) -> f64 {
    (i as f64 + 0.5 - 0.5 * h.lanes as f64) * h.lane_width_m
}

/// Lateral offset of the ramps' acceleration or deceleration lane: one lane
/// width right of lane 0.
fn ramp_lane_offset_m(h: &HighwayParams) -> f64 {
    lane_offset_m(h, 0) - h.lane_width_m
}

/// Distance from the centre line to the right edge of the paved lanes:
/// the carriageway's, and the ramps' acceleration or deceleration lane
/// beside it.
fn right_edge_m(h: &HighwayParams) -> f64 {
    let ramp = if h.on_ramp.is_some() || h.off_ramp.is_some() {
        1.0
    } else {
        0.0
    };
    (0.5 * h.lanes as f64 + ramp) * h.lane_width_m
}

/// The leading `length_m` of a path's pieces (the last one cut short).
fn pieces_up_to(pieces: &[PathPiece], length_m: f64) -> Vec<PathPiece> {
    let mut out = Vec::new();
    let mut left = length_m;
    for piece in pieces {
        if left <= 0.0 {
            break;
        }
        out.push(piece.cut_to(left));
        left -= piece.length_m();
    }
    out
}

/// Outer faces of the two rails.
fn cross_section(h: &HighwayParams) -> CrossSection {
    let half_road = 0.5 * h.lanes as f64 * h.lane_width_m;
    CrossSection {
        right_rail_m: -(right_edge_m(h) + RIGHT_SHOULDER_M + RAIL_WIDTH_M),
        left_rail_m: half_road + LEFT_SHOULDER_M + RAIL_WIDTH_M,
    }
}

/// Guard rail segments along both edges, each pitched to follow the ground.
fn guard_rails(
    h: &HighwayParams,
    reference: &LanePath,
    ground: &crate::scene::Ground,
) -> Vec<StaticObject> {
    let half_road = 0.5 * h.lanes as f64 * h.lane_width_m;
    let offsets = [
        -(right_edge_m(h) + RIGHT_SHOULDER_M + 0.5 * RAIL_WIDTH_M),
        half_road + LEFT_SHOULDER_M + 0.5 * RAIL_WIDTH_M,
    ];
    let segments = (reference.length_m() / h.guard_rail_segment_m).floor() as usize;
    let mut rails = Vec::with_capacity(2 * segments);
    for offset in offsets {
        for k in 0..segments {
            let s0 = k as f64 * h.guard_rail_segment_m;
            rails.push(rail_segment(h, ground, reference, s0, offset));
        }
    }
    rails
}

/// One guard rail segment beside `path` from `s0_m` on, `offset_m` from it:
/// a beam on posts (the posts are roadside) or, without posts, solid down to
/// the ground.
fn rail_segment(
    h: &HighwayParams,
    ground: &crate::scene::Ground,
    path: &LanePath,
    s0_m: f64,
    offset_m: f64,
) -> StaticObject {
    let base = if h.rail_post_spacing_m > 0.0 {
        RAIL_BEAM_BOTTOM_M
    } else {
        0.0
    };
    cuboid_between(
        ground,
        StaticKind::GuardRail,
        beside(path, s0_m, offset_m),
        beside(path, s0_m + h.guard_rail_segment_m, offset_m),
        RAIL_WIDTH_M,
        (base, RAIL_HEIGHT_M),
    )
}

/// Light poles outside the right rail at a fixed spacing, and now and then a
/// sign board on a short pole half-way between two light poles.
fn poles_and_signs(
    h: &HighwayParams,
    reference: &LanePath,
    ground: &crate::scene::Ground,
    rng: &mut ChaCha8Rng,
) -> Vec<StaticObject> {
    let offset = -(right_edge_m(h) + RIGHT_SHOULDER_M + RAIL_WIDTH_M + POLE_OUTSIDE_RAIL_M);
    let count = (reference.length_m() / h.pole_spacing_m).floor() as usize;
    let mut out = Vec::new();
    for k in 0..count {
        let s = k as f64 * h.pole_spacing_m;
        out.push(pole(
            ground,
            beside(reference, s, offset),
            POLE_RADIUS_M,
            POLE_HEIGHT_M,
        ));
        let s_sign = s + 0.5 * h.pole_spacing_m;
        if s_sign < reference.length_m() && rng.random_bool(1.0 / SIGN_EVERY_POLES) {
            let at = beside(reference, s_sign, offset);
            let yaw = reference.heading_at(s_sign);
            out.push(pole(ground, at, POLE_RADIUS_M, 4.0));
            // board 3 m wide, 2 m tall, facing the traffic, bottom at 3.5 m
            out.push(upright_static(
                ground,
                StaticKind::Sign,
                Shape::Cuboid {
                    half_extents_m: Vector3::new(0.05, 1.5, 1.0),
                },
                at,
                3.5,
                yaw,
            ));
        }
    }
    out
}

/// Cars and trucks in spawn slots: each lane of the spawn zone is cut into
/// slots at least `highway_min_spacing_m` long, the slots around the ego in
/// its lane stay free (nobody starts right behind the standing ego), and
/// each vehicle takes a random free slot with a random jitter inside it.
/// Trucks prefer the two rightmost lanes. Ids are 1..=N.
fn place_vehicles(
    h: &HighwayParams,
    ego_lane: usize,
    ego_s: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<VehicleSpec> {
    let span = h.spawn_behind_m + h.spawn_ahead_m;
    let min_spacing = highway_min_spacing_m(h);
    let per_lane = (span / min_spacing).floor() as usize;
    if per_lane == 0 || h.vehicles == 0 {
        return Vec::new();
    }
    let slot_len = span / per_lane as f64;
    let first_s = ego_s - h.spawn_behind_m;
    // each lane's slot grid is shifted by a random phase so that vehicles do
    // not line up side by side across lanes
    let phase: Vec<f64> = (0..h.lanes).map(|_| uniform(rng, 0.0, 1.0)).collect();
    let centre = |lane: usize, i: usize| first_s + (i as f64 + phase[lane]) * slot_len;
    let mut slots: Vec<(usize, usize)> = (0..h.lanes)
        .flat_map(|lane| (0..per_lane).map(move |i| (lane, i)))
        .filter(|&(lane, i)| {
            let c = centre(lane, i);
            lane != ego_lane || !(ego_s - 2.0 * slot_len..=ego_s + slot_len).contains(&c)
        })
        .collect();
    debug_assert!(
        slots.len() + HIGHWAY_EGO_FREE_SLOTS >= per_lane * h.lanes,
        "the ego's free zone takes at most HIGHWAY_EGO_FREE_SLOTS slots"
    );
    slots.shuffle(rng);
    let trucks = (h.truck_fraction * h.vehicles as f64).round() as usize;
    let jitter = 0.5 * (slot_len - min_spacing).max(0.0);
    let mut vehicles = Vec::with_capacity(h.vehicles);
    for k in 0..h.vehicles.min(slots.len()) {
        let class = if k < trucks {
            ObjectClass::Truck
        } else {
            ObjectClass::Car
        };
        let pick = match class {
            ObjectClass::Truck => slots.iter().position(|&(lane, _)| lane <= 1).unwrap_or(0),
            _ => 0,
        };
        let (lane, i) = slots.remove(pick);
        let (size, driver) = draw_body(rng, class);
        let speed_max = match class {
            ObjectClass::Truck => h.truck_speed_max_mps.min(h.speed_max_mps),
            _ => h.speed_max_mps,
        };
        let speed = uniform(rng, h.speed_min_mps, speed_max);
        vehicles.push(VehicleSpec {
            id: k as u32 + 1,
            class,
            size_lwh_m: size,
            lane,
            start_s_m: centre(lane, i) + uniform(rng, -jitter, jitter),
            start_speed_mps: speed,
            desired_speed_mps: speed,
            depart_s: 0.0,
            lane_changes: Vec::new(),
            driver,
        });
    }
    vehicles
}

/// Spreads `lane_changes` requests over the vehicles (round robin over a
/// shuffled order) and over time; each request moves one lane left or right
/// of where the previous request left the vehicle, trucks staying in the
/// three rightmost lanes.
fn add_lane_changes(
    h: &HighwayParams,
    duration_s: f64,
    vehicles: &mut [VehicleSpec],
    rng: &mut ChaCha8Rng,
) {
    let t_end = duration_s - LANE_CHANGE_END_MARGIN_S;
    if vehicles.is_empty() || t_end <= LANE_CHANGE_START_S {
        return;
    }
    let mut order: Vec<usize> = (0..vehicles.len()).collect();
    order.shuffle(rng);
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); vehicles.len()];
    for r in 0..h.lane_changes {
        times[order[r % order.len()]].push(uniform(rng, LANE_CHANGE_START_S, t_end));
    }
    for (vehicle, mut ts) in vehicles.iter_mut().zip(times) {
        ts.sort_by(f64::total_cmp);
        let top_lane = match vehicle.class {
            ObjectClass::Truck => 2.min(h.lanes - 1),
            _ => h.lanes - 1,
        };
        let mut lane = vehicle.lane;
        let mut last_t = f64::NEG_INFINITY;
        for t in ts {
            let t = t.max(last_t + LANE_CHANGE_SPACING_S);
            if t > t_end {
                break;
            }
            let to_lane = if lane == 0 {
                1
            } else if lane >= top_lane {
                lane - 1
            } else if rng.random_bool(0.5) {
                lane + 1
            } else {
                lane - 1
            };
            vehicle.lane_changes.push(LaneChange {
                t_s: t,
                to_lane,
                cooperative: false,
            });
            lane = to_lane;
            last_t = t;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use limot_estimator::geometry::wrap_angle_rad as wrap;
    use rand::SeedableRng;

    #[test]
    fn spawned_vehicles_keep_safe_gaps_and_the_ego_zone_free() {
        let h = HighwayParams {
            vehicles: 40,
            ..HighwayParams::default()
        };
        for seed in 0..10 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let ego_s = START_MARGIN_M + h.spawn_behind_m;
            let vehicles = place_vehicles(&h, 1, ego_s, &mut rng);
            assert_eq!(vehicles.len(), 40);
            let trucks = vehicles
                .iter()
                .filter(|v| v.class == ObjectClass::Truck)
                .count();
            assert_eq!(trucks, 8);
            for (a, va) in vehicles.iter().enumerate() {
                assert_eq!(va.id, a as u32 + 1);
                assert!((h.speed_min_mps..=h.speed_max_mps).contains(&va.desired_speed_mps));
                if va.lane == 1 {
                    let behind = ego_s - va.start_s_m;
                    assert!(!(-60.0..=140.0).contains(&behind), "{behind}");
                }
                for vb in &vehicles[a + 1..] {
                    if va.lane == vb.lane {
                        let d = (va.start_s_m - vb.start_s_m).abs();
                        assert!(d >= highway_min_spacing_m(&h) - 1e-9, "{d}");
                    }
                }
            }
        }
    }

    #[test]
    fn lane_change_requests_are_adjacent_spaced_and_in_time() {
        let h = HighwayParams {
            lane_changes: 60,
            ..HighwayParams::default()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut vehicles = place_vehicles(&h, 1, 230.0, &mut rng);
        add_lane_changes(&h, 60.0, &mut vehicles, &mut rng);
        let total: usize = vehicles.iter().map(|v| v.lane_changes.len()).sum();
        assert!(total >= 40, "{total} of 60 requests kept");
        for v in &vehicles {
            let mut lane = v.lane;
            let mut last = f64::NEG_INFINITY;
            for c in &v.lane_changes {
                assert_eq!(c.to_lane.abs_diff(lane), 1);
                assert!(c.to_lane < h.lanes);
                if v.class == ObjectClass::Truck {
                    assert!(c.to_lane <= 2);
                }
                assert!(c.t_s >= last + LANE_CHANGE_SPACING_S - 1e-9);
                assert!((LANE_CHANGE_START_S..=60.0 - LANE_CHANGE_END_MARGIN_S).contains(&c.t_s));
                lane = c.to_lane;
                last = c.t_s;
            }
        }
    }

    /// (time, from lane, to lane) of every lane switch of the ego's track.
    fn ego_lane_switches(spec: &ScenarioSpec) -> Vec<(f64, usize, usize)> {
        let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
        let (_, _, traffic, _) = layout(spec, &mut rng).unwrap();
        let tracks = crate::traffic::simulate_traffic(&traffic).unwrap();
        let ego = tracks.last().unwrap();
        assert_eq!(ego.id, super::super::common::EGO_TRAFFIC_ID);
        ego.samples
            .windows(2)
            .enumerate()
            .filter(|(_, w)| w[0].lane != w[1].lane)
            .map(|(k, w)| (ego.t0_s + (k + 1) as f64 * ego.dt_s, w[0].lane, w[1].lane))
            .collect()
    }

    /// The default route: the ego merges from the on-ramp within seconds of
    /// its request, well before the ramp ends (which it reaches from a
    /// standstill after ~15 s), then overtakes on the left and returns, each
    /// change within seconds of its request.
    #[test]
    fn the_default_ego_merges_overtakes_and_returns_within_seconds_of_each_request() {
        for seed in 1..=6 {
            let mut spec = ScenarioSpec::builtin("highway").unwrap();
            spec.seed = seed;
            spec.duration_s = 40.0;
            let h = spec.highway_params();
            let ramp = h.on_ramp.clone().unwrap();
            let switches = ego_lane_switches(&spec);
            let requests = &h.ego_lane_changes;
            assert_eq!(
                switches.len(),
                1 + requests.len(),
                "seed {seed}: {switches:?}"
            );
            let (t_merge, from, to) = switches[0];
            assert_eq!((from, to), (h.lanes, 0), "seed {seed}");
            assert!(
                (ramp.merge_request_s..ramp.merge_request_s + 6.0).contains(&t_merge),
                "seed {seed}: merged at {t_merge} s"
            );
            let mut lane = spec.ego.lane;
            for (&(t_s, from, to), request) in switches[1..].iter().zip(requests) {
                assert_eq!((from, to), (lane, request.to_lane), "seed {seed}");
                // traffic makes room within a few seconds of the request
                assert!(
                    (request.t_s..request.t_s + 5.0).contains(&t_s),
                    "seed {seed}: change to lane {to} at {t_s} s, requested at {} s",
                    request.t_s
                );
                lane = to;
            }
        }
    }

    #[test]
    fn the_on_ramp_is_paved_beside_the_carriageway_and_ends_ahead_of_the_ego() {
        let spec = ScenarioSpec::builtin("highway").unwrap();
        let h = spec.highway_params();
        let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
        let (_, _, traffic, _) = layout(&spec, &mut rng).unwrap();
        assert_eq!(traffic.lanes.len(), h.lanes + 1);
        let ramp = &traffic.lanes[h.lanes];
        let ego = traffic.vehicles.last().unwrap();
        assert_eq!(ego.lane, h.lanes);
        let end = ego.start_s_m + h.on_ramp.as_ref().unwrap().length_m;
        assert!((ramp.length_m() - end).abs() < 1e-6);
        // one lane width right of lane 0, and the rail a lane further out
        let lane0 = &traffic.lanes[0];
        let gap = (ramp.point_at(100.0) - lane0.point_at(100.0)).norm();
        assert!((gap - h.lane_width_m).abs() < 1e-6);
        let plain = HighwayParams {
            on_ramp: None,
            ..h.clone()
        };
        let shift = cross_section(&plain).right_rail_m - cross_section(&h).right_rail_m;
        assert!((shift - h.lane_width_m).abs() < 1e-12);
    }

    /// The off-ramp's lane runs one lane width right of lane 0 up to the
    /// diverge point, then curves right with the ramp's radius through 30
    /// degrees; past the diverge point nothing stands in the ramp's corridor
    /// but its own rail, which lines its right side.
    #[test]
    fn the_off_ramp_curves_away_through_a_cleared_gore() {
        let spec = ScenarioSpec::builtin("highway-exit").unwrap();
        let h = spec.highway_params();
        let params = h.off_ramp.clone().unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
        let (_, statics, traffic, exit) = layout(&spec, &mut rng).unwrap();
        let exit = exit.unwrap();
        assert_eq!(traffic.lanes.len(), h.lanes + 1);
        let ramp = &traffic.lanes[h.lanes];
        assert_eq!(exit.lane, h.lanes);
        let ego = traffic.vehicles.last().unwrap();
        assert_eq!(ego.lane, 0);
        let leave = ego.lane_changes.last().unwrap();
        assert_eq!((leave.t_s, leave.to_lane), (params.exit_request_s, h.lanes));
        assert!((exit.diverge_s_m - (ego.start_s_m + params.diverge_ahead_m)).abs() < 1e-9);
        // parallel before the diverge point
        let lane0 = &traffic.lanes[0];
        for s_m in [100.0, exit.diverge_s_m - 1.0] {
            let gap = (ramp.point_at(s_m) - lane0.point_at(s_m)).norm();
            assert!((gap - h.lane_width_m).abs() < 1e-6, "{gap} at {s_m}");
        }
        // the curve: heading turns right by 30 deg over radius x 30 deg
        let arc_m = params.curve_radius_m * OFF_RAMP_TURN_RAD;
        let turned =
            wrap(ramp.heading_at(exit.diverge_s_m + arc_m) - ramp.heading_at(exit.diverge_s_m));
        assert!(
            (turned + OFF_RAMP_TURN_RAD).abs() < 1e-3,
            "turned {turned} rad"
        );
        let mid = exit.diverge_s_m + 0.5 * arc_m;
        let rate = wrap(ramp.heading_at(mid + 1.0) - ramp.heading_at(mid - 1.0)) / 2.0;
        assert!(
            (rate + 1.0 / params.curve_radius_m).abs() < 1e-4,
            "curvature {rate}"
        );
        // the gore: nothing but the ramp's rail within its corridor
        let clear_m = 0.5 * h.lane_width_m + RIGHT_SHOULDER_M;
        let mut ramp_rails = 0;
        for st in &statics {
            let c = st.t_world_object.translation.vector;
            let (s_m, d_m) = ramp.project(&Point2::new(c.x, c.y));
            if s_m > exit.diverge_s_m + 1.0 && s_m < ramp.length_m() - 1.0 {
                if st.kind == StaticKind::GuardRail && d_m < 0.0 && d_m > -(clear_m + RAIL_WIDTH_M)
                {
                    ramp_rails += 1;
                    continue;
                }
                assert!(
                    d_m.abs() >= clear_m,
                    "{:?} at {s_m}, {d_m} from the ramp",
                    st.kind
                );
            }
        }
        assert!(
            ramp_rails >= 20,
            "{ramp_rails} rail segments along the ramp"
        );
    }

    /// Over seeds the ego ends on the ramp, heading 30 deg right of the
    /// carriageway; an exit requested too late is a build error naming it.
    #[test]
    fn the_ego_leaves_by_the_off_ramp_and_a_late_request_is_an_error() {
        for seed in 1..=4 {
            let mut spec = ScenarioSpec::builtin("highway-exit").unwrap();
            spec.seed = seed;
            spec.duration_s = 36.0;
            let scene = spec.build().unwrap();
            let end = scene.ego.trajectory.pose_at(spec.duration_s);
            let forward = end.rotation * Vector3::x();
            let heading = forward.y.atan2(forward.x);
            assert!(
                (heading + OFF_RAMP_TURN_RAD).abs() < 0.03,
                "seed {seed}: heading {heading} rad at the end"
            );
        }
        let mut spec = ScenarioSpec::builtin("highway-exit").unwrap();
        spec.duration_s = 40.0;
        spec.highway
            .as_mut()
            .unwrap()
            .off_ramp
            .as_mut()
            .unwrap()
            .exit_request_s = 35.0;
        let err = spec.build().unwrap_err().to_string();
        assert!(err.contains("highway.off_ramp.exit_request_s"), "{err}");
    }

    #[test]
    fn in_the_jam_the_ego_and_its_neighbours_stop_and_go_in_waves() {
        for seed in 1..=4 {
            let mut spec = ScenarioSpec::builtin("highway-jam").unwrap();
            spec.seed = seed;
            let jam = spec.highway_params().jam.unwrap();
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let (_, _, traffic, _) = layout(&spec, &mut rng).unwrap();
            let tracks = crate::traffic::simulate_traffic(&traffic).unwrap();
            // (stands, top speed once in the jam) of a track
            let waves = |track: &crate::traffic::PlanarTrack| {
                let (mut stands, mut standing, mut top) = (0, false, 0.0f64);
                for (k, p) in track.samples.iter().enumerate() {
                    let t_s = track.t0_s + k as f64 * track.dt_s;
                    if p.speed_mps < 0.5 && !standing && t_s > spec.ego.depart_s + 1.0 {
                        stands += 1;
                    }
                    standing = p.speed_mps < 0.5 || (standing && p.speed_mps < 3.0);
                    if t_s > jam.period_s {
                        top = top.max(p.speed_mps);
                    }
                }
                (stands, top)
            };
            let ego = tracks.last().unwrap();
            let (stands, top) = waves(ego);
            // one stand per period, moving at up to the heads' speed between
            assert!(stands >= 2, "seed {seed}: the ego stood {stands} times");
            assert!(
                (10.0..jam.peak_speed_mps + 1.5).contains(&top),
                "seed {seed}: top speed in the jam {top}"
            );
            // the traffic behind the heads queues too (what starts far
            // behind reaches the jam late: at least one stand)
            let front_s = traffic.jam_fronts[0].start_s_m;
            let queued: Vec<_> = tracks
                .iter()
                .zip(&traffic.vehicles)
                .filter(|(t, v)| v.start_s_m < front_s && t.id != ego.id)
                .map(|(t, _)| waves(t).0)
                .collect();
            let waving = queued.iter().filter(|&&n| n >= 1).count();
            assert!(
                waving * 10 >= queued.len() * 8,
                "seed {seed}: {waving} of {} queued vehicles stop and go",
                queued.len()
            );
        }
    }

    #[test]
    fn without_requests_or_before_them_the_ego_keeps_its_lane() {
        let mut spec = ScenarioSpec::builtin("highway").unwrap();
        // no ramp: the ego starts in lane 0, the first request is at 14 s
        spec.highway.as_mut().unwrap().on_ramp = None;
        spec.duration_s = 13.5;
        assert!(ego_lane_switches(&spec).is_empty());
        spec.duration_s = 20.0;
        spec.highway.as_mut().unwrap().ego_lane_changes.clear();
        assert!(ego_lane_switches(&spec).is_empty());
    }

    #[test]
    fn road_is_long_enough_and_gently_curved() {
        let h = HighwayParams::default();
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let pieces = road_pieces(&h, 3000.0, &mut rng);
        let mut total = 0.0;
        for (i, p) in pieces.iter().enumerate() {
            match *p {
                PathPiece::Straight { length_m } => {
                    total += length_m;
                    if i == 0 {
                        assert_eq!(length_m, h.straight_length_m);
                    }
                }
                PathPiece::Arc {
                    length_m,
                    curvature_1pm,
                } => {
                    total += length_m;
                    let radius = 1.0 / curvature_1pm.abs();
                    assert!((h.curve_radius_min_m..=h.curve_radius_max_m).contains(&radius));
                }
            }
        }
        assert!(total >= 3000.0);
    }
}
