//! The traffic spec (lanes, vehicles, stop lines, driver parameters), its
//! validation, and the planar tracks the traffic simulation produces.

use super::LanePath;
use limot_estimator::input::ObjectClass;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// A lane change request; executed at the first moment after `t_s` when it is safe.
/// In a scenario file (`highway.ego_lane_changes`) it is an inline table
/// `{ t_s = 8.0, to_lane = 2 }`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaneChange {
    /// Earliest time of the change, s.
    pub t_s: f64,
    /// Index of the target lane in `TrafficSpec::lanes`.
    pub to_lane: usize,
    /// Traffic makes room once the request is due: the requester follows the
    /// target lane's vehicles ahead of it and those behind it follow the
    /// requester, each braking at most at its comfortable deceleration, until
    /// the gap is safe. Not a scenario-file field (generators set it).
    #[serde(skip)]
    pub cooperative: bool,
}

/// One road user. `start_speed_mps` applies when `depart_s <= 0`; a vehicle with
/// a later departure starts at rest and is held there until `depart_s`.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleSpec {
    /// Vehicle id (unique in the spec).
    pub id: u32,
    /// Car, Truck, Cyclist, Pedestrian all use this model.
    pub class: ObjectClass,
    /// Box length, width, height, m.
    pub size_lwh_m: Vector3<f64>,
    /// Index into `TrafficSpec::lanes`.
    pub lane: usize,
    /// Arc length of the box centre on the lane at t = 0.
    pub start_s_m: f64,
    /// Speed at t = 0, m/s.
    pub start_speed_mps: f64,
    /// IDM desired speed v0, m/s.
    pub desired_speed_mps: f64,
    /// Held at rest (speed 0) until this time.
    pub depart_s: f64,
    /// Processed in order: a request is considered once the previous one has
    /// finished its transition.
    pub lane_changes: Vec<LaneChange>,
    /// Driver and dynamics parameters.
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
    /// Duration of a lane change's lateral transition, s.
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
    /// Shortest pure-pursuit lookahead, m.
    pub min_lookahead_m: f64,
    /// Steering angle limit, rad (< 1.5).
    pub max_steer_rad: f64,
    /// Some(a): the driver slows before and through the curves of its lane so
    /// that speed^2 * |curvature| stays near a (m/s^2), braking at half its
    /// comfortable deceleration; None: it drives curves at its desired speed
    /// (lanes whose curves are gentle at every speed it reaches).
    pub curve_lateral_accel_mps2: Option<f64>,
}

impl DriverParams {
    /// Typical passenger-car parameters.
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
            curve_lateral_accel_mps2: None,
        }
    }

    /// Typical truck parameters (slower, longer gaps).
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
            curve_lateral_accel_mps2: None,
        }
    }

    /// Typical cyclist parameters.
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
            curve_lateral_accel_mps2: None,
        }
    }

    /// Typical pedestrian parameters.
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
            curve_lateral_accel_mps2: None,
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
        let curve = self
            .curve_lateral_accel_mps2
            .map(|a| ("driver.curve_lateral_accel_mps2", a));
        for (field, value) in fields.into_iter().chain(curve) {
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
    /// Index of the lane in `TrafficSpec::lanes`.
    pub lane: usize,
    /// Arc length of the line on the lane, m.
    pub s_m: f64,
    /// Half-open red intervals [start, end) in seconds.
    pub red_intervals_s: Vec<(f64, f64)>,
}

impl StopLine {
    pub(super) fn is_red(&self, t_s: f64) -> bool {
        self.red_intervals_s
            .iter()
            .any(|&(a, b)| t_s >= a && t_s < b)
    }
}

/// The head of a stop-and-go jam across one lane: an invisible leader that
/// cruises at `peak_speed_mps`, brakes at `accel_mps2` to a stand, stands
/// `stopped_s`, pulls away at `accel_mps2`, and repeats every `period_s`;
/// at t = 0 it is `phase_s` into its cycle (which begins with the cruise)
/// and at `start_s_m` on its lane. The traffic behind it queues and moves
/// off in waves, as behind the head of a real jam; what is ahead of it
/// drives on.
#[derive(Debug, Clone, PartialEq)]
pub struct JamFront {
    /// Index of the lane in `TrafficSpec::lanes`.
    pub lane: usize,
    /// Arc length of the front on its lane at t = 0, m.
    pub start_s_m: f64,
    /// Length of one cycle, s.
    pub period_s: f64,
    /// Standing part of each cycle, s.
    pub stopped_s: f64,
    /// Speed between the stands, m/s.
    pub peak_speed_mps: f64,
    /// Braking and pulling-away rate, m/s².
    pub accel_mps2: f64,
    /// Time into the cycle at t = 0, s.
    pub phase_s: f64,
}

impl JamFront {
    /// Time to brake from the peak speed to a stand (or pull away), s.
    fn ramp_s(&self) -> f64 {
        self.peak_speed_mps / self.accel_mps2
    }

    /// Cruising part of each cycle, s (negative = the cycle is too short).
    pub fn cruise_s(&self) -> f64 {
        self.period_s - self.stopped_s - 2.0 * self.ramp_s()
    }

    /// Distance from the cycle's start and speed, `tau_s` into a cycle.
    fn in_cycle(&self, tau_s: f64) -> (f64, f64) {
        let (v, a) = (self.peak_speed_mps, self.accel_mps2);
        let (cruise, ramp) = (self.cruise_s(), self.ramp_s());
        let braked = v * cruise + 0.5 * v * ramp;
        if tau_s < cruise {
            (v * tau_s, v)
        } else if tau_s < cruise + ramp {
            let t = tau_s - cruise;
            (v * cruise + v * t - 0.5 * a * t * t, v - a * t)
        } else if tau_s < cruise + ramp + self.stopped_s {
            (braked, 0.0)
        } else {
            let t = (tau_s - cruise - ramp - self.stopped_s).min(ramp);
            (braked + 0.5 * a * t * t, a * t)
        }
    }

    /// Distance covered in one cycle, m.
    fn cycle_m(&self) -> f64 {
        self.peak_speed_mps * (self.cruise_s() + self.ramp_s())
    }

    /// Distance from the start of cycle 0 and speed at cycle time `u_s`.
    fn travelled(&self, u_s: f64) -> (f64, f64) {
        let cycles = (u_s / self.period_s).floor();
        let (d, v) = self.in_cycle(u_s - cycles * self.period_s);
        (cycles * self.cycle_m() + d, v)
    }

    /// Arc length on its lane (m) and speed (m/s) at time `t_s`.
    pub fn state_at(&self, t_s: f64) -> (f64, f64) {
        let (d0, _) = self.travelled(self.phase_s);
        let (d, v) = self.travelled(self.phase_s + t_s);
        (self.start_s_m + d - d0, v)
    }
}

/// The input of the traffic simulation: lanes, vehicles on them, stop lines.
#[derive(Debug, Clone, PartialEq)]
pub struct TrafficSpec {
    /// Lane paths, world frame.
    pub lanes: Vec<LanePath>,
    /// Road users, simulated in this order.
    pub vehicles: Vec<VehicleSpec>,
    /// Stop lines with their red phases.
    pub stop_lines: Vec<StopLine>,
    /// Heads of stop-and-go jams.
    pub jam_fronts: Vec<JamFront>,
    /// Simulated time span [0, duration_s], s (at most one hour).
    pub duration_s: f64,
}

/// Planar motion of one vehicle's box centre, sampled every `dt_s` (0.01 s).
#[derive(Debug, Clone, PartialEq)]
pub struct PlanarTrack {
    /// Vehicle id, as in the spec.
    pub id: u32,
    /// Time of the first sample, s.
    pub t0_s: f64,
    /// Sample spacing, s.
    pub dt_s: f64,
    /// Samples at `t0_s + k dt_s`.
    pub samples: Vec<PlanarSample>,
}

/// State of the box centre at one sample, with exact time derivatives of the
/// vehicle model at that instant (used as Hermite knot data).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarSample {
    /// Box centre, world frame.
    pub x: f64,
    /// Box centre y, world frame, m.
    pub y: f64,
    /// Heading, unwrapped (continuous over the track).
    pub yaw: f64,
    /// Rear-axle speed along the heading (the model's speed state), >= 0.
    pub speed_mps: f64,
    /// d speed / dt.
    pub accel_mps2: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_radps: f64,
    /// Yaw acceleration, rad/s².
    pub yaw_accel_radps2: f64,
    /// Box-centre velocity and acceleration, world frame.
    pub vx_mps: f64,
    /// Box-centre velocity y, m/s.
    pub vy_mps: f64,
    /// Box-centre acceleration x, m/s².
    pub ax_mps2: f64,
    /// Box-centre acceleration y, m/s².
    pub ay_mps2: f64,
    /// Reference lane at this instant (the target lane during a lane change).
    pub lane: usize,
}

impl PlanarSample {
    /// A body standing at `(x, y)` with heading `yaw_rad` on lane 0.
    pub fn at_rest(x: f64, y: f64, yaw_rad: f64) -> PlanarSample {
        PlanarSample {
            x,
            y,
            yaw: yaw_rad,
            speed_mps: 0.0,
            accel_mps2: 0.0,
            yaw_rate_radps: 0.0,
            yaw_accel_radps2: 0.0,
            vx_mps: 0.0,
            vy_mps: 0.0,
            ax_mps2: 0.0,
            ay_mps2: 0.0,
            lane: 0,
        }
    }
}

/// Why a traffic spec was rejected or its simulation failed.
#[derive(Debug, thiserror::Error)]
pub enum TrafficError {
    #[error("invalid lane path: {reason}")]
    /// A lane path cannot be built.
    InvalidPath {
        /// What is wrong with it.
        reason: String,
    },
    #[error("traffic spec: {field}: {reason}")]
    /// A spec-wide field is invalid.
    InvalidSpec {
        /// The field.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    #[error("vehicle id {id}: {field}: {reason}")]
    /// A vehicle's field is invalid.
    InvalidVehicle {
        /// The vehicle's id.
        id: u32,
        /// The field, e.g. `driver.min_gap_m`.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    #[error("stop line {index}: {field}: {reason}")]
    /// A stop line's field is invalid.
    InvalidStopLine {
        /// Index of the stop line in the spec.
        index: usize,
        /// The field.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    #[error(
        "vehicle id {follower} starts {gap_m:.2} m behind vehicle id {leader} on lane {lane}; at least {required_m:.2} m needed"
    )]
    /// A vehicle starts closer behind another body than it can handle.
    StartTooClose {
        /// Id of the following vehicle.
        follower: u32,
        /// Id of the vehicle ahead.
        leader: u32,
        /// Lane of the follower.
        lane: usize,
        /// Bumper-to-bumper gap at t = 0, m.
        gap_m: f64,
        /// Smallest gap the follower can handle, m.
        required_m: f64,
    },
    #[error("vehicle id {id}: state became non-finite at t = {t_s} s")]
    /// A vehicle's state became NaN or infinite.
    Diverged {
        /// The vehicle's id.
        id: u32,
        /// Time of the failure, s.
        t_s: f64,
    },
}

fn vehicle_error(id: u32, field: &str, reason: String) -> TrafficError {
    TrafficError::InvalidVehicle {
        id,
        field: field.to_string(),
        reason,
    }
}

pub(super) fn validate(spec: &TrafficSpec) -> Result<(), TrafficError> {
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
    for (index, front) in spec.jam_fronts.iter().enumerate() {
        let err = |field: &str, reason: String| TrafficError::InvalidSpec {
            field: format!("jam_fronts[{index}].{field}"),
            reason,
        };
        if front.lane >= n_lanes {
            return Err(err(
                "lane",
                format!("{} out of range ({n_lanes} lanes)", front.lane),
            ));
        }
        for (field, value) in [
            ("period_s", front.period_s),
            ("stopped_s", front.stopped_s),
            ("peak_speed_mps", front.peak_speed_mps),
            ("accel_mps2", front.accel_mps2),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(err(field, format!("{value} must be positive and finite")));
            }
        }
        for (field, value) in [("start_s_m", front.start_s_m), ("phase_s", front.phase_s)] {
            if !value.is_finite() {
                return Err(err(field, format!("{value} must be finite")));
            }
        }
        if front.cruise_s() < 0.0 {
            return Err(err(
                "period_s",
                format!(
                    "{} s leaves no time to cruise after standing {} s and braking and pulling away at {} m/s^2 to and from {} m/s",
                    front.period_s, front.stopped_s, front.accel_mps2, front.peak_speed_mps
                ),
            ));
        }
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
