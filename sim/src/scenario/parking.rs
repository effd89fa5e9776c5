//! Car park generator: two one-way aisles along x between rows of
//! perpendicular bays, and the ego's route at walking pace: down aisle 1,
//! round the end of the double row between the aisles through two tight
//! left corners, along aisle 2 and forwards into a free bay of the far row,
//! where it stops.
//!
//! Layout (y up; aisle 1's centre line is y = 0, the rows run from x = 0 to
//! `L = bays_per_row x bay_width_m`):
//!
//! ```text
//! trees | walkway | row N (bays) | aisle 2 (-x) | row M2 | row M1 | aisle 1 (+x) | row S | walkway | building
//! ```
//!
//! Parked cars stand nose first in most bays; light poles and trees stand on
//! islands at the rows' ends; pedestrians walk along both walkways. East of
//! the rows the ego turns across a circulation lane, lined by trees.

use super::common::{
    MANOEUVRE_LOOKAHEAD_M, building, draw_body, ego_vehicle, generate_ground, parked_agent, pole,
    run_traffic, tree, uniform,
};
use super::{
    EgoSpec, ParkingParams, ScenarioError, ScenarioSpec, URBAN_PEDESTRIAN_SPACING_M, invalid,
};
use crate::scene::{Agent, Ground, Scene, StaticObject};
use crate::traffic::{DriverParams, LanePath, PathPiece, TrafficSpec, VehicleSpec};
use limot_estimator::input::ObjectClass;
use nalgebra::Point2;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use std::f64::consts::{FRAC_PI_2, PI};

/// Radius of the ego's corners (its path's centre line), m: a car's tight
/// turn at parking speed.
pub(crate) const CORNER_RADIUS_M: f64 = 5.0;
/// The ego's first corner starts this far past the rows' east end, m.
const CORNER_PAST_ROWS_M: f64 = 1.5;
/// See [`ParkingLayout::aisle2_swing_m`], m.
const AISLE2_SWING_M: f64 = 1.5;
/// The ego keeps speed^2 * curvature near this in its corners, m/s^2.
const CORNER_LATERAL_ACCEL_MPS2: f64 = 1.5;
/// Islands at the rows' ends, m along x.
const ISLAND_LENGTH_M: f64 = 1.5;
/// Walkway width, m; pedestrians walk on two lines across it.
const WALKWAY_WIDTH_M: f64 = 3.0;
const WALK_LINES: [f64; 2] = [0.35, 0.7];
const PEDESTRIAN_SPEED_MPS: (f64, f64) = (1.1, 1.5);
/// The walkways, the building and the trees reach this far beyond the rows'
/// ends (the aisles' approach and the circulation lane), m.
const SURROUND_M: f64 = 40.0;
/// A parked car's back stands this far (drawn) from the back of its bay, m.
const PARKED_BACK_GAP_M: (f64, f64) = (0.15, 0.45);
/// A parked car sits this far (drawn) off its bay's centre line, m.
const PARKED_SIDE_OFFSET_M: f64 = 0.2;
/// Share of parked cars backed into their bays.
const BACKED_IN_FRACTION: f64 = 0.15;
const LIGHT_POLE_RADIUS_M: f64 = 0.12;
const LIGHT_POLE_HEIGHT_M: f64 = 8.0;
const TRUNK_HEIGHT_M: (f64, f64) = (3.0, 4.0);
const TRUNK_RADIUS_M: (f64, f64) = (0.1, 0.2);
const CROWN_RADIUS_M: (f64, f64) = (1.2, 1.8);
/// Trees along the north walkway and the circulation lane, m apart (their
/// crowns, half a radius above the trunk, clear a car by a few decimetres).
const TREE_SPACING_M: f64 = 9.0;
/// The building's front stands this far behind the south walkway, m.
const BUILDING_SETBACK_M: f64 = 0.5;
const BUILDING_DEPTH_M: f64 = 30.0;
const BUILDING_HEIGHT_M: (f64, f64) = (6.0, 9.0);

/// Where everything in the car park is.
pub(crate) struct ParkingLayout {
    /// Rows' length along x (from x = 0), m.
    length_m: f64,
    /// A bay's width along its row and depth across it, m.
    bay_width_m: f64,
    bay_depth_m: f64,
    aisle_width_m: f64,
    /// Aisle 2's centre line (aisle 1's is y = 0), m.
    aisle2_y_m: f64,
}

/// One row of bays: its bays' y range and the way a car nosed into it faces.
struct Row {
    y_lo_m: f64,
    y_hi_m: f64,
    /// Heading of a car parked nose first, rad.
    nose_in_yaw_rad: f64,
}

impl ParkingLayout {
    pub(crate) fn new(p: &ParkingParams) -> ParkingLayout {
        ParkingLayout {
            length_m: p.bays_per_row as f64 * p.bay_width_m,
            bay_width_m: p.bay_width_m,
            bay_depth_m: p.bay_depth_m,
            aisle_width_m: p.aisle_width_m,
            aisle2_y_m: p.aisle_width_m + 2.0 * p.bay_depth_m,
        }
    }

    /// South row, the double row's two halves, north row.
    fn rows(&self) -> [Row; 4] {
        let (a, d) = (0.5 * self.aisle_width_m, self.bay_depth_m);
        let y2 = self.aisle2_y_m;
        [
            Row {
                y_lo_m: -a - d,
                y_hi_m: -a,
                nose_in_yaw_rad: -FRAC_PI_2,
            },
            Row {
                y_lo_m: a,
                y_hi_m: a + d,
                nose_in_yaw_rad: FRAC_PI_2,
            },
            Row {
                y_lo_m: a + d,
                y_hi_m: a + 2.0 * d,
                nose_in_yaw_rad: -FRAC_PI_2,
            },
            Row {
                y_lo_m: y2 + a,
                y_hi_m: y2 + a + d,
                nose_in_yaw_rad: FRAC_PI_2,
            },
        ]
    }

    /// Centre x of bay `k` counted from the rows' east end (1 = the last).
    pub(crate) fn bay_from_east_x_m(&self, k: usize) -> f64 {
        self.length_m - (k as f64 - 0.5) * self.bay_width_m
    }

    /// The ego's bay in the north row: its centre.
    pub(crate) fn ego_bay_center(&self, ego_bay: usize) -> Point2<f64> {
        let north = &self.rows()[3];
        Point2::new(
            self.bay_from_east_x_m(ego_bay),
            0.5 * (north.y_lo_m + north.y_hi_m),
        )
    }

    /// South edge of the south walkway and north edge of the north one.
    fn walkway_outer_y_m(&self) -> (f64, f64) {
        let rows = self.rows();
        (
            rows[0].y_lo_m - WALKWAY_WIDTH_M,
            rows[3].y_hi_m + WALKWAY_WIDTH_M,
        )
    }

    /// How far to the south of aisle 2's centre line the ego drives along
    /// it, m: a driver swings out before turning into a bay, so that the
    /// straight after the corner sets the car straight in the bay; at most
    /// [`AISLE2_SWING_M`], and 1.2 m from the aisle's edge.
    fn aisle2_swing_m(&self) -> f64 {
        AISLE2_SWING_M.min(0.5 * self.aisle_width_m - 1.2)
    }

    /// x where the ego's first corner starts (aisle 1's route leaves it).
    fn corner_x_m(&self) -> f64 {
        self.length_m + CORNER_PAST_ROWS_M
    }

    /// The ego's route from `start_before_end_m` before the rows' east end
    /// on aisle 1's centre line into bay `ego_bay` of the north row, through
    /// the bay's centre and `overrun_m` beyond it: straight, two left corners
    /// of [`CORNER_RADIUS_M`] with a straight between, aisle 2 westwards
    /// (swung out, [`ParkingLayout::aisle2_swing_m`]), a right corner into
    /// the bay and a last straight. The traffic model stops
    /// a vehicle before its lane's end (the end is a standing leader), so the
    /// overrun is the ego's half length and standstill gap. None when the bay
    /// is too close to the aisle's start for the right corner or too shallow
    /// for it.
    pub(crate) fn ego_route(
        &self,
        start_before_end_m: f64,
        ego_bay: usize,
        overrun_m: f64,
    ) -> Option<(Point2<f64>, Vec<PathPiece>)> {
        let r = CORNER_RADIUS_M;
        let corner_x = self.corner_x_m();
        let bay = self.ego_bay_center(ego_bay);
        let aisle2_line = self.aisle2_y_m - self.aisle2_swing_m();
        let along_aisle2 = corner_x - (bay.x + r);
        let into_bay = bay.y - (aisle2_line + r);
        let across = aisle2_line - 2.0 * r;
        if along_aisle2 < 0.0 || into_bay < 0.0 || across < 0.0 {
            return None;
        }
        let quarter = 0.5 * PI * r;
        let mut pieces = vec![PathPiece::Straight {
            length_m: start_before_end_m + CORNER_PAST_ROWS_M,
        }];
        let push_straight = |pieces: &mut Vec<PathPiece>, length_m: f64| {
            if length_m > 1e-9 {
                pieces.push(PathPiece::Straight { length_m });
            }
        };
        pieces.push(PathPiece::Arc {
            length_m: quarter,
            curvature_1pm: 1.0 / r,
        });
        push_straight(&mut pieces, across);
        pieces.push(PathPiece::Arc {
            length_m: quarter,
            curvature_1pm: 1.0 / r,
        });
        push_straight(&mut pieces, along_aisle2);
        pieces.push(PathPiece::Arc {
            length_m: quarter,
            curvature_1pm: -1.0 / r,
        });
        push_straight(&mut pieces, into_bay + overrun_m);
        Some((Point2::new(self.length_m - start_before_end_m, 0.0), pieces))
    }
}

/// The route of `ego` (a car, [`DriverParams::car`]) for `p`
/// ([`ParkingLayout::ego_route`]), or an error naming `parking.ego_bay` when
/// there is none.
pub(crate) fn checked_ego_route(
    p: &ParkingParams,
    ego: &EgoSpec,
) -> Result<(Point2<f64>, Vec<PathPiece>), ScenarioError> {
    let overrun_m = 0.5 * ego.size_lwh_m[0] + DriverParams::car().min_gap_m;
    ParkingLayout::new(p)
        .ego_route(p.ego_start_before_end_m, p.ego_bay, overrun_m)
        .ok_or_else(|| {
            invalid(
                "parking.ego_bay",
                format!(
                    "= {}: the ego's right corner into it would start before aisle 2 \
                     does, or the bay is too shallow for it (choose a bay further along \
                     the aisle)",
                    p.ego_bay
                ),
            )
        })
}

/// The whole car park scene for a validated spec.
pub(crate) fn build(spec: &ScenarioSpec, rng: &mut ChaCha8Rng) -> Result<Scene, ScenarioError> {
    let p = spec.parking_params();
    let ground = generate_ground(rng, &spec.ground, spec.seed, (Point2::origin(), 0.0));
    let layout = ParkingLayout::new(&p);
    let (start, pieces) = checked_ego_route(&p, &spec.ego)?;
    let route = LanePath::from_pieces(start, 0.0, &pieces, 0.0)
        .map_err(|e| super::traffic_error(spec, e))?;

    let mut statics = islands(&layout, &ground, rng);
    statics.extend(surroundings(&layout, &ground, rng));

    let (walk_lanes, mut vehicles) = pedestrians(spec, &layout, &p, rng)?;
    let mut lanes = walk_lanes;
    let ego_lane = lanes.len();
    lanes.push(route);
    let mut ego = ego_vehicle(&spec.ego, ego_lane, 0.0, spec.ego_speed_mps());
    ego.driver.curve_lateral_accel_mps2 = Some(CORNER_LATERAL_ACCEL_MPS2);
    ego.driver.min_lookahead_m = MANOEUVRE_LOOKAHEAD_M;
    vehicles.push(ego);
    let traffic = TrafficSpec {
        lanes,
        vehicles,
        stop_lines: Vec::new(),
        jam_fronts: Vec::new(),
        duration_s: spec.duration_s,
    };
    let first_parked_id = traffic.vehicles.len() as u32;
    let (mut agents, ego) = run_traffic(spec, &ground, &|_, _| 0.0, &traffic)?;
    agents.extend(parked_cars(
        &layout,
        &p,
        &ground,
        first_parked_id,
        spec.duration_s,
        rng,
    ));
    Ok(Scene {
        duration_s: spec.duration_s,
        ground,
        statics,
        agents,
        ego,
    })
}

/// Walk lines: two on each walkway, one per direction.
const WALK_LINE_COUNT: usize = 4;

/// The most pedestrians a car park of `p` takes: a quarter of the places
/// [`URBAN_PEDESTRIAN_SPACING_M`] apart on its walk lines, so that drawing
/// free places at random finds one within a few draws.
pub(crate) fn max_pedestrians(p: &ParkingParams) -> usize {
    let line_m = p.bays_per_row as f64 * p.bay_width_m + 2.0 * SURROUND_M;
    let places = (line_m / URBAN_PEDESTRIAN_SPACING_M).floor() as usize;
    WALK_LINE_COUNT * (places / 4)
}

/// Pedestrians on the two walkways, in both directions: their walk lines
/// (lanes) and the walkers, ids from 1.
///
/// # Errors
/// [`ScenarioError::Build`] should a walker find no free place in 20 draws
/// (not within [`max_pedestrians`], which validation enforces).
fn pedestrians(
    spec: &ScenarioSpec,
    layout: &ParkingLayout,
    p: &ParkingParams,
    rng: &mut ChaCha8Rng,
) -> Result<(Vec<LanePath>, Vec<VehicleSpec>), ScenarioError> {
    let rows = layout.rows();
    let (x0, x1) = (-SURROUND_M, layout.length_m + SURROUND_M);
    // (inner edge of the walkway, direction away from the rows)
    let walkways = [(rows[0].y_lo_m, -1.0), (rows[3].y_hi_m, 1.0)];
    let mut lanes = Vec::new();
    for (edge, away) in walkways {
        for (i, fraction) in WALK_LINES.iter().enumerate() {
            let y = edge + away * fraction * WALKWAY_WIDTH_M;
            let (from, to) = if i == 0 { (x0, x1) } else { (x1, x0) };
            let length_m = (to - from).abs();
            let heading = if to > from { 0.0 } else { PI };
            let path = LanePath::from_pieces(
                Point2::new(from, y),
                heading,
                &[PathPiece::Straight { length_m }],
                0.0,
            )
            .expect("a straight walk line of positive length");
            lanes.push(path);
        }
    }
    let mut walkers = Vec::new();
    let mut taken: Vec<Vec<f64>> = vec![Vec::new(); lanes.len()];
    for n in 0..p.pedestrians {
        let lane = n % lanes.len();
        let length = lanes[lane].length_m();
        // a free place on the line, a few draws at most
        let Some(s) = (0..20).map(|_| uniform(rng, 0.0, length - 1.0)).find(|s| {
            taken[lane]
                .iter()
                .all(|t| (t - s).abs() >= URBAN_PEDESTRIAN_SPACING_M)
        }) else {
            return Err(ScenarioError::Build {
                scenario: spec.name.clone(),
                message: format!(
                    "parking.pedestrians: no free place for walker {} of {} on its walk line",
                    n + 1,
                    p.pedestrians
                ),
            });
        };
        taken[lane].push(s);
        let (size, driver) = draw_body(rng, ObjectClass::Pedestrian);
        let speed = uniform(rng, PEDESTRIAN_SPEED_MPS.0, PEDESTRIAN_SPEED_MPS.1);
        walkers.push(VehicleSpec {
            id: walkers.len() as u32 + 1,
            class: ObjectClass::Pedestrian,
            size_lwh_m: size,
            lane,
            start_s_m: s,
            start_speed_mps: speed,
            desired_speed_mps: speed,
            depart_s: 0.0,
            lane_changes: Vec::new(),
            driver,
        });
    }
    debug_assert_eq!(lanes.len(), WALK_LINE_COUNT);
    Ok((lanes, walkers))
}

/// Parked cars in the bays, with probability `occupancy` each; the ego's
/// bay and its neighbours stay free.
fn parked_cars(
    layout: &ParkingLayout,
    p: &ParkingParams,
    ground: &Ground,
    first_id: u32,
    duration_s: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Agent> {
    let mut cars = Vec::new();
    for (r, row) in layout.rows().iter().enumerate() {
        for k in 1..=p.bays_per_row {
            let ego_bay = r == 3 && k.abs_diff(p.ego_bay) <= 1;
            if ego_bay || !rng.random_bool(p.occupancy) {
                continue;
            }
            let (size, _) = draw_body(rng, ObjectClass::Car);
            let backed_in = rng.random_bool(BACKED_IN_FRACTION);
            let gap = uniform(rng, PARKED_BACK_GAP_M.0, PARKED_BACK_GAP_M.1);
            let side = uniform(rng, -PARKED_SIDE_OFFSET_M, PARKED_SIDE_OFFSET_M);
            // the back of the bay is the side the nose points to
            let nose_up = row.nose_in_yaw_rad > 0.0;
            let y = if nose_up {
                row.y_hi_m - gap - 0.5 * size.x
            } else {
                row.y_lo_m + gap + 0.5 * size.x
            };
            let yaw = row.nose_in_yaw_rad + if backed_in { PI } else { 0.0 };
            cars.push(parked_agent(
                ground,
                first_id + cars.len() as u32,
                ObjectClass::Car,
                size,
                Point2::new(layout.bay_from_east_x_m(k) + side, y),
                yaw,
                duration_s,
            ));
        }
    }
    cars
}

/// Islands at both ends of every row: a light pole on each end of the
/// double row, a tree on each end of the single rows.
fn islands(layout: &ParkingLayout, ground: &Ground, rng: &mut ChaCha8Rng) -> Vec<StaticObject> {
    let rows = layout.rows();
    let mut out = Vec::new();
    let ends = [
        -0.5 * ISLAND_LENGTH_M,
        layout.length_m + 0.5 * ISLAND_LENGTH_M,
    ];
    for x in ends {
        let double_row_y = rows[1].y_hi_m;
        out.push(pole(
            ground,
            Point2::new(x, double_row_y),
            LIGHT_POLE_RADIUS_M,
            LIGHT_POLE_HEIGHT_M,
        ));
        for row in [&rows[0], &rows[3]] {
            let y = 0.5 * (row.y_lo_m + row.y_hi_m);
            out.extend(tree(
                ground,
                Point2::new(x, y),
                TRUNK_HEIGHT_M,
                TRUNK_RADIUS_M,
                CROWN_RADIUS_M,
                rng,
            ));
        }
    }
    out
}

/// The building behind the south walkway, trees beyond the north walkway
/// and along the circulation lane east of the rows.
fn surroundings(
    layout: &ParkingLayout,
    ground: &Ground,
    rng: &mut ChaCha8Rng,
) -> Vec<StaticObject> {
    let (south, north) = layout.walkway_outer_y_m();
    let (x0, x1) = (-SURROUND_M, layout.length_m + SURROUND_M);
    let height = uniform(rng, BUILDING_HEIGHT_M.0, BUILDING_HEIGHT_M.1);
    let front = south - BUILDING_SETBACK_M;
    let mut out = vec![building(
        ground,
        Point2::new(0.5 * (x0 + x1), front - 0.5 * BUILDING_DEPTH_M),
        0.5 * (x1 - x0),
        0.5 * BUILDING_DEPTH_M,
        height,
    )];
    let tree_at = |out: &mut Vec<StaticObject>, at: Point2<f64>, rng: &mut ChaCha8Rng| {
        out.extend(tree(
            ground,
            at,
            TRUNK_HEIGHT_M,
            TRUNK_RADIUS_M,
            CROWN_RADIUS_M,
            rng,
        ));
    };
    let mut x = x0 + uniform(rng, 0.0, TREE_SPACING_M);
    while x < x1 {
        tree_at(&mut out, Point2::new(x, north + 1.5), rng);
        x += TREE_SPACING_M * uniform(rng, 0.8, 1.2);
    }
    // east of the ego's turn (its outer edge is a corner radius and half a
    // car beyond the corner's start), between the walkways
    let east = layout.corner_x_m() + CORNER_RADIUS_M + 4.5;
    let rows = layout.rows();
    let (y0, y1) = (rows[0].y_lo_m + 1.0, rows[3].y_hi_m - 1.0);
    let mut y = y0 + uniform(rng, 0.0, TREE_SPACING_M);
    while y < y1 {
        tree_at(&mut out, Point2::new(east, y), rng);
        y += TREE_SPACING_M * uniform(rng, 0.8, 1.2);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Family;

    fn spec(seed: u64) -> ScenarioSpec {
        ScenarioSpec {
            seed,
            ..ScenarioSpec::builtin("parking-lot").unwrap()
        }
    }

    #[test]
    fn the_route_ends_in_the_bay_facing_into_it() {
        let p = ParkingParams::default();
        let layout = ParkingLayout::new(&p);
        let (start, pieces) = layout.ego_route(15.0, p.ego_bay, 1.5).unwrap();
        let route = LanePath::from_pieces(start, 0.0, &pieces, 0.0).unwrap();
        let in_bay = route.point_at(route.length_m() - 1.5);
        let bay = layout.ego_bay_center(p.ego_bay);
        assert!((in_bay - bay).norm() < 1e-6, "{in_bay} vs {bay}");
        assert!((route.heading_at(route.length_m()) - FRAC_PI_2).abs() < 1e-9);
        // a bay at the aisle's start leaves no room for the corner into it
        assert!(layout.ego_route(15.0, 1, 1.5).is_none());
    }

    #[test]
    fn the_ego_parks_in_its_bay_and_stands() {
        for seed in 1..=3 {
            let spec = spec(seed);
            assert_eq!(spec.family, Family::Parking);
            let scene = spec.build().unwrap();
            let p = spec.parking_params();
            let bay = ParkingLayout::new(&p).ego_bay_center(p.ego_bay);
            let end = scene.ego.trajectory.end_s();
            let box_center = scene.ego.trajectory.pose_at(end)
                * nalgebra::Translation3::from(scene.ego.box_center_lidar_m);
            let xy = box_center.translation.vector.xy();
            assert!((xy - bay.coords).norm() < 0.3, "seed {seed}: {xy} vs {bay}");
            let v = scene.ego.trajectory.state_at(end).velocity_world_mps;
            assert!(v.norm() < 0.05, "seed {seed}: still moving {v}");
        }
    }
}
