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
//! - Lane changes are requested at a time and executed at the first 100 Hz
//!   update where a MOBIL-style safety criterion holds (new leader and new
//!   follower keep at least their minimum gap and neither would have to brake
//!   harder than the driver's `safe_decel_mps2`); otherwise retried.
//! - Deterministic: no randomness; vehicles are updated in spec order.
//!
//! Only same-lane and lane-changing conflicts are resolved; crossing lanes at
//! intersections must be separated by the generator's stop-line phases.

mod lane_path;
mod lift;
mod overlap;
mod suspension;

pub use lane_path::{LanePath, PathPiece};
pub use lift::{lift_onto, lift_to_ground};
pub use overlap::{Body, Overlap, first_overlap};
pub use suspension::{BodyAttitude, RideInput, Suspension, ride};

use lane_path::wrap_angle;
use limot_estimator::input::ObjectClass;
use nalgebra::{Point2, Vector2, Vector3};

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
/// Other bodies farther than this (centre distance) are ignored by the planner.
const INTERACTION_RANGE_M: f64 = 250.0;

/// A lane change request; executed at the first moment after `t_s` when it is safe.
#[derive(Debug, Clone, PartialEq)]
pub struct LaneChange {
    pub t_s: f64,
    pub to_lane: usize,
}

/// One road user. `start_speed_mps` applies when `depart_s <= 0`; a vehicle with
/// a later departure starts at rest and is held there until `depart_s`.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleSpec {
    pub id: u32,
    /// Car, Truck, Cyclist, Pedestrian all use this model.
    pub class: ObjectClass,
    pub size_lwh_m: Vector3<f64>,
    /// Index into `TrafficSpec::lanes`.
    pub lane: usize,
    /// Arc length of the box centre on the lane at t = 0.
    pub start_s_m: f64,
    pub start_speed_mps: f64,
    pub desired_speed_mps: f64,
    /// Held at rest (speed 0) until this time.
    pub depart_s: f64,
    /// Processed in order: a request is considered once the previous one has
    /// finished its transition.
    pub lane_changes: Vec<LaneChange>,
    pub driver: DriverParams,
}

/// Driver and vehicle-dynamics parameters (IDM, MOBIL safety, lags, pure pursuit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriverParams {
    /// IDM maximum acceleration a.
    pub max_accel_mps2: f64,
    /// IDM comfortable deceleration b (also the stop-line "can still stop" limit).
    pub comfortable_decel_mps2: f64,
    /// IDM desired time headway T.
    pub time_headway_s: f64,
    /// IDM standstill gap s0 (bumper to bumper along the lane).
    pub min_gap_m: f64,
    pub lane_change_duration_s: f64,
    /// Hard limit of the commanded deceleration.
    pub max_decel_mps2: f64,
    /// MOBIL safety: a lane change may not force anyone to brake harder than this.
    pub safe_decel_mps2: f64,
    /// First-order lag of the realised acceleration behind the IDM command.
    pub accel_lag_s: f64,
    /// First-order lag of the steering angle behind the pure-pursuit command.
    pub steer_lag_s: f64,
    /// Pure-pursuit lookahead = max(min_lookahead_m, lookahead_time_s * speed).
    pub lookahead_time_s: f64,
    pub min_lookahead_m: f64,
    pub max_steer_rad: f64,
}

impl DriverParams {
    pub fn car() -> Self {
        DriverParams {
            max_accel_mps2: 2.0,
            comfortable_decel_mps2: 2.5,
            time_headway_s: 1.4,
            min_gap_m: 2.0,
            lane_change_duration_s: 4.0,
            max_decel_mps2: 8.0,
            safe_decel_mps2: 3.0,
            accel_lag_s: 0.25,
            steer_lag_s: 0.15,
            lookahead_time_s: 0.9,
            min_lookahead_m: 5.0,
            max_steer_rad: 0.6,
        }
    }

    pub fn truck() -> Self {
        DriverParams {
            max_accel_mps2: 1.0,
            comfortable_decel_mps2: 1.8,
            time_headway_s: 1.8,
            min_gap_m: 3.0,
            lane_change_duration_s: 6.0,
            max_decel_mps2: 6.0,
            safe_decel_mps2: 2.0,
            accel_lag_s: 0.4,
            steer_lag_s: 0.25,
            lookahead_time_s: 1.1,
            min_lookahead_m: 8.0,
            max_steer_rad: 0.55,
        }
    }

    pub fn cyclist() -> Self {
        DriverParams {
            max_accel_mps2: 1.0,
            comfortable_decel_mps2: 2.0,
            time_headway_s: 1.2,
            min_gap_m: 1.5,
            lane_change_duration_s: 2.5,
            max_decel_mps2: 5.0,
            safe_decel_mps2: 2.0,
            accel_lag_s: 0.25,
            steer_lag_s: 0.1,
            lookahead_time_s: 0.9,
            min_lookahead_m: 2.5,
            max_steer_rad: 0.8,
        }
    }

    pub fn pedestrian() -> Self {
        DriverParams {
            max_accel_mps2: 0.8,
            comfortable_decel_mps2: 1.5,
            time_headway_s: 1.0,
            min_gap_m: 0.8,
            lane_change_duration_s: 2.0,
            max_decel_mps2: 3.0,
            safe_decel_mps2: 1.2,
            accel_lag_s: 0.3,
            steer_lag_s: 0.15,
            lookahead_time_s: 1.2,
            min_lookahead_m: 1.2,
            max_steer_rad: 1.0,
        }
    }

    fn check(&self, id: u32) -> Result<(), TrafficError> {
        let fields = [
            ("driver.max_accel_mps2", self.max_accel_mps2),
            ("driver.comfortable_decel_mps2", self.comfortable_decel_mps2),
            ("driver.time_headway_s", self.time_headway_s),
            ("driver.min_gap_m", self.min_gap_m),
            ("driver.lane_change_duration_s", self.lane_change_duration_s),
            ("driver.max_decel_mps2", self.max_decel_mps2),
            ("driver.safe_decel_mps2", self.safe_decel_mps2),
            ("driver.accel_lag_s", self.accel_lag_s),
            ("driver.steer_lag_s", self.steer_lag_s),
            ("driver.lookahead_time_s", self.lookahead_time_s),
            ("driver.min_lookahead_m", self.min_lookahead_m),
            ("driver.max_steer_rad", self.max_steer_rad),
        ];
        for (field, value) in fields {
            if !(value.is_finite() && value > 0.0) {
                return Err(vehicle_error(
                    id,
                    field,
                    format!("{value} must be finite and > 0"),
                ));
            }
        }
        if self.max_steer_rad >= 1.5 {
            return Err(vehicle_error(
                id,
                "driver.max_steer_rad",
                format!("{} must be < 1.5 rad", self.max_steer_rad),
            ));
        }
        if self.max_decel_mps2 < self.comfortable_decel_mps2 {
            return Err(vehicle_error(
                id,
                "driver.max_decel_mps2",
                format!(
                    "{} must be >= comfortable_decel_mps2 {}",
                    self.max_decel_mps2, self.comfortable_decel_mps2
                ),
            ));
        }
        Ok(())
    }
}

/// A stop line with red phases (stop-and-go at intersections).
#[derive(Debug, Clone, PartialEq)]
pub struct StopLine {
    pub lane: usize,
    pub s_m: f64,
    /// Half-open red intervals [start, end) in seconds.
    pub red_intervals_s: Vec<(f64, f64)>,
}

impl StopLine {
    fn is_red(&self, t_s: f64) -> bool {
        self.red_intervals_s
            .iter()
            .any(|&(a, b)| t_s >= a && t_s < b)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct TrafficSpec {
    pub lanes: Vec<LanePath>,
    pub vehicles: Vec<VehicleSpec>,
    pub stop_lines: Vec<StopLine>,
    pub duration_s: f64,
}

/// Planar motion of one vehicle's box centre, sampled every `dt_s` (0.01 s).
#[derive(Debug, Clone, PartialEq)]
pub struct PlanarTrack {
    pub id: u32,
    pub t0_s: f64,
    pub dt_s: f64,
    pub samples: Vec<PlanarSample>,
}

/// State of the box centre at one sample, with exact time derivatives of the
/// vehicle model at that instant (used as Hermite knot data).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarSample {
    /// Box centre, world frame.
    pub x: f64,
    pub y: f64,
    /// Heading, unwrapped (continuous over the track).
    pub yaw: f64,
    /// Rear-axle speed along the heading (the model's speed state), >= 0.
    pub speed_mps: f64,
    /// d speed / dt.
    pub accel_mps2: f64,
    pub yaw_rate_radps: f64,
    pub yaw_accel_radps2: f64,
    /// Box-centre velocity and acceleration, world frame.
    pub vx_mps: f64,
    pub vy_mps: f64,
    pub ax_mps2: f64,
    pub ay_mps2: f64,
    /// Reference lane at this instant (the target lane during a lane change).
    pub lane: usize,
}

#[derive(Debug, thiserror::Error)]
pub enum TrafficError {
    #[error("invalid lane path: {reason}")]
    InvalidPath { reason: String },
    #[error("traffic spec: {field}: {reason}")]
    InvalidSpec { field: String, reason: String },
    #[error("vehicle id {id}: {field}: {reason}")]
    InvalidVehicle {
        id: u32,
        field: String,
        reason: String,
    },
    #[error("stop line {index}: {field}: {reason}")]
    InvalidStopLine {
        index: usize,
        field: String,
        reason: String,
    },
    #[error(
        "vehicle id {follower} starts {gap_m:.2} m behind vehicle id {leader} on lane {lane}; at least {required_m:.2} m needed"
    )]
    StartTooClose {
        follower: u32,
        leader: u32,
        lane: usize,
        gap_m: f64,
        required_m: f64,
    },
    #[error("vehicle id {id}: state became non-finite at t = {t_s} s")]
    Diverged { id: u32, t_s: f64 },
}

fn vehicle_error(id: u32, field: &str, reason: String) -> TrafficError {
    TrafficError::InvalidVehicle {
        id,
        field: field.to_string(),
        reason,
    }
}

/// Simulates all vehicles over [0, duration_s]; tracks in `spec.vehicles` order,
/// each starting at t = 0 with one sample every 0.01 s (end included).
///
/// Errors: invalid fields (named with the vehicle id / stop-line index), and
/// vehicles that start overlapping or closer behind another body in their
/// corridor than min gap + (v_f^2 - v_l^2) / (2 max_decel) + v_f * accel_lag.
pub fn simulate_traffic(spec: &TrafficSpec) -> Result<Vec<PlanarTrack>, TrafficError> {
    simulate(spec, RECORD_EVERY)
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
    let dpsi = wrap_angle(v.yaw - lane.heading_at(s));
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
        let goal = lane.point_at_extended(s_goal) + normal_vec(lane.heading_at(s_goal)) * offset;
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

fn validate(spec: &TrafficSpec) -> Result<(), TrafficError> {
    if !(spec.duration_s.is_finite() && spec.duration_s > 0.0) {
        return Err(TrafficError::InvalidSpec {
            field: "duration_s".into(),
            reason: format!("{} must be finite and > 0", spec.duration_s),
        });
    }
    if spec.duration_s > 3600.0 {
        return Err(TrafficError::InvalidSpec {
            field: "duration_s".into(),
            reason: format!("{} exceeds one hour", spec.duration_s),
        });
    }
    let n_lanes = spec.lanes.len();
    let mut ids = std::collections::HashSet::new();
    for vs in &spec.vehicles {
        let id = vs.id;
        if !ids.insert(id) {
            return Err(vehicle_error(id, "id", "duplicate vehicle id".into()));
        }
        if vs.lane >= n_lanes {
            return Err(vehicle_error(
                id,
                "lane",
                format!("{} out of range ({} lanes)", vs.lane, n_lanes),
            ));
        }
        let size = vs.size_lwh_m;
        if !(size.iter().all(|x| x.is_finite() && *x > 0.05)) {
            return Err(vehicle_error(
                id,
                "size_lwh_m",
                format!("{size:?} must be finite and > 0.05 m"),
            ));
        }
        let len = spec.lanes[vs.lane].length_m();
        if !(vs.start_s_m.is_finite() && (0.0..=len).contains(&vs.start_s_m)) {
            return Err(vehicle_error(
                id,
                "start_s_m",
                format!("{} outside lane {} [0, {len}]", vs.start_s_m, vs.lane),
            ));
        }
        if !(vs.start_speed_mps.is_finite() && vs.start_speed_mps >= 0.0) {
            return Err(vehicle_error(
                id,
                "start_speed_mps",
                format!("{} must be finite and >= 0", vs.start_speed_mps),
            ));
        }
        if !(vs.desired_speed_mps.is_finite() && vs.desired_speed_mps > 0.0) {
            return Err(vehicle_error(
                id,
                "desired_speed_mps",
                format!("{} must be finite and > 0", vs.desired_speed_mps),
            ));
        }
        if !vs.depart_s.is_finite() {
            return Err(vehicle_error(
                id,
                "depart_s",
                format!("{} is not finite", vs.depart_s),
            ));
        }
        for (k, lc) in vs.lane_changes.iter().enumerate() {
            if !lc.t_s.is_finite() {
                return Err(vehicle_error(
                    id,
                    &format!("lane_changes[{k}].t_s"),
                    format!("{} is not finite", lc.t_s),
                ));
            }
            if lc.to_lane >= n_lanes {
                return Err(vehicle_error(
                    id,
                    &format!("lane_changes[{k}].to_lane"),
                    format!("{} out of range ({} lanes)", lc.to_lane, n_lanes),
                ));
            }
        }
        vs.driver.check(id)?;
    }
    for (index, line) in spec.stop_lines.iter().enumerate() {
        let err = |field: &str, reason: String| TrafficError::InvalidStopLine {
            index,
            field: field.into(),
            reason,
        };
        if line.lane >= n_lanes {
            return Err(err(
                "lane",
                format!("{} out of range ({n_lanes} lanes)", line.lane),
            ));
        }
        let len = spec.lanes[line.lane].length_m();
        if !(line.s_m.is_finite() && (0.0..=len).contains(&line.s_m)) {
            return Err(err("s_m", format!("{} outside [0, {len}]", line.s_m)));
        }
        for (k, &(a, b)) in line.red_intervals_s.iter().enumerate() {
            if !(a.is_finite() && b.is_finite() && a < b) {
                return Err(err(
                    &format!("red_intervals_s[{k}]"),
                    format!("({a}, {b}) must be finite with start < end"),
                ));
            }
        }
    }
    Ok(())
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

/// The simulation loop; records one sample every `record_every` 1 ms steps.
fn simulate(spec: &TrafficSpec, record_every: usize) -> Result<Vec<PlanarTrack>, TrafficError> {
    validate(spec)?;
    let mut sim = Sim::new(spec);
    check_start_gaps(&sim)?;
    let record_dt = SIM_DT_S * record_every as f64;
    let n_samples = (spec.duration_s / record_dt).round() as usize + 1;
    let n_steps = (n_samples - 1) * record_every;
    let mut samples: Vec<Vec<PlanarSample>> =
        vec![Vec::with_capacity(n_samples); spec.vehicles.len()];
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
                    idm_accel(&vs.driver, vs.desired_speed_mps, v, leader)
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
            for (i, out) in samples.iter_mut().enumerate() {
                out.push(sim.sample(i));
            }
        }
        if k < n_steps {
            sim.integrate(t_s)?;
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Agent, Ego, Ground, Scene, Undulation};
    use crate::trajectory::{Jet, Knot, Trajectory};
    use nalgebra::{Isometry3, Vector2};

    fn car(id: u32, lane: usize, s: f64, v: f64, v0: f64) -> VehicleSpec {
        VehicleSpec {
            id,
            class: ObjectClass::Car,
            size_lwh_m: Vector3::new(4.5, 1.8, 1.5),
            lane,
            start_s_m: s,
            start_speed_mps: v,
            desired_speed_mps: v0,
            depart_s: 0.0,
            lane_changes: Vec::new(),
            driver: DriverParams::car(),
        }
    }

    fn straight(length_m: f64, offset_m: f64) -> LanePath {
        LanePath::from_pieces(
            Point2::new(0.0, 0.0),
            0.0,
            &[PathPiece::Straight { length_m }],
            offset_m,
        )
        .unwrap()
    }

    fn spec(lanes: Vec<LanePath>, vehicles: Vec<VehicleSpec>, duration_s: f64) -> TrafficSpec {
        TrafficSpec {
            lanes,
            vehicles,
            stop_lines: Vec::new(),
            duration_s,
        }
    }

    /// Scene of the tracks on flat ground with the ego parked far away.
    fn scene_of(spec: &TrafficSpec, tracks: &[PlanarTrack]) -> Scene {
        let ground = Ground::flat(0.0);
        let agents = tracks
            .iter()
            .zip(&spec.vehicles)
            .map(|(tr, vs)| Agent {
                id: vs.id,
                class: vs.class,
                size_lwh_m: vs.size_lwh_m,
                parked: false,
                trajectory: lift_to_ground(tr, &ground, &vs.size_lwh_m, None),
            })
            .collect();
        Scene {
            duration_s: spec.duration_s,
            ground,
            statics: Vec::new(),
            agents,
            ego: Ego {
                trajectory: Trajectory::stationary(
                    0.0,
                    spec.duration_s,
                    &Isometry3::translation(-1e4, -1e4, 0.0),
                ),
                size_lwh_m: Vector3::new(4.5, 1.8, 1.5),
                box_center_lidar_m: Vector3::new(0.0, 0.0, -1.0),
                t_lidar_imu: Isometry3::identity(),
            },
        }
    }

    #[test]
    fn single_car_reaches_desired_speed_on_a_straight() {
        let s = spec(
            vec![straight(2000.0, 0.0)],
            vec![car(1, 0, 10.0, 0.0, 20.0)],
            40.0,
        );
        let tracks = simulate_traffic(&s).unwrap();
        let samples = &tracks[0].samples;
        assert_eq!(samples.len(), 4001);
        let last = samples.last().unwrap();
        assert!(
            (last.speed_mps - 20.0).abs() < 0.5,
            "speed {}",
            last.speed_mps
        );
        assert!(
            samples
                .iter()
                .all(|p| p.y.abs() < 1e-9 && p.speed_mps <= 20.0 + 1e-9)
        );
        // recorded velocity integrates to the recorded positions
        for w in samples.windows(2) {
            let mid_vx = 0.5 * (w[0].vx_mps + w[1].vx_mps);
            assert!((w[1].x - w[0].x - mid_vx * 0.01).abs() < 1e-4);
        }
    }

    #[test]
    fn car_stops_before_the_lane_ends() {
        let s = spec(
            vec![straight(120.0, 0.0)],
            vec![car(1, 0, 10.0, 15.0, 15.0)],
            30.0,
        );
        let tracks = simulate_traffic(&s).unwrap();
        let front_max = tracks[0]
            .samples
            .iter()
            .map(|p| p.x + 2.25)
            .fold(f64::MIN, f64::max);
        let last = tracks[0].samples.last().unwrap();
        eprintln!("stopped {:.2} m before the lane end", 120.0 - front_max);
        assert!(front_max < 120.0 && front_max > 115.0, "front {front_max}");
        assert!(last.speed_mps < 0.01);
    }

    #[test]
    fn car_on_an_arc_stays_near_the_lane_centre() {
        let radius = 60.0;
        let lane = LanePath::from_pieces(
            Point2::new(0.0, 0.0),
            0.0,
            &[
                PathPiece::Straight { length_m: 30.0 },
                PathPiece::Arc {
                    length_m: 300.0,
                    curvature_1pm: 1.0 / radius,
                },
            ],
            0.0,
        )
        .unwrap();
        let s = spec(vec![lane.clone()], vec![car(1, 0, 5.0, 12.0, 12.0)], 25.0);
        let tracks = simulate_traffic(&s).unwrap();
        let mut worst: f64 = 0.0;
        for (k, p) in tracks[0].samples.iter().enumerate() {
            let (s_m, d) = lane.project(&Point2::new(p.x, p.y));
            if k as f64 * 0.01 > 8.0 && s_m < 300.0 {
                worst = worst.max(d.abs());
            }
        }
        eprintln!("arc steady-state lateral error {worst:.4} m");
        assert!(worst < 0.2, "lateral error {worst}");
        // whole run, including the straight-to-arc transition
        let all = tracks[0]
            .samples
            .iter()
            .map(|p| lane.project(&Point2::new(p.x, p.y)).1.abs())
            .fold(0.0, f64::max);
        assert!(all < 0.5, "transient lateral error {all}");
    }

    #[test]
    fn follower_keeps_min_gap_and_acceleration_is_continuous() {
        let mut leader = car(1, 0, 100.0, 10.0, 10.0);
        leader.size_lwh_m = Vector3::new(12.0, 2.5, 3.5);
        leader.class = ObjectClass::Truck;
        leader.driver = DriverParams::truck();
        let follower = car(2, 0, 20.0, 25.0, 30.0);
        let s = spec(vec![straight(3000.0, 0.0)], vec![leader, follower], 60.0);
        let tracks = simulate_traffic(&s).unwrap();
        let p = DriverParams::car();
        let mut min_gap = f64::INFINITY;
        for (a, b) in tracks[0].samples.iter().zip(&tracks[1].samples) {
            min_gap = min_gap.min(a.x - b.x - 6.0 - 2.25);
        }
        let last_gap = {
            let (a, b) = (
                tracks[0].samples.last().unwrap(),
                tracks[1].samples.last().unwrap(),
            );
            a.x - b.x - 6.0 - 2.25
        };
        eprintln!("min gap {min_gap:.3} m, final gap {last_gap:.3} m");
        assert!(min_gap >= p.min_gap_m, "min gap {min_gap}");
        // converges towards the IDM equilibrium gap s0 + v T (+ a little)
        let equilibrium = p.min_gap_m + 10.0 * p.time_headway_s;
        assert!((last_gap - equilibrium).abs() < 1.5, "final gap {last_gap}");
        // acceleration only changes as fast as the lag allows
        let max_jump = (p.max_accel_mps2 + p.max_decel_mps2) / p.accel_lag_s * 0.01;
        let mut worst_jump: f64 = 0.0;
        for w in tracks[1].samples.windows(2) {
            worst_jump = worst_jump.max((w[1].accel_mps2 - w[0].accel_mps2).abs());
            // centre acceleration is continuous as well
            let da = ((w[1].ax_mps2 - w[0].ax_mps2).powi(2)
                + (w[1].ay_mps2 - w[0].ay_mps2).powi(2))
            .sqrt();
            assert!(da <= max_jump + 1e-6, "centre accel jump {da}");
        }
        eprintln!("largest accel change per 10 ms {worst_jump:.4} (bound {max_jump:.3})");
        assert!(worst_jump <= max_jump);
        // the follower did brake in earnest
        assert!(tracks[1].samples.iter().any(|p| p.accel_mps2 < -1.0));
    }

    #[test]
    fn follower_stops_behind_a_leader_that_stops_at_a_red_line() {
        let leader = car(1, 0, 150.0, 15.0, 15.0);
        let follower = car(2, 0, 60.0, 25.0, 30.0);
        let mut s = spec(vec![straight(3000.0, 0.0)], vec![leader, follower], 40.0);
        s.stop_lines.push(StopLine {
            lane: 0,
            s_m: 330.0,
            red_intervals_s: vec![(0.0, 30.0)],
        });
        let tracks = simulate_traffic(&s).unwrap();
        let gaps: Vec<f64> = tracks[0]
            .samples
            .iter()
            .zip(&tracks[1].samples)
            .map(|(a, b)| a.x - b.x - 4.5)
            .collect();
        let min_gap = gaps.iter().copied().fold(f64::INFINITY, f64::min);
        eprintln!(
            "stopped queue: min gap {min_gap:.3} m, gap at 29.9 s {:.3} m",
            gaps[2990]
        );
        assert!(
            min_gap >= DriverParams::car().min_gap_m,
            "min gap {min_gap}"
        );
        assert!(tracks[1].samples[2990].speed_mps < 0.05);
        // both move on after the red
        assert!(tracks[1].samples.last().unwrap().speed_mps > 5.0);
    }

    #[test]
    fn car_stops_at_a_red_line_and_goes_on_green() {
        let mut s = spec(
            vec![straight(600.0, 0.0)],
            vec![car(1, 0, 20.0, 12.0, 12.0)],
            40.0,
        );
        s.stop_lines.push(StopLine {
            lane: 0,
            s_m: 150.0,
            red_intervals_s: vec![(0.0, 25.0)],
        });
        let tracks = simulate_traffic(&s).unwrap();
        let samples = &tracks[0].samples;
        let front = |p: &PlanarSample| p.x + 2.25;
        for p in &samples[..2500] {
            assert!(front(p) < 150.0, "crossed on red: {}", front(p));
        }
        let at_red_end = &samples[2499];
        eprintln!(
            "stopped {:.2} m before the line, speed {:.4}",
            150.0 - front(at_red_end),
            at_red_end.speed_mps
        );
        assert!(at_red_end.speed_mps < 0.05);
        assert!(150.0 - front(at_red_end) < 4.0);
        assert!(front(samples.last().unwrap()) > 170.0);
        // a car too close to stop comfortably when the red starts goes on
        let mut late = spec(
            vec![straight(600.0, 0.0)],
            vec![car(1, 0, 140.0, 15.0, 15.0)],
            5.0,
        );
        late.stop_lines.push(StopLine {
            lane: 0,
            s_m: 150.0,
            red_intervals_s: vec![(0.0, 25.0)],
        });
        let tracks = simulate_traffic(&late).unwrap();
        assert!(tracks[0].samples.last().unwrap().x > 180.0);
    }

    #[test]
    fn lane_change_executes_when_free_and_waits_when_blocked() {
        let lanes = vec![straight(2000.0, 0.0), straight(2000.0, 3.5)];
        let mut changer = car(1, 0, 50.0, 15.0, 15.0);
        changer.lane_changes.push(LaneChange {
            t_s: 2.0,
            to_lane: 1,
        });
        let free = spec(lanes.clone(), vec![changer.clone()], 15.0);
        let tracks = simulate_traffic(&free).unwrap();
        let first = tracks[0].samples.iter().position(|p| p.lane == 1).unwrap();
        assert_eq!(first, 200, "change should start at the request");
        let last = tracks[0].samples.last().unwrap();
        assert!((last.y - 3.5).abs() < 0.05, "ended at y {}", last.y);
        // lateral motion is smooth: the lateral acceleration stays moderate
        let max_ay = tracks[0]
            .samples
            .iter()
            .map(|p| p.ay_mps2.abs())
            .fold(0.0, f64::max);
        assert!(max_ay < 2.0, "lateral accel {max_ay}");

        // a car alongside in the target lane blocks until it has pulled ahead
        let blocker = car(2, 1, 50.0, 15.0, 22.0);
        let blocked = spec(lanes, vec![changer, blocker], 30.0);
        let tracks = simulate_traffic(&blocked).unwrap();
        let first = tracks[0].samples.iter().position(|p| p.lane == 1).unwrap();
        eprintln!(
            "blocked lane change started at {:.2} s",
            first as f64 * 0.01
        );
        assert!(first > 300, "started too early at sample {first}");
        let (a, b) = (&tracks[0].samples[first], &tracks[1].samples[first]);
        assert!(b.x - a.x - 4.5 > DriverParams::car().min_gap_m);
        assert!((tracks[0].samples.last().unwrap().y - 3.5).abs() < 0.05);
        let scene = scene_of(&blocked, &tracks);
        assert_eq!(first_overlap(&scene, 0.01), None);
    }

    #[test]
    fn lifted_trajectory_follows_the_dense_samples() {
        let lane = LanePath::from_pieces(
            Point2::new(0.0, 0.0),
            0.2,
            &[
                PathPiece::Straight { length_m: 20.0 },
                PathPiece::Arc {
                    length_m: 80.0,
                    curvature_1pm: -0.04,
                },
                PathPiece::Straight { length_m: 200.0 },
            ],
            0.0,
        )
        .unwrap();
        let mut s = spec(vec![lane], vec![car(1, 0, 5.0, 3.0, 14.0)], 12.0);
        s.stop_lines.push(StopLine {
            lane: 0,
            s_m: 120.0,
            red_intervals_s: vec![(0.0, 7.0)],
        });
        let ground = Ground {
            base_height_m: 1.0,
            slope: Vector2::new(0.02, -0.01),
            undulations: vec![Undulation {
                amplitude_m: 0.4,
                wave_vector: Vector2::new(0.15, 0.1),
                phase_rad: 0.3,
            }],
            ..Ground::flat(0.0)
        };
        let size = s.vehicles[0].size_lwh_m;
        let track = &simulate(&s, RECORD_EVERY).unwrap()[0];
        let dense = &simulate(&s, 1).unwrap()[0];
        let traj = lift_to_ground(track, &ground, &size, None);
        let mut worst_xy: f64 = 0.0;
        let mut worst_z: f64 = 0.0;
        let mut worst_yaw: f64 = 0.0;
        for (k, p) in dense.samples.iter().enumerate() {
            let t = k as f64 * 1e-3;
            let pose = traj.pose_at(t);
            let v = pose.translation.vector;
            worst_xy = worst_xy.max(((v.x - p.x).powi(2) + (v.y - p.y).powi(2)).sqrt());
            worst_z = worst_z.max((v.z - ground.height(p.x, p.y) - 0.75).abs());
            let (_, _, yaw) = pose.rotation.euler_angles();
            worst_yaw = worst_yaw.max(wrap_angle(yaw - p.yaw).abs());
        }
        eprintln!("lift error: xy {worst_xy:.2e} m, z {worst_z:.2e} m, yaw {worst_yaw:.2e} rad");
        assert!(worst_xy < 1e-3 && worst_z < 1e-3 && worst_yaw < 1e-4);
        // pitch/roll knot rates match finite differences of the interpolant
        let state = traj.state_at(3.333);
        let e = 1e-4;
        let fd = (traj.pose_at(3.333 + e).translation.vector
            - traj.pose_at(3.333 - e).translation.vector)
            / (2.0 * e);
        assert!((state.velocity_world_mps - fd).norm() < 1e-5);
        let r0 = traj.pose_at(3.333 - e).rotation;
        let r1 = traj.pose_at(3.333 + e).rotation;
        let omega_fd = (r0.inverse() * r1).scaled_axis() / (2.0 * e);
        assert!((state.angular_velocity_body_radps - omega_fd).norm() < 1e-4);
        // the ground is actually tilting the body
        let (roll, pitch, _) = traj.pose_at(6.0).rotation.euler_angles();
        assert!(roll.abs() + pitch.abs() > 1e-3);
    }

    #[test]
    fn invalid_specs_are_reported() {
        let lane = straight(500.0, 0.0);
        let mut bad_lane = car(7, 3, 10.0, 0.0, 10.0);
        let err = simulate_traffic(&spec(vec![lane.clone()], vec![bad_lane.clone()], 5.0));
        assert!(
            matches!(err, Err(TrafficError::InvalidVehicle { id: 7, ref field, .. }) if field == "lane")
        );
        bad_lane.lane = 0;
        bad_lane.start_speed_mps = f64::NAN;
        let err = simulate_traffic(&spec(vec![lane.clone()], vec![bad_lane], 5.0));
        assert!(err.unwrap_err().to_string().contains("start_speed_mps"));
        let close = vec![car(1, 0, 50.0, 10.0, 10.0), car(2, 0, 44.0, 10.0, 10.0)];
        let err = simulate_traffic(&spec(vec![lane.clone()], close, 5.0));
        assert!(
            matches!(
                err,
                Err(TrafficError::StartTooClose {
                    follower: 2,
                    leader: 1,
                    ..
                })
            ),
            "{err:?}"
        );
        let err = simulate_traffic(&spec(vec![lane], vec![car(1, 0, 5.0, 0.0, 10.0)], -1.0));
        assert!(matches!(err, Err(TrafficError::InvalidSpec { .. })));
    }

    /// Constant-velocity planar trajectory at height 0.75 m.
    fn straight_motion(x0: f64, y0: f64, vx: f64, vy: f64, duration_s: f64) -> Trajectory {
        let yaw = vy.atan2(vx);
        let knots = (0..=(duration_s / 0.1).round() as usize)
            .map(|k| {
                let t = k as f64 * 0.1;
                Knot {
                    position: [
                        Jet::new(x0 + vx * t, vx, 0.0),
                        Jet::new(y0 + vy * t, vy, 0.0),
                        Jet::new(0.75, 0.0, 0.0),
                    ],
                    euler: [Jet::new(yaw, 0.0, 0.0), Jet::default(), Jet::default()],
                }
            })
            .collect();
        Trajectory::new(0.0, 0.1, knots)
    }

    #[test]
    fn first_overlap_reports_collisions_with_agents_ego_and_statics() {
        let s = spec(vec![straight(10.0, 0.0)], Vec::new(), 6.0);
        let mut scene = scene_of(&s, &[]);
        let size = Vector3::new(4.5, 1.8, 1.5);
        let agent = |id: u32, trajectory: Trajectory| Agent {
            id,
            class: ObjectClass::Car,
            size_lwh_m: size,
            parked: false,
            trajectory,
        };
        // two cars crossing at right angles, centres 30 m from the crossing
        scene
            .agents
            .push(agent(1, straight_motion(-30.0, 0.0, 10.0, 0.0, 6.0)));
        scene
            .agents
            .push(agent(2, straight_motion(0.0, -30.0, 0.0, 10.0, 6.0)));
        let hit = first_overlap(&scene, 0.01).expect("crossing cars collide");
        assert_eq!((hit.a, hit.b), (Body::Agent(1), Body::Agent(2)));
        // fronts reach the other's side after 30 - 2.25 - 0.9 m at 10 m/s, plus the 1 cm shrink
        assert!((hit.t_s - 2.69).abs() < 0.015, "{}", hit.t_s);
        // the ego box (below the LiDAR origin) against an agent driving into it
        scene.agents.truncate(1);
        scene.ego.trajectory =
            Trajectory::stationary(0.0, 6.0, &Isometry3::translation(20.0, 0.0, 1.75));
        let hit = first_overlap(&scene, 0.01).expect("agent hits the ego");
        assert_eq!((hit.a, hit.b), (Body::Ego, Body::Agent(1)));
        assert!((hit.t_s - 4.55).abs() < 0.015, "{}", hit.t_s);
        // lifting the ego 2 m higher clears it; a pole in the way is then hit
        scene.ego.trajectory =
            Trajectory::stationary(0.0, 6.0, &Isometry3::translation(20.0, 0.0, 3.9));
        assert_eq!(first_overlap(&scene, 0.01), None);
        scene.statics.push(crate::scene::StaticObject {
            kind: crate::scene::StaticKind::Pole,
            shape: crate::scene::Shape::Cylinder {
                radius_m: 0.2,
                half_height_m: 3.0,
            },
            t_world_object: Isometry3::translation(10.0, 1.0, 3.0),
        });
        let hit = first_overlap(&scene, 0.01).expect("agent hits the pole");
        assert_eq!((hit.a, hit.b), (Body::Agent(1), Body::Static(0)));
        // front at 10 - 0.2 m: centre at 7.55 m, 37.55 m travelled
        assert!((hit.t_s - 3.76).abs() < 0.015, "{}", hit.t_s);
    }
}
