//! Noisy IMU derived from the ego trajectory (Kalibr noise model).

use crate::scene::Ego;
use limot_estimator::input::ImuSample;
use nalgebra::{Isometry3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

/// IMU settings, the `[imu]` table of a scenario file. Densities follow the
/// Kalibr convention (continuous-time); defaults are LIO-SAM's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImuConfig {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Accelerometer white noise density, m/s^2/sqrt(Hz).
    pub accel_noise_density: f64,
    /// Gyroscope white noise density, rad/s/sqrt(Hz).
    pub gyro_noise_density: f64,
    /// Accelerometer bias random walk, m/s^3/sqrt(Hz).
    pub accel_bias_random_walk: f64,
    /// Gyroscope bias random walk, rad/s^2/sqrt(Hz).
    pub gyro_bias_random_walk: f64,
    /// Standard deviation of the initial accelerometer bias per axis, m/s^2.
    pub accel_bias_initial_sigma: f64,
    /// Standard deviation of the initial gyroscope bias per axis, rad/s.
    pub gyro_bias_initial_sigma: f64,
    /// Magnitude of gravity, m/s^2 (pointing along world -z).
    pub gravity_mps2: f64,
}

impl Default for ImuConfig {
    fn default() -> Self {
        ImuConfig {
            rate_hz: 100.0,
            accel_noise_density: 3.993_957_088_823_881e-3,
            gyro_noise_density: 1.563_634_394_969_818_7e-3,
            accel_bias_random_walk: 6.435_665_953_253_257e-5,
            gyro_bias_random_walk: 3.564_031_869_636_761e-5,
            accel_bias_initial_sigma: 0.05,
            gyro_bias_initial_sigma: 0.002,
            gravity_mps2: 9.80511,
        }
    }
}

/// A rejected IMU configuration or query.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ImuError {
    #[error("IMU config field `{field}` = {value} is invalid: {why}")]
    /// A config field outside its valid range.
    BadConfig {
        /// Name of the field.
        field: &'static str,
        /// The rejected value.
        value: f64,
        /// What the field must satisfy.
        why: &'static str,
    },
    #[error("IMU time range [{t0_s}, {t1_s}] is not finite")]
    /// A query's time range has a NaN or infinite end.
    BadTimeRange {
        /// Start of the range, s.
        t0_s: f64,
        /// End of the range, s.
        t1_s: f64,
    },
}

impl ImuConfig {
    /// The default IMU without noise and without biases: it reports the
    /// motion exactly.
    pub fn noise_free() -> ImuConfig {
        ImuConfig {
            accel_noise_density: 0.0,
            gyro_noise_density: 0.0,
            accel_bias_random_walk: 0.0,
            gyro_bias_random_walk: 0.0,
            accel_bias_initial_sigma: 0.0,
            gyro_bias_initial_sigma: 0.0,
            ..ImuConfig::default()
        }
    }

    /// Rejects rates that are not positive and noise figures that are
    /// negative or not finite.
    ///
    /// # Errors
    /// [`ImuError::BadConfig`] naming the first invalid field.
    pub fn validate(&self) -> Result<(), ImuError> {
        let bad = |field, value, why| Err(ImuError::BadConfig { field, value, why });
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return bad("rate_hz", self.rate_hz, "must be finite and positive");
        }
        let non_negative = [
            ("accel_noise_density", self.accel_noise_density),
            ("gyro_noise_density", self.gyro_noise_density),
            ("accel_bias_random_walk", self.accel_bias_random_walk),
            ("gyro_bias_random_walk", self.gyro_bias_random_walk),
            ("accel_bias_initial_sigma", self.accel_bias_initial_sigma),
            ("gyro_bias_initial_sigma", self.gyro_bias_initial_sigma),
            ("gravity_mps2", self.gravity_mps2),
        ];
        for (field, value) in non_negative {
            if !(value.is_finite() && value >= 0.0) {
                return bad(field, value, "must be finite and non-negative");
            }
        }
        Ok(())
    }

    /// Standard deviation of the discrete accelerometer white noise per
    /// sample (Kalibr: sigma_d = density * sqrt(rate)).
    pub fn accel_noise_sigma_discrete(&self) -> f64 {
        self.accel_noise_density * self.rate_hz.sqrt()
    }

    /// Standard deviation of the discrete gyroscope white noise per sample.
    pub fn gyro_noise_sigma_discrete(&self) -> f64 {
        self.gyro_noise_density * self.rate_hz.sqrt()
    }

    /// Standard deviation of one accelerometer bias step between samples
    /// (Kalibr: sigma_bd = random_walk * sqrt(dt)).
    pub fn accel_bias_step_sigma(&self) -> f64 {
        self.accel_bias_random_walk / self.rate_hz.sqrt()
    }

    /// Standard deviation of one gyroscope bias step between samples.
    pub fn gyro_bias_step_sigma(&self) -> f64 {
        self.gyro_bias_random_walk / self.rate_hz.sqrt()
    }
}

/// The IMU output over a time range with its ground truth biases:
/// `samples[k]` was measured with biases `accel_bias[k]`, `gyro_bias[k]`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ImuStream {
    /// The noisy samples (specific force and angular rate, IMU frame), in time order.
    pub samples: Vec<ImuSample>,
    /// True accelerometer bias of each sample, IMU frame, m/s².
    pub accel_bias: Vec<Vector3<f64>>,
    /// True gyroscope bias of each sample, IMU frame, rad/s.
    pub gyro_bias: Vec<Vector3<f64>>,
}

/// Derives IMU samples from the ego trajectory and corrupts them with
/// Kalibr-style white noise and bias random walks, deterministically from
/// the seed.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuSimulator {
    config: ImuConfig,
    seed: u64,
}

/// Tolerance when mapping a time range onto the sample grid k / rate_hz, so
/// that `0.3 * 100.0 = 30.000000000000004` still includes sample 30.
const GRID_EPSILON: f64 = 1e-6;

impl ImuSimulator {
    /// An IMU with a validated `config` whose noise and biases are drawn from `seed`.
    ///
    /// # Errors
    /// [`ImuError::BadConfig`] if `config` is invalid.
    pub fn new(config: ImuConfig, seed: u64) -> Result<ImuSimulator, ImuError> {
        config.validate()?;
        Ok(ImuSimulator { config, seed })
    }

    /// The configuration this IMU was built with.
    pub fn config(&self) -> &ImuConfig {
        &self.config
    }

    /// The IMU body frame in the world at `t_s`.
    pub fn t_world_imu(ego: &Ego, t_s: f64) -> Isometry3<f64> {
        ego.trajectory.pose_at(t_s) * ego.t_lidar_imu
    }

    /// Velocity of the IMU origin in the world at `t_s` (includes the lever
    /// arm from the LiDAR origin).
    pub fn velocity_world_imu(ego: &Ego, t_s: f64) -> Vector3<f64> {
        let state = ego.trajectory.state_at(t_s);
        let r_lidar = ego.t_lidar_imu.translation.vector;
        let rotation = state.t_world_body.rotation;
        state.velocity_world_mps + rotation * state.angular_velocity_body_radps.cross(&r_lidar)
    }

    /// The noise-free, bias-free IMU sample at `t_s`.
    pub fn true_sample(&self, ego: &Ego, t_s: f64) -> ImuSample {
        let state = ego.trajectory.state_at(t_s);
        let r_lidar = ego.t_lidar_imu.translation.vector;
        let omega_lidar = state.angular_velocity_body_radps;
        let alpha_lidar = state.angular_accel_body_radps2;
        // r is fixed in the LiDAR frame, so d^2/dt^2 (R r) = R (alpha x r + omega x (omega x r))
        // with omega and alpha in the body (LiDAR) frame.
        let lever_accel_lidar =
            alpha_lidar.cross(&r_lidar) + omega_lidar.cross(&omega_lidar.cross(&r_lidar));
        let rotation_world_lidar = state.t_world_body.rotation;
        let accel_imu_world = state.accel_world_mps2 + rotation_world_lidar * lever_accel_lidar;
        let gravity_world = Vector3::new(0.0, 0.0, -self.config.gravity_mps2);
        let rotation_world_imu = rotation_world_lidar * ego.t_lidar_imu.rotation;
        ImuSample {
            t_s,
            accel_mps2: rotation_world_imu
                .inverse_transform_vector(&(accel_imu_world - gravity_world)),
            // R_world_imu = R_world_lidar R_lidar_imu, so the IMU's body rate is
            // the LiDAR's body rate seen in the IMU frame.
            gyro_radps: ego
                .t_lidar_imu
                .rotation
                .inverse_transform_vector(&omega_lidar),
        }
    }

    /// Samples at every t = k / rate_hz in [t0_s, t1_s] (empty if t1_s < t0_s).
    /// Sample k carries the current biases and fresh white noise; the biases
    /// then take one random-walk step. The noise sequence starts at `t0_s`.
    ///
    /// # Errors
    /// [`ImuError::BadTimeRange`] if `t0_s` or `t1_s` is not finite.
    pub fn simulate(&self, ego: &Ego, t0_s: f64, t1_s: f64) -> Result<ImuStream, ImuError> {
        if !(t0_s.is_finite() && t1_s.is_finite()) {
            return Err(ImuError::BadTimeRange { t0_s, t1_s });
        }
        let rate = self.config.rate_hz;
        let k0 = (t0_s * rate - GRID_EPSILON).ceil() as i64;
        let k1 = (t1_s * rate + GRID_EPSILON).floor() as i64;
        let count = usize::try_from(k1 - k0 + 1).unwrap_or(0);

        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let cfg = &self.config;
        let mut accel_bias = gaussian_vector(&mut rng) * cfg.accel_bias_initial_sigma;
        let mut gyro_bias = gaussian_vector(&mut rng) * cfg.gyro_bias_initial_sigma;
        let (accel_sigma, gyro_sigma) = (
            cfg.accel_noise_sigma_discrete(),
            cfg.gyro_noise_sigma_discrete(),
        );
        let (accel_step, gyro_step) = (cfg.accel_bias_step_sigma(), cfg.gyro_bias_step_sigma());

        let mut stream = ImuStream {
            samples: Vec::with_capacity(count),
            accel_bias: Vec::with_capacity(count),
            gyro_bias: Vec::with_capacity(count),
        };
        for k in k0..k0 + count as i64 {
            let truth = self.true_sample(ego, k as f64 / rate);
            let accel_noise = gaussian_vector(&mut rng) * accel_sigma;
            let gyro_noise = gaussian_vector(&mut rng) * gyro_sigma;
            stream.samples.push(ImuSample {
                t_s: truth.t_s,
                accel_mps2: truth.accel_mps2 + accel_bias + accel_noise,
                gyro_radps: truth.gyro_radps + gyro_bias + gyro_noise,
            });
            stream.accel_bias.push(accel_bias);
            stream.gyro_bias.push(gyro_bias);
            accel_bias += gaussian_vector(&mut rng) * accel_step;
            gyro_bias += gaussian_vector(&mut rng) * gyro_step;
        }
        Ok(stream)
    }
}

/// Three independent standard normal draws.
fn gaussian_vector(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    Vector3::new(
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectory::{Jet, Knot, Trajectory};
    use nalgebra::Translation3;

    /// A LiDAR spinning in place about world z at `rate` rad/s.
    fn turntable(rate: f64, lever_arm: Vector3<f64>) -> Ego {
        let knots = (0..5)
            .map(|i| {
                let t = i as f64;
                Knot {
                    position: [Jet::default(); 3],
                    euler: [
                        Jet::new(rate * t, rate, 0.0),
                        Jet::default(),
                        Jet::default(),
                    ],
                }
            })
            .collect();
        Ego {
            trajectory: Trajectory::new(0.0, 1.0, knots),
            size_lwh_m: Vector3::new(4.0, 2.0, 1.5),
            box_center_lidar_m: Vector3::zeros(),
            t_lidar_imu: Isometry3::from_parts(
                Translation3::from(lever_arm),
                nalgebra::UnitQuaternion::identity(),
            ),
        }
    }

    #[test]
    fn lever_arm_on_a_turntable_feels_centripetal_acceleration() {
        let (rate, r) = (0.7, 1.5);
        let ego = turntable(rate, Vector3::new(r, 0.0, 0.0));
        let sim = ImuSimulator::new(ImuConfig::default(), 1).unwrap();
        let s = sim.true_sample(&ego, 2.3);
        let g = sim.config().gravity_mps2;
        // pointing at the axis: -omega^2 r along the arm; gravity reads as +g
        assert!((s.accel_mps2 - Vector3::new(-rate * rate * r, 0.0, g)).norm() < 1e-9);
        assert!((s.gyro_radps - Vector3::new(0.0, 0.0, rate)).norm() < 1e-12);
        let v = ImuSimulator::velocity_world_imu(&ego, 2.3);
        assert!((v.norm() - rate * r).abs() < 1e-9);
    }

    #[test]
    fn samples_sit_on_the_rate_grid() {
        let ego = turntable(0.1, Vector3::zeros());
        let sim = ImuSimulator::new(ImuConfig::default(), 1).unwrap();
        let stream = sim.simulate(&ego, 0.3, 0.6).unwrap();
        let times: Vec<f64> = stream.samples.iter().map(|s| s.t_s).collect();
        assert_eq!(times.len(), 31);
        assert_eq!(times[0], 0.3);
        assert_eq!(times[30], 0.6);
    }
}
