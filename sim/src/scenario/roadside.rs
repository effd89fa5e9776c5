//! The highway's roadside beyond its guard rails: rail posts, delineators,
//! noise walls with their posts, cuttings (earth slopes rising beside the
//! road), bushes and trees on the verges and the median, overpasses with
//! their piers, and sign gantries. All seeded from the scenario seed's own
//! ChaCha stream, so the traffic and the rails stay what they are.
//!
//! Cross-section (right of the carriageway, `y` = lateral offset, + left):
//!
//! ```text
//! lanes | shoulder | rail (beam on posts) | light poles | verge | wall or slope or vegetation
//! ```

use super::HighwayParams;
use super::common::{beside, bush, tree, uniform, upright_static};
use crate::scene::{Ground, Shape, StaticKind, StaticObject};
use crate::traffic::LanePath;
use nalgebra::{Isometry3, Point2, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// ChaCha stream (of the scenario seed) of the roadside; the generator's
/// main stream is 0.
const ROADSIDE_STREAM: u64 = 0x0052_4f41_4453; // "ROADS" in ASCII
/// Rail posts: a sigma post's cross-section (along, across) and height, m.
const RAIL_POST_SIZE_M: (f64, f64, f64) = (0.12, 0.15, 0.75);
/// The verge: from the light poles to this far beyond the rail, m.
const VERGE_WIDTH_M: f64 = 4.5;
/// Lengths of the roadside stretches (wall, cutting or open verge), m.
const STRETCH_LENGTH_M: (f64, f64) = (80.0, 300.0);
/// Noise walls: height range, thickness, post spacing and post depth, m.
const NOISE_WALL_HEIGHT_M: (f64, f64) = (3.0, 4.5);
const NOISE_WALL_THICKNESS_M: f64 = 0.25;
const NOISE_WALL_POST_SPACING_M: f64 = 4.0;
const NOISE_WALL_POST_DEPTH_M: f64 = 0.35;
/// Every other panel stands this much farther back.
const NOISE_WALL_STAGGER_M: f64 = 0.4;
/// The right-of-way fence along open verges: distance beyond the verge
/// and post height, m.
const FENCE_OFFSET_M: f64 = 15.0;
const FENCE_HEIGHT_M: f64 = 1.6;
/// Cuttings: rise, slope (rise over run: 1:1.7 to 1:1, firm cut slopes) and
/// segment length, m.
const CUTTING_RISE_M: (f64, f64) = (2.0, 6.0);
const CUTTING_GRADE: (f64, f64) = (0.6, 1.0);
const SEGMENT_M: f64 = 20.0;
/// Vegetation on open verges and cutting tops, and bushes in the median.
const BUSH_RADIUS_M: (f64, f64) = (0.5, 1.4);
const TREE_TRUNK_HEIGHT_M: (f64, f64) = (3.2, 5.0);
const TREE_TRUNK_RADIUS_M: (f64, f64) = (0.1, 0.25);
const TREE_CROWN_RADIUS_M: (f64, f64) = (1.5, 2.2);
/// Overpasses: clearance over the road, deck thickness and width (along the
/// road), span beyond the rails, m.
const OVERPASS_CLEARANCE_M: f64 = 5.2;
const OVERPASS_DECK_M: (f64, f64) = (1.4, 11.0);
const OVERPASS_SPAN_BEYOND_RAIL_M: f64 = 20.0;
/// Gantries: post radius, beam height and the sign boards' height and width.
const GANTRY_BEAM_HEIGHT_M: f64 = 6.5;
const GANTRY_BOARD_M: (f64, f64) = (2.4, 4.0);

/// The lateral layout, from the carriageway's centre line (+ left).
pub(crate) struct CrossSection {
    /// Outer faces of the right and left rails.
    pub right_rail_m: f64,
    pub left_rail_m: f64,
}

/// Everything beside the road between arc lengths `s_lo` and `s_hi` of the
/// centre line (the stretch the ego can see).
pub(crate) fn roadside(
    h: &HighwayParams,
    reference: &LanePath,
    ground: &Ground,
    section: &CrossSection,
    (s_lo, s_hi): (f64, f64),
    seed: u64,
) -> Vec<StaticObject> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(ROADSIDE_STREAM);
    let (s_lo, s_hi) = (s_lo.max(0.0), s_hi.min(reference.length_m()));
    let mut out = Vec::new();
    if h.rail_post_spacing_m > 0.0 {
        rail_posts(h, reference, ground, section, (s_lo, s_hi), &mut out);
    }
    if h.delineator_spacing_m > 0.0 {
        delineators(h, reference, ground, section, (s_lo, s_hi), &mut out);
    }
    right_stretches(
        h,
        reference,
        ground,
        section,
        (s_lo, s_hi),
        &mut rng,
        &mut out,
    );
    median(
        h,
        reference,
        ground,
        section,
        (s_lo, s_hi),
        &mut rng,
        &mut out,
    );
    let span = (s_lo, s_hi);
    at_intervals(
        &mut rng,
        span,
        h.overpass_spacing_m,
        (0.3, 1.0),
        (0.7, 1.3),
        |s, _| overpass(reference, ground, section, s, &mut out),
    );
    at_intervals(
        &mut rng,
        span,
        h.sign_spacing_m,
        (0.0, 1.0),
        (0.6, 1.4),
        |s, rng| sign_board(reference, ground, section, s, rng, &mut out),
    );
    at_intervals(
        &mut rng,
        span,
        h.gantry_spacing_m,
        (0.2, 1.0),
        (0.7, 1.3),
        |s, rng| gantry(reference, ground, section, s, rng, &mut out),
    );
    out
}

/// Calls `place(s, rng)` at arc lengths over `span`: the first a drawn
/// fraction `first` of `spacing` in, each next a drawn multiple `step` of it
/// further; nothing when `spacing` is 0.
fn at_intervals(
    rng: &mut ChaCha8Rng,
    (s_lo, s_hi): (f64, f64),
    spacing: f64,
    first: (f64, f64),
    step: (f64, f64),
    mut place: impl FnMut(f64, &mut ChaCha8Rng),
) {
    if spacing <= 0.0 {
        return;
    }
    let mut s = s_lo + uniform(rng, first.0, first.1) * spacing;
    while s < s_hi {
        place(s, rng);
        s += spacing * uniform(rng, step.0, step.1);
    }
}

/// An upright cuboid beside the centre line, yawed with the road.
fn roadside_box(
    reference: &LanePath,
    ground: &Ground,
    kind: StaticKind,
    s: f64,
    lateral_m: f64,
    (along, across, height): (f64, f64, f64),
    base_m: f64,
) -> StaticObject {
    upright_static(
        ground,
        kind,
        Shape::Cuboid {
            half_extents_m: Vector3::new(0.5 * along, 0.5 * across, 0.5 * height),
        },
        beside(reference, s, lateral_m),
        base_m,
        reference.heading_at(s),
    )
}

/// Sigma posts under both rails' beams (the rails stand on them).
fn rail_posts(
    h: &HighwayParams,
    reference: &LanePath,
    ground: &Ground,
    section: &CrossSection,
    (s_lo, s_hi): (f64, f64),
    out: &mut Vec<StaticObject>,
) {
    let (along, across, height) = RAIL_POST_SIZE_M;
    // just outside each rail's outer face
    let offsets = [
        section.right_rail_m - 0.5 * across,
        section.left_rail_m + 0.5 * across,
    ];
    let mut s = (s_lo / h.rail_post_spacing_m).ceil() * h.rail_post_spacing_m;
    while s < s_hi {
        for lateral in offsets {
            out.push(roadside_box(
                reference,
                ground,
                StaticKind::GuardRail,
                s,
                lateral,
                (along, across, height + 0.3),
                -0.3,
            ));
        }
        s += h.rail_post_spacing_m;
    }
}

/// Reflector posts on the right shoulder's edge.
fn delineators(
    h: &HighwayParams,
    reference: &LanePath,
    ground: &Ground,
    section: &CrossSection,
    (s_lo, s_hi): (f64, f64),
    out: &mut Vec<StaticObject>,
) {
    let spacing = h.delineator_spacing_m;
    let mut s = (s_lo / spacing).ceil() * spacing + 0.5 * spacing;
    while s < s_hi {
        out.push(upright_static(
            ground,
            StaticKind::Pole,
            Shape::Cylinder {
                radius_m: 0.06,
                half_height_m: 0.6,
            },
            beside(reference, s, section.right_rail_m + 0.6),
            -0.1,
            0.0,
        ));
        s += spacing;
    }
}

/// What stands beyond the right verge over one stretch.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Stretch {
    NoiseWall,
    Cutting,
    OpenVerge,
}

/// The right side, stretch by stretch: a noise wall, a cutting, or an
/// open verge with bushes and trees.
fn right_stretches(
    h: &HighwayParams,
    reference: &LanePath,
    ground: &Ground,
    section: &CrossSection,
    (s_lo, s_hi): (f64, f64),
    rng: &mut ChaCha8Rng,
    out: &mut Vec<StaticObject>,
) {
    let verge_end = section.right_rail_m - VERGE_WIDTH_M;
    let mut s = s_lo;
    while s < s_hi {
        let length = uniform(rng, STRETCH_LENGTH_M.0, STRETCH_LENGTH_M.1).min(s_hi - s);
        let draw: f64 = rng.random();
        let kind = if draw < h.noise_wall_fraction {
            Stretch::NoiseWall
        } else if draw < h.noise_wall_fraction + h.cutting_fraction {
            Stretch::Cutting
        } else {
            Stretch::OpenVerge
        };
        match kind {
            Stretch::NoiseWall => {
                let height = uniform(rng, NOISE_WALL_HEIGHT_M.0, NOISE_WALL_HEIGHT_M.1);
                // panels between H-section posts, staggered back and forth
                // and stepped in height, as walls built of precast elements are
                let panels = (length / NOISE_WALL_POST_SPACING_M).floor().max(1.0) as usize;
                let panel = length / panels as f64;
                for k in 0..panels {
                    let stagger = if k % 2 == 0 {
                        0.0
                    } else {
                        NOISE_WALL_STAGGER_M
                    };
                    let step = uniform(rng, -0.3, 0.3);
                    out.push(roadside_box(
                        reference,
                        ground,
                        StaticKind::Wall,
                        s + (k as f64 + 0.5) * panel,
                        verge_end - stagger - 0.5 * NOISE_WALL_THICKNESS_M,
                        (panel, NOISE_WALL_THICKNESS_M, height + step + 0.5),
                        -0.5,
                    ));
                    out.push(roadside_box(
                        reference,
                        ground,
                        StaticKind::Wall,
                        s + k as f64 * panel,
                        verge_end + 0.5 * NOISE_WALL_POST_DEPTH_M - 0.5 * NOISE_WALL_STAGGER_M,
                        (
                            0.3,
                            NOISE_WALL_POST_DEPTH_M + NOISE_WALL_STAGGER_M,
                            height + 0.7,
                        ),
                        -0.5,
                    ));
                }
            }
            Stretch::Cutting => {
                let rise = uniform(rng, CUTTING_RISE_M.0, CUTTING_RISE_M.1);
                let grade = uniform(rng, CUTTING_GRADE.0, CUTTING_GRADE.1);
                let run = rise / grade;
                segments(s, length, |s0, len| {
                    out.push(slope_slab(
                        reference,
                        ground,
                        s0 + 0.5 * len,
                        len,
                        verge_end,
                        -1.0,
                        rise,
                        run,
                    ));
                });
                vegetation(
                    h.vegetation_spacing_m,
                    reference,
                    ground,
                    (s, s + length),
                    verge_end - run - 0.5,
                    (1.0, 6.0),
                    rng,
                    out,
                );
                // scrub growing on the slope itself
                if h.vegetation_spacing_m > 0.0 {
                    let mut p = s + uniform(rng, 0.0, h.vegetation_spacing_m);
                    while p < s + length {
                        let up = uniform(rng, 0.15, 0.85);
                        let at = beside(reference, p, verge_end - up * run);
                        let radius = uniform(rng, BUSH_RADIUS_M.0, BUSH_RADIUS_M.1);
                        out.push(upright_static(
                            ground,
                            StaticKind::Shrub,
                            Shape::Ball { radius_m: radius },
                            at,
                            up * rise - 0.4 * radius,
                            0.0,
                        ));
                        p += h.vegetation_spacing_m * uniform(rng, 0.3, 1.0);
                    }
                }
            }
            Stretch::OpenVerge => {
                vegetation(
                    h.vegetation_spacing_m,
                    reference,
                    ground,
                    (s, s + length),
                    verge_end,
                    (0.5, 14.0),
                    rng,
                    out,
                );
                // the right-of-way fence at the boundary: posts and a top
                // wire (the mesh between is too fine for the LiDAR)
                if h.fence_post_spacing_m > 0.0 {
                    let lateral = verge_end - FENCE_OFFSET_M;
                    let mut p = s + uniform(rng, 0.0, h.fence_post_spacing_m);
                    while p < s + length {
                        out.push(roadside_box(
                            reference,
                            ground,
                            StaticKind::Fence,
                            p,
                            lateral,
                            (0.1, 0.1, FENCE_HEIGHT_M + 0.3),
                            -0.3,
                        ));
                        p += h.fence_post_spacing_m;
                    }
                }
            }
        }
        s += length;
    }
}

/// Bushes and trees in the median beyond the left rail.
fn median(
    h: &HighwayParams,
    reference: &LanePath,
    ground: &Ground,
    section: &CrossSection,
    span: (f64, f64),
    rng: &mut ChaCha8Rng,
    out: &mut Vec<StaticObject>,
) {
    if h.vegetation_spacing_m <= 0.0 {
        return;
    }
    let mut s = span.0 + uniform(rng, 0.0, h.vegetation_spacing_m);
    while s < span.1 {
        let at = beside(reference, s, section.left_rail_m + uniform(rng, 1.5, 4.0));
        bush_cluster(ground, at, rng, out);
        s += h.vegetation_spacing_m * uniform(rng, 0.5, 1.5);
    }
}

/// Bushes and, one in `TREE_EVERY`, trees over `span` at mean `spacing`
/// (0 = none), on the right from the lateral offset `from_m` outwards by a
/// depth drawn from `depth_m`.
#[allow(clippy::too_many_arguments)]
fn vegetation(
    spacing: f64,
    reference: &LanePath,
    ground: &Ground,
    span: (f64, f64),
    from_m: f64,
    depth_m: (f64, f64),
    rng: &mut ChaCha8Rng,
    out: &mut Vec<StaticObject>,
) {
    const TREE_EVERY: f64 = 6.0;
    if spacing <= 0.0 {
        return;
    }
    let mut s = span.0 + uniform(rng, 0.0, spacing);
    while s < span.1 {
        let at = beside(reference, s, from_m - uniform(rng, depth_m.0, depth_m.1));
        if rng.random_bool(1.0 / TREE_EVERY) {
            out.extend(tree(
                ground,
                at,
                TREE_TRUNK_HEIGHT_M,
                TREE_TRUNK_RADIUS_M,
                TREE_CROWN_RADIUS_M,
                rng,
            ));
        } else {
            bush_cluster(ground, at, rng, out);
        }
        s += spacing * uniform(rng, 0.5, 1.5);
    }
}

/// A shrub of two to four overlapping balls around `at`: an irregular
/// outline, not a sphere.
fn bush_cluster(
    ground: &Ground,
    at: Point2<f64>,
    rng: &mut ChaCha8Rng,
    out: &mut Vec<StaticObject>,
) {
    let balls = rng.random_range(2..=4);
    for _ in 0..balls {
        let offset = nalgebra::Vector2::new(uniform(rng, -1.2, 1.2), uniform(rng, -1.2, 1.2));
        out.push(bush(ground, at + offset, BUSH_RADIUS_M, rng));
    }
}

/// Cuts `[s, s + length)` into pieces of at most `SEGMENT_M` (so straight
/// boxes follow curves and the ground) and calls `f(start, length)` on each.
fn segments(s: f64, length: f64, mut f: impl FnMut(f64, f64)) {
    let n = (length / SEGMENT_M).ceil().max(1.0);
    let len = length / n;
    for k in 0..n as usize {
        f(s + k as f64 * len, len);
    }
}

/// An earth slope rising away from the road: a slab whose upper face climbs
/// `rise` over `run` from the lateral offset `foot_m` outwards (`side` -1 =
/// to the right), `length` along the road at `s`.
#[allow(clippy::too_many_arguments)]
fn slope_slab(
    reference: &LanePath,
    ground: &Ground,
    s: f64,
    length: f64,
    foot_m: f64,
    side: f64,
    rise: f64,
    run: f64,
) -> StaticObject {
    const THICKNESS_M: f64 = 2.0;
    let heading = reference.heading_at(s);
    let width = (rise * rise + run * run).sqrt();
    // upper face's centre: half-way up the slope
    let mid = beside(reference, s, foot_m + side * 0.5 * run);
    let z_mid = ground.untextured_height(mid.x, mid.y) + 0.5 * rise;
    // roll about the road direction: the face rises outwards
    let angle = rise.atan2(run);
    let rotation = UnitQuaternion::from_euler_angles(0.0, 0.0, heading)
        * UnitQuaternion::from_euler_angles(side * angle, 0.0, 0.0);
    let normal = rotation * Vector3::z();
    let centre = Vector3::new(mid.x, mid.y, z_mid) - normal * (0.5 * THICKNESS_M);
    StaticObject {
        kind: StaticKind::Embankment,
        shape: Shape::Cuboid {
            half_extents_m: Vector3::new(0.5 * length + 0.05, 0.5 * width, 0.5 * THICKNESS_M),
        },
        t_world_object: Isometry3::from_parts(Translation3::from(centre), rotation),
    }
}

/// A road bridge across the highway at `s`: a deck at `OVERPASS_CLEARANCE_M`
/// over the road spanning both rails and beyond, on two pier walls outside
/// the rails and 1:1 abutment slopes at both ends.
fn overpass(
    reference: &LanePath,
    ground: &Ground,
    section: &CrossSection,
    s: f64,
    out: &mut Vec<StaticObject>,
) {
    let (thickness, width) = OVERPASS_DECK_M;
    let centre_lateral = 0.5 * (section.right_rail_m + section.left_rail_m);
    let span = section.left_rail_m - section.right_rail_m + 2.0 * OVERPASS_SPAN_BEYOND_RAIL_M;
    let road = beside(reference, s, centre_lateral);
    let heading = reference.heading_at(s);
    let z_road = ground.untextured_height(road.x, road.y);
    out.push(StaticObject {
        kind: StaticKind::Bridge,
        shape: Shape::Cuboid {
            half_extents_m: Vector3::new(0.5 * width, 0.5 * span, 0.5 * thickness),
        },
        t_world_object: Isometry3::from_parts(
            Translation3::new(
                road.x,
                road.y,
                z_road + OVERPASS_CLEARANCE_M + 0.5 * thickness,
            ),
            UnitQuaternion::from_euler_angles(0.0, 0.0, heading),
        ),
    });
    // pier walls along the road, a metre outside each rail
    for lateral in [section.right_rail_m - 1.5, section.left_rail_m + 1.5] {
        out.push(roadside_box(
            reference,
            ground,
            StaticKind::Bridge,
            s,
            lateral,
            (0.8 * width, 1.0, OVERPASS_CLEARANCE_M + 0.5),
            -0.5,
        ));
    }
    // the abutments under both ends of the deck: 1:1 slopes from 3 m
    // beyond the rails up to the deck
    let run = OVERPASS_CLEARANCE_M;
    for (foot, side) in [
        (section.right_rail_m - 3.0, -1.0),
        (section.left_rail_m + 3.0, 1.0),
    ] {
        out.push(slope_slab(
            reference,
            ground,
            s,
            width,
            foot,
            side,
            OVERPASS_CLEARANCE_M,
            run,
        ));
    }
}

/// A sign board on two posts on the right verge at `s`, facing the traffic.
fn sign_board(
    reference: &LanePath,
    ground: &Ground,
    section: &CrossSection,
    s: f64,
    rng: &mut ChaCha8Rng,
    out: &mut Vec<StaticObject>,
) {
    let width = uniform(rng, 1.5, 3.0);
    let height = uniform(rng, 1.0, 2.0);
    let bottom = uniform(rng, 1.2, 2.2);
    let lateral = section.right_rail_m - 2.5 - 0.5 * width;
    for k in [-0.4, 0.4] {
        out.push(upright_static(
            ground,
            StaticKind::Pole,
            Shape::Cylinder {
                radius_m: 0.05,
                half_height_m: 0.5 * (bottom + height + 0.3),
            },
            beside(reference, s, lateral + k * width),
            -0.2,
            0.0,
        ));
    }
    out.push(roadside_box(
        reference,
        ground,
        StaticKind::Sign,
        s - 0.1,
        lateral,
        (0.06, width, height),
        bottom,
    ));
}

/// A sign gantry at `s`: two posts outside the rails, a beam across the
/// road and two or three boards facing the traffic.
fn gantry(
    reference: &LanePath,
    ground: &Ground,
    section: &CrossSection,
    s: f64,
    rng: &mut ChaCha8Rng,
    out: &mut Vec<StaticObject>,
) {
    let heading = reference.heading_at(s);
    for lateral in [section.right_rail_m - 1.0, section.left_rail_m + 1.0] {
        out.push(upright_static(
            ground,
            StaticKind::Pole,
            Shape::Cylinder {
                radius_m: 0.3,
                half_height_m: 0.5 * (GANTRY_BEAM_HEIGHT_M + 1.0),
            },
            beside(reference, s, lateral),
            -0.2,
            0.0,
        ));
    }
    let centre_lateral = 0.5 * (section.right_rail_m + section.left_rail_m);
    let road = beside(reference, s, centre_lateral);
    let z_road = ground.untextured_height(road.x, road.y);
    let span = section.left_rail_m - section.right_rail_m + 2.0;
    let placed = |lateral: f64, z: f64, half: Vector3<f64>, kind| {
        let at = beside(reference, s, lateral);
        StaticObject {
            kind,
            shape: Shape::Cuboid {
                half_extents_m: half,
            },
            t_world_object: Isometry3::from_parts(
                Translation3::new(at.x, at.y, z),
                UnitQuaternion::from_euler_angles(0.0, 0.0, heading),
            ),
        }
    };
    out.push(placed(
        centre_lateral,
        z_road + GANTRY_BEAM_HEIGHT_M,
        Vector3::new(0.4, 0.5 * span, 0.4),
        StaticKind::Bridge,
    ));
    let (board_h, board_w) = GANTRY_BOARD_M;
    let boards = rng.random_range(2..=3);
    for k in 0..boards {
        let lateral = section.right_rail_m + 3.0 + k as f64 * (board_w + 1.0);
        // hung in front of the beam (towards the oncoming traffic)
        let front = beside(reference, s - 0.5, lateral);
        let mut board = placed(
            lateral,
            z_road + GANTRY_BEAM_HEIGHT_M + 0.2,
            Vector3::new(0.05, 0.5 * board_w, 0.5 * board_h),
            StaticKind::Sign,
        );
        board.t_world_object.translation.vector.x = front.x;
        board.t_world_object.translation.vector.y = front.y;
        out.push(board);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::traffic::PathPiece;

    fn road() -> LanePath {
        LanePath::from_pieces(
            Point2::origin(),
            0.0,
            &[
                PathPiece::Straight { length_m: 400.0 },
                PathPiece::Arc {
                    length_m: 400.0,
                    curvature_1pm: 1.0 / 900.0,
                },
            ],
            0.0,
        )
        .unwrap()
    }

    #[test]
    fn nothing_stands_between_the_rails_below_the_clearance() {
        let h = HighwayParams {
            overpass_spacing_m: 150.0,
            gantry_spacing_m: 200.0,
            ..HighwayParams::default()
        };
        let reference = road();
        let ground = Ground::flat(0.0);
        let section = CrossSection {
            right_rail_m: -10.7,
            left_rail_m: 8.9,
        };
        for seed in 0..5 {
            let statics = roadside(&h, &reference, &ground, &section, (0.0, 800.0), seed);
            assert!(statics.len() > 500, "{}", statics.len());
            let mut kinds = std::collections::HashSet::new();
            for object in &statics {
                kinds.insert(object.kind);
                // sample the object's volume: every point between the rails
                // is above the clearance
                let Shape::Cuboid { half_extents_m: e } = object.shape else {
                    continue;
                };
                for corner in 0..8 {
                    let sign = |bit: usize| if corner & (1 << bit) != 0 { 1.0 } else { -1.0 };
                    let local = nalgebra::Point3::new(sign(0) * e.x, sign(1) * e.y, sign(2) * e.z);
                    let p = object.t_world_object * local;
                    let (_, lateral) = reference.project(&Point2::new(p.x, p.y));
                    if lateral > section.right_rail_m + 0.05 && lateral < section.left_rail_m - 0.05
                    {
                        assert!(
                            p.z > 5.0,
                            "{:?} at lateral {lateral}, z {}",
                            object.kind,
                            p.z
                        );
                    }
                }
            }
            for kind in [
                StaticKind::GuardRail,
                StaticKind::Shrub,
                StaticKind::Bridge,
                StaticKind::Sign,
                StaticKind::Pole,
            ] {
                assert!(kinds.contains(&kind), "seed {seed}: no {kind:?}");
            }
            assert_eq!(
                statics,
                roadside(&h, &reference, &ground, &section, (0.0, 800.0), seed)
            );
        }
    }
}
