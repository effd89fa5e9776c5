//! Vehicle motion for generated scenarios: every road user (car, truck,
//! cyclist, pedestrian) is a kinematic bicycle (rear-axle reference, wheelbase
//! 0.6 l, axles symmetric about the box centre) integrated at 1 kHz.
//!
//! - Lateral: pure pursuit on the current lane path (rear axle, lookahead
//!   proportional to speed) with a first-order steering lag. A lane change
//!   switches the reference lane and fades the initial lateral offset to zero
//!   with a quintic smoothstep over `lane_change_duration_s`.
//! - Longitudinal: IDM, re-evaluated at 100 Hz, with a first-order acceleration
//!   lag, so speed is C1 and position C2. The leader is the nearest body ahead
//!   on my reference lane whose footprint, or the strip it will sweep to reach
//!   its own reference lane's centre, overlaps my corridor (the strip I sweep
//!   from my current footprint to the lane centre), or that has committed to
//!   change into my lane. Braking is limited to speed / 0.15 s so that stops
//!   end without an acceleration jump. Red stop lines are standing leaders for
//!   vehicles that could still stop comfortably when they first saw the red
//!   (decision latched for the red phase); the end of a lane is a standing
//!   leader too, so **vehicles stop before a lane ends** (generators make
//!   lanes long enough if they do not want that).
//! - Curves: a driver with a lateral-acceleration limit lowers its desired
//!   speed before and through its lane's curves (`DriverParams::
//!   curve_lateral_accel_mps2`); the others drive curves at their desired speed.
//! - Lane changes are requested at a time and executed at the first 100 Hz
//!   update where a MOBIL-style safety criterion holds (new leader and new
//!   follower keep at least their minimum gap and neither would have to brake
//!   harder than the driver's `safe_decel_mps2`); otherwise retried. While a
//!   cooperative request is due, the requester also follows the target
//!   lane's vehicles ahead of it and those behind it follow the requester
//!   (braking at most comfortably), so that a gap opens.
//! - Deterministic: no randomness; vehicles are updated in spec order.
//!
//! Only same-lane and lane-changing conflicts are resolved; crossing lanes at
//! intersections must be separated by the generator's stop-line phases.

mod lane_path;
mod lift;
pub(crate) mod overlap;
mod spec;
mod suspension;

pub use lane_path::{LanePath, PathPiece};
use lift::Lifting;
pub use lift::{lift_onto, lift_to_ground};
pub use overlap::{Body, Overlap, first_overlap};
pub use suspension::{BodyAttitude, RideInput, Suspension, ride};

use limot_estimator::geometry::wrap_angle_rad;
use spec::validate;
pub use spec::{
    DriverParams, JamFront, LaneChange, PlanarSample, PlanarTrack, StopLine, TrafficError,
    TrafficSpec, VehicleSpec,
};

use nalgebra::{Point2, Vector2};

/// Integration step of the vehicle model.
const SIM_DT_S: f64 = 1e-3;
/// Recording interval, in integration steps (0.01 s).
const RECORD_EVERY: usize = 10;
/// The IDM / lane-change logic runs every this many integration steps (100 Hz).
const PLAN_EVERY: usize = 10;
/// Extra lateral clearance of a lane corridor on each side.
const CORRIDOR_MARGIN_M: f64 = 0.3;
/// Braking is limited to speed / STOP_TIME_S (only matters just before a stop).
const STOP_TIME_S: f64 = 0.15;
/// Lanes farther than this from a body are not considered near it.
const FRAME_RADIUS_M: f64 = 20.0;
/// Drivers who limit their speed in curves brake for them at this share of
/// their comfortable deceleration.
const CURVE_DECEL_SHARE: f64 = 0.5;
/// Other bodies farther than this (centre distance) are ignored by the planner.
const INTERACTION_RANGE_M: f64 = 250.0;

/// Simulates all vehicles over [0, duration_s]; tracks in `spec.vehicles` order,
/// each starting at t = 0 with one sample every 0.01 s (end included).
///
/// # Errors
/// [`TrafficError`] for invalid fields (named with the vehicle id /
/// stop-line index), for vehicles that start overlapping or closer behind
/// another body in their corridor than min gap + (v_f^2 - v_l^2) /
/// (2 max_decel) + v_f * accel_lag, and for a diverging state.
pub fn simulate_traffic(spec: &TrafficSpec) -> Result<Vec<PlanarTrack>, TrafficError> {
    simulate(spec, RECORD_EVERY)
}

/// [`simulate_traffic`] with every track lifted as it is recorded
/// ([`lift_onto`] the ground raised by `raised(x, y)`, each vehicle with its
/// class's [`Suspension`]): the same trajectories, bit for bit, without
/// ever holding the planar tracks.
///
/// # Errors
/// As [`simulate_traffic`].
pub(crate) fn simulate_traffic_lifted(
    spec: &TrafficSpec,
    ground: &crate::scene::Ground,
    raised: &dyn Fn(f64, f64) -> f64,
) -> Result<Vec<crate::trajectory::Trajectory>, TrafficError> {
    // before the tracks' room is taken: the duration is checked there
    validate(spec)?;
    let record_dt = SIM_DT_S * RECORD_EVERY as f64;
    let samples = sample_count(spec, record_dt);
    let mut lifting: Vec<Lifting> = spec
        .vehicles
        .iter()
        .map(|vs| {
            let suspension = Suspension::for_class(vs.class);
            Lifting::new(
                0.0,
                record_dt,
                samples,
                ground,
                raised,
                &vs.size_lwh_m,
                suspension.as_ref(),
            )
        })
        .collect();
    run(spec, RECORD_EVERY, |i, sample| lifting[i].push(sample))?;
    Ok(lifting.into_iter().map(Lifting::finish).collect())
}

/// Samples of each track over `[0, duration_s]`, one every `record_dt_s`,
/// the end included.
fn sample_count(spec: &TrafficSpec, record_dt_s: f64) -> usize {
    (spec.duration_s / record_dt_s).round() as usize + 1
}

/// Lateral transition of a lane change: reference offset fades from `d0_m` to 0.
#[derive(Debug, Clone, Copy)]
struct Transition {
    t0_s: f64,
    d0_m: f64,
    duration_s: f64,
}

impl Transition {
    fn offset_at(&self, t_s: f64) -> f64 {
        let u = ((t_s - self.t0_s) / self.duration_s).clamp(0.0, 1.0);
        let smooth = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
        self.d0_m * (1.0 - smooth)
    }
}

/// Mutable per-vehicle simulation state.
#[derive(Debug, Clone)]
struct Vehicle {
    /// Rear-axle position.
    rear: Vector2<f64>,
    yaw: f64,
    speed_mps: f64,
    accel_mps2: f64,
    steer_rad: f64,
    accel_cmd_mps2: f64,
    steer_cmd_rad: f64,
    lane: usize,
    transition: Option<Transition>,
    next_change: usize,
    /// Per stop line: latched "must stop" decision for the current red phase.
    stop_decision: Vec<Option<bool>>,
    half_wheelbase_m: f64,
}

impl Vehicle {
    fn centre(&self) -> Point2<f64> {
        Point2::from(self.rear + heading_vec(self.yaw) * self.half_wheelbase_m)
    }
}

/// Where a body sits relative to a lane.
#[derive(Debug, Clone, Copy)]
struct LaneFrame {
    s_m: f64,
    lateral_m: f64,
    /// Half extents of the body footprint along / across the lane.
    lon_half_m: f64,
    lat_half_m: f64,
    /// Speed component along the lane.
    speed_along_mps: f64,
}

fn heading_vec(h: f64) -> Vector2<f64> {
    Vector2::new(h.cos(), h.sin())
}

fn normal_vec(h: f64) -> Vector2<f64> {
    Vector2::new(-h.sin(), h.cos())
}

/// Body `v` in the frame of `lane` by a global projection (slow, never fails).
fn global_lane_frame(lane: &LanePath, v: &Vehicle, vs: &VehicleSpec) -> LaneFrame {
    let (s, d) = lane.project(&v.centre());
    frame_from(lane, v, vs, s, d)
}

fn frame_from(lane: &LanePath, v: &Vehicle, vs: &VehicleSpec, s: f64, d: f64) -> LaneFrame {
    let dpsi = wrap_angle_rad(v.yaw - lane.heading_at(s));
    let (sn, cs) = dpsi.sin_cos();
    let (l2, w2) = (0.5 * vs.size_lwh_m.x, 0.5 * vs.size_lwh_m.y);
    LaneFrame {
        s_m: s,
        lateral_m: d,
        lon_half_m: cs.abs() * l2 + sn.abs() * w2,
        lat_half_m: sn.abs() * l2 + cs.abs() * w2,
        speed_along_mps: v.speed_mps * cs,
    }
}

/// IDM acceleration command, limited to [-max_decel, max_accel]; the free-road
/// term alone never brakes harder than the comfortable deceleration.
fn idm_accel(
    p: &DriverParams,
    desired_speed_mps: f64,
    speed_mps: f64,
    leader: Option<(f64, f64)>,
) -> f64 {
    let ratio = speed_mps / desired_speed_mps;
    let free = (p.max_accel_mps2 * (1.0 - ratio.powi(4))).max(-p.comfortable_decel_mps2);
    let interaction = match leader {
        None => 0.0,
        Some((gap_m, dv_mps)) => {
            let s_star = p.min_gap_m
                + (speed_mps * p.time_headway_s
                    + speed_mps * dv_mps
                        / (2.0 * (p.max_accel_mps2 * p.comfortable_decel_mps2).sqrt()))
                .max(0.0);
            let gap = gap_m.max(1e-3);
            p.max_accel_mps2 * (s_star / gap).powi(2)
        }
    };
    (free - interaction).clamp(-p.max_decel_mps2, p.max_accel_mps2)
}

/// Closest of two optional (gap, dv) leaders.
fn nearer(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    match (a, b) {
        (Some(x), Some(y)) => Some(if y.0 < x.0 { y } else { x }),
        (x, None) => x,
        (None, y) => y,
    }
}

struct Sim<'a> {
    spec: &'a TrafficSpec,
    vehicles: Vec<Vehicle>,
    /// [vehicle][lane]: the vehicle in that lane's frame at the last planning
    /// tick, None if farther than FRAME_RADIUS_M from the lane.
    frames: Vec<Vec<Option<LaneFrame>>>,
    /// [vehicle][lane]: previous arc length, to track projections locally.
    hints: Vec<Vec<Option<f64>>>,
    /// Previous (lane, arc length) of each rear axle, for steering.
    rear_hints: Vec<Option<(usize, f64)>>,
}

impl Sim<'_> {
    /// Lateral interval of vehicle `i`'s corridor on a lane: its current
    /// footprint, its final footprint on the lane centre (aligned with the
    /// lane), and everything between, widened by a margin.
    fn corridor(&self, i: usize, me: &LaneFrame) -> (f64, f64) {
        let half_width = 0.5 * self.spec.vehicles[i].size_lwh_m.y;
        (
            (me.lateral_m - me.lat_half_m).min(-half_width) - CORRIDOR_MARGIN_M,
            (me.lateral_m + me.lat_half_m).max(half_width) + CORRIDOR_MARGIN_M,
        )
    }

    fn new(spec: &TrafficSpec) -> Sim<'_> {
        let (n, n_lanes) = (spec.vehicles.len(), spec.lanes.len());
        let mut sim = Sim {
            spec,
            vehicles: initial_vehicles(spec),
            frames: vec![vec![None; n_lanes]; n],
            hints: vec![vec![None; n_lanes]; n],
            rear_hints: vec![None; n],
        };
        sim.refresh_frames();
        sim
    }

    /// Re-projects every vehicle onto every lane near it, tracking each
    /// projection locally from the previous one (cheap Newton steps).
    fn refresh_frames(&mut self) {
        for (j, (v, vs)) in self.vehicles.iter().zip(&self.spec.vehicles).enumerate() {
            let c = v.centre();
            for (l, lane) in self.spec.lanes.iter().enumerate() {
                let near = |sd: &(f64, f64)| sd.1.abs() <= FRAME_RADIUS_M;
                let sd = self.hints[j][l]
                    .and_then(|s0| lane.project_from(&c, s0))
                    .filter(near)
                    .or_else(|| lane.project_near(&c, FRAME_RADIUS_M).filter(near));
                self.hints[j][l] = sd.map(|sd| sd.0);
                self.frames[j][l] = sd.map(|(s, d)| frame_from(lane, v, vs, s, d));
            }
        }
    }

    /// Bodies relevant to vehicle `i` on `lane`: (j, frame of j) for every other
    /// vehicle overlapping i's corridor there or committed to that lane.
    fn corridor_bodies(
        &self,
        i: usize,
        lane_idx: usize,
        me: &LaneFrame,
    ) -> Vec<(usize, LaneFrame)> {
        let lane = &self.spec.lanes[lane_idx];
        let (lo, hi) = self.corridor(i, me);
        let ci = self.vehicles[i].centre();
        let mut out = Vec::new();
        for (j, (vj, sj)) in self.vehicles.iter().zip(&self.spec.vehicles).enumerate() {
            if j == i || (vj.centre() - ci).norm() > INTERACTION_RANGE_M {
                continue;
            }
            let fj = match self.frames[j][lane_idx] {
                Some(f) => f,
                // committed to this lane: relevant wherever it still is
                None if vj.lane == lane_idx => global_lane_frame(lane, vj, sj),
                None => continue,
            };
            // j occupies (or is about to occupy) everything between its current
            // footprint and its footprint on its own reference lane's centre
            let offset_own = self.frames[j][vj.lane].map_or(0.0, |f| f.lateral_m);
            let target_centre = fj.lateral_m - offset_own;
            let half_width = 0.5 * sj.size_lwh_m.y;
            let j_lo = (fj.lateral_m - fj.lat_half_m).min(target_centre - half_width);
            let j_hi = (fj.lateral_m + fj.lat_half_m).max(target_centre + half_width);
            let overlaps = j_hi > lo && j_lo < hi;
            if overlaps || vj.lane == lane_idx {
                out.push((j, fj));
            }
        }
        out
    }

    /// Own frame on the reference lane; falls back to a global projection.
    fn own_frame(&self, i: usize) -> LaneFrame {
        let lane_idx = self.vehicles[i].lane;
        self.frames[i][lane_idx].unwrap_or_else(|| {
            global_lane_frame(
                &self.spec.lanes[lane_idx],
                &self.vehicles[i],
                &self.spec.vehicles[i],
            )
        })
    }

    /// Desired speed of `i` where it is: its IDM desired speed, lowered
    /// before and through curves of its reference lane if its driver limits
    /// the lateral acceleration there (braking at half the comfortable
    /// deceleration, looking as far ahead as it needs to stop that way).
    fn curve_limited_speed_mps(&self, i: usize) -> f64 {
        let vs = &self.spec.vehicles[i];
        let Some(lateral_accel) = vs.driver.curve_lateral_accel_mps2 else {
            return vs.desired_speed_mps;
        };
        let decel = CURVE_DECEL_SHARE * vs.driver.comfortable_decel_mps2;
        let v = self.vehicles[i].speed_mps.max(vs.desired_speed_mps);
        let horizon = v * v / (2.0 * decel) + vs.size_lwh_m.x;
        let me = self.own_frame(i);
        let lane = &self.spec.lanes[self.vehicles[i].lane];
        let limit = lane.curve_speed_limit_mps(me.s_m, horizon, lateral_accel, decel);
        vs.desired_speed_mps.min(limit)
    }

    /// (gap, closing speed) to the nearest relevant obstacle ahead of `i`.
    fn leader_of(&mut self, i: usize, t_s: f64) -> Option<(f64, f64)> {
        let lane_idx = self.vehicles[i].lane;
        let me = self.own_frame(i);
        let v_i = self.vehicles[i].speed_mps;
        let mut best: Option<(f64, f64)> = None;
        for (_, fj) in self.corridor_bodies(i, lane_idx, &me) {
            if fj.s_m <= me.s_m {
                continue;
            }
            let gap = fj.s_m - me.s_m - me.lon_half_m - fj.lon_half_m;
            best = nearer(best, Some((gap, v_i - fj.speed_along_mps)));
        }
        let front = me.s_m + me.lon_half_m;
        let lane_len = self.spec.lanes[lane_idx].length_m();
        best = nearer(best, Some((lane_len - front, v_i)));
        for jam in &self.spec.jam_fronts {
            if jam.lane != lane_idx {
                continue;
            }
            let (s_m, speed_mps) = jam.state_at(t_s);
            if s_m > front {
                best = nearer(best, Some((s_m - front, v_i - speed_mps)));
            }
        }
        let b = self.spec.vehicles[i].driver.comfortable_decel_mps2;
        for (k, line) in self.spec.stop_lines.iter().enumerate() {
            if line.lane != lane_idx {
                continue;
            }
            if !line.is_red(t_s) {
                self.vehicles[i].stop_decision[k] = None;
                continue;
            }
            let dist = line.s_m - front;
            let decision = *self.vehicles[i].stop_decision[k]
                .get_or_insert(dist > 0.0 && v_i * v_i <= 2.0 * b * dist);
            if decision {
                best = nearer(best, Some((dist, v_i)));
            }
        }
        best
    }

    /// The cooperative lane change `i` has due at `t_s`, if any: requested,
    /// departed, the previous transition over and not yet started.
    fn due_cooperative_change(&self, i: usize, t_s: f64) -> Option<&LaneChange> {
        let (spec_i, v) = (&self.spec.vehicles[i], &self.vehicles[i]);
        let request = spec_i.lane_changes.get(v.next_change)?;
        let in_transition = v.transition.is_some_and(|tr| t_s < tr.t0_s + tr.duration_s);
        (request.cooperative
            && t_s >= request.t_s
            && t_s >= spec_i.depart_s
            && !in_transition
            && request.to_lane != v.lane)
            .then_some(request)
    }

    /// Acceleration limit of `i` from cooperative lane changes, braking at
    /// most at its comfortable deceleration: IDM behind the target lane's
    /// vehicles ahead of `i` while `i`'s own change is due, and behind every
    /// vehicle ahead of `i` whose due change targets `i`'s lane.
    fn cooperative_accel(&self, i: usize, t_s: f64) -> Option<f64> {
        let spec_i = &self.spec.vehicles[i];
        let v_i = self.vehicles[i].speed_mps;
        let ci = self.vehicles[i].centre();
        let follow = |me: &LaneFrame, fj: &LaneFrame| {
            let gap = fj.s_m - me.s_m - me.lon_half_m - fj.lon_half_m;
            idm_accel(
                &spec_i.driver,
                spec_i.desired_speed_mps,
                v_i,
                Some((gap, v_i - fj.speed_along_mps)),
            )
            .max(-spec_i.driver.comfortable_decel_mps2)
        };
        let near =
            |j: usize| j != i && (self.vehicles[j].centre() - ci).norm() <= INTERACTION_RANGE_M;
        let mut limit: Option<f64> = None;
        let mut lower = |a: f64| limit = Some(limit.map_or(a, |l| l.min(a)));
        if let Some(request) = self.due_cooperative_change(i, t_s)
            && let Some(me) = self.frames[i][request.to_lane]
        {
            for j in (0..self.vehicles.len()).filter(|&j| near(j)) {
                if self.vehicles[j].lane == request.to_lane
                    && let Some(fj) = self.frames[j][request.to_lane]
                    && fj.s_m > me.s_m
                {
                    lower(follow(&me, &fj));
                }
            }
        }
        let lane_i = self.vehicles[i].lane;
        let me = self.own_frame(i);
        for j in (0..self.vehicles.len()).filter(|&j| near(j)) {
            if self
                .due_cooperative_change(j, t_s)
                .is_some_and(|r| r.to_lane == lane_i)
                && let Some(fj) = self.frames[j][lane_i]
                && fj.s_m > me.s_m
            {
                lower(follow(&me, &fj));
            }
        }
        limit
    }

    /// Tries the pending lane change of `i`; true if it starts now.
    fn try_lane_change(&mut self, i: usize, t_s: f64) -> bool {
        let spec_i = &self.spec.vehicles[i];
        let v = &self.vehicles[i];
        let Some(request) = spec_i.lane_changes.get(v.next_change) else {
            return false;
        };
        if t_s < request.t_s || t_s < spec_i.depart_s {
            return false;
        }
        if let Some(tr) = v.transition
            && t_s < tr.t0_s + tr.duration_s
        {
            return false;
        }
        if request.to_lane == v.lane {
            self.vehicles[i].next_change += 1;
            return false;
        }
        let to = request.to_lane;
        let Some(me) = self.frames[i][to] else {
            return false; // target lane not nearby (yet): retry later
        };
        let v_i = v.speed_mps;
        for (j, fj) in self.corridor_bodies(i, to, &me) {
            let spec_j = &self.spec.vehicles[j];
            let ok = if fj.s_m >= me.s_m {
                let gap = fj.s_m - me.s_m - me.lon_half_m - fj.lon_half_m;
                gap > spec_i.driver.min_gap_m
                    && idm_accel(
                        &spec_i.driver,
                        spec_i.desired_speed_mps,
                        v_i,
                        Some((gap, v_i - fj.speed_along_mps)),
                    ) >= -spec_i.driver.safe_decel_mps2
            } else {
                let gap = me.s_m - fj.s_m - me.lon_half_m - fj.lon_half_m;
                gap > spec_j.driver.min_gap_m
                    && idm_accel(
                        &spec_j.driver,
                        spec_j.desired_speed_mps,
                        fj.speed_along_mps.max(0.0),
                        Some((gap, fj.speed_along_mps - me.speed_along_mps)),
                    ) >= -spec_j.driver.safe_decel_mps2
            };
            if !ok {
                return false;
            }
        }
        // the pure-pursuit reference is the rear axle: fade its lateral offset
        let v = &self.vehicles[i];
        let (_, d_rear) = self.spec.lanes[to]
            .project_near(&Point2::from(v.rear), 40.0)
            .unwrap_or_else(|| self.spec.lanes[to].project(&Point2::from(v.rear)));
        let vm = &mut self.vehicles[i];
        vm.lane = to;
        vm.next_change += 1;
        vm.transition = Some(Transition {
            t0_s: t_s,
            d0_m: d_rear,
            duration_s: spec_i.driver.lane_change_duration_s,
        });
        true
    }

    /// Pure-pursuit steering command of vehicle `i`.
    fn steer_command(&mut self, i: usize, t_s: f64) -> f64 {
        let v = &self.vehicles[i];
        let p = &self.spec.vehicles[i].driver;
        let lane = &self.spec.lanes[v.lane];
        let rear = Point2::from(v.rear);
        let (s_r, _) = match self.rear_hints[i] {
            Some((l, s0)) if l == v.lane => lane.project_from(&rear, s0),
            _ => None,
        }
        .or_else(|| lane.project_near(&rear, 15.0))
        .unwrap_or_else(|| lane.project(&rear));
        self.rear_hints[i] = Some((v.lane, s_r));
        let lookahead = (p.lookahead_time_s * v.speed_mps).max(p.min_lookahead_m);
        let offset = v.transition.map_or(0.0, |tr| {
            tr.offset_at(t_s + lookahead / v.speed_mps.max(1.0))
        });
        let s_goal = s_r + lookahead;
        let (heading_goal, point_goal, _, _) = lane.local_at(s_goal, 0);
        let goal = point_goal + normal_vec(heading_goal) * offset;
        let g = goal - rear;
        let (sn, cs) = v.yaw.sin_cos();
        let (gx, gy) = (cs * g.x + sn * g.y, -sn * g.x + cs * g.y);
        let dist2 = (gx * gx + gy * gy).max(1e-6);
        let curvature = 2.0 * gy / dist2;
        (curvature * 2.0 * v.half_wheelbase_m)
            .atan()
            .clamp(-p.max_steer_rad, p.max_steer_rad)
    }

    /// Sample of vehicle `i` with exact model derivatives at this instant.
    fn sample(&self, i: usize) -> PlanarSample {
        let v = &self.vehicles[i];
        let p = &self.spec.vehicles[i].driver;
        let wb = 2.0 * v.half_wheelbase_m;
        let tan_d = v.steer_rad.tan();
        let sec2 = 1.0 + tan_d * tan_d;
        let steer_rate = (v.steer_cmd_rad - v.steer_rad) / p.steer_lag_s;
        let yaw_rate = v.speed_mps * tan_d / wb;
        let yaw_accel = (v.accel_mps2 * tan_d + v.speed_mps * sec2 * steer_rate) / wb;
        let (t, n) = (heading_vec(v.yaw), normal_vec(v.yaw));
        let h = v.half_wheelbase_m;
        let vel = t * v.speed_mps + n * (h * yaw_rate);
        let acc = t * v.accel_mps2
            + n * (v.speed_mps * yaw_rate)
            + (n * yaw_accel - t * (yaw_rate * yaw_rate)) * h;
        let c = v.centre();
        PlanarSample {
            x: c.x,
            y: c.y,
            yaw: v.yaw,
            speed_mps: v.speed_mps,
            accel_mps2: v.accel_mps2,
            yaw_rate_radps: yaw_rate,
            yaw_accel_radps2: yaw_accel,
            vx_mps: vel.x,
            vy_mps: vel.y,
            ax_mps2: acc.x,
            ay_mps2: acc.y,
            lane: v.lane,
        }
    }

    /// One semi-implicit Euler step of every vehicle (lags first, then speed,
    /// heading, position).
    fn integrate(&mut self, t_s: f64) -> Result<(), TrafficError> {
        for (v, vs) in self.vehicles.iter_mut().zip(&self.spec.vehicles) {
            let p = &vs.driver;
            v.steer_rad +=
                (v.steer_cmd_rad - v.steer_rad) * (1.0 - (-SIM_DT_S / p.steer_lag_s).exp());
            if t_s < vs.depart_s {
                v.speed_mps = 0.0;
                v.accel_mps2 = 0.0;
                continue;
            }
            v.accel_mps2 +=
                (v.accel_cmd_mps2 - v.accel_mps2) * (1.0 - (-SIM_DT_S / p.accel_lag_s).exp());
            // no deceleration beyond what stops the vehicle within STOP_TIME_S:
            // a stop ends with the deceleration fading to zero, not jumping
            v.accel_mps2 = v.accel_mps2.max(-v.speed_mps / STOP_TIME_S);
            v.speed_mps += v.accel_mps2 * SIM_DT_S;
            if v.speed_mps <= 0.0 {
                // standing still: no reversing, no residual braking
                v.speed_mps = 0.0;
                v.accel_mps2 = v.accel_mps2.max(0.0);
            }
            v.yaw += v.speed_mps * v.steer_rad.tan() / (2.0 * v.half_wheelbase_m) * SIM_DT_S;
            v.rear += heading_vec(v.yaw) * (v.speed_mps * SIM_DT_S);
            if !(v.rear.x.is_finite()
                && v.rear.y.is_finite()
                && v.yaw.is_finite()
                && v.speed_mps.is_finite())
            {
                return Err(TrafficError::Diverged { id: vs.id, t_s });
            }
        }
        Ok(())
    }
}

/// Initial state of every vehicle: centre on its lane at start_s, aligned with it.
fn initial_vehicles(spec: &TrafficSpec) -> Vec<Vehicle> {
    spec.vehicles
        .iter()
        .map(|vs| {
            let lane = &spec.lanes[vs.lane];
            let h = 0.3 * vs.size_lwh_m.x;
            let yaw = lane.heading_at(vs.start_s_m);
            let centre = lane.point_at(vs.start_s_m);
            let speed = if vs.depart_s > 0.0 {
                0.0
            } else {
                vs.start_speed_mps
            };
            Vehicle {
                rear: centre.coords - heading_vec(yaw) * h,
                yaw,
                speed_mps: speed,
                accel_mps2: 0.0,
                steer_rad: 0.0,
                accel_cmd_mps2: 0.0,
                steer_cmd_rad: 0.0,
                lane: vs.lane,
                transition: None,
                next_change: 0,
                stop_decision: vec![None; spec.stop_lines.len()],
                half_wheelbase_m: h,
            }
        })
        .collect()
}

/// Spec error if two bodies overlap or a follower starts closer than it can
/// handle: min gap + emergency stopping distance difference + lag distance.
fn check_start_gaps(sim: &Sim) -> Result<(), TrafficError> {
    for i in 0..sim.vehicles.len() {
        let lane_idx = sim.vehicles[i].lane;
        let me = sim.own_frame(i);
        let p = &sim.spec.vehicles[i].driver;
        for (j, fj) in sim.corridor_bodies(i, lane_idx, &me) {
            let overlap_lat = (fj.lateral_m - me.lateral_m).abs() < fj.lat_half_m + me.lat_half_m;
            if fj.s_m < me.s_m || (!overlap_lat && sim.vehicles[j].lane != lane_idx) {
                continue;
            }
            let gap = fj.s_m - me.s_m - me.lon_half_m - fj.lon_half_m;
            let (v_f, v_l) = (sim.vehicles[i].speed_mps, fj.speed_along_mps.max(0.0));
            let required = p.min_gap_m
                + ((v_f * v_f - v_l * v_l) / (2.0 * p.max_decel_mps2)).max(0.0)
                + v_f * p.accel_lag_s;
            if gap < required {
                return Err(TrafficError::StartTooClose {
                    follower: sim.spec.vehicles[i].id,
                    leader: sim.spec.vehicles[j].id,
                    lane: lane_idx,
                    gap_m: gap,
                    required_m: required,
                });
            }
        }
    }
    Ok(())
}

/// The simulation loop into tracks: one sample every `record_every` 1 ms
/// steps.
fn simulate(spec: &TrafficSpec, record_every: usize) -> Result<Vec<PlanarTrack>, TrafficError> {
    validate(spec)?;
    let record_dt = SIM_DT_S * record_every as f64;
    let n_samples = sample_count(spec, record_dt);
    let mut samples: Vec<Vec<PlanarSample>> =
        vec![Vec::with_capacity(n_samples); spec.vehicles.len()];
    run(spec, record_every, |i, sample| samples[i].push(*sample))?;
    Ok(spec
        .vehicles
        .iter()
        .zip(samples)
        .map(|(vs, samples)| PlanarTrack {
            id: vs.id,
            t0_s: 0.0,
            dt_s: record_dt,
            samples,
        })
        .collect())
}

/// The simulation loop; hands `record(vehicle index, sample)` one sample
/// of every vehicle (in spec order) every `record_every` 1 ms steps.
fn run(
    spec: &TrafficSpec,
    record_every: usize,
    mut record: impl FnMut(usize, &PlanarSample),
) -> Result<(), TrafficError> {
    validate(spec)?;
    let mut sim = Sim::new(spec);
    check_start_gaps(&sim)?;
    let record_dt = SIM_DT_S * record_every as f64;
    let n_samples = sample_count(spec, record_dt);
    let n_steps = (n_samples - 1) * record_every;
    for k in 0..=n_steps {
        let t_s = k as f64 * SIM_DT_S;
        if k % PLAN_EVERY == 0 {
            sim.refresh_frames();
            for i in 0..sim.vehicles.len() {
                sim.try_lane_change(i, t_s);
            }
            for i in 0..sim.vehicles.len() {
                let vs = &spec.vehicles[i];
                let leader = sim.leader_of(i, t_s);
                let v = sim.vehicles[i].speed_mps;
                let cmd = if t_s < vs.depart_s {
                    0.0
                } else {
                    let desired = sim.curve_limited_speed_mps(i);
                    let own = idm_accel(&vs.driver, desired, v, leader);
                    sim.cooperative_accel(i, t_s).map_or(own, |c| own.min(c))
                };
                sim.vehicles[i].accel_cmd_mps2 = cmd;
                if k == 0 && t_s >= vs.depart_s {
                    // start in equilibrium with the command: no initial jerk
                    sim.vehicles[i].accel_mps2 = cmd.max(-v / STOP_TIME_S);
                }
            }
        }
        for i in 0..sim.vehicles.len() {
            let cmd = sim.steer_command(i, t_s);
            sim.vehicles[i].steer_cmd_rad = cmd;
            if k == 0 {
                sim.vehicles[i].steer_rad = cmd;
            }
        }
        if k % record_every == 0 {
            for i in 0..sim.vehicles.len() {
                record(i, &sim.sample(i));
            }
        }
        if k < n_steps {
            sim.integrate(t_s)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
