//! One tracked object: stable id, class, world-frame box history in a sliding
//! window, the trajectory fit over it, lifecycle and static/dynamic state.
//!
//! Lifecycle (paper: "initialized" after 5 consecutive frames):
//! * `Tentative` until `init_frames` consecutive matched frames (in all, with
//!   `confirm_on_total_hits`), then `Confirmed` for good.
//! * Any track survives up to `max_misses` consecutive misses; meanwhile its
//!   box is the trajectory prediction (output with `predicted = true`, never
//!   fed back into the fit). A miss resets the consecutive-hit count, so a
//!   tentative track needs `init_frames` uninterrupted hits again — but keeps
//!   its id. One more miss deletes the track (the tracker drops it).
//!
//! Motion state: the average velocity over the window is the slope of a
//! least-squares line through the measured centres of the last
//! `motion_window_frames` boxes (the minimum-variance estimate of a constant
//! velocity under independent box noise). Only its horizontal part counts:
//! vehicles move on the ground and the detector's z noise would otherwise add
//! speed to parked cars. The slope of a line through n boxes with per-axis
//! noise σ has standard deviation `σ_v = σ / sqrt(Σ (t_i − t̄)²)` per axis —
//! 0.47 m/s for the paper's 5 frames at 10 Hz and σ = 0.15 m, so the paper's
//! plain rule "speed > v_thres" calls a noisy parked car dynamic in ~10 % of
//! frames. Hence, with hysteresis:
//! * Static → Dynamic when `speed > v_thres_mps + dynamic_confidence_sigmas · σ_v`
//!   (the speed is significantly above the threshold; with 2 samples σ_v is
//!   large and only fast objects switch at once, slow ones after more frames);
//! * Dynamic → Static when `speed < v_thres_mps − v_hysteresis_mps`,
//!
//! so neither a noisy parked car nor a car crawling at about `v_thres`
//! flickers between the states. `dynamic_confidence_sigmas = 0`,
//! `v_hysteresis_mps = 0` and `motion_window_frames = 5` give the paper's rule.

use super::TrackerConfig;
use super::trajectory_fit::{FitError, FitPrediction, FitSample, TrajectoryFit};
use crate::input::ObjectClass;
use nalgebra::{Isometry3, Vector3};
use std::collections::VecDeque;

/// A track counts as having moved ([`Track::has_moved`]) once its box
/// stands this far from its first one (horizontally) while it is dynamic:
/// a car's length, far beyond a parked car's detection noise (~0.15 m).
pub const MOVED_DISTANCE_M: f64 = 4.0;

/// How a track is predicted after its last measured box.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Extrapolation {
    /// The trajectory fit itself (the paper's cubic, extrapolated).
    #[default]
    Fit,
    /// Constant velocity from the last measured time: the fitted centre
    /// there plus the fit's velocity there times the elapsed time, the
    /// fitted heading held (AB3DMOT's Kalman prediction). A polynomial
    /// extrapolated over a few missed frames diverges; a straight line
    /// does not.
    ConstantVelocity,
}

/// Which of the two headings of a box (`yaw` or `yaw + π`: detectors
/// confuse front and back) a track keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HeadingRule {
    /// The first detection's heading; later ones are folded onto the track.
    #[default]
    FirstDetection,
    /// A dynamic track faces its direction of travel; a static one keeps the
    /// heading most of its detections gave (later detections are still
    /// folded onto the track's heading, the whole history turns by π when
    /// the rule disagrees with it).
    MotionOrMajority,
}

/// Lifecycle state of a track.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Lifecycle {
    /// Seen, but not yet in `init_frames` consecutive frames.
    Tentative,
    /// Initialised (paper: tracked for 5 consecutive frames).
    Confirmed,
}

/// Whether the object moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Motion {
    /// Parked or standing (its speed is not significantly above `v_thres_mps`).
    Static,
    /// Moving.
    Dynamic,
}

/// One measured box of a track, world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimedBox {
    /// Measurement time (s).
    pub t_s: f64,
    /// Box centre, world frame (m).
    pub center_world: Vector3<f64>,
    /// Unwrapped so that consecutive boxes differ by less than π/2
    /// (heading flips of the detector are folded onto the track's heading).
    pub yaw_rad: f64,
    /// Length, width, height (m).
    pub size_lwh: Vector3<f64>,
}

/// A tracked object.
#[derive(Debug, Clone)]
pub struct Track {
    id: u64,
    class: ObjectClass,
    /// Measured boxes, oldest first, at most `max(window_frames,
    /// motion_window_frames)` of them.
    history: VecDeque<TimedBox>,
    fit: TrajectoryFit,
    lifecycle: Lifecycle,
    motion: Motion,
    /// Whether the track has ever been dynamic while its box stood more than
    /// [`MOVED_DISTANCE_M`] from where the track started.
    has_moved: bool,
    /// The first box's centre, world frame.
    first_center_world: Vector3<f64>,
    consecutive_hits: usize,
    consecutive_misses: usize,
    total_hits: usize,
    /// Running mean of the matched detections' sizes.
    size_mean_lwh: Vector3<f64>,
    /// Latest horizontal window-average speed.
    speed_mps: f64,
    extrapolation: Extrapolation,
    /// Matched detections whose raw heading agreed with the track's / was
    /// turned by π to fold onto it.
    heading_votes: (usize, usize),
}

impl Track {
    /// Starts a track from its first detection. `first.yaw_rad` is taken as is.
    ///
    /// # Errors
    /// [`FitError::NotFinite`] for a non-finite box (the tracker filters
    /// those out first); [`FitError`] for a `config` whose fit settings
    /// [`TrackerConfig::validate`] would reject.
    pub fn new(
        id: u64,
        class: ObjectClass,
        first: TimedBox,
        config: &TrackerConfig,
    ) -> Result<Self, FitError> {
        let fit = TrajectoryFit::fit_with_prior(
            &[fit_sample(&first)],
            config.max_poly_degree,
            &config.fit_prior(),
        )?;
        let mut track = Track {
            id,
            class,
            history: VecDeque::from([first]),
            fit,
            lifecycle: Lifecycle::Tentative,
            motion: Motion::Static,
            has_moved: false,
            first_center_world: first.center_world,
            consecutive_hits: 1,
            consecutive_misses: 0,
            total_hits: 1,
            size_mean_lwh: first.size_lwh,
            speed_mps: 0.0,
            extrapolation: config.extrapolation,
            heading_votes: (1, 0),
        };
        track.update_lifecycle(config);
        Ok(track)
    }

    /// Stable id, unique within one tracker.
    pub fn id(&self) -> u64 {
        self.id
    }

    /// Class of the first detection (tracks only match their own class).
    pub fn class(&self) -> ObjectClass {
        self.class
    }

    /// Tentative or confirmed.
    pub fn lifecycle(&self) -> Lifecycle {
        self.lifecycle
    }

    /// Static or dynamic, with the hysteresis of the module documentation.
    pub fn motion(&self) -> Motion {
        self.motion
    }

    /// Whether the track has ever been dynamic with its box more than
    /// `MOVED_DISTANCE_M` from where it started: a car standing in a queue
    /// or at a red light after driving is one that moves again, while a
    /// parked car judged dynamic for a moment by its boxes' noise has not
    /// gone anywhere.
    pub fn has_moved(&self) -> bool {
        self.has_moved
    }

    /// Horizontal average speed over the motion window (m/s).
    pub fn speed_mps(&self) -> f64 {
        self.speed_mps
    }

    /// Matched frames in a row up to now (0 after a miss).
    pub fn consecutive_hits(&self) -> usize {
        self.consecutive_hits
    }

    /// Missed frames in a row up to now (0 after a hit).
    pub fn consecutive_misses(&self) -> usize {
        self.consecutive_misses
    }

    /// Matched frames in all, the first detection included.
    pub fn total_hits(&self) -> usize {
        self.total_hits
    }

    /// Running mean of the matched sizes (length, width, height).
    pub fn size_lwh(&self) -> Vector3<f64> {
        self.size_mean_lwh
    }

    /// Measured boxes kept for fitting, oldest first.
    pub fn history(&self) -> &VecDeque<TimedBox> {
        &self.history
    }

    /// The latest measured box.
    pub fn last_box(&self) -> &TimedBox {
        self.history
            .back()
            .expect("a track always holds its first box")
    }

    /// The track's state at `t_s`: the trajectory fit over the window
    /// (position, unwrapped yaw, velocity), extrapolated after the last
    /// measured box as `extrapolation` says.
    pub fn predict(&self, t_s: f64) -> FitPrediction {
        let t_last_s = self.last_box().t_s;
        match self.extrapolation {
            Extrapolation::ConstantVelocity if t_s > t_last_s => {
                let last = self.fit.predict(t_last_s);
                FitPrediction {
                    center_world: last.center_world + last.velocity_world_mps * (t_s - t_last_s),
                    yaw_rate_radps: 0.0,
                    ..last
                }
            }
            _ => self.fit.predict(t_s),
        }
    }

    /// Degree of the current fit.
    pub fn fit_degree(&self) -> usize {
        self.fit.degree()
    }

    /// Folds a detected yaw onto the track's heading: picks the
    /// representative of `yaw_rad (mod π)` nearest to the predicted yaw at
    /// `t_s`. Detectors confuse front and back; a real turn of more than
    /// π/2 between two frames is not physical for a vehicle.
    pub fn unwrap_yaw(&self, t_s: f64, yaw_rad: f64) -> f64 {
        let reference = self.predict(t_s).yaw_rad;
        let pi = std::f64::consts::PI;
        let diff = (yaw_rad - reference).rem_euclid(pi);
        // diff in [0, π): nearest representative is diff or diff − π.
        if diff > 0.5 * pi {
            reference + diff - pi
        } else {
            reference + diff
        }
    }

    /// Counts one matched detection's heading vote: `raw_yaw_rad` as
    /// detected, `folded_yaw_rad` what [`Self::unwrap_yaw`] made of it.
    pub fn vote_heading(&mut self, raw_yaw_rad: f64, folded_yaw_rad: f64) {
        let turned = (folded_yaw_rad - raw_yaw_rad).rem_euclid(2.0 * std::f64::consts::PI);
        if (turned - std::f64::consts::PI).abs() < 0.5 * std::f64::consts::PI {
            self.heading_votes.1 += 1;
        } else {
            self.heading_votes.0 += 1;
        }
    }

    /// Adds a matched detection (yaw already unwrapped with [`Self::unwrap_yaw`],
    /// time after the last box).
    ///
    /// # Errors
    /// [`FitError`] when the refit fails (a non-finite box, or fit settings
    /// that [`TrackerConfig::validate`] rejects); the box is then in the
    /// history but the fit is the previous one.
    pub fn record_hit(
        &mut self,
        measured: TimedBox,
        config: &TrackerConfig,
    ) -> Result<(), FitError> {
        self.history.push_back(measured);
        while self.history.len() > config.history_len() {
            self.history.pop_front();
        }
        self.total_hits += 1;
        self.size_mean_lwh += (measured.size_lwh - self.size_mean_lwh) / self.total_hits as f64;
        self.consecutive_hits += 1;
        self.consecutive_misses = 0;
        self.refit(config)?;
        self.update_lifecycle(config);
        self.update_motion(config);
        if config.heading_rule == HeadingRule::MotionOrMajority && self.heading_is_backwards(config)
        {
            for b in &mut self.history {
                b.yaw_rad += std::f64::consts::PI;
            }
            self.heading_votes = (self.heading_votes.1, self.heading_votes.0);
            self.refit(config)?;
        }
        Ok(())
    }

    /// [`HeadingRule::MotionOrMajority`]: a dynamic track moving faster than
    /// `v_thres_mps` faces away from its velocity; otherwise more of its
    /// detections pointed the other way than this way.
    fn heading_is_backwards(&self, config: &TrackerConfig) -> bool {
        let last = self.fit.predict(self.last_box().t_s);
        let v = last.velocity_world_mps.xy();
        if self.motion == Motion::Dynamic && v.norm() > config.v_thres_mps {
            let heading = nalgebra::Vector2::new(last.yaw_rad.cos(), last.yaw_rad.sin());
            heading.dot(&v) < 0.0
        } else {
            self.heading_votes.1 > self.heading_votes.0
        }
    }

    /// Records a frame without a matching detection.
    pub fn record_miss(&mut self) {
        self.consecutive_hits = 0;
        self.consecutive_misses += 1;
    }

    /// True once the track has missed more than `max_misses` frames in a row.
    pub fn is_lost(&self, config: &TrackerConfig) -> bool {
        self.consecutive_misses > config.max_misses
    }

    /// Re-expresses the track in another world frame: every kept box is
    /// moved by `t_new_old` (its heading rotated with it), then the fit and
    /// the motion state are recomputed from the moved boxes.
    ///
    /// # Errors
    /// [`FitError`] when the refit fails (a non-finite `t_new_old`, or fit
    /// settings that [`TrackerConfig::validate`] rejects); the boxes are
    /// moved but the fit is the previous one.
    pub fn transform_world(
        &mut self,
        t_new_old: &Isometry3<f64>,
        config: &TrackerConfig,
    ) -> Result<(), FitError> {
        for b in &mut self.history {
            b.center_world = t_new_old.transform_point(&b.center_world.into()).coords;
            b.yaw_rad = rotated_yaw(t_new_old, b.yaw_rad);
        }
        self.first_center_world = t_new_old
            .transform_point(&self.first_center_world.into())
            .coords;
        self.refit(config)?;
        self.update_motion(config);
        Ok(())
    }

    fn refit(&mut self, config: &TrackerConfig) -> Result<(), FitError> {
        let skip = self.history.len().saturating_sub(config.window_frames);
        let samples: Vec<FitSample> = self.history.iter().skip(skip).map(fit_sample).collect();
        self.fit =
            TrajectoryFit::fit_with_prior(&samples, config.max_poly_degree, &config.fit_prior())?;
        Ok(())
    }

    fn update_lifecycle(&mut self, config: &TrackerConfig) {
        let hits = if config.confirm_on_total_hits {
            self.total_hits
        } else {
            self.consecutive_hits
        };
        if hits >= config.init_frames {
            self.lifecycle = Lifecycle::Confirmed;
        }
    }

    fn update_motion(&mut self, config: &TrackerConfig) {
        let skip = self
            .history
            .len()
            .saturating_sub(config.motion_window_frames);
        let samples: Vec<FitSample> = self.history.iter().skip(skip).map(fit_sample).collect();
        let n = samples.len();
        // Spread of the sample times: the slope's noise gain.
        let t_mean_s = samples.iter().map(|s| s.t_s).sum::<f64>() / n as f64;
        let t_spread_s2: f64 = samples.iter().map(|s| (s.t_s - t_mean_s).powi(2)).sum();
        if n < 2 || t_spread_s2 <= 0.0 {
            self.speed_mps = 0.0;
            return;
        }
        // Least-squares line slope, closed form: Σ(t−t̄)(p−p̄) / Σ(t−t̄)².
        let p_mean = samples.iter().map(|s| s.center_world).sum::<Vector3<f64>>() / n as f64;
        let slope_mps = samples
            .iter()
            .map(|s| (s.center_world - p_mean) * (s.t_s - t_mean_s))
            .sum::<Vector3<f64>>()
            / t_spread_s2;
        self.speed_mps = slope_mps.xy().norm();
        let slope_sigma_mps = config.detection_sigma_m / t_spread_s2.sqrt();
        let enter_dynamic_mps =
            config.v_thres_mps + config.dynamic_confidence_sigmas * slope_sigma_mps;
        self.motion = match self.motion {
            Motion::Static if self.speed_mps > enter_dynamic_mps => Motion::Dynamic,
            Motion::Dynamic if self.speed_mps < config.v_thres_mps - config.v_hysteresis_mps => {
                Motion::Static
            }
            unchanged => unchanged,
        };
        let latest = samples
            .last()
            .map_or(self.first_center_world, |b| b.center_world);
        let left_start = (latest - self.first_center_world).xy().norm() > MOVED_DISTANCE_M;
        self.has_moved |= self.motion == Motion::Dynamic && left_start;
    }
}

/// The heading `yaw_rad` (about the old frame's z) seen from the new frame:
/// the yaw of the rotated heading vector, unwrapped to within π of `yaw_rad`
/// so an unwrapped history stays unwrapped.
pub(crate) fn rotated_yaw(t_new_old: &Isometry3<f64>, yaw_rad: f64) -> f64 {
    let heading = t_new_old.rotation * Vector3::new(yaw_rad.cos(), yaw_rad.sin(), 0.0);
    yaw_rad + crate::geometry::wrap_angle_rad(heading.y.atan2(heading.x) - yaw_rad)
}

fn fit_sample(b: &TimedBox) -> FitSample {
    FitSample {
        t_s: b.t_s,
        center_world: b.center_world,
        yaw_rad: b.yaw_rad,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn accelerating_track(extrapolation: Extrapolation) -> Track {
        let config = TrackerConfig {
            extrapolation,
            ..TrackerConfig::default()
        };
        let at = |k: usize| {
            let t_s = 0.1 * k as f64;
            TimedBox {
                t_s,
                // 5 m/s, accelerating at 4 m/s², turning at 0.5 rad/s.
                center_world: Vector3::new(5.0 * t_s + 2.0 * t_s * t_s, 0.0, 0.8),
                yaw_rad: 0.5 * t_s,
                size_lwh: Vector3::new(4.5, 1.8, 1.5),
            }
        };
        let mut track = Track::new(0, ObjectClass::Car, at(0), &config).unwrap();
        for k in 1..5 {
            track.record_hit(at(k), &config).unwrap();
        }
        track
    }

    #[test]
    fn constant_velocity_extrapolates_the_fit_from_the_last_box() {
        let fit = accelerating_track(Extrapolation::Fit);
        let cv = accelerating_track(Extrapolation::ConstantVelocity);
        let t_last_s = 0.4;
        // Up to the last box both are the fit.
        for t_s in [0.0, 0.25, t_last_s] {
            assert_eq!(cv.predict(t_s), fit.predict(t_s));
        }
        // After it: a straight line with the fit's velocity, heading held.
        let last = fit.predict(t_last_s);
        for dt_s in [0.1, 0.3] {
            let p = cv.predict(t_last_s + dt_s);
            let expected = last.center_world + last.velocity_world_mps * dt_s;
            assert!((p.center_world - expected).norm() < 1e-12);
            assert_eq!(p.yaw_rad, last.yaw_rad);
            assert_eq!(p.velocity_world_mps, last.velocity_world_mps);
        }
        // The (regularised) cubic keeps part of the curvature: 0.3 s on,
        // the two differ (the full acceleration term would be ½·4·0.3² =
        // 0.18 m; the acceleration prior shrinks it).
        let gap = (fit.predict(0.7).center_world - cv.predict(0.7).center_world).norm();
        assert!(gap > 0.02, "{gap}");
    }

    /// A parked car whose boxes jump by a metre for a few frames (a swap
    /// with a passing car, a bad detection) turns dynamic for a moment but
    /// has not moved; a car that drives 12 m and stops has.
    #[test]
    fn a_track_has_moved_only_after_leaving_its_start() {
        let config = TrackerConfig::default();
        let run = |x_of: &dyn Fn(usize) -> f64| {
            let at = |k: usize| TimedBox {
                t_s: 0.1 * k as f64,
                center_world: Vector3::new(x_of(k), 0.0, 0.8),
                yaw_rad: 0.0,
                size_lwh: Vector3::new(4.5, 1.8, 1.5),
            };
            let mut track = Track::new(0, ObjectClass::Car, at(0), &config).unwrap();
            let mut was_dynamic = false;
            for k in 1..40 {
                track.record_hit(at(k), &config).unwrap();
                was_dynamic |= track.motion() == Motion::Dynamic;
            }
            (was_dynamic, track)
        };
        let (jumped, parked) = run(&|k| {
            if (10..14).contains(&k) {
                1.5 * (k - 9) as f64 / 4.0
            } else {
                0.0
            }
        });
        assert!(jumped, "the jump should make it dynamic for a moment");
        assert!(!parked.has_moved());
        let (drove, stopped) = run(&|k| 1.2 * k.min(10) as f64);
        assert!(drove && stopped.motion() == Motion::Static);
        assert!(stopped.has_moved());
    }
}
