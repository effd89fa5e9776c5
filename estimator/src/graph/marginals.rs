//! Marginals: the joint covariance of chosen variables, `H⁻¹` restricted to
//! their columns, by sparse Cholesky solves against unit vectors.

use super::elimination::SparseCholesky;
use super::factor::Factor;
use super::key::Key;
use super::linearization::linearize_normal_equations;
use super::optimizer::SolverError;
use super::values::Values;
use super::variable_index::VariableIndex;
use faer::Mat;
use nalgebra::{DMatrix, DVector};
use std::borrow::Borrow;

/// Marginal covariance (in the tangent spaces, right perturbation) of
/// `keys` jointly, `(H⁻¹)` restricted to their columns, with `H` the
/// Gauss–Newton Hessian of `factors` at `values`. Rows/columns follow `keys`.
pub fn marginal_covariance<F: Borrow<dyn Factor>>(
    factors: &[F],
    values: &Values,
    keys: &[Key],
) -> Result<DMatrix<f64>, SolverError> {
    let index = VariableIndex::from_values(values);
    let normal = linearize_normal_equations(factors, values, &index)?;
    let mut spans = Vec::with_capacity(keys.len());
    for key in keys {
        spans.push(index.span(key).ok_or(SolverError::UnknownKey(*key))?);
    }
    let m: usize = spans.iter().map(|s| s.1).sum();
    if m == 0 {
        return Ok(DMatrix::zeros(0, 0));
    }
    let n = index.total_dim();
    let zero = DVector::zeros(n);
    let mut cholesky = SparseCholesky::new();
    if !cholesky.factorize(&normal, &zero)? {
        return Err(SolverError::NotPositiveDefinite { lambda: 0.0 });
    }
    let mut rhs = Mat::<f64>::zeros(n, m);
    let mut col = 0;
    for &(o, d) in &spans {
        for i in 0..d {
            rhs[(o + i, col)] = 1.0;
            col += 1;
        }
    }
    cholesky.solve_in_place(rhs.as_mut());
    let mut cov = DMatrix::zeros(m, m);
    let mut row = 0;
    for &(o, d) in &spans {
        for i in 0..d {
            for c in 0..m {
                cov[(row, c)] = rhs[(o + i, c)];
            }
            row += 1;
        }
    }
    Ok(cov)
}
