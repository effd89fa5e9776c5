//! Linearization: every factor's residual and Jacobians whitened by its
//! noise model (robust kernels by IRLS reweighting) and accumulated into the
//! normal equations `H·δ = -g`, `H = JᵀJ`, `g = Jᵀr`, kept as dense blocks per
//! pair of variables; and the compressed-column [`BlockPattern`] of `H` that
//! the sparse Cholesky factorizes.

use super::factor::{Factor, JacobiansMut};
use super::key::Key;
use super::noise::NoiseModel;
use super::optimizer::SolverError;
use super::values::Values;
use super::variable_index::VariableIndex;
#[cfg(test)]
use faer::sparse::SparseColMat;
use faer::sparse::SymbolicSparseColMat;
use nalgebra::{DMatrix, DMatrixView, DVector};
use std::borrow::Borrow;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

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
    /// The column layout of `H`, `g` and the step.
    pub index: VariableIndex,
    /// `(row position, col position)` → offset of the block in
    /// `block_values` (column-major, `dims[row] × dims[col]`), for row ≥ col.
    /// One flat buffer instead of a matrix per block: no allocation per block.
    pub(super) blocks: BlockMap<usize>,
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
    #[cfg(test)]
    pub(crate) fn pattern(&self) -> BlockPattern {
        let order: Vec<usize> = (0..self.index.len()).collect();
        BlockPattern::new(self, &order)
    }

    /// Lower triangle of `H + diag(damping)` as a faer CSC matrix. Every
    /// diagonal entry is present (so damping always applies).
    #[cfg(test)]
    pub(crate) fn sparse_lower(&self, damping: &DVector<f64>) -> SparseColMat<usize, f64> {
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
pub(crate) struct BlockPattern {
    pub(super) symbolic: SymbolicSparseColMat<usize>,
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
    pub(super) fn new(normal: &NormalEquations, order: &[usize]) -> BlockPattern {
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
    #[cfg(test)]
    pub(super) fn matrix(
        &self,
        normal: &NormalEquations,
        damping: &DVector<f64>,
    ) -> SparseColMat<usize, f64> {
        SparseColMat::new(self.symbolic.clone(), self.fill(normal, damping))
    }

    /// Whether `normal` has the block structure this pattern was built for.
    pub(super) fn matches(&self, normal: &NormalEquations) -> bool {
        self.dims == normal.index.dims
            && self.block_count == normal.blocks.len()
            && normal
                .blocks
                .keys()
                .all(|&(pr, pc)| pr == pc || self.slots.contains_key(&(pr, pc)))
    }

    /// Layout column of every column of the variable order (scalar
    /// permutation: variable order → layout).
    pub(super) fn layout_of_columns(&self, index: &VariableIndex) -> Vec<usize> {
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
    #[cfg(test)]
    fn fill(&self, normal: &NormalEquations, damping: &DVector<f64>) -> Vec<f64> {
        let mut values = Vec::new();
        self.fill_into(normal, damping, &mut values);
        values
    }

    /// [`BlockPattern::fill`] into `values` (resized; its memory reused).
    pub(super) fn fill_into(
        &self,
        normal: &NormalEquations,
        damping: &DVector<f64>,
        values: &mut Vec<f64>,
    ) {
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

/// Buffers one factor at a time is linearized and whitened in, reused from
/// factor to factor: linearizing allocates nothing per factor.
#[derive(Debug, Default)]
pub(super) struct FactorBuffers {
    /// The residual, whitened and reweighted in place.
    residual: Vec<f64>,
    /// The Jacobian blocks ([`JacobiansMut`]'s layout), whitened in place.
    jacobians: Vec<f64>,
    /// `L·x` before it is copied back (non-diagonal noise models).
    product: Vec<f64>,
    /// Tangent dimension of each key of the factor.
    cols: Vec<usize>,
}

/// Whether `l` is square and diagonal (most noise models are).
fn is_diagonal(l: &DMatrix<f64>) -> bool {
    let n = l.nrows();
    l.is_square()
        && l.as_slice()
            .chunks_exact(n.max(1))
            .enumerate()
            .all(|(c, col)| col.iter().enumerate().all(|(r, &x)| r == c || x == 0.0))
}

/// `x ← (L·x)·scale` for each column `x` (length `L.ncols()`) of `values`
/// (column-major, `columns` columns); `product` is scratch.
fn whiten_columns(
    l: &DMatrix<f64>,
    diagonal: bool,
    scale: f64,
    values: &mut [f64],
    product: &mut Vec<f64>,
) {
    let m = l.nrows();
    if m == 0 {
        return;
    }
    if diagonal {
        for col in values.chunks_exact_mut(m) {
            for (r, x) in col.iter_mut().enumerate() {
                *x = (l[(r, r)] * *x) * scale;
            }
        }
        return;
    }
    // A plain column loop: the general matrix product's packing dominated
    // for 6×6 blocks.
    let l_values = l.as_slice();
    product.clear();
    product.resize(m, 0.0);
    for col in values.chunks_exact_mut(m) {
        product.fill(0.0);
        for (kk, &b) in col.iter().enumerate() {
            for (o, &a) in product.iter_mut().zip(&l_values[kk * m..(kk + 1) * m]) {
                *o += a * b;
            }
        }
        for (x, &p) in col.iter_mut().zip(product.iter()) {
            *x = p * scale;
        }
    }
}

/// `(weight, cost)` of a whitened residual: the IRLS weight and `ρ(‖r‖)`
/// (`½‖r‖²` without a kernel).
fn weight_and_cost(noise: &NoiseModel, whitened: &[f64]) -> (f64, f64) {
    let s = whitened.iter().map(|x| x * x).sum::<f64>().sqrt();
    match noise.robust {
        Some(kernel) => (kernel.weight(s), kernel.loss(s)),
        None => (1.0, 0.5 * s * s),
    }
}

/// The shape error of a factor whose noise model does not match its residual.
fn noise_mismatch(factor_id: usize, factor: &dyn Factor, cols: &[usize]) -> SolverError {
    let l = &factor.noise().sqrt_information;
    SolverError::DimensionMismatch {
        factor: factor_id,
        key: factor.keys().first().copied().unwrap_or(Key::EgoPose(0)),
        residual_dim: factor.residual_dim(),
        noise_dim: l.ncols(),
        jacobian_rows: l.nrows(),
        jacobian_cols: 0,
        tangent_dim: cols.first().copied().unwrap_or(0),
    }
}

/// Checks the noise model's shape against the factor's residual, then
/// writes the factor's whitened, reweighted residual and Jacobians (keys of
/// tangent dims `buffers.cols`, filled by the caller) into `buffers` and
/// returns its cost.
fn whitened_linearization(
    factor_id: usize,
    factor: &dyn Factor,
    values: &Values,
    buffers: &mut FactorBuffers,
) -> Result<f64, SolverError> {
    let noise = factor.noise();
    let l = &noise.sqrt_information;
    let rows = factor.residual_dim();
    if l.nrows() != rows || l.ncols() != rows {
        return Err(noise_mismatch(factor_id, factor, &buffers.cols));
    }
    let FactorBuffers {
        residual,
        jacobians,
        product,
        cols,
    } = buffers;
    residual.clear();
    residual.resize(rows, 0.0);
    jacobians.clear();
    jacobians.resize(rows * cols.iter().sum::<usize>(), 0.0);
    factor.linearize_into(
        values,
        residual,
        &mut JacobiansMut::new(jacobians, rows, cols),
    );
    if residual
        .iter()
        .chain(jacobians.iter())
        .any(|v| !v.is_finite())
    {
        return Err(SolverError::NonFinite {
            factor: factor_id,
            keys: key_list(factor.keys()),
        });
    }
    let diagonal = is_diagonal(l);
    whiten_columns(l, diagonal, 1.0, residual, product);
    let (weight, cost) = weight_and_cost(noise, residual);
    let sqrt_w = weight.sqrt();
    if sqrt_w != 1.0 {
        for x in residual.iter_mut() {
            *x *= sqrt_w;
        }
    }
    whiten_columns(l, diagonal, sqrt_w, jacobians, product);
    Ok(cost)
}

/// Cost `ρ(‖L·r‖)` (or `½‖L·r‖²`) of one factor at `values`, its residual
/// written into `buffers`. Panics if the noise model does not match the
/// residual (the solver checks that when it linearizes).
fn factor_cost(factor: &dyn Factor, values: &Values, buffers: &mut FactorBuffers) -> f64 {
    let noise = factor.noise();
    let rows = factor.residual_dim();
    buffers.residual.clear();
    buffers.residual.resize(rows, 0.0);
    factor.residual_into(values, &mut buffers.residual);
    let l = &noise.sqrt_information;
    assert_eq!(
        l.shape(),
        (rows, rows),
        "noise model of the residual's dimension"
    );
    whiten_columns(
        l,
        is_diagonal(l),
        1.0,
        &mut buffers.residual,
        &mut buffers.product,
    );
    weight_and_cost(noise, &buffers.residual).1
}

fn key_list(keys: &[Key]) -> String {
    keys.iter()
        .map(|k| k.to_string())
        .collect::<Vec<_>>()
        .join(",")
}

/// Total cost `Σ ρ(‖L·r‖)` (or `½‖L·r‖²`) of `factors` at `values`.
///
/// # Errors
/// [`SolverError::MissingKey`] for a factor key without a value,
/// [`SolverError::NonFinite`] for a non-finite factor cost.
pub fn total_cost<F: Borrow<dyn Factor>>(
    factors: &[F],
    values: &Values,
) -> Result<f64, SolverError> {
    let mut cost = 0.0;
    let mut buffers = FactorBuffers::default();
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
        let l = &factor.noise().sqrt_information;
        if l.shape() != (factor.residual_dim(), factor.residual_dim()) {
            return Err(noise_mismatch(i, factor, &[]));
        }
        let c = factor_cost(factor, values, &mut buffers);
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
///
/// # Errors
/// A factor key without a value or outside `index`, shapes that disagree,
/// or non-finite residuals or Jacobians ([`SolverError`]).
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
pub(super) struct FactorPositions {
    flat: Vec<usize>,
    starts: Vec<usize>,
}

/// Whether [`linearize`] looks the keys up (checking them) or reuses the
/// positions of an earlier linearization over the same keys.
pub(super) enum KeyPositions<'a> {
    Record(&'a mut FactorPositions),
    Cached(&'a FactorPositions),
}

pub(super) fn linearize<F: Borrow<dyn Factor>>(
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
    let mut buffers = FactorBuffers::default();
    let mut looked_up = Vec::new();
    let mut jac_a_t = Vec::new();
    if let KeyPositions::Record(record) = &mut key_positions {
        record.flat.clear();
        record.starts.clear();
        record.starts.push(0);
    }
    for (i, factor) in factors.iter().enumerate() {
        let factor = factor.borrow();
        buffers.cols.clear();
        let c = match &mut key_positions {
            KeyPositions::Record(record) => {
                for key in factor.keys() {
                    let value = values.get(key).ok_or(SolverError::MissingKey {
                        factor: i,
                        key: *key,
                    })?;
                    buffers.cols.push(value.dim());
                }
                let c = whitened_linearization(i, factor, values, &mut buffers)?;
                looked_up.clear();
                for key in factor.keys() {
                    looked_up.push(index.position(key).ok_or(SolverError::UnknownKey(*key))?);
                }
                record.flat.extend_from_slice(&looked_up);
                record.starts.push(record.flat.len());
                c
            }
            KeyPositions::Cached(cached) => {
                let positions = &cached.flat[cached.starts[i]..cached.starts[i + 1]];
                buffers
                    .cols
                    .extend(positions.iter().map(|&p| index.dims[p]));
                whitened_linearization(i, factor, values, &mut buffers)?
            }
        };
        cost += c;
        let positions = match &key_positions {
            KeyPositions::Record(record) => &record.flat[record.starts[i]..record.starts[i + 1]],
            KeyPositions::Cached(cached) => &cached.flat[cached.starts[i]..cached.starts[i + 1]],
        };
        let rows = buffers.residual.len();
        let residual = &buffers.residual;
        let mut start_a = 0;
        for &pa in positions {
            let (oa, da) = (index.offsets[pa], index.dims[pa]);
            let jac_a = &buffers.jacobians[start_a..start_a + rows * da];
            start_a += rows * da;
            // g_a += J_aᵀ·r
            for (g, col) in gradient.as_mut_slice()[oa..oa + da]
                .iter_mut()
                .zip(jac_a.chunks_exact(rows.max(1)))
            {
                *g += col.iter().zip(residual).map(|(j, r)| j * r).sum::<f64>();
            }
            transpose_into(jac_a, rows, da, &mut jac_a_t);
            let mut start_b = 0;
            for &pb in positions {
                let db = index.dims[pb];
                let jac_b = &buffers.jacobians[start_b..start_b + rows * db];
                start_b += rows * db;
                // Keep the lower triangle only (row position ≥ col position).
                if pa < pb {
                    continue;
                }
                let offset = *blocks.entry((pa, pb)).or_insert_with(|| {
                    let offset = block_values.len();
                    block_values.resize(offset + da * db, 0.0);
                    offset
                });
                // A key repeated within one factor lands here for both
                // (a, b) and (b, a), so the diagonal block stays symmetric.
                add_jacobian_product(
                    &mut block_values[offset..offset + da * db],
                    &jac_a_t,
                    jac_b,
                    rows,
                );
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

/// `a_t` := `Aᵀ` for `A` column-major `m × n` in `a`: row `k` of `A`
/// becomes contiguous, for [`add_jacobian_product`].
fn transpose_into(a: &[f64], m: usize, n: usize, a_t: &mut Vec<f64>) {
    a_t.clear();
    a_t.resize(m * n, 0.0);
    if m == 0 {
        return;
    }
    for (i, a_col) in a.chunks_exact(m).enumerate() {
        for (k, &x) in a_col.iter().enumerate() {
            a_t[k * n + i] = x;
        }
    }
}

/// `block += Aᵀ·B` (column-major `block`, `A.ncols() × B.ncols()`) from
/// `a_t` = `Aᵀ` ([`transpose_into`]) and `b` column-major with `m` rows:
/// each block column gathers rows of `A` scaled by one entry of `B`,
/// independent multiply-adds the compiler vectorizes (a dot product per
/// entry is one serial chain of additions), fully unrolled for the common
/// 3- and 6-dimensional tangents.
fn add_jacobian_product(block: &mut [f64], a_t: &[f64], b: &[f64], m: usize) {
    if m == 0 {
        return;
    }
    let rows = a_t.len() / m;
    debug_assert_eq!(block.len(), rows * (b.len() / m));
    match rows {
        3 => add_jacobian_product_fixed::<3>(block, a_t, b, m),
        6 => add_jacobian_product_fixed::<6>(block, a_t, b, m),
        _ => {
            for (b_col, block_col) in b.chunks_exact(m).zip(block.chunks_exact_mut(rows)) {
                for (&bk, a_row) in b_col.iter().zip(a_t.chunks_exact(rows)) {
                    for (out, &x) in block_col.iter_mut().zip(a_row) {
                        *out += x * bk;
                    }
                }
            }
        }
    }
}

fn add_jacobian_product_fixed<const R: usize>(block: &mut [f64], a_t: &[f64], b: &[f64], m: usize) {
    for (b_col, block_col) in b.chunks_exact(m).zip(block.chunks_exact_mut(R)) {
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
pub(super) fn cost_of_checked<F: Borrow<dyn Factor>>(
    factors: &[F],
    values: &Values,
) -> Result<f64, SolverError> {
    let mut cost = 0.0;
    let mut buffers = FactorBuffers::default();
    for (i, factor) in factors.iter().enumerate() {
        let factor = factor.borrow();
        let c = factor_cost(factor, values, &mut buffers);
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
