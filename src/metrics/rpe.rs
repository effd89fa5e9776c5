//! Relative pose error (evo `evo_rpe`, Zhang & Scaramuzza 2018).
//!
//! After timestamp association (as in [`super::ate::associate`]), pose pairs
//! `(i, j)` are chosen along the trajectory and
//!
//! ```text
//! E_ij = (T_true,i⁻¹ · T_true,j)⁻¹ · (T_est,i⁻¹ · T_est,j)
//! e_t  = ‖trans(E_ij)‖ [m],   e_R = ‖Log(rot(E_ij))‖ [rad]
//! ```
//!
//! The relative motion is frame-independent, so no alignment is needed.
//! Pair selection follows evo: with `all_pairs = false`, consecutive pairs of
//! the index sequence 0, δ, 2δ, … (frames) or of index 0 and the indices at
//! which the path length since the last index first reaches δ (metres); with
//! `all_pairs = true`, every `i` is paired with `i + δ` (frames) or with the
//! `j > i` whose path length from `i` is closest to δ, kept when it is within
//! `path_tolerance_m` of δ (metres; evo's tolerance is relative, δ·rel_tol).
//! Path lengths are measured on the true trajectory, as evo's
//! `--pairs_from_reference` (evo's default measures them on the estimate).

use super::ate::associate;
use super::{ErrorStats, EvalError};
use nalgebra::Isometry3;

/// The step over which relative motion is compared.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RpeDelta {
    /// A fixed number of frames.
    Frames(usize),
    /// A distance travelled along the true path.
    Meters {
        /// The distance, m.
        delta_m: f64,
        /// How far a pair's path length may differ from `delta_m`, m.
        path_tolerance_m: f64,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
/// Relative pose error over the pose pairs of one delta.
pub struct RpeResult {
    /// Translation RMSE, m.
    pub trans_rmse_m: f64,
    /// Translation mean, m.
    pub trans_mean_m: f64,
    /// Translation median, m.
    pub trans_median_m: f64,
    /// Largest translation error, m.
    pub trans_max_m: f64,
    /// Rotation RMSE, rad.
    pub rot_rmse_rad: f64,
    /// Rotation mean, rad.
    pub rot_mean_rad: f64,
    /// Rotation median, rad.
    pub rot_median_rad: f64,
    /// Largest rotation error, rad.
    pub rot_max_rad: f64,
    /// Number of pose pairs compared.
    pub n_pairs: usize,
}

fn pair_indices(
    truth_positions: &[nalgebra::Vector3<f64>],
    delta: RpeDelta,
    all_pairs: bool,
) -> Result<Vec<(usize, usize)>, EvalError> {
    let n = truth_positions.len();
    match delta {
        RpeDelta::Frames(0) => Err(EvalError::BadParameter {
            what: "rpe delta",
            why: "frame delta must be >= 1".into(),
        }),
        RpeDelta::Frames(d) => Ok(if all_pairs {
            (0..n.saturating_sub(d)).map(|i| (i, i + d)).collect()
        } else {
            let ids: Vec<usize> = (0..n).step_by(d).collect();
            ids.windows(2).map(|w| (w[0], w[1])).collect()
        }),
        RpeDelta::Meters {
            delta_m,
            path_tolerance_m,
        } => {
            let delta_ok = delta_m > 0.0 && delta_m.is_finite();
            let tolerance_ok = path_tolerance_m >= 0.0 && path_tolerance_m.is_finite();
            if !(delta_ok && tolerance_ok) {
                return Err(EvalError::BadParameter {
                    what: "rpe delta",
                    why: format!(
                        "need delta_m > 0 and path_tolerance_m >= 0, got {delta_m} and {path_tolerance_m}"
                    ),
                });
            }
            // Accumulated path length along the true trajectory.
            let mut dist = vec![0.0; n];
            for i in 1..n {
                dist[i] = dist[i - 1] + (truth_positions[i] - truth_positions[i - 1]).norm();
            }
            if all_pairs {
                let mut pairs = Vec::new();
                for i in 0..n.saturating_sub(1) {
                    let best = (i + 1..n)
                        .min_by(|&a, &b| {
                            let da = (dist[a] - dist[i] - delta_m).abs();
                            let db = (dist[b] - dist[i] - delta_m).abs();
                            da.total_cmp(&db)
                        })
                        .filter(|&j| (dist[j] - dist[i] - delta_m).abs() <= path_tolerance_m);
                    if let Some(j) = best {
                        pairs.push((i, j));
                    }
                }
                Ok(pairs)
            } else {
                // The first pose always starts a pair (evo ≥ 1.2x).
                let mut ids = vec![0];
                let mut path = 0.0;
                for i in 1..n {
                    path += (truth_positions[i] - truth_positions[i - 1]).norm();
                    if path >= delta_m {
                        ids.push(i);
                        path = 0.0;
                    }
                }
                Ok(ids.windows(2).map(|w| (w[0], w[1])).collect())
            }
        }
    }
}

/// Relative pose error between an estimated and a true trajectory.
///
/// # Errors
///
/// [`EvalError`] for invalid inputs; [`EvalError::TooFew`] when no pose pair spans the delta.
///
/// # Examples
///
/// An estimate that moves 2 m per frame where the truth moves 1 m has a
/// relative translation error of 1 m over every one-frame pair:
///
/// ```
/// use limot::metrics::{RpeDelta, rpe};
/// use nalgebra::{Isometry3, Translation3};
///
/// let along_x = |k: f64| (0..5)
///     .map(|i| (i as f64, Isometry3::from(Translation3::new(k * i as f64, 0.0, 0.0))))
///     .collect::<Vec<_>>();
/// let (truth, est) = (along_x(1.0), along_x(2.0));
/// let r = rpe(&est, &truth, 0.01, RpeDelta::Frames(1), false)?;
/// assert!((r.trans_rmse_m - 1.0).abs() < 1e-12);
/// assert!(r.rot_max_rad < 1e-12);
/// # Ok::<(), limot::metrics::EvalError>(())
/// ```
pub fn rpe(
    est: &[(f64, Isometry3<f64>)],
    truth: &[(f64, Isometry3<f64>)],
    max_dt_s: f64,
    delta: RpeDelta,
    all_pairs: bool,
) -> Result<RpeResult, EvalError> {
    let assoc = associate(est, truth, max_dt_s)?;
    let est_poses: Vec<Isometry3<f64>> = assoc.iter().map(|&(ie, _)| est[ie].1).collect();
    let true_poses: Vec<Isometry3<f64>> = assoc.iter().map(|&(_, it)| truth[it].1).collect();
    let positions: Vec<_> = true_poses.iter().map(|p| p.translation.vector).collect();
    let pairs = pair_indices(&positions, delta, all_pairs)?;
    if pairs.is_empty() {
        return Err(EvalError::TooFew {
            what: "rpe: pose pairs at the requested delta",
            got: 0,
            need: 1,
        });
    }
    let mut t_err = Vec::with_capacity(pairs.len());
    let mut r_err = Vec::with_capacity(pairs.len());
    for (i, j) in pairs {
        let rel_true = true_poses[i].inverse() * true_poses[j];
        let rel_est = est_poses[i].inverse() * est_poses[j];
        let e = rel_true.inverse() * rel_est;
        t_err.push(e.translation.vector.norm());
        r_err.push(e.rotation.angle());
    }
    let t = ErrorStats::of(&t_err).ok_or(EvalError::Empty { what: "rpe" })?;
    let r = ErrorStats::of(&r_err).ok_or(EvalError::Empty { what: "rpe" })?;
    Ok(RpeResult {
        trans_rmse_m: t.rmse,
        trans_mean_m: t.mean,
        trans_median_m: t.median,
        trans_max_m: t.max,
        rot_rmse_rad: r.rmse,
        rot_mean_rad: r.mean,
        rot_median_rad: r.median,
        rot_max_rad: r.max,
        n_pairs: t.n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    fn straight(n: usize, step_m: f64) -> Vec<(f64, Isometry3<f64>)> {
        (0..n)
            .map(|i| {
                (
                    i as f64,
                    Isometry3::from_parts(
                        Translation3::new(step_m * i as f64, 0.0, 0.0),
                        UnitQuaternion::identity(),
                    ),
                )
            })
            .collect()
    }

    #[test]
    fn global_offset_gives_zero_rpe() {
        let truth = straight(20, 1.0);
        let offset = Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.1, 0.2, 0.3));
        let est: Vec<_> = truth.iter().map(|(t, p)| (*t, offset * p)).collect();
        let r = rpe(&est, &truth, 0.01, RpeDelta::Frames(1), true).unwrap();
        assert_eq!(r.n_pairs, 19);
        assert!(r.trans_rmse_m < 1e-12 && r.rot_rmse_rad < 1e-12);
    }

    #[test]
    fn scale_drift_hand_case() {
        // Estimate moves 1.1 m per frame instead of 1 m: every 1-frame error is 0.1 m.
        let truth = straight(11, 1.0);
        let est = straight(11, 1.1);
        let r = rpe(&est, &truth, 0.01, RpeDelta::Frames(1), false).unwrap();
        assert_eq!(r.n_pairs, 10);
        assert!((r.trans_rmse_m - 0.1).abs() < 1e-12);
        let r2 = rpe(&est, &truth, 0.01, RpeDelta::Frames(2), false).unwrap();
        assert_eq!(r2.n_pairs, 5);
        assert!((r2.trans_mean_m - 0.2).abs() < 1e-12);
        // 3 m of true path per pair: indices 0, 3, 6, 9 -> three pairs of 0.3 m error.
        let delta = RpeDelta::Meters {
            delta_m: 3.0,
            path_tolerance_m: 0.0,
        };
        let r3 = rpe(&est, &truth, 0.01, delta, false).unwrap();
        assert_eq!(r3.n_pairs, 3);
        assert!((r3.trans_max_m - 0.3).abs() < 1e-12);
        assert!((r3.trans_rmse_m - 0.3).abs() < 1e-12);
        let r4 = rpe(&est, &truth, 0.01, delta, true).unwrap();
        assert_eq!(r4.n_pairs, 8);
    }

    #[test]
    fn rotation_error_hand_case() {
        let truth = straight(3, 0.0);
        let est: Vec<_> = (0..3)
            .map(|i| {
                (
                    i as f64,
                    Isometry3::from_parts(
                        Translation3::identity(),
                        UnitQuaternion::from_euler_angles(0.0, 0.0, 0.05 * i as f64),
                    ),
                )
            })
            .collect();
        let r = rpe(&est, &truth, 0.01, RpeDelta::Frames(1), true).unwrap();
        assert!((r.rot_rmse_rad - 0.05).abs() < 1e-12);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let truth = straight(5, 1.0);
        assert!(rpe(&truth, &truth, 0.01, RpeDelta::Frames(0), false).is_err());
        assert!(matches!(
            rpe(&truth, &truth, 0.01, RpeDelta::Frames(10), false),
            Err(EvalError::TooFew { .. })
        ));
        let bad = RpeDelta::Meters {
            delta_m: f64::NAN,
            path_tolerance_m: 0.1,
        };
        assert!(rpe(&truth, &truth, 0.01, bad, false).is_err());
    }
}
