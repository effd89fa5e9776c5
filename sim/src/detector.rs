//! Detector model: noisy 3D boxes from ground truth, with misses, heading
//! flips and false positives; default figures close to CenterPoint's.

use serde::{Deserialize, Serialize};

/// Per-class noise of detected boxes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClassNoise {
    /// Standard deviation of the box centre error per axis, m.
    pub position_sigma_m: f64,
    /// Standard deviation of the length/width/height error, m.
    pub size_sigma_m: f64,
    pub yaw_sigma_rad: f64,
    /// Probability that the heading comes out reversed (yaw + pi).
    pub heading_flip_probability: f64,
}

impl Default for ClassNoise {
    fn default() -> Self {
        ClassNoise {
            position_sigma_m: 0.15,
            size_sigma_m: 0.10,
            yaw_sigma_rad: 0.03,
            heading_flip_probability: 0.02,
        }
    }
}

/// Detector settings, the `[detector]` table of a scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectorConfig {
    pub car: ClassNoise,
    pub truck: ClassNoise,
    pub cyclist: ClassNoise,
    pub pedestrian: ClassNoise,
    /// Objects farther than this are never detected, m.
    pub max_range_m: f64,
    /// Recall for a close, fully visible object.
    pub max_recall: f64,
    /// Range at which recall has fallen to half of `max_recall`, m.
    pub half_recall_range_m: f64,
    /// Objects with fewer LiDAR points than this are never detected.
    pub min_points: usize,
    /// Point count above which occlusion no longer lowers recall.
    pub full_recall_points: usize,
    /// Mean number of false positive boxes per frame (Poisson).
    pub false_positives_per_frame: f64,
}

impl Default for DetectorConfig {
    fn default() -> Self {
        DetectorConfig {
            car: ClassNoise::default(),
            truck: ClassNoise {
                position_sigma_m: 0.30,
                size_sigma_m: 0.30,
                yaw_sigma_rad: 0.03,
                heading_flip_probability: 0.02,
            },
            cyclist: ClassNoise {
                position_sigma_m: 0.15,
                size_sigma_m: 0.08,
                yaw_sigma_rad: 0.10,
                heading_flip_probability: 0.05,
            },
            pedestrian: ClassNoise {
                position_sigma_m: 0.12,
                size_sigma_m: 0.05,
                yaw_sigma_rad: 0.30,
                heading_flip_probability: 0.10,
            },
            max_range_m: 80.0,
            max_recall: 0.95,
            half_recall_range_m: 70.0,
            min_points: 5,
            full_recall_points: 60,
            false_positives_per_frame: 0.3,
        }
    }
}
