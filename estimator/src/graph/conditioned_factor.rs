//! A factor with some of its variables held fixed (conditioning).
//!
//! Marginalizing the oldest frame of a window that holds objects would couple
//! every object to every other through the shared ego pose (Schur fill-in),
//! so the marginal prior grows dense and the solve quadratic in the number of
//! objects. Conditioning the oldest frame's object observations on the ego
//! estimate first (the ego pose becomes a constant in them) keeps the priors
//! per object: the ego gives its information to the objects but takes none
//! back from that frame, the usual sparsification of sliding-window SLAM.

use super::factor::{Factor, JacobiansMut};
use super::key::Key;
use super::noise::NoiseModel;
use super::values::Values;

/// `inner` with the keys in `fixed` held at the values `fixed` stores.
#[derive(Debug)]
pub struct ConditionedFactor {
    inner: Box<dyn Factor>,
    fixed: Values,
    /// The inner factor's keys that stay variables, in its order.
    free_keys: Vec<Key>,
    /// For each free key, its position among the inner factor's keys.
    free_positions: Vec<usize>,
}

impl ConditionedFactor {
    /// Holds every key of `inner` that `fixed` has a value for. Returns the
    /// factor unchanged (as `Err`) when no key would remain free, since a
    /// factor without variables carries no information.
    ///
    /// # Errors
    /// The factor unchanged when `fixed` holds every one of its keys.
    pub fn new(
        inner: Box<dyn Factor>,
        fixed: Values,
    ) -> Result<ConditionedFactor, Box<dyn Factor>> {
        let mut free_keys = Vec::new();
        let mut free_positions = Vec::new();
        for (i, key) in inner.keys().iter().enumerate() {
            if !fixed.contains(key) {
                free_keys.push(*key);
                free_positions.push(i);
            }
        }
        if free_keys.is_empty() {
            return Err(inner);
        }
        Ok(ConditionedFactor {
            inner,
            fixed,
            free_keys,
            free_positions,
        })
    }

    /// The values merged for the inner factor: the fixed ones win.
    fn merged(&self, values: &Values) -> Values {
        let mut merged = Values::new();
        for key in &self.free_keys {
            merged.insert(*key, *values.get(key).expect("free key in values"));
        }
        for key in self.inner.keys() {
            if let Some(v) = self.fixed.get(key) {
                merged.insert(*key, *v);
            }
        }
        merged
    }
}

impl Factor for ConditionedFactor {
    fn keys(&self) -> &[Key] {
        &self.free_keys
    }

    fn residual_dim(&self) -> usize {
        self.inner.residual_dim()
    }

    /// The inner factor's Jacobians of the held keys go to a scratch
    /// buffer (allocated: conditioned factors are few, the oldest frame's).
    fn linearize_into(
        &self,
        values: &Values,
        residual: &mut [f64],
        jacobians: &mut JacobiansMut<'_>,
    ) {
        let merged = self.merged(values);
        let rows = jacobians.rows();
        let inner_cols: Vec<usize> = self
            .inner
            .keys()
            .iter()
            .map(|key| merged.get(key).expect("every inner key merged").dim())
            .collect();
        let mut inner_values = vec![0.0; rows * inner_cols.iter().sum::<usize>()];
        let mut inner = JacobiansMut::new(&mut inner_values, rows, &inner_cols);
        self.inner.linearize_into(&merged, residual, &mut inner);
        for (free, &i) in self.free_positions.iter().enumerate() {
            jacobians.set(free, &inner.block(i));
        }
    }

    fn noise(&self) -> &NoiseModel {
        self.inner.noise()
    }

    fn residual_into(&self, values: &Values, residual: &mut [f64]) {
        self.inner.residual_into(&self.merged(values), residual);
    }

    /// The held keys that `values` still has take their values from it:
    /// conditioning on the latest estimate rather than on the one at
    /// conditioning time.
    fn refresh_fixed(&mut self, values: &Values) {
        let keys: Vec<Key> = self.fixed.keys().copied().collect();
        for key in keys {
            if let Some(v) = values.get(&key) {
                self.fixed.insert(key, *v);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::between_factor::BetweenFactor;
    use crate::graph::{Linearization, Variable, check_factor_jacobians};
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    fn pose(x: f64, yaw: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(x, 0.5 * x, -0.2),
            UnitQuaternion::from_euler_angles(0.1, -0.05, yaw),
        )
    }

    #[test]
    fn holds_the_fixed_key_and_keeps_the_other_jacobian() {
        let a = Key::EgoPose(1);
        let b = Key::ObjectPose { id: 7, frame: 1 };
        let inner =
            BetweenFactor::new(a, b, pose(3.0, 0.3), NoiseModel::diagonal_sigmas(&[0.1; 6]));
        let mut values = Values::new();
        values.insert(a, Variable::Pose(pose(1.0, 0.1)));
        values.insert(b, Variable::Pose(pose(4.5, 0.5)));
        let full = Linearization::of(&inner, &values);
        let mut fixed = Values::new();
        fixed.insert(a, *values.get(&a).unwrap());
        let conditioned = ConditionedFactor::new(Box::new(inner), fixed).unwrap();
        assert_eq!(conditioned.keys(), &[b]);
        let lin = Linearization::of(&conditioned, &values);
        assert_eq!(lin.residual, full.residual);
        assert_eq!(lin.jacobians.len(), 1);
        assert_eq!(lin.jacobians[0], full.jacobians[1]);
        // Moving the fixed key in `values` changes nothing: it is a constant.
        let mut moved = values.clone();
        moved.insert(a, Variable::Pose(pose(9.0, -1.0)));
        assert_eq!(conditioned.residual(&moved), full.residual);
        assert!(check_factor_jacobians(&conditioned, &values, 1e-6) < 1e-6);
    }

    #[test]
    fn refreshing_conditions_on_the_latest_value() {
        let a = Key::EgoPose(1);
        let b = Key::ObjectPose { id: 7, frame: 1 };
        let noise = NoiseModel::diagonal_sigmas(&[0.1; 6]);
        let inner = BetweenFactor::new(a, b, pose(3.0, 0.3), noise.clone());
        let mut fixed = Values::new();
        fixed.insert(a, Variable::Pose(pose(1.0, 0.1)));
        let mut conditioned = ConditionedFactor::new(Box::new(inner), fixed).unwrap();
        let mut values = Values::new();
        values.insert(a, Variable::Pose(pose(2.0, -0.2)));
        values.insert(b, Variable::Pose(pose(4.5, 0.5)));
        conditioned.refresh_fixed(&values);
        let reference = BetweenFactor::new(a, b, pose(3.0, 0.3), noise);
        assert_eq!(conditioned.residual(&values), reference.residual(&values));
        // A held key no longer in the values keeps its last value.
        let mut without = values.clone();
        without.remove(&a);
        conditioned.refresh_fixed(&without);
        assert_eq!(conditioned.residual(&values), reference.residual(&values));
    }

    #[test]
    fn a_factor_with_every_key_fixed_is_returned() {
        let a = Key::EgoPose(1);
        let inner =
            BetweenFactor::new(a, a, pose(0.0, 0.0), NoiseModel::diagonal_sigmas(&[0.1; 6]));
        let mut fixed = Values::new();
        fixed.insert(a, Variable::Pose(pose(1.0, 0.0)));
        assert!(ConditionedFactor::new(Box::new(inner), fixed).is_err());
    }
}
