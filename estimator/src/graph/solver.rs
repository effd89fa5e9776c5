//! Sparse nonlinear least squares on the factor graph: Levenberg–Marquardt
//! with Nielsen damping, robust kernels by IRLS, normal equations assembled
//! block by block and solved with faer's sparse Cholesky (AMD ordering).
//!
//! Conventions: the step `δ` is a stacked right perturbation of every
//! variable in [`VariableIndex`] order; `H = JᵀJ`, `g = Jᵀr` of the whitened,
//! reweighted residuals; the Gauss–Newton step solves `H·δ = -g`.

use super::factor::Factor;
use super::key::Key;
use super::values::Values;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat};
use faer::{Mat, Side};
use nalgebra::{DMatrix, DVector};
use std::borrow::Borrow;
use std::collections::{BTreeMap, HashMap};
use std::time::{Duration, Instant};

/// Why an optimization (or a linearization) failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolverError {
    #[error("factor {factor} needs key {key}, which has no value")]
    MissingKey { factor: usize, key: Key },
    #[error(
        "factor {factor}: shapes disagree at key {key} (residual {residual_dim}, noise {noise_dim}, jacobian {jacobian_rows}×{jacobian_cols}, tangent {tangent_dim})"
    )]
    DimensionMismatch {
        factor: usize,
        key: Key,
        residual_dim: usize,
        noise_dim: usize,
        jacobian_rows: usize,
        jacobian_cols: usize,
        tangent_dim: usize,
    },
    #[error("factor {factor} (keys {keys}) gave a non-finite residual or Jacobian")]
    NonFinite { factor: usize, keys: String },
    #[error("the normal equations are not positive definite even with damping {lambda:e}")]
    NotPositiveDefinite { lambda: f64 },
    #[error("sparse factorization failed: {0}")]
    Factorization(String),
    #[error("key {0} is not a variable of the problem")]
    UnknownKey(Key),
}

/// Levenberg–Marquardt settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverConfig {
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
    pub initial_cost: f64,
    pub final_cost: f64,
    pub converged: bool,
    /// Final damping.
    pub lambda: f64,
    pub duration: Duration,
}

/// Column layout of the stacked tangent vector: key → (offset, dim).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VariableIndex {
    keys: Vec<Key>,
    offsets: Vec<usize>,
    dims: Vec<usize>,
    position: BTreeMap<Key, usize>,
    total_dim: usize,
}

impl VariableIndex {
    /// Every variable of `values`, in key order.
    pub fn from_values(values: &Values) -> VariableIndex {
        let mut index = VariableIndex::default();
        for (key, value) in values.iter() {
            index.push(*key, value.dim());
        }
        index
    }

    /// The given keys in the given order (duplicates skipped).
    pub fn from_keys(keys: &[Key], values: &Values) -> Result<VariableIndex, SolverError> {
        let mut index = VariableIndex::default();
        for key in keys {
            let value = values.get(key).ok_or(SolverError::UnknownKey(*key))?;
            if !index.position.contains_key(key) {
                index.push(*key, value.dim());
            }
        }
        Ok(index)
    }

    fn push(&mut self, key: Key, dim: usize) {
        self.position.insert(key, self.keys.len());
        self.keys.push(key);
        self.offsets.push(self.total_dim);
        self.dims.push(dim);
        self.total_dim += dim;
    }

    pub fn keys(&self) -> &[Key] {
        &self.keys
    }

    pub fn len(&self) -> usize {
        self.keys.len()
    }

    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// Position of `key` in the ordering.
    pub fn position(&self, key: &Key) -> Option<usize> {
        self.position.get(key).copied()
    }

    /// `(column offset, tangent dim)` of `key`.
    pub fn span(&self, key: &Key) -> Option<(usize, usize)> {
        self.position(key).map(|p| (self.offsets[p], self.dims[p]))
    }

    pub fn total_dim(&self) -> usize {
        self.total_dim
    }

    /// `values ⊕ δ` for every key of the index.
    pub fn retract(&self, values: &mut Values, delta: &[f64]) {
        for (p, key) in self.keys.iter().enumerate() {
            let o = self.offsets[p];
            values.retract_key(key, &delta[o..o + self.dims[p]]);
        }
    }
}

/// A set of factors, owned; the solver's input.
#[derive(Debug, Default)]
pub struct FactorGraph {
    pub factors: Vec<Box<dyn Factor>>,
}

impl FactorGraph {
    pub fn new() -> FactorGraph {
        FactorGraph::default()
    }

    pub fn add(&mut self, factor: Box<dyn Factor>) {
        self.factors.push(factor);
    }

    pub fn len(&self) -> usize {
        self.factors.len()
    }

    pub fn is_empty(&self) -> bool {
        self.factors.is_empty()
    }

    /// Total cost at `values`.
    pub fn cost(&self, values: &Values) -> Result<f64, SolverError> {
        total_cost(&self.factors, values)
    }

    pub fn optimize(
        &self,
        values: &mut Values,
        config: &SolverConfig,
    ) -> Result<SolverReport, SolverError> {
        optimize(&self.factors, values, config)
    }
}

/// The normal equations `H·δ = -g` of a set of factors, kept as dense blocks
/// per pair of variables (lower triangle: row position ≥ column position).
#[derive(Debug, Clone)]
pub struct NormalEquations {
    pub index: VariableIndex,
    /// `(row position, col position)` → block, for row ≥ col.
    blocks: HashMap<(usize, usize), DMatrix<f64>>,
    /// `Jᵀr` over the whole tangent vector.
    pub gradient: DVector<f64>,
    /// Total (robust) cost at the linearization point.
    pub cost: f64,
}

impl NormalEquations {
    /// The full symmetric `H` as a dense matrix (tests, marginalization).
    pub fn dense_hessian(&self) -> DMatrix<f64> {
        let n = self.index.total_dim();
        let mut h = DMatrix::zeros(n, n);
        for (&(pr, pc), block) in &self.blocks {
            let (ro, rd) = (self.index.offsets[pr], self.index.dims[pr]);
            let (co, cd) = (self.index.offsets[pc], self.index.dims[pc]);
            h.view_mut((ro, co), (rd, cd)).copy_from(block);
            if pr != pc {
                h.view_mut((co, ro), (cd, rd)).copy_from(&block.transpose());
            }
        }
        h
    }

    /// Number of stored (lower-triangle) blocks; grows linearly with the
    /// factors for a sparse graph.
    pub fn block_count(&self) -> usize {
        self.blocks.len()
    }

    /// Diagonal of `H`.
    pub fn hessian_diagonal(&self) -> DVector<f64> {
        let mut d = DVector::zeros(self.index.total_dim());
        for p in 0..self.index.len() {
            let o = self.index.offsets[p];
            if let Some(block) = self.blocks.get(&(p, p)) {
                for i in 0..self.index.dims[p] {
                    d[o + i] = block[(i, i)];
                }
            }
        }
        d
    }

    /// The CSC pattern of the lower triangle of `H` (see [`BlockPattern`]).
    pub fn pattern(&self) -> BlockPattern {
        BlockPattern::new(self)
    }

    /// Lower triangle of `H + diag(damping)` as a faer CSC matrix. Every
    /// diagonal entry is present (so damping always applies).
    pub fn sparse_lower(&self, damping: &DVector<f64>) -> SparseColMat<usize, f64> {
        self.pattern().matrix(self, damping)
    }
}

/// Compressed-column pattern of the lower triangle of a block-sparse `H`:
/// for the column of variable `pc`, the rows of its diagonal block (from the
/// diagonal down), then those of every block `(pr, pc)`, `pr > pc`, in
/// increasing `pr`. Built once per factor set, so each LM iteration writes
/// its values straight into place (no triplet sorting) and the symbolic
/// Cholesky analysis is reused.
#[derive(Debug, Clone)]
pub struct BlockPattern {
    symbolic: SymbolicSparseColMat<usize>,
    /// `(pr, pc)` (`pr > pc`) → sum of the heights of the blocks above it in
    /// the off-diagonal part of `pc`'s columns.
    block_row_offset: HashMap<(usize, usize), usize>,
    /// Number of blocks (diagonal ones included) of the `H` it was built for.
    block_count: usize,
}

impl BlockPattern {
    fn new(normal: &NormalEquations) -> BlockPattern {
        let index = &normal.index;
        let n_vars = index.len();
        let mut rows_of: Vec<Vec<usize>> = vec![Vec::new(); n_vars];
        for &(pr, pc) in normal.blocks.keys() {
            if pr != pc {
                rows_of[pc].push(pr);
            }
        }
        let mut block_row_offset = HashMap::with_capacity(normal.blocks.len());
        let n = index.total_dim();
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0usize);
        for (pc, rows) in rows_of.iter_mut().enumerate() {
            rows.sort_unstable();
            let mut offset = 0;
            for &pr in rows.iter() {
                block_row_offset.insert((pr, pc), offset);
                offset += index.dims[pr];
            }
            let (co, cd) = (index.offsets[pc], index.dims[pc]);
            for cc in 0..cd {
                row_idx.extend(co + cc..co + cd);
                for &pr in rows.iter() {
                    let ro = index.offsets[pr];
                    row_idx.extend(ro..ro + index.dims[pr]);
                }
                col_ptr.push(row_idx.len());
            }
        }
        // Sorted and in bounds by construction.
        let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        BlockPattern {
            symbolic,
            block_row_offset,
            block_count: normal.blocks.len(),
        }
    }

    /// `H + diag(damping)` (lower triangle) on this pattern.
    fn matrix(&self, normal: &NormalEquations, damping: &DVector<f64>) -> SparseColMat<usize, f64> {
        SparseColMat::new(self.symbolic.clone(), self.fill(normal, damping))
    }

    /// Whether `normal` has the block structure this pattern was built for.
    fn matches(&self, normal: &NormalEquations) -> bool {
        self.symbolic.ncols() == normal.index.total_dim()
            && self.block_count == normal.blocks.len()
            && normal
                .blocks
                .keys()
                .all(|&(pr, pc)| pr == pc || self.block_row_offset.contains_key(&(pr, pc)))
    }

    /// The CSC values of the lower triangle of `H + diag(damping)`.
    fn fill(&self, normal: &NormalEquations, damping: &DVector<f64>) -> Vec<f64> {
        let index = &normal.index;
        let col_ptr = self.symbolic.col_ptr();
        let mut values = vec![0.0; self.symbolic.row_idx().len()];
        for p in 0..index.len() {
            let (o, d) = (index.offsets[p], index.dims[p]);
            for cc in 0..d {
                values[col_ptr[o + cc]] = damping[o + cc];
            }
        }
        for (&(pr, pc), block) in &normal.blocks {
            let (co, cd) = (index.offsets[pc], index.dims[pc]);
            if pr == pc {
                for cc in 0..cd {
                    let start = col_ptr[co + cc];
                    for r in cc..cd {
                        values[start + r - cc] += block[(r, cc)];
                    }
                }
            } else {
                let offset = self.block_row_offset[&(pr, pc)];
                for cc in 0..cd {
                    let start = col_ptr[co + cc] + (cd - cc) + offset;
                    for r in 0..block.nrows() {
                        values[start + r] = block[(r, cc)];
                    }
                }
            }
        }
        values
    }
}

/// A factor's residual and Jacobians after whitening and IRLS reweighting.
struct WhitenedLinearization {
    residual: DVector<f64>,
    jacobians: Vec<DMatrix<f64>>,
    cost: f64,
}

/// Checks keys and shapes, then returns the factor's whitened, reweighted
/// residual and Jacobians, and its cost.
fn whitened_linearization(
    factor_id: usize,
    factor: &dyn Factor,
    values: &Values,
) -> Result<WhitenedLinearization, SolverError> {
    for key in factor.keys() {
        if !values.contains(key) {
            return Err(SolverError::MissingKey {
                factor: factor_id,
                key: *key,
            });
        }
    }
    let lin = factor.linearize(values);
    let noise = factor.noise();
    let keys = factor.keys();
    let non_finite = || SolverError::NonFinite {
        factor: factor_id,
        keys: key_list(keys),
    };
    if lin.jacobians.len() != keys.len() {
        return Err(SolverError::DimensionMismatch {
            factor: factor_id,
            key: keys.first().copied().unwrap_or(Key::EgoPose(0)),
            residual_dim: lin.residual.len(),
            noise_dim: noise.dim(),
            jacobian_rows: 0,
            jacobian_cols: lin.jacobians.len(),
            tangent_dim: keys.len(),
        });
    }
    for (key, jac) in keys.iter().zip(&lin.jacobians) {
        let tangent_dim = values.get(key).map(|v| v.dim()).unwrap_or(0);
        if jac.nrows() != lin.residual.len()
            || jac.ncols() != tangent_dim
            || noise.sqrt_information.ncols() != lin.residual.len()
        {
            return Err(SolverError::DimensionMismatch {
                factor: factor_id,
                key: *key,
                residual_dim: lin.residual.len(),
                noise_dim: noise.sqrt_information.ncols(),
                jacobian_rows: jac.nrows(),
                jacobian_cols: jac.ncols(),
                tangent_dim,
            });
        }
        if jac.iter().any(|v| !v.is_finite()) {
            return Err(non_finite());
        }
    }
    if lin.residual.iter().any(|v| !v.is_finite()) {
        return Err(non_finite());
    }
    let mut residual = noise.whiten(&lin.residual);
    let s = residual.norm();
    let (weight, cost) = match noise.robust {
        Some(kernel) => (kernel.weight(s), kernel.loss(s)),
        None => (1.0, 0.5 * s * s),
    };
    let sqrt_w = weight.sqrt();
    residual *= sqrt_w;
    let jacobians = lin
        .jacobians
        .iter()
        .map(|j| (&noise.sqrt_information * j) * sqrt_w)
        .collect();
    Ok(WhitenedLinearization {
        residual,
        jacobians,
        cost,
    })
}

fn key_list(keys: &[Key]) -> String {
    keys.iter()
        .map(|k| k.to_string())
        .collect::<Vec<_>>()
        .join(",")
}

/// Total cost `Σ ρ(‖L·r‖)` (or `½‖L·r‖²`) of `factors` at `values`.
pub fn total_cost<F: Borrow<dyn Factor>>(
    factors: &[F],
    values: &Values,
) -> Result<f64, SolverError> {
    let mut cost = 0.0;
    for (i, factor) in factors.iter().enumerate() {
        let factor = factor.borrow();
        for key in factor.keys() {
            if !values.contains(key) {
                return Err(SolverError::MissingKey {
                    factor: i,
                    key: *key,
                });
            }
        }
        let c = factor.cost(values);
        if !c.is_finite() {
            return Err(SolverError::NonFinite {
                factor: i,
                keys: key_list(factor.keys()),
            });
        }
        cost += c;
    }
    Ok(cost)
}

/// Linearizes every factor at `values` and accumulates `H` and `g` over the
/// variables of `index`. Keys of a factor that are not in `index` are an
/// error ([`SolverError::UnknownKey`]) unless they have no value at all
/// ([`SolverError::MissingKey`]).
pub fn linearize_normal_equations<F: Borrow<dyn Factor>>(
    factors: &[F],
    values: &Values,
    index: &VariableIndex,
) -> Result<NormalEquations, SolverError> {
    let mut blocks: HashMap<(usize, usize), DMatrix<f64>> = HashMap::new();
    let mut gradient = DVector::zeros(index.total_dim());
    let mut cost = 0.0;
    let mut positions = Vec::new();
    for (i, factor) in factors.iter().enumerate() {
        let factor = factor.borrow();
        let WhitenedLinearization {
            residual,
            jacobians,
            cost: c,
        } = whitened_linearization(i, factor, values)?;
        cost += c;
        positions.clear();
        for key in factor.keys() {
            positions.push(index.position(key).ok_or(SolverError::UnknownKey(*key))?);
        }
        for (a, jac_a) in jacobians.iter().enumerate() {
            let pa = positions[a];
            let oa = index.offsets[pa];
            let mut g = gradient.rows_mut(oa, index.dims[pa]);
            g.gemv_tr(1.0, jac_a, &residual, 1.0);
            for (b, jac_b) in jacobians.iter().enumerate() {
                let pb = positions[b];
                // Keep the lower triangle only (row position ≥ col position).
                if pa < pb {
                    continue;
                }
                let block = blocks
                    .entry((pa, pb))
                    .or_insert_with(|| DMatrix::zeros(index.dims[pa], index.dims[pb]));
                // A key repeated within one factor lands here for both
                // (a, b) and (b, a), so the diagonal block stays symmetric.
                block.gemm_tr(1.0, jac_a, jac_b, 1.0);
            }
        }
    }
    Ok(NormalEquations {
        index: index.clone(),
        blocks,
        gradient,
        cost,
    })
}

/// A sparse Cholesky factorization that keeps its symbolic analysis (AMD
/// ordering, elimination tree) across LM iterations: the pattern of `H`
/// does not change while the factor set does not.
struct SparseCholesky {
    cache: Option<(BlockPattern, SymbolicLlt<usize>)>,
}

impl SparseCholesky {
    fn new() -> SparseCholesky {
        SparseCholesky { cache: None }
    }

    /// Solves `(H + diag(damping))·x = rhs`; `Ok(None)` if not positive definite.
    fn solve(
        &mut self,
        normal: &NormalEquations,
        damping: &DVector<f64>,
        rhs: &DVector<f64>,
    ) -> Result<Option<DVector<f64>>, SolverError> {
        let n = rhs.len();
        if n == 0 {
            return Ok(Some(DVector::zeros(0)));
        }
        let llt = match self.factorize(normal, damping)? {
            Some(llt) => llt,
            None => return Ok(None),
        };
        let mut x = Mat::<f64>::from_fn(n, 1, |i, _| rhs[i]);
        llt.solve_in_place(x.as_mut());
        let x = DVector::from_fn(n, |i, _| x[(i, 0)]);
        if x.iter().any(|v| !v.is_finite()) {
            return Ok(None);
        }
        Ok(Some(x))
    }

    /// Numeric factorization of `H + diag(damping)`; `Ok(None)` if not
    /// positive definite. Rebuilds the pattern and symbolic analysis only
    /// when the block structure changed.
    fn factorize(
        &mut self,
        normal: &NormalEquations,
        damping: &DVector<f64>,
    ) -> Result<Option<Llt<usize, f64>>, SolverError> {
        if !matches!(&self.cache, Some((pattern, _)) if pattern.matches(normal)) {
            let pattern = normal.pattern();
            let symbolic = SymbolicLlt::try_new(pattern.symbolic.as_ref(), Side::Lower)
                .map_err(|e| SolverError::Factorization(format!("{e:?}")))?;
            self.cache = Some((pattern, symbolic));
        }
        let Some((pattern, symbolic)) = &self.cache else {
            unreachable!("cache filled above")
        };
        let values = pattern.fill(normal, damping);
        let matrix = SparseColMatRef::new(pattern.symbolic.as_ref(), &values);
        match Llt::try_new_with_symbolic(symbolic.clone(), matrix, Side::Lower) {
            Ok(llt) => Ok(Some(llt)),
            Err(faer::sparse::linalg::LltError::Numeric(_)) => Ok(None),
            Err(e) => Err(SolverError::Factorization(format!("{e:?}"))),
        }
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
pub fn optimize<F: Borrow<dyn Factor>>(
    factors: &[F],
    values: &mut Values,
    config: &SolverConfig,
) -> Result<SolverReport, SolverError> {
    let start = Instant::now();
    let index = VariableIndex::from_values(values);
    let mut cholesky = SparseCholesky::new();
    let mut lambda = config.initial_lambda.max(0.0);
    let mut nu = 2.0;
    let mut normal = linearize_normal_equations(factors, values, &index)?;
    let initial_cost = normal.cost;
    let mut cost = initial_cost;
    let mut iterations = 1;
    let mut converged = false;
    let mut relinearize = false;
    let mut inner_steps = 0usize;
    while iterations <= config.max_iterations && inner_steps < 10 * config.max_iterations.max(1) {
        inner_steps += 1;
        if relinearize {
            normal = linearize_normal_equations(factors, values, &index)?;
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
        let new_cost = total_cost(factors, &candidate);
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
    let llt = SparseCholesky::new()
        .factorize(&normal, &zero)?
        .ok_or(SolverError::NotPositiveDefinite { lambda: 0.0 })?;
    let mut rhs = Mat::<f64>::zeros(n, m);
    let mut col = 0;
    for &(o, d) in &spans {
        for i in 0..d {
            rhs[(o + i, col)] = 1.0;
            col += 1;
        }
    }
    llt.solve_in_place(rhs.as_mut());
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::between_factor::BetweenFactor;
    use crate::graph::noise::NoiseModel;
    use crate::graph::prior_factor::PriorFactor;
    use crate::graph::values::Variable;
    use crate::lie;
    use nalgebra::{Vector3, Vector6};

    #[test]
    fn sparse_lower_is_the_lower_triangle_of_the_damped_hessian() {
        let mut values = Values::new();
        for k in 0..4 {
            let xi = Vector6::new(k as f64, 0.5, -0.2 * k as f64, 0.1, 0.2 * k as f64, -0.3);
            values.insert(Key::EgoPose(k), Variable::Pose(lie::se3_exp(&xi)));
        }
        // Touched by no factor: only its damping appears on the diagonal.
        values.insert(Key::EgoVelocity(9), Variable::Vector3(Vector3::zeros()));
        let noise = NoiseModel::diagonal_sigmas(&[0.1, 0.2, 0.3, 0.01, 0.02, 0.03]);
        let mut factors: Vec<Box<dyn Factor>> = vec![Box::new(PriorFactor::new(
            Key::EgoPose(0),
            Variable::Pose(lie::se3_exp(&Vector6::new(0.1, 0.0, 0.0, 0.0, 0.0, 0.1))),
            noise.clone(),
        ))];
        // Non-adjacent pairs too, so columns hold several off-diagonal blocks.
        for (a, b) in [(0, 1), (1, 2), (2, 3), (0, 3), (3, 1)] {
            factors.push(Box::new(BetweenFactor::new(
                Key::EgoPose(a),
                Key::EgoPose(b),
                lie::se3_exp(&Vector6::new(1.0, 0.1, 0.0, 0.0, 0.05, 0.1)),
                noise.clone(),
            )));
        }
        let index = VariableIndex::from_values(&values);
        let normal = linearize_normal_equations(&factors, &values, &index).unwrap();
        let damping = DVector::from_fn(index.total_dim(), |i, _| 0.5 + i as f64);
        let sparse = normal.sparse_lower(&damping).to_dense();
        let mut expected = normal.dense_hessian() + DMatrix::from_diagonal(&damping);
        for c in 0..expected.ncols() {
            for r in 0..c {
                expected[(r, c)] = 0.0;
            }
        }
        let n = index.total_dim();
        for r in 0..n {
            for c in 0..n {
                assert!(
                    (sparse[(r, c)] - expected[(r, c)]).abs() < 1e-9,
                    "({r}, {c}): {} vs {}",
                    sparse[(r, c)],
                    expected[(r, c)]
                );
            }
        }
    }
}
