//! Relative-pose factor between two SE(3) variables: the paper's LiDAR
//! odometry residual `r_odo = Log(Z⁻¹·T_a⁻¹·T_b)`.

use super::factor::{Factor, JacobiansMut};
use super::key::Key;
use super::noise::NoiseModel;
use super::values::Values;
use crate::lie;
use nalgebra::Isometry3;

/// `r = Log(measured_t_a_b⁻¹ · T_a⁻¹ · T_b)` (tangent order `(ρ, φ)`).
#[derive(Debug, Clone)]
pub struct BetweenFactor {
    keys: [Key; 2],
    measured_t_a_b: Isometry3<f64>,
    noise: NoiseModel,
}

impl BetweenFactor {
    /// `noise` must be 6-dimensional (translation then rotation).
    pub fn new(
        key_a: Key,
        key_b: Key,
        measured_t_a_b: Isometry3<f64>,
        noise: NoiseModel,
    ) -> BetweenFactor {
        BetweenFactor {
            keys: [key_a, key_b],
            measured_t_a_b,
            noise,
        }
    }

    /// The measured relative pose `T_a_b`.
    pub fn measured(&self) -> &Isometry3<f64> {
        &self.measured_t_a_b
    }
}

impl Factor for BetweenFactor {
    fn keys(&self) -> &[Key] {
        &self.keys
    }

    fn residual_dim(&self) -> usize {
        6
    }

    fn linearize_into(
        &self,
        values: &Values,
        residual: &mut [f64],
        jacobians: &mut JacobiansMut<'_>,
    ) {
        let t_a = values.pose(&self.keys[0]);
        let t_b = values.pose(&self.keys[1]);
        // E = Z⁻¹·T_a⁻¹·T_b. A right perturbation of T_b enters E on the
        // right: dr/dξ_b = J_r⁻¹(r). A right perturbation of T_a becomes
        // E·Exp(-Ad(T_b⁻¹·T_a)·ξ_a), so dr/dξ_a = -J_r⁻¹(r)·Ad(T_b⁻¹·T_a).
        let error = self.measured_t_a_b.inverse() * lie::between(t_a, t_b);
        let (r, jr_inv) = lie::se3_log_with_jacobian(&error);
        let d_b = jr_inv;
        let d_a = -jr_inv * lie::se3_adjoint(&(t_b.inverse() * t_a));
        residual.copy_from_slice(r.as_slice());
        jacobians.set(0, &d_a);
        jacobians.set(1, &d_b);
    }

    fn noise(&self) -> &NoiseModel {
        &self.noise
    }

    fn residual_into(&self, values: &Values, residual: &mut [f64]) {
        let error = self.measured_t_a_b.inverse()
            * lie::between(values.pose(&self.keys[0]), values.pose(&self.keys[1]));
        residual.copy_from_slice(lie::se3_log(&error).as_slice());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::{Variable, check_factor_jacobians};
    use nalgebra::Vector6;

    #[test]
    fn jacobians_match_finite_differences_and_residual_vanishes_at_truth() {
        let t_a = lie::se3_exp(&Vector6::new(1.0, -2.0, 0.5, 0.3, -0.2, 0.9));
        let t_b = lie::se3_exp(&Vector6::new(-0.5, 3.0, 1.5, -1.1, 0.4, 0.2));
        let mut values = Values::new();
        values.insert(Key::EgoPose(0), Variable::Pose(t_a));
        values.insert(Key::EgoPose(1), Variable::Pose(t_b));
        let exact = BetweenFactor::new(
            Key::EgoPose(0),
            Key::EgoPose(1),
            t_a.inverse() * t_b,
            NoiseModel::diagonal_sigmas(&[0.1; 6]),
        );
        assert!(exact.residual(&values).amax() < 1e-12);
        let noisy = BetweenFactor::new(
            Key::EgoPose(0),
            Key::EgoPose(1),
            lie::se3_exp(&Vector6::new(0.3, 0.1, -0.2, 0.2, 0.1, -0.3)) * t_a.inverse() * t_b,
            NoiseModel::diagonal_sigmas(&[0.1; 6]),
        );
        assert!(check_factor_jacobians(&exact, &values, 1e-6) < 1e-7);
        assert!(check_factor_jacobians(&noisy, &values, 1e-6) < 1e-7);
    }
}
