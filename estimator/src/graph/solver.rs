//! Sparse nonlinear least squares on the factor graph: Levenberg–Marquardt
//! with Nielsen damping, robust kernels by IRLS, normal equations assembled
//! block by block and solved with faer's supernodal sparse Cholesky, the
//! variables laid out in a block-AMD elimination order (see
//! `SparseCholesky`).
//!
//! Conventions: the step `δ` is a stacked right perturbation of every
//! variable in [`VariableIndex`] order; `H = JᵀJ`, `g = Jᵀr` of the whitened,
//! reweighted residuals; the Gauss–Newton step solves `H·δ = -g`.

use super::factor::Factor;
use super::key::Key;
use super::values::Values;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::linalg::{SupernodalThreshold, amd};
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, Mat, Side};
use nalgebra::{DMatrix, DMatrixView, DVector};
use std::borrow::Borrow;
use std::collections::{BTreeMap, HashMap};
use std::hash::{BuildHasherDefault, Hasher};
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

/// A cheap hasher for `(usize, usize)` block keys (FxHash's mixing): the
/// normal equations look blocks up once per factor and key pair, and SipHash
/// showed up in profiles.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct BlockKeyHasher(u64);

impl Hasher for BlockKeyHasher {
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x517c_c1b7_2722_0a95);
    }

    fn write_usize(&mut self, i: usize) {
        self.write_u64(i as u64);
    }

    fn finish(&self) -> u64 {
        self.0
    }
}

/// Map keyed by `(row position, col position)` of a block.
type BlockMap<V> = HashMap<(usize, usize), V, BuildHasherDefault<BlockKeyHasher>>;

/// A hash map with [`BlockKeyHasher`]'s mixing, for the graph's small
/// integer-like keys (variable keys, positions) on hot paths.
pub(crate) type FastHashMap<K, V> = HashMap<K, V, BuildHasherDefault<BlockKeyHasher>>;

/// The normal equations `H·δ = -g` of a set of factors, kept as dense blocks
/// per pair of variables (lower triangle: row position ≥ column position).
#[derive(Debug, Clone)]
pub struct NormalEquations {
    pub index: VariableIndex,
    /// `(row position, col position)` → offset of the block in
    /// `block_values` (column-major, `dims[row] × dims[col]`), for row ≥ col.
    /// One flat buffer instead of a matrix per block: no allocation per block.
    blocks: BlockMap<usize>,
    block_values: Vec<f64>,
    /// `Jᵀr` over the whole tangent vector.
    pub gradient: DVector<f64>,
    /// Total (robust) cost at the linearization point.
    pub cost: f64,
}

impl NormalEquations {
    /// Column-major values of block `(pr, pc)` stored at `offset`.
    fn block_slice(&self, pr: usize, pc: usize, offset: usize) -> &[f64] {
        &self.block_values[offset..offset + self.index.dims[pr] * self.index.dims[pc]]
    }

    /// The full symmetric `H` as a dense matrix (tests, marginalization).
    pub fn dense_hessian(&self) -> DMatrix<f64> {
        let n = self.index.total_dim();
        let mut h = DMatrix::zeros(n, n);
        for (&(pr, pc), &offset) in &self.blocks {
            let (ro, rd) = (self.index.offsets[pr], self.index.dims[pr]);
            let (co, cd) = (self.index.offsets[pc], self.index.dims[pc]);
            let block = DMatrixView::from_slice(self.block_slice(pr, pc, offset), rd, cd);
            h.view_mut((ro, co), (rd, cd)).copy_from(&block);
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
            let (o, dim) = (self.index.offsets[p], self.index.dims[p]);
            if let Some(&offset) = self.blocks.get(&(p, p)) {
                let block = self.block_slice(p, p, offset);
                for i in 0..dim {
                    d[o + i] = block[i * dim + i];
                }
            }
        }
        d
    }

    /// The CSC pattern of the lower triangle of `H` (see [`BlockPattern`]),
    /// columns in variable order.
    pub fn pattern(&self) -> BlockPattern {
        let order: Vec<usize> = (0..self.index.len()).collect();
        BlockPattern::new(self, &order)
    }

    /// Lower triangle of `H + diag(damping)` as a faer CSC matrix. Every
    /// diagonal entry is present (so damping always applies).
    pub fn sparse_lower(&self, damping: &DVector<f64>) -> SparseColMat<usize, f64> {
        self.pattern().matrix(self, damping)
    }
}

/// Where an off-diagonal block `(pr, pc)` lands in a [`BlockPattern`].
#[derive(Debug, Clone, Copy)]
struct BlockSlot {
    /// Sum of the heights of the blocks above it in the off-diagonal part of
    /// its column variable's columns.
    offset: usize,
    /// The layout puts `pr` before `pc`: the block is stored transposed, in
    /// `pr`'s columns.
    transposed: bool,
}

/// Compressed-column pattern of the lower triangle of a block-sparse `H`,
/// with the variables laid out in a given order (the identity, or a
/// fill-reducing elimination order so the Cholesky needs no permutation):
/// for the columns of each variable, the rows of its diagonal block (from
/// the diagonal down), then those of every variable coupled to it that comes
/// later in the layout, in layout order. Built once per factor set, so each
/// LM iteration writes its values straight into place (no triplet sorting)
/// and the symbolic Cholesky analysis is reused.
#[derive(Debug, Clone)]
pub struct BlockPattern {
    symbolic: SymbolicSparseColMat<usize>,
    /// Variable position → its first column in the layout.
    columns: Vec<usize>,
    /// `(pr, pc)` (`pr > pc`) → where the block is stored.
    slots: BlockMap<BlockSlot>,
    /// Number of blocks (diagonal ones included) of the `H` it was built for.
    block_count: usize,
    /// Tangent dimension of each variable position.
    dims: Vec<usize>,
}

impl BlockPattern {
    /// `order[q]` is the variable (position in `normal.index`) laid out `q`-th.
    fn new(normal: &NormalEquations, order: &[usize]) -> BlockPattern {
        let index = &normal.index;
        let n_vars = index.len();
        debug_assert_eq!(order.len(), n_vars);
        let mut layout_position = vec![0usize; n_vars];
        let mut columns = vec![0usize; n_vars];
        let mut next_column = 0;
        for (q, &p) in order.iter().enumerate() {
            layout_position[p] = q;
            columns[p] = next_column;
            next_column += index.dims[p];
        }
        // Column variable → the variables below it in the layout.
        let mut rows_of: Vec<Vec<usize>> = vec![Vec::new(); n_vars];
        for &(pr, pc) in normal.blocks.keys() {
            if pr != pc {
                if layout_position[pr] > layout_position[pc] {
                    rows_of[pc].push(pr);
                } else {
                    rows_of[pr].push(pc);
                }
            }
        }
        let mut slots = BlockMap::with_capacity_and_hasher(normal.blocks.len(), Default::default());
        let n = index.total_dim();
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0usize);
        for &p in order {
            let rows = &mut rows_of[p];
            rows.sort_unstable_by_key(|&r| layout_position[r]);
            let mut offset = 0;
            for &r in rows.iter() {
                slots.insert(
                    (p.max(r), p.min(r)),
                    BlockSlot {
                        offset,
                        transposed: p > r,
                    },
                );
                offset += index.dims[r];
            }
            let (c0, d) = (columns[p], index.dims[p]);
            for cc in 0..d {
                row_idx.extend(c0 + cc..c0 + d);
                for &r in rows.iter() {
                    row_idx.extend(columns[r]..columns[r] + index.dims[r]);
                }
                col_ptr.push(row_idx.len());
            }
        }
        // Sorted and in bounds by construction.
        let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        BlockPattern {
            symbolic,
            columns,
            slots,
            block_count: normal.blocks.len(),
            dims: index.dims.clone(),
        }
    }

    /// `H + diag(damping)` (lower triangle) on this pattern.
    fn matrix(&self, normal: &NormalEquations, damping: &DVector<f64>) -> SparseColMat<usize, f64> {
        SparseColMat::new(self.symbolic.clone(), self.fill(normal, damping))
    }

    /// Whether `normal` has the block structure this pattern was built for.
    fn matches(&self, normal: &NormalEquations) -> bool {
        self.dims == normal.index.dims
            && self.block_count == normal.blocks.len()
            && normal
                .blocks
                .keys()
                .all(|&(pr, pc)| pr == pc || self.slots.contains_key(&(pr, pc)))
    }

    /// Layout column of every column of the variable order (scalar
    /// permutation: variable order → layout).
    fn layout_of_columns(&self, index: &VariableIndex) -> Vec<usize> {
        let mut layout = vec![0usize; index.total_dim()];
        for p in 0..index.len() {
            for i in 0..index.dims[p] {
                layout[index.offsets[p] + i] = self.columns[p] + i;
            }
        }
        layout
    }

    /// The CSC values of the lower triangle of `H + diag(damping)`
    /// (`damping` in variable order).
    fn fill(&self, normal: &NormalEquations, damping: &DVector<f64>) -> Vec<f64> {
        let mut values = Vec::new();
        self.fill_into(normal, damping, &mut values);
        values
    }

    /// [`BlockPattern::fill`] into `values` (resized; its memory reused).
    fn fill_into(&self, normal: &NormalEquations, damping: &DVector<f64>, values: &mut Vec<f64>) {
        let index = &normal.index;
        let col_ptr = self.symbolic.col_ptr();
        values.clear();
        values.resize(self.symbolic.row_idx().len(), 0.0);
        for p in 0..index.len() {
            let (o, d, c0) = (index.offsets[p], index.dims[p], self.columns[p]);
            for cc in 0..d {
                values[col_ptr[c0 + cc]] = damping[o + cc];
            }
        }
        for (&(pr, pc), &offset) in &normal.blocks {
            let (rd, cd) = (index.dims[pr], index.dims[pc]);
            // Column-major: block(r, c) = block[c * rd + r].
            let block = normal.block_slice(pr, pc, offset);
            if pr == pc {
                let c0 = self.columns[pc];
                for cc in 0..cd {
                    let start = col_ptr[c0 + cc];
                    for r in cc..cd {
                        values[start + r - cc] += block[cc * rd + r];
                    }
                }
                continue;
            }
            let slot = self.slots[&(pr, pc)];
            if slot.transposed {
                // In pr's columns, rows of pc: H(pc_i, pr_cc) = block(cc, i).
                let c0 = self.columns[pr];
                for cc in 0..rd {
                    let start = col_ptr[c0 + cc] + (rd - cc) + slot.offset;
                    for i in 0..cd {
                        values[start + i] = block[i * rd + cc];
                    }
                }
            } else {
                let c0 = self.columns[pc];
                for cc in 0..cd {
                    let start = col_ptr[c0 + cc] + (cd - cc) + slot.offset;
                    values[start..start + rd].copy_from_slice(&block[cc * rd..(cc + 1) * rd]);
                }
            }
        }
    }
}

/// A factor's residual and Jacobians after whitening and IRLS reweighting.
struct WhitenedLinearization {
    residual: DVector<f64>,
    jacobians: Vec<DMatrix<f64>>,
    cost: f64,
}

/// Checks shapes (against the keys' tangent dims, `tangent_dims`; the
/// caller has checked that every key has a value), then returns the
/// factor's whitened, reweighted residual and Jacobians, and its cost.
fn whitened_linearization(
    factor_id: usize,
    factor: &dyn Factor,
    values: &Values,
    tangent_dims: &[usize],
) -> Result<WhitenedLinearization, SolverError> {
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
    for ((key, jac), &tangent_dim) in keys.iter().zip(&lin.jacobians).zip(tangent_dims) {
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
    let l = &noise.sqrt_information;
    // Most noise models are diagonal: scale rows instead of a full product
    // (the same numbers: the skipped terms are exact zeros).
    let diagonal =
        l.is_square() && (0..l.ncols()).all(|c| (0..l.nrows()).all(|r| r == c || l[(r, c)] == 0.0));
    let mut jacobians = lin.jacobians;
    for j in &mut jacobians {
        if diagonal {
            // In place: the factor's Jacobian is ours to scale.
            let m = j.nrows();
            for col in j.as_mut_slice().chunks_exact_mut(m) {
                for (r, x) in col.iter_mut().enumerate() {
                    *x = (l[(r, r)] * *x) * sqrt_w;
                }
            }
        } else {
            *j = whiten_jacobian(l, j, sqrt_w);
        }
    }
    Ok(WhitenedLinearization {
        residual,
        jacobians,
        cost,
    })
}

/// `(L·J)·scale` for the small matrices of one factor. A plain column
/// loop: the general matrix product's packing dominated for 6×6 blocks.
fn whiten_jacobian(
    sqrt_information: &DMatrix<f64>,
    jacobian: &DMatrix<f64>,
    scale: f64,
) -> DMatrix<f64> {
    let (m, k) = sqrt_information.shape();
    let n = jacobian.ncols();
    debug_assert_eq!(jacobian.nrows(), k);
    let l = sqrt_information.as_slice();
    let j = jacobian.as_slice();
    let mut out = DMatrix::zeros(m, n);
    for (c, out_col) in out.as_mut_slice().chunks_exact_mut(m).enumerate() {
        for kk in 0..k {
            let b = j[c * k + kk];
            for (o, &a) in out_col.iter_mut().zip(&l[kk * m..(kk + 1) * m]) {
                *o += a * b;
            }
        }
        if scale != 1.0 {
            for o in out_col.iter_mut() {
                *o *= scale;
            }
        }
    }
    out
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
    let mut positions = FactorPositions::default();
    linearize(factors, values, index, KeyPositions::Record(&mut positions))
}

/// Positions in a [`VariableIndex`] of the keys of every factor, flattened:
/// factor `i`'s are `flat[starts[i]..starts[i + 1]]`. Looked up once per
/// optimization instead of once per key per iteration.
#[derive(Debug, Default)]
struct FactorPositions {
    flat: Vec<usize>,
    starts: Vec<usize>,
}

/// Whether [`linearize`] looks the keys up (checking them) or reuses the
/// positions of an earlier linearization over the same keys.
enum KeyPositions<'a> {
    Record(&'a mut FactorPositions),
    Cached(&'a FactorPositions),
}

fn linearize<F: Borrow<dyn Factor>>(
    factors: &[F],
    values: &Values,
    index: &VariableIndex,
    mut key_positions: KeyPositions<'_>,
) -> Result<NormalEquations, SolverError> {
    // About three blocks per factor (each factor couples few keys).
    let mut blocks =
        BlockMap::with_capacity_and_hasher(3 * factors.len() + index.len(), Default::default());
    let mut block_values: Vec<f64> = Vec::new();
    let mut gradient = DVector::zeros(index.total_dim());
    let mut cost = 0.0;
    let mut tangent_dims = Vec::new();
    let mut looked_up = Vec::new();
    let mut jac_a_t = Vec::new();
    if let KeyPositions::Record(record) = &mut key_positions {
        record.flat.clear();
        record.starts.clear();
        record.starts.push(0);
    }
    for (i, factor) in factors.iter().enumerate() {
        let factor = factor.borrow();
        tangent_dims.clear();
        let WhitenedLinearization {
            residual,
            jacobians,
            cost: c,
        } = match &mut key_positions {
            KeyPositions::Record(record) => {
                for key in factor.keys() {
                    let value = values.get(key).ok_or(SolverError::MissingKey {
                        factor: i,
                        key: *key,
                    })?;
                    tangent_dims.push(value.dim());
                }
                let lin = whitened_linearization(i, factor, values, &tangent_dims)?;
                looked_up.clear();
                for key in factor.keys() {
                    looked_up.push(index.position(key).ok_or(SolverError::UnknownKey(*key))?);
                }
                record.flat.extend_from_slice(&looked_up);
                record.starts.push(record.flat.len());
                lin
            }
            KeyPositions::Cached(cached) => {
                let positions = &cached.flat[cached.starts[i]..cached.starts[i + 1]];
                tangent_dims.extend(positions.iter().map(|&p| index.dims[p]));
                whitened_linearization(i, factor, values, &tangent_dims)?
            }
        };
        cost += c;
        let positions = match &key_positions {
            KeyPositions::Record(record) => &record.flat[record.starts[i]..record.starts[i + 1]],
            KeyPositions::Cached(cached) => &cached.flat[cached.starts[i]..cached.starts[i + 1]],
        };
        for (a, jac_a) in jacobians.iter().enumerate() {
            let pa = positions[a];
            let (oa, da) = (index.offsets[pa], index.dims[pa]);
            let mut g = gradient.rows_mut(oa, da);
            g.gemv_tr(1.0, jac_a, &residual, 1.0);
            transpose_into(jac_a, &mut jac_a_t);
            for (b, jac_b) in jacobians.iter().enumerate() {
                let pb = positions[b];
                // Keep the lower triangle only (row position ≥ col position).
                if pa < pb {
                    continue;
                }
                let db = index.dims[pb];
                let offset = *blocks.entry((pa, pb)).or_insert_with(|| {
                    let offset = block_values.len();
                    block_values.resize(offset + da * db, 0.0);
                    offset
                });
                // A key repeated within one factor lands here for both
                // (a, b) and (b, a), so the diagonal block stays symmetric.
                add_jacobian_product(&mut block_values[offset..offset + da * db], &jac_a_t, jac_b);
            }
        }
    }
    Ok(NormalEquations {
        index: index.clone(),
        blocks,
        block_values,
        gradient,
        cost,
    })
}

/// `a_t` := `Aᵀ` (column-major `A.ncols() × A.nrows()`): row `k` of `A`
/// becomes contiguous, for [`add_jacobian_product`].
fn transpose_into(a: &DMatrix<f64>, a_t: &mut Vec<f64>) {
    let (m, n) = a.shape();
    a_t.clear();
    a_t.resize(m * n, 0.0);
    for (i, a_col) in a.as_slice().chunks_exact(m).enumerate() {
        for (k, &x) in a_col.iter().enumerate() {
            a_t[k * n + i] = x;
        }
    }
}

/// `block += Aᵀ·B` (column-major `block`, `A.ncols() × B.ncols()`) from
/// `a_t` = `Aᵀ` ([`transpose_into`]): each block column gathers rows of `A`
/// scaled by one entry of `B`, independent multiply-adds the compiler
/// vectorizes (a dot product per entry is one serial chain of additions),
/// fully unrolled for the common 3- and 6-dimensional tangents.
fn add_jacobian_product(block: &mut [f64], a_t: &[f64], b: &DMatrix<f64>) {
    let m = b.nrows();
    let rows = a_t.len() / m.max(1);
    debug_assert_eq!(block.len(), rows * b.ncols());
    match rows {
        3 => add_jacobian_product_fixed::<3>(block, a_t, b),
        6 => add_jacobian_product_fixed::<6>(block, a_t, b),
        _ => {
            for (b_col, block_col) in b
                .as_slice()
                .chunks_exact(m)
                .zip(block.chunks_exact_mut(rows))
            {
                for (&bk, a_row) in b_col.iter().zip(a_t.chunks_exact(rows)) {
                    for (out, &x) in block_col.iter_mut().zip(a_row) {
                        *out += x * bk;
                    }
                }
            }
        }
    }
}

fn add_jacobian_product_fixed<const R: usize>(block: &mut [f64], a_t: &[f64], b: &DMatrix<f64>) {
    let m = b.nrows();
    for (b_col, block_col) in b.as_slice().chunks_exact(m).zip(block.chunks_exact_mut(R)) {
        let mut acc = [0.0; R];
        acc.copy_from_slice(block_col);
        for (&bk, a_row) in b_col.iter().zip(a_t.chunks_exact(R)) {
            for r in 0..R {
                acc[r] += a_row[r] * bk;
            }
        }
        block_col.copy_from_slice(&acc);
    }
}

/// Cost of `factors` at `values` whose keys were all checked to have values
/// (the LM candidates: the checked values, retracted).
fn cost_of_checked<F: Borrow<dyn Factor>>(
    factors: &[F],
    values: &Values,
) -> Result<f64, SolverError> {
    let mut cost = 0.0;
    for (i, factor) in factors.iter().enumerate() {
        let factor = factor.borrow();
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

/// Sparse Cholesky factorizations that keep their symbolic analyses
/// (ordering, elimination tree, supernodes) for as long as the block
/// pattern of `H` recurs: across LM iterations (the factor set does not
/// change), and, when one workspace serves many solves, across the windows
/// of one sliding-window smoother (each object's part of the window has the
/// same shape every frame) — so a [`SolverWorkspace`] keeps the last few
/// patterns.
///
/// The fill-reducing ordering is AMD on the *block* graph (one node per
/// variable), and `H` is assembled directly in that order (each variable's
/// columns together), so faer factorizes it as is, with no permutation
/// pass. In a window of ego states and objects it eliminates each object's
/// chain (which couples only to ego poses) before the ego states, so the
/// cost grows linearly with the number of objects; the variables' blocks
/// make a supernodal factorization (dense kernels) pay off over the scalar
/// simplicial one.
struct SparseCholesky {
    /// Most recently used first, at most [`SparseCholesky::KEPT_PATTERNS`].
    structures: Vec<CholeskyStructure>,
    /// Values of `H + diag(damping)` on the front pattern (buffer reused).
    matrix_values: Vec<f64>,
    /// Whether the front structure holds a successful factorization.
    factored: bool,
}

/// What stays fixed while the block structure does.
struct CholeskyStructure {
    /// `H` laid out in elimination order.
    pattern: BlockPattern,
    symbolic: SymbolicCholesky<usize>,
    /// Layout column of each column in variable order.
    layout: Vec<usize>,
    /// Values of the factor `L` of the latest factorization.
    factor: Vec<f64>,
    workspace: MemBuffer,
}

/// Buffers and symbolic factorizations that [`optimize_with`] reuses
/// across calls: pass the same workspace to repeated solves of problems of
/// recurring shapes (a sliding window's parts, frame after frame).
pub struct SolverWorkspace(SparseCholesky);

impl SolverWorkspace {
    pub fn new() -> SolverWorkspace {
        SolverWorkspace(SparseCholesky::new())
    }
}

impl Default for SolverWorkspace {
    fn default() -> Self {
        SolverWorkspace::new()
    }
}

impl std::fmt::Debug for SolverWorkspace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SolverWorkspace")
            .field("patterns", &self.0.structures.len())
            .finish()
    }
}

impl SparseCholesky {
    /// Patterns kept: a window's ego part and its objects' parts at each
    /// chain length fit, and looking one up is a few hash probes.
    const KEPT_PATTERNS: usize = 8;

    fn new() -> SparseCholesky {
        SparseCholesky {
            structures: Vec::new(),
            matrix_values: Vec::new(),
            factored: false,
        }
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
        if !self.factorize(normal, damping)? {
            return Ok(None);
        }
        let mut x = Mat::<f64>::from_fn(n, 1, |i, _| rhs[i]);
        self.solve_in_place(x.as_mut());
        let x = DVector::from_fn(n, |i, _| x[(i, 0)]);
        if x.iter().any(|v| !v.is_finite()) {
            return Ok(None);
        }
        Ok(Some(x))
    }

    /// Numeric factorization of `H + diag(damping)`; `Ok(false)` if not
    /// positive definite. Builds the ordering, pattern and symbolic
    /// analysis only for a block structure not seen among the kept ones.
    fn factorize(
        &mut self,
        normal: &NormalEquations,
        damping: &DVector<f64>,
    ) -> Result<bool, SolverError> {
        self.factored = false;
        match self
            .structures
            .iter()
            .position(|c| c.pattern.matches(normal))
        {
            Some(0) => {}
            Some(i) => {
                let structure = self.structures.remove(i);
                self.structures.insert(0, structure);
            }
            None => {
                let structure = CholeskyStructure::new(normal)?;
                self.structures.insert(0, structure);
                self.structures.truncate(Self::KEPT_PATTERNS);
            }
        }
        let structure = &mut self.structures[0];
        structure
            .pattern
            .fill_into(normal, damping, &mut self.matrix_values);
        let matrix = SparseColMatRef::new(structure.pattern.symbolic.as_ref(), &self.matrix_values);
        let result = structure.symbolic.factorize_numeric_llt::<f64>(
            &mut structure.factor,
            matrix,
            Side::Lower,
            Default::default(),
            faer::get_global_parallelism(),
            MemStack::new(&mut structure.workspace),
            Default::default(),
        );
        // The only numeric failure is a non-positive pivot: not SPD.
        self.factored = result.is_ok();
        Ok(self.factored)
    }

    /// `rhs ← (H + diag(damping))⁻¹·rhs` (rows in variable order) with the
    /// latest successful factorization.
    fn solve_in_place(&mut self, mut rhs: faer::MatMut<'_, f64>) {
        let structure = match self.structures.first_mut() {
            Some(structure) if self.factored => structure,
            _ => unreachable!("solve_in_place after a successful factorize"),
        };
        let (n, k) = (rhs.nrows(), rhs.ncols());
        let mut x = Mat::<f64>::zeros(n, k);
        for c in 0..k {
            for (i, &l) in structure.layout.iter().enumerate() {
                x[(l, c)] = rhs[(i, c)];
            }
        }
        let par = faer::get_global_parallelism();
        let llt = LltRef::new(&structure.symbolic, &structure.factor);
        if k == 1 {
            llt.solve_in_place_with_conj(
                Conj::No,
                x.as_mut(),
                par,
                MemStack::new(&mut structure.workspace),
            );
        } else {
            // Several right-hand sides (marginal covariances) need more room.
            let req = structure.symbolic.solve_in_place_scratch::<f64>(k, par);
            let mut workspace = MemBuffer::new(req);
            llt.solve_in_place_with_conj(Conj::No, x.as_mut(), par, MemStack::new(&mut workspace));
        }
        for c in 0..k {
            for (i, &l) in structure.layout.iter().enumerate() {
                rhs[(i, c)] = x[(l, c)];
            }
        }
    }
}

impl CholeskyStructure {
    /// Ordering, pattern and symbolic analysis for the block structure of
    /// `normal`.
    fn new(normal: &NormalEquations) -> Result<CholeskyStructure, SolverError> {
        let order = block_elimination_order(normal)?;
        let pattern = BlockPattern::new(normal, &order);
        // faer's symbolic analysis takes an unpermuted matrix as its
        // upper triangle whatever `side` says: give it the transpose.
        let upper = pattern
            .symbolic
            .as_ref()
            .transpose()
            .to_col_major()
            .map_err(factorization_error)?;
        let symbolic = factorize_symbolic_cholesky(
            upper.as_ref(),
            Side::Upper,
            SymmetricOrdering::Identity,
            CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
                ..Default::default()
            },
        )
        .map_err(factorization_error)?;
        let factor = vec![0.0; symbolic.len_val()];
        let par = faer::get_global_parallelism();
        let req = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, par));
        let workspace = MemBuffer::try_new(req).map_err(factorization_error)?;
        let layout = pattern.layout_of_columns(&normal.index);
        Ok(CholeskyStructure {
            pattern,
            symbolic,
            layout,
            factor,
            workspace,
        })
    }
}

fn factorization_error(e: impl std::fmt::Debug) -> SolverError {
    SolverError::Factorization(format!("{e:?}"))
}

/// Fill-reducing elimination order of the variables of `normal`: AMD on
/// the block graph (one node per variable, an edge per off-diagonal block).
/// `order[q]` is the variable eliminated `q`-th.
fn block_elimination_order(normal: &NormalEquations) -> Result<Vec<usize>, SolverError> {
    let n_vars = normal.index.len();
    // Lower triangle with the diagonal, CSC.
    let mut rows_of: Vec<Vec<usize>> = (0..n_vars).map(|p| vec![p]).collect();
    for &(pr, pc) in normal.blocks.keys() {
        if pr != pc {
            rows_of[pc].push(pr);
        }
    }
    let mut col_ptr = Vec::with_capacity(n_vars + 1);
    let mut row_idx = Vec::with_capacity(n_vars + normal.blocks.len());
    col_ptr.push(0usize);
    for rows in &mut rows_of {
        rows.sort_unstable();
        row_idx.extend_from_slice(rows);
        col_ptr.push(row_idx.len());
    }
    let graph = SymbolicSparseColMat::new_checked(n_vars, n_vars, col_ptr, None, row_idx);
    let mut order = vec![0usize; n_vars];
    let mut order_inv = vec![0usize; n_vars];
    let mut memory = MemBuffer::try_new(amd::order_scratch::<usize>(n_vars, graph.compute_nnz()))
        .map_err(factorization_error)?;
    amd::order(
        &mut order,
        &mut order_inv,
        graph.as_ref(),
        amd::Control::default(),
        MemStack::new(&mut memory),
    )
    .map_err(factorization_error)?;
    Ok(order)
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
    optimize_with(factors, values, config, &mut SolverWorkspace::new())
}

/// [`optimize`] with a workspace kept by the caller: symbolic analyses of
/// block patterns it has seen before are reused.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::between_factor::BetweenFactor;
    use crate::graph::noise::NoiseModel;
    use crate::graph::prior_factor::PriorFactor;
    use crate::graph::values::Variable;
    use crate::lie;
    use nalgebra::{Isometry3, Vector3, Vector6};

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

    /// A hub (the ego) coupled to many leaves (objects), the leaves chained
    /// in pairs: the block ordering eliminates every leaf before the hub,
    /// and the supernodal solve equals a dense one.
    #[test]
    fn block_ordering_eliminates_leaves_before_the_hub() {
        let mut values = Values::new();
        let hub = Key::EgoPose(0);
        values.insert(hub, Variable::Pose(Isometry3::identity()));
        let noise = NoiseModel::diagonal_sigmas(&[0.1, 0.2, 0.3, 0.01, 0.02, 0.03]);
        let mut factors: Vec<Box<dyn Factor>> = vec![Box::new(PriorFactor::new(
            hub,
            Variable::Pose(Isometry3::identity()),
            noise.clone(),
        ))];
        let step = lie::se3_exp(&Vector6::new(1.0, 0.1, 0.0, 0.0, 0.05, 0.1));
        for id in 0..8u64 {
            for frame in 0..2u64 {
                let key = Key::ObjectPose { id, frame };
                let xi = Vector6::new(id as f64, frame as f64, 0.3, 0.01, -0.02, 0.1);
                values.insert(key, Variable::Pose(lie::se3_exp(&xi)));
                factors.push(Box::new(BetweenFactor::new(hub, key, step, noise.clone())));
            }
            factors.push(Box::new(BetweenFactor::new(
                Key::ObjectPose { id, frame: 0 },
                Key::ObjectPose { id, frame: 1 },
                step,
                noise.clone(),
            )));
        }
        let index = VariableIndex::from_values(&values);
        let normal = linearize_normal_equations(&factors, &values, &index).unwrap();
        let order = block_elimination_order(&normal).unwrap();
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..index.len()).collect::<Vec<_>>());
        assert_eq!(order.last(), index.position(&hub).as_ref());

        // The pattern laid out in that order is the permuted lower triangle.
        let damping = DVector::from_fn(index.total_dim(), |i, _| 0.25 + 0.01 * i as f64);
        let pattern = BlockPattern::new(&normal, &order);
        let layout = pattern.layout_of_columns(&index);
        let sparse = pattern.matrix(&normal, &damping).to_dense();
        let full = normal.dense_hessian() + DMatrix::from_diagonal(&damping);
        let n = index.total_dim();
        for r in 0..n {
            for c in 0..n {
                let (lr, lc) = (layout[r], layout[c]);
                let expected = if lr >= lc { full[(r, c)] } else { 0.0 };
                assert!(
                    (sparse[(lr, lc)] - expected).abs() < 1e-9,
                    "({r}, {c}) at ({lr}, {lc}): {} vs {expected}",
                    sparse[(lr, lc)]
                );
            }
        }
        let rhs = DVector::from_fn(n, |i, _| (i as f64 * 0.37).sin());
        let x = SparseCholesky::new()
            .solve(&normal, &damping, &rhs)
            .unwrap()
            .expect("SPD");
        let dense = full.cholesky().expect("SPD").solve(&rhs);
        assert!((x - dense).amax() < 1e-9);
    }
}
