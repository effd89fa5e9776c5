//! Multi-object tracking (LIMOT "Multi-object Tracking", after DL-SLOT):
//! cubic trajectory fit over a sliding window ([`TrajectoryFit`]),
//! score matrix + min-cost-flow association ([`AssociationMetric`],
//! [`associate_by_class`]), track lifecycle and static/dynamic state
//! ([`Track`], [`Lifecycle`], [`Motion`]), and the per-frame driver
//! ([`Tracker`], configured by [`TrackerConfig`]). Everything is in the world
//! frame; the caller transforms LiDAR-frame detections with the ego pose.
//!
//! Lifecycle: a track is [`Lifecycle::Tentative`] until `init_frames`
//! consecutive matched frames, then [`Lifecycle::Confirmed`]; it survives
//! `max_misses` misses on its prediction. Motion: the horizontal speed of a
//! line fit over the last `motion_window_frames` boxes; static -> dynamic
//! when it is significantly above `v_thres_mps`, dynamic -> static below
//! `v_thres_mps - v_hysteresis_mps`.

mod association;
mod box_overlap;
mod track;
mod tracker;
mod trajectory_fit;

pub use association::{
    AssociationMetric, associate_by_class, matching_matrix, matching_score, max_score_assignment,
};
pub use box_overlap::{giou_3d, iou_3d};
pub use track::{Extrapolation, HeadingRule, Lifecycle, Motion, TimedBox, Track};
pub use tracker::{TrackOutput, Tracker, TrackerError, WorldDetection};
pub use trajectory_fit::{
    FitError, FitPrediction, FitPrior, FitSample, MAX_DEGREE, TrajectoryFit, degree_for_samples,
};

/// Tracker parameters. Defaults are the paper's where it gives them
/// (window 5, alpha 100, v_thres 1 m/s, initialised after 5 frames, cubic);
/// the static/dynamic decision adds noise-aware hysteresis (see the module
/// documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerConfig {
    /// Measured boxes in the sliding window used by the trajectory fit.
    pub window_frames: usize,
    /// Highest polynomial degree of the fit (3 = the paper's cubic).
    pub max_poly_degree: usize,
    /// Zero-mean prior sigma of an object's acceleration in the trajectory fit
    /// (`f64::INFINITY` = the paper's plain least-squares cubic; see
    /// [`TrajectoryFit::fit_with_prior`] for why the default regularises).
    pub accel_sigma_mps2: f64,
    /// Prior sigma of the jerk (third derivative).
    pub jerk_sigma_mps3: f64,
    /// Prior sigma of the yaw acceleration.
    pub yaw_accel_sigma_radps2: f64,
    /// Prior sigma of the yaw jerk.
    pub yaw_jerk_sigma_radps3: f64,
    /// `alpha` of the score `psi = 1 - d/alpha` (metres).
    pub alpha_m: f64,
    /// Association gate: pairs farther apart than this score 0 (metres).
    pub d_thres_m: f64,
    /// Consecutive matched frames before a track is confirmed.
    pub init_frames: usize,
    /// Consecutive misses a track survives (coasting on its prediction);
    /// one more deletes it.
    pub max_misses: usize,
    /// Horizontal window-average speed above which an object is dynamic.
    pub v_thres_mps: f64,
    /// A dynamic object turns static again only below
    /// `v_thres_mps - v_hysteresis_mps`.
    pub v_hysteresis_mps: f64,
    /// Measured boxes over which the average speed is computed. The paper
    /// uses its sliding window (5); 10 (1 s at 10 Hz) cuts the speed noise
    /// of a parked car by 2.9x (the slope noise of a line fit falls as
    /// `1/sqrt(Σ (t_i − t̄)²)`).
    pub motion_window_frames: usize,
    /// Per-axis standard deviation of detected box centres (metres): weighs
    /// the fit's priors and judges whether a speed is significantly above
    /// `v_thres_mps`.
    pub detection_sigma_m: f64,
    /// Standard deviation of detected yaw (radians), for the fit's priors.
    pub detection_yaw_sigma_rad: f64,
    /// How many standard deviations of the speed estimate it must exceed
    /// `v_thres_mps` by to turn a static object dynamic (0 = paper's rule).
    pub dynamic_confidence_sigmas: f64,
    /// Detections with a lower score are ignored.
    pub min_score: f64,
    /// Unmatched detections with a lower score start no track: weak
    /// detections may continue tracks but not begin them (at or below
    /// `min_score` = every usable detection starts a track).
    pub birth_min_score: f64,
    /// Confirm after `init_frames` matched frames in all, not necessarily
    /// consecutive (AB3DMOT's rule); `false` = the paper's consecutive rule.
    pub confirm_on_total_hits: bool,
    /// What association scores a track–detection pair on (the paper's
    /// centre distance, or AB3DMOT's 3D GIoU).
    pub association: AssociationMetric,
    /// How a track is predicted after its last measured box.
    pub extrapolation: Extrapolation,
    /// A confirmed track lost after `max_misses` misses is kept this many
    /// more frames, out of the output, for re-association: a detection left
    /// over by the live tracks that matches it revives it with its id
    /// instead of starting a tentative track (0 = deleted at once).
    pub revive_frames: usize,
    /// Which of a box's two headings a track keeps.
    pub heading_rule: HeadingRule,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        TrackerConfig {
            window_frames: 5,
            max_poly_degree: 3,
            accel_sigma_mps2: 4.0,
            jerk_sigma_mps3: 10.0,
            yaw_accel_sigma_radps2: 2.0,
            yaw_jerk_sigma_radps3: 10.0,
            alpha_m: 100.0,
            d_thres_m: 2.0,
            init_frames: 5,
            max_misses: 3,
            v_thres_mps: 1.0,
            v_hysteresis_mps: 0.3,
            motion_window_frames: 10,
            detection_sigma_m: 0.15,
            detection_yaw_sigma_rad: 0.03,
            dynamic_confidence_sigmas: 2.0,
            min_score: 0.0,
            birth_min_score: 0.0,
            confirm_on_total_hits: false,
            association: AssociationMetric::CentreDistance,
            extrapolation: Extrapolation::Fit,
            revive_frames: 0,
            heading_rule: HeadingRule::FirstDetection,
        }
    }
}

/// A configuration value out of its valid range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("tracker config: field `{field}` = {value} is invalid ({why})")]
pub struct TrackerConfigError {
    /// Name of the field (`association.min_giou` for the GIoU threshold).
    pub field: &'static str,
    /// Its value (counts as `f64`).
    pub value: f64,
    /// What the field must satisfy.
    pub why: &'static str,
}

impl TrackerConfig {
    /// Checks every field's range.
    ///
    /// # Errors
    /// [`TrackerConfigError`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), TrackerConfigError> {
        let check = |ok: bool, field, value: f64, why| {
            if ok {
                Ok(())
            } else {
                Err(TrackerConfigError { field, value, why })
            }
        };
        check(
            self.window_frames >= 1,
            "window_frames",
            self.window_frames as f64,
            "must be at least 1",
        )?;
        check(
            self.max_poly_degree <= trajectory_fit::MAX_DEGREE,
            "max_poly_degree",
            self.max_poly_degree as f64,
            "must be at most 3",
        )?;
        check(
            self.alpha_m.is_finite() && self.alpha_m > 0.0,
            "alpha_m",
            self.alpha_m,
            "must be finite and positive",
        )?;
        check(
            self.d_thres_m.is_finite() && self.d_thres_m > 0.0 && self.d_thres_m <= self.alpha_m,
            "d_thres_m",
            self.d_thres_m,
            "must be finite, positive and at most alpha_m (scores stay positive)",
        )?;
        check(
            self.init_frames >= 1,
            "init_frames",
            self.init_frames as f64,
            "must be at least 1",
        )?;
        check(
            self.v_thres_mps.is_finite() && self.v_thres_mps >= 0.0,
            "v_thres_mps",
            self.v_thres_mps,
            "must be finite and non-negative",
        )?;
        check(
            self.v_hysteresis_mps.is_finite()
                && (0.0..=self.v_thres_mps).contains(&self.v_hysteresis_mps),
            "v_hysteresis_mps",
            self.v_hysteresis_mps,
            "must be within [0, v_thres_mps]",
        )?;
        check(
            self.motion_window_frames >= 2,
            "motion_window_frames",
            self.motion_window_frames as f64,
            "must be at least 2",
        )?;
        check(
            self.detection_sigma_m.is_finite() && self.detection_sigma_m > 0.0,
            "detection_sigma_m",
            self.detection_sigma_m,
            "must be finite and positive",
        )?;
        check(
            self.detection_yaw_sigma_rad.is_finite() && self.detection_yaw_sigma_rad > 0.0,
            "detection_yaw_sigma_rad",
            self.detection_yaw_sigma_rad,
            "must be finite and positive",
        )?;
        for (field, value) in [
            ("accel_sigma_mps2", self.accel_sigma_mps2),
            ("jerk_sigma_mps3", self.jerk_sigma_mps3),
            ("yaw_accel_sigma_radps2", self.yaw_accel_sigma_radps2),
            ("yaw_jerk_sigma_radps3", self.yaw_jerk_sigma_radps3),
        ] {
            check(
                value > 0.0,
                field,
                value,
                "must be positive (infinity disables the prior)",
            )?;
        }
        check(
            self.dynamic_confidence_sigmas.is_finite() && self.dynamic_confidence_sigmas >= 0.0,
            "dynamic_confidence_sigmas",
            self.dynamic_confidence_sigmas,
            "must be finite and non-negative",
        )?;
        check(
            self.min_score.is_finite(),
            "min_score",
            self.min_score,
            "must be finite",
        )?;
        check(
            self.birth_min_score.is_finite(),
            "birth_min_score",
            self.birth_min_score,
            "must be finite",
        )?;
        if let AssociationMetric::Giou3d { min_giou, .. } = self.association {
            check(
                (-1.0..1.0).contains(&min_giou),
                "association.min_giou",
                min_giou,
                "must be within [-1, 1)",
            )?;
        }
        Ok(())
    }

    /// The trajectory fit's priors.
    pub fn fit_prior(&self) -> trajectory_fit::FitPrior {
        trajectory_fit::FitPrior {
            position_sigma_m: self.detection_sigma_m,
            yaw_sigma_rad: self.detection_yaw_sigma_rad,
            accel_sigma_mps2: self.accel_sigma_mps2,
            jerk_sigma_mps3: self.jerk_sigma_mps3,
            yaw_accel_sigma_radps2: self.yaw_accel_sigma_radps2,
            yaw_jerk_sigma_radps3: self.yaw_jerk_sigma_radps3,
        }
    }

    /// Measured boxes a track keeps: enough for the fit and the speed.
    pub fn history_len(&self) -> usize {
        self.window_frames.max(self.motion_window_frames)
    }
}
