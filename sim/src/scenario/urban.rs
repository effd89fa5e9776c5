//! Urban generator: a straight main street with 1 or 2 lanes per direction,
//! a bike lane and a parking strip on each side, sidewalks, cross streets
//! every block with signalised stop lines (stop-and-go), buildings set back
//! behind the sidewalks, poles, trees, parked cars along both kerbs, moving
//! cars in both directions, cyclists in the bike lanes and pedestrians on the
//! sidewalks. Every intersection the ego's LiDAR can see has a two-lane
//! cross street with its own cars: they stop at the cross street's stop
//! lines and cross while the main street is red (with an all-red clearance
//! between the phases); pedestrians along the main street wait while the
//! cross street has green.
//!
//! The ego's route (`urban.ego_route`) either follows the main street or
//! turns at its first traffic light, on the main street's green, through an
//! arc of `TURN_RADIUS_M` into the cross street's lane away from the main
//! street, which it then follows to its end: right from the kerb lane, or
//! left from the inner lane across the oncoming lanes, or turns round there
//! (a U-turn from the kerb lane into the oncoming kerb lane, back along the
//! main street). The turn is protected: at that light the movements it
//! crosses keep their red `TURN_CLEARANCE_S` longer than the main street (a
//! right turn crosses the pedestrians and cyclists on the ego's side of the
//! main street; a left turn the oncoming cars and the pedestrians and
//! cyclists on the far side; a U-turn the ego's other lanes and the oncoming
//! cars). At the intersections without lights (`urban.give_way_fraction`)
//! the cross streets' cars give way to the main street instead. The traffic
//! of a cross street the ego turns into is simulated together with the main
//! street's, so the ego follows its cars and they follow it, and that street
//! is lined with buildings, parked cars, poles and trees (`side_street`).
//!
//! Cross-section (the ego drives along +x on the right, y < 0 side; the
//! street is mirror-symmetric about y = 0):
//!
//! ```text
//! y = 0 | lanes (n x lane_width) | bike lane | parking | sidewalk | setback | buildings
//! ```
//!
//! Sidewalk: street furniture (poles, tree trunks) in a strip next to the kerb;
//! pedestrians walk in two lines further out, one per walking direction.

use super::common::{
    MANOEUVRE_LOOKAHEAD_M, draw_body, ego_vehicle, generate_ground, run_traffic, uniform,
};
use super::streetscape::{StreetLayout, streetscape};
use super::{
    EgoRoute, ScenarioError, ScenarioSpec, URBAN_CAR_SPACING_M, URBAN_CYCLIST_SPACING_M,
    URBAN_PEDESTRIAN_SPACING_M, UrbanParams, traffic_error, urban_spawn_length_m,
};
use crate::scene::{Agent, Ground, Scene};
use crate::traffic::{
    LanePath, PathPiece, StopLine, TrafficSpec, VehicleSpec, simulate_traffic,
    simulate_traffic_lifted,
};
use limot_estimator::input::ObjectClass;
use nalgebra::{Isometry2, Point2};
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

mod ego_yield;
mod side_street;
mod signals;
mod statics;

use side_street::side_street;
use signals::{SignalPlan, earliest_travel_time_s, signals};
use statics::{building_lot_rng, buildings, furniture, parked_cars};

/// Street beyond the farthest point any agent can reach (agents brake for
/// the end of their lane), m.
const END_MARGIN_M: f64 = 100.0;
/// Statics and parked cars are generated where the LiDAR can see them from
/// anywhere the ego can drive: this far beyond its reach, plus the LiDAR range.
const VIEW_MARGIN_M: f64 = 30.0;
/// The first cross street ahead of the ego is at least this far away, so the
/// ego can reach speed before it has to stop.
const FIRST_STOP_MIN_M: f64 = 60.0;
const FIRST_STOP_SPREAD_M: f64 = 30.0;
/// The crossing behind the ego ends at least this far behind it, m.
const EGO_CLEAR_OF_CROSSING_M: f64 = 10.0;
/// Stop lines sit this far before the cross street's edge.
const STOP_LINE_SETBACK_M: f64 = 1.5;
/// Parked cars, trees and poles keep this far from a cross street's edge.
const CORNER_CLEARANCE_M: f64 = 4.0;
/// Length of one parking place.
const PARKING_PLACE_M: f64 = 6.5;
/// Street furniture stands this far from the kerb (pole / trunk axis).
const FURNITURE_FROM_KERB_M: f64 = 0.6;
/// Pedestrian lines, as fractions of the sidewalk width from the kerb.
const WALK_LINES: [f64; 2] = [0.45, 0.75];
/// Buildings: frontage length, depth, height, gap between, setback from the
/// sidewalk, m.
const BUILDING_LENGTH_M: (f64, f64) = (10.0, 40.0);
const BUILDING_DEPTH_M: (f64, f64) = (10.0, 25.0);
const BUILDING_HEIGHT_M: (f64, f64) = (6.0, 30.0);
const BUILDING_GAP_M: (f64, f64) = (0.0, 4.0);
const BUILDING_SETBACK_M: (f64, f64) = (1.0, 3.0);
/// ChaCha stream (of the scenario seed) that decides which intersections
/// have no traffic lights (`urban.give_way_fraction`), so that the decisions
/// never shift the generator's other draws.
const GIVE_WAY_STREAM: u64 = 0x0047_4956_4557; // "GIVEW" in ASCII
/// At an intersection without lights a cross-street car takes a gap when no
/// road user of the main street (its sidewalks included) will be in the strip
/// its lane sweeps for this long: the time to cross the main street from the
/// stop line, from a standstill, with a margin (see [`give_way_red_s`]).
const GIVE_WAY_MARGIN_S: f64 = 1.5;
/// The strip a cross-street car sweeps: its lane's centre +- this, m (half
/// the widest car with room to spare).
const GIVE_WAY_STRIP_HALF_M: f64 = 1.5;
/// ChaCha stream (of the scenario seed) for the building lots' keep/skip
/// draws; the generator's main stream is 0.
const BUILDING_LOT_STREAM: u64 = 0x0042_5549_4c44; // "BUILD" in ASCII
const POLE_RADIUS_M: f64 = 0.12;
const POLE_HEIGHT_M: f64 = 7.0;
const SIGNAL_POLE_HEIGHT_M: f64 = 5.0;
/// Tree trunks: radius and height; crowns: radius; the crown centre is half a
/// radius above the trunk top, so its lowest point is >= 2 m above ground.
const TRUNK_RADIUS_M: (f64, f64) = (0.12, 0.25);
const TRUNK_HEIGHT_M: (f64, f64) = (3.0, 4.0);
const CROWN_RADIUS_M: (f64, f64) = (1.2, 2.0);
/// Trees keep this far from poles along the sidewalk.
const TREE_POLE_CLEARANCE_M: f64 = 2.5;
/// In the ego's lane, nobody starts within this far behind / ahead of it.
const EGO_FREE_BEHIND_M: f64 = 50.0;
const EGO_FREE_AHEAD_M: f64 = 25.0;
/// The red phase at the ego's first intersection starts this long before the
/// ego could arrive there at the earliest, so it must stop.
const EGO_RED_LEAD_S: f64 = 4.0;
/// No red phase starts before this (everyone has time to see it).
const EARLIEST_RED_S: f64 = 2.0;
/// Pedestrians along the main street stop this far before a cross street's
/// carriageway (its lanes are as wide as the main street's).
const WALK_STOP_SETBACK_M: f64 = 0.5;
/// Cross-street cars start at rest: the first in each lane this far
/// (bumper to stop line) before its stop line, ...
const CROSS_FIRST_GAP_M: (f64, f64) = (2.0, 40.0);
/// ... each further one this far behind the one ahead (bumper to bumper).
const CROSS_FOLLOW_GAP_M: (f64, f64) = (6.0, 30.0);
/// Cross-street cars depart at a time drawn from [0, this x signal_cycle_s],
/// so they reach their stop line at staggered times, except at the ego's
/// first intersection: there they depart so that they could reach the stop
/// line in the second half of the cross street's first green (drawn), which
/// falls while the ego waits at its red.
const CROSS_DEPART_SPREAD: f64 = 0.5;
/// ... and no later than this before that green ends.
const CROSS_ARRIVAL_BEFORE_RED_S: f64 = 2.0;
/// Cross streets are side streets: their cars drive at most this fast, so
/// one that cannot stop at the onset of its red any more clears the main
/// street within the all-red (`URBAN_ALL_RED_S`) plus the main street's
/// start-up time, m/s.
const CROSS_SPEED_MAX_MPS: f64 = 12.0;
/// Radius of the ego's turn (its lane's centre line), m: a tight corner,
/// taken at about sqrt(TURN_LATERAL_ACCEL_MPS2 * radius).
const TURN_RADIUS_M: f64 = 8.0;
/// The ego keeps speed^2 * curvature near this in its turn, m/s^2.
const TURN_LATERAL_ACCEL_MPS2: f64 = 2.0;
/// The same for a U-turn's half circle (about 5 m, taken at ~2.7 m/s): the
/// tighter curve's entry asks more of the steering's lag.
const U_TURN_LATERAL_ACCEL_MPS2: f64 = 1.5;
/// At the ego's turn, the movements it crosses stay red this long after the
/// main street's green starts, so the ego, waiting at the light, has turned
/// past their paths before they move (the scene properties check that nobody
/// overlaps), s.
const TURN_CLEARANCE_S: f64 = 12.0;
/// Longest body of a pedestrian (`draw_body`), m.
const PEDESTRIAN_LENGTH_MAX_M: f64 = 0.6;

/// What kind of path a traffic lane is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LaneKind {
    Car,
    Bike,
    Walk,
}

/// One traffic lane: its kind, direction (+x or -x) and path.
struct Lane {
    kind: LaneKind,
    forward: bool,
    path: LanePath,
}

/// A cross street with traffic: one lane per direction.
struct CrossStreet {
    /// Index into `Street::crossings`.
    crossing: usize,
    /// Along +y (at x = c + w/2: right-hand traffic) and along -y.
    lanes: [LanePath; 2],
}

/// Direction of the cross-street lane `CrossStreet::lanes[i]` (true = +y).
fn cross_forward(i: usize) -> bool {
    i == 0
}

/// The ego's turn: where, which way, and the lane it drives.
struct EgoTurn {
    /// Index into `Street::crossings`.
    crossing: usize,
    /// Right (into the cross street's -y half), left (across the oncoming
    /// lanes, into its +y half) or round (into the oncoming kerb lane).
    route: EgoRoute,
    /// The ego's lane from the street's start up to the turn (the kerb lane
    /// for a right turn or a U-turn, the inner lane for a left one), an arc
    /// of `TURN_RADIUS_M` (a U-turn's: half a circle from kerb lane to kerb
    /// lane), then the cross street's lane away from the main street (-y to
    /// the right, +y to the left) or the oncoming kerb lane to its end.
    path: LanePath,
}

impl EgoTurn {
    /// The direction the ego drives along the cross street after a turn into
    /// it: -1 = -y (right), +1 = +y (left); None after a U-turn, which keeps
    /// it on the main street.
    fn away_sign(&self) -> Option<f64> {
        match self.route {
            EgoRoute::TurnRight => Some(-1.0),
            EgoRoute::TurnLeft => Some(1.0),
            EgoRoute::UTurn | EgoRoute::Straight => None,
        }
    }

    /// Whether the ego leaves the main street into the cross street.
    fn leaves_main_street(&self) -> bool {
        self.away_sign().is_some()
    }
}

/// The street layout shared by all placement steps.
struct Street {
    u: UrbanParams,
    /// The street runs from x_min to x_max along y = 0.
    x_min: f64,
    x_max: f64,
    /// Statics and parked cars are generated in [view_lo, view_hi].
    view_lo: f64,
    view_hi: f64,
    /// Cross street centres, increasing.
    crossings: Vec<f64>,
    /// Index of the first crossing ahead of the ego.
    ego_crossing: usize,
    /// Per crossing: no traffic lights, the cross street gives way.
    give_way: Vec<bool>,
    /// Cross-street lanes run along x = crossing +- lane_width / 2 from
    /// y = -+cross_half_length_m to y = +-cross_half_length_m.
    cross_half_length_m: f64,
    /// Main-street lanes.
    lanes: Vec<Lane>,
    /// The cross streets with traffic, by increasing crossing index.
    cross_streets: Vec<CrossStreet>,
    /// The ego's turn, None if it drives straight.
    turn: Option<EgoTurn>,
}

impl Street {
    /// |y| of the kerb (sidewalk's inner edge).
    fn kerb_m(&self) -> f64 {
        let u = &self.u;
        u.lanes_per_direction as f64 * u.lane_width_m + u.bike_lane_width_m + u.parking_width_m
    }

    /// |y| of the cross streets' stop lines: before the main street's
    /// sidewalk, so waiting cars leave the pedestrians' lines free.
    fn cross_stop_y_m(&self) -> f64 {
        self.kerb_m() + self.u.sidewalk_width_m + STOP_LINE_SETBACK_M
    }

    /// Arc length on a cross-street lane of the given direction at world y.
    fn cross_s_of(&self, forward: bool, y: f64) -> f64 {
        if forward {
            y + self.cross_half_length_m
        } else {
            self.cross_half_length_m - y
        }
    }

    /// Arc length on a lane of the given direction at world x.
    fn s_of(&self, forward: bool, x: f64) -> f64 {
        if forward {
            x - self.x_min
        } else {
            self.x_max - x
        }
    }

    /// True if [x0, x1] comes within `clearance_m` of a cross street.
    fn near_crossing(&self, x0: f64, x1: f64, clearance_m: f64) -> bool {
        let half = 0.5 * self.u.cross_street_width_m + clearance_m;
        self.crossings
            .iter()
            .any(|&c| x1 > c - half && x0 < c + half)
    }

    /// World point at x on the side `side` (-1 = right of the ego, y < 0;
    /// +1 = left), `from_axis_m` from the street's centre line.
    fn at(&self, x: f64, side: f64, from_axis_m: f64) -> Point2<f64> {
        Point2::new(x, side * from_axis_m)
    }
}

/// The whole urban scene for a validated spec.
pub(crate) fn build(spec: &ScenarioSpec, rng: &mut ChaCha8Rng) -> Result<Scene, ScenarioError> {
    let u = spec.urban_params();
    // the main street and the highway's initial straight run along +x through the origin
    let ground = generate_ground(rng, &spec.ground, spec.seed, (Point2::origin(), 0.0));
    let ego_speed = spec.ego_speed_mps();
    let street = layout(spec, &u, ego_speed, rng).map_err(|e| traffic_error(spec, e))?;

    let mut lots = building_lot_rng(spec.seed);
    let mut statics = buildings(&street, &ground, rng, &mut lots);
    statics.extend(furniture(&street, &ground, rng));
    let layout = StreetLayout {
        kerb_m: street.kerb_m(),
        sidewalk_width_m: u.sidewalk_width_m,
        crossings: &street.crossings,
        cross_half_width_m: 0.5 * u.cross_street_width_m,
        view: (street.view_lo, street.view_hi),
        furniture: u.street_furniture,
        t_world_street: Isometry2::identity(),
    };
    let detail = streetscape(&layout, &ground, &statics, spec.seed);
    statics.extend(detail);

    let mut vehicles = moving_agents(&street, spec.ego.lane, rng);
    let ego_lane = spec.ego.lane;
    let ego_s = street.s_of(true, 0.0);
    let (plans, stop_lines) = signals(&street, spec, ego_speed, rng);
    // cross streets are simulated apart from the main street (and from each
    // other): their signals keep them from meeting, and a joint simulation
    // would cost every vehicle a projection onto every cross lane
    // except the one the ego turns into: its traffic meets the ego
    let mut lanes: Vec<LanePath> = street.lanes.iter().map(|l| l.path.clone()).collect();
    let mut stop_lines = stop_lines;
    let mut next_id = vehicles.len() as u32 + 1;
    let mut cross_specs = Vec::new();
    // the ego's turn at a crossing without lights: it yields there (below)
    let yielding_turn = street.turn.as_ref().filter(|t| street.give_way[t.crossing]);
    for cross in &street.cross_streets {
        let plan = &plans[cross.crossing];
        // where the ego turns without lights the cross street's cars all come
        // towards the main street: the ego meets them oncoming, and they give
        // way to it like to the main street's other users
        let only_lane = yielding_turn
            .filter(|t| t.crossing == cross.crossing)
            .and_then(|t| t.away_sign())
            // from the half it turns into: along +y (lane 0, `cross_forward`)
            // from the -y half
            .map(|away| if away < 0.0 { 0 } else { 1 });
        let traffic = cross_traffic(
            &street,
            cross,
            plan,
            only_lane,
            next_id,
            spec.duration_s,
            rng,
        );
        next_id += traffic.vehicles.len() as u32;
        let turns_into = street
            .turn
            .as_ref()
            .is_some_and(|t| t.crossing == cross.crossing && t.leaves_main_street());
        if turns_into && only_lane.is_none() {
            join_traffic(&mut lanes, &mut vehicles, &mut stop_lines, traffic);
        } else {
            cross_specs.push((cross.crossing, traffic));
        }
    }
    let ego = match &street.turn {
        None => ego_vehicle(&spec.ego, ego_lane, ego_s, ego_speed),
        Some(turn) => {
            let route_lane = lanes.len();
            lanes.push(turn.path.clone());
            stop_lines.extend(route_stop_lines(&street, turn, &plans, route_lane));
            protect_turn(&street, turn, &plans[turn.crossing], &mut stop_lines);
            let mut ego = ego_vehicle(&spec.ego, route_lane, ego_s, ego_speed);
            let lateral_accel = if turn.route == EgoRoute::UTurn {
                ego.driver.min_lookahead_m = MANOEUVRE_LOOKAHEAD_M;
                U_TURN_LATERAL_ACCEL_MPS2
            } else {
                TURN_LATERAL_ACCEL_MPS2
            };
            ego.driver.curve_lateral_accel_mps2 = Some(lateral_accel);
            ego
        }
    };
    let ego_size = ego.size_lwh_m;
    vehicles.push(ego);
    let mut traffic = TrafficSpec {
        lanes,
        vehicles,
        stop_lines,
        jam_fronts: Vec::new(),
        duration_s: spec.duration_s,
    };
    if let Some(turn) = yielding_turn {
        add_yield_line(spec, &street, turn, ego_size, &mut traffic)?;
    }
    // ids: main street 1..=N, cross streets N+1..=M, parked cars from M+1
    // pedestrians walk on the raised sidewalks
    let (mut agents, ego) = run_traffic(spec, &ground, &|x, y| layout.raised_m(x, y), &traffic)?;
    // the cross streets without lights give way to the main street as it was
    // simulated: their stop lines are red while it is busy
    let main_street: Vec<Occupant> = agents
        .iter()
        .map(|a| Occupant::of(&a.trajectory, None, &a.size_lwh_m))
        .chain([Occupant::of(
            &ego.trajectory,
            Some(&ego.box_center_lidar_m),
            &ego.size_lwh_m,
        )])
        .collect();
    for (crossing, traffic) in &mut cross_specs {
        if street.give_way[*crossing] {
            for line in &mut traffic.stop_lines {
                let lane_x = traffic.lanes[line.lane].point_at(0.0).x;
                line.red_intervals_s = give_way_red_s(&street, lane_x, &main_street, spec);
            }
        }
    }
    for (_, traffic) in &cross_specs {
        agents.extend(simulate_agents(spec, &ground, traffic)?);
    }
    let first_parked_id = next_id;
    let parked = parked_cars(&street, &ground, first_parked_id, spec.duration_s, rng);
    let first_side_id = first_parked_id + parked.len() as u32;
    agents.extend(parked);
    if let Some((turn, away_sign)) = street
        .turn
        .as_ref()
        .and_then(|t| t.away_sign().map(|sign| (t, sign)))
    {
        let view = spec.lidar.max_range_m + VIEW_MARGIN_M;
        let far_m = (ego_speed * spec.duration_s + view).min(street.cross_half_length_m);
        let c = street.crossings[turn.crossing];
        let side = side_street(
            &street,
            &ground,
            c,
            away_sign,
            far_m,
            first_side_id,
            spec.duration_s,
            spec.seed,
        );
        statics.extend(side.statics);
        agents.extend(side.parked);
    }
    Ok(Scene {
        duration_s: spec.duration_s,
        ground,
        statics,
        agents,
        ego,
    })
}

/// The ego's yield line before its turn at a crossing without lights (on
/// its route lane, the last of `traffic.lanes`): red while the main-street
/// users its turn crosses are near its path, found by simulating them with
/// the ego held at the line (see [`ego_yield`]).
fn add_yield_line(
    spec: &ScenarioSpec,
    street: &Street,
    turn: &EgoTurn,
    ego_size_lwh_m: nalgebra::Vector3<f64>,
    traffic: &mut TrafficSpec,
) -> Result<(), ScenarioError> {
    let route_lane = traffic.lanes.len() - 1;
    traffic.stop_lines.push(StopLine {
        lane: route_lane,
        s_m: ego_yield::yield_line_s(street, turn),
        red_intervals_s: vec![(0.0, spec.duration_s + 1.0)],
    });
    let held = simulate_traffic(traffic).map_err(|e| traffic_error(spec, e))?;
    let lanes = ego_yield::conflicting_lanes(street, turn);
    let crossers: Vec<ego_yield::Crosser> = traffic
        .vehicles
        .iter()
        .zip(&held)
        .filter(|(v, _)| lanes.contains(&v.lane))
        .map(|(v, track)| ego_yield::Crosser {
            track,
            radius_m: 0.5 * v.size_lwh_m.x.hypot(v.size_lwh_m.y),
        })
        .collect();
    let path = ego_yield::swept_path(street, turn, ego_size_lwh_m.x);
    let ego_radius_m = 0.5 * ego_size_lwh_m.x.hypot(ego_size_lwh_m.y);
    let red = ego_yield::yield_red_s(&path, ego_radius_m, &crossers, spec.duration_s);
    traffic
        .stop_lines
        .last_mut()
        .expect("the yield line was pushed")
        .red_intervals_s = red;
    Ok(())
}

/// Which crossings have no traffic lights: each with probability
/// `give_way_fraction`, drawn from the seed's own stream, never the ego's
/// first (where it waits at red, and turns).
fn give_way_crossings(count: usize, ego_crossing: usize, u: &UrbanParams, seed: u64) -> Vec<bool> {
    if u.give_way_fraction <= 0.0 {
        return vec![false; count];
    }
    let mut stream = ChaCha8Rng::seed_from_u64(seed);
    stream.set_stream(GIVE_WAY_STREAM);
    (0..count)
        .map(|k| stream.random::<f64>() < u.give_way_fraction && k != ego_crossing)
        .collect()
}

/// A main-street road user as the cross street sees it: the footprint's
/// centre over time and the radius of a circle round the footprint.
struct Occupant<'a> {
    trajectory: &'a crate::trajectory::Trajectory,
    /// Box centre in the trajectory's body frame (None: the body origin).
    box_center_body: Option<nalgebra::Vector3<f64>>,
    radius_m: f64,
}

impl<'a> Occupant<'a> {
    fn of(
        trajectory: &'a crate::trajectory::Trajectory,
        box_center_body: Option<&nalgebra::Vector3<f64>>,
        size_lwh_m: &nalgebra::Vector3<f64>,
    ) -> Occupant<'a> {
        Occupant {
            trajectory,
            box_center_body: box_center_body.copied(),
            radius_m: 0.5 * size_lwh_m.x.hypot(size_lwh_m.y),
        }
    }

    fn center_at(&self, t_s: f64) -> Point2<f64> {
        let pose = self.trajectory.pose_at(t_s);
        let c = match &self.box_center_body {
            Some(d) => pose * nalgebra::Point3::from(*d),
            None => nalgebra::Point3::from(pose.translation.vector),
        };
        Point2::new(c.x, c.y)
    }
}

/// Red intervals of a give-way line on the cross-street lane at x =
/// `lane_x`: red from the time a cross-street car needs to cross the main
/// street (kerb to kerb and both sidewalks, from a standstill at its stop
/// line, plus its length and [`GIVE_WAY_MARGIN_S`]) before any main-street
/// road user reaches the strip the lane sweeps until it has left it, sampled
/// every 0.1 s (the first interval from t = 0 when one is there already).
fn give_way_red_s(
    street: &Street,
    lane_x: f64,
    main_street: &[Occupant<'_>],
    spec: &ScenarioSpec,
) -> Vec<(f64, f64)> {
    let u = &street.u;
    let half_y = street.kerb_m() + u.sidewalk_width_m;
    let across_m = STOP_LINE_SETBACK_M + 2.0 * half_y + 5.0;
    let driver = crate::traffic::DriverParams::car();
    let clear_s = earliest_travel_time_s(across_m, CROSS_SPEED_MAX_MPS, driver.max_accel_mps2)
        + driver.accel_lag_s
        + GIVE_WAY_MARGIN_S;
    let (x0, x1) = (
        lane_x - GIVE_WAY_STRIP_HALF_M,
        lane_x + GIVE_WAY_STRIP_HALF_M,
    );
    let in_strip = |p: Point2<f64>, r: f64| {
        let dx = (x0 - p.x).max(p.x - x1).max(0.0);
        let dy = (p.y.abs() - half_y).max(0.0);
        dx.hypot(dy) <= r
    };
    red_while(spec.duration_s, clear_s, |t| {
        main_street
            .iter()
            .any(|o| in_strip(o.center_at(t), o.radius_m))
    })
}

/// Sample spacing of the red intervals of give-way and yield lines, s.
const RED_STEP_S: f64 = 0.1;

/// Red intervals of a line that must be red while `occupied(t)` holds and
/// `lead_s` before, sampled every [`RED_STEP_S`] over [0, `duration_s`]
/// (the first interval from t = 0 when it holds already), merged.
fn red_while(duration_s: f64, lead_s: f64, occupied: impl Fn(f64) -> bool) -> Vec<(f64, f64)> {
    let steps = (duration_s / RED_STEP_S).ceil() as usize;
    let red = (0..=steps)
        .map(|k| (k as f64 * RED_STEP_S).min(duration_s))
        .filter(|&t| occupied(t))
        .map(|t| ((t - lead_s).max(0.0), t + RED_STEP_S))
        .collect();
    merged(red)
}

/// `intervals`' union as disjoint intervals, ascending (overlapping or
/// touching ones joined).
fn merged(mut intervals: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    intervals.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut union: Vec<(f64, f64)> = Vec::new();
    for (from, to) in intervals {
        match union.last_mut() {
            Some(last) if from <= last.1 => last.1 = last.1.max(to),
            _ => union.push((from, to)),
        }
    }
    union
}

/// Adds `other`'s lanes, vehicles and stop lines to the joint traffic
/// (lane indices shifted behind the lanes already there).
fn join_traffic(
    lanes: &mut Vec<LanePath>,
    vehicles: &mut Vec<VehicleSpec>,
    stop_lines: &mut Vec<StopLine>,
    other: TrafficSpec,
) {
    let shift = lanes.len();
    lanes.extend(other.lanes);
    vehicles.extend(other.vehicles.into_iter().map(|v| VehicleSpec {
        lane: v.lane + shift,
        ..v
    }));
    stop_lines.extend(other.stop_lines.into_iter().map(|l| StopLine {
        lane: l.lane + shift,
        ..l
    }));
}

/// Stop lines on the ego's route lane (index `route_lane`): the main street's
/// before every crossing up to the one it turns at, with their main-street
/// red, so it turns on the main street's green; after a U-turn, the
/// oncoming direction's before every crossing it passes on the way back.
fn route_stop_lines(
    street: &Street,
    turn: &EgoTurn,
    plans: &[SignalPlan],
    route_lane: usize,
) -> Vec<StopLine> {
    let half = 0.5 * street.u.cross_street_width_m;
    let length_m = turn.path.length_m();
    let line = |s: f64, plan: &SignalPlan| {
        (s > 0.0 && s < length_m && !plan.main_red.is_empty()).then(|| StopLine {
            lane: route_lane,
            s_m: s,
            red_intervals_s: plan.main_red.clone(),
        })
    };
    let mut lines: Vec<StopLine> = street.crossings[..=turn.crossing]
        .iter()
        .zip(plans)
        .filter_map(|(&c, plan)| line(street.s_of(true, c - half - STOP_LINE_SETBACK_M), plan))
        .collect();
    if turn.route == EgoRoute::UTurn {
        // the route's arc length at a point x on the way back: its length at
        // the half circle's end plus the distance driven back from there
        let (end_s, end_x) = u_turn_end(street, turn);
        lines.extend(
            street.crossings[..turn.crossing]
                .iter()
                .zip(plans)
                .rev()
                .filter_map(|(&c, plan)| {
                    line(end_s + end_x - (c + half + STOP_LINE_SETBACK_M), plan)
                }),
        );
    }
    lines
}

/// Arc length and x where a U-turn's half circle ends on `turn.path`.
fn u_turn_end(street: &Street, turn: &EgoTurn) -> (f64, f64) {
    let radius = u_turn_radius_m(&street.u);
    let start_x = u_turn_start_x(street.crossings[turn.crossing], radius);
    (start_x - street.x_min + PI * radius, start_x)
}

/// Where a turn into the cross street at x = `c` leaves its main-street lane
/// (its arc's start): `TURN_RADIUS_M` before the cross-street lane it turns
/// into, at `c + w/2` turning left (the +y lane) or `c - w/2` turning right.
fn turn_arc_start_x(c: f64, lane_width_m: f64, left: bool) -> f64 {
    let lane_x = if left {
        c + 0.5 * lane_width_m
    } else {
        c - 0.5 * lane_width_m
    };
    lane_x - TURN_RADIUS_M
}

/// A U-turn's radius: from the kerb lane's centre to the oncoming one's.
fn u_turn_radius_m(u: &UrbanParams) -> f64 {
    (u.lanes_per_direction as f64 - 0.5) * u.lane_width_m
}

/// Where a U-turn's half circle starts at the crossing at x = `c`: half its
/// radius before the cross street's centre, so that the half circle (and the
/// car round it) stays inside the intersection.
fn u_turn_start_x(c: f64, radius_m: f64) -> f64 {
    c - 0.5 * radius_m
}

/// The protected turn: at the crossing the ego turns at, the stop lines of
/// the movements its path crosses stay red until `TURN_CLEARANCE_S` after
/// each main-street red: the bike lane and the walk lines on the side it
/// turns to (y < 0 for a right turn, y > 0 for a left one; the walk lines get
/// a red there even without cross traffic) and, for a left turn, the
/// oncoming car lanes.
fn protect_turn(
    street: &Street,
    turn: &EgoTurn,
    plan: &SignalPlan,
    stop_lines: &mut Vec<StopLine>,
) {
    let u = &street.u;
    let c = street.crossings[turn.crossing];
    let half = 0.5 * u.cross_street_width_m;
    let extend = |red: &[(f64, f64)]| -> Vec<(f64, f64)> {
        red.iter()
            .map(|&(a, b)| (a, b + TURN_CLEARANCE_S))
            .collect()
    };
    let crosses_oncoming = matches!(turn.route, EgoRoute::TurnLeft | EgoRoute::UTurn);
    for (index, lane) in street.lanes.iter().enumerate() {
        let turn_side = turn
            .away_sign()
            .is_some_and(|away| lane.path.point_at(0.0).y * away > 0.0);
        let sign = if lane.forward { -1.0 } else { 1.0 };
        // a U-turn from the kerb lane crosses the ego's other lanes too
        let crossed_beside = turn.route == EgoRoute::UTurn && lane.forward && index != 0;
        let (line_x, red) = match lane.kind {
            LaneKind::Bike if turn_side => {
                (c + sign * (half + STOP_LINE_SETBACK_M), &plan.main_red)
            }
            LaneKind::Car if (crosses_oncoming && !lane.forward) || crossed_beside => {
                (c + sign * (half + STOP_LINE_SETBACK_M), &plan.main_red)
            }
            LaneKind::Walk if turn_side => (
                c + sign * (u.lane_width_m + WALK_STOP_SETBACK_M),
                &plan.walk_red,
            ),
            _ => continue,
        };
        let s = street.s_of(lane.forward, line_x);
        if red.is_empty() || s <= 0.0 || s >= lane.path.length_m() {
            continue;
        }
        stop_lines.retain(|l| !(l.lane == index && (l.s_m - s).abs() < 1e-6));
        stop_lines.push(StopLine {
            lane: index,
            s_m: s,
            red_intervals_s: extend(red),
        });
    }
}

/// Simulates traffic without the ego and lifts it onto the ground.
fn simulate_agents(
    spec: &ScenarioSpec,
    ground: &Ground,
    traffic: &TrafficSpec,
) -> Result<Vec<Agent>, ScenarioError> {
    let trajectories = simulate_traffic_lifted(traffic, ground, &|_, _| 0.0)
        .map_err(|e| traffic_error(spec, e))?;
    Ok(traffic
        .vehicles
        .iter()
        .zip(trajectories)
        .map(|(vehicle, trajectory)| Agent {
            id: vehicle.id,
            class: vehicle.class,
            size_lwh_m: vehicle.size_lwh_m,
            parked: false,
            trajectory,
            presence: crate::scene::Presence::ALWAYS,
            labelled: crate::scene::Labelling::Seen,
        })
        .collect())
}

/// Street extent, cross streets and lanes. The ego starts at x = 0; moving
/// agents start in [-spawn/4, 3 spawn/4] and the street extends far enough
/// both ways that nobody reaches its end.
fn layout(
    spec: &ScenarioSpec,
    u: &UrbanParams,
    ego_speed_mps: f64,
    rng: &mut ChaCha8Rng,
) -> Result<Street, crate::traffic::TrafficError> {
    let spawn = urban_spawn_length_m(u, spec.duration_s);
    let (spawn_lo, spawn_hi) = (-0.25 * spawn, 0.75 * spawn);
    let reach = u.car_speed_max_mps.max(ego_speed_mps) * spec.duration_s;
    let x_min = spawn_lo - reach - END_MARGIN_M;
    let x_max = spawn_hi + reach + END_MARGIN_M;
    let view = spec.lidar.max_range_m + VIEW_MARGIN_M;
    let ego_reach = ego_speed_mps * (spec.duration_s - spec.ego.depart_s).max(0.0);
    // after a U-turn the ego drives back past its start
    let behind = if u.ego_route == EgoRoute::UTurn {
        ego_reach
    } else {
        0.0
    };
    let view_lo = (-view - behind).max(x_min);
    let view_hi = (ego_reach + view).min(x_max);

    // cross streets: the first one ahead of the ego, then every block both ways
    let ego_front = 0.5 * spec.ego.size_lwh_m[0];
    let first = ego_front
        + 0.5 * u.cross_street_width_m
        + STOP_LINE_SETBACK_M
        + FIRST_STOP_MIN_M
        + uniform(rng, 0.0, FIRST_STOP_SPREAD_M);
    let mut crossings = vec![first];
    let mut x = first;
    while x < x_max {
        x += uniform(rng, u.block_length_min_m, u.block_length_max_m);
        crossings.push(x);
    }
    // behind: the ego (at x = 0) never starts on a crossing, so the block it
    // starts in may come out longer than block_length_max_m
    let mut x = (first - uniform(rng, u.block_length_min_m, u.block_length_max_m))
        .min(-(0.5 * u.cross_street_width_m + EGO_CLEAR_OF_CROSSING_M));
    crossings.insert(0, x);
    while x > x_min {
        x -= uniform(rng, u.block_length_min_m, u.block_length_max_m);
        crossings.insert(0, x);
    }
    let ego_crossing = crossings.len() - crossings.iter().filter(|&&c| c >= first).count();

    let length = x_max - x_min;
    let piece = [PathPiece::Straight { length_m: length }];
    let path = |forward: bool, offset_m: f64| {
        let (start, heading) = if forward {
            (Point2::new(x_min, 0.0), 0.0)
        } else {
            (Point2::new(x_max, 0.0), PI)
        };
        LanePath::from_pieces(start, heading, &piece, offset_m)
    };
    let n = u.lanes_per_direction;
    let w = u.lane_width_m;
    let kerb = n as f64 * w + u.bike_lane_width_m + u.parking_width_m;
    let mut lanes = Vec::new();
    // lanes 0..n: the ego's direction, 0 = kerb side (the ego's lane index)
    for forward in [true, false] {
        for i in 0..n {
            let offset = -((n - i) as f64 - 0.5) * w;
            lanes.push(Lane {
                kind: LaneKind::Car,
                forward,
                path: path(forward, offset)?,
            });
        }
    }
    for forward in [true, false] {
        lanes.push(Lane {
            kind: LaneKind::Bike,
            forward,
            path: path(forward, -(n as f64 * w + 0.5 * u.bike_lane_width_m))?,
        });
    }
    // pedestrians: on each sidewalk the inner line walks with the traffic on
    // that side, the outer line against it
    for forward in [true, false] {
        let with = kerb + WALK_LINES[0] * u.sidewalk_width_m;
        let against = kerb + WALK_LINES[1] * u.sidewalk_width_m;
        for offset in [-with, against] {
            lanes.push(Lane {
                kind: LaneKind::Walk,
                forward,
                path: path(forward, offset)?,
            });
        }
    }
    // cross streets the LiDAR can see get one lane per direction (right-hand
    // traffic: +y at x = c + w/2), long enough that their cars never brake
    // for the lane's end
    let stop_y = kerb + u.sidewalk_width_m + STOP_LINE_SETBACK_M;
    let queue =
        CROSS_FIRST_GAP_M.1 + u.cross_cars_per_intersection as f64 * (CROSS_FOLLOW_GAP_M.1 + 5.0);
    let cross_half_length = stop_y + queue + u.car_speed_max_mps * spec.duration_s + END_MARGIN_M;
    let cross_piece = [PathPiece::Straight {
        length_m: 2.0 * cross_half_length,
    }];
    let turn_crossing = match u.ego_route {
        EgoRoute::Straight => None,
        EgoRoute::TurnRight | EgoRoute::TurnLeft | EgoRoute::UTurn => Some(ego_crossing),
    };
    let mut cross_streets = Vec::new();
    if u.cross_cars_per_intersection > 0 {
        for (k, &c) in crossings.iter().enumerate() {
            if !(view_lo..=view_hi).contains(&c) && turn_crossing != Some(k) {
                continue;
            }
            let north = Point2::new(c + 0.5 * w, -cross_half_length);
            let south = Point2::new(c - 0.5 * w, cross_half_length);
            cross_streets.push(CrossStreet {
                crossing: k,
                lanes: [
                    LanePath::from_pieces(north, 0.5 * PI, &cross_piece, 0.0)?,
                    LanePath::from_pieces(south, -0.5 * PI, &cross_piece, 0.0)?,
                ],
            });
        }
    }
    // the route turns from the kerb lane right into the cross street's -y
    // lane (x = c - w / 2), or from the inner lane left into its +y lane
    // (x = c + w / 2), and follows it to the cross street's end
    let turn = match turn_crossing {
        None => None,
        Some(k) if u.ego_route == EgoRoute::UTurn => {
            // from the kerb lane half round into the oncoming kerb lane,
            // then back to the street's start
            let radius = u_turn_radius_m(u);
            let start_x = u_turn_start_x(crossings[k], radius);
            let pieces = [
                PathPiece::Straight {
                    length_m: start_x - x_min,
                },
                PathPiece::Arc {
                    length_m: PI * radius,
                    curvature_1pm: 1.0 / radius,
                },
                PathPiece::Straight {
                    length_m: start_x - x_min,
                },
            ];
            let start = Point2::new(x_min, -radius);
            Some(EgoTurn {
                crossing: k,
                route: EgoRoute::UTurn,
                path: LanePath::from_pieces(start, 0.0, &pieces, 0.0)?,
            })
        }
        Some(k) => {
            let left = u.ego_route == EgoRoute::TurnLeft;
            // the lane's y, where the arc starts, its curvature's sign and
            // the straight from the arc's end to the cross street's end
            let (lane_y, turn_x, curvature, after_arc_m) = if left {
                let lane_y = -0.5 * w;
                let after = cross_half_length - (lane_y + TURN_RADIUS_M);
                (lane_y, turn_arc_start_x(crossings[k], w, true), 1.0, after)
            } else {
                let lane_y = -(n as f64 - 0.5) * w;
                let after = cross_half_length + lane_y - TURN_RADIUS_M;
                (
                    lane_y,
                    turn_arc_start_x(crossings[k], w, false),
                    -1.0,
                    after,
                )
            };
            let pieces = [
                PathPiece::Straight {
                    length_m: turn_x - x_min,
                },
                PathPiece::Arc {
                    length_m: 0.5 * PI * TURN_RADIUS_M,
                    curvature_1pm: curvature / TURN_RADIUS_M,
                },
                PathPiece::Straight {
                    length_m: after_arc_m,
                },
            ];
            let start = Point2::new(x_min, lane_y);
            Some(EgoTurn {
                crossing: k,
                route: u.ego_route,
                path: LanePath::from_pieces(start, 0.0, &pieces, 0.0)?,
            })
        }
    };
    Ok(Street {
        u: u.clone(),
        x_min,
        x_max,
        view_lo,
        view_hi,
        give_way: {
            let mut give_way = give_way_crossings(crossings.len(), ego_crossing, u, spec.seed);
            if u.ego_turn_give_way && turn.is_some() {
                give_way[ego_crossing] = true;
            }
            give_way
        },
        crossings,
        ego_crossing,
        cross_half_length_m: cross_half_length,
        lanes,
        cross_streets,
        turn,
    })
}

/// Moving cars, cyclists and pedestrians in spawn slots: every lane of a kind
/// is cut into slots of the kind's spacing over the spawn zone; each agent
/// takes a random slot (jittered inside it), half of each kind in each
/// direction. The ego's lane stays free around the ego. Ids 1..=N.
fn moving_agents(street: &Street, ego_lane: usize, rng: &mut ChaCha8Rng) -> Vec<VehicleSpec> {
    let u = &street.u;
    let spawn = urban_spawn_length_m(u, 0.0);
    let spawn_lo = -0.25 * spawn;
    let kinds = [
        (
            LaneKind::Car,
            ObjectClass::Car,
            u.moving_cars,
            URBAN_CAR_SPACING_M,
            (u.car_speed_min_mps, u.car_speed_max_mps),
        ),
        (
            LaneKind::Bike,
            ObjectClass::Cyclist,
            u.cyclists,
            URBAN_CYCLIST_SPACING_M,
            (u.cyclist_speed_min_mps, u.cyclist_speed_max_mps),
        ),
        (
            LaneKind::Walk,
            ObjectClass::Pedestrian,
            u.pedestrians,
            URBAN_PEDESTRIAN_SPACING_M,
            (u.pedestrian_speed_min_mps, u.pedestrian_speed_max_mps),
        ),
    ];
    let mut agents = Vec::new();
    for (kind, class, count, spacing, (v_min, v_max)) in kinds {
        let per_lane = (spawn / spacing).floor() as usize;
        let slot_len = spawn / per_lane.max(1) as f64;
        // random phase per lane: agents do not line up across lanes
        let phase: Vec<f64> = (0..street.lanes.len())
            .map(|_| uniform(rng, 0.0, 1.0))
            .collect();
        let centre = |lane: usize, i: usize| spawn_lo + (i as f64 + phase[lane]) * slot_len;
        let jitter = 0.5 * (slot_len - spacing).max(0.0);
        // half of each kind goes each way (the odd one with the ego)
        for (forward, n_dir) in [(true, count.div_ceil(2)), (false, count / 2)] {
            let mut slots: Vec<(usize, usize)> = street
                .lanes
                .iter()
                .enumerate()
                .filter(|(_, l)| l.kind == kind && l.forward == forward)
                .flat_map(|(lane, _)| (0..per_lane).map(move |i| (lane, i)))
                .filter(|&(lane, i)| {
                    let x = centre(lane, i);
                    lane != ego_lane || !(-EGO_FREE_BEHIND_M..=EGO_FREE_AHEAD_M).contains(&x)
                })
                .collect();
            slots.shuffle(rng);
            for &(lane, i) in slots.iter().take(n_dir) {
                let x = centre(lane, i) + uniform(rng, -jitter, jitter);
                let (size, driver) = draw_body(rng, class);
                let speed = uniform(rng, v_min, v_max);
                agents.push(VehicleSpec {
                    id: agents.len() as u32 + 1,
                    class,
                    size_lwh_m: size,
                    lane,
                    start_s_m: street.s_of(forward, x),
                    start_speed_mps: speed,
                    desired_speed_mps: speed,
                    depart_s: 0.0,
                    lane_changes: Vec::new(),
                    driver,
                });
            }
        }
    }
    agents
}

/// The traffic of one cross street: its two lanes, stop lines before the
/// main street with the cross street's red, and its cars (ids from
/// `first_id`; all in lane `only_lane` when given). The cars start at rest queued before their stop line
/// (alternating directions, the first one's drawn) and depart at staggered
/// times; at the ego's first intersection they depart so that they reach the
/// stop line in the second half of the cross street's first green, when the
/// ego waits at its red, and cross in front of it.
fn cross_traffic(
    street: &Street,
    cross: &CrossStreet,
    plan: &SignalPlan,
    only_lane: Option<usize>,
    first_id: u32,
    duration_s: f64,
    rng: &mut ChaCha8Rng,
) -> TrafficSpec {
    let u = &street.u;
    let stop_s = |i: usize| {
        let forward = cross_forward(i);
        let sign = if forward { -1.0 } else { 1.0 };
        street.cross_s_of(forward, sign * street.cross_stop_y_m())
    };
    // distance from the stop line to the rear of the last car, per lane
    let mut queue_m = [0.0; 2];
    let first_lane = rng.random_range(0..2);
    // the first green: between the first two red intervals
    let first_green = match plan.cross_red.as_slice() {
        [a, b, ..] if cross.crossing == street.ego_crossing => Some((a.1, b.0)),
        _ => None,
    };
    let mut cars = Vec::new();
    for i in 0..u.cross_cars_per_intersection {
        let lane = only_lane.unwrap_or((first_lane + i) % 2);
        let gap = if queue_m[lane] == 0.0 {
            uniform(rng, CROSS_FIRST_GAP_M.0, CROSS_FIRST_GAP_M.1)
        } else {
            queue_m[lane] + uniform(rng, CROSS_FOLLOW_GAP_M.0, CROSS_FOLLOW_GAP_M.1)
        };
        let (size, driver) = draw_body(rng, ObjectClass::Car);
        queue_m[lane] = gap + size.x;
        let speed = uniform(rng, u.car_speed_min_mps, u.car_speed_max_mps).min(CROSS_SPEED_MAX_MPS);
        let depart = match first_green {
            Some((start, end)) => {
                let arrival = uniform(rng, 0.5 * (start + end), end - CROSS_ARRIVAL_BEFORE_RED_S);
                let travel = earliest_travel_time_s(gap, speed, driver.max_accel_mps2);
                (arrival - travel).max(0.0)
            }
            None => uniform(rng, 0.0, CROSS_DEPART_SPREAD * u.signal_cycle_s),
        };
        cars.push(VehicleSpec {
            id: first_id + cars.len() as u32,
            class: ObjectClass::Car,
            size_lwh_m: size,
            lane,
            start_s_m: stop_s(lane) - gap - 0.5 * size.x,
            start_speed_mps: 0.0,
            desired_speed_mps: speed,
            depart_s: depart,
            lane_changes: Vec::new(),
            driver,
        });
    }
    TrafficSpec {
        lanes: cross.lanes.to_vec(),
        vehicles: cars,
        stop_lines: (0..2)
            .map(|lane| StopLine {
                lane,
                s_m: stop_s(lane),
                red_intervals_s: plan.cross_red.clone(),
            })
            .collect(),
        jam_fronts: Vec::new(),
        duration_s,
    }
}

#[cfg(test)]
mod tests {
    use super::signals::{red_intervals, signal_plan, walk_clearance_s};
    use super::*;
    use crate::scenario::URBAN_ALL_RED_S;
    use crate::scene::Shape;
    use crate::traffic::simulate_traffic;
    use rand::SeedableRng;

    fn is_red(intervals: &[(f64, f64)], t_s: f64) -> bool {
        intervals.iter().any(|&(a, b)| t_s >= a && t_s < b)
    }

    #[test]
    fn signal_plans_separate_main_and_cross_street_with_all_red() {
        let u = UrbanParams::default();
        let duration = 60.0;
        let walk_clear = walk_clearance_s(&u);
        // slowest pedestrian over 2 lanes + setbacks + a body, and its stop
        assert!((walk_clear - (8.2 / 1.2 + 1.5 / 3.0)).abs() < 1e-9);
        for k in 0..40 {
            let first_red = EARLIEST_RED_S + k as f64 * u.signal_cycle_s / 40.0;
            let plan = signal_plan(first_red, &u, duration, walk_clear);
            assert_eq!(
                plan.main_red,
                red_intervals(first_red, u.red_s, u.signal_cycle_s, duration)
            );
            for w in plan.cross_red.windows(2) {
                assert!(w[0].0 < w[0].1 && w[0].1 < w[1].0, "{:?}", plan.cross_red);
            }
            let mut green_s = 0.0;
            let dt = 0.01;
            for i in 0..(duration / dt) as usize {
                let t = i as f64 * dt;
                let cross_green = !is_red(&plan.cross_red, t);
                if cross_green {
                    green_s += dt;
                    assert!(t >= walk_clear + URBAN_ALL_RED_S - 1e-9, "green at {t}");
                    // the main street is red from ALL_RED before to ALL_RED after
                    for d in [-URBAN_ALL_RED_S + 1e-6, 0.0, URBAN_ALL_RED_S - 1e-6] {
                        let tm = t + d;
                        if (0.0..duration).contains(&tm) {
                            assert!(is_red(&plan.main_red, tm), "first {first_red} t {t} d {d}");
                        }
                    }
                }
                // pedestrians along the main street step out only if the
                // cross street stays red until they are across
                if !is_red(&plan.walk_red, t) {
                    for d in [0.0, 0.5 * walk_clear, walk_clear - 1e-6] {
                        let tc = (t + d).min(duration);
                        assert!(is_red(&plan.cross_red, tc), "walk at {t}");
                    }
                }
            }
            // the cross street gets green in every main red that starts
            // after the start-up clearance, less two all-reds
            let full_reds = plan
                .main_red
                .iter()
                .filter(|&&(a, _)| a >= walk_clear && a + u.red_s <= duration)
                .count() as f64;
            let want = full_reds * (u.red_s - 2.0 * URBAN_ALL_RED_S);
            assert!(
                green_s >= want - 0.05,
                "first {first_red}: green {green_s} < {want}"
            );
        }
    }

    #[test]
    fn nothing_static_stands_on_a_cross_street() {
        let spec = ScenarioSpec::builtin("urban").unwrap();
        let u = spec.urban_params();
        let half = 0.5 * u.cross_street_width_m;
        for seed in 0..10 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let ground = generate_ground(&mut rng, &spec.ground, seed, (Point2::origin(), 0.0));
            let street = layout(&spec, &u, spec.ego_speed_mps(), &mut rng).unwrap();
            let mut statics = buildings(&street, &ground, &mut rng, &mut building_lot_rng(seed));
            statics.extend(furniture(&street, &ground, &mut rng));
            let parked = parked_cars(&street, &ground, 1, 10.0, &mut rng);
            // (centre x, half extent along x) of every footprint
            let mut footprints: Vec<(f64, f64)> = statics
                .iter()
                .map(|s| {
                    let x = s.t_world_object.translation.vector.x;
                    let r = match s.shape {
                        // buildings are axis-aligned
                        Shape::Cuboid { half_extents_m } => half_extents_m.x,
                        Shape::Cylinder { radius_m, .. } => radius_m,
                        Shape::Ball { radius_m } => radius_m,
                    };
                    (x, r)
                })
                .collect();
            footprints.extend(parked.iter().map(|a| {
                let x = a.trajectory.pose_at(0.0).translation.vector.x;
                (x, 0.5 * a.size_lwh_m.xy().norm())
            }));
            assert!(footprints.len() > 100);
            // the whole cross street (carriageway and sidewalks) stays free,
            // at every y
            for &c in &street.crossings {
                for &(x, r) in &footprints {
                    assert!(
                        x + r <= c - half || x - r >= c + half,
                        "seed {seed}: footprint {x} +- {r} on the cross street at {c}"
                    );
                }
            }
        }
    }

    #[test]
    fn building_fraction_keeps_each_lot_independently_and_nested() {
        let spec = ScenarioSpec::builtin("urban").unwrap();
        let u = spec.urban_params();
        let (mut lots, mut built) = (0usize, [0usize; 3]);
        for seed in 0..40 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let ground = generate_ground(&mut rng, &spec.ground, seed, (Point2::origin(), 0.0));
            let mut street = layout(&spec, &u, spec.ego_speed_mps(), &mut rng).unwrap();
            // the same main stream for every fraction: the lots are the same
            let mut at = |fraction: f64| {
                street.u.building_fraction = fraction;
                let mut rng = rng.clone();
                let out = buildings(&street, &ground, &mut rng, &mut building_lot_rng(seed));
                (out, rng)
            };
            let (all, rng_all) = at(1.0);
            let (none, rng_none) = at(0.0);
            let (third, _) = at(1.0 / 3.0);
            let (two_thirds, rng_two_thirds) = at(2.0 / 3.0);
            assert!(none.is_empty());
            // the main stream ends where it does at fraction 1
            let next = |mut r: ChaCha8Rng| r.random::<u64>();
            assert_eq!(next(rng_none), next(rng_all.clone()));
            assert_eq!(next(rng_two_thirds), next(rng_all));
            // a lot built at some fraction is built at every higher one
            assert!(third.iter().all(|b| two_thirds.contains(b)));
            assert!(two_thirds.iter().all(|b| all.contains(b)));
            lots += all.len();
            built[0] += third.len();
            built[1] += two_thirds.len();
            built[2] += all.len();
        }
        assert_eq!(built[2], lots);
        assert!(lots > 1000, "{lots} lots");
        for (k, fraction) in [1.0 / 3.0, 2.0 / 3.0].into_iter().enumerate() {
            let share = built[k] as f64 / lots as f64;
            let sigma = (fraction * (1.0 - fraction) / lots as f64).sqrt();
            println!("fraction {fraction:.3}: {share:.3} of {lots} lots built (sigma {sigma:.3})");
            assert!(
                (share - fraction).abs() < 4.0 * sigma,
                "{fraction}: {} of {lots} lots built",
                built[k]
            );
        }
    }

    #[test]
    fn cross_cars_queue_before_their_stop_lines() {
        let spec = ScenarioSpec::builtin("urban").unwrap();
        let mut u = spec.urban_params();
        u.cross_cars_per_intersection = 5;
        for seed in 0..10 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let street = layout(&spec, &u, spec.ego_speed_mps(), &mut rng).unwrap();
            let walk_clear = walk_clearance_s(&u);
            for (n, cross) in street.cross_streets.iter().enumerate() {
                let plan = signal_plan(10.0, &u, spec.duration_s, walk_clear);
                let first_id = 100 + 5 * n as u32;
                let traffic = cross_traffic(&street, cross, &plan, None, first_id, 60.0, &mut rng);
                let ids: Vec<u32> = traffic.vehicles.iter().map(|v| v.id).collect();
                assert_eq!(ids, (first_id..first_id + 5).collect::<Vec<_>>());
                // both directions, 3 + 2 cars
                let in_lane = |l: usize| traffic.vehicles.iter().filter(|v| v.lane == l).count();
                assert_eq!(in_lane(0) + in_lane(1), 5);
                assert!(in_lane(0).min(in_lane(1)) == 2);
                for line in &traffic.stop_lines {
                    let p = traffic.lanes[line.lane].point_at(line.s_m);
                    assert!((p.y.abs() - street.cross_stop_y_m()).abs() < 1e-9);
                    assert_eq!(line.red_intervals_s, plan.cross_red);
                }
                // at rest, before the stop line, bumpers >= min gap apart
                for lane in 0..2 {
                    let mut cars: Vec<&VehicleSpec> =
                        traffic.vehicles.iter().filter(|v| v.lane == lane).collect();
                    cars.sort_by(|a, b| b.start_s_m.total_cmp(&a.start_s_m));
                    let line = traffic.stop_lines[lane].s_m;
                    let mut front_limit = line - CROSS_FIRST_GAP_M.0;
                    for car in cars {
                        assert_eq!(car.start_speed_mps, 0.0);
                        assert!((0.0..spec.duration_s).contains(&car.depart_s));
                        let front = car.start_s_m + 0.5 * car.size_lwh_m.x;
                        assert!(front <= front_limit + 1e-9);
                        front_limit = car.start_s_m - 0.5 * car.size_lwh_m.x - CROSS_FOLLOW_GAP_M.0;
                    }
                }
                let sim = simulate_traffic(&TrafficSpec {
                    duration_s: 1.0,
                    ..traffic
                });
                assert!(sim.is_ok(), "{sim:?}");
            }
        }
    }

    #[test]
    fn red_intervals_repeat_inside_the_run() {
        let red = red_intervals(5.0, 15.0, 40.0, 100.0);
        assert_eq!(red, vec![(5.0, 20.0), (45.0, 60.0), (85.0, 100.0)]);
        assert!(red_intervals(5.0, 0.0, 40.0, 100.0).is_empty());
    }

    #[test]
    fn earliest_travel_time_is_continuous_at_cruise_speed() {
        let (v, a) = (10.0, 2.0);
        let d = v * v / (2.0 * a);
        let t0 = earliest_travel_time_s(d - 1e-9, v, a);
        let t1 = earliest_travel_time_s(d + 1e-9, v, a);
        assert!((t0 - t1).abs() < 1e-6 && (t0 - v / a).abs() < 1e-6);
        assert!((earliest_travel_time_s(d + 50.0, v, a) - (v / a + 5.0)).abs() < 1e-12);
    }

    #[test]
    fn give_way_lines_are_red_while_the_main_street_is_in_the_lanes_strip() {
        let mut spec = ScenarioSpec::builtin("urban").unwrap();
        spec.duration_s = 30.0;
        let mut u = spec.urban_params();
        u.give_way_fraction = 1.0;
        spec.urban = Some(u.clone());
        let street = layout(&spec, &u, 10.0, &mut ChaCha8Rng::seed_from_u64(3)).unwrap();
        // every crossing but the ego's first has no lights
        for (k, &give_way) in street.give_way.iter().enumerate() {
            assert_eq!(give_way, k != street.ego_crossing, "crossing {k}");
        }
        let c = street.crossings[street.ego_crossing + 1];
        let lane_x = c + 0.5 * u.lane_width_m;
        let standing = |x: f64, y: f64, t0: f64, t1: f64| {
            let pose = nalgebra::Isometry3::translation(x, y, 0.0);
            crate::trajectory::Trajectory::stationary(t0, t1, &pose)
        };
        let size = nalgebra::Vector3::new(4.5, 1.8, 1.5);
        // a car standing on the main street, its footprint reaching into the
        // lane's strip, all the run, and one standing a block away
        let in_strip = standing(lane_x + 2.0, -5.0, 0.0, 30.0);
        let away = standing(c + 40.0, -5.0, 0.0, 30.0);
        let occupants = [
            Occupant::of(&away, None, &size),
            Occupant::of(&in_strip, None, &size),
        ];
        let red = give_way_red_s(&street, lane_x, &occupants, &spec);
        assert_eq!(red.len(), 1);
        assert_eq!(red[0].0, 0.0);
        assert!(red[0].1 >= 30.0, "{red:?}");
        // nobody near: never red
        assert!(give_way_red_s(&street, lane_x, &occupants[..1], &spec).is_empty());
        // a pedestrian walking along the far sidewalk through the strip at
        // 1.25 m/s: red from the crossing time before it reaches the strip
        // until it has left it
        let knots: Vec<_> = (0..=300)
            .map(|i| {
                let t = i as f64 * 0.1;
                let x = lane_x - 15.0 + 1.25 * t;
                crate::trajectory::Knot {
                    position: [
                        crate::trajectory::Jet::new(x, 1.25, 0.0),
                        crate::trajectory::Jet::new(street.kerb_m() + 2.0, 0.0, 0.0),
                        crate::trajectory::Jet::new(0.0, 0.0, 0.0),
                    ],
                    euler: [crate::trajectory::Jet::new(0.0, 0.0, 0.0); 3],
                }
            })
            .collect();
        let walking = crate::trajectory::Trajectory::new(0.0, 0.1, knots);
        let body = nalgebra::Vector3::new(0.5, 0.6, 1.7);
        let red = give_way_red_s(
            &street,
            lane_x,
            &[Occupant::of(&walking, None, &body)],
            &spec,
        );
        assert_eq!(red.len(), 1, "{red:?}");
        // it reaches the strip (1.5 m + its radius 0.39 m) at 10.49 s and
        // leaves it at 13.51 s; the red starts the crossing time (~7.7 s)
        // before
        let (from, to) = red[0];
        assert!(from > 0.0 && from < 10.49 - 5.0, "{red:?}");
        assert!((13.5..13.7).contains(&to), "{red:?}");
    }

    #[test]
    fn layout_keeps_the_ego_off_crossings_and_blocks_in_range() {
        let spec = ScenarioSpec::builtin("urban").unwrap();
        let u = spec.urban_params();
        for seed in 0..20 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let street = layout(&spec, &u, spec.ego_speed_mps(), &mut rng).unwrap();
            let half = 0.5 * u.cross_street_width_m;
            let first = street.crossings[street.ego_crossing];
            assert!(first - half > FIRST_STOP_MIN_M);
            assert!(street.crossings[street.ego_crossing - 1] + half <= -EGO_CLEAR_OF_CROSSING_M);
            for (k, pair) in street.crossings.windows(2).enumerate() {
                let block = pair[1] - pair[0];
                if k + 1 != street.ego_crossing {
                    assert!((u.block_length_min_m..=u.block_length_max_m).contains(&block));
                }
            }
            assert!(
                street.crossings[0] <= street.x_min
                    && *street.crossings.last().unwrap() >= street.x_max
            );
            // 2 x 2 car lanes, 2 bike lanes, 4 pedestrian lines
            assert_eq!(street.lanes.len(), 10);
            // every crossing in view has a cross street with two lanes
            let in_view: Vec<usize> = (0..street.crossings.len())
                .filter(|&k| (street.view_lo..=street.view_hi).contains(&street.crossings[k]))
                .collect();
            let with_traffic: Vec<usize> =
                street.cross_streets.iter().map(|x| x.crossing).collect();
            assert!(in_view.len() >= 3 && in_view.contains(&street.ego_crossing));
            assert_eq!(with_traffic, in_view);
            for cross in &street.cross_streets {
                let c = street.crossings[cross.crossing];
                for (i, lane) in cross.lanes.iter().enumerate() {
                    let start = lane.point_at(0.0);
                    let end = lane.point_at(lane.length_m());
                    // right-hand traffic, from one end of the cross street to the other
                    let forward = cross_forward(i);
                    let x_want = c + if forward { 0.5 } else { -0.5 } * u.lane_width_m;
                    assert!((start.x - x_want).abs() < 1e-9 && (end.x - x_want).abs() < 1e-9);
                    assert!((start.y + end.y).abs() < 1e-9);
                    assert_eq!(forward, end.y > start.y);
                    assert!(start.y.abs() > 0.5 * street.cross_half_length_m);
                }
            }
        }
    }
}
