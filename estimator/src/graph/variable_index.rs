//! The column layout of the stacked tangent vector: which variable owns
//! which columns of `H` and of the step `δ`.

use super::key::Key;
use super::optimizer::SolverError;
use super::values::Values;
use std::collections::BTreeMap;

/// Column layout of the stacked tangent vector: key → (offset, dim).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VariableIndex {
    keys: Vec<Key>,
    pub(super) offsets: Vec<usize>,
    pub(super) dims: Vec<usize>,
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
    ///
    /// # Errors
    /// [`SolverError::UnknownKey`] for a key without a value.
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

    /// The variables in column order.
    pub fn keys(&self) -> &[Key] {
        &self.keys
    }

    /// Number of variables.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// Whether there is no variable.
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

    /// Length of the stacked tangent vector.
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
