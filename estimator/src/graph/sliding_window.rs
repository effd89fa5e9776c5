//! Fixed-lag smoother: values and factors of the current window plus the
//! marginal priors summarizing everything marginalized so far.
//!
//! Marginalizing folds in only the priors that touch the removed keys, so
//! independent parts of the window (the ego and each tracked object, once
//! their coupling at the oldest frame is conditioned away, see
//! [`SlidingWindowSmoother::condition_factors`]) keep separate small priors.

use super::conditioned_factor::ConditionedFactor;
use super::elimination::SolverWorkspace;
use super::factor::Factor;
use super::key::Key;
use super::linearization::{FastHashMap, total_cost};
use super::marginalization::{
    MarginalPriorFactor, MarginalizationConfig, MarginalizationError, marginalize,
};
use super::marginals::marginal_covariance;
use super::optimizer::{SolverConfig, SolverError, SolverReport, optimize_with};
use super::values::{Values, Variable};
use nalgebra::DMatrix;
use std::collections::BTreeSet;

/// Bad use of the window (named keys), or a failed solve/marginalization.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WindowError {
    /// A variable was added twice.
    #[error("key {0} already has a value in the window")]
    DuplicateKey(Key),
    /// A named key is not in the window.
    #[error("key {0} is not in the window")]
    UnknownKey(Key),
    /// A factor names a key the window does not hold.
    #[error("factor references key {0}, which is not in the window")]
    FactorKeyMissing(Key),
    #[error(transparent)]
    /// An optimization failed.
    Solver(#[from] SolverError),
    #[error(transparent)]
    /// A marginalization failed.
    Marginalization(#[from] MarginalizationError),
}

/// A sliding-window smoother over any keys (ego states, objects).
#[derive(Debug, Default)]
pub struct SlidingWindowSmoother {
    values: Values,
    factors: Vec<Box<dyn Factor>>,
    priors: Vec<MarginalPriorFactor>,
    marginalization: MarginalizationConfig,
    /// The window's parts keep their shapes from frame to frame: their
    /// symbolic factorizations are kept here.
    workspace: SolverWorkspace,
}

/// The window's factors followed by its marginal priors.
fn window_factors<'a>(
    factors: &'a [Box<dyn Factor>],
    priors: &'a [MarginalPriorFactor],
) -> Vec<&'a (dyn Factor + 'static)> {
    factors
        .iter()
        .map(|f| f.as_ref())
        .chain(priors.iter().map(|p| p as &(dyn Factor + 'static)))
        .collect()
}

/// Groups factors that share keys (transitively); returns factor indices
/// per group, in first-appearance order.
fn connected_parts(factors: &[&(dyn Factor + 'static)]) -> Vec<Vec<usize>> {
    let mut parent: Vec<usize> = (0..factors.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut owner: FastHashMap<Key, usize> =
        FastHashMap::with_capacity_and_hasher(factors.len(), Default::default());
    for (i, f) in factors.iter().enumerate() {
        for key in f.keys() {
            match owner.get(key) {
                Some(&j) => {
                    let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                    parent[a.max(b)] = a.min(b);
                }
                None => {
                    owner.insert(*key, i);
                }
            }
        }
    }
    let mut parts: Vec<Vec<usize>> = Vec::new();
    let mut index_of_root: FastHashMap<usize, usize> = FastHashMap::default();
    for i in 0..factors.len() {
        let r = root(&mut parent, i);
        let part = *index_of_root.entry(r).or_insert_with(|| {
            parts.push(Vec::new());
            parts.len() - 1
        });
        parts[part].push(i);
    }
    parts
}

impl SlidingWindowSmoother {
    /// An empty window with the default marginalization settings.
    pub fn new() -> SlidingWindowSmoother {
        SlidingWindowSmoother::default()
    }

    /// An empty window marginalizing with `config`.
    pub fn with_marginalization_config(config: MarginalizationConfig) -> SlidingWindowSmoother {
        SlidingWindowSmoother {
            marginalization: config,
            ..SlidingWindowSmoother::default()
        }
    }

    /// Adds a variable with its initial value.
    ///
    /// # Errors
    /// [`WindowError::DuplicateKey`] when `key` is already in the window.
    pub fn add_variable(&mut self, key: Key, value: Variable) -> Result<(), WindowError> {
        if self.values.contains(&key) {
            return Err(WindowError::DuplicateKey(key));
        }
        self.values.insert(key, value);
        Ok(())
    }

    /// Overwrites the value of an existing variable (e.g. a re-prediction).
    ///
    /// # Errors
    /// [`WindowError::UnknownKey`] when `key` is not in the window.
    pub fn set_value(&mut self, key: Key, value: Variable) -> Result<(), WindowError> {
        if !self.values.contains(&key) {
            return Err(WindowError::UnknownKey(key));
        }
        self.values.insert(key, value);
        Ok(())
    }

    /// Adds a factor; every key it references must already be in the window.
    ///
    /// # Errors
    /// [`WindowError::FactorKeyMissing`] naming the first key of `factor` the
    /// window does not hold.
    pub fn add_factor(&mut self, factor: Box<dyn Factor>) -> Result<(), WindowError> {
        if let Some(key) = factor.keys().iter().find(|k| !self.values.contains(k)) {
            return Err(WindowError::FactorKeyMissing(*key));
        }
        self.factors.push(factor);
        Ok(())
    }

    /// All factors of the window, the marginal priors included.
    fn all_factors(&self) -> Vec<&(dyn Factor + 'static)> {
        window_factors(&self.factors, &self.priors)
    }

    /// Optimizes every variable of the window.
    ///
    /// # Errors
    /// A failed solve ([`WindowError::Solver`]).
    pub fn optimize(&mut self, config: &SolverConfig) -> Result<SolverReport, WindowError> {
        // Borrowed field by field: the workspace is borrowed mutably.
        let factors = window_factors(&self.factors, &self.priors);
        let mut values = self.values.clone();
        let report = optimize_with(&factors, &mut values, config, &mut self.workspace)?;
        self.values = values;
        Ok(report)
    }

    /// Optimizes, each on its own, the connected parts of the window (sets
    /// of variables linked by factors or priors) whose keys `select` picks.
    /// Parts share no variable, so this reaches the same optimum as one
    /// joint solve, and each part stops after its own number of iterations.
    ///
    /// # Errors
    /// A failed solve of any part ([`WindowError::Solver`]).
    pub fn optimize_parts(
        &mut self,
        config: &SolverConfig,
        select: impl Fn(&[Key]) -> bool,
    ) -> Result<Vec<SolverReport>, WindowError> {
        let factors = window_factors(&self.factors, &self.priors);
        let mut reports = Vec::new();
        let mut solved: Vec<Values> = Vec::new();
        for part in connected_parts(&factors) {
            let part_factors: Vec<&(dyn Factor + 'static)> =
                part.iter().map(|&i| factors[i]).collect();
            let keys: BTreeSet<Key> = part_factors
                .iter()
                .flat_map(|f| f.keys().iter().copied())
                .collect();
            let keys: Vec<Key> = keys.into_iter().collect();
            if !select(&keys) {
                continue;
            }
            let mut values = Values::new();
            for key in &keys {
                values.insert(
                    *key,
                    *self.values.get(key).expect("factor keys are in the window"),
                );
            }
            reports.push(optimize_with(
                &part_factors,
                &mut values,
                config,
                &mut self.workspace,
            )?);
            solved.push(values);
        }
        for values in solved {
            for (key, value) in values.iter() {
                self.values.insert(*key, *value);
            }
        }
        Ok(reports)
    }

    /// Removes `keys` from the window: every factor and marginal prior
    /// touching them is folded into a new marginal prior at the current
    /// values. Factors touching only removed keys vanish with them.
    ///
    /// # Errors
    /// A failed marginalization ([`WindowError::Marginalization`]).
    pub fn marginalize(&mut self, keys: &[Key]) -> Result<(), WindowError> {
        let removed: BTreeSet<Key> = keys.iter().copied().collect();
        if let Some(key) = removed.iter().find(|k| !self.values.contains(k)) {
            return Err(WindowError::UnknownKey(*key));
        }
        if removed.is_empty() {
            return Ok(());
        }
        self.fold(|keys| keys.iter().any(|k| removed.contains(k)), &removed)
    }

    /// Replaces every factor and prior whose keys all lie in `keys` by one
    /// linear prior at the current values (nothing is removed). Bounds the
    /// factor count of a long-lived variable, e.g. a parked car's single
    /// pose node observed in every frame.
    ///
    /// # Errors
    /// A failed linearization of the folded factors
    /// ([`WindowError::Marginalization`]).
    pub fn fold_factors(&mut self, keys: &[Key]) -> Result<(), WindowError> {
        let kept: BTreeSet<Key> = keys.iter().copied().collect();
        if let Some(key) = kept.iter().find(|k| !self.values.contains(k)) {
            return Err(WindowError::UnknownKey(*key));
        }
        self.fold(
            |keys| !keys.is_empty() && keys.iter().all(|k| kept.contains(k)),
            &BTreeSet::new(),
        )
    }

    /// Folds the factors and priors selected by `select` (on their keys) into
    /// one new prior, eliminating `removed`.
    fn fold(
        &mut self,
        select: impl Fn(&[Key]) -> bool,
        removed: &BTreeSet<Key>,
    ) -> Result<(), WindowError> {
        let (touching, rest): (Vec<_>, Vec<_>) = std::mem::take(&mut self.factors)
            .into_iter()
            .partition(|f| select(f.keys()));
        let (old_priors, other_priors): (Vec<_>, Vec<_>) = std::mem::take(&mut self.priors)
            .into_iter()
            .partition(|p| select(p.keys()));
        let mut to_fold: Vec<&(dyn Factor + 'static)> =
            touching.iter().map(|f| f.as_ref()).collect();
        to_fold.extend(old_priors.iter().map(|p| p as &(dyn Factor + 'static)));
        // One prior per connected part: parts that share no key (the ego and
        // each object) stay separate, so the priors stay small and sparse.
        let mut new_priors = Vec::new();
        for part in connected_parts(&to_fold) {
            let factors: Vec<&(dyn Factor + 'static)> = part.iter().map(|&i| to_fold[i]).collect();
            let removed_keys: Vec<Key> = removed
                .iter()
                .filter(|k| factors.iter().any(|f| f.keys().contains(k)))
                .copied()
                .collect();
            match marginalize(&factors, &self.values, &removed_keys, &self.marginalization) {
                Ok(p) => new_priors.extend(p),
                Err(e) => {
                    // Leave the window untouched on failure.
                    drop(to_fold);
                    self.factors = touching.into_iter().chain(rest).collect();
                    self.priors = old_priors.into_iter().chain(other_priors).collect();
                    return Err(e.into());
                }
            }
        }
        drop(to_fold);
        self.factors = rest;
        self.priors = other_priors;
        self.priors.extend(new_priors);
        for key in removed {
            self.values.remove(key);
        }
        Ok(())
    }

    /// Holds the keys in `fixed` at their current values inside every factor
    /// that touches one of them and that `select` picks (the keys stay in the
    /// window for the other factors). Used before marginalizing the oldest
    /// frame: conditioning its object observations on the ego pose keeps
    /// each object's marginal prior separate from the ego's.
    ///
    /// # Errors
    /// [`WindowError::UnknownKey`] when a key of `fixed` is not in the window.
    pub fn condition_factors(
        &mut self,
        fixed: &[Key],
        select: impl Fn(&dyn Factor) -> bool,
    ) -> Result<usize, WindowError> {
        let mut held = Values::new();
        for key in fixed {
            let value = self.values.get(key).ok_or(WindowError::UnknownKey(*key))?;
            held.insert(*key, *value);
        }
        let mut conditioned = 0;
        let factors = std::mem::take(&mut self.factors);
        for factor in factors {
            let touches = factor.keys().iter().any(|k| held.contains(k));
            if touches && select(factor.as_ref()) {
                // With every key fixed the factor says nothing about the
                // rest of the window and is dropped.
                if let Ok(c) = ConditionedFactor::new(factor, held.clone()) {
                    self.factors.push(Box::new(c));
                    conditioned += 1;
                }
            } else {
                self.factors.push(factor);
            }
        }
        Ok(conditioned)
    }

    /// Re-conditions every conditioned factor on the current values of the
    /// keys it holds (those still in the window). After an optimization
    /// moved the ego, one-way observations (the ego informs the objects, not
    /// the reverse) follow it this way.
    pub fn refresh_conditioned(&mut self) {
        for f in &mut self.factors {
            f.refresh_fixed(&self.values);
        }
    }

    /// Marginalizes every key of frame `frame`; returns the removed keys.
    ///
    /// # Errors
    /// A failed marginalization ([`WindowError::Marginalization`]).
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

    /// The current values of the window's variables.
    pub fn values(&self) -> &Values {
        &self.values
    }

    /// Number of factors, not counting the marginal prior.
    pub fn factor_count(&self) -> usize {
        self.factors.len()
    }

    /// The window's factors (marginal priors not included).
    pub fn factors(&self) -> &[Box<dyn Factor>] {
        &self.factors
    }

    /// The window's variables, in key order.
    pub fn keys(&self) -> Vec<Key> {
        self.values.keys().copied().collect()
    }

    /// The marginal priors (one per independent part of the window).
    pub fn marginal_priors(&self) -> &[MarginalPriorFactor] {
        &self.priors
    }

    /// Smallest frame index among the window's keys.
    pub fn oldest_frame(&self) -> Option<u64> {
        self.values.keys().filter_map(|k| k.frame()).min()
    }

    /// Marginal covariance of `key` (tangent space) at the current values.
    ///
    /// # Errors
    /// As [`SlidingWindowSmoother::joint_marginal_covariance`].
    pub fn marginal_covariance(&self, key: Key) -> Result<DMatrix<f64>, WindowError> {
        self.joint_marginal_covariance(&[key])
    }

    /// Joint marginal covariance of `keys` (stacked tangents, in that order).
    ///
    /// # Errors
    /// [`WindowError::UnknownKey`] for a key not in the window; a singular
    /// or non-finite Hessian ([`WindowError::Solver`]).
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
    ///
    /// # Errors
    /// A factor with a non-finite cost ([`WindowError::Solver`]).
    pub fn cost(&self) -> Result<f64, WindowError> {
        Ok(total_cost(&self.all_factors(), &self.values)?)
    }
}
