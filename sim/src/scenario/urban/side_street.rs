//! What lines the cross street the ego turns into: rows of buildings behind
//! its sidewalks in blocks (beyond the main street's corner buildings, whose
//! side walls line its first stretch), cars parked half on the sidewalk along
//! both kerbs, light poles and trees at the back of the sidewalks. Each building lot is built with the
//! probability `building_fraction`, as on the main street, and its street
//! face gets the main street's facade detail and front garden
//! (`streetscape::building_detail`). The sidewalks are not raised: the
//! parked cars stand half on them.
//!
//! The cross street at x = c runs along y; its carriageway is two lanes
//! (|x - c| <= lane_width), its sidewalks reach to the cross street's half
//! width. Everything is drawn from the seed's own ChaCha stream, so the rest
//! of the scene is the one the straight route has. The street is laid out
//! for its -y half (a right turn's) and turned half a turn about the
//! crossing for its +y half (a left turn's), so both are lined alike.

use super::{
    BUILDING_DEPTH_M, BUILDING_GAP_M, BUILDING_HEIGHT_M, BUILDING_LENGTH_M, BUILDING_SETBACK_M,
    CORNER_CLEARANCE_M, CROWN_RADIUS_M, PARKING_PLACE_M, POLE_HEIGHT_M, POLE_RADIUS_M, Street,
    TREE_POLE_CLEARANCE_M, TRUNK_HEIGHT_M, TRUNK_RADIUS_M,
};
use crate::scenario::common::{building, draw_body, parked_agent, pole, tree, uniform};
use crate::scenario::streetscape::{StreetLayout, building_detail};
use crate::scene::{Agent, Ground, StaticObject};
use limot_estimator::input::ObjectClass;
use nalgebra::{Isometry2, Point2, Vector2};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

/// Parked cars' centres stand this far outside the carriageway edge, m.
const PARKED_FROM_KERB_M: f64 = 1.1;
/// Poles and trees stand this far inside the cross street's edge, m.
const FURNITURE_FROM_EDGE_M: f64 = 0.9;

/// What lines the side street.
pub(super) struct SideStreet {
    /// Buildings, poles, trees.
    pub(super) statics: Vec<StaticObject>,
    /// Parked cars, ids from the `first_id` given.
    pub(super) parked: Vec<Agent>,
}

/// ChaCha stream (of the scenario seed) of the side street's statics.
const SIDE_STREET_STREAM: u64 = 0x0053_4944_4545; // "SIDEE" in ASCII

/// What lines the cross street at x = `crossing_x_m` on one side of the main
/// street (`away_sign` -1: y < 0, +1: y > 0), from the main street's
/// sidewalk to `far_m` (> 0) from the main street's axis.
#[allow(clippy::too_many_arguments)]
pub(super) fn side_street(
    street: &Street,
    ground: &Ground,
    crossing_x_m: f64,
    away_sign: f64,
    far_m: f64,
    first_id: u32,
    duration_s: f64,
    seed: u64,
) -> SideStreet {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(SIDE_STREET_STREAM);
    let u = &street.u;
    let half = 0.5 * u.cross_street_width_m;
    let back_of_main_sidewalk = street.kerb_m() + u.sidewalk_width_m;
    // the main street's corner buildings reach at most this far from its axis
    let main_buildings_end = back_of_main_sidewalk + BUILDING_SETBACK_M.1 + BUILDING_DEPTH_M.1;
    // laid out in the -y half (y down to far_y_m); the +y half is the same
    // turned by pi about (crossing_x_m, 0)
    let far_y_m = -far_m;
    let turned = away_sign > 0.0;
    let at = |side: f64, from_axis_m: f64, y: f64| {
        if turned {
            Point2::new(crossing_x_m - side * from_axis_m, -y)
        } else {
            Point2::new(crossing_x_m + side * from_axis_m, y)
        }
    };
    let turn_yaw = if turned { PI } else { 0.0 };
    let mut out = Vec::new();
    let mut parked = Vec::new();
    for side in [-1.0, 1.0] {
        // buildings, lot by lot away from the main street, in blocks of the
        // main street's block lengths with an open gap as wide as a cross
        // street between them (their end walls face along the street)
        let block = |rng: &mut ChaCha8Rng| uniform(rng, u.block_length_min_m, u.block_length_max_m);
        let mut y = -(main_buildings_end + 1.0);
        let mut block_end = y - block(&mut rng);
        while y - BUILDING_LENGTH_M.0 >= far_y_m {
            if y - BUILDING_LENGTH_M.0 < block_end {
                y = block_end - u.cross_street_width_m;
                block_end = y - block(&mut rng);
                continue;
            }
            let length =
                uniform(&mut rng, BUILDING_LENGTH_M.0, BUILDING_LENGTH_M.1).min(y - block_end);
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
            let centre = at(side, half + setback + 0.5 * depth, y - 0.5 * length);
            out.push(building(ground, centre, 0.5 * depth, 0.5 * length, height));
            y -= length + gap;
        }
        // parked cars heading with the traffic on their side (right-hand:
        // -y at x < c), past the main street's sidewalk and its pedestrians'
        // lines
        let start = -(back_of_main_sidewalk + CORNER_CLEARANCE_M);
        let yaw = side * 0.5 * PI + turn_yaw;
        let mut y = start;
        while y - PARKING_PLACE_M >= far_y_m {
            let (y0, y1) = (y - PARKING_PLACE_M, y);
            y = y0;
            if !rng.random_bool(u.parking_occupancy) {
                continue;
            }
            let (size, _) = draw_body(&mut rng, ObjectClass::Car);
            let slack = 0.5 * (PARKING_PLACE_M - size.x - 0.6).max(0.0);
            let cy = 0.5 * (y0 + y1) + uniform(&mut rng, -slack, slack);
            parked.push(parked_agent(
                ground,
                first_id + parked.len() as u32,
                ObjectClass::Car,
                size,
                at(side, u.lane_width_m + PARKED_FROM_KERB_M, cy),
                yaw,
                duration_s,
            ));
        }
        // poles, then trees clear of them, at the back of the sidewalk
        let from_axis = half - FURNITURE_FROM_EDGE_M;
        let mut pole_ys = Vec::new();
        let mut y = start - uniform(&mut rng, 0.0, u.pole_spacing_m);
        while y > far_y_m {
            pole_ys.push(y);
            out.push(pole(
                ground,
                at(side, from_axis, y),
                POLE_RADIUS_M,
                POLE_HEIGHT_M,
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
    // the cross street's own frame: x along it, away from the main street
    let layout = StreetLayout {
        kerb_m: u.lane_width_m,
        sidewalk_width_m: half - u.lane_width_m,
        crossings: &[],
        cross_half_width_m: 0.0,
        view: (0.0, -far_y_m),
        furniture: false,
        t_world_street: Isometry2::new(Vector2::new(crossing_x_m, 0.0), -0.5 * PI + turn_yaw),
    };
    let detail = building_detail(&layout, ground, &out, seed);
    out.extend(detail);
    SideStreet {
        statics: out,
        parked,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::ScenarioSpec;
    use crate::scenario::common::generate_ground;
    use crate::scenario::urban::layout;
    use crate::scene::{Shape, StaticKind};

    /// Footprints stay off the carriageway and out of the main street's
    /// building zone, the street is lined along its whole length, and parked
    /// cars face the traffic on their side, in both halves of the cross
    /// street (y < 0 for a right turn, y > 0 for a left one).
    #[test]
    fn side_street_lines_the_cross_street_and_keeps_its_carriageway_free() {
        let spec = ScenarioSpec::builtin("urban").unwrap();
        let u = spec.urban_params();
        for (seed, away) in (0..5).flat_map(|seed| [(seed, -1.0), (seed, 1.0)]) {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let ground = generate_ground(&mut rng, &spec.ground, seed, (Point2::origin(), 0.0));
            let street = layout(&spec, &u, spec.ego_speed_mps(), &mut rng).unwrap();
            let c = street.crossings[street.ego_crossing];
            let far = 400.0;
            let side = side_street(&street, &ground, c, away, far, 1000, 60.0, seed);
            // y measured away from the main street, negative as in the -y half
            let local_y = |y: f64| -away * y;
            let statics = &side.statics;
            let mut building_ys = Vec::new();
            for s in statics {
                let p = s.t_world_object.translation.vector;
                let (half_x, half_y) = match s.shape {
                    Shape::Cuboid { half_extents_m } => {
                        if s.kind == StaticKind::Building {
                            building_ys.push(local_y(p.y));
                        }
                        // the footprint's world box (facade detail is
                        // turned with the street)
                        let half = s
                            .t_world_object
                            .rotation
                            .to_rotation_matrix()
                            .matrix()
                            .abs()
                            * half_extents_m;
                        (half.x, half.y)
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
                assert!(
                    local_y(p.y) + half_y <= -main_zone,
                    "{p:?} in the main street"
                );
                assert!(
                    local_y(p.y) - half_y >= -far - BUILDING_LENGTH_M.1,
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
                        s.kind == StaticKind::Building
                            && (s.t_world_object.translation.vector.x - c) * sign > 0.0
                    })
                    .count()
            };
            assert!(side_count(1.0) >= 8 && side_count(-1.0) >= 8);
            // the street faces have the main street's facade detail
            let detail = statics
                .iter()
                .filter(|s| s.kind == StaticKind::Facade)
                .count();
            assert!(detail >= 4 * building_ys.len(), "{detail} facade parts");
            // parked cars on both sides, off the carriageway, ids in order
            let ids: Vec<u32> = side.parked.iter().map(|a| a.id).collect();
            assert_eq!(ids, (1000..1000 + ids.len() as u32).collect::<Vec<_>>());
            for sign in [-1.0, 1.0] {
                let on_side: Vec<_> = side
                    .parked
                    .iter()
                    .map(|a| a.trajectory.pose_at(0.0))
                    .filter(|pose| (pose.translation.vector.x - c) * sign > 0.0)
                    .collect();
                assert!(on_side.len() >= 20, "{} parked cars", on_side.len());
                for pose in on_side {
                    let p = pose.translation.vector;
                    let inner = (p.x - c).abs() - 0.5 * 1.95;
                    assert!(inner >= u.lane_width_m, "{p:?} on the carriageway");
                    assert!(
                        local_y(p.y) <= -(street.kerb_m() + u.sidewalk_width_m),
                        "{p:?}"
                    );
                    // right-hand traffic: +y at x > c, -y at x < c
                    let heading = pose.rotation * nalgebra::Vector3::x();
                    assert!(heading.y * sign > 0.99, "{p:?} heading {heading:?}");
                }
            }
            // same seed, same street
            let again = side_street(&street, &ground, c, away, far, 1000, 60.0, seed);
            assert_eq!(side.statics, again.statics);
            assert_eq!(side.parked, again.parked);
            // the +y half is the -y half turned by pi about the crossing
            // (the buildings, poles, trees and parked cars; the facade detail
            // follows the ground under it)
            let other = side_street(&street, &ground, c, -away, far, 1000, 60.0, seed);
            let footprints = |s: &SideStreet| -> Vec<Vector2<f64>> {
                let statics = s.statics.iter().filter(|o| {
                    matches!(
                        o.kind,
                        StaticKind::Building
                            | StaticKind::Pole
                            | StaticKind::TreeTrunk
                            | StaticKind::TreeCrown
                    )
                });
                let statics = statics.map(|o| o.t_world_object.translation.vector.xy());
                let cars = s
                    .parked
                    .iter()
                    .map(|a| a.trajectory.pose_at(0.0).translation.vector.xy());
                statics.chain(cars).collect()
            };
            let (a, b) = (footprints(&side), footprints(&other));
            assert_eq!(a.len(), b.len());
            assert!(a.len() > 50);
            for (a, b) in a.iter().zip(&b) {
                assert!((a.x - c + (b.x - c)).abs() < 1e-9 && (a.y + b.y).abs() < 1e-9);
            }
        }
    }
}
