//! IMU model shared by preintegration and the graph: biases and noise
//! densities ([`ImuBias`], [`ImuNoise`]), on-manifold preintegration between
//! two frames ([`Preintegration`], Forster et al. 2016) and world-frame
//! propagation of a known state for de-skewing ([`ImuTrajectory`]).
//!
//! Measurements are in the IMU body frame (specific force in m/s², angular
//! rate in rad/s; measured = true + bias + noise) and are treated as
//! piecewise linear in time between samples.

mod preintegration;

pub use preintegration::{
    COVERAGE_TOLERANCE_S, ImuTrajectory, Matrix9, Preintegration, PreintegrationError,
};

use nalgebra::{Vector3, Vector6};

/// Accelerometer and gyroscope biases (measured = true + bias + noise).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ImuBias {
    /// Accelerometer bias, IMU body frame (m/s²).
    pub accel_mps2: Vector3<f64>,
    /// Gyroscope bias, IMU body frame (rad/s).
    pub gyro_radps: Vector3<f64>,
}

impl ImuBias {
    /// `(accel, gyro)` stacked, the tangent ordering of a bias variable.
    pub fn to_vector6(&self) -> Vector6<f64> {
        Vector6::new(
            self.accel_mps2.x,
            self.accel_mps2.y,
            self.accel_mps2.z,
            self.gyro_radps.x,
            self.gyro_radps.y,
            self.gyro_radps.z,
        )
    }

    /// Inverse of [`ImuBias::to_vector6`].
    pub fn from_vector6(v: &Vector6<f64>) -> ImuBias {
        ImuBias {
            accel_mps2: Vector3::new(v[0], v[1], v[2]),
            gyro_radps: Vector3::new(v[3], v[4], v[5]),
        }
    }
}

/// Continuous-time IMU noise (Kalibr convention). Defaults are LIO-SAM's,
/// which the simulator also uses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuNoise {
    /// White accelerometer noise, m/s²/√Hz.
    pub accel_noise_density: f64,
    /// White gyroscope noise, rad/s/√Hz.
    pub gyro_noise_density: f64,
    /// Accelerometer bias random walk, m/s³/√Hz.
    pub accel_bias_random_walk: f64,
    /// Gyroscope bias random walk, rad/s²/√Hz.
    pub gyro_bias_random_walk: f64,
}

impl Default for ImuNoise {
    fn default() -> Self {
        ImuNoise {
            accel_noise_density: 3.993_957_088_823_881e-3,
            gyro_noise_density: 1.563_634_394_969_818_7e-3,
            accel_bias_random_walk: 6.435_665_935_353_257e-5,
            gyro_bias_random_walk: 3.564_031_869_636_761e-5,
        }
    }
}
