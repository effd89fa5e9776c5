//! Marginalization by Schur complement (VINS-Mono / OKVIS style): the
//! factors touching the removed variables are linearized once, the removed
//! block is eliminated from their normal equations, and what remains is a
//! Gaussian prior on the connected kept variables, stored as a linear factor
//! around their linearization points. Factors are replaced, never dropped.

use super::factor::{Factor, JacobiansMut};
use super::key::Key;
use super::linearization::linearize_normal_equations;
use super::noise::NoiseModel;
use super::optimizer::SolverError;
use super::values::{Values, Variable};
use super::variable_index::VariableIndex;
use crate::lie;
use nalgebra::{DMatrix, DVector, DVectorView, DVectorViewMut, SymmetricEigen, Vector6};
use std::borrow::Borrow;
use std::collections::BTreeSet;

/// Why a marginalization failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MarginalizationError {
    /// A key to marginalize has no value.
    #[error("key {0} to marginalize has no value")]
    MissingKey(Key),
    /// Linearizing the factors of the removed keys failed.
    #[error("linearizing the marginalized factors failed: {0}")]
    Solver(#[from] SolverError),
    /// The marginal information came out non-finite.
    #[error("the marginal information matrix is not finite")]
    NonFinite,
}

/// Eigenvalue thresholds of the pseudo-inverses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarginalizationConfig {
    /// Eigenvalues below `threshold · λ_max` count as zero, in the removed
    /// block (its pseudo-inverse) and in the resulting prior (its rank).
    pub relative_eigenvalue_threshold: f64,
}

impl Default for MarginalizationConfig {
    fn default() -> Self {
        MarginalizationConfig {
            relative_eigenvalue_threshold: 1e-10,
        }
    }
}

/// `r = r_p + J_p·(x ⊖ x₀)` over the stacked kept keys, identity noise:
/// the cost `½‖r‖²` is the marginal information left by eliminated variables.
#[derive(Debug, Clone)]
pub struct MarginalPriorFactor {
    keys: Vec<Key>,
    /// Linearization point `x₀` of each key (same order as `keys`).
    linearization_points: Vec<Variable>,
    /// Column offset of each key in `jacobian`.
    offsets: Vec<usize>,
    /// `J_p = S^{1/2}·Vᵀ` (rank × total tangent dim).
    jacobian: DMatrix<f64>,
    /// `r_p = S^{-1/2}·Vᵀ·g*`.
    residual_at_linearization: DVector<f64>,
    noise: NoiseModel,
}

impl MarginalPriorFactor {
    /// The linearization point of every key.
    pub fn linearization_points(&self) -> impl Iterator<Item = (&Key, &Variable)> {
        self.keys.iter().zip(&self.linearization_points)
    }

    /// `J_p` (rows = rank of the prior).
    pub fn jacobian(&self) -> &DMatrix<f64> {
        &self.jacobian
    }

    /// `r_p`, the residual at the linearization point.
    pub fn residual_at_linearization(&self) -> &DVector<f64> {
        &self.residual_at_linearization
    }

    /// The information matrix `J_pᵀ·J_p` over the stacked keys.
    pub fn information(&self) -> DMatrix<f64> {
        self.jacobian.transpose() * &self.jacobian
    }

    /// `r_p + J_p·(x ⊖ x₀)` into `residual`, and, when `jacobians` is
    /// given, each key's block `J_p[:, key]·∂(x ⊖ x₀)/∂δ` (a key's local
    /// coordinates are at most 6-dimensional: no allocation).
    fn evaluate(
        &self,
        values: &Values,
        residual: &mut [f64],
        mut jacobians: Option<&mut JacobiansMut<'_>>,
    ) {
        let mut r = DVectorViewMut::from_slice(residual, self.jacobian.nrows());
        r.copy_from(&self.residual_at_linearization);
        for (i, key) in self.keys.iter().enumerate() {
            let x = values
                .get(key)
                .unwrap_or_else(|| panic!("no value for {key}"));
            let dim = x.dim();
            let mut local = [0.0; 6];
            x.local_into(&self.linearization_points[i], &mut local[..dim]);
            let columns = self.jacobian.columns(self.offsets[i], dim);
            r.gemv(
                1.0,
                &columns,
                &DVectorView::from_slice(&local[..dim], dim),
                1.0,
            );
            if let Some(jacobians) = jacobians.as_deref_mut() {
                match x {
                    Variable::Pose(_) => {
                        let d_local =
                            lie::se3_right_jacobian_inv(&Vector6::from_column_slice(&local));
                        jacobians.block(i).gemm(1.0, &columns, &d_local, 0.0);
                    }
                    _ => jacobians.set(i, &columns),
                }
            }
        }
    }
}

impl Factor for MarginalPriorFactor {
    fn keys(&self) -> &[Key] {
        &self.keys
    }

    fn residual_dim(&self) -> usize {
        self.jacobian.nrows()
    }

    fn linearize_into(
        &self,
        values: &Values,
        residual: &mut [f64],
        jacobians: &mut JacobiansMut<'_>,
    ) {
        self.evaluate(values, residual, Some(jacobians));
    }

    fn noise(&self) -> &NoiseModel {
        &self.noise
    }

    fn residual_into(&self, values: &Values, residual: &mut [f64]) {
        self.evaluate(values, residual, None);
    }
}

/// `(L, L⁻¹)` with `sym(h) = L·Lᵀ` when every eigenvalue of `sym(h)`
/// provably exceeds `relative_threshold · max(λ_max, scale)`: then no mode
/// is below the eigenvalue threshold, and the inverse and a square root
/// follow from the Cholesky factor at a fraction of an eigendecomposition's
/// cost. The proof: `λ_min = 1/‖(LLᵀ)⁻¹‖₂ ≥ 1/‖L⁻¹‖²_F` and `λ_max ≤ trace`.
/// `None` (not positive definite, or not provably so conditioned) sends the
/// caller to the eigendecomposition.
fn well_conditioned_cholesky(
    h: &DMatrix<f64>,
    relative_threshold: f64,
    scale: f64,
) -> Option<(DMatrix<f64>, DMatrix<f64>)> {
    let n = h.nrows();
    let sym = (h + h.transpose()) * 0.5;
    let trace = sym.trace();
    let l = sym.cholesky()?.unpack();
    let l_inv = l.solve_lower_triangular(&DMatrix::identity(n, n))?;
    let lambda_min_bound = 1.0 / l_inv.norm_squared();
    let certain = lambda_min_bound.is_finite()
        && lambda_min_bound > relative_threshold * trace.max(scale)
        && l_inv.iter().all(|v| v.is_finite());
    certain.then_some((l, l_inv))
}

/// Symmetric pseudo-inverse with a relative eigenvalue threshold.
fn pseudo_inverse(h: &DMatrix<f64>, relative_threshold: f64) -> DMatrix<f64> {
    let n = h.nrows();
    if n == 0 {
        return DMatrix::zeros(0, 0);
    }
    if let Some((_, l_inv)) = well_conditioned_cholesky(h, relative_threshold, 0.0) {
        return l_inv.transpose() * l_inv;
    }
    let sym = (h + h.transpose()) * 0.5;
    let eig = SymmetricEigen::new(sym);
    let max = eig.eigenvalues.amax();
    let threshold = relative_threshold * max;
    let inv = eig.eigenvalues.map(|s| {
        if s > threshold && s > 0.0 {
            1.0 / s
        } else {
            0.0
        }
    });
    &eig.eigenvectors * DMatrix::from_diagonal(&inv) * eig.eigenvectors.transpose()
}

/// `(J_p, r_p)` with `J_pᵀJ_p = H*` and `J_pᵀr_p = g*` over the modes of
/// `H*` above the eigenvalue threshold (relative to `H*`'s largest and,
/// since when the removed variables absorb everything `H*` is pure
/// cancellation round-off and its own largest eigenvalue is no scale at
/// all, to `H_kk`'s largest diagonal). Full rank with certainty: `J_p = Lᵀ`,
/// `r_p = L⁻¹g*` (the eigen form `S^½Vᵀ` up to a rotation of the rows, the
/// same prior); otherwise `J_p = S^½Vᵀ`, `r_p = S^-½Vᵀg*` on the kept modes.
fn prior_square_root(
    h_star: &DMatrix<f64>,
    g_star: &DVector<f64>,
    h_kk: &DMatrix<f64>,
    config: &MarginalizationConfig,
) -> (DMatrix<f64>, DVector<f64>) {
    let n = h_star.nrows();
    let kk_scale = h_kk.diagonal().amax();
    if let Some((l, l_inv)) =
        well_conditioned_cholesky(h_star, config.relative_eigenvalue_threshold, kk_scale)
    {
        return (l.transpose(), l_inv * g_star);
    }
    let eig = SymmetricEigen::new((h_star + h_star.transpose()) * 0.5);
    let scale = eig.eigenvalues.amax().max(kk_scale);
    let threshold = config.relative_eigenvalue_threshold * scale;
    let kept_modes: Vec<usize> = (0..n)
        .filter(|&i| eig.eigenvalues[i] > threshold && eig.eigenvalues[i] > 0.0)
        .collect();
    let rank = kept_modes.len();
    let mut jacobian = DMatrix::zeros(rank, n);
    let mut residual = DVector::zeros(rank);
    for (row, &mode) in kept_modes.iter().enumerate() {
        let s = eig.eigenvalues[mode];
        let v = eig.eigenvectors.column(mode);
        jacobian.row_mut(row).copy_from(&(v.transpose() * s.sqrt()));
        residual[row] = v.dot(g_star) / s.sqrt();
    }
    (jacobian, residual)
}

/// Eliminates `removed` from the normal equations of `factors` (every
/// factor touching a removed key, plus any earlier marginal prior that
/// should be folded in) linearized at `values`, and returns the prior on the
/// remaining keys of those factors, or `None` when no key remains (or the
/// remaining information is zero).
///
/// # Errors
/// A removed key without a value, a failed linearization, or a
/// non-finite marginal information ([`MarginalizationError`]).
pub fn marginalize<F: Borrow<dyn Factor>>(
    factors: &[F],
    values: &Values,
    removed: &[Key],
    config: &MarginalizationConfig,
) -> Result<Option<MarginalPriorFactor>, MarginalizationError> {
    let removed_set: BTreeSet<Key> = removed.iter().copied().collect();
    for key in &removed_set {
        if !values.contains(key) {
            return Err(MarginalizationError::MissingKey(*key));
        }
    }
    let kept: BTreeSet<Key> = factors
        .iter()
        .flat_map(|f| f.borrow().keys().iter().copied())
        .filter(|k| !removed_set.contains(k))
        .collect();
    if kept.is_empty() {
        return Ok(None);
    }
    // Removed keys first, then kept ones: H = [[H_rr, H_rk], [H_kr, H_kk]].
    let order: Vec<Key> = removed_set.iter().chain(kept.iter()).copied().collect();
    let index = VariableIndex::from_keys(&order, values)?;
    let normal = linearize_normal_equations(factors, values, &index)?;
    let h = normal.dense_hessian();
    let g = &normal.gradient;
    let m: usize = removed_set
        .iter()
        .map(|k| index.span(k).map(|s| s.1).unwrap_or(0))
        .sum();
    let n = index.total_dim() - m;
    let h_rr = h.view((0, 0), (m, m)).into_owned();
    let h_kr = h.view((m, 0), (n, m)).into_owned();
    let h_kk = h.view((m, m), (n, n)).into_owned();
    let h_rr_inv = pseudo_inverse(&h_rr, config.relative_eigenvalue_threshold);
    let h_kr_rr_inv = &h_kr * h_rr_inv;
    let h_star = &h_kk - &h_kr_rr_inv * h_kr.transpose();
    let g_star = g.rows(m, n) - &h_kr_rr_inv * g.rows(0, m);
    if h_star.iter().chain(g_star.iter()).any(|v| !v.is_finite()) {
        return Err(MarginalizationError::NonFinite);
    }
    let (jacobian, residual) = prior_square_root(&h_star, &g_star, &h_kk, config);
    if jacobian.nrows() == 0 {
        return Ok(None);
    }
    let rank = jacobian.nrows();
    let keys: Vec<Key> = kept.into_iter().collect();
    let mut offsets = Vec::with_capacity(keys.len());
    let mut linearization_points = Vec::with_capacity(keys.len());
    for key in &keys {
        // Unwraps are safe: every kept key is in `index`, built from `values`.
        let (offset, _) = index.span(key).ok_or(SolverError::UnknownKey(*key))?;
        offsets.push(offset - m);
        linearization_points.push(*values.get(key).ok_or(SolverError::UnknownKey(*key))?);
    }
    Ok(Some(MarginalPriorFactor {
        keys,
        linearization_points,
        offsets,
        jacobian,
        residual_at_linearization: residual,
        noise: NoiseModel {
            sqrt_information: DMatrix::identity(rank, rank),
            robust: None,
        },
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::between_factor::BetweenFactor;
    use crate::graph::check_factor_jacobians;
    use crate::graph::prior_factor::PriorFactor;
    use nalgebra::Vector3;

    fn pose(a: f64) -> Variable {
        Variable::Pose(lie::se3_exp(&Vector6::new(
            a,
            -0.5 * a,
            0.2,
            0.1 * a,
            -0.3,
            0.2 * a,
        )))
    }

    #[test]
    fn prior_jacobians_match_finite_differences_away_from_linearization_point() {
        let mut values = Values::new();
        for k in 0..3 {
            values.insert(Key::EgoPose(k), pose(k as f64));
        }
        values.insert(
            Key::EgoVelocity(1),
            Variable::Vector3(Vector3::new(1.0, 2.0, 3.0)),
        );
        let noise = NoiseModel::diagonal_sigmas(&[0.1; 6]);
        let factors: Vec<Box<dyn Factor>> = vec![
            Box::new(PriorFactor::new(Key::EgoPose(0), pose(0.1), noise.clone())),
            Box::new(BetweenFactor::new(
                Key::EgoPose(0),
                Key::EgoPose(1),
                lie::se3_exp(&Vector6::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.1)),
                noise.clone(),
            )),
            Box::new(BetweenFactor::new(
                Key::EgoPose(0),
                Key::EgoPose(2),
                lie::se3_exp(&Vector6::new(2.0, 0.0, 0.0, 0.0, 0.0, 0.2)),
                noise.clone(),
            )),
            Box::new(PriorFactor::new(
                Key::EgoVelocity(1),
                Variable::Vector3(Vector3::zeros()),
                NoiseModel::diagonal_sigmas(&[1.0; 3]),
            )),
        ];
        let prior = marginalize(
            &factors[..3],
            &values,
            &[Key::EgoPose(0)],
            &MarginalizationConfig::default(),
        )
        .unwrap()
        .unwrap();
        assert_eq!(prior.keys(), &[Key::EgoPose(1), Key::EgoPose(2)]);
        assert_eq!(prior.residual_at_linearization().len(), 12);
        // Moved away from x₀, so the J_r⁻¹ terms matter.
        values.retract_key(&Key::EgoPose(1), &[0.1, -0.2, 0.3, 0.2, -0.1, 0.3]);
        values.retract_key(&Key::EgoPose(2), &[-0.3, 0.1, 0.2, -0.2, 0.3, 0.1]);
        assert!(check_factor_jacobians(&prior, &values, 1e-6) < 1e-6);
    }
}

#[cfg(test)]
mod rank_tests {
    use super::*;
    use nalgebra::Vector3;

    /// `r = A·x - b` on 3-vectors.
    #[derive(Debug)]
    struct Linear {
        keys: Vec<Key>,
        a: Vec<DMatrix<f64>>,
        noise: NoiseModel,
    }

    impl Factor for Linear {
        fn keys(&self) -> &[Key] {
            &self.keys
        }

        fn residual_dim(&self) -> usize {
            self.a[0].nrows()
        }
        fn linearize_into(
            &self,
            values: &Values,
            residual: &mut [f64],
            jacobians: &mut JacobiansMut<'_>,
        ) {
            self.residual_into(values, residual);
            for (i, a) in self.a.iter().enumerate() {
                jacobians.set(i, a);
            }
        }
        fn residual_into(&self, values: &Values, residual: &mut [f64]) {
            let mut r = DVector::from_element(self.a[0].nrows(), -1.0);
            for (key, a) in self.keys.iter().zip(&self.a) {
                r += a * DVector::from_column_slice(values.vector3(key).as_slice());
            }
            residual.copy_from_slice(r.as_slice());
        }
        fn noise(&self) -> &NoiseModel {
            &self.noise
        }
    }

    fn values() -> Values {
        let mut values = Values::new();
        values.insert(
            Key::EgoVelocity(0),
            Variable::Vector3(Vector3::new(1.0, 2.0, 3.0)),
        );
        values.insert(
            Key::EgoVelocity(1),
            Variable::Vector3(Vector3::new(-1.0, 0.5, 2.0)),
        );
        values
    }

    #[test]
    fn unobservable_removed_variable_leaves_no_information() {
        // One scalar measurement couples x0 and x1; x0 has two free
        // directions, so H_rr is singular and x0 can absorb the measurement
        // entirely: the marginal on x1 must carry no information.
        let factor = Linear {
            keys: vec![Key::EgoVelocity(0), Key::EgoVelocity(1)],
            a: vec![
                DMatrix::from_row_slice(1, 3, &[1.0, 2.0, -1.0]),
                DMatrix::from_row_slice(1, 3, &[0.5, -1.0, 3.0]),
            ],
            noise: NoiseModel::diagonal_sigmas(&[0.1]),
        };
        let factors: Vec<&dyn Factor> = vec![&factor];
        let prior = marginalize(
            &factors,
            &values(),
            &[Key::EgoVelocity(0)],
            &MarginalizationConfig::default(),
        )
        .unwrap();
        assert!(prior.is_none(), "{prior:?}");
    }

    #[test]
    fn prior_reproduces_the_schur_complement_at_the_linearization_point() {
        let a0 = DMatrix::from_row_slice(3, 3, &[2.0, 0.1, 0.0, 0.3, 1.0, 0.2, 0.0, -0.4, 1.5]);
        let a1 = DMatrix::from_row_slice(3, 3, &[1.0, 0.0, 0.5, 0.0, 1.0, 0.0, -0.2, 0.3, 1.0]);
        let coupling = Linear {
            keys: vec![Key::EgoVelocity(0), Key::EgoVelocity(1)],
            a: vec![a0.clone(), a1.clone()],
            noise: NoiseModel::diagonal_sigmas(&[0.5, 1.0, 2.0]),
        };
        let unary = Linear {
            keys: vec![Key::EgoVelocity(0)],
            a: vec![DMatrix::identity(3, 3)],
            noise: NoiseModel::diagonal_sigmas(&[1.0; 3]),
        };
        let factors: Vec<&dyn Factor> = vec![&coupling, &unary];
        let values = values();
        let prior = marginalize(
            &factors,
            &values,
            &[Key::EgoVelocity(0)],
            &MarginalizationConfig::default(),
        )
        .unwrap()
        .unwrap();
        // Dense reference: H and g of the stacked whitened system.
        let l = DMatrix::from_diagonal(&DVector::from_column_slice(&[2.0, 1.0, 0.5]));
        let x0 = DVector::from_column_slice(&[1.0, 2.0, 3.0]);
        let x1 = DVector::from_column_slice(&[-1.0, 0.5, 2.0]);
        let r_c = &l * (&a0 * &x0 + &a1 * &x1 - DVector::from_element(3, 1.0));
        let r_u = &x0 - DVector::from_element(3, 1.0);
        let (j0, j1) = (&l * &a0, &l * &a1);
        let h00 = j0.transpose() * &j0 + DMatrix::identity(3, 3);
        let h10 = j1.transpose() * &j0;
        let h11 = j1.transpose() * &j1;
        let g0 = j0.transpose() * &r_c + r_u;
        let g1 = j1.transpose() * &r_c;
        let h00_inv = h00.try_inverse().unwrap();
        let h_star = &h11 - &h10 * &h00_inv * h10.transpose();
        let g_star = &g1 - &h10 * &h00_inv * &g0;
        let lin = crate::graph::Linearization::of(&prior, &values);
        assert!((prior.information() - &h_star).amax() < 1e-9);
        assert!((lin.jacobians[0].transpose() * &lin.residual - &g_star).amax() < 1e-9);
    }

    /// A symmetric matrix `V·diag(eigenvalues)·Vᵀ` with a fixed, well-mixed
    /// orthogonal `V` (QR of a deterministic matrix).
    fn with_eigenvalues(eigenvalues: &[f64]) -> DMatrix<f64> {
        let n = eigenvalues.len();
        let a = DMatrix::from_fn(n, n, |r, c| ((r * 7 + c * 3 + 1) as f64).sin());
        let q = a.qr().q();
        &q * DMatrix::from_diagonal(&DVector::from_column_slice(eigenvalues)) * q.transpose()
    }

    /// The eigen-based square root, for comparison with the fast path.
    fn eigen_square_root(h: &DMatrix<f64>, g: &DVector<f64>) -> (DMatrix<f64>, DVector<f64>) {
        let eig = SymmetricEigen::new(h.clone());
        let max = eig.eigenvalues.amax();
        let modes: Vec<usize> = (0..h.nrows())
            .filter(|&i| eig.eigenvalues[i] > 1e-10 * max)
            .collect();
        let j = DMatrix::from_fn(modes.len(), h.nrows(), |r, c| {
            eig.eigenvectors[(c, modes[r])] * eig.eigenvalues[modes[r]].sqrt()
        });
        let res = DVector::from_fn(modes.len(), |r, _| {
            eig.eigenvectors.column(modes[r]).dot(g) / eig.eigenvalues[modes[r]].sqrt()
        });
        (j, res)
    }

    #[test]
    fn cholesky_square_root_is_the_eigen_prior_up_to_a_rotation() {
        let config = MarginalizationConfig::default();
        let g = DVector::from_fn(6, |i, _| 0.3 * i as f64 - 0.7);
        for spread in [1.0, 1e3, 1e6] {
            let h = with_eigenvalues(&[spread, 2.0, 3.0, 5.0, 7.0, 11.0]);
            let kk = h.clone();
            assert!(well_conditioned_cholesky(&h, 1e-10, 0.0).is_some());
            let (j, r) = prior_square_root(&h, &g, &kk, &config);
            let (je, re) = eigen_square_root(&h, &g);
            assert_eq!(j.nrows(), 6);
            let scale = h.amax();
            assert!((j.transpose() * &j - &h).amax() < 1e-12 * scale);
            assert!((j.transpose() * &r - &g).amax() < 1e-10);
            // Same information, gradient and constant cost as the eigen form.
            assert!((j.transpose() * &j - je.transpose() * &je).amax() < 1e-9 * scale);
            assert!((r.norm_squared() - re.norm_squared()).abs() < 1e-9 * re.norm_squared());
            let inverse = pseudo_inverse(&h, 1e-10);
            assert!((&inverse * &h - DMatrix::identity(6, 6)).amax() < 1e-8);
        }
    }

    #[test]
    fn rank_deficient_matrices_take_the_eigen_path() {
        let config = MarginalizationConfig::default();
        let g = DVector::from_fn(6, |i, _| 0.3 * i as f64 - 0.7);
        // Two modes at round-off level: below the threshold, dropped.
        let h = with_eigenvalues(&[1e-14, -1e-15, 3.0, 5.0, 7.0, 11.0]);
        assert!(well_conditioned_cholesky(&h, 1e-10, 0.0).is_none());
        let (j, r) = prior_square_root(&h, &g, &h, &config);
        assert_eq!(j.nrows(), 4);
        assert_eq!(r.len(), 4);
        assert!((j.transpose() * &j - &h).amax() < 1e-9);
        // The pseudo-inverse inverts the kept modes and zeroes the others.
        let pinv = pseudo_inverse(&h, 1e-10);
        assert!((&h * &pinv * &h - &h).amax() < 1e-9);
        assert!(pinv.amax() < 1.0);
        // Positive definite but past the threshold: not certain, eigen path.
        let ill = with_eigenvalues(&[1e-12, 1.0, 3.0, 5.0, 7.0, 11.0]);
        assert!(well_conditioned_cholesky(&ill, 1e-10, 0.0).is_none());
        let (j, _) = prior_square_root(&ill, &g, &ill, &config);
        assert_eq!(j.nrows(), 5);
    }
}
