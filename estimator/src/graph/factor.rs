//! The factor interface: a residual with its Jacobians, plus a noise model.

use super::key::Key;
use super::noise::NoiseModel;
use super::values::Values;
use nalgebra::{DMatrix, DVector};

/// A factor's residual and its Jacobians at the current values, unwhitened.
#[derive(Debug, Clone, PartialEq)]
pub struct Linearization {
    /// The residual `r(x)`, unwhitened.
    pub residual: DVector<f64>,
    /// One block per key of [`Factor::keys`], in that order:
    /// `residual_dim × key tangent dim`, wrt a right perturbation of the key.
    pub jacobians: Vec<DMatrix<f64>>,
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

    /// Residual and Jacobians at `values` (which hold every key of the factor).
    fn linearize(&self, values: &Values) -> Linearization;

    /// The noise model that whitens the residual (and its robust kernel).
    fn noise(&self) -> &NoiseModel;

    /// Residual only; override when it is much cheaper than [`Factor::linearize`].
    fn residual(&self, values: &Values) -> DVector<f64> {
        self.linearize(values).residual
    }

    /// Updates values the factor holds fixed (see
    /// [`super::ConditionedFactor`]) from `values`; others ignore it.
    fn refresh_fixed(&mut self, _values: &Values) {}

    /// `ρ(‖L·r‖)`, or `½‖L·r‖²` without a robust kernel.
    fn cost(&self, values: &Values) -> f64 {
        let whitened = self.noise().whiten(&self.residual(values));
        let s = whitened.norm();
        match self.noise().robust {
            Some(kernel) => kernel.loss(s),
            None => 0.5 * s * s,
        }
    }
}

/// Largest absolute difference between each analytic Jacobian block of
/// `factor` at `values` and central finite differences through the keys'
/// retractions (step `h`). Every factor's tests call this.
pub fn check_factor_jacobians(factor: &dyn Factor, values: &Values, h: f64) -> f64 {
    let lin = factor.linearize(values);
    let mut worst: f64 = 0.0;
    for (block, key) in factor.keys().iter().enumerate() {
        let dim = values
            .get(key)
            .unwrap_or_else(|| panic!("no value for {key}"))
            .dim();
        assert_eq!(lin.jacobians[block].ncols(), dim, "Jacobian width of {key}");
        assert_eq!(
            lin.jacobians[block].nrows(),
            lin.residual.len(),
            "Jacobian height of {key}"
        );
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
