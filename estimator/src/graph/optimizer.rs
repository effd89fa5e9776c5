//! Sparse nonlinear least squares on the factor graph: Levenberg–Marquardt
//! with Nielsen damping, robust kernels by IRLS, normal equations assembled
//! block by block and solved with faer's supernodal sparse Cholesky, the
//! variables laid out in a block-AMD elimination order (see
//! `SparseCholesky`).
//!
//! Conventions: the step `δ` is a stacked right perturbation of every
//! variable in [`VariableIndex`] order; `H = JᵀJ`, `g = Jᵀr` of the whitened,
//! reweighted residuals; the Gauss–Newton step solves `H·δ = -g`.

use super::elimination::{SolverWorkspace, SparseCholesky};
use super::factor::Factor;
use super::key::Key;
use super::linearization::{
    FactorPositions, KeyPositions, NormalEquations, cost_of_checked, linearize,
    linearize_normal_equations, total_cost,
};
use super::values::Values;
use super::variable_index::VariableIndex;
use nalgebra::DVector;
use std::borrow::Borrow;
use std::time::{Duration, Instant};

/// Why an optimization (or a linearization) failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolverError {
    /// A factor names a key that has no value.
    #[error("factor {factor} needs key {key}, which has no value")]
    MissingKey {
        /// Index of the factor.
        factor: usize,
        /// The key without a value.
        key: Key,
    },
    /// A factor's residual, Jacobians and noise model disagree in shape
    /// with each other or with the key's tangent.
    #[error(
        "factor {factor}: shapes disagree at key {key} (residual {residual_dim}, noise {noise_dim}, jacobian {jacobian_rows}×{jacobian_cols}, tangent {tangent_dim})"
    )]
    DimensionMismatch {
        /// Index of the factor.
        factor: usize,
        /// The key whose Jacobian disagrees.
        key: Key,
        /// Length of the residual.
        residual_dim: usize,
        /// Columns of the noise model's square-root information.
        noise_dim: usize,
        /// Rows of the Jacobian.
        jacobian_rows: usize,
        /// Columns of the Jacobian.
        jacobian_cols: usize,
        /// Tangent dimension of the key's variable.
        tangent_dim: usize,
    },
    /// A factor gave a non-finite residual, Jacobian or cost.
    #[error("factor {factor} (keys {keys}) gave a non-finite residual or Jacobian")]
    NonFinite {
        /// Index of the factor.
        factor: usize,
        /// Its keys, comma-separated.
        keys: String,
    },
    /// `H + λD` could not be factorized even at the largest damping.
    #[error("the normal equations are not positive definite even with damping {lambda:e}")]
    NotPositiveDefinite {
        /// The last damping tried.
        lambda: f64,
    },
    /// The sparse Cholesky's symbolic analysis or workspace failed.
    #[error("sparse factorization failed: {0}")]
    Factorization(String),
    /// A key asked for is not a variable of the problem.
    #[error("key {0} is not a variable of the problem")]
    UnknownKey(Key),
}

/// Levenberg–Marquardt settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverConfig {
    /// Linearizations at most, each followed by its step (0: none).
    pub max_iterations: usize,
    /// Initial damping `λ` (relative to `diag(H)`); 0 gives Gauss–Newton
    /// steps until a step fails to decrease the cost.
    pub initial_lambda: f64,
    /// Give up when `λ` exceeds this.
    pub max_lambda: f64,
    /// Converged when the relative cost decrease of an accepted step is below this.
    pub function_tolerance: f64,
    /// Converged when `max |g|` is below this.
    pub gradient_tolerance: f64,
    /// Converged when `max |δ|` is below this.
    pub step_tolerance: f64,
}

impl Default for SolverConfig {
    fn default() -> Self {
        SolverConfig {
            max_iterations: 50,
            initial_lambda: 1e-5,
            max_lambda: 1e16,
            function_tolerance: 1e-12,
            gradient_tolerance: 1e-12,
            step_tolerance: 1e-12,
        }
    }
}

/// What an optimization did.
#[derive(Debug, Clone, PartialEq)]
pub struct SolverReport {
    /// Linearizations (outer iterations) performed.
    pub iterations: usize,
    /// Cost at the initial values.
    pub initial_cost: f64,
    /// Cost at the returned values.
    pub final_cost: f64,
    /// A tolerance was met (rather than the iteration limit).
    pub converged: bool,
    /// Final damping.
    pub lambda: f64,
    /// Wall time of the optimization.
    pub duration: Duration,
}

/// A set of factors, owned; the solver's input.
#[derive(Debug, Default)]
pub struct FactorGraph {
    /// The factors, in the order they were added.
    pub factors: Vec<Box<dyn Factor>>,
}

impl FactorGraph {
    /// An empty graph.
    pub fn new() -> FactorGraph {
        FactorGraph::default()
    }

    /// Appends `factor`.
    pub fn add(&mut self, factor: Box<dyn Factor>) {
        self.factors.push(factor);
    }

    /// Number of factors.
    pub fn len(&self) -> usize {
        self.factors.len()
    }

    /// Whether the graph has no factor.
    pub fn is_empty(&self) -> bool {
        self.factors.is_empty()
    }

    /// Total cost at `values`.
    ///
    /// # Errors
    /// As [`total_cost`].
    pub fn cost(&self, values: &Values) -> Result<f64, SolverError> {
        total_cost(&self.factors, values)
    }

    /// Levenberg–Marquardt on every variable of `values` ([`optimize`]).
    ///
    /// # Errors
    /// As [`optimize`].
    pub fn optimize(
        &self,
        values: &mut Values,
        config: &SolverConfig,
    ) -> Result<SolverReport, SolverError> {
        optimize(&self.factors, values, config)
    }
}

/// Smallest diagonal scaling of the Marquardt damping, so variables without
/// curvature still get damped.
const MIN_DIAGONAL: f64 = 1e-6;
const MAX_DIAGONAL: f64 = 1e32;
/// Floor of a positive damping (below it the step is Gauss–Newton anyway).
const MIN_LAMBDA: f64 = 1e-15;

/// Levenberg–Marquardt on every variable of `values` (each must be reached
/// by a factor for a well-posed problem; unreached ones stay put under damping).
/// `values` is updated in place to the best values found.
///
/// # Errors
/// A factor key without a value, shapes that disagree, non-finite
/// residuals or Jacobians, or normal equations that stay indefinite up to
/// [`SolverConfig::max_lambda`] ([`SolverError`]).
pub fn optimize<F: Borrow<dyn Factor>>(
    factors: &[F],
    values: &mut Values,
    config: &SolverConfig,
) -> Result<SolverReport, SolverError> {
    optimize_with(factors, values, config, &mut SolverWorkspace::new())
}

/// [`optimize`] with a workspace kept by the caller: symbolic analyses of
/// block patterns it has seen before are reused.
///
/// # Errors
/// As [`optimize`].
pub fn optimize_with<F: Borrow<dyn Factor>>(
    factors: &[F],
    values: &mut Values,
    config: &SolverConfig,
    workspace: &mut SolverWorkspace,
) -> Result<SolverReport, SolverError> {
    let start = Instant::now();
    let index = VariableIndex::from_values(values);
    let cholesky = &mut workspace.0;
    let mut lambda = config.initial_lambda.max(0.0);
    let mut nu = 2.0;
    // The first linearization checks every key and records its position;
    // later ones (same keys) reuse them.
    let mut positions = FactorPositions::default();
    let mut normal = linearize(
        factors,
        values,
        &index,
        KeyPositions::Record(&mut positions),
    )?;
    let initial_cost = normal.cost;
    let mut cost = initial_cost;
    let mut iterations = 1;
    let mut converged = false;
    let mut relinearize = false;
    let mut inner_steps = 0usize;
    while config.max_iterations > 0 && inner_steps < 10 * config.max_iterations {
        inner_steps += 1;
        if relinearize {
            // `max_iterations` bounds the linearizations, each followed by
            // its step.
            if iterations >= config.max_iterations {
                break;
            }
            normal = linearize(factors, values, &index, KeyPositions::Cached(&positions))?;
            iterations += 1;
            relinearize = false;
        }
        if normal.gradient.amax() < config.gradient_tolerance {
            converged = true;
            break;
        }
        let diagonal = normal
            .hessian_diagonal()
            .map(|d| d.clamp(MIN_DIAGONAL, MAX_DIAGONAL));
        let damping = &diagonal * lambda;
        let rhs = -&normal.gradient;
        let Some(step) = cholesky.solve(&normal, &damping, &rhs)? else {
            // Not SPD at this damping: raise it and retry.
            lambda = if lambda == 0.0 { 1e-6 } else { lambda * nu };
            nu *= 2.0;
            if lambda > config.max_lambda {
                return Err(SolverError::NotPositiveDefinite { lambda });
            }
            continue;
        };
        if step.amax() < config.step_tolerance {
            converged = true;
            break;
        }
        let mut candidate = values.clone();
        index.retract(&mut candidate, step.as_slice());
        let new_cost = cost_of_checked(factors, &candidate);
        // Predicted decrease of the quadratic model: -(gᵀδ + ½δᵀHδ)
        // = ½δᵀ(λD·δ - g) since (H + λD)δ = -g.
        let predicted = 0.5 * step.dot(&(damping.component_mul(&step) - &normal.gradient));
        let accepted = match new_cost {
            Ok(c) if c.is_finite() && c < cost => Some(c),
            _ => None,
        };
        if let Some(new_cost) = accepted {
            let actual = cost - new_cost;
            let rho = if predicted > 0.0 {
                actual / predicted
            } else {
                1.0
            };
            *values = candidate;
            let relative = actual / cost.max(f64::MIN_POSITIVE);
            cost = new_cost;
            if lambda > 0.0 {
                // Nielsen's update, floored so λ never underflows to 0.
                lambda =
                    (lambda * (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0)).max(MIN_LAMBDA);
            }
            nu = 2.0;
            if relative < config.function_tolerance {
                converged = true;
                break;
            }
            relinearize = true;
        } else {
            lambda = if lambda == 0.0 { 1e-6 } else { lambda * nu };
            nu *= 2.0;
            if lambda > config.max_lambda {
                // No step decreases the cost, however short: a (numerical)
                // minimum that the tolerances were too tight to detect.
                converged = true;
                break;
            }
        }
    }
    Ok(SolverReport {
        iterations,
        initial_cost,
        final_cost: cost,
        converged,
        lambda,
        duration: start.elapsed(),
    })
}

/// One undamped Gauss–Newton step `δ = -H⁻¹g` at `values` via the sparse
/// Cholesky (tests compare it with a dense solve).
///
/// # Errors
/// As [`linearize_normal_equations`]; [`SolverError::NotPositiveDefinite`]
/// when `H` is singular.
pub fn gauss_newton_step<F: Borrow<dyn Factor>>(
    factors: &[F],
    values: &Values,
) -> Result<(NormalEquations, DVector<f64>), SolverError> {
    let index = VariableIndex::from_values(values);
    let normal = linearize_normal_equations(factors, values, &index)?;
    let zero = DVector::zeros(index.total_dim());
    let rhs = -&normal.gradient;
    let step = SparseCholesky::new()
        .solve(&normal, &zero, &rhs)?
        .ok_or(SolverError::NotPositiveDefinite { lambda: 0.0 })?;
    Ok((normal, step))
}
