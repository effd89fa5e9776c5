//! Unary prior on one variable: `r = x ⊖ prior`.

use super::factor::{Factor, JacobiansMut};
use super::key::Key;
use super::noise::NoiseModel;
use super::values::{Values, Variable};
use crate::lie;
use nalgebra::Vector6;

/// `r = x ⊖ prior`: `Log(prior⁻¹·x)` for poses (Jacobian `J_r⁻¹(r)`),
/// `x - prior` for velocities and biases (Jacobian identity).
#[derive(Debug, Clone)]
pub struct PriorFactor {
    keys: [Key; 1],
    prior: Variable,
    noise: NoiseModel,
}

impl PriorFactor {
    /// `noise` must have the tangent dimension of `prior`.
    pub fn new(key: Key, prior: Variable, noise: NoiseModel) -> PriorFactor {
        PriorFactor {
            keys: [key],
            prior,
            noise,
        }
    }

    /// The prior value.
    pub fn prior(&self) -> &Variable {
        &self.prior
    }
}

impl Factor for PriorFactor {
    fn keys(&self) -> &[Key] {
        &self.keys
    }

    fn residual_dim(&self) -> usize {
        self.prior.dim()
    }

    fn linearize_into(
        &self,
        values: &Values,
        residual: &mut [f64],
        jacobians: &mut JacobiansMut<'_>,
    ) {
        self.residual_into(values, residual);
        match values.get(&self.keys[0]) {
            Some(Variable::Pose(_)) => {
                let r = Vector6::from_column_slice(residual);
                jacobians.set(0, &lie::se3_right_jacobian_inv(&r));
            }
            _ => jacobians.set_scaled_identity(0, 1.0),
        }
    }

    fn noise(&self) -> &NoiseModel {
        &self.noise
    }

    fn residual_into(&self, values: &Values, residual: &mut [f64]) {
        values
            .get(&self.keys[0])
            .unwrap_or_else(|| panic!("no value for {}", self.keys[0]))
            .local_into(&self.prior, residual);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::check_factor_jacobians;
    use crate::imu::ImuBias;
    use nalgebra::{Vector3, Vector6};

    #[test]
    fn jacobians_match_finite_differences_for_every_kind() {
        let cases = [
            (
                Key::EgoPose(0),
                Variable::Pose(lie::se3_exp(&Vector6::new(1.0, -2.0, 0.5, 0.3, -0.2, 0.9))),
                Variable::Pose(lie::se3_exp(&Vector6::new(0.7, -1.0, 0.1, 0.8, -0.6, 0.4))),
            ),
            (
                Key::EgoVelocity(0),
                Variable::Vector3(Vector3::new(1.0, 2.0, 3.0)),
                Variable::Vector3(Vector3::new(-1.0, 0.5, 2.0)),
            ),
            (
                Key::EgoBias(0),
                Variable::Bias(ImuBias::from_vector6(&Vector6::new(
                    0.1, 0.2, 0.3, 0.01, 0.02, 0.03,
                ))),
                Variable::Bias(ImuBias::default()),
            ),
        ];
        for (key, value, prior) in cases {
            let mut values = Values::new();
            values.insert(key, value);
            let factor = PriorFactor::new(
                key,
                prior,
                NoiseModel::diagonal_sigmas(&vec![0.1; value.dim()]),
            );
            assert!(
                check_factor_jacobians(&factor, &values, 1e-6) < 1e-7,
                "{key}"
            );
            values.insert(key, prior);
            assert!(factor.residual(&values).amax() < 1e-12);
        }
    }
}
