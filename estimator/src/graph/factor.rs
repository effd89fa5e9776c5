//! The factor interface: a residual with its Jacobians, plus a noise model.
//! A factor writes them into buffers the caller owns ([`Factor::linearize_into`]),
//! so linearizing a graph allocates nothing per factor.

use super::key::Key;
use super::noise::NoiseModel;
use super::values::Values;
use nalgebra::constraint::{SameNumberOfColumns, SameNumberOfRows, ShapeConstraint};
use nalgebra::{DMatrix, DMatrixView, DMatrixViewMut, DVector, Dim, Dyn, Matrix, RawStorage};

/// Where a factor writes its Jacobians: one column-major block per key of
/// [`Factor::keys`], in that order, each `residual_dim × key tangent dim`,
/// wrt a right perturbation of the key; the blocks lie one after the other
/// in one flat buffer.
#[derive(Debug)]
pub struct JacobiansMut<'a> {
    values: &'a mut [f64],
    rows: usize,
    cols: &'a [usize],
}

impl<'a> JacobiansMut<'a> {
    /// Blocks of `rows` rows and `cols[i]` columns over `values`, whose
    /// length must be `rows · Σ cols`.
    pub fn new(values: &'a mut [f64], rows: usize, cols: &'a [usize]) -> JacobiansMut<'a> {
        assert_eq!(
            values.len(),
            rows * cols.iter().sum::<usize>(),
            "Jacobian buffer size"
        );
        JacobiansMut { values, rows, cols }
    }

    /// Number of blocks (keys).
    pub fn len(&self) -> usize {
        self.cols.len()
    }

    /// Whether there is no block.
    pub fn is_empty(&self) -> bool {
        self.cols.is_empty()
    }

    /// Rows of every block (the residual's dimension).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Columns of block `i` (the tangent dimension of key `i`).
    pub fn cols(&self, i: usize) -> usize {
        self.cols[i]
    }

    /// Block `i`, to write in place.
    pub fn block(&mut self, i: usize) -> DMatrixViewMut<'_, f64> {
        let start = self.rows * self.cols[..i].iter().sum::<usize>();
        let len = self.rows * self.cols[i];
        DMatrixViewMut::from_slice(
            &mut self.values[start..start + len],
            self.rows,
            self.cols[i],
        )
    }

    /// Sets block `i` to `m` (which must have the block's shape).
    pub fn set<R: Dim, C: Dim, S: RawStorage<f64, R, C>>(
        &mut self,
        i: usize,
        m: &Matrix<f64, R, C, S>,
    ) where
        ShapeConstraint: SameNumberOfRows<Dyn, R> + SameNumberOfColumns<Dyn, C>,
    {
        self.block(i).copy_from(m);
    }

    /// Sets block `i` to `scale · I` (square blocks).
    pub fn set_scaled_identity(&mut self, i: usize, scale: f64) {
        let mut block = self.block(i);
        block.fill(0.0);
        block.fill_diagonal(scale);
    }
}

/// Why a factor could not be built or evaluated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FactorError {
    /// A key of the factor has no value.
    #[error("factor needs key {0}, which has no value")]
    MissingKey(Key),
    /// A key holds another kind of variable than the factor needs.
    #[error("key {key} holds the wrong kind of variable for this factor (expected {expected})")]
    WrongKind {
        /// The key.
        key: Key,
        /// The kind of variable the factor needs.
        expected: &'static str,
    },
    /// A covariance given to the factor is not positive definite.
    #[error("covariance of {what} is not positive definite")]
    BadCovariance {
        /// Which covariance.
        what: &'static str,
    },
}

/// One term `½‖ρ(L·r(x))‖²` of the cost, GTSAM style: the factor knows its
/// residual and Jacobians; whitening and robust weighting are the solver's.
pub trait Factor: Send + Sync + std::fmt::Debug {
    /// The variables this factor connects, in the order of its Jacobians.
    fn keys(&self) -> &[Key];

    /// Dimension of the residual (the noise model's must match it).
    fn residual_dim(&self) -> usize;

    /// The noise model that whitens the residual (and its robust kernel).
    fn noise(&self) -> &NoiseModel;

    /// Writes the residual and the Jacobians at `values` (which hold every
    /// key of the factor, of the kinds it needs), unwhitened. `residual` has
    /// [`Factor::residual_dim`] entries; `jacobians` one block per key, each of
    /// the key's tangent dimension; every entry must be written.
    fn linearize_into(
        &self,
        values: &Values,
        residual: &mut [f64],
        jacobians: &mut JacobiansMut<'_>,
    );

    /// Writes the residual only (the same numbers as
    /// [`Factor::linearize_into`]'s).
    fn residual_into(&self, values: &Values, residual: &mut [f64]);

    /// Updates values the factor holds fixed (see
    /// [`super::ConditionedFactor`]) from `values`; others ignore it.
    fn refresh_fixed(&mut self, _values: &Values) {}

    /// The residual at `values`, allocated (tests and diagnostics; the
    /// solver writes into its own buffers).
    fn residual(&self, values: &Values) -> DVector<f64> {
        let mut r = DVector::zeros(self.residual_dim());
        self.residual_into(values, r.as_mut_slice());
        r
    }
}

/// A factor's residual and its Jacobians at some values, unwhitened, owned:
/// [`Factor::linearize_into`] into fresh buffers (tests and diagnostics).
#[derive(Debug, Clone, PartialEq)]
pub struct Linearization {
    /// The residual `r(x)`, unwhitened.
    pub residual: DVector<f64>,
    /// One block per key of [`Factor::keys`], in that order:
    /// `residual_dim × key tangent dim`, wrt a right perturbation of the key.
    pub jacobians: Vec<DMatrix<f64>>,
}

impl Linearization {
    /// Linearizes `factor` at `values`. Panics if a key has no value.
    pub fn of<F: Factor + ?Sized>(factor: &F, values: &Values) -> Linearization {
        let rows = factor.residual_dim();
        let cols: Vec<usize> = factor
            .keys()
            .iter()
            .map(|key| {
                values
                    .get(key)
                    .unwrap_or_else(|| panic!("no value for {key}"))
                    .dim()
            })
            .collect();
        let mut residual = DVector::zeros(rows);
        let mut flat = vec![0.0; rows * cols.iter().sum::<usize>()];
        factor.linearize_into(
            values,
            residual.as_mut_slice(),
            &mut JacobiansMut::new(&mut flat, rows, &cols),
        );
        let mut jacobians = Vec::with_capacity(cols.len());
        let mut start = 0;
        for &c in &cols {
            jacobians.push(
                DMatrixView::from_slice(&flat[start..start + rows * c], rows, c).into_owned(),
            );
            start += rows * c;
        }
        Linearization {
            residual,
            jacobians,
        }
    }
}

/// Largest absolute difference between each analytic Jacobian block of
/// `factor` at `values` and central finite differences of
/// [`Factor::residual_into`] through the keys' retractions (step `h`).
/// Panics if `linearize_into`'s residual differs from `residual_into`'s.
/// Every factor's tests call this.
pub fn check_factor_jacobians<F: Factor + ?Sized>(factor: &F, values: &Values, h: f64) -> f64 {
    let lin = Linearization::of(factor, values);
    let residual = factor.residual(values);
    let mismatch = (&lin.residual - &residual).amax();
    assert!(
        mismatch <= 1e-9 * residual.amax().max(1.0),
        "linearize_into and residual_into disagree by {mismatch:e}"
    );
    let mut worst: f64 = 0.0;
    for (block, key) in factor.keys().iter().enumerate() {
        let dim = values
            .get(key)
            .unwrap_or_else(|| panic!("no value for {key}"))
            .dim();
        for i in 0..dim {
            let mut delta = vec![0.0; dim];
            delta[i] = h;
            let mut plus = values.clone();
            plus.retract_key(key, &delta);
            delta[i] = -h;
            let mut minus = values.clone();
            minus.retract_key(key, &delta);
            let numeric = (factor.residual(&plus) - factor.residual(&minus)) / (2.0 * h);
            let diff = (numeric - lin.jacobians[block].column(i)).amax();
            worst = worst.max(diff);
        }
    }
    worst
}
