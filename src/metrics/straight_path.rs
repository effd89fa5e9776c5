//! Completing an alignment on straight and static paths.
//!
//! Straight paths: positions on (nearly) a line do not determine the rotation
//! of the alignment about that line, and Umeyama then returns a numerically
//! arbitrary roll (docs/metrics.md gives an example). When the second eigenvalue of the
//! associated estimate positions' scatter is below [`STRAIGHT_PATH_RATIO`]
//! times the first, the roll about the path is taken from the orientations
//! instead: `θ = mean_i ⟨Log(R_true,i · (R·R_est,i)ᵀ), a⟩` about the aligned
//! path direction `a`, and the translation is re-solved. When all positions
//! coincide or spread by less than 10 cm rms ([`STATIC_SCATTER_M2`]: a
//! standing ego), the whole rotation is the chordal mean of
//! `R_true,i · R_est,iᵀ`. Both are exact for a rigidly moved copy of the truth;
//! evo keeps the arbitrary roll in these cases.

use super::align::Alignment;
use super::ate::paired_positions;
use nalgebra::{Isometry3, Matrix3, Rotation3, UnitQuaternion, Vector3};

/// Scatter-eigenvalue ratio λ₂/λ₁ of the estimate positions below which the
/// path counts as straight (lateral spread under 1 % of the along-path spread)
/// and the alignment's roll about it is taken from the orientations.
pub const STRAIGHT_PATH_RATIO: f64 = 1e-4;

/// Largest position scatter eigenvalue (m², the variance along the path)
/// below which the trajectory counts as standing still: positions that
/// spread by less than 10 cm rms (a standing ego's estimate jitters by
/// millimetres) leave the rotation to their noise, so it comes from the
/// orientations.
pub const STATIC_SCATTER_M2: f64 = 0.01;

/// Whether the Umeyama rotation was completed from orientations (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AlignmentFix {
    /// Positions determine the rotation (or no alignment was asked for).
    None,
    /// Straight path: roll about it from the orientations.
    RollFromOrientations,
    /// All positions coincide: rotation from the orientations.
    RotationFromOrientations,
}

/// The rotation about the unit axis `axis` that best takes `residuals` (world-
/// frame rotation errors) to the identity, for residuals that are mostly
/// about that axis: the mean of their rotation vectors projected on it.
fn mean_roll_about(axis: &Vector3<f64>, residuals: &[UnitQuaternion<f64>]) -> Rotation3<f64> {
    let n = residuals.len().max(1) as f64;
    let theta = residuals
        .iter()
        .map(|q| q.scaled_axis().dot(axis))
        .sum::<f64>()
        / n;
    Rotation3::from_scaled_axis(axis * theta)
}

/// Chordal L2 mean of rotations: the rotation nearest to their summed matrices.
fn chordal_mean(rotations: &[UnitQuaternion<f64>]) -> Option<Rotation3<f64>> {
    let sum: Matrix3<f64> = rotations
        .iter()
        .map(|q| q.to_rotation_matrix().into_inner())
        .sum();
    let svd = sum.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut s = Matrix3::identity();
    if (u * v_t).determinant() < 0.0 {
        s[(2, 2)] = -1.0;
    }
    Some(Rotation3::from_matrix_unchecked(u * s * v_t))
}

/// Completes an alignment whose rotation the positions leave (partly) free;
/// `None` when the positions determine it.
pub fn complete_alignment(
    est: &[(f64, Isometry3<f64>)],
    truth: &[(f64, Isometry3<f64>)],
    pairs: &[(usize, usize)],
    alignment: &Alignment,
) -> Option<(Alignment, AlignmentFix)> {
    let n = pairs.len() as f64;
    let (p_est, p_true) = paired_positions(est, truth, pairs);
    let mean_est = p_est.iter().sum::<Vector3<f64>>() / n;
    let mean_true = p_true.iter().sum::<Vector3<f64>>() / n;
    let scatter: Matrix3<f64> = p_est
        .iter()
        .map(|p| (p - mean_est) * (p - mean_est).transpose())
        .sum::<Matrix3<f64>>()
        / n;
    let eig = scatter.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let (l1, l2) = (eig.eigenvalues[order[0]], eig.eigenvalues[order[1]]);
    let residuals = |rotation: &Rotation3<f64>| -> Vec<UnitQuaternion<f64>> {
        let q = UnitQuaternion::from_rotation_matrix(rotation);
        pairs
            .iter()
            .map(|&(ie, it)| truth[it].1.rotation * (q * est[ie].1.rotation).inverse())
            .collect()
    };
    let (rotation, fix) = if l1 <= STATIC_SCATTER_M2 {
        let relative: Vec<UnitQuaternion<f64>> = residuals(&Rotation3::identity());
        (
            chordal_mean(&relative)?,
            AlignmentFix::RotationFromOrientations,
        )
    } else if l2 < STRAIGHT_PATH_RATIO * l1 {
        let axis_est: Vector3<f64> = eig.eigenvectors.column(order[0]).into_owned();
        let axis = alignment.rotation * axis_est;
        let roll = mean_roll_about(&axis, &residuals(&alignment.rotation));
        (
            roll * alignment.rotation,
            AlignmentFix::RollFromOrientations,
        )
    } else {
        return None;
    };
    let translation = mean_true - alignment.scale * (rotation * mean_est);
    Some((
        Alignment {
            rotation,
            translation,
            scale: alignment.scale,
            degenerate: alignment.degenerate,
        },
        fix,
    ))
}
