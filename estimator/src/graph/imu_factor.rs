//! IMU factors: the preintegrated-IMU factor between two ego states
//! (Forster et al. 2016, eq. 45) and the bias random-walk factor.
//!
//! Perturbations (ours, see [`crate::lie`] and [`super`]): poses
//! `T ⊕ (ρ, φ) = T·Exp((ρ, φ))`, i.e. to first order `p ← p + R·ρ`,
//! `R ← R·Exp(φ)`; velocities (world frame) and biases are Euclidean.

use super::factor::{Factor, FactorError, JacobiansMut};
use super::key::Key;
use super::noise::NoiseModel;
use super::values::Values;
use crate::imu::Preintegration;
use crate::imu::{ImuBias, ImuNoise};
use crate::lie;
use nalgebra::{DMatrix, Isometry3, Matrix3, SMatrix, SVector, Vector3};

/// 9-vector residual `(r_ΔR, r_Δv, r_Δp)`.
pub type Vector9 = SVector<f64, 9>;

/// Jacobians of the IMU residual, one block per key of [`ImuFactor`].
#[derive(Debug, Clone, PartialEq)]
pub struct ImuFactorJacobians {
    /// With respect to the pose at `i`.
    pub pose_i: SMatrix<f64, 9, 6>,
    /// With respect to the velocity at `i`.
    pub velocity_i: SMatrix<f64, 9, 3>,
    /// With respect to the biases at `i`.
    pub bias_i: SMatrix<f64, 9, 6>,
    /// With respect to the pose at `j`.
    pub pose_j: SMatrix<f64, 9, 6>,
    /// With respect to the velocity at `j`.
    pub velocity_j: SMatrix<f64, 9, 3>,
    /// With respect to gravity in the world frame.
    pub gravity: SMatrix<f64, 9, 3>,
}

/// Preintegrated IMU factor on `[EgoPose(i), EgoVelocity(i), EgoBias(i),
/// EgoPose(j), EgoVelocity(j)]`, and `Gravity` when gravity is estimated
/// ([`ImuFactor::with_estimated_gravity`]) rather than given. Residual (Forster eq. 45, first-order bias
/// correction with `δb = b_i − b̂`):
/// * `r_ΔR = Log((ΔR·Exp(J_R^g·δbg))ᵀ·R_iᵀ·R_j)`
/// * `r_Δv = R_iᵀ(v_j − v_i − g·Δt) − (Δv + J_v^a·δba + J_v^g·δbg)`
/// * `r_Δp = R_iᵀ(p_j − p_i − v_i·Δt − ½g·Δt²) − (Δp + J_p^a·δba + J_p^g·δbg)`
///
/// Noise: the preintegration covariance (same `(δφ, δv, δp)` order).
#[derive(Debug, Clone)]
pub struct ImuFactor {
    keys: Vec<Key>,
    preintegration: Preintegration,
    /// Gravity in the world frame, m/s²; `None`: the value of `Key::Gravity`.
    gravity_world: Option<Vector3<f64>>,
    noise: NoiseModel,
}

impl ImuFactor {
    /// Factor between ego frames `i` and `j` with the measurements
    /// preintegrated from `i` to `j`. Fails if the preintegration covariance
    /// is not positive definite (e.g. nothing integrated or zero noise).
    ///
    /// # Errors
    /// [`FactorError::BadCovariance`] when the preintegrated covariance is
    /// not positive definite.
    pub fn new(
        i: u64,
        j: u64,
        preintegration: Preintegration,
        gravity_world: Vector3<f64>,
    ) -> Result<ImuFactor, FactorError> {
        ImuFactor::build(i, j, preintegration, Some(gravity_world))
    }

    /// As [`ImuFactor::new`], with gravity the variable `Key::Gravity`
    /// (the sixth key), so the window estimates the world's gravity
    /// direction with the states.
    ///
    /// # Errors
    /// As [`ImuFactor::new`].
    pub fn with_estimated_gravity(
        i: u64,
        j: u64,
        preintegration: Preintegration,
    ) -> Result<ImuFactor, FactorError> {
        ImuFactor::build(i, j, preintegration, None)
    }

    fn build(
        i: u64,
        j: u64,
        preintegration: Preintegration,
        gravity_world: Option<Vector3<f64>>,
    ) -> Result<ImuFactor, FactorError> {
        let cov = preintegration.covariance();
        let noise = NoiseModel::from_covariance(&DMatrix::from_column_slice(9, 9, cov.as_slice()))
            .ok_or(FactorError::BadCovariance {
                what: "IMU preintegration",
            })?;
        let mut keys = vec![
            Key::EgoPose(i),
            Key::EgoVelocity(i),
            Key::EgoBias(i),
            Key::EgoPose(j),
            Key::EgoVelocity(j),
        ];
        if gravity_world.is_none() {
            keys.push(Key::Gravity);
        }
        Ok(ImuFactor {
            keys,
            preintegration,
            gravity_world,
            noise,
        })
    }

    /// The preintegrated measurements from `i` to `j`.
    pub fn preintegration(&self) -> &Preintegration {
        &self.preintegration
    }

    /// Gravity in the world frame, m/s², when given (`None` when it is the
    /// variable `Key::Gravity`).
    pub fn gravity_world(&self) -> Option<&Vector3<f64>> {
        self.gravity_world.as_ref()
    }

    /// Residual and (if asked) its Jacobians wrt right perturbations of the
    /// five states and gravity `g` (world, m/s²), in fixed-size types.
    #[allow(clippy::too_many_arguments)]
    pub fn evaluate(
        &self,
        t_world_imu_i: &Isometry3<f64>,
        v_world_i: &Vector3<f64>,
        bias_i: &ImuBias,
        t_world_imu_j: &Isometry3<f64>,
        v_world_j: &Vector3<f64>,
        g: &Vector3<f64>,
        with_jacobians: bool,
    ) -> (Vector9, Option<ImuFactorJacobians>) {
        let pre = &self.preintegration;
        let dt = pre.delta_t_s();
        let r_i = t_world_imu_i.rotation.to_rotation_matrix().into_inner();
        let r_j = t_world_imu_j.rotation.to_rotation_matrix().into_inner();
        let p_i = t_world_imu_i.translation.vector;
        let p_j = t_world_imu_j.translation.vector;
        let r_i_t = r_i.transpose();

        let bias_hat = pre.bias_hat();
        let dbg = bias_i.gyro_radps - bias_hat.gyro_radps;
        let j_r_bg = pre.d_rotation_d_bias_gyro();
        let (dq_corr, dv_corr, dp_corr) = pre.corrected_quaternion(bias_i);
        let dr_corr = dq_corr.to_rotation_matrix().into_inner();

        // Rotation residual.
        let m = dr_corr.transpose() * r_i_t * r_j;
        let r_rot = lie::so3_log(&nalgebra::Rotation3::from_matrix_unchecked(m));
        // Velocity and position residuals.
        let u = v_world_j - v_world_i - g * dt;
        let w = p_j - p_i - v_world_i * dt - g * (0.5 * dt * dt);
        let r_i_t_u = r_i_t * u;
        let r_i_t_w = r_i_t * w;
        let r_vel = r_i_t_u - dv_corr;
        let r_pos = r_i_t_w - dp_corr;

        let mut residual = Vector9::zeros();
        residual.fixed_rows_mut::<3>(0).copy_from(&r_rot);
        residual.fixed_rows_mut::<3>(3).copy_from(&r_vel);
        residual.fixed_rows_mut::<3>(6).copy_from(&r_pos);
        if !with_jacobians {
            return (residual, None);
        }

        let jr_inv = lie::so3_right_jacobian_inv(&r_rot);
        let mut pose_i = SMatrix::<f64, 9, 6>::zeros();
        // Columns (ρ, φ). r_ΔR: ∂/∂φ_i = −J_r⁻¹(r)·R_jᵀR_i.
        pose_i
            .fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&(-jr_inv * r_j.transpose() * r_i));
        // r_Δv: ∂(Exp(−φ)R_iᵀu)/∂φ = [R_iᵀu]ₓ.
        pose_i
            .fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&lie::skew(&r_i_t_u));
        // r_Δp: p_i ← p_i + R_i·ρ gives −I; rotation as for r_Δv.
        pose_i
            .fixed_view_mut::<3, 3>(6, 0)
            .copy_from(&(-Matrix3::identity()));
        pose_i
            .fixed_view_mut::<3, 3>(6, 3)
            .copy_from(&lie::skew(&r_i_t_w));

        let mut velocity_i = SMatrix::<f64, 9, 3>::zeros();
        velocity_i.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-r_i_t));
        velocity_i
            .fixed_view_mut::<3, 3>(6, 0)
            .copy_from(&(-r_i_t * dt));

        let mut bias_jac = SMatrix::<f64, 9, 6>::zeros();
        // Columns (accel, gyro). r_ΔR depends on b_g only:
        // −J_r⁻¹(r)·Exp(r)ᵀ·J_r(J_R^g·δbg)·J_R^g.
        let jr_corr = lie::so3_right_jacobian(&(j_r_bg * dbg));
        bias_jac
            .fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&(-jr_inv * m.transpose() * jr_corr * j_r_bg));
        bias_jac
            .fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(-pre.d_velocity_d_bias_accel()));
        bias_jac
            .fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(-pre.d_velocity_d_bias_gyro()));
        bias_jac
            .fixed_view_mut::<3, 3>(6, 0)
            .copy_from(&(-pre.d_position_d_bias_accel()));
        bias_jac
            .fixed_view_mut::<3, 3>(6, 3)
            .copy_from(&(-pre.d_position_d_bias_gyro()));

        let mut pose_j = SMatrix::<f64, 9, 6>::zeros();
        pose_j.fixed_view_mut::<3, 3>(0, 3).copy_from(&jr_inv);
        // p_j ← p_j + R_j·ρ_j.
        pose_j
            .fixed_view_mut::<3, 3>(6, 0)
            .copy_from(&(r_i_t * r_j));

        let mut velocity_j = SMatrix::<f64, 9, 3>::zeros();
        velocity_j.fixed_view_mut::<3, 3>(3, 0).copy_from(&r_i_t);

        // r_Δv and r_Δp are linear in g.
        let mut gravity = SMatrix::<f64, 9, 3>::zeros();
        gravity
            .fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(-r_i_t * dt));
        gravity
            .fixed_view_mut::<3, 3>(6, 0)
            .copy_from(&(-r_i_t * (0.5 * dt * dt)));

        (
            residual,
            Some(ImuFactorJacobians {
                pose_i,
                velocity_i,
                bias_i: bias_jac,
                pose_j,
                velocity_j,
                gravity,
            }),
        )
    }

    fn evaluate_values(
        &self,
        values: &Values,
        with_jacobians: bool,
    ) -> (Vector9, Option<ImuFactorJacobians>) {
        let [kpi, kvi, kbi, kpj, kvj] = &self.keys[..5] else {
            unreachable!("an IMU factor has five state keys");
        };
        let g = match &self.gravity_world {
            Some(g) => g,
            None => values.vector3(&Key::Gravity),
        };
        self.evaluate(
            values.pose(kpi),
            values.vector3(kvi),
            values.bias(kbi),
            values.pose(kpj),
            values.vector3(kvj),
            g,
            with_jacobians,
        )
    }
}

impl Factor for ImuFactor {
    fn keys(&self) -> &[Key] {
        &self.keys
    }

    fn residual_dim(&self) -> usize {
        9
    }

    fn linearize_into(
        &self,
        values: &Values,
        residual: &mut [f64],
        jacobians: &mut JacobiansMut<'_>,
    ) {
        let (r, jac) = self.evaluate_values(values, true);
        let jac = jac.expect("Jacobians were requested");
        residual.copy_from_slice(r.as_slice());
        jacobians.set(0, &jac.pose_i);
        jacobians.set(1, &jac.velocity_i);
        jacobians.set(2, &jac.bias_i);
        jacobians.set(3, &jac.pose_j);
        jacobians.set(4, &jac.velocity_j);
        if self.gravity_world.is_none() {
            jacobians.set(5, &jac.gravity);
        }
    }

    fn noise(&self) -> &NoiseModel {
        &self.noise
    }

    fn residual_into(&self, values: &Values, residual: &mut [f64]) {
        residual.copy_from_slice(self.evaluate_values(values, false).0.as_slice());
    }
}

/// Bias random walk between frames `i` and `j`: residual `b_j − b_i`
/// (accelerometer then gyroscope), covariance `diag(σ_ba²·Δt, σ_bg²·Δt)`
/// from the random-walk densities.
#[derive(Debug, Clone)]
pub struct BiasRandomWalkFactor {
    keys: [Key; 2],
    noise: NoiseModel,
}

impl BiasRandomWalkFactor {
    /// Fails unless `dt_s` and both random-walk densities are finite and positive.
    ///
    /// # Errors
    /// [`FactorError::BadCovariance`] unless `dt_s` and both random-walk
    /// densities are finite and positive.
    pub fn new(
        i: u64,
        j: u64,
        dt_s: f64,
        noise: &ImuNoise,
    ) -> Result<BiasRandomWalkFactor, FactorError> {
        let sigma_accel = noise.accel_bias_random_walk * dt_s.sqrt();
        let sigma_gyro = noise.gyro_bias_random_walk * dt_s.sqrt();
        let ok = |s: f64| s.is_finite() && s > 0.0;
        if !(ok(dt_s) && ok(sigma_accel) && ok(sigma_gyro)) {
            return Err(FactorError::BadCovariance {
                what: "IMU bias random walk (dt and random-walk densities must be positive)",
            });
        }
        Ok(BiasRandomWalkFactor {
            keys: [Key::EgoBias(i), Key::EgoBias(j)],
            noise: NoiseModel::diagonal_sigmas(&[
                sigma_accel,
                sigma_accel,
                sigma_accel,
                sigma_gyro,
                sigma_gyro,
                sigma_gyro,
            ]),
        })
    }
}

impl Factor for BiasRandomWalkFactor {
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
        self.residual_into(values, residual);
        jacobians.set_scaled_identity(0, -1.0);
        jacobians.set_scaled_identity(1, 1.0);
    }

    fn noise(&self) -> &NoiseModel {
        &self.noise
    }

    fn residual_into(&self, values: &Values, residual: &mut [f64]) {
        let b_i = values.bias(&self.keys[0]).to_vector6();
        let b_j = values.bias(&self.keys[1]).to_vector6();
        residual.copy_from_slice((b_j - b_i).as_slice());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::{Variable, check_factor_jacobians};
    use crate::imu::Preintegration;
    use nalgebra::Vector6;

    fn test_preintegration() -> Preintegration {
        let bias_hat = ImuBias {
            accel_mps2: Vector3::new(0.05, -0.02, 0.01),
            gyro_radps: Vector3::new(0.01, 0.02, -0.015),
        };
        let mut pre = Preintegration::new(bias_hat, ImuNoise::default());
        for k in 0..20 {
            let t = k as f64 * 0.005;
            pre.integrate(
                &Vector3::new(1.0 + t, -0.3 + 2.0 * t, 9.9 - t),
                &Vector3::new(0.4 - t, 0.2 + t, -0.6 + 3.0 * t),
                0.005,
            );
        }
        pre
    }

    fn test_values() -> Values {
        let mut values = Values::new();
        values.insert(
            Key::EgoPose(3),
            Variable::Pose(lie::se3_exp(&Vector6::new(1.0, -2.0, 0.3, 0.4, -0.7, 1.1))),
        );
        values.insert(
            Key::EgoVelocity(3),
            Variable::Vector3(Vector3::new(4.0, 1.0, -0.2)),
        );
        values.insert(
            Key::EgoBias(3),
            Variable::Bias(ImuBias {
                accel_mps2: Vector3::new(0.1, 0.05, -0.08),
                gyro_radps: Vector3::new(-0.02, 0.03, 0.01),
            }),
        );
        values.insert(
            Key::EgoPose(4),
            Variable::Pose(lie::se3_exp(&Vector6::new(1.5, -1.8, 0.2, 0.5, -0.6, 1.3))),
        );
        values.insert(
            Key::EgoVelocity(4),
            Variable::Vector3(Vector3::new(4.2, 1.3, 0.1)),
        );
        values.insert(Key::EgoBias(4), Variable::Bias(ImuBias::default()));
        values
    }

    #[test]
    fn imu_factor_jacobians_match_finite_differences() {
        let factor = ImuFactor::new(
            3,
            4,
            test_preintegration(),
            Vector3::new(0.0, 0.0, -9.80511),
        )
        .unwrap();
        let err = check_factor_jacobians(&factor, &test_values(), 1e-6);
        assert!(err < 1e-6, "max Jacobian error {err:e}");
    }

    #[test]
    fn imu_factor_with_estimated_gravity_matches_the_given_one_and_finite_differences() {
        let g = Vector3::new(0.07, -0.05, -9.8);
        let given = ImuFactor::new(3, 4, test_preintegration(), g).unwrap();
        let estimated = ImuFactor::with_estimated_gravity(3, 4, test_preintegration()).unwrap();
        assert_eq!(estimated.keys().len(), 6);
        assert_eq!(estimated.keys()[5], Key::Gravity);
        assert!(estimated.gravity_world().is_none());
        let mut values = test_values();
        values.insert(Key::Gravity, Variable::Vector3(g));
        assert_eq!(given.residual(&values), estimated.residual(&values));
        let err = check_factor_jacobians(&estimated, &values, 1e-6);
        assert!(err < 1e-6, "max Jacobian error {err:e}");
        // gravity moves the velocity and position residuals only
        let lin = crate::graph::Linearization::of(&estimated, &values);
        assert_eq!(lin.jacobians[5].rows(0, 3).amax(), 0.0);
        assert!(lin.jacobians[5].rows(3, 6).amax() > 0.0);
    }

    #[test]
    fn bias_random_walk_factor() {
        let noise = ImuNoise::default();
        let factor = BiasRandomWalkFactor::new(3, 4, 0.1, &noise).unwrap();
        let values = test_values();
        assert!(check_factor_jacobians(&factor, &values, 1e-6) < 1e-9);
        let r = factor.residual(&values);
        assert!((r[0] + 0.1).abs() < 1e-15 && (r[5] + 0.01).abs() < 1e-15);
        let l = &factor.noise().sqrt_information;
        assert!((l[(0, 0)] - 1.0 / (noise.accel_bias_random_walk * 0.1f64.sqrt())).abs() < 1e-6);
        assert!((l[(5, 5)] - 1.0 / (noise.gyro_bias_random_walk * 0.1f64.sqrt())).abs() < 1e-6);
        assert!(BiasRandomWalkFactor::new(3, 4, 0.0, &noise).is_err());
        assert!(BiasRandomWalkFactor::new(3, 4, f64::NAN, &noise).is_err());
    }

    #[test]
    fn empty_preintegration_is_rejected() {
        let pre = Preintegration::new(ImuBias::default(), ImuNoise::default());
        assert!(ImuFactor::new(0, 1, pre, Vector3::zeros()).is_err());
    }
}
