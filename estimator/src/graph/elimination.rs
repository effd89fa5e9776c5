//! Elimination: the Cholesky factorization of `H + diag(damping)`. Small
//! problems (a sliding window's connected parts, mostly) take a dense
//! Cholesky; larger ones a fill-reducing block ordering (AMD on the graph of
//! variables) and faer's supernodal sparse Cholesky, with the symbolic
//! analyses kept in a reusable [`SolverWorkspace`].

use super::linearization::{BlockPattern, NormalEquations};
use super::optimizer::SolverError;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::linalg::{SupernodalThreshold, amd};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, Mat, Par, Side};
use nalgebra::DVector;

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
///
/// Problems of at most `dense_max_dim` dimensions skip all of that: `H` is
/// written into a dense matrix (in variable order) and factorized by a
/// plain dense Cholesky that skips zeros, cheaper than the sparse one's
/// bookkeeping at these sizes.
pub(super) struct SparseCholesky {
    /// Most recently used first, at most [`SparseCholesky::KEPT_PATTERNS`].
    structures: Vec<CholeskyStructure>,
    /// Values of `H + diag(damping)` on the front pattern (buffer reused).
    matrix_values: Vec<f64>,
    /// `H + diag(damping)`, then its factor `L` (lower triangle), of the
    /// latest dense factorization: column-major, `dense_dim²` values.
    dense: Vec<f64>,
    /// Dimension of `dense`.
    dense_dim: usize,
    /// One right-hand side of a dense solve.
    dense_rhs: Vec<f64>,
    /// Largest total dimension factorized densely.
    dense_max_dim: usize,
    /// Which factorization the latest successful [`SparseCholesky::factorize`] made.
    factored: Factored,
}

/// The state of a [`SparseCholesky`] after a factorization.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Factored {
    /// None, or it failed.
    No,
    /// `dense` holds `L`.
    Dense,
    /// The front structure holds `L`.
    Sparse,
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

/// Buffers and symbolic factorizations that [`optimize_with`](super::optimize_with) reuses
/// across calls: pass the same workspace to repeated solves of problems of
/// recurring shapes (a sliding window's parts, frame after frame).
pub struct SolverWorkspace(pub(super) SparseCholesky);

impl SolverWorkspace {
    /// An empty workspace: problems of at most
    /// [`SolverWorkspace::DENSE_MAX_DIM`] dimensions are factorized densely.
    pub fn new() -> SolverWorkspace {
        SolverWorkspace(SparseCholesky::new())
    }

    /// Largest total tangent dimension solved with a dense Cholesky by
    /// default; larger problems go the sparse way.
    pub const DENSE_MAX_DIM: usize = 200;

    /// An empty workspace that factorizes problems of at most
    /// `dense_max_dim` dimensions densely and larger ones sparsely (0: always
    /// sparse, `usize::MAX`: always dense). The two give the same steps to
    /// rounding.
    pub fn with_dense_max_dim(dense_max_dim: usize) -> SolverWorkspace {
        SolverWorkspace(SparseCholesky::with_dense_max_dim(dense_max_dim))
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

    pub(super) fn new() -> SparseCholesky {
        SparseCholesky::with_dense_max_dim(SolverWorkspace::DENSE_MAX_DIM)
    }

    /// See [`SolverWorkspace::with_dense_max_dim`].
    pub(super) fn with_dense_max_dim(dense_max_dim: usize) -> SparseCholesky {
        SparseCholesky {
            structures: Vec::new(),
            matrix_values: Vec::new(),
            dense: Vec::new(),
            dense_dim: 0,
            dense_rhs: Vec::new(),
            dense_max_dim,
            factored: Factored::No,
        }
    }

    /// Solves `(H + diag(damping))·x = rhs`; `Ok(None)` if not positive definite.
    pub(super) fn solve(
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
    /// positive definite. Dense up to `dense_max_dim` dimensions; sparse
    /// beyond, building the ordering, pattern and symbolic analysis only for
    /// a block structure not seen among the kept ones.
    pub(super) fn factorize(
        &mut self,
        normal: &NormalEquations,
        damping: &DVector<f64>,
    ) -> Result<bool, SolverError> {
        self.factored = Factored::No;
        if normal.index.total_dim() <= self.dense_max_dim {
            return self.factorize_dense(normal, damping);
        }
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
        if result.is_ok() {
            self.factored = Factored::Sparse;
        }
        Ok(result.is_ok())
    }

    /// [`SparseCholesky::factorize`] with a dense Cholesky, `H` in
    /// variable order (its lower triangle written block by block).
    fn factorize_dense(
        &mut self,
        normal: &NormalEquations,
        damping: &DVector<f64>,
    ) -> Result<bool, SolverError> {
        let n = normal.index.total_dim();
        self.dense_dim = n;
        self.dense.clear();
        self.dense.resize(n * n, 0.0);
        normal.write_lower(&mut self.dense);
        for (i, &d) in damping.iter().enumerate() {
            self.dense[i * n + i] += d;
        }
        let ok = dense_cholesky_in_place(&mut self.dense, n);
        if ok {
            self.factored = Factored::Dense;
        }
        Ok(ok)
    }

    /// `rhs ← (H + diag(damping))⁻¹·rhs` (rows in variable order) with the
    /// latest successful factorization.
    pub(super) fn solve_in_place(&mut self, mut rhs: faer::MatMut<'_, f64>) {
        if self.factored == Factored::Dense {
            let n = self.dense_dim;
            for c in 0..rhs.ncols() {
                self.dense_rhs.clear();
                self.dense_rhs.extend((0..n).map(|i| rhs[(i, c)]));
                dense_cholesky_solve_in_place(&self.dense, n, &mut self.dense_rhs);
                for (i, &x) in self.dense_rhs.iter().enumerate() {
                    rhs[(i, c)] = x;
                }
            }
            return;
        }
        let structure = match self.structures.first_mut() {
            Some(structure) if self.factored == Factored::Sparse => structure,
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

/// In-place Cholesky `A = L·Lᵀ` of the column-major `n × n` `a` (its lower
/// triangle read, `L` written there; the strict upper triangle is left
/// alone). Left-looking by columns, skipping the zero entries of `L`'s rows,
/// so the block sparsity of a window's `H` (an object's chain couples only
/// neighbouring variables) saves most of the work. `false` if a pivot is not
/// positive (or not finite): not positive definite.
fn dense_cholesky_in_place(a: &mut [f64], n: usize) -> bool {
    debug_assert_eq!(a.len(), n * n);
    for j in 0..n {
        let (done, rest) = a.split_at_mut(j * n);
        let col_j = &mut rest[j..n];
        for k in 0..j {
            let l_jk = done[k * n + j];
            if l_jk != 0.0 {
                for (x, &l) in col_j.iter_mut().zip(&done[k * n + j..k * n + n]) {
                    *x -= l_jk * l;
                }
            }
        }
        let pivot = col_j[0];
        if !(pivot > 0.0 && pivot.is_finite()) {
            return false;
        }
        let l_jj = pivot.sqrt();
        col_j[0] = l_jj;
        let inv = 1.0 / l_jj;
        for x in &mut col_j[1..] {
            *x *= inv;
        }
    }
    true
}

/// `x ← (L·Lᵀ)⁻¹·x` with the factor of [`dense_cholesky_in_place`].
fn dense_cholesky_solve_in_place(l: &[f64], n: usize, x: &mut [f64]) {
    // L·y = x, by columns.
    for j in 0..n {
        let col = &l[j * n..(j + 1) * n];
        let y_j = x[j] / col[j];
        x[j] = y_j;
        if y_j != 0.0 {
            for (xi, &lij) in x[j + 1..].iter_mut().zip(&col[j + 1..]) {
                *xi -= y_j * lij;
            }
        }
    }
    // Lᵀ·x = y, by rows of Lᵀ (columns of L).
    for j in (0..n).rev() {
        let col = &l[j * n..(j + 1) * n];
        let dot: f64 = x[j + 1..]
            .iter()
            .zip(&col[j + 1..])
            .map(|(a, b)| a * b)
            .sum();
        x[j] = (x[j] - dot) / col[j];
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::between_factor::BetweenFactor;
    use crate::graph::factor::Factor;
    use crate::graph::key::Key;
    use crate::graph::linearization::linearize_normal_equations;
    use crate::graph::noise::NoiseModel;
    use crate::graph::prior_factor::PriorFactor;
    use crate::graph::values::{Values, Variable};
    use crate::graph::variable_index::VariableIndex;
    use crate::lie;
    use nalgebra::{DMatrix, Isometry3, Vector6};

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
        assert!((&x - &dense).amax() < 1e-9);
        // The dense Cholesky (the small problems' path) agrees, for one
        // right-hand side and for several.
        let mut dense_path = SparseCholesky::with_dense_max_dim(usize::MAX);
        let y = dense_path
            .solve(&normal, &damping, &rhs)
            .unwrap()
            .expect("SPD");
        assert!((&x - &y).amax() < 1e-12 * x.amax().max(1.0));
        let mut sparse_path = SparseCholesky::with_dense_max_dim(0);
        assert!(sparse_path.factorize(&normal, &damping).unwrap());
        let columns = |i: usize, c: usize| ((i * 3 + c * 7) as f64 * 0.21).cos();
        let mut several_dense = Mat::<f64>::from_fn(n, 3, columns);
        let mut several_sparse = Mat::<f64>::from_fn(n, 3, columns);
        dense_path.solve_in_place(several_dense.as_mut());
        sparse_path.solve_in_place(several_sparse.as_mut());
        for c in 0..3 {
            for i in 0..n {
                assert!((several_dense[(i, c)] - several_sparse[(i, c)]).abs() < 1e-12);
            }
        }
        // Not positive definite: both paths say so.
        let negative = DVector::from_element(n, -1e6);
        assert_eq!(dense_path.solve(&normal, &negative, &rhs).unwrap(), None);
        assert_eq!(sparse_path.solve(&normal, &negative, &rhs).unwrap(), None);
    }
}
