//! Statics along the cross street the ego turns into: rows of buildings
//! behind its sidewalks (beyond the main street's corner buildings, whose
//! side walls line its first stretch), light poles and trees on its
//! sidewalks next to the carriageway. Each building lot is built with the
//! probability `building_fraction`, as on the main street.
//!
//! The cross street at x = c runs along y; its carriageway is two lanes
//! (|x - c| <= lane_width), its sidewalks reach to the cross street's half
//! width. Everything is drawn from the seed's own ChaCha stream, so the rest
//! of the scene is the one the straight route has.

use super::{
    BUILDING_DEPTH_M, BUILDING_GAP_M, BUILDING_HEIGHT_M, BUILDING_LENGTH_M, BUILDING_SETBACK_M,
    BUILDING_SINK_M, CORNER_CLEARANCE_M, CROWN_RADIUS_M, FURNITURE_FROM_KERB_M, POLE_HEIGHT_M,
    POLE_RADIUS_M, Street, TREE_POLE_CLEARANCE_M, TRUNK_HEIGHT_M, TRUNK_RADIUS_M,
};
use crate::scenario::common::{tree, uniform, upright_static};
use crate::scene::{Ground, Shape, StaticKind, StaticObject};
use nalgebra::{Point2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// ChaCha stream (of the scenario seed) of the side street's statics.
const SIDE_STREET_STREAM: u64 = 0x0053_4944_4545; // "SIDEE" in ASCII

/// Statics along the cross street at x = `crossing_x_m`, on the ego's side of
/// the main street (y < 0), from the main street's building zone to
/// `far_y_m` (< 0).
pub(super) fn side_street(
    street: &Street,
    ground: &Ground,
    crossing_x_m: f64,
    far_y_m: f64,
    seed: u64,
) -> Vec<StaticObject> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(SIDE_STREET_STREAM);
    let u = &street.u;
    let half = 0.5 * u.cross_street_width_m;
    let back_of_main_sidewalk = street.kerb_m() + u.sidewalk_width_m;
    // the main street's corner buildings reach at most this far from its axis
    let main_buildings_end = back_of_main_sidewalk + BUILDING_SETBACK_M.1 + BUILDING_DEPTH_M.1;
    let at =
        |side: f64, from_axis_m: f64, y: f64| Point2::new(crossing_x_m + side * from_axis_m, y);
    let mut out = Vec::new();
    for side in [-1.0, 1.0] {
        // buildings, lot by lot away from the main street
        let mut y = -(main_buildings_end + 1.0);
        while y - BUILDING_LENGTH_M.0 >= far_y_m {
            let length = uniform(&mut rng, BUILDING_LENGTH_M.0, BUILDING_LENGTH_M.1);
            let depth = uniform(&mut rng, BUILDING_DEPTH_M.0, BUILDING_DEPTH_M.1);
            let height = uniform(&mut rng, BUILDING_HEIGHT_M.0, BUILDING_HEIGHT_M.1);
            let setback = uniform(&mut rng, BUILDING_SETBACK_M.0, BUILDING_SETBACK_M.1);
            let gap = uniform(&mut rng, BUILDING_GAP_M.0, BUILDING_GAP_M.1);
            // one draw per lot, as on the main street (`statics::buildings`)
            let built = rng.random::<f64>() < u.building_fraction;
            if !built {
                y -= length + gap;
                continue;
            }
            let near = half + setback;
            let centre = at(side, near + 0.5 * depth, y - 0.5 * length);
            let lowest = [y, y - length]
                .iter()
                .flat_map(|&cy| [near, near + depth].map(|d| at(side, d, cy)))
                .map(|p| ground.height(p.x, p.y))
                .fold(f64::INFINITY, f64::min);
            let base = lowest - BUILDING_SINK_M - ground.height(centre.x, centre.y);
            out.push(upright_static(
                ground,
                StaticKind::Building,
                Shape::Cuboid {
                    half_extents_m: Vector3::new(
                        0.5 * depth,
                        0.5 * length,
                        0.5 * (height + BUILDING_SINK_M),
                    ),
                },
                centre,
                base,
                0.0,
            ));
            y -= length + gap;
        }
        // poles, then trees clear of them, next to the carriageway; they
        // start past the main street's sidewalk and its pedestrians' lines
        let from_axis = u.lane_width_m + FURNITURE_FROM_KERB_M;
        let start = -(back_of_main_sidewalk + CORNER_CLEARANCE_M);
        let mut pole_ys = Vec::new();
        let mut y = start - uniform(&mut rng, 0.0, u.pole_spacing_m);
        while y > far_y_m {
            pole_ys.push(y);
            out.push(upright_static(
                ground,
                StaticKind::Pole,
                Shape::Cylinder {
                    radius_m: POLE_RADIUS_M,
                    half_height_m: 0.5 * POLE_HEIGHT_M,
                },
                at(side, from_axis, y),
                -0.2,
                0.0,
            ));
            y -= u.pole_spacing_m;
        }
        let mut y = start - uniform(&mut rng, 0.0, u.tree_spacing_m);
        while y > far_y_m {
            if pole_ys
                .iter()
                .all(|&p| (p - y).abs() >= TREE_POLE_CLEARANCE_M)
            {
                out.extend(tree(
                    ground,
                    at(side, from_axis, y),
                    TRUNK_HEIGHT_M,
                    TRUNK_RADIUS_M,
                    CROWN_RADIUS_M,
                    &mut rng,
                ));
            }
            y -= u.tree_spacing_m * uniform(&mut rng, 0.7, 1.3);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::ScenarioSpec;
    use crate::scenario::common::generate_ground;
    use crate::scenario::urban::layout;

    /// Footprints stay off the carriageway and out of the main street's
    /// building zone, and the street is lined along its whole length.
    #[test]
    fn side_street_lines_the_cross_street_and_keeps_its_carriageway_free() {
        let spec = ScenarioSpec::builtin("urban").unwrap();
        let u = spec.urban_params();
        for seed in 0..5 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let ground = generate_ground(&mut rng, &spec.ground, seed, (Point2::origin(), 0.0));
            let street = layout(&spec, &u, spec.ego_speed_mps(), &mut rng).unwrap();
            let c = street.crossings[street.ego_crossing];
            let far = -400.0;
            let statics = side_street(&street, &ground, c, far, seed);
            let mut building_ys = Vec::new();
            for s in &statics {
                let p = s.t_world_object.translation.vector;
                let (half_x, half_y) = match s.shape {
                    Shape::Cuboid { half_extents_m } => {
                        building_ys.push(p.y);
                        (half_extents_m.x, half_extents_m.y)
                    }
                    Shape::Cylinder { radius_m, .. } | Shape::Ball { radius_m } => {
                        (radius_m, radius_m)
                    }
                };
                // off the carriageway (crowns overhang above 2 m; their
                // trunks stand next to it)
                if !matches!(s.shape, Shape::Ball { .. }) {
                    assert!(
                        (p.x - c).abs() - half_x >= u.lane_width_m,
                        "{p:?} on the street"
                    );
                }
                let main_zone = street.kerb_m() + u.sidewalk_width_m;
                assert!(p.y + half_y <= -main_zone, "{p:?} in the main street");
                assert!(
                    p.y - half_y >= far - BUILDING_LENGTH_M.1,
                    "{p:?} beyond the end"
                );
            }
            // buildings on both sides, every 50 m of the street
            building_ys.sort_by(f64::total_cmp);
            assert!(
                building_ys.len() >= 2 * 8,
                "{} buildings",
                building_ys.len()
            );
            let side_count = |sign: f64| {
                statics
                    .iter()
                    .filter(|s| {
                        matches!(s.shape, Shape::Cuboid { .. })
                            && (s.t_world_object.translation.vector.x - c) * sign > 0.0
                    })
                    .count()
            };
            assert!(side_count(1.0) >= 8 && side_count(-1.0) >= 8);
            // same seed, same statics
            assert_eq!(statics, side_street(&street, &ground, c, far, seed));
        }
    }
}
