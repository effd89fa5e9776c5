//! The LiDAR front end of one sweep: its motion over the sweep from the IMU,
//! de-skew, LOAM features, removal of the variant's object features,
//! downsampling, scan-to-map matching and the local-map update.

use super::EgoState;
use super::Estimator;
use super::EstimatorError;
use crate::geometry::OrientedBox;
use crate::imu::ImuTrajectory;
use crate::input::LidarScan;
use crate::lidar::LocalMapError;
use crate::lidar::ScanFeatures;
use crate::lidar::{DeskewError, SweepMotion};
use crate::lidar::{ScanMatchResult, match_scan};
use crate::object_removal::{BoxAtTime, all_boxes_mask, dynamic_feature_mask};
use crate::pipeline::config::Variant;
use crate::pipeline::estimate::{ModuleTimings, ScanMatchSummary};
use crate::tracking::{Lifecycle, Motion, Track};
use nalgebra::{Isometry3, Vector3};
use std::time::Instant;

/// A dynamic track's box at any time, from its trajectory fit.
struct TrackBox(Track);

impl BoxAtTime for TrackBox {
    fn box_at(&self, t_s: f64) -> OrientedBox {
        let p = self.0.predict(t_s);
        OrientedBox {
            center: p.center_world,
            yaw_rad: p.yaw_rad,
            size_lwh: self.0.size_lwh(),
        }
    }
}

/// Features of one de-skewed sweep, LiDAR frame at the scan start.
pub(super) struct SweepFeatures {
    pub(super) edge_lidar: Vec<Vector3<f64>>,
    pub(super) planar_lidar: Vec<Vector3<f64>>,
    /// Indices (into the scan's points) of features dropped as object points.
    pub(super) removed: Vec<u32>,
    /// Every feature index before the filter, when `record_feature_indices`.
    pub(super) all_indices: Vec<u32>,
}

/// Which feature points to drop before matching (the variants).
pub(super) enum FeatureFilter {
    /// `lio`: keep everything.
    Keep,
    /// `allfilt`: every detected box, fixed, in the world frame.
    AllBoxes(Vec<OrientedBox>),
    /// `dynafilt`: boxes of dynamic tracks, each at the point's own time.
    Moving(Vec<Box<dyn BoxAtTime>>),
}

impl Estimator {
    /// LiDAR poses over the sweep from IMU propagation of `start` (a state at
    /// the scan start). Instants past the end of the IMU data are left out;
    /// [`SweepMotion`] extrapolates with the last segment's velocity there.
    pub(super) fn imu_sweep_motion(
        &self,
        start: &EgoState,
        scan: &LidarScan,
        timings: &mut ModuleTimings,
    ) -> Result<SweepMotion, DeskewError> {
        let clock = Instant::now();
        let n = self.config.deskew_samples.max(2);
        let last_imu_s = self.imu.last().map_or(start.t_s, |s| s.t_s);
        let sweep_end_s = (start.t_s + scan.sweep_duration_s).min(last_imu_s);
        let mut samples = vec![(start.t_s, start.t_world_imu * self.t_imu_lidar)];
        if sweep_end_s > start.t_s
            && let Ok(trajectory) = ImuTrajectory::propagate(
                &self.imu,
                start.t_s,
                sweep_end_s,
                &start.t_world_imu,
                &start.velocity_world_mps,
                &start.bias,
                &self.gravity_world,
                self.config.max_imu_gap_s,
            )
        {
            for i in 1..n {
                let t = start.t_s + (sweep_end_s - start.t_s) * i as f64 / (n - 1) as f64;
                if let Ok(t_world_imu) = trajectory.pose_at(t) {
                    samples.push((t, t_world_imu * self.t_imu_lidar));
                }
            }
        }
        if samples.len() == 1 {
            // No IMU inside the sweep: constant velocity from the state.
            let end_s = start.t_s + scan.sweep_duration_s.max(1e-3);
            let mut t_end = start.t_world_imu;
            t_end.translation.vector += start.velocity_world_mps * (end_s - start.t_s);
            samples.push((end_s, t_end * self.t_imu_lidar));
        }
        let motion = SweepMotion::from_poses(samples);
        timings.imu_prediction += clock.elapsed();
        motion
    }

    /// De-skews to the scan start, extracts LOAM features and downsamples them.
    pub(super) fn sweep_features(
        &mut self,
        scan: &LidarScan,
        motion: &SweepMotion,
        t_ref_s: f64,
        filter: &FeatureFilter,
        timings: &mut ModuleTimings,
    ) -> SweepFeatures {
        let clock = Instant::now();
        self.deskewed.clear();
        self.deskewer
            .deskew(scan, motion, t_ref_s, &mut self.deskewed);
        timings.deskew = clock.elapsed();

        let clock = Instant::now();
        let mut features = self.feature_extractor.extract(&self.deskewed, scan);
        timings.features = clock.elapsed();

        let all_indices = if self.config.record_feature_indices {
            let mut all: Vec<u32> = features
                .edge_indices
                .iter()
                .chain(&features.planar_indices)
                .map(|&i| i as u32)
                .collect();
            all.sort_unstable();
            all
        } else {
            Vec::new()
        };
        let clock = Instant::now();
        let removed = self.filter_features(scan, motion, filter, &mut features);
        timings.filter = clock.elapsed();

        let clock = Instant::now();
        let deskewed = &self.deskewed;
        self.gathered.clear();
        self.gathered
            .extend(features.edge_indices.iter().map(|&i| deskewed[i]));
        let edge_lidar = self
            .downsampler
            .downsample(&self.gathered, self.config.edge_voxel_m);
        self.gathered.clear();
        self.gathered
            .extend(features.planar_indices.iter().map(|&i| deskewed[i]));
        let planar_lidar = self
            .downsampler
            .downsample(&self.gathered, self.config.planar_voxel_m);
        let result = SweepFeatures {
            edge_lidar,
            planar_lidar,
            removed,
            all_indices,
        };
        timings.downsample = clock.elapsed();
        result
    }

    /// The variant's object boxes for this sweep.
    pub(super) fn feature_filter(&self, scan: &LidarScan, motion: &SweepMotion) -> FeatureFilter {
        match self.config.variant {
            Variant::Lio => FeatureFilter::Keep,
            Variant::Allfilt => FeatureFilter::AllBoxes(
                self.frame_detections
                    .iter()
                    .map(|d| {
                        d.box_lidar
                            .transformed(&motion.pose_at(scan.t_s + d.time_offset_s))
                    })
                    .collect(),
            ),
            Variant::Dynafilt | Variant::Limot => FeatureFilter::Moving(
                self.tracker
                    .tracks()
                    .iter()
                    .filter(|t| {
                        t.motion() == Motion::Dynamic
                            && (t.lifecycle() == Lifecycle::Confirmed
                                || !self.config.filter_confirmed_only)
                    })
                    .map(|t| Box::new(TrackBox(t.clone())) as Box<dyn BoxAtTime>)
                    .collect(),
            ),
        }
    }

    /// Drops the feature points that lie in the variant's object boxes,
    /// testing each RAW point at its own time against the box then (the
    /// ego pose comes from the sweep motion). Returns the dropped indices.
    fn filter_features(
        &self,
        scan: &LidarScan,
        motion: &SweepMotion,
        filter: &FeatureFilter,
        features: &mut ScanFeatures,
    ) -> Vec<u32> {
        if matches!(filter, FeatureFilter::Keep) {
            return Vec::new();
        }
        // Edge features first, then planar: mask[..n_edge] belongs to the
        // edge list, mask[n_edge..] to the planar list.
        let n_edge = features.edge_indices.len();
        let indices = || features.edge_indices.iter().chain(&features.planar_indices);
        let points: Vec<Vector3<f64>> = indices().map(|&i| scan.points[i].position()).collect();
        let times: Vec<f64> = indices()
            .map(|&i| scan.t_s + f64::from(scan.points[i].time_offset_s))
            .collect();
        let pose_at = |t: f64| motion.pose_at(t);
        let mask = match filter {
            FeatureFilter::Keep => return Vec::new(),
            FeatureFilter::AllBoxes(boxes) => {
                all_boxes_mask(&points, &times, &pose_at, boxes, &self.config.filter)
            }
            FeatureFilter::Moving(boxes) => {
                let refs: Vec<&dyn BoxAtTime> = boxes.iter().map(|b| b.as_ref()).collect();
                dynamic_feature_mask(&points, &times, &pose_at, &refs, &self.config.filter)
            }
        };
        // The inputs are finite and equally long and the config is
        // validated at construction, so the filter cannot fail here.
        let mask = mask.unwrap_or_else(|_| vec![false; points.len()]);
        if !mask.contains(&true) {
            return Vec::new();
        }
        let mut removed: Vec<u32> = indices()
            .zip(&mask)
            .filter(|(_, drop)| **drop)
            .map(|(&i, _)| i as u32)
            .collect();
        removed.sort_unstable();
        removed.dedup();
        // The mask depends on a point's position and time only, so an index
        // listed twice gets the same verdict at both places.
        let (edge_mask, planar_mask) = mask.split_at(n_edge);
        let mut edge_drop = edge_mask.iter();
        features
            .edge_indices
            .retain(|_| !edge_drop.next().copied().unwrap_or(false));
        let mut planar_drop = planar_mask.iter();
        features
            .planar_indices
            .retain(|_| !planar_drop.next().copied().unwrap_or(false));
        removed
    }

    pub(super) fn match_features(
        &self,
        features: &SweepFeatures,
        initial_t_world_lidar: &Isometry3<f64>,
    ) -> Option<ScanMatchResult> {
        if self.map.is_empty() {
            return None;
        }
        match_scan(
            &self.map,
            &features.edge_lidar,
            &features.planar_lidar,
            initial_t_world_lidar,
            &self.config.scan_match,
        )
        .ok()
    }

    /// Adds the sweep's features to the local map when it is a keyframe
    /// (enough motion since the last one) or when `force`d (the first sweep).
    pub(super) fn update_map(
        &mut self,
        frame_index: u64,
        t_s: f64,
        t_world_lidar: &Isometry3<f64>,
        features: &SweepFeatures,
        force: bool,
    ) -> Result<(), EstimatorError> {
        if !force && !self.is_keyframe(t_world_lidar) {
            return Ok(());
        }
        self.add_keyframe(t_world_lidar, features)
            .map_err(|source| EstimatorError::Map {
                frame_index,
                t_s,
                source,
            })
    }

    fn is_keyframe(&self, t_world_lidar: &Isometry3<f64>) -> bool {
        match &self.last_keyframe_t_world_lidar {
            None => true,
            Some(last) => {
                let delta = last.inverse() * t_world_lidar;
                delta.translation.vector.norm() >= self.config.keyframe_distance_m
                    || delta.rotation.angle() >= self.config.keyframe_angle_rad
            }
        }
    }

    fn add_keyframe(
        &mut self,
        t_world_lidar: &Isometry3<f64>,
        features: &SweepFeatures,
    ) -> Result<(), LocalMapError> {
        if features.edge_lidar.is_empty() && features.planar_lidar.is_empty() {
            return Ok(());
        }
        self.map
            .add_keyframe(t_world_lidar, &features.edge_lidar, &features.planar_lidar)?;
        self.last_keyframe_t_world_lidar = Some(*t_world_lidar);
        Ok(())
    }
}

pub(super) fn summary(result: &ScanMatchResult, features: &SweepFeatures) -> ScanMatchSummary {
    ScanMatchSummary {
        edge_features: features.edge_lidar.len(),
        planar_features: features.planar_lidar.len(),
        edge_matches: result.edge_matches,
        planar_matches: result.planar_matches,
        iterations: result.iterations,
        converged: result.converged,
        degenerate_directions: result.degenerate_directions,
        rms_residual_m: result.rms_residual_m,
    }
}
