//! Elimination: a fill-reducing block ordering (AMD on the graph of
//! variables) and faer's supernodal sparse Cholesky of `H + diag(damping)`,
//! with the symbolic analyses kept in a reusable [`SolverWorkspace`].

use super::linearization::{BlockPattern, NormalEquations};
use super::optimizer::SolverError;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::linalg::{SupernodalThreshold, amd};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, Mat, Side};
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
pub(super) struct SparseCholesky {
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

/// Buffers and symbolic factorizations that [`optimize_with`](super::optimize_with) reuses
/// across calls: pass the same workspace to repeated solves of problems of
/// recurring shapes (a sliding window's parts, frame after frame).
pub struct SolverWorkspace(pub(super) SparseCholesky);

impl SolverWorkspace {
    /// An empty workspace.
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

    pub(super) fn new() -> SparseCholesky {
        SparseCholesky {
            structures: Vec::new(),
            matrix_values: Vec::new(),
            factored: false,
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
    /// positive definite. Builds the ordering, pattern and symbolic
    /// analysis only for a block structure not seen among the kept ones.
    pub(super) fn factorize(
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
    pub(super) fn solve_in_place(&mut self, mut rhs: faer::MatMut<'_, f64>) {
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
        assert!((x - dense).amax() < 1e-9);
    }
}
