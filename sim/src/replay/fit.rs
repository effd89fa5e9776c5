//! The C2 fit of a trajectory through poses sampled at a fixed period.
//!
//! Each channel (x, y, z and the unwrapped yaw, pitch, roll of
//! R = Rz(yaw) Ry(pitch) Rx(roll)) is smoothed by penalised least squares
//! (a Whittaker smoother): the knot values `x` minimise
//! `sum_k ((x_k - y_k) / sigma_k)^2 + sum_k (D3 x_k / (sigma_jerk dt^3))^2`,
//! with `D3` the third difference, so the path keeps within a few sigma of
//! the samples while its jerk stays of order `sigma_jerk`. Each knot's rate
//! and acceleration are the central differences of the smoothed values; the
//! quintic Hermite segments of [`Trajectory`] then give a C2 path through
//! the smoothed knots. One knot extrapolated at constant acceleration is
//! appended, so the last frame's sweep (which ends one period after the last
//! sample) sees the body still moving.

use crate::scene::{Jet, Knot, Trajectory};
use nalgebra::Isometry3;

/// Weights of the smoother: how far the fit may leave the samples and how
/// much jerk it allows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothingConfig {
    /// Scale of the jerk the fit allows, m/s^3.
    pub jerk_sigma_mps3: f64,
    /// 1-sigma uncertainty of each sampled angle, rad.
    pub angle_sigma_rad: f64,
    /// Scale of the angular jerk the fit allows, rad/s^3.
    pub angular_jerk_sigma_radps3: f64,
}

impl SmoothingConfig {
    /// The ego's: a car's jerk rarely exceeds a few m/s^3; GPS/INS attitude
    /// is good to a few mrad.
    pub const EGO: SmoothingConfig = SmoothingConfig {
        jerk_sigma_mps3: 2.0,
        angle_sigma_rad: 0.003,
        angular_jerk_sigma_radps3: 1.0,
    };
}

/// How far the fitted trajectory is from the samples at the sample times,
/// and how hard it accelerates.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FitResidual {
    /// RMS of the position residual, m.
    pub position_rms_m: f64,
    /// Largest position residual, m.
    pub position_max_m: f64,
    /// RMS of the rotation residual (angle of R_fit^T R_sample), rad.
    pub rotation_rms_rad: f64,
    /// Largest rotation residual, rad.
    pub rotation_max_rad: f64,
    /// Largest linear acceleration at a knot, m/s^2.
    pub accel_max_mps2: f64,
}

/// Fits a C2 trajectory through `poses` (sample `k` at `k * dt_s`),
/// weighting each position by `position_sigma_m[k]` (see the module docs).
/// `poses` must hold at least one pose, `position_sigma_m` as many positive
/// sigmas, and `dt_s` must be positive (as [`super::ReplayInput::validate`] checks).
pub fn fit_trajectory(
    poses: &[Isometry3<f64>],
    position_sigma_m: &[f64],
    dt_s: f64,
    config: &SmoothingConfig,
) -> (Trajectory, FitResidual) {
    let n = poses.len();
    let position_weight: Vec<f64> = position_sigma_m.iter().map(|s| 1.0 / (s * s)).collect();
    let angle_weight = vec![1.0 / (config.angle_sigma_rad * config.angle_sigma_rad); n];
    let mut smoothed: Vec<Vec<f64>> = Vec::with_capacity(6);
    for axis in 0..3 {
        let y: Vec<f64> = poses.iter().map(|p| p.translation.vector[axis]).collect();
        smoothed.push(smooth(&y, &position_weight, config.jerk_sigma_mps3, dt_s));
    }
    for channel in euler_channels(poses) {
        smoothed.push(smooth(
            &channel,
            &angle_weight,
            config.angular_jerk_sigma_radps3,
            dt_s,
        ));
    }
    let jets: Vec<Vec<Jet>> = smoothed.iter().map(|x| jets(x, dt_s)).collect();
    let mut knots: Vec<Knot> = (0..n)
        .map(|k| Knot {
            position: [jets[0][k], jets[1][k], jets[2][k]],
            euler: [jets[3][k], jets[4][k], jets[5][k]],
        })
        .collect();
    if let Some(last) = knots.last() {
        knots.push(extrapolated(last, dt_s));
    }
    let trajectory = Trajectory::new(0.0, dt_s, knots);
    let residual = residual(&trajectory, poses, dt_s);
    (trajectory, residual)
}

/// [yaw, pitch, roll] of each pose, each channel unwrapped (no 2 pi jumps).
pub(crate) fn euler_channels(poses: &[Isometry3<f64>]) -> [Vec<f64>; 3] {
    let mut out = [Vec::new(), Vec::new(), Vec::new()];
    for p in poses {
        let (roll, pitch, yaw) = p.rotation.euler_angles();
        for (channel, value) in out.iter_mut().zip([yaw, pitch, roll]) {
            let v = match channel.last() {
                Some(&prev) => prev + limot_estimator::geometry::wrap_angle_rad(value - prev),
                None => value,
            };
            channel.push(v);
        }
    }
    out
}

fn residual(trajectory: &Trajectory, poses: &[Isometry3<f64>], dt_s: f64) -> FitResidual {
    let mut out = FitResidual::default();
    let (mut sum_p, mut sum_r) = (0.0, 0.0);
    for (k, sample) in poses.iter().enumerate() {
        let state = trajectory.state_at(k as f64 * dt_s);
        let dp = (state.t_world_body.translation.vector - sample.translation.vector).norm();
        let dr = (state.t_world_body.rotation.inverse() * sample.rotation).angle();
        sum_p += dp * dp;
        sum_r += dr * dr;
        out.position_max_m = out.position_max_m.max(dp);
        out.rotation_max_rad = out.rotation_max_rad.max(dr);
        out.accel_max_mps2 = out.accel_max_mps2.max(state.accel_world_mps2.norm());
    }
    let n = poses.len().max(1) as f64;
    out.position_rms_m = (sum_p / n).sqrt();
    out.rotation_rms_rad = (sum_r / n).sqrt();
    out
}

/// The knot after `last`, `dt_s` later at constant acceleration.
pub(crate) fn extrapolated(last: &Knot, dt_s: f64) -> Knot {
    let step = |j: &Jet| {
        Jet::new(
            j.value + j.rate * dt_s + 0.5 * j.accel * dt_s * dt_s,
            j.rate + j.accel * dt_s,
            j.accel,
        )
    };
    Knot {
        position: last.position.each_ref().map(step),
        euler: last.euler.each_ref().map(step),
    }
}

/// Value, rate and acceleration at each sample: central differences inside,
/// second-order one-sided rates and the neighbour's acceleration at the ends.
pub(crate) fn jets(x: &[f64], dt_s: f64) -> Vec<Jet> {
    let n = x.len();
    match n {
        0 => Vec::new(),
        1 => vec![Jet::new(x[0], 0.0, 0.0)],
        2 => {
            let rate = (x[1] - x[0]) / dt_s;
            vec![Jet::new(x[0], rate, 0.0), Jet::new(x[1], rate, 0.0)]
        }
        _ => {
            let mut out: Vec<Jet> = (0..n)
                .map(|k| {
                    if k == 0 {
                        let rate = (-3.0 * x[0] + 4.0 * x[1] - x[2]) / (2.0 * dt_s);
                        Jet::new(x[0], rate, 0.0)
                    } else if k == n - 1 {
                        let rate = (3.0 * x[k] - 4.0 * x[k - 1] + x[k - 2]) / (2.0 * dt_s);
                        Jet::new(x[k], rate, 0.0)
                    } else {
                        Jet::new(
                            x[k],
                            (x[k + 1] - x[k - 1]) / (2.0 * dt_s),
                            (x[k + 1] - 2.0 * x[k] + x[k - 1]) / (dt_s * dt_s),
                        )
                    }
                })
                .collect();
            out[0].accel = out[1].accel;
            out[n - 1].accel = out[n - 2].accel;
            out
        }
    }
}

/// Half bandwidth of `D3^T D3`.
const BAND: usize = 3;

/// The Whittaker smoother of `y` (see the module docs); fewer than four
/// samples have no third difference and come back unchanged.
fn smooth(y: &[f64], weight: &[f64], jerk_sigma: f64, dt_s: f64) -> Vec<f64> {
    let n = y.len();
    if n < 4 {
        return y.to_vec();
    }
    let lambda = 1.0 / (jerk_sigma * jerk_sigma * dt_s.powi(6));
    // A = W + lambda D3^T D3 in band storage: a[i][d] = A[i][i - d]
    let mut a = vec![[0.0; BAND + 1]; n];
    for (row, w) in a.iter_mut().zip(weight) {
        row[0] = *w;
    }
    const D3: [f64; 4] = [-1.0, 3.0, -3.0, 1.0];
    for start in 0..n - 3 {
        for (p, cp) in D3.iter().enumerate() {
            for (q, cq) in D3.iter().enumerate().take(p + 1) {
                a[start + p][p - q] += lambda * cp * cq;
            }
        }
    }
    let rhs: Vec<f64> = y.iter().zip(weight).map(|(v, w)| v * w).collect();
    solve_banded_spd(&a, &rhs)
}

/// Solves `A x = b` for a symmetric positive definite band matrix
/// (`a[i][d] = A[i][i - d]`, d <= BAND) by band Cholesky.
fn solve_banded_spd(a: &[[f64; BAND + 1]], b: &[f64]) -> Vec<f64> {
    let n = b.len();
    // l[i][d] = L[i][i - d]
    let mut l = vec![[0.0; BAND + 1]; n];
    for i in 0..n {
        for j in i.saturating_sub(BAND)..=i {
            let mut sum = a[i][i - j];
            for k in i.saturating_sub(BAND)..j {
                if j - k <= BAND {
                    sum -= l[i][i - k] * l[j][j - k];
                }
            }
            if i == j {
                l[i][0] = sum.max(f64::MIN_POSITIVE).sqrt();
            } else {
                l[i][i - j] = sum / l[j][0];
            }
        }
    }
    let mut z = vec![0.0; n];
    for i in 0..n {
        let mut sum = b[i];
        for k in i.saturating_sub(BAND)..i {
            sum -= l[i][i - k] * z[k];
        }
        z[i] = sum / l[i][0];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let mut sum = z[i];
        for k in i + 1..(i + BAND + 1).min(n) {
            sum -= l[k][k - i] * x[k];
        }
        x[i] = sum / l[i][0];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    #[test]
    fn banded_solver_matches_a_dense_solve() {
        let n = 9;
        let y: Vec<f64> = (0..n).map(|k| (k as f64 * 0.7).sin()).collect();
        let w = vec![4.0; n];
        let x = smooth(&y, &w, 1.0, 0.1);
        // dense A = W + lambda D3^T D3
        let lambda = 1.0 / 0.1f64.powi(6);
        let mut d = nalgebra::DMatrix::<f64>::zeros(n - 3, n);
        for r in 0..n - 3 {
            for (c, v) in [-1.0, 3.0, -3.0, 1.0].iter().enumerate() {
                d[(r, r + c)] = *v;
            }
        }
        let a = nalgebra::DMatrix::<f64>::identity(n, n) * 4.0 + d.transpose() * &d * lambda;
        let b = nalgebra::DVector::from_vec(y.iter().map(|v| v * 4.0).collect());
        let dense = a.cholesky().unwrap().solve(&b);
        for k in 0..n {
            assert!(
                (x[k] - dense[k]).abs() < 1e-9,
                "{k}: {} vs {}",
                x[k],
                dense[k]
            );
        }
    }

    #[test]
    fn a_quadratic_path_is_kept_exactly() {
        // constant acceleration has no jerk: the smoother leaves it alone
        let poses: Vec<Isometry3<f64>> = (0..30)
            .map(|k| {
                let t = k as f64 * 0.1;
                Isometry3::from_parts(
                    Translation3::new(2.0 * t + 0.4 * t * t, 0.1 * t * t, 0.0),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, 0.05 * t),
                )
            })
            .collect();
        let (trajectory, residual) =
            fit_trajectory(&poses, &[0.05; 30], 0.1, &SmoothingConfig::EGO);
        assert!(residual.position_max_m < 1e-9, "{residual:?}");
        assert!(residual.rotation_max_rad < 1e-9, "{residual:?}");
        // between knots the acceleration is the true one
        let a = trajectory.state_at(1.55).accel_world_mps2;
        assert!((a - Vector3::new(0.8, 0.2, 0.0)).norm() < 1e-6, "{a}");
        // the extrapolated knot keeps the body moving past the last sample
        assert!(trajectory.end_s() > 2.95);
        let v = trajectory.state_at(2.95).velocity_world_mps.x;
        assert!((v - (2.0 + 0.8 * 2.95)).abs() < 1e-6, "{v}");
    }

    #[test]
    fn jitter_is_smoothed_and_the_residual_reports_it() {
        // +-3 cm alternating jitter on a straight drive: the fit stays within
        // about it (a little more at the ends) and its acceleration stays far
        // below the jitter's 6 m/s^2
        let poses: Vec<Isometry3<f64>> = (0..50)
            .map(|k: usize| {
                let jitter = if k.is_multiple_of(2) { 0.03 } else { -0.03 };
                Isometry3::translation(k as f64 + jitter, 0.0, 0.0)
            })
            .collect();
        let (_, residual) = fit_trajectory(&poses, &[0.05; 50], 0.1, &SmoothingConfig::EGO);
        assert!(residual.position_max_m < 0.04, "{residual:?}");
        assert!(residual.position_rms_m > 0.02, "{residual:?}");
        assert!(residual.accel_max_mps2 < 1.0, "{residual:?}");
    }

    #[test]
    fn yaw_is_unwrapped_across_pi() {
        let poses: Vec<Isometry3<f64>> = (0..20)
            .map(|k| {
                Isometry3::from_parts(
                    Translation3::new(0.0, 0.0, 0.0),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, 3.0 + 0.05 * k as f64),
                )
            })
            .collect();
        let [yaw, _, _] = euler_channels(&poses);
        assert!((yaw[19] - (3.0 + 0.95)).abs() < 1e-9, "{}", yaw[19]);
        let (_, residual) = fit_trajectory(&poses, &[0.05; 20], 0.1, &SmoothingConfig::EGO);
        assert!(residual.rotation_max_rad < 1e-6, "{residual:?}");
    }
}
