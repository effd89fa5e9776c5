//! Least-squares polynomial trajectory fit over a track's sliding window
//! (DL-SLOT / LIMOT "Multi-object Tracking": cubic polynomial per coordinate).
//!
//! Each of x, y, z (world frame) and the unwrapped yaw is fitted independently
//! against time. Times are centred on their mean and scaled by their largest
//! deviation, so the Vandermonde matrix has entries in [-1, 1] and stays well
//! conditioned whatever the absolute clock value is (KITTI times start at 0,
//! UNIX times near 1.7e9).
//!
//! The degree falls back while the history is short: 1 sample → constant,
//! 2 → line through both, n ≥ 3 → `min(max_degree, n - 2)`. Keeping one
//! redundant sample once there are three or more means a single noisy box
//! cannot bend the extrapolation arbitrarily (an interpolating cubic through
//! four noisy boxes extrapolates the noise with a gain of ~7).
//!
//! [`TrajectoryFit::fit`] is the plain least-squares fit;
//! [`TrajectoryFit::fit_with_prior`] adds priors on the higher derivatives
//! (its documentation says why).

use nalgebra::{DMatrix, Vector3};

/// Highest polynomial degree supported (the paper's cubic).
pub const MAX_DEGREE: usize = 3;

/// Number of fitted coordinates: x, y, z, yaw.
const N_COORDS: usize = 4;

/// One timed pose sample of a track (world frame, yaw already unwrapped so that
/// consecutive samples differ by less than π).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitSample {
    /// Time (s).
    pub t_s: f64,
    /// Centre, world frame (m).
    pub center_world: Vector3<f64>,
    /// Unwrapped yaw about the world z axis (rad).
    pub yaw_rad: f64,
}

/// The fitted trajectory evaluated at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitPrediction {
    /// Centre, world frame (m).
    pub center_world: Vector3<f64>,
    /// Unwrapped (continuous) yaw; wrap it for display.
    pub yaw_rad: f64,
    /// Time derivative of the centre.
    pub velocity_world_mps: Vector3<f64>,
    /// Time derivative of the yaw (rad/s).
    pub yaw_rate_radps: f64,
}

/// Why a fit could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// No sample was given.
    #[error("trajectory fit needs at least one sample")]
    NoSamples,
    /// A sample's time, centre or yaw is not finite.
    #[error("trajectory fit: sample {index}, field `{field}` is not finite")]
    NotFinite {
        /// Index of the sample.
        index: usize,
        /// Name of the field.
        field: &'static str,
    },
    /// `max_degree` is above [`MAX_DEGREE`].
    #[error("trajectory fit: max degree {max_degree} above the supported {MAX_DEGREE}")]
    DegreeTooHigh {
        /// The degree asked for.
        max_degree: usize,
    },
    /// A sigma of the [`FitPrior`] is not positive (or a noise sigma not finite).
    #[error("trajectory fit: prior sigmas must be positive (noise sigmas also finite)")]
    BadPrior,
}

/// Zero-mean Gaussian priors on the higher derivatives at the window centre,
/// relative to the measurement noise. An infinite prior sigma disables that
/// prior (plain least squares for that term).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitPrior {
    /// Per-axis noise of the measured centres.
    pub position_sigma_m: f64,
    /// Noise of the measured (unwrapped) yaw.
    pub yaw_sigma_rad: f64,
    /// Prior sigma of the acceleration (m/s²; infinity = no prior).
    pub accel_sigma_mps2: f64,
    /// Prior sigma of the jerk (m/s³; infinity = no prior).
    pub jerk_sigma_mps3: f64,
    /// Prior sigma of the yaw acceleration (rad/s²; infinity = no prior).
    pub yaw_accel_sigma_radps2: f64,
    /// Prior sigma of the yaw jerk (rad/s³; infinity = no prior).
    pub yaw_jerk_sigma_radps3: f64,
}

impl FitPrior {
    /// No prior at all: [`TrajectoryFit::fit_with_prior`] equals
    /// [`TrajectoryFit::fit`].
    pub const NONE: FitPrior = FitPrior {
        position_sigma_m: 1.0,
        yaw_sigma_rad: 1.0,
        accel_sigma_mps2: f64::INFINITY,
        jerk_sigma_mps3: f64::INFINITY,
        yaw_accel_sigma_radps2: f64::INFINITY,
        yaw_jerk_sigma_radps3: f64::INFINITY,
    };

    /// Checks that every sigma is positive (infinity allowed for the priors).
    fn is_valid(&self) -> bool {
        let noise_ok = |v: f64| v.is_finite() && v > 0.0;
        let prior_ok = |v: f64| !v.is_nan() && v > 0.0;
        noise_ok(self.position_sigma_m)
            && noise_ok(self.yaw_sigma_rad)
            && prior_ok(self.accel_sigma_mps2)
            && prior_ok(self.jerk_sigma_mps3)
            && prior_ok(self.yaw_accel_sigma_radps2)
            && prior_ok(self.yaw_jerk_sigma_radps3)
    }
}

/// Polynomial coefficients (ascending powers of the scaled time
/// `u = (t - t_center_s) / t_scale_s`) for x, y, z and yaw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryFit {
    t_center_s: f64,
    t_scale_s: f64,
    degree: usize,
    /// `coeffs[coord][power]`, zero above `degree`.
    coeffs: [[f64; MAX_DEGREE + 1]; N_COORDS],
}

/// Degree used for `n_samples` samples with at most `max_degree`
/// (1 sample: constant, 2: line, n ≥ 3: `min(max_degree, n − 2)`, one
/// sample kept redundant so a single noisy box cannot bend the
/// extrapolation arbitrarily).
pub fn degree_for_samples(n_samples: usize, max_degree: usize) -> usize {
    match n_samples {
        0 | 1 => 0,
        2 => max_degree.min(1),
        n => max_degree.min(n - 2),
    }
}

impl TrajectoryFit {
    /// Plain least-squares fit of all coordinates over `samples` (any order,
    /// distinct times expected; repeated times only reduce the effective
    /// degree through the SVD's minimum-norm solution).
    ///
    /// # Errors
    /// As [`TrajectoryFit::fit_with_prior`].
    ///
    /// ```
    /// use limot_estimator::tracking::{FitSample, TrajectoryFit};
    /// use nalgebra::Vector3;
    ///
    /// // Five samples of x = t²: the degree is min(3, 5 − 2) = 3, and a cubic
    /// // fit reproduces a quadratic exactly.
    /// let samples: Vec<FitSample> = (0..5)
    ///     .map(|k| {
    ///         let t_s = 0.1 * k as f64;
    ///         FitSample { t_s, center_world: Vector3::new(t_s * t_s, 0.0, 0.0), yaw_rad: 0.0 }
    ///     })
    ///     .collect();
    /// let fit = TrajectoryFit::fit(&samples, 3).unwrap();
    /// let ahead = fit.predict(0.5);
    /// assert!((ahead.center_world.x - 0.25).abs() < 1e-9);
    /// assert!((ahead.velocity_world_mps.x - 1.0).abs() < 1e-9);
    /// ```
    pub fn fit(samples: &[FitSample], max_degree: usize) -> Result<Self, FitError> {
        Self::fit_with_prior(samples, max_degree, &FitPrior::NONE)
    }

    /// Least-squares fit with zero-mean priors on acceleration and jerk at
    /// the window centre. The degree still follows [`degree_for_samples`].
    ///
    /// Why: an unregularised cubic through the paper's 5 boxes extrapolates
    /// one frame ahead with a noise gain of 4.9 (quadratic 2.1, line 1.05);
    /// with 0.15 m box noise that is 0.74 m per axis, so a 2 m association
    /// gate loses several percent of true matches. The priors are ridge rows
    /// in the least-squares system, in physical units: the cubic still
    /// follows strong, well-sampled curvature but no longer amplifies box
    /// noise.
    ///
    /// # Errors
    /// [`FitError::DegreeTooHigh`] above [`MAX_DEGREE`],
    /// [`FitError::BadPrior`] for a sigma that is not positive (noise sigmas
    /// also finite), [`FitError::NoSamples`] for no samples,
    /// [`FitError::NotFinite`] for a non-finite sample.
    pub fn fit_with_prior(
        samples: &[FitSample],
        max_degree: usize,
        prior: &FitPrior,
    ) -> Result<Self, FitError> {
        if max_degree > MAX_DEGREE {
            return Err(FitError::DegreeTooHigh { max_degree });
        }
        if !prior.is_valid() {
            return Err(FitError::BadPrior);
        }
        if samples.is_empty() {
            return Err(FitError::NoSamples);
        }
        for (index, s) in samples.iter().enumerate() {
            if !s.t_s.is_finite() {
                return Err(FitError::NotFinite {
                    index,
                    field: "t_s",
                });
            }
            if !s.center_world.iter().all(|v| v.is_finite()) {
                return Err(FitError::NotFinite {
                    index,
                    field: "center_world",
                });
            }
            if !s.yaw_rad.is_finite() {
                return Err(FitError::NotFinite {
                    index,
                    field: "yaw_rad",
                });
            }
        }
        let n = samples.len();
        let t_center_s = samples.iter().map(|s| s.t_s).sum::<f64>() / n as f64;
        let t_scale_s = samples
            .iter()
            .map(|s| (s.t_s - t_center_s).abs())
            .fold(0.0, f64::max);
        let mut degree = degree_for_samples(n, max_degree);
        // All samples at one instant: only a constant is identifiable.
        let t_scale_s = if t_scale_s > 0.0 {
            t_scale_s
        } else {
            degree = 0;
            1.0
        };
        let mut coeffs = [[0.0; MAX_DEGREE + 1]; N_COORDS];
        if degree == 0 {
            // Mean of each coordinate: the least-squares constant.
            for s in samples {
                for (c, v) in values(s).iter().enumerate() {
                    coeffs[c][0] += v / n as f64;
                }
            }
        } else {
            // Positions and yaw have different noise and priors: two solves.
            let groups: [(&[usize], f64, [f64; 2]); 2] = [
                (
                    &[0, 1, 2],
                    prior.position_sigma_m,
                    [prior.accel_sigma_mps2, prior.jerk_sigma_mps3],
                ),
                (
                    &[3],
                    prior.yaw_sigma_rad,
                    [prior.yaw_accel_sigma_radps2, prior.yaw_jerk_sigma_radps3],
                ),
            ];
            for (coords, noise_sigma, derivative_sigmas) in groups {
                // Prior rows for powers p ≥ 2: the p-th time derivative at the
                // centre is p!·c_p / s^p ~ N(0, σ_p²), i.e. c_p ~ N(0,
                // (σ_p s^p / p!)²); weighted relative to the unit-weight rows
                // of measurements with noise `noise_sigma`.
                let prior_rows: Vec<(usize, f64)> = (2..=degree)
                    .map(|p| {
                        let sigma = derivative_sigmas[p - 2];
                        let factorial = if p == 2 { 2.0 } else { 6.0 };
                        let weight = noise_sigma * factorial / (sigma * t_scale_s.powi(p as i32));
                        (p, weight)
                    })
                    .filter(|&(_, w)| w > 0.0)
                    .collect();
                let solution = solve_least_squares(
                    samples,
                    coords,
                    &prior_rows,
                    degree,
                    t_center_s,
                    t_scale_s,
                );
                for (k, &c) in coords.iter().enumerate() {
                    for p in 0..=degree {
                        coeffs[c][p] = solution[(p, k)];
                    }
                }
            }
        }
        Ok(TrajectoryFit {
            t_center_s,
            t_scale_s,
            degree,
            coeffs,
        })
    }

    /// Degree actually fitted.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// Evaluates the fitted trajectory and its time derivative at `t_s`
    /// (inside the window: smoothing; after it: extrapolation).
    pub fn predict(&self, t_s: f64) -> FitPrediction {
        let u = (t_s - self.t_center_s) / self.t_scale_s;
        let mut value = [0.0; N_COORDS];
        let mut derivative = [0.0; N_COORDS];
        for c in 0..N_COORDS {
            // Horner for p(u) and p'(u) together.
            let (mut p, mut dp) = (0.0, 0.0);
            for k in (0..=self.degree).rev() {
                dp = dp * u + p;
                p = p * u + self.coeffs[c][k];
            }
            value[c] = p;
            // d/dt = d/du · du/dt.
            derivative[c] = dp / self.t_scale_s;
        }
        FitPrediction {
            center_world: Vector3::new(value[0], value[1], value[2]),
            yaw_rad: value[3],
            velocity_world_mps: Vector3::new(derivative[0], derivative[1], derivative[2]),
            yaw_rate_radps: derivative[3],
        }
    }
}

/// Solves the (prior-augmented) least-squares problem for the coefficients of
/// `coords`: rows `[u^0 … u^degree] · c = value` for every sample plus one row
/// `weight · c_p = 0` per prior. Normal equations with Cholesky on at most
/// 4×4 (u ∈ [−1, 1] keeps them well conditioned: ~1e3 for 5 samples and a
/// cubic); an SVD only if they are singular (repeated times).
fn solve_least_squares(
    samples: &[FitSample],
    coords: &[usize],
    prior_rows: &[(usize, f64)],
    degree: usize,
    t_center_s: f64,
    t_scale_s: f64,
) -> DMatrix<f64> {
    let n_coeffs = degree + 1;
    let row_of = |sample: &FitSample| {
        let u = (sample.t_s - t_center_s) / t_scale_s;
        let mut row = [0.0; MAX_DEGREE + 1];
        let mut power = 1.0;
        for value in row.iter_mut().take(n_coeffs) {
            *value = power;
            power *= u;
        }
        row
    };
    let mut normal = DMatrix::<f64>::zeros(n_coeffs, n_coeffs);
    let mut rhs = DMatrix::<f64>::zeros(n_coeffs, coords.len());
    for sample in samples {
        let row = row_of(sample);
        let v = values(sample);
        for a in 0..n_coeffs {
            for b in 0..n_coeffs {
                normal[(a, b)] += row[a] * row[b];
            }
            for (k, &c) in coords.iter().enumerate() {
                rhs[(a, k)] += row[a] * v[c];
            }
        }
    }
    for &(p, weight) in prior_rows {
        normal[(p, p)] += weight * weight;
    }
    if let Some(cholesky) = normal.clone().cholesky() {
        // Positive definite in the numerical sense too? Check the pivots'
        // spread before trusting it; otherwise fall through to the SVD.
        let diag = cholesky.l_dirty().diagonal();
        let (lo, hi) = diag.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &d| {
            (lo.min(d), hi.max(d))
        });
        if lo > 1e-6 * hi {
            return cholesky.solve(&rhs);
        }
    }
    // Rank-deficient (repeated times): minimum-norm least squares.
    let mut design = DMatrix::<f64>::zeros(samples.len() + prior_rows.len(), n_coeffs);
    let mut values_m = DMatrix::<f64>::zeros(design.nrows(), coords.len());
    for (r, sample) in samples.iter().enumerate() {
        let row = row_of(sample);
        for p in 0..n_coeffs {
            design[(r, p)] = row[p];
        }
        for (k, &c) in coords.iter().enumerate() {
            values_m[(r, k)] = values(sample)[c];
        }
    }
    for (k, &(p, weight)) in prior_rows.iter().enumerate() {
        design[(samples.len() + k, p)] = weight;
    }
    design
        .svd(true, true)
        .solve(&values_m, 1e-12)
        .expect("SVD was computed with both U and V^T")
}

fn values(s: &FitSample) -> [f64; N_COORDS] {
    [
        s.center_world.x,
        s.center_world.y,
        s.center_world.z,
        s.yaw_rad,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t_s: f64, x: f64) -> FitSample {
        FitSample {
            t_s,
            center_world: Vector3::new(x, -x, 0.5 * x),
            yaw_rad: 0.1 * x,
        }
    }

    #[test]
    fn degree_falls_back_while_short() {
        assert_eq!(degree_for_samples(1, 3), 0);
        assert_eq!(degree_for_samples(2, 3), 1);
        assert_eq!(degree_for_samples(3, 3), 1);
        assert_eq!(degree_for_samples(4, 3), 2);
        assert_eq!(degree_for_samples(5, 3), 3);
        assert_eq!(degree_for_samples(9, 3), 3);
        assert_eq!(degree_for_samples(9, 1), 1);
        assert_eq!(degree_for_samples(2, 0), 0);
    }

    #[test]
    fn single_sample_is_constant_with_zero_velocity() {
        let fit = TrajectoryFit::fit(&[sample(1e9, 4.0)], 3).unwrap();
        let p = fit.predict(1e9 + 1.0);
        assert_eq!(p.center_world, Vector3::new(4.0, -4.0, 2.0));
        assert_eq!(p.velocity_world_mps, Vector3::zeros());
    }

    #[test]
    fn line_is_exact_at_large_absolute_times() {
        // t ≈ 1.7e9 s (UNIX clock): centring keeps this exact.
        let t0 = 1.7e9;
        let samples: Vec<_> = (0..3)
            .map(|k| sample(t0 + 0.1 * k as f64, 2.0 + 3.0 * 0.1 * k as f64))
            .collect();
        let fit = TrajectoryFit::fit(&samples, 3).unwrap();
        let p = fit.predict(t0 + 0.5);
        assert!(
            (p.center_world.x - 3.5).abs() < 1e-6,
            "{}",
            p.center_world.x
        );
        assert!((p.velocity_world_mps.x - 3.0).abs() < 1e-5);
        assert!((p.velocity_world_mps.y + 3.0).abs() < 1e-5);
    }

    #[test]
    fn bad_input_is_an_error() {
        assert_eq!(TrajectoryFit::fit(&[], 3), Err(FitError::NoSamples));
        let mut s = sample(0.0, 1.0);
        s.center_world.y = f64::NAN;
        assert_eq!(
            TrajectoryFit::fit(&[sample(-1.0, 0.0), s], 3),
            Err(FitError::NotFinite {
                index: 1,
                field: "center_world"
            })
        );
        assert_eq!(
            TrajectoryFit::fit(&[sample(0.0, 0.0)], 4),
            Err(FitError::DegreeTooHigh { max_degree: 4 })
        );
    }

    #[test]
    fn prior_shrinks_curvature_but_keeps_a_line_exact() {
        let prior = FitPrior {
            position_sigma_m: 0.15,
            yaw_sigma_rad: 0.03,
            accel_sigma_mps2: 3.0,
            jerk_sigma_mps3: 10.0,
            yaw_accel_sigma_radps2: 1.0,
            yaw_jerk_sigma_radps3: 3.0,
        };
        // A line has zero acceleration and jerk: the prior does not bias it.
        let line: Vec<_> = (0..5)
            .map(|k| sample(0.1 * k as f64, 2.0 * k as f64))
            .collect();
        let fit = TrajectoryFit::fit_with_prior(&line, 3, &prior).unwrap();
        let p = fit.predict(0.5);
        assert!((p.center_world.x - 10.0).abs() < 1e-9);
        assert!((p.velocity_world_mps.x - 20.0).abs() < 1e-8);
        // One outlier: the plain cubic swings far more than the prior fit.
        let mut bumped = line.clone();
        bumped[3].center_world.x += 0.3;
        let plain = TrajectoryFit::fit(&bumped, 3).unwrap().predict(0.5);
        let ridge = TrajectoryFit::fit_with_prior(&bumped, 3, &prior)
            .unwrap()
            .predict(0.5);
        let plain_err = (plain.center_world.x - 10.0).abs();
        let ridge_err = (ridge.center_world.x - 10.0).abs();
        assert!(ridge_err < 0.3 * plain_err, "{ridge_err} vs {plain_err}");
        let bad = FitPrior {
            accel_sigma_mps2: 0.0,
            ..prior
        };
        assert_eq!(
            TrajectoryFit::fit_with_prior(&line, 3, &bad),
            Err(FitError::BadPrior)
        );
    }

    #[test]
    fn repeated_time_gives_mean() {
        let fit = TrajectoryFit::fit(&[sample(2.0, 1.0), sample(2.0, 3.0)], 3).unwrap();
        assert_eq!(fit.degree(), 0);
        assert!((fit.predict(5.0).center_world.x - 2.0).abs() < 1e-12);
    }
}
