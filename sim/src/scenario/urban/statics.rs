//! Statics of the urban street: parked cars, buildings and street furniture
//! (poles, trees).

use super::{
    BUILDING_DEPTH_M, BUILDING_GAP_M, BUILDING_HEIGHT_M, BUILDING_LENGTH_M, BUILDING_LOT_STREAM,
    BUILDING_SETBACK_M, CORNER_CLEARANCE_M, CROWN_RADIUS_M, FURNITURE_FROM_KERB_M, PARKING_PLACE_M,
    POLE_HEIGHT_M, POLE_RADIUS_M, SIGNAL_POLE_HEIGHT_M, Street, TREE_POLE_CLEARANCE_M,
    TRUNK_HEIGHT_M, TRUNK_RADIUS_M,
};
use crate::scenario::common::{building, draw_body, parked_agent, pole, tree, uniform};
use crate::scene::{Agent, Ground, StaticObject};
use limot_estimator::input::ObjectClass;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

/// Parked cars in the parking strips on both sides, facing the traffic on
/// their side, in places of `PARKING_PLACE_M` away from the crossings.
pub(super) fn parked_cars(
    street: &Street,
    ground: &Ground,
    first_id: u32,
    duration_s: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Agent> {
    let u = &street.u;
    let from_axis = street.kerb_m() - 0.5 * u.parking_width_m;
    let mut cars = Vec::new();
    for side in [-1.0, 1.0] {
        let yaw = if side < 0.0 { 0.0 } else { PI };
        let mut x = street.view_lo;
        while x + PARKING_PLACE_M <= street.view_hi {
            let (x0, x1) = (x, x + PARKING_PLACE_M);
            x = x1;
            if street.near_crossing(x0, x1, CORNER_CLEARANCE_M)
                || !rng.random_bool(u.parking_occupancy)
            {
                continue;
            }
            let (size, _) = draw_body(rng, ObjectClass::Car);
            let slack = 0.5 * (PARKING_PLACE_M - size.x - 0.6).max(0.0);
            let cx = 0.5 * (x0 + x1) + uniform(rng, -slack, slack);
            let lateral = uniform(rng, -0.1, 0.1);
            cars.push(parked_agent(
                ground,
                first_id + cars.len() as u32,
                ObjectClass::Car,
                size,
                street.at(cx, side, from_axis + lateral),
                yaw,
                duration_s,
            ));
        }
    }
    cars
}

/// The random stream that decides which building lots hold a building: the
/// scenario seed on its own ChaCha stream, so the decisions never shift the
/// generator's other draws: at `building_fraction` = 1 every lot is built
/// and the scene is bit-identical to the one before this parameter existed;
/// below 1 buildings disappear and nothing else changes.
pub(super) fn building_lot_rng(seed: u64) -> ChaCha8Rng {
    let mut lots = ChaCha8Rng::seed_from_u64(seed);
    lots.set_stream(BUILDING_LOT_STREAM);
    lots
}

/// Rows of buildings behind both sidewalks, block by block. Every lot is
/// drawn from `rng` whether it gets built or not (so the lots stay where they
/// are); `lots` decides, with probability `building_fraction`, that it is.
pub(super) fn buildings(
    street: &Street,
    ground: &Ground,
    rng: &mut ChaCha8Rng,
    lots: &mut ChaCha8Rng,
) -> Vec<StaticObject> {
    let u = &street.u;
    let back_of_sidewalk = street.kerb_m() + u.sidewalk_width_m;
    let half = 0.5 * u.cross_street_width_m;
    let mut out = Vec::new();
    for side in [-1.0, 1.0] {
        for pair in street.crossings.windows(2) {
            let start = (pair[0] + half + 1.0).max(street.view_lo);
            let end = (pair[1] - half - 1.0).min(street.view_hi);
            let mut x = start;
            while end - x >= BUILDING_LENGTH_M.0 {
                let length = uniform(rng, BUILDING_LENGTH_M.0, BUILDING_LENGTH_M.1).min(end - x);
                let depth = uniform(rng, BUILDING_DEPTH_M.0, BUILDING_DEPTH_M.1);
                let height = uniform(rng, BUILDING_HEIGHT_M.0, BUILDING_HEIGHT_M.1);
                let setback = uniform(rng, BUILDING_SETBACK_M.0, BUILDING_SETBACK_M.1);
                let gap = uniform(rng, BUILDING_GAP_M.0, BUILDING_GAP_M.1);
                // one draw per lot, also at fraction 1, so that a lot built
                // at some fraction is built at every higher one
                let built = lots.random::<f64>() < u.building_fraction;
                if !built {
                    x += length + gap;
                    continue;
                }
                let near = back_of_sidewalk + setback;
                let centre = street.at(x + 0.5 * length, side, near + 0.5 * depth);
                out.push(building(ground, centre, 0.5 * length, 0.5 * depth, height));
                x += length + gap;
            }
        }
    }
    out
}

/// Signal poles at every corner of an intersection with lights, light poles
/// at a regular spacing and trees in between, all in the furniture strip next
/// to the kerb.
pub(super) fn furniture(
    street: &Street,
    ground: &Ground,
    rng: &mut ChaCha8Rng,
) -> Vec<StaticObject> {
    let u = &street.u;
    let from_axis = street.kerb_m() + FURNITURE_FROM_KERB_M;
    let half = 0.5 * u.cross_street_width_m;
    let mut out = Vec::new();
    for side in [-1.0, 1.0] {
        let mut pole_xs = Vec::new();
        // signal poles at the corners of the intersections with lights
        let signalled = street
            .crossings
            .iter()
            .zip(&street.give_way)
            .filter(|(_, give_way)| !**give_way);
        for (&c, _) in signalled {
            for x in [c - half - 1.0, c + half + 1.0] {
                if (street.view_lo..=street.view_hi).contains(&x) {
                    pole_xs.push(x);
                    let at = street.at(x, side, from_axis);
                    out.push(pole(ground, at, POLE_RADIUS_M, SIGNAL_POLE_HEIGHT_M));
                }
            }
        }
        let mut x = street.view_lo + uniform(rng, 0.0, u.pole_spacing_m);
        while x < street.view_hi {
            if !street.near_crossing(x, x, CORNER_CLEARANCE_M) {
                pole_xs.push(x);
                let at = street.at(x, side, from_axis);
                out.push(pole(ground, at, POLE_RADIUS_M, POLE_HEIGHT_M));
            }
            x += u.pole_spacing_m;
        }
        let mut x = street.view_lo + uniform(rng, 0.0, u.tree_spacing_m);
        while x < street.view_hi {
            let clear = pole_xs
                .iter()
                .all(|&p| (p - x).abs() >= TREE_POLE_CLEARANCE_M);
            if clear && !street.near_crossing(x, x, CORNER_CLEARANCE_M) {
                out.extend(tree(
                    ground,
                    street.at(x, side, from_axis),
                    TRUNK_HEIGHT_M,
                    TRUNK_RADIUS_M,
                    CROWN_RADIUS_M,
                    rng,
                ));
            }
            x += u.tree_spacing_m * uniform(rng, 0.7, 1.3);
        }
    }
    out
}
