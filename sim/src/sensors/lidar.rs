//! Rolling 64-beam LiDAR (Velodyne HDL-64E model).
//!
//! The head spins clockwise seen from above (azimuth decreasing), starting
//! each sweep pointing backwards (azimuth pi), as KITTI's HDL-64E does.

use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};

/// LiDAR settings, the `[lidar]` table of a scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LidarConfig {
    /// Revolutions per second, Hz (one sweep per revolution).
    pub rotation_hz: f64,
    /// Columns (firings of all lasers) per revolution.
    pub azimuth_steps: usize,
    /// Returns beyond this range are lost, m.
    pub max_range_m: f64,
    /// Returns closer than this are lost (the ego's own body), m.
    pub min_range_m: f64,
    /// Standard deviation of the additive range noise.
    pub range_noise_sigma_m: f64,
    /// Probability that a return that hit something is lost anyway.
    pub dropout_probability: f64,
}

impl Default for LidarConfig {
    fn default() -> Self {
        LidarConfig {
            rotation_hz: 10.0,
            azimuth_steps: 2000,
            max_range_m: 120.0,
            min_range_m: 2.0,
            range_noise_sigma_m: 0.02,
            dropout_probability: 0.02,
        }
    }
}

impl LidarConfig {
    /// Duration of one sweep, `1 / rotation_hz`, s.
    pub fn sweep_duration_s(&self) -> f64 {
        1.0 / self.rotation_hz
    }

    /// Azimuth (rad, counter-clockwise from +x, in (-pi, pi]) the head points
    /// at `time_offset_s` after the sweep start.
    pub fn azimuth_at(&self, time_offset_s: f64) -> f64 {
        let a = PI - TAU * time_offset_s * self.rotation_hz;
        // wrap to (-pi, pi]
        let wrapped = (a + PI).rem_euclid(TAU) - PI;
        if wrapped == -PI { PI } else { wrapped }
    }

    /// Time after the sweep start at which the head points at `azimuth_rad`.
    pub fn time_offset_of_azimuth(&self, azimuth_rad: f64) -> f64 {
        (PI - azimuth_rad).rem_euclid(TAU) / (TAU * self.rotation_hz)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn azimuth_and_time_are_inverse() {
        let cfg = LidarConfig::default();
        for i in 0..100 {
            let tau = i as f64 * cfg.sweep_duration_s() / 100.0;
            let az = cfg.azimuth_at(tau);
            assert!(
                (cfg.time_offset_of_azimuth(az) - tau).abs() < 1e-12,
                "{tau}"
            );
        }
        // clockwise from above: backwards, then left (+y), forwards, right (-y)
        assert!((cfg.azimuth_at(0.025) - PI / 2.0).abs() < 1e-12);
        assert!(cfg.azimuth_at(0.05).abs() < 1e-12);
    }
}
