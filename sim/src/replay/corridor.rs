//! The world around a replayed drive: the ground under the ego's path and a
//! seeded static scene along the driven corridor.
//!
//! Ground: the road height under the ego (the LiDAR origin `lidar_height_m`
//! below, along the body's z) is fitted by weighted least squares with the
//! existing [`Ground`] terms: a plane plus sinusoids along each of the
//! path's two principal axes (one per 25 m of extent along that axis, at
//! most 12 per axis; heights along an L-shaped drive are a sum of a profile
//! along each leg); the roughness
//! texture is the scenario's. The residual under the ego is reported.
//!
//! Statics: the path (the ego's, extended 60 m straight beyond both ends so
//! the first and last sweeps see scenery behind and ahead) is lined on both
//! sides with what a corridor of its type holds, at distances measured from a
//! road edge per side: [`DEFAULT_EDGE_M`] or, when labelled vehicles drive or
//! park farther out, 1 m beyond the outermost of them (within
//! [`EDGE_SEARCH_M`]). Each candidate object has a footprint on the ground:
//! a circle for round things (poles, trees, shrubs), its exact oriented
//! rectangle for boxes (buildings, guard rails, walls). It is clear when
//! that footprint keeps [`AGENT_CLEARANCE_M`] from every replayed agent's
//! footprint circle (sampled every 0.5 s of its labelled presence) and
//! reaches at most [`EDGE_TOLERANCE_M`] inside the road edge, on the side
//! of the path it is on, of any part of the path (inside of bends; a
//! rectangle is tested along its outline). A building that is not clear is
//! set back, then split; any other object is dropped. Every object's random
//! draws are made whether or not it is kept. The straight
//! street generators of the highway and urban families assume a road along
//! x and are not used; the object helpers they share are.

use super::ReplayInput;
use crate::scenario::HighwayParams;
use crate::scenario::common::{beside, cuboid_between, tree, uniform, upright_static};
use crate::scenario::roadside::{CrossSection, roadside};
use crate::scene::{
    Agent, Ground, Roughness, Shape, StaticKind, StaticObject, Trajectory, Undulation,
};
use crate::traffic::LanePath;
use limot_estimator::input::ObjectClass;
use nalgebra::{DMatrix, DVector, Point2, Point3, Vector2, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// What lines a replayed drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Corridor {
    /// A raised sidewalk, plot fronts (fences, hedges, low walls, with
    /// driveway gaps), detached houses set back behind front gardens, trees,
    /// street lights, shrubs.
    Residential,
    /// Continuous building fronts close to the road, street lights, a few trees.
    City,
    /// Guard rails and light poles; beyond them the highway family's roadside
    /// (rail posts, delineators, noise walls, cuttings, vegetation, overpasses,
    /// signs, gantries).
    Highway,
}

/// A mean ego speed above this makes an unnamed corridor a highway, m/s.
pub const HIGHWAY_SPEED_MPS: f64 = 14.0;
/// Dense traffic without pedestrians or cyclists (at least this many
/// vehicle tracks and none of them) makes an unnamed corridor a highway
/// whatever the speed: a congested highway (KITTI tracking 0020).
pub const HIGHWAY_VEHICLE_TRACKS: usize = 60;
/// At least this many labelled pedestrians and cyclists make an unnamed
/// corridor a city street.
pub const CITY_VULNERABLE_TRACKS: usize = 4;
/// Road edge (lateral distance from the ego path) when no labelled vehicle
/// is farther out, m.
pub const DEFAULT_EDGE_M: f64 = 4.5;
/// Labelled vehicles within this lateral distance push the road edge out, m.
pub const EDGE_SEARCH_M: f64 = 14.0;
/// One ground harmonic per this much of the road's extent along an axis, m.
const HARMONIC_SPACING_M: f64 = 12.0;
/// At most this many ground harmonics per axis.
const MAX_HARMONICS: usize = 24;
/// How far the corridor continues beyond the drive's ends, m.
const EXTENSION_M: f64 = 60.0;
/// Ridge on the ground's slopes, m²: a drive whose positions spread by
/// much less than sqrt of this (10 cm) along an axis gets a level ground
/// along it; a drive of metres keeps its fitted slope to 1e-5.
const SLOPE_RIDGE_M2: f64 = 0.01;
/// Clearance between a static object and any agent box, m.
const AGENT_CLEARANCE_M: f64 = 0.5;
/// How far a static may reach inside the road edge (a kerb's width), m.
const EDGE_TOLERANCE_M: f64 = 0.5;
/// Radius around a tree's trunk kept clear (its crown overhangs), m.
const TREE_CLEARANCE_M: f64 = 1.5;
/// Spacing of the points along a rectangular footprint's outline that are
/// tested against the road edge, m.
const OUTLINE_SAMPLE_M: f64 = 0.5;
/// A building that is not clear is set back by up to this many steps...
const SETBACK_STEPS: usize = 3;
/// ...of this much each, m.
const SETBACK_STEP_M: f64 = 1.5;
/// A building that is not clear at any set-back is split in two halves, each
/// placed alike, while the halves are at least this long, m.
const MIN_BUILDING_LENGTH_M: f64 = 5.0;
/// Residential sidewalks: width beyond the road edge and kerb height, m,
/// laid in slabs of this length along the path, m.
const SIDEWALK_WIDTH_M: f64 = 2.0;
const KERB_HEIGHT_M: f64 = 0.12;
const KERB_SEGMENT_M: f64 = 4.0;
/// Residential plots' front boundaries (fences, hedges, low walls): their
/// line beyond the road edge, behind the sidewalk and the trees, in front of
/// the houses (set 4-9 m back), m; laid in pieces of this length, m.
const PLOT_LINE_M: f64 = 3.8;
const PLOT_FRONT_SEGMENT_M: f64 = 3.0;
/// Highway guard rails: the beam's centre beyond the road edge and its
/// width, m.
const HIGHWAY_RAIL_OFFSET_M: f64 = 1.0;
const HIGHWAY_RAIL_WIDTH_M: f64 = 0.3;

impl Corridor {
    /// The corridor of a drive with no corridor named: highway when the ego's
    /// mean speed exceeds `HIGHWAY_SPEED_MPS` or at least
    /// `HIGHWAY_VEHICLE_TRACKS` vehicles and no pedestrian or cyclist are
    /// labelled, city when at least
    /// `CITY_VULNERABLE_TRACKS` pedestrians or cyclists are labelled,
    /// residential otherwise.
    pub fn choose(input: &ReplayInput) -> Corridor {
        let path_m: f64 = input
            .t_world_lidar
            .windows(2)
            .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
            .sum();
        let span_s = (input.t_world_lidar.len() - 1).max(1) as f64 * input.frame_period_s;
        let vulnerable = input
            .tracks
            .iter()
            .filter(|t| matches!(t.class, ObjectClass::Pedestrian | ObjectClass::Cyclist))
            .count();
        let vehicles = input.tracks.len() - vulnerable;
        let congested = vulnerable == 0 && vehicles >= HIGHWAY_VEHICLE_TRACKS;
        if path_m / span_s > HIGHWAY_SPEED_MPS || congested {
            Corridor::Highway
        } else if vulnerable >= CITY_VULNERABLE_TRACKS {
            Corridor::City
        } else {
            Corridor::Residential
        }
    }

    /// The lower-case name (as in the TOML).
    pub fn name(self) -> &'static str {
        match self {
            Corridor::Residential => "residential",
            Corridor::City => "city",
            Corridor::Highway => "highway",
        }
    }
}

/// The fitted ground's residual under the ego at the frames, m.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GroundFit {
    /// RMS of (ground - road height under the ego).
    pub rms_m: f64,
    /// Largest |ground - road height under the ego|.
    pub max_m: f64,
}

/// The ground under `ego` (see the module docs), sampled every 0.1 s over
/// `[0, duration_s]`.
pub(super) fn fit_ground(
    ego: &Trajectory,
    lidar_height_m: f64,
    duration_s: f64,
    roughness: Option<Roughness>,
) -> (Ground, GroundFit) {
    let samples = ((duration_s / 0.1).floor() as usize).max(1) + 1;
    let road: Vec<Vector3<f64>> = (0..samples)
        .map(|i| {
            let pose = ego.pose_at(duration_s * i as f64 / (samples - 1) as f64);
            pose.transform_point(&Point3::new(0.0, 0.0, -lidar_height_m))
                .coords
        })
        .collect();
    let centre = road.iter().sum::<Vector3<f64>>() / road.len() as f64;
    // principal horizontal axis of the road points
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in &road {
        let d = p - centre;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let axes = [
        Vector2::new(angle.cos(), angle.sin()),
        Vector2::new(-angle.sin(), angle.cos()),
    ];
    // per axis: the coordinate's range and the harmonics along it
    let terms: Vec<(Vector2<f64>, f64, f64)> = axes
        .iter()
        .flat_map(|axis| {
            let along: Vec<f64> = road.iter().map(|p| axis.dot(&(p - centre).xy())).collect();
            let (lo, hi) = along
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &s| {
                    (a.min(s), b.max(s))
                });
            let extent_m = (hi - lo).max(1.0);
            let harmonics = ((extent_m / HARMONIC_SPACING_M).floor() as usize).min(MAX_HARMONICS);
            (1..=harmonics).map(move |j| (*axis, TAU * j as f64 / (2.0 * extent_m), lo))
        })
        .collect();
    // unknowns: height at the centre, slope x, slope y, (sin, cos) per term
    let unknowns = 3 + 2 * terms.len();
    let mut a = DMatrix::<f64>::zeros(road.len(), unknowns);
    let mut b = DVector::<f64>::zeros(road.len());
    for (r, p) in road.iter().enumerate() {
        let d = p - centre;
        a[(r, 0)] = 1.0;
        a[(r, 1)] = d.x;
        a[(r, 2)] = d.y;
        for (j, (axis, k, lo)) in terms.iter().enumerate() {
            let phase = k * (axis.dot(&d.xy()) - lo);
            a[(r, 3 + 2 * j)] = phase.sin();
            a[(r, 4 + 2 * j)] = phase.cos();
        }
        b[r] = p.z;
    }
    // A little ridge keeps an ill-posed fit tame: on the sinusoids, and on
    // the slopes for a drive that spans centimetres (a standing ego, whose
    // positions jitter by millimetres, would otherwise get any slope at all).
    let mut normal = a.transpose() * &a;
    for k in 1..3 {
        normal[(k, k)] += SLOPE_RIDGE_M2 * road.len() as f64;
    }
    for k in 3..unknowns {
        normal[(k, k)] += 1e-3 * road.len() as f64;
    }
    let rhs = a.transpose() * &b;
    let x = normal
        .clone()
        .cholesky()
        .map(|c| c.solve(&rhs))
        .unwrap_or_else(|| DVector::from_element(unknowns, 0.0));
    let slope = Vector2::new(x[1], x[2]);
    let undulations = terms
        .iter()
        .enumerate()
        .map(|(j, (axis, k, lo))| {
            let (s_coef, c_coef) = (x[3 + 2 * j], x[4 + 2 * j]);
            // A sin(k (axis . (q - c) - lo) + phi), phi = atan2(c, s)
            Undulation {
                amplitude_m: s_coef.hypot(c_coef),
                wave_vector: axis * *k,
                phase_rad: c_coef.atan2(s_coef) - k * (axis.dot(&centre.xy()) + lo),
            }
        })
        .collect();
    let mut ground = Ground {
        base_height_m: x[0] - slope.dot(&centre.xy()),
        slope,
        undulations,
        crown: None,
        roughness: None,
    };
    let (mut sum, mut max) = (0.0, 0.0f64);
    for p in &road {
        let e = ground.height(p.x, p.y) - p.z;
        sum += e * e;
        max = max.max(e.abs());
    }
    ground.roughness = roughness;
    let fit = GroundFit {
        rms_m: (sum / road.len() as f64).sqrt(),
        max_m: max,
    };
    (ground, fit)
}

/// The ground an upright static covers.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Footprint {
    /// A disc: poles, trees (their crowns), shrubs.
    Circle { centre: Point2<f64>, radius_m: f64 },
    /// A rectangle whose first half extent lies along `yaw_rad`: buildings,
    /// guard rails, walls.
    Rectangle {
        centre: Point2<f64>,
        yaw_rad: f64,
        half_extents_m: Vector2<f64>,
    },
}

impl Footprint {
    /// An object's footprint: its rectangle for a box, its disc otherwise.
    fn of(object: &StaticObject) -> Footprint {
        let centre = Point2::from(object.t_world_object.translation.vector.xy());
        match object.shape {
            Shape::Cuboid { half_extents_m } => {
                let x_axis = object.t_world_object.rotation * Vector3::x();
                Footprint::Rectangle {
                    centre,
                    yaw_rad: x_axis.y.atan2(x_axis.x),
                    half_extents_m: half_extents_m.xy(),
                }
            }
            Shape::Cylinder { radius_m, .. } | Shape::Ball { radius_m } => {
                Footprint::Circle { centre, radius_m }
            }
        }
    }

    /// The rectangle `width_m` wide from `p0` to `p1` (a [`cuboid_between`]'s).
    fn between(p0: Point2<f64>, p1: Point2<f64>, width_m: f64) -> Footprint {
        let d = p1 - p0;
        Footprint::Rectangle {
            centre: nalgebra::center(&p0, &p1),
            yaw_rad: d.y.atan2(d.x),
            half_extents_m: Vector2::new(0.5 * d.norm(), 0.5 * width_m),
        }
    }

    /// A rectangle's unit axes: along `yaw_rad` (its first half extent) and across.
    fn rectangle_axes(yaw_rad: f64) -> (Vector2<f64>, Vector2<f64>) {
        let (sin, cos) = yaw_rad.sin_cos();
        (Vector2::new(cos, sin), Vector2::new(-sin, cos))
    }

    /// Distance from `p` to the footprint, 0 inside it, m.
    fn distance_m(&self, p: &Point2<f64>) -> f64 {
        match *self {
            Footprint::Circle { centre, radius_m } => ((p - centre).norm() - radius_m).max(0.0),
            Footprint::Rectangle {
                centre,
                yaw_rad,
                half_extents_m,
            } => {
                let (along, across) = Footprint::rectangle_axes(yaw_rad);
                let d = p - centre;
                let local = Vector2::new(along.dot(&d), across.dot(&d));
                local
                    .abs()
                    .zip_map(&half_extents_m, |l, h| (l - h).max(0.0))
                    .norm()
            }
        }
    }

    /// Points of the footprint with how far it reaches around each, m: a
    /// circle's centre and radius; a rectangle's centre and its outline at
    /// most [`OUTLINE_SAMPLE_M`] apart, reaching 0. Every point of the
    /// footprint is within reach of one of them, and every point within a
    /// distance d of the footprint is within about d + OUTLINE_SAMPLE_M / 2.
    fn probes(&self) -> Vec<(Point2<f64>, f64)> {
        match *self {
            Footprint::Circle { centre, radius_m } => vec![(centre, radius_m)],
            Footprint::Rectangle {
                centre,
                yaw_rad,
                half_extents_m,
            } => {
                let (along, across) = Footprint::rectangle_axes(yaw_rad);
                let along = along * half_extents_m.x;
                let across = across * half_extents_m.y;
                let corners = [
                    centre - along - across,
                    centre + along - across,
                    centre + along + across,
                    centre - along + across,
                ];
                let mut probes = vec![(centre, 0.0)];
                for (i, a) in corners.iter().enumerate() {
                    let b = corners[(i + 1) % 4];
                    let pieces = ((b - a).norm() / OUTLINE_SAMPLE_M).ceil().max(1.0) as usize;
                    probes.extend(
                        (0..pieces).map(|k| (a + (b - a) * (k as f64 / pieces as f64), 0.0)),
                    );
                }
                probes
            }
        }
    }
}

/// Where the statics must keep clear of: the carriageway and the agents.
struct Clearance<'a> {
    path: &'a LanePath,
    /// Agent footprint circles (centre, radius) at their labelled times.
    agents: Vec<(Point2<f64>, f64)>,
    /// Road edge right (index 0) and left (1), m from the path.
    edge_m: [f64; 2],
}

impl Clearance<'_> {
    /// Whether `footprint` keeps [`AGENT_CLEARANCE_M`] from every agent
    /// circle and reaches at most [`EDGE_TOLERANCE_M`] inside the road edge
    /// (of the side of the path it is on) anywhere along the path.
    fn free(&self, footprint: &Footprint) -> bool {
        let widest_m = self.edge_m[0].max(self.edge_m[1]);
        let off_road = footprint.probes().iter().all(|(p, reach_m)| {
            match self.path.project_near(p, widest_m + reach_m) {
                Some((_, lateral)) => {
                    let edge = self.edge_m[usize::from(lateral > 0.0)];
                    lateral.abs() - reach_m >= edge - EDGE_TOLERANCE_M
                }
                None => true,
            }
        });
        off_road
            && self
                .agents
                .iter()
                .all(|(c, r)| footprint.distance_m(c) >= r + AGENT_CLEARANCE_M)
    }
}

/// The path through the ego's positions (points at least 1 m apart),
/// extended straight by [`EXTENSION_M`] at both ends.
fn corridor_path(ego: &Trajectory, duration_s: f64) -> Option<LanePath> {
    let steps = ((duration_s / 0.1).ceil() as usize).max(1);
    let mut points: Vec<Point2<f64>> = Vec::new();
    for i in 0..=steps {
        let p = Point2::from(
            ego.pose_at(duration_s * i as f64 / steps as f64)
                .translation
                .vector
                .xy(),
        );
        if points.last().is_none_or(|q| (p - q).norm() >= 1.0) {
            points.push(p);
        }
    }
    let heading = |t: f64| {
        let (_, _, yaw) = ego.pose_at(t).rotation.euler_angles();
        Vector2::new(yaw.cos(), yaw.sin())
    };
    let first = points[0] - heading(0.0) * EXTENSION_M;
    let last_point = points[points.len() - 1];
    let mut all = vec![first];
    all.extend(points);
    all.push(last_point + heading(duration_s) * EXTENSION_M);
    LanePath::from_points(&all).ok()
}

/// The statics of `corridor` along the ego's path (see the module docs).
pub(super) fn statics(
    corridor: Corridor,
    ego: &Trajectory,
    duration_s: f64,
    ground: &Ground,
    agents: &[Agent],
    rng: &mut ChaCha8Rng,
) -> Vec<StaticObject> {
    let Some(path) = corridor_path(ego, duration_s) else {
        return Vec::new();
    };
    let mut footprints = Vec::new();
    let mut edge_m = [DEFAULT_EDGE_M; 2];
    for agent in agents {
        let radius = 0.5 * agent.size_lwh_m.xy().norm();
        let (t0, t1) = (
            agent.presence.from_s.max(agent.trajectory.start_s()),
            agent.presence.until_s.min(agent.trajectory.end_s()),
        );
        let steps = (((t1 - t0) / 0.5).ceil() as usize).clamp(1, 10_000);
        for i in 0..=steps {
            let t = t0 + (t1 - t0) * i as f64 / steps as f64;
            let c = Point2::from(agent.trajectory.pose_at(t).translation.vector.xy());
            footprints.push((c, radius));
            if matches!(agent.class, ObjectClass::Car | ObjectClass::Truck)
                && let Some((_, lateral)) = path.project_near(&c, EDGE_SEARCH_M)
                && lateral.abs() <= EDGE_SEARCH_M
            {
                let side = usize::from(lateral > 0.0);
                edge_m[side] = edge_m[side].max(lateral.abs() + agent.size_lwh_m.y * 0.5 + 1.0);
            }
        }
    }
    let clearance = Clearance {
        path: &path,
        agents: footprints,
        edge_m,
    };
    let mut out = Vec::new();
    for (side_index, side) in [(0usize, -1.0), (1, 1.0)] {
        let edge = clearance.edge_m[side_index];
        let lining = Lining {
            path: &path,
            ground,
            clearance: &clearance,
            side,
            edge_m: edge,
        };
        match corridor {
            Corridor::Residential => lining.residential(rng, &mut out),
            Corridor::City => lining.city(rng, &mut out),
            Corridor::Highway => lining.highway(rng, &mut out),
        }
    }
    if corridor == Corridor::Highway {
        out.extend(highway_roadside(&path, ground, &clearance, rng));
    }
    out
}

/// Beyond a highway corridor's rails, the highway family's roadside: rail
/// posts, delineators, noise walls, cuttings, bushes and trees, overpasses,
/// signs and gantries. Overpass decks and gantry beams span the road above
/// the traffic; every other object is kept only where it is clear.
fn highway_roadside(
    path: &LanePath,
    ground: &Ground,
    clearance: &Clearance,
    rng: &mut ChaCha8Rng,
) -> Vec<StaticObject> {
    let rail_face_m = HIGHWAY_RAIL_OFFSET_M + 0.5 * HIGHWAY_RAIL_WIDTH_M;
    let section = CrossSection {
        right_rail_m: -(clearance.edge_m[0] + rail_face_m),
        left_rail_m: clearance.edge_m[1] + rail_face_m,
    };
    let seed: u64 = rng.random();
    roadside(
        &HighwayParams::default(),
        path,
        ground,
        &section,
        (0.0, path.length_m()),
        seed,
    )
    .into_iter()
    .filter(|o| o.kind == StaticKind::Bridge || clearance.free(&Footprint::of(o)))
    .collect()
}

/// One side of the corridor being lined.
struct Lining<'a> {
    path: &'a LanePath,
    ground: &'a Ground,
    clearance: &'a Clearance<'a>,
    /// -1 right, +1 left.
    side: f64,
    edge_m: f64,
}

impl Lining<'_> {
    fn at(&self, s_m: f64, offset_m: f64) -> Point2<f64> {
        beside(self.path, s_m, self.side * (self.edge_m + offset_m))
    }

    /// Arc lengths from the start, each next `step` further.
    fn walk(
        &self,
        rng: &mut ChaCha8Rng,
        step: (f64, f64),
        mut place: impl FnMut(f64, &mut ChaCha8Rng),
    ) {
        let mut s = uniform(rng, 0.0, step.1);
        while s < self.path.length_m() {
            place(s, rng);
            s += uniform(rng, step.0, step.1);
        }
    }

    /// A building block `size_m` (length along the path, depth, height)
    /// centred at arc length `s` with its street face `front_m` beyond the
    /// edge. Where that is not clear it is set back by up to
    /// [`SETBACK_STEPS`] of [`SETBACK_STEP_M`]; where none is, it is split
    /// into two halves placed alike, and dropped when the halves would be
    /// shorter than [`MIN_BUILDING_LENGTH_M`].
    fn building(&self, s: f64, front_m: f64, size_m: Vector3<f64>, out: &mut Vec<StaticObject>) {
        let yaw = self.path.heading_at(s);
        for step in 0..=SETBACK_STEPS {
            let front = front_m + step as f64 * SETBACK_STEP_M;
            let at = self.at(s, front + 0.5 * size_m.y);
            let footprint = Footprint::Rectangle {
                centre: at,
                yaw_rad: yaw,
                half_extents_m: 0.5 * size_m.xy(),
            };
            if self.clearance.free(&footprint) {
                out.push(upright_static(
                    self.ground,
                    StaticKind::Building,
                    Shape::Cuboid {
                        half_extents_m: size_m * 0.5 + Vector3::new(0.0, 0.0, 0.25),
                    },
                    at,
                    -0.5,
                    yaw,
                ));
                return;
            }
        }
        let half_length_m = 0.5 * size_m.x;
        if half_length_m >= MIN_BUILDING_LENGTH_M {
            let half = Vector3::new(half_length_m, size_m.y, size_m.z);
            self.building(s - 0.5 * half_length_m, front_m, half, out);
            self.building(s + 0.5 * half_length_m, front_m, half, out);
        }
    }

    fn pole(&self, s: f64, offset_m: f64, height_m: f64, out: &mut Vec<StaticObject>) {
        let at = self.at(s, offset_m);
        if !self.clearance.free(&Footprint::Circle {
            centre: at,
            radius_m: 0.2,
        }) {
            return;
        }
        out.push(upright_static(
            self.ground,
            StaticKind::Pole,
            Shape::Cylinder {
                radius_m: 0.08,
                half_height_m: 0.5 * height_m + 0.1,
            },
            at,
            -0.2,
            0.0,
        ));
    }

    /// A tree at `offset_m` beyond the edge, drawn whether or not it is kept
    /// (the draws never depend on the clearance); kept when a circle of
    /// [`TREE_CLEARANCE_M`] around its trunk is clear.
    fn tree(&self, s: f64, offset_m: f64, rng: &mut ChaCha8Rng, out: &mut Vec<StaticObject>) {
        let at = self.at(s, offset_m);
        let tree = tree(self.ground, at, (2.5, 4.5), (0.12, 0.25), (1.4, 2.4), rng);
        if self.clearance.free(&Footprint::Circle {
            centre: at,
            radius_m: TREE_CLEARANCE_M,
        }) {
            out.extend(tree);
        }
    }

    /// A straight piece of a strip (rail, kerb, fence, hedge, wall) between
    /// two ground points, `width_m` wide from `heights_m.0` to `heights_m.1`
    /// above the ground, kept where clear.
    fn strip(
        &self,
        kind: StaticKind,
        (p0, p1): (Point2<f64>, Point2<f64>),
        width_m: f64,
        heights_m: (f64, f64),
        out: &mut Vec<StaticObject>,
    ) {
        if self.clearance.free(&Footprint::between(p0, p1, width_m)) {
            out.push(cuboid_between(
                self.ground,
                kind,
                p0,
                p1,
                width_m,
                heights_m,
            ));
        }
    }

    /// A raised sidewalk along the road edge: slabs of [`KERB_SEGMENT_M`]
    /// whose road-side face is the kerb, where clear.
    fn sidewalk(&self, out: &mut Vec<StaticObject>) {
        let mut s = 0.0;
        while s < self.path.length_m() {
            let end = (s + KERB_SEGMENT_M).min(self.path.length_m());
            let offset = 0.5 * SIDEWALK_WIDTH_M;
            let (p0, p1) = (self.at(s, offset), self.at(end, offset));
            if (p1 - p0).norm() > 0.1 {
                let heights_m = (-0.2, KERB_HEIGHT_M);
                self.strip(StaticKind::Kerb, (p0, p1), SIDEWALK_WIDTH_M, heights_m, out);
            }
            s = end;
        }
    }

    /// The front boundaries of the plots along the street, [`PLOT_LINE_M`]
    /// beyond the edge: per plot (12-25 m along the path) a fence, a hedge, a
    /// low wall or nothing, with a driveway gap at one end; drawn whether or
    /// not they are kept, kept piece by piece where clear.
    fn plot_fronts(&self, rng: &mut ChaCha8Rng, out: &mut Vec<StaticObject>) {
        let mut s = uniform(rng, 0.0, 10.0);
        while s < self.path.length_m() {
            let plot_m = uniform(rng, 12.0, 25.0);
            let gap_m = uniform(rng, 3.0, 4.5);
            let kind = uniform(rng, 0.0, 1.0);
            let height_m = uniform(rng, 0.0, 1.0);
            let (kind, width_m, top_m) = match kind {
                k if k < 0.35 => (StaticKind::Fence, 0.06, 0.9 + 0.5 * height_m),
                k if k < 0.7 => (StaticKind::Shrub, 0.8, 1.0 + 0.8 * height_m),
                k if k < 0.85 => (StaticKind::Wall, 0.25, 0.5 + 0.5 * height_m),
                _ => {
                    s += plot_m;
                    continue;
                }
            };
            let mut a = s + gap_m;
            let end = (s + plot_m).min(self.path.length_m());
            while a + 0.5 < end {
                let b = (a + PLOT_FRONT_SEGMENT_M).min(end);
                let ends = (self.at(a, PLOT_LINE_M), self.at(b, PLOT_LINE_M));
                self.strip(kind, ends, width_m, (-0.1, top_m), out);
                a = b;
            }
            s += plot_m;
        }
    }

    /// A row of houses, one every `spacing` (m), each drawn with its length,
    /// depth and height from `size` and its street face `front` beyond the
    /// edge (ranges, m).
    fn houses(
        &self,
        rng: &mut ChaCha8Rng,
        spacing: (f64, f64),
        size: [(f64, f64); 3],
        front: (f64, f64),
        out: &mut Vec<StaticObject>,
    ) {
        self.walk(rng, spacing, |s, rng| {
            let [l, d, h] = size.map(|(lo, hi)| uniform(rng, lo, hi));
            let front = uniform(rng, front.0, front.1);
            self.building(s, front, Vector3::new(l, d, h), out);
        });
    }

    /// A row of trees, one every `spacing`, each `offset` beyond the edge
    /// (ranges, m).
    fn trees(
        &self,
        rng: &mut ChaCha8Rng,
        spacing: (f64, f64),
        offset: (f64, f64),
        out: &mut Vec<StaticObject>,
    ) {
        self.walk(rng, spacing, |s, rng| {
            let offset = uniform(rng, offset.0, offset.1);
            self.tree(s, offset, rng, out);
        });
    }

    fn residential(&self, rng: &mut ChaCha8Rng, out: &mut Vec<StaticObject>) {
        self.sidewalk(out);
        self.plot_fronts(rng, out);
        self.houses(
            rng,
            (14.0, 24.0),
            [(8.0, 12.0), (8.0, 11.0), (5.5, 8.5)],
            (4.0, 9.0),
            out,
        );
        self.trees(rng, (8.0, 16.0), (1.0, 3.0), out);
        self.walk(rng, (30.0, 45.0), |s, _| self.pole(s, 0.6, 7.0, out));
        // Behind the houses: garden trees and the next row of houses, which
        // hide the ground beyond the street as a town's blocks do (open
        // ground to the horizon is what a point-to-point ICP slips on).
        self.trees(rng, (6.0, 12.0), (13.0, 20.0), out);
        self.houses(
            rng,
            (12.0, 20.0),
            [(8.0, 14.0), (8.0, 12.0), (5.5, 9.0)],
            (22.0, 30.0),
            out,
        );
        self.walk(rng, (5.0, 10.0), |s, rng| {
            let at = self.at(s, uniform(rng, 2.5, 3.5));
            let r = uniform(rng, 0.5, 1.0);
            if self.clearance.free(&Footprint::Circle {
                centre: at,
                radius_m: r,
            }) {
                out.push(upright_static(
                    self.ground,
                    StaticKind::Shrub,
                    Shape::Ball { radius_m: r },
                    at,
                    -r / 3.0,
                    0.0,
                ));
            }
        });
    }

    fn city(&self, rng: &mut ChaCha8Rng, out: &mut Vec<StaticObject>) {
        let mut s = uniform(rng, 0.0, 10.0);
        while s < self.path.length_m() {
            let width = uniform(rng, 12.0, 30.0);
            let size = Vector3::new(width, uniform(rng, 12.0, 16.0), uniform(rng, 12.0, 22.0));
            let front = uniform(rng, 3.0, 5.0);
            self.building(s + 0.5 * width, front, size, out);
            s += width + uniform(rng, 0.0, 4.0);
        }
        self.walk(rng, (25.0, 35.0), |s, _| self.pole(s, 0.8, 8.0, out));
        self.walk(rng, (15.0, 30.0), |s, rng| {
            if uniform(rng, 0.0, 1.0) < 0.5 {
                self.tree(s, 1.8, rng, out);
            }
        });
    }

    /// The rails and light poles; the rest of the roadside is the highway
    /// family's (see [`statics`]).
    fn highway(&self, rng: &mut ChaCha8Rng, out: &mut Vec<StaticObject>) {
        const RAIL_SEGMENT_M: f64 = 4.0;
        let rail_offset = HIGHWAY_RAIL_OFFSET_M;
        let mut s = 0.0;
        while s + RAIL_SEGMENT_M <= self.path.length_m() {
            let ends = (
                self.at(s, rail_offset),
                self.at(s + RAIL_SEGMENT_M, rail_offset),
            );
            let kind = StaticKind::GuardRail;
            self.strip(kind, ends, HIGHWAY_RAIL_WIDTH_M, (0.45, 0.8), out);
            s += RAIL_SEGMENT_M;
        }
        self.walk(rng, (45.0, 60.0), |s, _| self.pole(s, 2.0, 10.0, out));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn flat() -> Ground {
        Ground {
            base_height_m: 0.0,
            slope: Vector2::zeros(),
            undulations: Vec::new(),
            crown: None,
            roughness: None,
        }
    }

    /// The clearance of a street with the default edges on both sides.
    fn street_clearance(path: &LanePath, agents: Vec<(Point2<f64>, f64)>) -> Clearance<'_> {
        Clearance {
            path,
            agents,
            edge_m: [DEFAULT_EDGE_M; 2],
        }
    }

    /// The lining of the street's left side.
    fn left_side<'a>(
        path: &'a LanePath,
        ground: &'a Ground,
        clearance: &'a Clearance<'a>,
    ) -> Lining<'a> {
        Lining {
            path,
            ground,
            clearance,
            side: 1.0,
            edge_m: DEFAULT_EDGE_M,
        }
    }

    /// Distance from `p` to a static's footprint, computed from its pose.
    fn distance_to_static_m(object: &StaticObject, p: &Point2<f64>) -> f64 {
        let Shape::Cuboid { half_extents_m } = object.shape else {
            panic!("not a box: {object:?}");
        };
        let local = object.t_world_object.inverse_transform_point(&Point3::new(
            p.x,
            p.y,
            object.t_world_object.translation.z,
        ));
        Vector2::new(
            (local.x.abs() - half_extents_m.x).max(0.0),
            (local.y.abs() - half_extents_m.y).max(0.0),
        )
        .norm()
    }

    fn corners(object: &StaticObject) -> Vec<Point2<f64>> {
        let Shape::Cuboid { half_extents_m: h } = object.shape else {
            panic!("not a box: {object:?}");
        };
        [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .iter()
            .map(|(a, b)| {
                object
                    .t_world_object
                    .transform_point(&Point3::new(a * h.x, b * h.y, 0.0))
                    .xy()
            })
            .collect()
    }

    #[test]
    fn a_long_building_near_a_walker_is_kept_clear_of_it_and_of_the_road() {
        let path =
            LanePath::from_points(&[Point2::new(0.0, 0.0), Point2::new(200.0, 0.0)]).unwrap();
        // a walker on the left sidewalk 2.5 m beyond the edge, near the west
        // end of a building whose street face would be 3 m beyond the edge
        let walker = (Point2::new(90.0, DEFAULT_EDGE_M + 2.5), 0.4);
        let clearance = Clearance {
            path: &path,
            agents: vec![walker],
            edge_m: [DEFAULT_EDGE_M; 2],
        };
        let ground = flat();
        let lining = Lining {
            path: &path,
            ground: &ground,
            clearance: &clearance,
            side: 1.0,
            edge_m: DEFAULT_EDGE_M,
        };
        let mut out = Vec::new();
        lining.building(100.0, 3.0, Vector3::new(30.0, 14.0, 15.0), &mut out);
        assert!(!out.is_empty(), "the building was dropped");
        assert!(
            out.iter()
                .all(|o| o.t_world_object.translation.y > lining.at(100.0, 10.0).y),
            "not set back"
        );
        // the old test, a circle of half the diagonal, would have dropped it
        assert!((walker.0 - lining.at(100.0, 10.0)).norm() < 0.5 * 30.0f64.hypot(14.0));
        let length_m: f64 = out
            .iter()
            .map(|o| match o.shape {
                Shape::Cuboid { half_extents_m } => 2.0 * half_extents_m.x,
                _ => 0.0,
            })
            .sum();
        assert!(length_m >= 15.0 - 1e-9, "only {length_m} m of 30 m kept");
        for object in &out {
            assert_eq!(object.kind, StaticKind::Building);
            let gap_m = distance_to_static_m(object, &walker.0) - walker.1;
            assert!(
                gap_m >= AGENT_CLEARANCE_M - 1e-9,
                "{gap_m} m from the walker"
            );
            for c in corners(object) {
                assert!(c.y >= DEFAULT_EDGE_M - EDGE_TOLERANCE_M, "{c} on the road");
            }
        }
    }

    #[test]
    fn a_rectangle_is_tested_exactly_and_a_circle_by_its_radius() {
        let path =
            LanePath::from_points(&[Point2::new(0.0, 0.0), Point2::new(100.0, 0.0)]).unwrap();
        let clearance = Clearance {
            path: &path,
            agents: vec![(Point2::new(50.0, 8.0), 0.5)],
            edge_m: [4.0, 6.0],
        };
        let rectangle = |x: f64, y: f64| Footprint::Rectangle {
            centre: Point2::new(x, y),
            yaw_rad: 0.0,
            half_extents_m: Vector2::new(2.0, 0.15),
        };
        // a guard rail 1 m beyond each edge; the left edge is the wider one
        assert!(clearance.free(&rectangle(20.0, -5.0)));
        assert!(clearance.free(&rectangle(20.0, 7.0)));
        assert!(
            !clearance.free(&rectangle(20.0, 5.0)),
            "inside the left edge"
        );
        // beside the agent: 0.85 m from its circle's edge clears, 0.35 m does not
        assert!(clearance.free(&rectangle(53.35, 8.0)));
        assert!(!clearance.free(&rectangle(52.85, 8.0)));
        let circle = |y: f64| Footprint::Circle {
            centre: Point2::new(20.0, y),
            radius_m: 1.0,
        };
        assert!(clearance.free(&circle(-4.5)));
        assert!(!clearance.free(&circle(-4.4)));
        // a rectangle across the path is caught by its outline
        let across = Footprint::Rectangle {
            centre: Point2::new(30.0, 0.0),
            yaw_rad: std::f64::consts::FRAC_PI_2,
            half_extents_m: Vector2::new(40.0, 0.2),
        };
        assert!(!clearance.free(&across));
    }

    #[test]
    fn the_draws_do_not_depend_on_what_is_kept() {
        let path =
            LanePath::from_points(&[Point2::new(0.0, 0.0), Point2::new(300.0, 0.0)]).unwrap();
        let ground = flat();
        let crowded: Vec<_> = (0..60)
            .map(|i| (Point2::new(5.0 * i as f64, DEFAULT_EDGE_M + 2.0), 0.4))
            .collect();
        let draws_after = |agents: Vec<(Point2<f64>, f64)>| {
            let clearance = street_clearance(&path, agents);
            let lining = left_side(&path, &ground, &clearance);
            let mut rng = ChaCha8Rng::seed_from_u64(7);
            let mut out = Vec::new();
            lining.city(&mut rng, &mut out);
            lining.residential(&mut rng, &mut out);
            (out.len(), uniform(&mut rng, 0.0, 1.0))
        };
        let (empty_kept, empty_next) = draws_after(Vec::new());
        let (crowded_kept, crowded_next) = draws_after(crowded);
        assert!(crowded_kept < empty_kept);
        assert_eq!(empty_next, crowded_next);
    }

    #[test]
    fn a_residential_street_is_lined_by_sidewalks_and_plot_fronts_clear_of_the_road() {
        let path =
            LanePath::from_points(&[Point2::new(0.0, 0.0), Point2::new(300.0, 0.0)]).unwrap();
        let ground = flat();
        // a pedestrian on the left sidewalk at x = 150
        let walker = (Point2::new(150.0, DEFAULT_EDGE_M + 1.0), 0.4);
        let clearance = street_clearance(&path, vec![walker]);
        let lining = left_side(&path, &ground, &clearance);
        let mut out = Vec::new();
        lining.residential(&mut ChaCha8Rng::seed_from_u64(3), &mut out);
        let length_of = |kinds: &[StaticKind]| -> f64 {
            out.iter()
                .filter(|o| kinds.contains(&o.kind))
                .map(|o| match o.shape {
                    Shape::Cuboid { half_extents_m } => 2.0 * half_extents_m.x,
                    _ => 0.0,
                })
                .sum()
        };
        // sidewalk slabs along the whole street but where the walker is
        let kerb_m = length_of(&[StaticKind::Kerb]);
        assert!(
            kerb_m > 300.0 - 2.0 * KERB_SEGMENT_M - 0.1 && kerb_m < 300.0,
            "{kerb_m}"
        );
        // plot fronts along most of it (a plot in seven has none, and gaps)
        let fronts_m = length_of(&[StaticKind::Fence, StaticKind::Shrub, StaticKind::Wall]);
        assert!(fronts_m > 100.0, "{fronts_m}");
        for o in &out {
            // nothing inside the road edge (beyond the kerb's tolerance)
            for c in corners_or_centre(o) {
                assert!(
                    c.y > DEFAULT_EDGE_M - EDGE_TOLERANCE_M,
                    "{:?} at {c}",
                    o.kind
                );
            }
            if o.kind == StaticKind::Kerb {
                assert!(distance_to_static_m(o, &walker.0) > walker.1 + AGENT_CLEARANCE_M - 1e-9);
                let top = o.t_world_object.translation.z
                    + match o.shape {
                        Shape::Cuboid { half_extents_m } => half_extents_m.z,
                        _ => 0.0,
                    };
                assert!((top - KERB_HEIGHT_M).abs() < 1e-9, "{top}");
            }
        }
    }

    /// A box's footprint corners, or a round static's centre.
    fn corners_or_centre(object: &StaticObject) -> Vec<Point2<f64>> {
        match object.shape {
            Shape::Cuboid { .. } => corners(object),
            _ => vec![object.t_world_object.translation.vector.xy().into()],
        }
    }

    #[test]
    fn a_highway_roadside_stays_off_the_road_and_clear_of_the_agents() {
        let path =
            LanePath::from_points(&[Point2::new(0.0, 0.0), Point2::new(600.0, 0.0)]).unwrap();
        let ground = flat();
        // a broken-down car on the right verge, 4 m beyond the edge
        let car = (Point2::new(300.0, -(DEFAULT_EDGE_M + 4.0)), 2.2);
        let clearance = Clearance {
            path: &path,
            agents: vec![car],
            edge_m: [DEFAULT_EDGE_M, DEFAULT_EDGE_M + 3.0],
        };
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let out = highway_roadside(&path, &ground, &clearance, &mut rng);
        let count = |kind| out.iter().filter(|o| o.kind == kind).count();
        // posts every 2 m under both rails, delineators, vegetation
        assert!(
            count(StaticKind::GuardRail) > 400,
            "{}",
            count(StaticKind::GuardRail)
        );
        assert!(count(StaticKind::Pole) >= 10);
        assert!(count(StaticKind::Shrub) + count(StaticKind::TreeCrown) > 20);
        for object in out.iter().filter(|o| o.kind != StaticKind::Bridge) {
            let centre = object.t_world_object.translation.vector.xy();
            let (gap_m, nearest_to_path_m) = match object.shape {
                Shape::Cuboid { .. } => (
                    distance_to_static_m(object, &car.0),
                    corners(object)
                        .iter()
                        .map(|c| c.y.abs())
                        .fold(f64::INFINITY, f64::min),
                ),
                Shape::Cylinder { radius_m, .. } | Shape::Ball { radius_m } => (
                    (centre - car.0.coords).norm() - radius_m,
                    centre.y.abs() - radius_m,
                ),
            };
            assert!(
                gap_m - car.1 >= AGENT_CLEARANCE_M - 1e-9,
                "{:?} at {centre:?}: {gap_m} m from the car",
                object.kind
            );
            let edge = clearance.edge_m[usize::from(centre.y > 0.0)];
            assert!(
                nearest_to_path_m >= edge - EDGE_TOLERANCE_M - 1e-9,
                "{:?} at {centre:?} on the road",
                object.kind
            );
        }
    }
}
