//! Highway generator: one carriageway of 3-5 lanes, a long straight followed
//! by gentle alternating curves, guard rails on both sides, sparse light
//! poles and signs, and 20-50 cars and trucks at highway speeds with lane
//! changes. The ego changes lanes too, at the requested times once the
//! target lane's gap is safe (the traffic model's own lane-change logic).
//! The long straight with parallel rails is the LiDAR-degenerate case.
//! Optionally the ego starts on an on-ramp's acceleration lane and merges
//! (`[highway.on_ramp]`), and jam heads ahead of it make the traffic stop
//! and go (`[highway.jam]`).

use super::common::{
    beside, cuboid_between, draw_body, ego_vehicle, generate_ground, pole, run_traffic, uniform,
    upright_static,
};
use super::roadside::{CrossSection, roadside};
use super::{
    HIGHWAY_EGO_FREE_SLOTS, HighwayParams, ScenarioError, ScenarioSpec, highway_min_spacing_m,
    traffic_error,
};
use crate::scene::{Scene, Shape, StaticKind, StaticObject};
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

/// The whole highway scene for a validated spec.
pub(crate) fn build(spec: &ScenarioSpec, rng: &mut ChaCha8Rng) -> Result<Scene, ScenarioError> {
    let (ground, statics, traffic) = layout(spec, rng)?;
    let (agents, ego) = run_traffic(spec, &ground, &|_, _| 0.0, &traffic)?;
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
fn layout(
    spec: &ScenarioSpec,
    rng: &mut ChaCha8Rng,
) -> Result<(crate::scene::Ground, Vec<StaticObject>, TrafficSpec), ScenarioError> {
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
        let offset_m = lane_offset_m(&h, 0) - h.lane_width_m;
        lanes.push(
            LanePath::from_pieces(Point2::origin(), 0.0, &ramp_pieces, offset_m)
                .map_err(|e| traffic_error(spec, e))?,
        );
    }

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
    // traffic makes room for the ego's changes (the route must happen)
    ego.lane_changes = merge
        .chain(h.ego_lane_changes.iter().map(|change| LaneChange {
            cooperative: true,
            ..change.clone()
        }))
        .collect();
    vehicles.push(ego);
    let traffic = TrafficSpec {
        lanes,
        vehicles,
        stop_lines: Vec::new(),
        jam_fronts: fronts,
        duration_s: spec.duration_s,
    };
    Ok((ground, statics, traffic))
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

/// Distance from the centre line to the right edge of the paved lanes:
/// the carriageway's, and the on-ramp's acceleration lane beside it.
fn right_edge_m(h: &HighwayParams) -> f64 {
    let ramp = if h.on_ramp.is_some() { 1.0 } else { 0.0 };
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

/// Guard rail segments along both edges, each pitched to follow the ground:
/// a beam on posts (the posts are roadside) or, without posts, solid down
/// to the ground.
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
            let s1 = s0 + h.guard_rail_segment_m;
            let base = if h.rail_post_spacing_m > 0.0 {
                RAIL_BEAM_BOTTOM_M
            } else {
                0.0
            };
            rails.push(cuboid_between(
                ground,
                StaticKind::GuardRail,
                beside(reference, s0, offset),
                beside(reference, s1, offset),
                RAIL_WIDTH_M,
                (base, RAIL_HEIGHT_M),
            ));
        }
    }
    rails
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
        let (_, _, traffic) = layout(spec, &mut rng).unwrap();
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
        let (_, _, traffic) = layout(&spec, &mut rng).unwrap();
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

    #[test]
    fn in_the_jam_the_ego_and_its_neighbours_stop_and_go_in_waves() {
        for seed in 1..=4 {
            let mut spec = ScenarioSpec::builtin("highway-jam").unwrap();
            spec.seed = seed;
            let jam = spec.highway_params().jam.unwrap();
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let (_, _, traffic) = layout(&spec, &mut rng).unwrap();
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
