//! Noisy IMU derived from the ego trajectory (Kalibr noise model).

use serde::{Deserialize, Serialize};

/// IMU settings, the `[imu]` table of a scenario file. Densities follow the
/// Kalibr convention (continuous-time); defaults are LIO-SAM's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImuConfig {
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
            accel_noise_density: 3.993_957_088_823_880_8e-3,
            gyro_noise_density: 1.563_634_394_969_818_7e-3,
            accel_bias_random_walk: 6.435_665_953_253_256_6e-5,
            gyro_bias_random_walk: 3.564_031_869_636_761_3e-5,
            accel_bias_initial_sigma: 0.05,
            gyro_bias_initial_sigma: 0.002,
            gravity_mps2: 9.80511,
        }
    }
}
