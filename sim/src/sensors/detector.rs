//! Detector model: noisy 3D boxes from ground truth, with misses, heading
//! flips and false positives; default figures close to CenterPoint's.
//!
//! Where the default figures come from: `docs/simulator-notes.md`.

use crate::scene::{Agent, Ego, Scene};
use crate::sensors::LidarConfig;
use limot_estimator::geometry::{OrientedBox, wrap_angle_rad};
use limot_estimator::input::{Detection, InputError, ObjectClass};
use nalgebra::{Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Poisson, StandardNormal};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::f64::consts::PI;

/// Per-class noise of detected boxes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClassNoise {
    /// Standard deviation of the box centre error per axis, m.
    pub position_sigma_m: f64,
    /// Standard deviation of the length/width/height error, m.
    pub size_sigma_m: f64,
    /// Standard deviation of the yaw error, rad.
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
    /// Noise of detected cars.
    pub car: ClassNoise,
    /// Noise of detected trucks.
    pub truck: ClassNoise,
    /// Noise of detected cyclists.
    pub cyclist: ClassNoise,
    /// Noise of detected pedestrians.
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

/// Recall falls from `max_recall` to half of it at `half_recall_range_m`
/// along a logistic curve; this is its steepness in units of
/// 1 / half_recall_range (10: ~99% of max_recall at half the half-range,
/// ~2% at 1.4x the half-range).
const RANGE_STEEPNESS: f64 = 10.0;
/// Scores of true detections: base + gain * visibility + N(0, sigma), so
/// near, well-covered objects score ~0.9 and faint ones ~0.4 (CenterPoint's
/// scores on true positives spread the same way).
const TRUE_SCORE_BASE: f64 = 0.3;
const TRUE_SCORE_GAIN: f64 = 0.6;
const TRUE_SCORE_SIGMA: f64 = 0.05;
/// False positives score uniformly in this range, below most true ones.
const FALSE_SCORE_MIN: f64 = 0.05;
const FALSE_SCORE_MAX: f64 = 0.45;
/// False positives are placed at least this far from the LiDAR, m.
const FALSE_MIN_RANGE_M: f64 = 3.0;
/// False positive car sizes: mean and spread of l, w, h, m.
const FALSE_SIZE_MEAN_M: [f64; 3] = [4.4, 1.8, 1.55];
const FALSE_SIZE_SIGMA_M: [f64; 3] = [0.3, 0.1, 0.1];
/// Noisy sizes never go below this, m.
const MIN_SIZE_M: f64 = 0.05;

/// A rejected detector configuration or input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DetectorError {
    #[error("detector config field `{field}` = {value} is invalid: {why}")]
    /// A config field outside its valid range.
    BadConfig {
        /// Dotted name of the field, e.g. `car.position_sigma_m`.
        field: String,
        /// The rejected value.
        value: f64,
        /// What the field must satisfy.
        why: &'static str,
    },
    #[error("scan time {t_s} is not finite")]
    /// The scan time handed to the detector is NaN or infinite.
    BadScanTime {
        /// The rejected time, s.
        t_s: f64,
    },
    #[error("generated detection is invalid (bad scene or LiDAR config?): {0}")]
    /// A generated detection failed the estimator input's checks.
    BadDetection(#[from] InputError),
}

impl ClassNoise {
    fn validate(&self, class: &str) -> Result<(), DetectorError> {
        let sigmas = [
            ("position_sigma_m", self.position_sigma_m),
            ("size_sigma_m", self.size_sigma_m),
            ("yaw_sigma_rad", self.yaw_sigma_rad),
        ];
        for (name, value) in sigmas {
            if !(value.is_finite() && value >= 0.0) {
                return Err(bad_config(class, name, value, "must be finite and >= 0"));
            }
        }
        let p = self.heading_flip_probability;
        if !(0.0..=1.0).contains(&p) {
            return Err(bad_config(
                class,
                "heading_flip_probability",
                p,
                "must be in [0, 1]",
            ));
        }
        Ok(())
    }
}

fn bad_config(table: &str, field: &str, value: f64, why: &'static str) -> DetectorError {
    let field = if table.is_empty() {
        field.to_string()
    } else {
        format!("{table}.{field}")
    };
    DetectorError::BadConfig { field, value, why }
}

impl DetectorConfig {
    /// Checks every field's range.
    ///
    /// # Errors
    /// [`DetectorError::BadConfig`] naming the first invalid field.
    pub fn validate(&self) -> Result<(), DetectorError> {
        for class in ObjectClass::ALL {
            self.noise(class)
                .validate(&class.name().to_ascii_lowercase())?;
        }
        let positive = [
            ("max_range_m", self.max_range_m),
            // may be infinite: recall then does not fall with range
            ("half_recall_range_m", self.half_recall_range_m),
        ];
        for (name, value) in positive {
            if value.is_nan() || value <= 0.0 {
                return Err(bad_config("", name, value, "must be positive"));
            }
        }
        if !self.max_range_m.is_finite() {
            return Err(bad_config(
                "",
                "max_range_m",
                self.max_range_m,
                "must be finite",
            ));
        }
        if !(0.0..=1.0).contains(&self.max_recall) {
            return Err(bad_config(
                "",
                "max_recall",
                self.max_recall,
                "must be in [0, 1]",
            ));
        }
        let fp = self.false_positives_per_frame;
        if !(fp.is_finite() && (0.0..=1000.0).contains(&fp)) {
            return Err(bad_config(
                "",
                "false_positives_per_frame",
                fp,
                "must be in [0, 1000]",
            ));
        }
        Ok(())
    }

    /// The noise settings of `class`.
    pub fn noise(&self, class: ObjectClass) -> &ClassNoise {
        match class {
            ObjectClass::Car => &self.car,
            ObjectClass::Truck => &self.truck,
            ObjectClass::Cyclist => &self.cyclist,
            ObjectClass::Pedestrian => &self.pedestrian,
        }
    }

    /// Recall loss with range: 1 at the sensor, 1/2 at `half_recall_range_m`
    /// (normalised logistic), 0 beyond `max_range_m`.
    pub fn range_factor(&self, range_m: f64) -> f64 {
        if range_m > self.max_range_m {
            return 0.0;
        }
        let x = range_m / self.half_recall_range_m - 1.0;
        (1.0 + (-RANGE_STEEPNESS).exp()) / (1.0 + (RANGE_STEEPNESS * x).exp())
    }

    /// Recall loss with occlusion/sparsity: 0 below `min_points`, then
    /// sqrt(points / full_recall_points) up to 1 (a detector needs few
    /// points to find an object, the square root rewards the first ones).
    pub fn occlusion_factor(&self, points: usize) -> f64 {
        if points < self.min_points {
            return 0.0;
        }
        if self.full_recall_points == 0 {
            return 1.0;
        }
        (points as f64 / self.full_recall_points as f64)
            .min(1.0)
            .sqrt()
    }

    /// Probability that an object at `range_m` (horizontal, LiDAR frame)
    /// hit by `points` LiDAR returns is detected.
    pub fn recall(&self, range_m: f64, points: usize) -> f64 {
        self.max_recall * self.range_factor(range_m) * self.occlusion_factor(points)
    }
}

/// A detection with its ground truth instance id (None: false positive).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectionWithTruth {
    /// The noisy detection, LiDAR frame at the sweep start.
    pub detection: Detection,
    /// Instance id of the agent it came from; `None` for a false positive.
    pub truth_id: Option<u32>,
}

/// Turns ground truth into noisy per-frame detections, deterministically
/// from the seed and the frame index.
#[derive(Debug, Clone, PartialEq)]
pub struct Detector {
    config: DetectorConfig,
    seed: u64,
}

impl Detector {
    /// A detector with a validated `config` whose noise is drawn from `seed`.
    ///
    /// # Errors
    /// [`DetectorError::BadConfig`] if `config` is invalid.
    pub fn new(config: DetectorConfig, seed: u64) -> Result<Detector, DetectorError> {
        config.validate()?;
        Ok(Detector { config, seed })
    }

    /// The configuration this detector was built with.
    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// The random stream of one frame: frames are independent of each other
    /// and of the order in which they are generated.
    fn frame_rng(&self, frame_index: u64) -> ChaCha8Rng {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_stream(frame_index);
        rng
    }

    /// The noise-free box of `agent` as the sweep starting at `t_scan_s`
    /// sees it: at the time the head passes the box centre's azimuth (taken
    /// at the scan start), in the LiDAR frame at that time. Score 1.
    pub fn sighted_box(agent: &Agent, ego: &Ego, t_scan_s: f64, lidar: &LidarConfig) -> Detection {
        let t_world_lidar0 = ego.trajectory.pose_at(t_scan_s);
        let center0 = t_world_lidar0
            .inverse_transform_point(&agent.trajectory.pose_at(t_scan_s).translation.vector.into());
        let time_offset_s = lidar.time_offset_of_azimuth(center0.y.atan2(center0.x));
        let t_seen_s = t_scan_s + time_offset_s;
        let t_lidar_box =
            ego.trajectory.pose_at(t_seen_s).inverse() * agent.trajectory.pose_at(t_seen_s);
        let r = t_lidar_box.rotation.to_rotation_matrix();
        Detection {
            box_lidar: OrientedBox {
                center: t_lidar_box.translation.vector,
                size_lwh: agent.size_lwh_m,
                // heading of the box's x axis projected on the LiDAR's xy plane
                yaw_rad: r[(1, 0)].atan2(r[(0, 0)]),
            },
            class: agent.class,
            score: 1.0,
            time_offset_s,
        }
    }

    /// Detections of the sweep starting at `t_scan_s` (frame `frame_index`):
    /// every agent of the scene present at `t_scan_s` is detected with probability
    /// `recall(range, points_per_instance[id])` and its sighted box noised
    /// per class; then a Poisson number of false positives. Agents come in
    /// scene order, false positives last.
    ///
    /// # Errors
    /// [`DetectorError::BadScanTime`] for a non-finite `t_scan_s`;
    /// [`DetectorError::BadDetection`] if a generated box fails the
    /// estimator input's checks (a bad scene or LiDAR config).
    pub fn detect(
        &self,
        frame_index: u64,
        t_scan_s: f64,
        scene: &Scene,
        points_per_instance: &BTreeMap<u32, usize>,
        lidar: &LidarConfig,
    ) -> Result<Vec<DetectionWithTruth>, DetectorError> {
        if !t_scan_s.is_finite() {
            return Err(DetectorError::BadScanTime { t_s: t_scan_s });
        }
        let mut rng = self.frame_rng(frame_index);
        let mut out = Vec::new();
        // agents absent at the sweep start are not there to be detected
        for agent in scene.agents.iter().filter(|a| a.is_present(t_scan_s)) {
            let truth = Self::sighted_box(agent, &scene.ego, t_scan_s, lidar);
            // a non-finite trajectory or LiDAR timing must not reach the RNG
            truth.validate(t_scan_s, out.len())?;
            let points = points_per_instance.get(&agent.id).copied().unwrap_or(0);
            let range_m = truth.box_lidar.center.xy().norm();
            let recall = self.config.recall(range_m, points);
            if !rng.random_bool(recall.clamp(0.0, 1.0)) {
                continue;
            }
            let visibility =
                self.config.range_factor(range_m) * self.config.occlusion_factor(points);
            let detection = self.noisy(&truth, visibility, &mut rng);
            out.push(DetectionWithTruth {
                detection,
                truth_id: Some(agent.id),
            });
        }
        for _ in 0..self.false_positive_count(&mut rng) {
            if let Some(detection) = self.false_positive(t_scan_s, scene, lidar, &mut rng) {
                out.push(DetectionWithTruth {
                    detection,
                    truth_id: None,
                });
            }
        }
        for (index, d) in out.iter().enumerate() {
            d.detection.validate(t_scan_s, index)?;
        }
        Ok(out)
    }

    /// The true box with the class's centre, size and yaw noise, a possible
    /// heading flip, and a score that grows with visibility.
    fn noisy(&self, truth: &Detection, visibility: f64, rng: &mut ChaCha8Rng) -> Detection {
        let noise = self.config.noise(truth.class);
        let center_lidar = truth.box_lidar.center + gaussian_vector(rng) * noise.position_sigma_m;
        let size_lwh = (truth.box_lidar.size_lwh + gaussian_vector(rng) * noise.size_sigma_m)
            .map(|s| s.max(MIN_SIZE_M));
        let mut yaw_rad = truth.box_lidar.yaw_rad + gaussian(rng) * noise.yaw_sigma_rad;
        if rng.random_bool(noise.heading_flip_probability) {
            yaw_rad += PI;
        }
        let score =
            TRUE_SCORE_BASE + TRUE_SCORE_GAIN * visibility + TRUE_SCORE_SIGMA * gaussian(rng);
        Detection {
            box_lidar: OrientedBox {
                center: center_lidar,
                size_lwh,
                yaw_rad: wrap_angle_rad(yaw_rad),
            },
            class: truth.class,
            score: score.clamp(0.0, 1.0),
            time_offset_s: truth.time_offset_s,
        }
    }

    fn false_positive_count(&self, rng: &mut ChaCha8Rng) -> usize {
        let mean = self.config.false_positives_per_frame;
        match Poisson::new(mean) {
            Ok(poisson) => rng.sample(poisson) as usize,
            // mean == 0 (validated otherwise)
            Err(_) => 0,
        }
    }

    /// A car-sized box standing on the ground, uniformly distributed over
    /// the area between `FALSE_MIN_RANGE_M` and `max_range_m` around the
    /// LiDAR. None when the tilt of the LiDAR pushes it out of range.
    fn false_positive(
        &self,
        t_scan_s: f64,
        scene: &Scene,
        lidar: &LidarConfig,
        rng: &mut ChaCha8Rng,
    ) -> Option<Detection> {
        let (r_min, r_max) = (
            FALSE_MIN_RANGE_M.min(self.config.max_range_m),
            self.config.max_range_m,
        );
        let range_m =
            (rng.random_range(0.0..=1.0) * (r_max * r_max - r_min * r_min) + r_min * r_min).sqrt();
        let azimuth = rng.random_range(-PI..PI);
        let size_lwh = Vector3::from_fn(|i, _| {
            (FALSE_SIZE_MEAN_M[i] + FALSE_SIZE_SIGMA_M[i] * gaussian(rng)).max(MIN_SIZE_M)
        });
        let yaw_rad = wrap_angle_rad(rng.random_range(-PI..PI));
        let score = rng.random_range(FALSE_SCORE_MIN..FALSE_SCORE_MAX);

        let time_offset_s = lidar.time_offset_of_azimuth(azimuth);
        let t_world_lidar = scene.ego.trajectory.pose_at(t_scan_s + time_offset_s);
        // the azimuth's direction levelled in the world, so the box stands on the ground
        let direction = t_world_lidar.rotation * Vector3::new(azimuth.cos(), azimuth.sin(), 0.0);
        let horizontal = Vector3::new(direction.x, direction.y, 0.0).try_normalize(1e-9)?;
        let xy = t_world_lidar.translation.vector + horizontal * range_m;
        let center_world = Point3::new(
            xy.x,
            xy.y,
            scene.ground.height(xy.x, xy.y) + 0.5 * size_lwh.z,
        );
        let center_lidar = t_world_lidar.inverse_transform_point(&center_world).coords;
        if center_lidar.xy().norm() > self.config.max_range_m {
            return None;
        }
        Some(Detection {
            box_lidar: OrientedBox {
                center: center_lidar,
                size_lwh,
                yaw_rad,
            },
            class: ObjectClass::Car,
            score,
            time_offset_s,
        })
    }
}

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample(StandardNormal)
}

fn gaussian_vector(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recall_shape_matches_the_documented_figures() {
        let cfg = DetectorConfig::default();
        assert!((cfg.range_factor(0.0) - 1.0).abs() < 1e-12);
        assert!((cfg.range_factor(cfg.half_recall_range_m) - 0.5).abs() < 1e-3);
        assert!(cfg.range_factor(35.0) > 0.99);
        assert_eq!(cfg.range_factor(80.1), 0.0);
        assert_eq!(cfg.occlusion_factor(4), 0.0);
        assert_eq!(cfg.occlusion_factor(60), 1.0);
        assert_eq!(cfg.occlusion_factor(6000), 1.0);
        assert!((cfg.occlusion_factor(15) - 0.5).abs() < 1e-12);
        assert!((cfg.recall(10.0, 100) - cfg.max_recall).abs() < 1e-3);
    }

    #[test]
    fn defaults_validate() {
        assert!(DetectorConfig::default().validate().is_ok());
    }
}
