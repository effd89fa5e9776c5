//! The ego's turn at an intersection without lights (`urban.ego_turn_give_way`):
//! a yield line where its turn begins, red while the road users its path
//! crosses are near it.
//!
//! The ego has right of way over the cross street but not over the main
//! street's users it turns across: the cyclists and pedestrians going
//! straight over the cross street's mouth on the side it turns to and,
//! turning left, the oncoming cars. Those users never react to the ego
//! while it waits at its line (it stands in its own lane, out of their
//! corridors), so their motion is found first, with the ego held at the line
//! for the whole run, and the line's red intervals follow from it: red from
//! the time the ego needs from a standstill to get past a user's line before
//! that user comes within reach of its path until it has passed.

use super::{EgoTurn, earliest_travel_time_s, merged, red_while, turn_arc_start_x};
use super::{GIVE_WAY_MARGIN_S, LaneKind, Street, TURN_LATERAL_ACCEL_MPS2, TURN_RADIUS_M};
use crate::traffic::{DriverParams, PlanarTrack};
use nalgebra::Point2;

/// Spacing of the points that stand for the ego's swept path, m.
const PATH_STEP_M: f64 = 0.5;
/// Clearance kept between the ego's and a user's bounding circles, m.
const CLEARANCE_M: f64 = 0.5;

/// Arc length on the ego's route where its turn begins: its yield line.
pub(super) fn yield_line_s(street: &Street, turn: &EgoTurn) -> f64 {
    let left = turn.away_sign().is_some_and(|away| away > 0.0);
    let c = street.crossings[turn.crossing];
    street.s_of(true, turn_arc_start_x(c, street.u.lane_width_m, left))
}

/// The main-street lanes whose users the ego's turn crosses: the bike lane
/// and walk lines on the side it turns to and, turning left, the oncoming
/// car lanes (which lie on that side).
pub(super) fn conflicting_lanes(street: &Street, turn: &EgoTurn) -> Vec<usize> {
    let Some(away) = turn.away_sign() else {
        return Vec::new();
    };
    street
        .lanes
        .iter()
        .enumerate()
        .filter(|(_, lane)| {
            let on_turn_side = lane.path.point_at(0.0).y * away > 0.0;
            on_turn_side && (lane.kind != LaneKind::Car || !lane.forward)
        })
        .map(|(index, _)| index)
        .collect()
}

/// Where the ego's box centre passes between its yield line and the point
/// where its whole body has left the main street's far sidewalk (on the
/// side it turns to), every [`PATH_STEP_M`], with the time it needs from a
/// standstill (front at the line) to reach each of them.
pub(super) fn swept_path(street: &Street, turn: &EgoTurn, ego_length_m: f64) -> Vec<PathPoint> {
    let u = &street.u;
    let away = turn.away_sign().unwrap_or(-1.0);
    let beyond = street.kerb_m() + u.sidewalk_width_m + 0.5 * ego_length_m;
    let start = yield_line_s(street, turn) - 0.5 * ego_length_m;
    let driver = DriverParams::car();
    let turn_speed = (TURN_LATERAL_ACCEL_MPS2 * TURN_RADIUS_M).sqrt();
    let mut points = Vec::new();
    let mut s = start.max(0.0);
    while s <= turn.path.length_m() {
        let p = turn.path.point_at(s);
        let reached_s = earliest_travel_time_s(s - start, turn_speed, driver.max_accel_mps2)
            + driver.accel_lag_s;
        points.push(PathPoint {
            point: p,
            reached_s,
        });
        if p.y * away >= beyond {
            break;
        }
        s += PATH_STEP_M;
    }
    points
}

/// A point of the ego's swept path and when, at the earliest, a start from
/// its yield line gets there.
pub(super) struct PathPoint {
    pub(super) point: Point2<f64>,
    pub(super) reached_s: f64,
}

/// One main-street user whose path the ego's turn crosses: its box centre
/// over time and the radius of a circle round its footprint.
pub(super) struct Crosser<'a> {
    pub(super) track: &'a PlanarTrack,
    pub(super) radius_m: f64,
}

impl Crosser<'_> {
    fn centre_at(&self, t_s: f64) -> Point2<f64> {
        let k = ((t_s - self.track.t0_s) / self.track.dt_s).round().max(0.0) as usize;
        let sample = &self.track.samples[k.min(self.track.samples.len() - 1)];
        Point2::new(sample.x, sample.y)
    }

    /// The time the ego needs from its yield line until its body has passed
    /// this user's line along the main street (the last path point within
    /// reach of it, plus [`GIVE_WAY_MARGIN_S`]); the user keeps to its line.
    fn clear_s(&self, path: &[PathPoint], ego_radius_m: f64) -> f64 {
        let line_y = self.centre_at(self.track.t0_s).y;
        let reach = self.radius_m + ego_radius_m + CLEARANCE_M;
        let last = path
            .iter()
            .rev()
            .find(|q| (q.point.y - line_y).abs() <= reach)
            .or(path.last());
        last.map_or(0.0, |q| q.reached_s) + GIVE_WAY_MARGIN_S
    }
}

/// Red intervals of the ego's yield line: red while a crosser is within
/// reach of the swept path (its circle and the ego's, `ego_radius_m`, with
/// [`CLEARANCE_M`] between) and, before that, for the time the ego needs to
/// get past its line ([`Crosser::clear_s`]); sampled every 0.1 s over [0,
/// `duration_s`] (the first interval from t = 0 when one is within reach
/// already).
pub(super) fn yield_red_s(
    path: &[PathPoint],
    ego_radius_m: f64,
    crossers: &[Crosser<'_>],
    duration_s: f64,
) -> Vec<(f64, f64)> {
    let red = crossers
        .iter()
        .flat_map(|c| {
            let reach = c.radius_m + ego_radius_m + CLEARANCE_M;
            red_while(duration_s, c.clear_s(path, ego_radius_m), |t| {
                let p = c.centre_at(t);
                path.iter()
                    .any(|q| (p - q.point).norm_squared() <= reach * reach)
            })
        })
        .collect();
    merged(red)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::traffic::PlanarSample;

    fn track(points: &[(f64, f64)]) -> PlanarTrack {
        PlanarTrack {
            id: 1,
            t0_s: 0.0,
            dt_s: 1.0,
            samples: points
                .iter()
                .map(|&(x, y)| PlanarSample::at_rest(x, y, 0.0))
                .collect(),
        }
    }

    /// A straight path along +y from (0, 0) to (0, 5), reached 1 s per metre.
    fn path() -> Vec<PathPoint> {
        (0..=10)
            .map(|i| PathPoint {
                point: Point2::new(0.0, 0.5 * i as f64),
                reached_s: 0.5 * i as f64,
            })
            .collect()
    }

    #[test]
    fn red_while_a_crosser_is_within_reach_and_clear_time_before() {
        let path = path();
        // on the line y = 2 (reach 3.5 m: the ego past it at y = 5, 5 s),
        // 20 m away, then at the path from t = 10 s to t = 12 s, then gone
        let mut points = vec![(20.0, 2.0); 10];
        points.extend([(0.0, 2.0), (1.0, 2.0), (2.0, 2.0)]);
        points.extend(vec![(30.0, 2.0); 8]);
        let t = track(&points);
        let crossers = [Crosser {
            track: &t,
            radius_m: 0.5,
        }];
        let red = yield_red_s(&path, 2.5, &crossers, 20.0);
        assert_eq!(red.len(), 1, "{red:?}");
        let (a, b) = red[0];
        // within reach from t = 9.5 s (the nearest sample is then t = 10 s)
        // to 12.4 s, sampled every 0.1 s; red from the clear time before:
        // the last path point within 3.5 m of y = 2 is y = 5 (5 s), plus
        // the margin
        let clear = 5.0 + GIVE_WAY_MARGIN_S;
        assert!((a - (9.5 - clear)).abs() < 1e-9, "{red:?}");
        assert!((b - 12.5).abs() < 1e-9, "{red:?}");
        // nobody: never red
        assert!(yield_red_s(&path, 2.5, &[], 20.0).is_empty());
        // within reach at the start: red from t = 0
        let t0 = track(&[(0.0, 1.0), (40.0, 1.0), (40.0, 1.0)]);
        let crosser = Crosser {
            track: &t0,
            radius_m: 0.5,
        };
        let red = yield_red_s(&path, 2.5, &[crosser], 2.0);
        assert_eq!(red[0].0, 0.0);
    }

    #[test]
    fn a_line_the_ego_passes_early_needs_a_shorter_gap() {
        let path = path();
        // a crosser on y = -3 is within reach of the path's first points
        // only (reach 3.5 m: up to y = 0.5, reached at 0.5 s)
        let t = track(&[(0.0, -3.0)]);
        let near = Crosser {
            track: &t,
            radius_m: 0.5,
        };
        assert!((near.clear_s(&path, 2.5) - (0.5 + GIVE_WAY_MARGIN_S)).abs() < 1e-12);
        // one on y = 20 never comes within reach: the whole path's time
        let t = track(&[(0.0, 20.0)]);
        let far = Crosser {
            track: &t,
            radius_m: 0.5,
        };
        assert!((far.clear_s(&path, 2.5) - (5.0 + GIVE_WAY_MARGIN_S)).abs() < 1e-12);
    }
}
