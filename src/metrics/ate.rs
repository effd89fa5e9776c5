//! Absolute trajectory error (evo `evo_ape` with `--align`, Zhang & Scaramuzza 2018).
//!
//! Estimated and true poses are associated by timestamp (nearest true pose within
//! `max_dt_s`), the estimated positions are aligned to the true ones with Umeyama
//! (SE(3) by default), and per associated pair `i`:
//!
//! ```text
//! E_i     = (S · T_est,i)⁻¹ · T_true,i        S = aligning transform
//! e_t,i   = ‖trans(E_i)‖ = ‖p_true,i − (s·R·p_est,i + t)‖          [m]
//! e_R,i   = ‖Log(rot(E_i))‖ = angle of (R·R_est,i)ᵀ·R_true,i        [rad]
//! ATE_T   = sqrt(mean e_t,i²),   ATE_R = sqrt(mean e_R,i²)
//! ```
//!
//! The translation error is also split along the true direction of travel
//! ([`AteResult::along_rmse_m`]): a LiDAR odometry whose scan match cannot
//! see along a featureless road drifts there alone.

use super::align::{Alignment, umeyama};
use super::{ErrorStats, EvalError, check_pose};
use limot_sim::record::EgoTruth;
use nalgebra::{Isometry3, Vector3};

/// How the estimate is brought onto the ground truth before measuring.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AlignMode {
    /// Compare as given (both already in the same world frame).
    None,
    /// Rigid Umeyama alignment of positions (evo `--align`), the default.
    #[default]
    Se3,
    /// Similarity alignment (evo `--align --correct_scale`).
    Sim3,
}

#[derive(Debug, Clone, PartialEq)]
/// Absolute trajectory error after alignment.
pub struct AteResult {
    /// RMSE of the translation errors, metres (ATE_T).
    pub ate_t_rmse_m: f64,
    /// RMSE of the rotation-error angles, radians (ATE_R).
    pub ate_r_rmse_rad: f64,
    /// Mean translation error, m.
    pub mean_m: f64,
    /// Median translation error, m.
    pub median_m: f64,
    /// Largest translation error, m.
    pub max_m: f64,
    /// RMSE of the translation errors' component along the true direction
    /// of travel (`travel_directions`), m; `None` when the truth never
    /// moves. Its square and the cross-track errors' add up to ATE_T².
    pub along_rmse_m: Option<f64>,
    /// Number of associated pose pairs used.
    pub n: usize,
    /// Transform applied to the estimate (identity for [`AlignMode::None`]).
    /// When `alignment.degenerate` is set (estimated positions on a line, e.g.
    /// a straight drive), the rotation about that line is arbitrary and
    /// ATE_R is not meaningful; ATE_T still is.
    pub alignment: Alignment,
    /// Per-pair (t_est_s, translation error m, rotation error rad), in estimate time order.
    pub per_pose: Vec<(f64, f64, f64)>,
}

/// The simulator's ground-truth ego trajectory as timestamped `t_world_lidar` poses.
pub fn ego_trajectory(truth: &[EgoTruth]) -> Vec<(f64, Isometry3<f64>)> {
    truth.iter().map(|e| (e.t_s, e.t_world_lidar)).collect()
}

/// Validates a timestamped trajectory and returns its indices sorted by time.
fn sorted_indices(
    what: &'static str,
    traj: &[(f64, Isometry3<f64>)],
) -> Result<Vec<usize>, EvalError> {
    if traj.is_empty() {
        return Err(EvalError::Empty { what });
    }
    for (i, (t_s, pose)) in traj.iter().enumerate() {
        check_pose(what, i, *t_s, pose)?;
    }
    let mut idx: Vec<usize> = (0..traj.len()).collect();
    idx.sort_by(|&a, &b| traj[a].0.total_cmp(&traj[b].0));
    Ok(idx)
}

/// Timestamp association as evo's `associate_trajectories`: each pose of the
/// trajectory with fewer poses (the estimate on a tie) is paired with the pose
/// of the other one nearest in time (the earlier one on an exact tie), if that
/// is within `max_dt_s`. Returns `(est index, truth index)` pairs in time order.
///
/// # Errors
///
/// [`EvalError`] for empty inputs, non-finite poses or a bad `max_dt_s`.
pub fn associate(
    est: &[(f64, Isometry3<f64>)],
    truth: &[(f64, Isometry3<f64>)],
    max_dt_s: f64,
) -> Result<Vec<(usize, usize)>, EvalError> {
    if !(max_dt_s >= 0.0 && max_dt_s.is_finite()) {
        return Err(EvalError::BadParameter {
            what: "associate",
            why: format!("max_dt_s must be finite and >= 0, got {max_dt_s}"),
        });
    }
    let est_idx = sorted_indices("estimate", est)?;
    let truth_idx = sorted_indices("truth", truth)?;
    if truth.len() < est.len() {
        let swapped = nearest_in_time(truth, &truth_idx, est, &est_idx, max_dt_s);
        return Ok(swapped.into_iter().map(|(it, ie)| (ie, it)).collect());
    }
    Ok(nearest_in_time(est, &est_idx, truth, &truth_idx, max_dt_s))
}

/// For every pose of `from` (in time order), the index of the pose of `into`
/// nearest in time within `max_dt_s`.
fn nearest_in_time(
    from: &[(f64, Isometry3<f64>)],
    from_sorted: &[usize],
    into: &[(f64, Isometry3<f64>)],
    into_sorted: &[usize],
    max_dt_s: f64,
) -> Vec<(usize, usize)> {
    let into_t: Vec<f64> = into_sorted.iter().map(|&i| into[i].0).collect();
    let mut pairs = Vec::with_capacity(from.len());
    for &i_from in from_sorted {
        let t = from[i_from].0;
        // First time >= t; the nearest is it or its predecessor.
        let k = into_t.partition_point(|&x| x < t);
        let mut best: Option<(f64, usize)> = None;
        for cand in [k.wrapping_sub(1), k] {
            if let Some(&tt) = into_t.get(cand) {
                let dt = (tt - t).abs();
                if dt <= max_dt_s && best.is_none_or(|(b, _)| dt < b) {
                    best = Some((dt, cand));
                }
            }
        }
        if let Some((_, cand)) = best {
            pairs.push((i_from, into_sorted[cand]));
        }
    }
    pairs
}

/// ATE with SE(3) alignment (the paper's ATE_T / ATE_R).
///
/// # Errors
///
/// [`EvalError`] for invalid inputs or too few associated pairs.
///
/// # Examples
///
/// A rigidly moved copy of the truth has zero error after SE(3) alignment, and
/// a copy shifted by 1 m has ATE_T = 1 m without alignment:
///
/// ```
/// use limot::metrics::{AlignMode, ate, ate_with};
/// use nalgebra::{Isometry3, Translation3, UnitQuaternion};
///
/// let truth: Vec<(f64, Isometry3<f64>)> = (0..10)
///     .map(|i| {
///         let x = i as f64;
///         let pose = Isometry3::from_parts(
///             Translation3::new(x, 0.1 * x * x, 0.0),
///             UnitQuaternion::from_euler_angles(0.0, 0.0, 0.1 * x),
///         );
///         (0.1 * x, pose)
///     })
///     .collect();
/// let offset = Isometry3::from_parts(
///     Translation3::new(5.0, -2.0, 1.0),
///     UnitQuaternion::from_euler_angles(0.0, 0.0, 0.7),
/// );
/// let moved: Vec<_> = truth.iter().map(|(t, p)| (*t, offset * p)).collect();
/// let r = ate(&moved, &truth, 0.01)?;
/// assert_eq!(r.n, 10);
/// assert!(r.ate_t_rmse_m < 1e-9 && r.ate_r_rmse_rad < 1e-9);
///
/// let shift = Translation3::new(0.0, 0.0, 1.0);
/// let shifted: Vec<_> = truth.iter().map(|(t, p)| (*t, shift * p)).collect();
/// let r = ate_with(&shifted, &truth, 0.01, AlignMode::None)?;
/// assert!((r.ate_t_rmse_m - 1.0).abs() < 1e-12);
/// # Ok::<(), limot::metrics::EvalError>(())
/// ```
pub fn ate(
    est: &[(f64, Isometry3<f64>)],
    truth: &[(f64, Isometry3<f64>)],
    max_dt_s: f64,
) -> Result<AteResult, EvalError> {
    ate_with(est, truth, max_dt_s, AlignMode::Se3)
}

/// The positions of the associated pose pairs `(index in est, index in truth)`:
/// estimated and true, in pair order.
pub(crate) fn paired_positions(
    est: &[(f64, Isometry3<f64>)],
    truth: &[(f64, Isometry3<f64>)],
    pairs: &[(usize, usize)],
) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
    let p_est = pairs
        .iter()
        .map(|&(ie, _)| est[ie].1.translation.vector)
        .collect();
    let p_true = pairs
        .iter()
        .map(|&(_, it)| truth[it].1.translation.vector)
        .collect();
    (p_est, p_true)
}

/// ATE with a chosen alignment.
///
/// # Errors
///
/// [`EvalError`] for invalid inputs or too few associated pairs.
pub fn ate_with(
    est: &[(f64, Isometry3<f64>)],
    truth: &[(f64, Isometry3<f64>)],
    max_dt_s: f64,
    mode: AlignMode,
) -> Result<AteResult, EvalError> {
    let pairs = associate(est, truth, max_dt_s)?;
    let need = if mode == AlignMode::None { 1 } else { 2 };
    if pairs.len() < need {
        return Err(EvalError::TooFew {
            what: "ate: associated pose pairs",
            got: pairs.len(),
            need,
        });
    }
    let (p_est, p_true) = paired_positions(est, truth, &pairs);
    let alignment = match mode {
        AlignMode::None => Alignment::identity(),
        AlignMode::Se3 => umeyama(&p_est, &p_true, false)?,
        AlignMode::Sim3 => umeyama(&p_est, &p_true, true)?,
    };
    let directions = travel_directions(&p_true);
    let mut per_pose = Vec::with_capacity(pairs.len());
    let mut along_sq_sum = 0.0;
    for (k, &(ie, it)) in pairs.iter().enumerate() {
        let aligned = alignment.transform_pose(&est[ie].1);
        let true_pose = &truth[it].1;
        let error = true_pose.translation.vector - aligned.translation.vector;
        let e_r = aligned.rotation.angle_to(&true_pose.rotation);
        per_pose.push((est[ie].0, error.norm(), e_r));
        if let Some(d) = &directions {
            along_sq_sum += error.dot(&d[k]).powi(2);
        }
    }
    let t_errors: Vec<f64> = per_pose.iter().map(|e| e.1).collect();
    let r_errors: Vec<f64> = per_pose.iter().map(|e| e.2).collect();
    // Both lists are non-empty here.
    let t_stats = ErrorStats::of(&t_errors).ok_or(EvalError::Empty { what: "ate" })?;
    let r_stats = ErrorStats::of(&r_errors).ok_or(EvalError::Empty { what: "ate" })?;
    Ok(AteResult {
        ate_t_rmse_m: t_stats.rmse,
        ate_r_rmse_rad: r_stats.rmse,
        mean_m: t_stats.mean,
        median_m: t_stats.median,
        max_m: t_stats.max,
        along_rmse_m: directions.map(|_| (along_sq_sum / pairs.len() as f64).sqrt()),
        n: t_stats.n,
        alignment,
        per_pose,
    })
}

/// The truth moves at least this far between a pair's neighbours for its
/// direction of travel to be taken from them, m (above the centimetres of a
/// GNSS/INS truth's jitter at rest).
const TRAVEL_MIN_DISPLACEMENT_M: f64 = 0.1;

/// Unit direction of travel at each of `p_true` (positions in time order):
/// from the neighbouring positions (central difference, one-sided at the
/// ends); where the truth moved less than [`TRAVEL_MIN_DISPLACEMENT_M`] (at
/// rest) the direction of the nearest pose that moved, the last one before
/// or else the first one after (a vehicle stands facing the way it drove).
/// `None` when the truth never moves. Taken from positions, not from the
/// poses' axes, so it holds in any body frame convention (KITTI's camera
/// looks along z, a LiDAR along x).
pub fn travel_directions(p_true: &[Vector3<f64>]) -> Option<Vec<Vector3<f64>>> {
    let n = p_true.len();
    let moving: Vec<Option<Vector3<f64>>> = (0..n)
        .map(|k| {
            let step = p_true[(k + 1).min(n - 1)] - p_true[k.saturating_sub(1)];
            let length = step.norm();
            (length >= TRAVEL_MIN_DISPLACEMENT_M).then(|| step / length)
        })
        .collect();
    let first = moving.iter().flatten().next().copied()?;
    let mut last = first;
    Some(
        moving
            .into_iter()
            .map(|d| {
                if let Some(d) = d {
                    last = d;
                }
                last
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn circle(n: usize) -> Vec<(f64, Isometry3<f64>)> {
        (0..n)
            .map(|i| {
                let a = i as f64 * 0.1;
                let pose = Isometry3::from_parts(
                    Translation3::new(10.0 * a.cos(), 10.0 * a.sin(), 0.3 * a),
                    UnitQuaternion::from_euler_angles(0.0, 0.05 * a, a + 1.5),
                );
                (i as f64 * 0.1, pose)
            })
            .collect()
    }

    #[test]
    fn rigid_offset_is_removed() {
        let truth = circle(50);
        let offset = Isometry3::from_parts(
            Translation3::new(3.0, -1.0, 2.0),
            UnitQuaternion::from_euler_angles(0.2, -0.1, 0.7),
        );
        let est: Vec<_> = truth.iter().map(|(t, p)| (*t, offset * p)).collect();
        let r = ate(&est, &truth, 0.01).unwrap();
        assert_eq!(r.n, 50);
        assert!(r.ate_t_rmse_m < 1e-9, "{}", r.ate_t_rmse_m);
        assert!(r.ate_r_rmse_rad < 1e-9, "{}", r.ate_r_rmse_rad);
        let raw = ate_with(&est, &truth, 0.01, AlignMode::None).unwrap();
        assert!(raw.ate_t_rmse_m > 1.0);
    }

    #[test]
    fn hand_case_without_alignment() {
        // Two poses, est shifted by 3 m and 4 m along x, rotated 0.1 rad / 0.3 rad.
        let truth = vec![(0.0, Isometry3::identity()), (1.0, Isometry3::identity())];
        let est = vec![
            (
                0.0,
                Isometry3::from_parts(
                    Translation3::new(3.0, 0.0, 0.0),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, 0.1),
                ),
            ),
            (
                1.0,
                Isometry3::from_parts(
                    Translation3::new(0.0, 4.0, 0.0),
                    UnitQuaternion::from_euler_angles(0.3, 0.0, 0.0),
                ),
            ),
        ];
        let r = ate_with(&est, &truth, 0.0, AlignMode::None).unwrap();
        assert!((r.ate_t_rmse_m - 12.5f64.sqrt()).abs() < 1e-12);
        assert!((r.ate_r_rmse_rad - (0.05f64).sqrt()).abs() < 1e-12);
        assert_eq!(r.median_m, 3.5);
        assert_eq!(r.max_m, 4.0);
    }

    fn at(t_s: f64, x: f64, y: f64) -> (f64, Isometry3<f64>) {
        (t_s, Isometry3::translation(x, y, 0.0))
    }

    #[test]
    fn along_track_error_is_the_component_along_the_travel() {
        // The truth drives along +x at 10 m/s, then along +y.
        let truth: Vec<_> = (0..40)
            .map(|i| {
                let t = 0.1 * i as f64;
                if i < 20 {
                    at(t, t * 10.0, 0.0)
                } else {
                    at(t, 20.0, (t - 2.0) * 10.0)
                }
            })
            .collect();
        // An estimate that lags along the path: all of its error is along.
        let lagging: Vec<_> = truth
            .iter()
            .enumerate()
            .map(|(i, (t, p))| {
                let lag = 0.01 * i as f64;
                let back = if i < 20 { (-lag, 0.0) } else { (0.0, -lag) };
                at(*t, p.translation.x + back.0, p.translation.y + back.1)
            })
            .collect();
        let r = ate_with(&lagging, &truth, 0.01, AlignMode::None).unwrap();
        let along = r.along_rmse_m.unwrap();
        // the corner's pose takes the diagonal between its neighbours
        assert!(
            (along - r.ate_t_rmse_m).abs() < 0.01 * r.ate_t_rmse_m,
            "{along} {r:?}"
        );
        // One beside the path: none of it is along (the corner pose aside).
        let beside: Vec<_> = truth
            .iter()
            .enumerate()
            .map(|(i, (t, p))| {
                let side = if i < 20 { (0.0, 0.5) } else { (-0.5, 0.0) };
                at(*t, p.translation.x + side.0, p.translation.y + side.1)
            })
            .collect();
        let r = ate_with(&beside, &truth, 0.01, AlignMode::None).unwrap();
        assert!((r.ate_t_rmse_m - 0.5).abs() < 1e-12);
        assert!(r.along_rmse_m.unwrap() < 0.1, "{r:?}");
        let squares = r.along_rmse_m.unwrap().powi(2);
        assert!(squares <= r.ate_t_rmse_m.powi(2) + 1e-12);
    }

    #[test]
    fn travel_direction_at_rest_is_the_nearest_motions() {
        let p = |x: f64, y: f64| Vector3::new(x, y, 0.0);
        // stands, drives along +y, stands, drives along +x, stands
        let path = [
            p(0.0, 0.0),
            p(0.0, 0.0),
            p(0.0, 1.0),
            p(0.0, 2.0),
            p(0.0, 2.0),
            p(0.0, 2.0),
            p(0.0, 2.0),
            p(1.0, 2.0),
            p(2.0, 2.0),
            p(2.0, 2.0),
            p(2.0, 2.0),
        ];
        let d = travel_directions(&path).unwrap();
        let y = Vector3::y();
        let x = Vector3::x();
        for (k, expected) in [y, y, y, y, y, y, x, x, x, x, x].iter().enumerate() {
            assert!((d[k] - expected).norm() < 1e-12, "pose {k}: {:?}", d[k]);
        }
        // a truth that never moves (or only jitters) has no direction
        assert!(travel_directions(&[p(0.0, 0.0), p(0.01, 0.0), p(0.0, 0.02)]).is_none());
        assert!(travel_directions(&[p(0.0, 0.0)]).is_none());
    }

    #[test]
    fn association_picks_nearest_within_tolerance() {
        let p = Isometry3::identity();
        let truth: Vec<_> = (0..5).map(|i| (i as f64, p)).collect();
        let est = vec![(0.4, p), (0.6, p), (1.5, p), (5.5, p), (-0.05, p)];
        let pairs = associate(&est, &truth, 0.45).unwrap();
        // est sorted by time: -0.05 -> 0, 0.4 -> 0, 0.6 -> 1, 1.5 dropped (0.5 away), 5.5 dropped.
        assert_eq!(pairs, vec![(4, 0), (0, 0), (1, 1)]);
        // Dense estimate, sparse truth: each true pose takes its nearest estimate.
        let dense: Vec<_> = (0..45).map(|i| (i as f64 * 0.1, p)).collect();
        let pairs = associate(&dense, &truth, 0.01).unwrap();
        assert_eq!(pairs, vec![(0, 0), (10, 1), (20, 2), (30, 3), (40, 4)]);
        let sparse = &truth[..3];
        assert_eq!(associate(&dense, sparse, 0.01).unwrap().len(), 3);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let truth = circle(5);
        assert!(matches!(
            ate(&[], &truth, 0.1),
            Err(EvalError::Empty { .. })
        ));
        let mut est = truth.clone();
        est[3].0 = f64::NAN;
        assert!(matches!(
            ate(&est, &truth, 0.1),
            Err(EvalError::NotFinite { index: 3, .. })
        ));
        let late: Vec<_> = truth.iter().map(|(t, p)| (t + 100.0, *p)).collect();
        assert!(matches!(
            ate(&late, &truth, 0.1),
            Err(EvalError::TooFew { got: 0, .. })
        ));
        assert!(ate(&truth, &truth, -1.0).is_err());
    }
}
