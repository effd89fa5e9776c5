//! IMU preintegration on the manifold (Forster et al. 2016, "On-Manifold
//! Preintegration for Real-Time Visual-Inertial Odometry"), and plain
//! world-frame propagation of a start state for de-skewing.
//!
//! # Conventions
//! * Measurements are in the IMU body frame: specific force `ã` (m/s²) and
//!   angular rate `ω̃` (rad/s); measured = true + bias + noise.
//! * The preintegrated deltas between frames `i` and `j` are
//!   `ΔR = Π Exp((ω̃ₖ − b̂g)·dt)`, `Δv = Σ Rₖ(ãₖ − b̂a)·dt`,
//!   `Δp = Σ Δvₖ·dt + ½Rₖ(ãₖ − b̂a)·dt²` (Forster eq. 24–26, discrete),
//!   with one deliberate change: `Rₖ = ΔRₖ·Exp((ω̃ₖ − b̂g)·dt/2)` is the
//!   mid-step rotation instead of `ΔRₖ`. Forster's start-of-step rotation is
//!   a first-order scheme; the mid-step one is second order.
//!   The covariance and bias Jacobians are derived for this scheme.
//! * The 9×9 covariance is ordered **`(δφ, δv, δp)`**, the noise of the
//!   measured deltas as `ΔR = ΔR_true·Exp(δφ)`, `Δv = Δv_true + δv`,
//!   `Δp = Δp_true + δp` (eq. 42).
//!   The same order is used by the residual of
//!   [`ImuFactor`](crate::graph::ImuFactor).
//! * Noise: continuous white-noise densities (Kalibr) become the discrete
//!   per-step covariance `σ²/dt` (eq. 42 and appendix).
//! * [`Preintegration::from_samples`] treats the measurements as piecewise
//!   linear in time, interpolates them at the interval ends, and integrates
//!   every sub-interval with the midpoint value (the mean of its ends), so
//!   the result does not depend on where the interval ends fall between
//!   samples.

use crate::imu::{ImuBias, ImuNoise};
use crate::input::ImuSample;
use crate::lie;
use nalgebra::{Isometry3, Matrix3, Rotation3, SMatrix, Translation3, UnitQuaternion, Vector3};

/// 9×9 matrix, e.g. the preintegration covariance ordered `(δφ, δv, δp)`.
pub type Matrix9 = SMatrix<f64, 9, 9>;

/// Variance density (m²/s) added to the position block of the covariance
/// every step: models the discretisation error of the integration and keeps
/// the covariance invertible when only one step was integrated (then δv and
/// δp are driven by the same noise). Negligible against the accelerometer
/// noise (GTSAM's `integrationCovariance`, same default magnitude).
pub(crate) const INTEGRATION_VARIANCE_M2_PER_S: f64 = 1e-8;

/// Timestamps closer than this (s) count as equal when checking that the
/// samples cover an interval; absorbs rounding of `t_s + k·dt` sums.
pub const COVERAGE_TOLERANCE_S: f64 = 1e-9;

/// Why preintegration or propagation over an interval could not be done.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
///
/// Times are seconds on the sensor clock.
pub enum PreintegrationError {
    /// An interval end is not finite, or the end is not after the start.
    #[error(
        "invalid IMU interval [{t_start_s}, {t_end_s}] s: both ends must be finite and the end after the start"
    )]
    BadInterval {
        /// Requested start.
        t_start_s: f64,
        /// Requested end.
        t_end_s: f64,
    },
    /// The largest allowed gap between samples is not finite and positive.
    #[error("max_gap_s = {max_gap_s} must be finite and positive")]
    BadMaxGap {
        /// The value given.
        max_gap_s: f64,
    },
    /// The sample list is empty.
    #[error("no IMU samples to integrate over [{t_start_s}, {t_end_s}] s")]
    NoSamples {
        /// Requested start.
        t_start_s: f64,
        /// Requested end.
        t_end_s: f64,
    },
    /// The samples do not bracket the interval.
    #[error(
        "IMU samples span [{first_sample_s}, {last_sample_s}] s, which does not cover the interval [{t_start_s}, {t_end_s}] s"
    )]
    NotCovered {
        /// Requested start.
        t_start_s: f64,
        /// Requested end.
        t_end_s: f64,
        /// Time of the first sample.
        first_sample_s: f64,
        /// Time of the last sample.
        last_sample_s: f64,
    },
    /// Two consecutive samples taking part are farther apart than allowed.
    #[error(
        "gap of {gap_s} s between the IMU samples at t={before_s} s and t={after_s} s exceeds max_gap_s = {max_gap_s} s"
    )]
    Gap {
        /// Time of the sample before the gap.
        before_s: f64,
        /// Time of the sample after the gap.
        after_s: f64,
        /// `after_s − before_s`.
        gap_s: f64,
        /// The allowed gap.
        max_gap_s: f64,
    },
    /// A sample taking part has a non-finite time or measurement.
    #[error("IMU sample {index} (t={t_s} s): field `{field}` is not finite")]
    NonFinite {
        /// Index of the sample in the slice given.
        index: usize,
        /// Its time.
        t_s: f64,
        /// `"t_s"`, `"accel_mps2"` or `"gyro_radps"`.
        field: &'static str,
    },
    /// Sample times taking part do not strictly increase.
    #[error(
        "IMU sample {index} at t={t_s} s is not after the previous sample at t={previous_t_s} s"
    )]
    NotIncreasing {
        /// Index of the sample in the slice given.
        index: usize,
        /// Its time.
        t_s: f64,
        /// Time of the sample before it.
        previous_t_s: f64,
    },
    /// [`Preintegration::try_integrate`] got a bad step or measurement.
    #[error(
        "invalid integration step: dt_s = {dt_s} must be finite and positive, and the measurements finite"
    )]
    BadStep {
        /// The step given (s).
        dt_s: f64,
    },
    /// An [`ImuTrajectory`] was queried outside its interval.
    #[error("time {t_s} s is outside the propagated interval [{t_start_s}, {t_end_s}] s")]
    TimeOutside {
        /// The time asked for.
        t_s: f64,
        /// Start of the propagated interval.
        t_start_s: f64,
        /// End of the propagated interval.
        t_end_s: f64,
    },
}

// ---------------------------------------------------------------------------
// Piecewise-linear measurement signal over an interval
// ---------------------------------------------------------------------------

/// One breakpoint of the piecewise-linear measurement signal inside the
/// interval: the interval ends (interpolated) and every sample strictly
/// inside. Between two consecutive knots the signal is linear.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Knot {
    t_s: f64,
    accel_mps2: Vector3<f64>,
    gyro_radps: Vector3<f64>,
}

impl Knot {
    /// The signal at `t_s` on the linear piece from `self` to `next`.
    fn lerp(&self, next: &Knot, t_s: f64) -> Knot {
        let span = next.t_s - self.t_s;
        let f = if span > 0.0 {
            ((t_s - self.t_s) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        Knot {
            t_s,
            accel_mps2: self.accel_mps2 + (next.accel_mps2 - self.accel_mps2) * f,
            gyro_radps: self.gyro_radps + (next.gyro_radps - self.gyro_radps) * f,
        }
    }

    fn from_sample(s: &ImuSample) -> Knot {
        Knot {
            t_s: s.t_s,
            accel_mps2: s.accel_mps2,
            gyro_radps: s.gyro_radps,
        }
    }
}

fn check_interval(t_start_s: f64, t_end_s: f64) -> Result<(), PreintegrationError> {
    if !(t_start_s.is_finite() && t_end_s.is_finite() && t_end_s > t_start_s) {
        return Err(PreintegrationError::BadInterval { t_start_s, t_end_s });
    }
    Ok(())
}

fn check_sample(index: usize, s: &ImuSample) -> Result<(), PreintegrationError> {
    let t_s = s.t_s;
    let field = if !t_s.is_finite() {
        Some("t_s")
    } else if !s.accel_mps2.iter().all(|v| v.is_finite()) {
        Some("accel_mps2")
    } else if !s.gyro_radps.iter().all(|v| v.is_finite()) {
        Some("gyro_radps")
    } else {
        None
    };
    match field {
        Some(field) => Err(PreintegrationError::NonFinite { index, t_s, field }),
        None => Ok(()),
    }
}

/// The knots of `samples` over `[t_start_s, t_end_s]`, after checking the
/// samples that take part (finite, strictly increasing, no gap above
/// `max_gap_s`, covering the interval). `samples` must be sorted by time;
/// only the samples bracketing the interval are inspected.
fn interval_knots(
    samples: &[ImuSample],
    t_start_s: f64,
    t_end_s: f64,
    max_gap_s: f64,
) -> Result<Vec<Knot>, PreintegrationError> {
    check_interval(t_start_s, t_end_s)?;
    if !(max_gap_s.is_finite() && max_gap_s > 0.0) {
        return Err(PreintegrationError::BadMaxGap { max_gap_s });
    }
    let (first, last) = match (samples.first(), samples.last()) {
        (Some(f), Some(l)) => (f, l),
        _ => return Err(PreintegrationError::NoSamples { t_start_s, t_end_s }),
    };
    let not_covered = || PreintegrationError::NotCovered {
        t_start_s,
        t_end_s,
        first_sample_s: first.t_s,
        last_sample_s: last.t_s,
    };
    // lo: last sample at or before the start; hi: first sample at or after the end.
    let after_start = samples.partition_point(|s| s.t_s <= t_start_s + COVERAGE_TOLERANCE_S);
    if after_start == 0 {
        return Err(not_covered());
    }
    let lo = after_start - 1;
    let hi = samples.partition_point(|s| s.t_s < t_end_s - COVERAGE_TOLERANCE_S);
    if hi >= samples.len() {
        return Err(not_covered());
    }
    // An interval shorter than the tolerance may sit inside one sample.
    let hi = hi.max(lo);
    // Validate every sample that contributes (also catches unsorted input
    // inside the range, where the binary searches above assume order).
    for (index, s) in samples.iter().enumerate().take(hi + 1).skip(lo) {
        check_sample(index, s)?;
        if index > lo {
            let previous_t_s = samples[index - 1].t_s;
            if s.t_s <= previous_t_s {
                return Err(PreintegrationError::NotIncreasing {
                    index,
                    t_s: s.t_s,
                    previous_t_s,
                });
            }
            let gap_s = s.t_s - previous_t_s;
            if gap_s > max_gap_s {
                return Err(PreintegrationError::Gap {
                    before_s: previous_t_s,
                    after_s: s.t_s,
                    gap_s,
                    max_gap_s,
                });
            }
        }
    }
    if samples[lo].t_s > t_start_s + COVERAGE_TOLERANCE_S
        || samples[hi].t_s < t_end_s - COVERAGE_TOLERANCE_S
    {
        return Err(not_covered());
    }

    let mut knots = Vec::with_capacity(hi - lo + 2);
    let start_next = &samples[(lo + 1).min(hi)];
    knots.push(Knot::from_sample(&samples[lo]).lerp(&Knot::from_sample(start_next), t_start_s));
    for s in &samples[lo + 1..hi] {
        if s.t_s > t_start_s && s.t_s < t_end_s {
            knots.push(Knot::from_sample(s));
        }
    }
    let end_prev = &samples[hi.saturating_sub(1).max(lo)];
    knots.push(Knot::from_sample(end_prev).lerp(&Knot::from_sample(&samples[hi]), t_end_s));
    Ok(knots)
}

// ---------------------------------------------------------------------------
// Preintegration
// ---------------------------------------------------------------------------

/// Preintegrated IMU measurements between two frames, with their covariance
/// and first-order bias Jacobians (Forster et al. 2016).
///
/// Deltas are in the IMU body frame at the interval start and exclude
/// gravity; [`Preintegration::predict`] adds it. The covariance is ordered
/// `(δφ, δv, δp)`.
///
/// ```
/// use limot_estimator::imu::{ImuBias, ImuNoise, Preintegration};
/// use limot_estimator::input::ImuSample;
/// use nalgebra::{Isometry3, Vector3};
///
/// // 1 s at 100 Hz of a constant 1 m/s² specific force along x, no rotation.
/// let samples: Vec<ImuSample> = (0..=100)
///     .map(|k| ImuSample {
///         t_s: k as f64 * 0.01,
///         accel_mps2: Vector3::new(1.0, 0.0, 0.0),
///         gyro_radps: Vector3::zeros(),
///     })
///     .collect();
/// let pre = Preintegration::from_samples(
///     &samples, 0.0, 1.0, ImuBias::default(), ImuNoise::default(), 0.05,
/// )
/// .unwrap();
/// assert!((pre.delta_velocity() - Vector3::new(1.0, 0.0, 0.0)).norm() < 1e-12);
/// assert!((pre.delta_position() - Vector3::new(0.5, 0.0, 0.0)).norm() < 1e-12);
///
/// // From rest, with gravity set to zero here: 0.5 m and 1 m/s after 1 s.
/// let (pose, v) = pre.predict(
///     &Isometry3::identity(), &Vector3::zeros(), &ImuBias::default(), &Vector3::zeros(),
/// );
/// assert!((pose.translation.x - 0.5).abs() < 1e-12 && (v.x - 1.0).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Preintegration {
    bias_hat: ImuBias,
    noise: ImuNoise,
    delta_t_s: f64,
    /// `ΔR` kept as a quaternion: renormalising it is cheap and exact.
    delta_q: UnitQuaternion<f64>,
    delta_v: Vector3<f64>,
    delta_p: Vector3<f64>,
    /// Ordered `(δφ, δv, δp)`.
    covariance: Matrix9,
    d_r_d_bg: Matrix3<f64>,
    d_v_d_ba: Matrix3<f64>,
    d_v_d_bg: Matrix3<f64>,
    d_p_d_ba: Matrix3<f64>,
    d_p_d_bg: Matrix3<f64>,
}

impl Preintegration {
    /// Empty preintegration (identity deltas, zero covariance) linearised at
    /// the bias estimate `bias_hat`.
    pub fn new(bias_hat: ImuBias, noise: ImuNoise) -> Self {
        Preintegration {
            bias_hat,
            noise,
            delta_t_s: 0.0,
            delta_q: UnitQuaternion::identity(),
            delta_v: Vector3::zeros(),
            delta_p: Vector3::zeros(),
            covariance: Matrix9::zeros(),
            d_r_d_bg: Matrix3::zeros(),
            d_v_d_ba: Matrix3::zeros(),
            d_v_d_bg: Matrix3::zeros(),
            d_p_d_ba: Matrix3::zeros(),
            d_p_d_bg: Matrix3::zeros(),
        }
    }

    /// Integrates one step with the measurements held constant over `dt_s`
    /// (`bias_hat` is subtracted here). Updates the deltas, the covariance
    /// and the bias Jacobians (Forster eq. 24–26, 63 and appendix A, with the
    /// mid-step rotation described in the module documentation).
    ///
    /// The caller guarantees finite measurements and `dt_s > 0`; use
    /// [`Preintegration::try_integrate`] for unchecked data.
    pub fn integrate(&mut self, accel_mps2: &Vector3<f64>, gyro_radps: &Vector3<f64>, dt_s: f64) {
        debug_assert!(dt_s > 0.0, "integrate: dt_s must be positive");
        let a = accel_mps2 - self.bias_hat.accel_mps2;
        let w = gyro_radps - self.bias_hat.gyro_radps;
        let dt = dt_s;
        let dt2 = dt * dt;

        let dr = self.delta_q.to_rotation_matrix().into_inner();
        let phi = w * dt;
        let step_q = lie::so3_exp_quat(&phi);
        let step_rt = step_q.to_rotation_matrix().into_inner().transpose();
        let jr = lie::so3_right_jacobian(&phi);
        // Mid-step rotation R_mid = ΔR·Exp(ω·dt/2): rotating the specific force
        // with it (instead of the start-of-step ΔR of Forster's Euler scheme)
        // makes Δv and Δp second-order accurate; with ΔR it is first order.
        let half_q = lie::so3_exp_quat(&(phi * 0.5));
        let half_rt = half_q.to_rotation_matrix().into_inner().transpose();
        let jr_half = lie::so3_right_jacobian(&(phi * 0.5));
        let r_mid = dr * half_q.to_rotation_matrix().into_inner();
        let r_mid_a_skew = r_mid * lie::skew(&a);

        // Covariance: Σ ← A Σ Aᵀ + B_a Σ_a B_aᵀ + B_g Σ_g B_gᵀ, order (δφ, δv, δp).
        // δ(R_mid·a) = −R_mid[a]ₓ·(Exp(ω·dt/2)ᵀ·δφ + J_r(ω·dt/2)·dt/2·η_g) + R_mid·η_a.
        let d_force_d_phi = -r_mid_a_skew * half_rt;
        let d_force_d_gyro = -r_mid_a_skew * jr_half * (0.5 * dt);
        let mut a_mat = Matrix9::identity();
        a_mat.fixed_view_mut::<3, 3>(0, 0).copy_from(&step_rt);
        a_mat
            .fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(d_force_d_phi * dt));
        a_mat
            .fixed_view_mut::<3, 3>(6, 0)
            .copy_from(&(d_force_d_phi * (0.5 * dt2)));
        a_mat
            .fixed_view_mut::<3, 3>(6, 3)
            .copy_from(&(Matrix3::identity() * dt));
        let mut b_accel = SMatrix::<f64, 9, 3>::zeros();
        b_accel
            .fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(r_mid * dt));
        b_accel
            .fixed_view_mut::<3, 3>(6, 0)
            .copy_from(&(r_mid * (0.5 * dt2)));
        let mut b_gyro = SMatrix::<f64, 9, 3>::zeros();
        b_gyro.fixed_view_mut::<3, 3>(0, 0).copy_from(&(jr * dt));
        b_gyro
            .fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(d_force_d_gyro * dt));
        b_gyro
            .fixed_view_mut::<3, 3>(6, 0)
            .copy_from(&(d_force_d_gyro * (0.5 * dt2)));
        // Discrete white noise: σ_d² = density² / dt.
        let var_accel = self.noise.accel_noise_density.powi(2) / dt;
        let var_gyro = self.noise.gyro_noise_density.powi(2) / dt;
        let mut cov = a_mat * self.covariance * a_mat.transpose()
            + b_accel * b_accel.transpose() * var_accel
            + b_gyro * b_gyro.transpose() * var_gyro;
        for k in 6..9 {
            cov[(k, k)] += INTEGRATION_VARIANCE_M2_PER_S * dt;
        }
        self.covariance = (cov + cov.transpose()) * 0.5;

        // Bias Jacobians, each from the previous values (Forster appendix A,
        // with R_mid): R_mid(b̂g + ε) ≈ R_mid·Exp(D_mid·ε).
        let d_mid = half_rt * self.d_r_d_bg - jr_half * (0.5 * dt);
        self.d_p_d_ba += self.d_v_d_ba * dt - r_mid * (0.5 * dt2);
        self.d_p_d_bg += self.d_v_d_bg * dt - r_mid_a_skew * d_mid * (0.5 * dt2);
        self.d_v_d_ba -= r_mid * dt;
        self.d_v_d_bg -= r_mid_a_skew * d_mid * dt;
        self.d_r_d_bg = step_rt * self.d_r_d_bg - jr * dt;

        // Deltas: position first, it uses the previous velocity.
        let force = r_mid * a;
        self.delta_p += self.delta_v * dt + force * (0.5 * dt2);
        self.delta_v += force * dt;
        self.delta_q =
            UnitQuaternion::new_normalize(self.delta_q.into_inner() * step_q.into_inner());
        self.delta_t_s += dt;
    }

    /// [`Preintegration::integrate`] with the inputs checked first.
    ///
    /// # Errors
    /// [`PreintegrationError::BadStep`] when `dt_s` is not finite and
    /// positive or a measurement is not finite; nothing is integrated then.
    pub fn try_integrate(
        &mut self,
        accel_mps2: &Vector3<f64>,
        gyro_radps: &Vector3<f64>,
        dt_s: f64,
    ) -> Result<(), PreintegrationError> {
        let finite = accel_mps2
            .iter()
            .chain(gyro_radps.iter())
            .all(|v| v.is_finite());
        if !(finite && dt_s.is_finite() && dt_s > 0.0) {
            return Err(PreintegrationError::BadStep { dt_s });
        }
        self.integrate(accel_mps2, gyro_radps, dt_s);
        Ok(())
    }

    /// Preintegrates exactly over `[t_start_s, t_end_s]`, treating the
    /// measurements as piecewise linear in time: values at the interval ends
    /// are interpolated and each sub-interval between breakpoints is
    /// integrated with its midpoint value.
    ///
    /// `samples` must be sorted by time; they must bracket the interval
    /// (one sample at or before the start, one at or after the end, up to
    /// [`COVERAGE_TOLERANCE_S`]) with no gap above `max_gap_s`. Only the
    /// samples taking part are validated.
    ///
    /// # Errors
    /// [`PreintegrationError::BadInterval`], [`PreintegrationError::BadMaxGap`]
    /// for bad arguments; [`PreintegrationError::NoSamples`],
    /// [`PreintegrationError::NotCovered`], [`PreintegrationError::Gap`],
    /// [`PreintegrationError::NonFinite`] and
    /// [`PreintegrationError::NotIncreasing`] for samples that cannot
    /// describe the interval.
    pub fn from_samples(
        samples: &[ImuSample],
        t_start_s: f64,
        t_end_s: f64,
        bias_hat: ImuBias,
        noise: ImuNoise,
        max_gap_s: f64,
    ) -> Result<Preintegration, PreintegrationError> {
        let knots = interval_knots(samples, t_start_s, t_end_s, max_gap_s)?;
        let mut pre = Preintegration::new(bias_hat, noise);
        for pair in knots.windows(2) {
            let (k0, k1) = (&pair[0], &pair[1]);
            let dt = k1.t_s - k0.t_s;
            if dt > 0.0 {
                let accel = (k0.accel_mps2 + k1.accel_mps2) * 0.5;
                let gyro = (k0.gyro_radps + k1.gyro_radps) * 0.5;
                pre.integrate(&accel, &gyro, dt);
            }
        }
        Ok(pre)
    }

    /// Integrated time `t_j − t_i`, seconds.
    pub fn delta_t_s(&self) -> f64 {
        self.delta_t_s
    }

    /// `ΔR_ij` at `bias_hat`.
    pub fn delta_rotation(&self) -> Rotation3<f64> {
        self.delta_q.to_rotation_matrix()
    }

    /// `ΔR_ij` at `bias_hat`, as a unit quaternion.
    pub fn delta_quaternion(&self) -> UnitQuaternion<f64> {
        self.delta_q
    }

    /// `Δv_ij` at `bias_hat` (frame `i`, gravity not included), m/s.
    pub fn delta_velocity(&self) -> Vector3<f64> {
        self.delta_v
    }

    /// `Δp_ij` at `bias_hat` (frame `i`, gravity not included), m.
    pub fn delta_position(&self) -> Vector3<f64> {
        self.delta_p
    }

    /// Covariance of the preintegration noise, ordered `(δφ, δv, δp)`.
    pub fn covariance(&self) -> Matrix9 {
        self.covariance
    }

    /// The bias the deltas were integrated with.
    pub fn bias_hat(&self) -> &ImuBias {
        &self.bias_hat
    }

    /// The noise densities the covariance was propagated with.
    pub fn noise(&self) -> &ImuNoise {
        &self.noise
    }

    /// `∂ΔR/∂b_g` (as a right perturbation of `ΔR`).
    pub fn d_rotation_d_bias_gyro(&self) -> Matrix3<f64> {
        self.d_r_d_bg
    }

    /// `∂Δv/∂b_a`.
    pub fn d_velocity_d_bias_accel(&self) -> Matrix3<f64> {
        self.d_v_d_ba
    }

    /// `∂Δv/∂b_g`.
    pub fn d_velocity_d_bias_gyro(&self) -> Matrix3<f64> {
        self.d_v_d_bg
    }

    /// `∂Δp/∂b_a`.
    pub fn d_position_d_bias_accel(&self) -> Matrix3<f64> {
        self.d_p_d_ba
    }

    /// `∂Δp/∂b_g`.
    pub fn d_position_d_bias_gyro(&self) -> Matrix3<f64> {
        self.d_p_d_bg
    }

    /// Deltas corrected to first order for `bias` (Forster eq. 44):
    /// `(ΔR·Exp(∂ΔR/∂bg·δbg), Δv + ∂Δv/∂b·δb, Δp + ∂Δp/∂b·δb)`,
    /// `δb = bias − bias_hat`.
    pub fn corrected(&self, bias: &ImuBias) -> (Rotation3<f64>, Vector3<f64>, Vector3<f64>) {
        let (q, v, p) = self.corrected_quaternion(bias);
        (q.to_rotation_matrix(), v, p)
    }

    /// [`Preintegration::corrected`] with the rotation as a quaternion.
    pub fn corrected_quaternion(
        &self,
        bias: &ImuBias,
    ) -> (UnitQuaternion<f64>, Vector3<f64>, Vector3<f64>) {
        let dba = bias.accel_mps2 - self.bias_hat.accel_mps2;
        let dbg = bias.gyro_radps - self.bias_hat.gyro_radps;
        let q = self.delta_q * lie::so3_exp_quat(&(self.d_r_d_bg * dbg));
        let v = self.delta_v + self.d_v_d_ba * dba + self.d_v_d_bg * dbg;
        let p = self.delta_p + self.d_p_d_ba * dba + self.d_p_d_bg * dbg;
        (q, v, p)
    }

    /// State at `j` from the state at `i` (Forster eq. 44):
    /// `R_j = R_i·ΔR`, `v_j = v_i + g·Δt + R_i·Δv`,
    /// `p_j = p_i + v_i·Δt + ½g·Δt² + R_i·Δp`, with bias-corrected deltas.
    pub fn predict(
        &self,
        t_world_imu_i: &Isometry3<f64>,
        v_world_i: &Vector3<f64>,
        bias: &ImuBias,
        gravity_world: &Vector3<f64>,
    ) -> (Isometry3<f64>, Vector3<f64>) {
        let (dq, dv, dp) = self.corrected_quaternion(bias);
        let dt = self.delta_t_s;
        let q_i = t_world_imu_i.rotation;
        let p_i = t_world_imu_i.translation.vector;
        let q_j = UnitQuaternion::new_normalize((q_i * dq).into_inner());
        let v_j = v_world_i + gravity_world * dt + q_i * dv;
        let p_j = p_i + v_world_i * dt + gravity_world * (0.5 * dt * dt) + q_i * dp;
        (Isometry3::from_parts(Translation3::from(p_j), q_j), v_j)
    }
}

// ---------------------------------------------------------------------------
// Plain propagation (de-skew)
// ---------------------------------------------------------------------------

/// One world-frame integration step with the measurement held over `dt`
/// (bias already removed): the same discretisation as [`Preintegration`],
/// so propagating to the end equals [`Preintegration::predict`].
fn world_step(
    q: &UnitQuaternion<f64>,
    v: &Vector3<f64>,
    p: &Vector3<f64>,
    accel_body: &Vector3<f64>,
    gyro_body: &Vector3<f64>,
    gravity_world: &Vector3<f64>,
    dt: f64,
) -> (UnitQuaternion<f64>, Vector3<f64>, Vector3<f64>) {
    // Mid-step rotation, as in Preintegration::integrate.
    let a_world = q * lie::so3_exp_quat(&(gyro_body * (0.5 * dt))) * accel_body + gravity_world;
    let p_next = p + v * dt + a_world * (0.5 * dt * dt);
    let v_next = v + a_world * dt;
    let q_next = UnitQuaternion::new_normalize(
        q.into_inner() * lie::so3_exp_quat(&(gyro_body * dt)).into_inner(),
    );
    (q_next, v_next, p_next)
}

/// The IMU-propagated ego trajectory over one interval, from a known start
/// state: the pose `t_world_imu` at any time inside, for de-skewing a sweep.
/// Built once per interval (one step per IMU sample); each query then costs
/// one binary search and one partial step.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuTrajectory {
    knots: Vec<Knot>,
    /// `(rotation, velocity, position)` in the world frame at each knot.
    states: Vec<(UnitQuaternion<f64>, Vector3<f64>, Vector3<f64>)>,
    bias: ImuBias,
    gravity_world: Vector3<f64>,
}

impl ImuTrajectory {
    /// Propagates `(t_world_imu_start, v_world_start)` at `t_start_s` over
    /// `[t_start_s, t_end_s]` with the measurements (piecewise linear, as in
    /// [`Preintegration::from_samples`], same checks) minus `bias`.
    ///
    /// # Errors
    /// The same as [`Preintegration::from_samples`].
    #[allow(clippy::too_many_arguments)]
    pub fn propagate(
        samples: &[ImuSample],
        t_start_s: f64,
        t_end_s: f64,
        t_world_imu_start: &Isometry3<f64>,
        v_world_start: &Vector3<f64>,
        bias: &ImuBias,
        gravity_world: &Vector3<f64>,
        max_gap_s: f64,
    ) -> Result<ImuTrajectory, PreintegrationError> {
        let knots = interval_knots(samples, t_start_s, t_end_s, max_gap_s)?;
        let mut states = Vec::with_capacity(knots.len());
        let mut state = (
            t_world_imu_start.rotation,
            *v_world_start,
            t_world_imu_start.translation.vector,
        );
        states.push(state);
        for pair in knots.windows(2) {
            let (k0, k1) = (&pair[0], &pair[1]);
            let dt = k1.t_s - k0.t_s;
            if dt > 0.0 {
                let accel = (k0.accel_mps2 + k1.accel_mps2) * 0.5 - bias.accel_mps2;
                let gyro = (k0.gyro_radps + k1.gyro_radps) * 0.5 - bias.gyro_radps;
                state = world_step(
                    &state.0,
                    &state.1,
                    &state.2,
                    &accel,
                    &gyro,
                    gravity_world,
                    dt,
                );
            }
            states.push(state);
        }
        Ok(ImuTrajectory {
            knots,
            states,
            bias: *bias,
            gravity_world: *gravity_world,
        })
    }

    /// Start of the propagated interval (s).
    pub fn t_start_s(&self) -> f64 {
        self.knots[0].t_s
    }

    /// End of the propagated interval (s).
    pub fn t_end_s(&self) -> f64 {
        self.knots[self.knots.len() - 1].t_s
    }

    /// Pose `t_world_imu` and world velocity at `t_s` in the interval (up to
    /// [`COVERAGE_TOLERANCE_S`] outside it, clamped).
    ///
    /// # Errors
    /// [`PreintegrationError::TimeOutside`] beyond that tolerance.
    pub fn state_at(
        &self,
        t_s: f64,
    ) -> Result<(Isometry3<f64>, Vector3<f64>), PreintegrationError> {
        let (t_start_s, t_end_s) = (self.t_start_s(), self.t_end_s());
        if !(t_s >= t_start_s - COVERAGE_TOLERANCE_S && t_s <= t_end_s + COVERAGE_TOLERANCE_S) {
            return Err(PreintegrationError::TimeOutside {
                t_s,
                t_start_s,
                t_end_s,
            });
        }
        let t = t_s.clamp(t_start_s, t_end_s);
        // Knot k with t_k ≤ t < t_{k+1} (the last piece includes its end).
        let k = self
            .knots
            .partition_point(|knot| knot.t_s <= t)
            .saturating_sub(1)
            .min(self.knots.len() - 2);
        let (k0, k1) = (&self.knots[k], &self.knots[k + 1]);
        let (q, v, p) = &self.states[k];
        let dt = t - k0.t_s;
        let (q, v, p) = if dt > 0.0 {
            let at_t = k0.lerp(k1, t);
            let accel = (k0.accel_mps2 + at_t.accel_mps2) * 0.5 - self.bias.accel_mps2;
            let gyro = (k0.gyro_radps + at_t.gyro_radps) * 0.5 - self.bias.gyro_radps;
            world_step(q, v, p, &accel, &gyro, &self.gravity_world, dt)
        } else {
            (*q, *v, *p)
        };
        Ok((Isometry3::from_parts(Translation3::from(p), q), v))
    }

    /// Pose `t_world_imu` at `t_s` (see [`ImuTrajectory::state_at`]).
    ///
    /// # Errors
    /// [`PreintegrationError::TimeOutside`], as [`ImuTrajectory::state_at`].
    pub fn pose_at(&self, t_s: f64) -> Result<Isometry3<f64>, PreintegrationError> {
        self.state_at(t_s).map(|(pose, _)| pose)
    }

    /// Poses at several instants (any order).
    ///
    /// # Errors
    /// [`PreintegrationError::TimeOutside`] for the first time outside the
    /// interval.
    pub fn poses_at(&self, times_s: &[f64]) -> Result<Vec<Isometry3<f64>>, PreintegrationError> {
        times_s.iter().map(|&t| self.pose_at(t)).collect()
    }

    /// Pose and velocity at the end of the interval.
    pub fn end_state(&self) -> (Isometry3<f64>, Vector3<f64>) {
        let (q, v, p) = self.states[self.states.len() - 1];
        (Isometry3::from_parts(Translation3::from(p), q), v)
    }
}

#[cfg(test)]
mod tests;
