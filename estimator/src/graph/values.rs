//! Variable values and their retractions.

use super::key::Key;
use crate::imu::ImuBias;
use crate::lie;
use nalgebra::{DVector, Isometry3, Vector3, Vector6};
use std::collections::BTreeMap;

/// A variable's value on its manifold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Variable {
    /// SE(3), tangent `(ρ, φ)`, `T ⊕ ξ = T·Exp(ξ)`.
    Pose(Isometry3<f64>),
    /// ℝ³ (velocities).
    Vector3(Vector3<f64>),
    /// IMU biases, ℝ⁶ ordered `(accelerometer, gyroscope)`.
    Bias(ImuBias),
}

impl Variable {
    /// Tangent-space dimension.
    pub fn dim(&self) -> usize {
        match self {
            Variable::Pose(_) | Variable::Bias(_) => 6,
            Variable::Vector3(_) => 3,
        }
    }

    /// `self ⊕ delta`; `delta.len()` must equal [`Variable::dim`].
    pub fn retract(&self, delta: &[f64]) -> Variable {
        assert_eq!(delta.len(), self.dim(), "tangent dimension mismatch");
        match self {
            Variable::Pose(t) => Variable::Pose(lie::oplus(t, &Vector6::from_column_slice(delta))),
            Variable::Vector3(v) => Variable::Vector3(v + Vector3::from_column_slice(delta)),
            Variable::Bias(b) => Variable::Bias(ImuBias {
                accel_mps2: b.accel_mps2 + Vector3::from_column_slice(&delta[0..3]),
                gyro_radps: b.gyro_radps + Vector3::from_column_slice(&delta[3..6]),
            }),
        }
    }

    /// `self ⊖ other`, the tangent vector `δ` with `other ⊕ δ = self`.
    /// Panics if the kinds differ (a programming error, not bad input).
    pub fn local(&self, other: &Variable) -> DVector<f64> {
        let mut delta = DVector::zeros(self.dim());
        self.local_into(other, delta.as_mut_slice());
        delta
    }

    /// [`Variable::local`] into `delta` (of length [`Variable::dim`]).
    pub fn local_into(&self, other: &Variable, delta: &mut [f64]) {
        match (self, other) {
            (Variable::Pose(a), Variable::Pose(b)) => {
                delta.copy_from_slice(lie::ominus(a, b).as_slice());
            }
            (Variable::Vector3(a), Variable::Vector3(b)) => {
                delta.copy_from_slice((a - b).as_slice());
            }
            (Variable::Bias(a), Variable::Bias(b)) => {
                delta.copy_from_slice((a.to_vector6() - b.to_vector6()).as_slice());
            }
            _ => panic!("Variable::local between different kinds"),
        }
    }
}

/// The current estimate of every variable, keyed and ordered.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Values {
    map: BTreeMap<Key, Variable>,
}

impl Values {
    /// No values.
    pub fn new() -> Values {
        Values::default()
    }

    /// Sets the value of `key`; returns the value it replaces.
    pub fn insert(&mut self, key: Key, value: Variable) -> Option<Variable> {
        self.map.insert(key, value)
    }

    /// Removes `key`; returns its value.
    pub fn remove(&mut self, key: &Key) -> Option<Variable> {
        self.map.remove(key)
    }

    /// The value of `key`.
    pub fn get(&self, key: &Key) -> Option<&Variable> {
        self.map.get(key)
    }

    /// Whether `key` has a value.
    pub fn contains(&self, key: &Key) -> bool {
        self.map.contains_key(key)
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        self.map.len()
    }

    /// Whether there is no value.
    pub fn is_empty(&self) -> bool {
        self.map.is_empty()
    }

    /// The values in key order.
    pub fn iter(&self) -> impl Iterator<Item = (&Key, &Variable)> {
        self.map.iter()
    }

    /// The keys in order.
    pub fn keys(&self) -> impl Iterator<Item = &Key> {
        self.map.keys()
    }

    /// The pose stored under `key`. Panics if it is missing or not a pose:
    /// factors are only evaluated on values the graph has checked.
    pub fn pose(&self, key: &Key) -> &Isometry3<f64> {
        match self.map.get(key) {
            Some(Variable::Pose(t)) => t,
            other => panic!("key {key} holds {other:?}, not a pose"),
        }
    }

    /// The 3-vector stored under `key` (see [`Values::pose`] on panics).
    pub fn vector3(&self, key: &Key) -> &Vector3<f64> {
        match self.map.get(key) {
            Some(Variable::Vector3(v)) => v,
            other => panic!("key {key} holds {other:?}, not a 3-vector"),
        }
    }

    /// The bias stored under `key` (see [`Values::pose`] on panics).
    pub fn bias(&self, key: &Key) -> &ImuBias {
        match self.map.get(key) {
            Some(Variable::Bias(b)) => b,
            other => panic!("key {key} holds {other:?}, not a bias"),
        }
    }

    /// Applies `value ⊕ delta` to one variable.
    pub fn retract_key(&mut self, key: &Key, delta: &[f64]) {
        if let Some(v) = self.map.get_mut(key) {
            *v = v.retract(delta);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn retract_and_local_are_inverse() {
        let pose = Variable::Pose(lie::se3_exp(&Vector6::new(1.0, -2.0, 0.5, 0.3, -0.2, 0.9)));
        let delta = [0.1, 0.2, -0.3, 0.05, -0.02, 0.01];
        let moved = pose.retract(&delta);
        let back = moved.local(&pose);
        for (a, b) in back.iter().zip(delta) {
            assert!((a - b).abs() < 1e-12);
        }
        let bias = Variable::Bias(ImuBias::default());
        let moved = bias.retract(&delta);
        assert_eq!(moved.local(&bias).as_slice(), &delta);
    }
}
