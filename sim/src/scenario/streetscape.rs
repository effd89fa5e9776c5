//! The urban street's detail: raised sidewalks with kerbs, facade detail on
//! the buildings (pilasters, window sills, balconies, shop awnings, door
//! canopies and steps, cornices), front-garden fences and hedges, and street
//! furniture (traffic signs, bollards, bins, benches, bus shelters). All
//! seeded from the scenario seed's own ChaCha stream, so the street's
//! layout, buildings and traffic stay what they are.
//!
//! Everything is laid out in the street's own frame (`StreetLayout::
//! t_world_street`): the street runs along its x; `side` -1 is y < 0 (on the
//! main street the ego's side), +1 the other; lateral distances are |y|.
//! Heights come from the world's ground under each object.

use super::common::{box_on_ground, uniform, upright_static};
use crate::scene::{Ground, Shape, StaticKind, StaticObject};
use nalgebra::{Isometry2, Isometry3, Point2, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// ChaCha stream (of the scenario seed) of the street's detail.
const STREETSCAPE_STREAM: u64 = 0x0053_5452_4545; // "STREE" in ASCII
/// Height of the sidewalks above the street, m.
pub(crate) const KERB_HEIGHT_M: f64 = 0.12;
/// Sidewalk slabs are cut into pieces of at most this length (they follow
/// the ground's slope piece by piece), m.
const SLAB_LENGTH_M: f64 = 8.0;
/// The sidewalk slabs end this far before a cross street (the dropped
/// kerb's apron), and a walker's height offset ramps from 0 at the cross
/// street to the full kerb height over the apron less half a walker's
/// length, so no walker's body meets a slab's end, m.
const APRON_M: f64 = 1.0;
const WALKER_HALF_LENGTH_M: f64 = 0.35;
/// Walkers' soles clear the slabs' flat tops by this much over the
/// ground's curvature under an 8 m slab, m.
const SOLE_CLEARANCE_M: f64 = 0.03;
/// Storey height and the facade bays' width range, m.
const STOREY_M: f64 = 3.0;
const BAY_M: (f64, f64) = (3.5, 5.0);
/// Street furniture stands this far from the kerb (centre line), m: inside
/// the furniture strip, clear of the walkers' lines.
const FURNITURE_LINE_M: f64 = 1.1;
/// Mean spacing of bins and benches (each side), bus shelters (alternating
/// sides), m.
const BIN_SPACING_M: f64 = 45.0;
const BENCH_SPACING_M: f64 = 70.0;
const SHELTER_SPACING_M: f64 = 250.0;
/// Bus shelters: centre from the kerb and depth, m; the back panel (0.05 m
/// thick) ends 1.375 m from the kerb, clear of the widest walker (0.7 m) on
/// the inner walkers' line (1.8 m from the kerb on a 4 m sidewalk).
const SHELTER_FROM_KERB_M: f64 = 0.7;
const SHELTER_DEPTH_M: f64 = 1.3;
/// Furniture keeps this far (along x) from poles and trunks, m.
const FURNITURE_CLEARANCE_M: f64 = 1.5;

/// What the street detail needs to know of the street.
pub(crate) struct StreetLayout<'a> {
    /// |y| of the kerbs and the sidewalks' width.
    pub kerb_m: f64,
    pub sidewalk_width_m: f64,
    /// Cross street centres and half width.
    pub crossings: &'a [f64],
    pub cross_half_width_m: f64,
    /// x range where the LiDAR can see the street.
    pub view: (f64, f64),
    /// Whether the sidewalks carry furniture (signs, bollards, bins,
    /// benches, shelters).
    pub furniture: bool,
    /// The street's frame in the world: origin on its axis, x along it.
    pub t_world_street: Isometry2<f64>,
}

impl StreetLayout<'_> {
    /// World point of the street-frame point `p`.
    fn world(&self, p: Point2<f64>) -> Point2<f64> {
        self.t_world_street * p
    }

    /// World yaw of a street-frame yaw.
    fn world_yaw(&self, yaw_rad: f64) -> f64 {
        self.t_world_street.rotation.angle() + yaw_rad
    }

    /// Street-frame point of the world point `p`.
    fn local(&self, p: Point2<f64>) -> Point2<f64> {
        self.t_world_street.inverse_transform_point(&p)
    }

    /// Street-frame position of `object`'s centre (on the ground plane).
    fn local_position(&self, object: &StaticObject) -> Point2<f64> {
        self.local(Point2::from(object.t_world_object.translation.vector.xy()))
    }

    /// The untextured ground height under the street-frame point (x, y).
    fn ground_height_m(&self, ground: &Ground, x: f64, y: f64) -> f64 {
        let p = self.world(Point2::new(x, y));
        ground.untextured_height(p.x, p.y)
    }

    /// `upright_static` at the street-frame point `xy`, yaw in the street frame.
    fn upright(
        &self,
        ground: &Ground,
        kind: StaticKind,
        shape: Shape,
        xy: Point2<f64>,
        base_height_m: f64,
        yaw_rad: f64,
    ) -> StaticObject {
        upright_static(
            ground,
            kind,
            shape,
            self.world(xy),
            base_height_m,
            self.world_yaw(yaw_rad),
        )
    }

    /// A box aligned with the street centred at the street-frame point
    /// `centre` (its z is the world's).
    fn boxed(&self, kind: StaticKind, centre: Vector3<f64>, size: Vector3<f64>) -> StaticObject {
        let xy = self.world(Point2::new(centre.x, centre.y));
        StaticObject {
            kind,
            shape: Shape::Cuboid {
                half_extents_m: size * 0.5,
            },
            t_world_object: Isometry3::from_parts(
                Translation3::new(xy.x, xy.y, centre.z),
                UnitQuaternion::from_euler_angles(0.0, 0.0, self.world_yaw(0.0)),
            ),
        }
    }

    /// The stretches of sidewalk between cross streets inside the view
    /// (for slabs: less the aprons).
    fn blocks(&self) -> Vec<(f64, f64)> {
        self.blocks_inset(0.0)
    }

    fn blocks_inset(&self, inset_m: f64) -> Vec<(f64, f64)> {
        self.crossings
            .windows(2)
            .map(|w| {
                (
                    (w[0] + self.cross_half_width_m + inset_m).max(self.view.0),
                    (w[1] - self.cross_half_width_m - inset_m).min(self.view.1),
                )
            })
            .filter(|(a, b)| b - a > 1.0)
            .collect()
    }

    /// How far a walker is raised at the world point (x, y): the kerb
    /// height (and a sole's clearance) on a sidewalk, falling to 0 over a
    /// dropped kerb before a cross street.
    pub fn raised_m(&self, x: f64, y: f64) -> f64 {
        let p = self.local(Point2::new(x, y));
        let (x, lateral) = (p.x, p.y.abs());
        if lateral < self.kerb_m || lateral > self.kerb_m + self.sidewalk_width_m {
            return 0.0;
        }
        let to_cross = self
            .crossings
            .iter()
            .map(|&c| (x - c).abs() - self.cross_half_width_m)
            .fold(f64::INFINITY, f64::min);
        let ramp = APRON_M - WALKER_HALF_LENGTH_M;
        (KERB_HEIGHT_M + SOLE_CLEARANCE_M) * (to_cross / ramp).clamp(0.0, 1.0)
    }
}

/// The street's detail. `statics` are the street's buildings, poles and
/// trees so far (facades get detail; furniture keeps clear of poles).
pub(crate) fn streetscape(
    street: &StreetLayout<'_>,
    ground: &Ground,
    statics: &[StaticObject],
    seed: u64,
) -> Vec<StaticObject> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(STREETSCAPE_STREAM);
    let mut out = sidewalks(street, ground);
    if street.furniture {
        furniture(street, ground, statics, &mut rng, &mut out);
    }
    out.extend(building_detail(street, ground, statics, seed));
    out
}

/// The facade detail and front gardens of the buildings among `statics`
/// that face the street (see [`facade`], [`front_garden`]).
pub(crate) fn building_detail(
    street: &StreetLayout<'_>,
    ground: &Ground,
    statics: &[StaticObject],
    seed: u64,
) -> Vec<StaticObject> {
    let mut out = Vec::new();
    for building in statics.iter().filter(|s| s.kind == StaticKind::Building) {
        // each building's detail from its own stream (keyed by where it
        // stands): a building's absence changes nothing else
        let mut own = building_rng(street, seed, building);
        facade(street, building, ground, &mut own, &mut out);
        front_garden(street, ground, building, &mut own, &mut out);
    }
    out
}

/// The stream of one building's detail: the scenario seed mixed with the
/// bits of the building's position in the street's frame, on the
/// streetscape's stream number.
fn building_rng(street: &StreetLayout<'_>, seed: u64, building: &StaticObject) -> ChaCha8Rng {
    let c = street.local_position(building);
    let mut key = seed;
    for v in [c.x, c.y] {
        key = (key ^ v.to_bits())
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .rotate_left(29);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(key);
    rng.set_stream(STREETSCAPE_STREAM);
    rng
}

/// Sidewalk slabs on both sides of every block, `KERB_HEIGHT_M` above the
/// street (their street-side faces are the kerbs).
fn sidewalks(street: &StreetLayout<'_>, ground: &Ground) -> Vec<StaticObject> {
    let mut out = Vec::new();
    let sink = 0.1;
    for side in [-1.0, 1.0] {
        let y = side * (street.kerb_m + 0.5 * street.sidewalk_width_m);
        for (x0, x1) in street.blocks_inset(APRON_M) {
            let n = ((x1 - x0) / SLAB_LENGTH_M).ceil().max(1.0);
            let length = (x1 - x0) / n;
            for k in 0..n as usize {
                let x = x0 + (k as f64 + 0.5) * length;
                out.push(box_on_ground(
                    ground,
                    StaticKind::Kerb,
                    street.world(Point2::new(x, y)),
                    street.world_yaw(0.0),
                    Vector3::new(
                        0.5 * length,
                        0.5 * street.sidewalk_width_m,
                        0.5 * (KERB_HEIGHT_M + sink),
                    ),
                    sink,
                ));
            }
        }
    }
    out
}

/// The street face of a building aligned with the street, in the street's
/// frame.
struct StreetFace {
    x0: f64,
    x1: f64,
    /// The face's y and the sign of y pointing out of it (to the street).
    y: f64,
    out_y: f64,
    /// The building's top.
    top_z: f64,
}

/// None for a building that is not a box or not aligned with the street
/// (its sides along or across it, within a millidegree).
fn street_face(street: &StreetLayout<'_>, building: &StaticObject) -> Option<StreetFace> {
    let Shape::Cuboid { half_extents_m: h } = building.shape else {
        return None;
    };
    let pose = &building.t_world_object;
    let (_, _, yaw) = pose.rotation.euler_angles();
    let relative = yaw - street.world_yaw(0.0);
    let (along, across) = if relative.sin().abs() < 1e-5 {
        (h.x, h.y)
    } else if relative.cos().abs() < 1e-5 {
        (h.y, h.x)
    } else {
        return None;
    };
    let c = street.local_position(building);
    let out_y = -c.y.signum();
    Some(StreetFace {
        x0: c.x - along,
        x1: c.x + along,
        y: c.y + out_y * across,
        out_y,
        top_z: pose.translation.vector.z + h.z,
    })
}

/// Storeys and bays on a building's street face: pilasters, window sills,
/// balconies, a shop front or a door, a cornice. Each building draws a
/// style; protrusions stay within its setback from the sidewalk.
fn facade(
    street: &StreetLayout<'_>,
    building: &StaticObject,
    ground: &Ground,
    rng: &mut ChaCha8Rng,
    out: &mut Vec<StaticObject>,
) {
    let Some(StreetFace {
        x0,
        x1,
        y: face_y,
        out_y,
        top_z,
        ..
    }) = street_face(street, building)
    else {
        return;
    };
    // storeys count from the ground at the face's middle; what stands on
    // the ground (pilasters, the door's step) starts from the ground under it
    let ground_at = |x: f64| street.ground_height_m(ground, x, face_y);
    // nothing reaches over the sidewalk
    let setback = face_y.abs() - (street.kerb_m + street.sidewalk_width_m);
    let reach = |depth: f64| depth.min(setback - 0.1).max(0.05);
    let street_z = ground_at(0.5 * (x0 + x1));
    let storeys = ((top_z - street_z) / STOREY_M).floor() as usize;
    let bays = ((x1 - x0) / uniform(rng, BAY_M.0, BAY_M.1))
        .floor()
        .max(1.0) as usize;
    let bay = (x1 - x0) / bays as f64;
    let pilasters = rng.random_bool(0.6);
    let sills = rng.random_bool(0.5);
    let balconies = rng.random_bool(0.35);
    let shops = rng.random_bool(0.4);
    let cornice = rng.random_bool(0.5);
    // a box of `depth` from `from` to `from + depth` out of the face, centred at (x, z)
    let mut protrude_from =
        |kind, from: f64, x: f64, z: f64, (width, depth, height): (f64, f64, f64)| {
            out.push(street.boxed(
                kind,
                Vector3::new(x, face_y + out_y * (from + 0.5 * depth), z),
                Vector3::new(width, depth, height),
            ))
        };
    if pilasters {
        for k in 0..=bays {
            let x = (x0 + k as f64 * bay).clamp(x0 + 0.2, x1 - 0.2);
            let foot = ground_at(x) - 0.2;
            protrude_from(
                StaticKind::Facade,
                0.0,
                x,
                0.5 * (foot + top_z),
                (0.4, 0.25, top_z - foot),
            );
        }
    }
    for storey in 1..storeys {
        let floor_z = street_z + storey as f64 * STOREY_M;
        for b in 0..bays {
            let x = x0 + (b as f64 + 0.5) * bay;
            if sills {
                protrude_from(StaticKind::Facade, 0.0, x, floor_z + 0.9, (1.4, 0.15, 0.1));
            }
            if balconies && (b + storey) % 2 == 0 {
                let width = 0.7 * bay;
                let depth = reach(1.1);
                protrude_from(
                    StaticKind::Facade,
                    0.0,
                    x,
                    floor_z + 0.08,
                    (width, depth, 0.16),
                );
                // the parapet at the balcony's front edge
                protrude_from(
                    StaticKind::Facade,
                    depth - 0.08,
                    x,
                    floor_z + 0.6,
                    (width, 0.08, 0.9),
                );
            }
        }
    }
    // street level: a shop front's awnings, or a door with canopy and step
    if shops {
        for b in 0..bays {
            let x = x0 + (b as f64 + 0.5) * bay;
            protrude_from(
                StaticKind::Facade,
                0.0,
                x,
                ground_at(x) + 2.8,
                (bay - 0.4, reach(1.0), 0.12),
            );
        }
    } else {
        let x = x0 + (rng.random_range(0..bays) as f64 + 0.5) * bay;
        let door_z = ground_at(x);
        protrude_from(
            StaticKind::Facade,
            0.0,
            x,
            door_z + 2.5,
            (1.8, reach(0.9), 0.15),
        );
        protrude_from(
            StaticKind::Facade,
            0.0,
            x,
            door_z + 0.02,
            (2.0, reach(0.6), 0.3),
        );
    }
    if cornice {
        protrude_from(
            StaticKind::Facade,
            0.0,
            0.5 * (x0 + x1),
            top_z - 0.2,
            (x1 - x0, 0.4, 0.35),
        );
    }
}

/// A fence or a hedge along the back of the sidewalk in front of a
/// building set back from it, with a gap for the gate.
fn front_garden(
    street: &StreetLayout<'_>,
    ground: &Ground,
    building: &StaticObject,
    rng: &mut ChaCha8Rng,
    out: &mut Vec<StaticObject>,
) {
    let Some(StreetFace {
        x0, x1, y: face_y, ..
    }) = street_face(street, building)
    else {
        return;
    };
    let back = street.kerb_m + street.sidewalk_width_m;
    let setback = face_y.abs() - back;
    if setback < 1.2 || !rng.random_bool(0.6) {
        return;
    }
    let side = face_y.signum();
    let y = side * (back + 0.35);
    let gate = uniform(rng, x0 + 1.5, (x1 - 1.5).max(x0 + 1.5));
    let hedge = rng.random_bool(0.5);
    let height = if hedge {
        uniform(rng, 0.9, 1.5)
    } else {
        uniform(rng, 0.9, 1.2)
    };
    for (a, b) in [(x0 + 0.3, gate - 0.6), (gate + 0.6, x1 - 0.3)] {
        if b - a < 0.5 {
            continue;
        }
        let mid = Point2::new(0.5 * (a + b), y);
        if hedge {
            out.push(street.upright(
                ground,
                StaticKind::Shrub,
                Shape::Cuboid {
                    half_extents_m: Vector3::new(0.5 * (b - a), 0.3, 0.5 * height + 0.1),
                },
                mid,
                -0.2,
                0.0,
            ));
        } else {
            // posts every 2 m and a top rail; the panels between are open
            let posts = ((b - a) / 2.0).ceil() as usize;
            for k in 0..=posts {
                let x = a + (b - a) * k as f64 / posts as f64;
                out.push(street.upright(
                    ground,
                    StaticKind::Fence,
                    Shape::Cuboid {
                        half_extents_m: Vector3::new(0.05, 0.05, 0.5 * height + 0.1),
                    },
                    Point2::new(x, y),
                    -0.2,
                    0.0,
                ));
            }
            for rail_z in [0.35, height - 0.1] {
                out.push(street.upright(
                    ground,
                    StaticKind::Fence,
                    Shape::Cuboid {
                        half_extents_m: Vector3::new(0.5 * (b - a), 0.03, 0.05),
                    },
                    mid,
                    rail_z - 0.05,
                    0.0,
                ));
            }
        }
    }
}

/// Signs before every crossing, bollards at the corners, bins, benches and
/// bus shelters along the furniture line, clear of poles and trunks.
fn furniture(
    street: &StreetLayout<'_>,
    ground: &Ground,
    statics: &[StaticObject],
    rng: &mut ChaCha8Rng,
    out: &mut Vec<StaticObject>,
) {
    let raised = KERB_HEIGHT_M;
    for side in [-1.0, 1.0] {
        let line = side * (street.kerb_m + FURNITURE_LINE_M);
        let occupied: Vec<f64> = statics
            .iter()
            .filter(|s| matches!(s.kind, StaticKind::Pole | StaticKind::TreeTrunk))
            .map(|s| street.local_position(s))
            .filter(|p| p.y * side > 0.0)
            .map(|p| p.x)
            .collect();
        let clear = |x: f64, half: f64| {
            occupied
                .iter()
                .all(|&p| (p - x).abs() > half + FURNITURE_CLEARANCE_M)
        };
        for (x0, x1) in street.blocks() {
            // traffic signs facing the traffic before the crossing ahead of
            // it (the traffic on this side drives along -side... +x on the
            // right), bollards at both corners
            let (sign_x, facing) = if side < 0.0 {
                (x1 - 3.0, 0.0)
            } else {
                (x0 + 3.0, std::f64::consts::PI)
            };
            if (street.view.0..street.view.1).contains(&sign_x) && clear(sign_x, 0.4) {
                traffic_sign(
                    street,
                    ground,
                    Point2::new(sign_x, line),
                    facing,
                    raised,
                    out,
                );
            }
            for corner in [x0 + 0.6, x1 - 0.6] {
                // clear of the walkers' lines (1.8 m and 3 m from the kerb)
                for k in 0..2 {
                    let y = side * (street.kerb_m + 0.3 + 0.8 * k as f64);
                    out.push(street.upright(
                        ground,
                        StaticKind::Pole,
                        Shape::Cylinder {
                            radius_m: 0.08,
                            half_height_m: 0.5,
                        },
                        Point2::new(corner, y),
                        raised - 0.1,
                        0.0,
                    ));
                }
            }
            let mut x = x0 + uniform(rng, 5.0, BIN_SPACING_M);
            while x < x1 - 5.0 {
                if clear(x, 0.3) {
                    out.push(street.upright(
                        ground,
                        StaticKind::Wall,
                        Shape::Cylinder {
                            radius_m: 0.3,
                            half_height_m: 0.5,
                        },
                        Point2::new(x, line),
                        raised - 0.1,
                        0.0,
                    ));
                }
                x += BIN_SPACING_M * uniform(rng, 0.6, 1.4);
            }
            let mut x = x0 + uniform(rng, 5.0, BENCH_SPACING_M);
            while x < x1 - 5.0 {
                if clear(x, 1.0) {
                    bench(street, ground, Point2::new(x, line), side, raised, out);
                }
                x += BENCH_SPACING_M * uniform(rng, 0.6, 1.4);
            }
        }
    }
    // bus shelters, alternating sides
    let mut x = street.view.0 + uniform(rng, 0.0, SHELTER_SPACING_M);
    let mut side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    while x < street.view.1 {
        let near_crossing = street
            .crossings
            .iter()
            .any(|&c| (x - c).abs() < street.cross_half_width_m + 4.0);
        let free = statics
            .iter()
            .filter(|s| matches!(s.kind, StaticKind::Pole | StaticKind::TreeTrunk))
            .map(|s| street.local_position(s))
            .all(|p| p.y * side < 0.0 || (p.x - x).abs() > 2.5);
        if !near_crossing && free {
            shelter(
                street,
                ground,
                Point2::new(x, side * (street.kerb_m + SHELTER_FROM_KERB_M)),
                side,
                raised,
                out,
            );
        }
        x += SHELTER_SPACING_M * uniform(rng, 0.7, 1.3);
        side = -side;
    }
}

/// A sign board on a thin pole, the board's face towards `facing_rad`.
fn traffic_sign(
    street: &StreetLayout<'_>,
    ground: &Ground,
    at: Point2<f64>,
    facing_rad: f64,
    raised: f64,
    out: &mut Vec<StaticObject>,
) {
    out.push(street.upright(
        ground,
        StaticKind::Pole,
        Shape::Cylinder {
            radius_m: 0.04,
            half_height_m: 1.4,
        },
        at,
        raised - 0.1,
        0.0,
    ));
    out.push(street.upright(
        ground,
        StaticKind::Sign,
        Shape::Cuboid {
            half_extents_m: Vector3::new(0.03, 0.35, 0.35),
        },
        at + nalgebra::Vector2::new(facing_rad.cos(), facing_rad.sin()) * 0.06,
        raised + 1.9,
        facing_rad,
    ));
}

/// A bench along the street: seat and back rest, facing the street.
fn bench(
    street: &StreetLayout<'_>,
    ground: &Ground,
    at: Point2<f64>,
    side: f64,
    raised: f64,
    out: &mut Vec<StaticObject>,
) {
    let seat = Shape::Cuboid {
        half_extents_m: Vector3::new(0.9, 0.25, 0.05),
    };
    out.push(street.upright(ground, StaticKind::Fence, seat, at, raised + 0.4, 0.0));
    let back = Shape::Cuboid {
        half_extents_m: Vector3::new(0.9, 0.03, 0.25),
    };
    let behind = at + nalgebra::Vector2::new(0.0, side * 0.25);
    out.push(street.upright(ground, StaticKind::Fence, back, behind, raised + 0.5, 0.0));
}

/// A bus shelter: roof, back panel and two side panels, open to the street.
fn shelter(
    street: &StreetLayout<'_>,
    ground: &Ground,
    at: Point2<f64>,
    side: f64,
    raised: f64,
    out: &mut Vec<StaticObject>,
) {
    let (length, depth, height) = (3.6, SHELTER_DEPTH_M, 2.4);
    let z = street.ground_height_m(ground, at.x, at.y) + raised;
    let place = |dx: f64, dy: f64, dz: f64, size: Vector3<f64>| {
        street.boxed(
            StaticKind::Wall,
            Vector3::new(at.x + dx, at.y + side * dy, z + dz),
            size,
        )
    };
    out.push(place(0.0, 0.0, height, Vector3::new(length, depth, 0.1)));
    out.push(place(
        0.0,
        0.5 * depth,
        0.5 * height + 0.1,
        Vector3::new(length, 0.05, height - 0.2),
    ));
    for end in [-0.5 * length, 0.5 * length] {
        out.push(place(
            end,
            0.15,
            0.5 * height + 0.1,
            Vector3::new(0.05, depth - 0.3, height - 0.2),
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    fn layout(crossings: &[f64]) -> StreetLayout<'_> {
        StreetLayout {
            kerb_m: 10.2,
            sidewalk_width_m: 4.0,
            crossings,
            cross_half_width_m: 7.0,
            view: (-150.0, 400.0),
            furniture: true,
            t_world_street: Isometry2::identity(),
        }
    }

    #[test]
    fn walkers_are_raised_on_sidewalks_only() {
        let crossings = [-200.0, 60.0, 170.0];
        let street = layout(&crossings);
        let raised = KERB_HEIGHT_M + SOLE_CLEARANCE_M;
        assert_eq!(street.raised_m(0.0, -12.0), raised);
        assert_eq!(street.raised_m(0.0, 13.9), raised);
        assert_eq!(street.raised_m(0.0, 9.0), 0.0);
        assert_eq!(street.raised_m(0.0, 15.0), 0.0);
        // a dropped kerb at the cross street's edge, none on it
        assert_eq!(street.raised_m(60.0 - 7.0, 12.0), 0.0);
        let ramp = APRON_M - WALKER_HALF_LENGTH_M;
        assert!((street.raised_m(60.0 - 7.0 - 0.5 * ramp, 12.0) - 0.5 * raised).abs() < 1e-9);
        assert!((street.raised_m(60.0 - 7.0 - ramp, 12.0) - raised).abs() < 1e-9);
        assert_eq!(street.raised_m(60.0, 12.0), 0.0);
    }

    #[test]
    fn sidewalk_slabs_cover_the_blocks_at_kerb_height_and_leave_the_street_free() {
        let crossings = [-200.0, 60.0, 170.0, 280.0, 390.0];
        let street = layout(&crossings);
        let ground = Ground::flat(0.0);
        let building = street.boxed(
            StaticKind::Building,
            Vector3::new(100.0, -(10.2 + 4.0 + 2.0 + 6.0), 8.0),
            Vector3::new(20.0, 12.0, 18.0),
        );
        let statics = streetscape(&street, &ground, std::slice::from_ref(&building), 3);
        let slabs: Vec<&StaticObject> = statics
            .iter()
            .filter(|s| s.kind == StaticKind::Kerb)
            .collect();
        assert!(slabs.len() > 100);
        for s in &statics {
            let Shape::Cuboid { half_extents_m: h } = s.shape else {
                continue;
            };
            let c = s.t_world_object.translation.vector;
            // nothing on the carriageway
            let lateral = c.y.abs() - h.y;
            assert!(lateral >= 10.2 - 1e-6, "{:?} at {c}", s.kind);
            if s.kind == StaticKind::Kerb && h.y > 1.0 {
                assert!((c.z + h.z - KERB_HEIGHT_M).abs() < 1e-9);
            }
        }
        // the facade got detail, none of it more than a metre out
        assert!(statics.iter().any(|s| s.kind == StaticKind::Facade));
        assert_eq!(statics, streetscape(&street, &ground, &[building], 3));
    }

    /// Street furniture (signs, bollards, bins, benches, shelters) stays
    /// within 1.45 m of the kerb: the urban walkers' inner line is 1.8 m out
    /// on a 4 m sidewalk and the widest walker is 0.7 m wide. (A shelter's
    /// back panel once reached 1.475 m, into a wide walker's path.)
    #[test]
    fn furniture_leaves_the_walkers_inner_line_free() {
        let crossings = [-200.0, 60.0, 170.0, 280.0, 390.0];
        let street = layout(&crossings);
        let ground = Ground::flat(0.0);
        let mut shelters = 0;
        for seed in 0..20 {
            let statics = streetscape(&street, &ground, &[], seed);
            for s in &statics {
                let c = s.t_world_object.translation.vector;
                let half_y = match s.shape {
                    Shape::Cuboid { half_extents_m } => {
                        let m = s.t_world_object.rotation.to_rotation_matrix();
                        (m.matrix().abs() * half_extents_m).y
                    }
                    Shape::Cylinder { radius_m, .. } | Shape::Ball { radius_m } => radius_m,
                };
                // on the sidewalks (not the slabs themselves)
                if s.kind == StaticKind::Kerb || c.y.abs() < 10.2 {
                    continue;
                }
                shelters += usize::from(s.kind == StaticKind::Wall && half_y < 0.1);
                let from_kerb = c.y.abs() + half_y - 10.2;
                assert!(
                    from_kerb <= 1.45,
                    "seed {seed}: {:?} reaches {from_kerb} m",
                    s.kind
                );
            }
        }
        assert!(shelters > 0);
    }

    /// A street turned and moved in the world gets the same detail, turned
    /// and moved with it.
    #[test]
    fn a_street_in_another_frame_gets_the_same_detail_in_that_frame() {
        let crossings = [-200.0, 60.0, 170.0];
        let along_x = layout(&crossings);
        let t_world_street = Isometry2::new(Vector2::new(50.0, -3.0), -0.5 * std::f64::consts::PI);
        let turned = StreetLayout {
            t_world_street,
            ..layout(&crossings)
        };
        let ground = Ground::flat(0.0);
        let centre = Vector3::new(100.0, -(10.2 + 4.0 + 2.0 + 6.0), 8.0);
        let size = Vector3::new(20.0, 12.0, 18.0);
        let a = streetscape(
            &along_x,
            &ground,
            &[along_x.boxed(StaticKind::Building, centre, size)],
            3,
        );
        let b = streetscape(
            &turned,
            &ground,
            &[turned.boxed(StaticKind::Building, centre, size)],
            3,
        );
        assert_eq!(a.len(), b.len());
        assert!(a.iter().filter(|s| s.kind == StaticKind::Facade).count() > 5);
        let turn = Isometry3::from_parts(
            Translation3::new(
                t_world_street.translation.x,
                t_world_street.translation.y,
                0.0,
            ),
            UnitQuaternion::from_euler_angles(0.0, 0.0, t_world_street.rotation.angle()),
        );
        for (a, b) in a.iter().zip(&b) {
            assert_eq!((a.kind, a.shape), (b.kind, b.shape));
            let moved = turn * a.t_world_object;
            let d = moved.translation.vector - b.t_world_object.translation.vector;
            assert!(d.norm() < 1e-9, "{:?}: {d}", a.kind);
            assert!(moved.rotation.angle_to(&b.t_world_object.rotation) < 1e-9);
        }
        // a walker on the turned street's sidewalk is raised, one on its
        // carriageway is not
        let on_sidewalk = t_world_street * Point2::new(0.0, -12.0);
        let on_street = t_world_street * Point2::new(0.0, -5.0);
        assert!(turned.raised_m(on_sidewalk.x, on_sidewalk.y) > KERB_HEIGHT_M);
        assert_eq!(turned.raised_m(on_street.x, on_street.y), 0.0);
    }
}
