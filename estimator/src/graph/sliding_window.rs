//! Fixed-lag smoother: values and factors of the current window plus one
//! marginal prior summarizing everything marginalized so far.

use super::factor::Factor;
use super::key::Key;
use super::marginalization::{
    MarginalPriorFactor, MarginalizationConfig, MarginalizationError, marginalize,
};
use super::solver::{
    SolverConfig, SolverError, SolverReport, marginal_covariance, optimize, total_cost,
};
use super::values::{Values, Variable};
use nalgebra::DMatrix;
use std::collections::BTreeSet;

/// Bad use of the window (named keys), or a failed solve/marginalization.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WindowError {
    #[error("key {0} already has a value in the window")]
    DuplicateKey(Key),
    #[error("key {0} is not in the window")]
    UnknownKey(Key),
    #[error("factor references key {0}, which is not in the window")]
    FactorKeyMissing(Key),
    #[error(transparent)]
    Solver(#[from] SolverError),
    #[error(transparent)]
    Marginalization(#[from] MarginalizationError),
}

/// A sliding-window smoother over any keys (ego states, objects).
#[derive(Debug, Default)]
pub struct SlidingWindowSmoother {
    values: Values,
    factors: Vec<Box<dyn Factor>>,
    prior: Option<MarginalPriorFactor>,
    marginalization: MarginalizationConfig,
}

impl SlidingWindowSmoother {
    pub fn new() -> SlidingWindowSmoother {
        SlidingWindowSmoother::default()
    }

    pub fn with_marginalization_config(config: MarginalizationConfig) -> SlidingWindowSmoother {
        SlidingWindowSmoother {
            marginalization: config,
            ..SlidingWindowSmoother::default()
        }
    }

    /// Adds a variable with its initial value.
    pub fn add_variable(&mut self, key: Key, value: Variable) -> Result<(), WindowError> {
        if self.values.contains(&key) {
            return Err(WindowError::DuplicateKey(key));
        }
        self.values.insert(key, value);
        Ok(())
    }

    /// Overwrites the value of an existing variable (e.g. a re-prediction).
    pub fn set_value(&mut self, key: Key, value: Variable) -> Result<(), WindowError> {
        if !self.values.contains(&key) {
            return Err(WindowError::UnknownKey(key));
        }
        self.values.insert(key, value);
        Ok(())
    }

    /// Adds a factor; every key it references must already be in the window.
    pub fn add_factor(&mut self, factor: Box<dyn Factor>) -> Result<(), WindowError> {
        if let Some(key) = factor.keys().iter().find(|k| !self.values.contains(k)) {
            return Err(WindowError::FactorKeyMissing(*key));
        }
        self.factors.push(factor);
        Ok(())
    }

    /// All factors of the window, the marginal prior included.
    fn all_factors(&self) -> Vec<&(dyn Factor + 'static)> {
        let mut all: Vec<&(dyn Factor + 'static)> =
            self.factors.iter().map(|f| f.as_ref()).collect();
        if let Some(prior) = &self.prior {
            all.push(prior);
        }
        all
    }

    /// Optimizes every variable of the window.
    pub fn optimize(&mut self, config: &SolverConfig) -> Result<SolverReport, WindowError> {
        let factors = self.all_factors();
        let mut values = self.values.clone();
        let report = optimize(&factors, &mut values, config)?;
        self.values = values;
        Ok(report)
    }

    /// Removes `keys` from the window: every factor touching them (and the
    /// previous marginal prior) is folded into a new marginal prior at the
    /// current values. Factors touching only removed keys vanish with them.
    pub fn marginalize(&mut self, keys: &[Key]) -> Result<(), WindowError> {
        let removed: BTreeSet<Key> = keys.iter().copied().collect();
        if let Some(key) = removed.iter().find(|k| !self.values.contains(k)) {
            return Err(WindowError::UnknownKey(*key));
        }
        if removed.is_empty() {
            return Ok(());
        }
        let (touching, rest): (Vec<_>, Vec<_>) = std::mem::take(&mut self.factors)
            .into_iter()
            .partition(|f| f.keys().iter().any(|k| removed.contains(k)));
        let mut to_fold: Vec<&(dyn Factor + 'static)> =
            touching.iter().map(|f| f.as_ref()).collect();
        // The old prior is always folded in, so there is one prior at a time.
        if let Some(prior) = &self.prior {
            to_fold.push(prior);
        }
        let removed_keys: Vec<Key> = removed.iter().copied().collect();
        let new_prior =
            match marginalize(&to_fold, &self.values, &removed_keys, &self.marginalization) {
                Ok(p) => p,
                Err(e) => {
                    // Leave the window untouched on failure.
                    self.factors = touching.into_iter().chain(rest).collect();
                    return Err(e.into());
                }
            };
        self.factors = rest;
        self.prior = new_prior;
        for key in &removed {
            self.values.remove(key);
        }
        Ok(())
    }

    /// Marginalizes every key of frame `frame`; returns the removed keys.
    pub fn marginalize_frame(&mut self, frame: u64) -> Result<Vec<Key>, WindowError> {
        let keys: Vec<Key> = self
            .values
            .keys()
            .filter(|k| k.frame() == Some(frame))
            .copied()
            .collect();
        self.marginalize(&keys)?;
        Ok(keys)
    }

    pub fn values(&self) -> &Values {
        &self.values
    }

    /// Number of factors, not counting the marginal prior.
    pub fn factor_count(&self) -> usize {
        self.factors.len()
    }

    pub fn factors(&self) -> &[Box<dyn Factor>] {
        &self.factors
    }

    pub fn keys(&self) -> Vec<Key> {
        self.values.keys().copied().collect()
    }

    pub fn marginal_prior(&self) -> Option<&MarginalPriorFactor> {
        self.prior.as_ref()
    }

    /// Smallest frame index among the window's keys.
    pub fn oldest_frame(&self) -> Option<u64> {
        self.values.keys().filter_map(|k| k.frame()).min()
    }

    /// Marginal covariance of `key` (tangent space) at the current values.
    pub fn marginal_covariance(&self, key: Key) -> Result<DMatrix<f64>, WindowError> {
        self.joint_marginal_covariance(&[key])
    }

    /// Joint marginal covariance of `keys` (stacked tangents, in that order).
    pub fn joint_marginal_covariance(&self, keys: &[Key]) -> Result<DMatrix<f64>, WindowError> {
        if let Some(key) = keys.iter().find(|k| !self.values.contains(k)) {
            return Err(WindowError::UnknownKey(*key));
        }
        Ok(marginal_covariance(
            &self.all_factors(),
            &self.values,
            keys,
        )?)
    }

    /// Total cost of the window (the marginal prior included) at the current values.
    pub fn cost(&self) -> Result<f64, WindowError> {
        Ok(total_cost(&self.all_factors(), &self.values)?)
    }
}
