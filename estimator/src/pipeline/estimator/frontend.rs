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
use crate::lidar::{ScanMatchConfig, ScanMatchResult, match_scan};
use crate::object_removal::{BoxAtTime, ConstantVelocityBox, moving_box_mask};
use crate::pipeline::config::Variant;
use crate::pipeline::estimate::{ModuleTimings, ScanMatchSummary};
use crate::tracking::{Lifecycle, Motion, Track, TrackerConfig};
use nalgebra::{Isometry3, Vector3};
use std::time::Instant;

/// A dynamic track's box at any time, from its trajectory fit.
struct TrackBox(Track);

impl BoxAtTime for TrackBox {
    fn box_at(&self, t_s: f64) -> OrientedBox {
        box_at(&self.0, t_s)
    }
}

/// `track`'s predicted box at `t_s`, world frame.
fn box_at(track: &Track, t_s: f64) -> OrientedBox {
    let p = track.predict(t_s);
    OrientedBox {
        center: p.center_world,
        yaw_rad: p.yaw_rad,
        size_lwh: track.size_lwh(),
    }
}

/// The 99 % quantile of the chi-square distribution with 2 degrees of
/// freedom: a horizontal offset this many variances away is not noise.
const CHI2_2DOF_99: f64 = 9.21;

/// Whether a detection centred at `center_world` has left the place where
/// the static `track` stood: its horizontal offset from the mean centre of
/// the track's motion window exceeds the detection noise
/// (`detection_sigma_m` per axis, plus the mean's own) at 99 %.
fn departs_from_standstill(
    track: &Track,
    center_world: &Vector3<f64>,
    config: &TrackerConfig,
) -> bool {
    let history = track.history();
    let n = history.len().min(config.motion_window_frames.max(1));
    let mean = history
        .iter()
        .rev()
        .take(n)
        .map(|b| b.center_world)
        .sum::<Vector3<f64>>()
        / n as f64;
    let variance_m2 = config.detection_sigma_m.powi(2) * (1.0 + 1.0 / n as f64);
    (center_world - mean).xy().norm_squared() > CHI2_2DOF_99 * variance_m2
}

/// Features of one de-skewed sweep, LiDAR frame at the scan start.
pub(super) struct SweepFeatures {
    pub(super) edge_lidar: Vec<Vector3<f64>>,
    pub(super) planar_lidar: Vec<Vector3<f64>>,
    /// Indices (into the scan's points) of features dropped as object points.
    pub(super) removed: Vec<u32>,
    /// Every feature index before the filter, when `record_feature_indices`.
    pub(super) all_indices: Vec<u32>,
    /// The edge features among `all_indices`, ascending.
    pub(super) all_edge_indices: Vec<u32>,
}

/// What [`Estimator::deskewed_sweep`] shows of the last sweep besides the
/// de-skewed points.
pub(super) struct LastSweep {
    pub(super) frame_index: u64,
    pub(super) t_s: f64,
    pub(super) t_ref_s: f64,
    pub(super) motion: SweepMotion,
    pub(super) removed: Vec<u32>,
}

/// Which feature points to drop before matching (the variants).
pub(super) enum FeatureFilter {
    /// `lio`: keep everything.
    Keep,
    /// `allfilt`: every detected box, fixed, in the world frame.
    AllBoxes(Vec<OrientedBox>),
    /// `dynafilt`: boxes of dynamic tracks, each at the point's own time,
    /// and the boxes whose edge points alone are dropped (confirmed static
    /// tracks at the sweep's middle, with
    /// [`EstimatorConfig::filter_static_edges`]).
    Moving {
        boxes: Vec<Box<dyn BoxAtTime>>,
        edges_only: Vec<OrientedBox>,
    },
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
                &self.gravity_world(),
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

        let (all_indices, all_edge_indices) = if self.config.record_feature_indices {
            let sorted = |indices: &mut dyn Iterator<Item = &usize>| {
                let mut all: Vec<u32> = indices.map(|&i| i as u32).collect();
                all.sort_unstable();
                all
            };
            (
                sorted(&mut features.edge_indices.iter().chain(&features.planar_indices)),
                sorted(&mut features.edge_indices.iter()),
            )
        } else {
            (Vec::new(), Vec::new())
        };
        let clock = Instant::now();
        let removed = self.filter_features(scan, motion, filter, &mut features);
        timings.filter = clock.elapsed();
        self.last_sweep = Some(LastSweep {
            frame_index: self.next_frame_index - 1,
            t_s: scan.t_s,
            t_ref_s,
            motion: motion.clone(),
            removed: removed.clone(),
        });

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
            all_edge_indices,
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
            Variant::Dynafilt | Variant::Limot => {
                let moving = |t: &&Track| {
                    filters_as_moving(t, self.config.filter_stopped_movers)
                        && (t.lifecycle() == Lifecycle::Confirmed
                            || !self.config.filter_confirmed_only)
                };
                let mut boxes: Vec<Box<dyn BoxAtTime>> = self
                    .tracker
                    .tracks()
                    .iter()
                    .filter(moving)
                    .map(|t| Box::new(TrackBox(t.clone())) as Box<dyn BoxAtTime>)
                    .collect();
                if self.config.filter_unsettled_detections {
                    boxes.extend(self.unsettled_detection_boxes(scan, motion));
                }
                let edges_only = if self.config.filter_static_edges {
                    let middle_s = scan.t_s + 0.5 * scan.sweep_duration_s;
                    self.tracker
                        .tracks()
                        .iter()
                        .filter(|t| {
                            t.lifecycle() == Lifecycle::Confirmed
                                && !filters_as_moving(t, self.config.filter_stopped_movers)
                        })
                        .map(|t| box_at(t, middle_s))
                        .collect()
                } else {
                    Vec::new()
                };
                FeatureFilter::Moving { boxes, edges_only }
            }
        }
    }

    /// This sweep's detections that no confirmed static track explains, as
    /// boxes for the trajectory-based filter. A detection belongs to the
    /// track whose predicted centre is nearest within
    /// `filter.detection_track_gate_m`; a confirmed static track explains it
    /// unless the detection has left where the track stood (see
    /// [`departs_from_standstill`]: a car pulling away is judged dynamic
    /// only once its window-average speed is significant, a second or more
    /// later). A detection of a moving (or departing) track moves on from
    /// its own time with the track's fitted velocity: this sweep's
    /// measurement of where the car is, which the prediction from the last
    /// sweep may miss. Any other one (an object too new to be judged, a
    /// tentative track) stays where it was detected, as in `allfilt`.
    fn unsettled_detection_boxes(
        &self,
        scan: &LidarScan,
        motion: &SweepMotion,
    ) -> Vec<Box<dyn BoxAtTime>> {
        let gate_sq = self.config.filter.detection_track_gate_m.powi(2);
        let mut boxes: Vec<Box<dyn BoxAtTime>> = Vec::new();
        for d in &self.frame_detections {
            let t_s = scan.t_s + d.time_offset_s;
            let box_world = d.box_lidar.transformed(&motion.pose_at(t_s));
            let nearest = self
                .tracker
                .tracks()
                .iter()
                .map(|t| (t, t.predict(t_s)))
                .map(|(t, p)| (t, (p.center_world - box_world.center).norm_squared(), p))
                .filter(|(_, d_sq, _)| *d_sq <= gate_sq)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let moving_box = |velocity_world_mps| {
                Box::new(ConstantVelocityBox {
                    box_ref: box_world,
                    t_ref_s: t_s,
                    velocity_world_mps,
                    yaw_rate_radps: 0.0,
                }) as Box<dyn BoxAtTime>
            };
            match nearest {
                Some((t, _, p)) if filters_as_moving(t, self.config.filter_stopped_movers) => {
                    boxes.push(moving_box(p.velocity_world_mps));
                }
                Some((t, _, p)) if t.lifecycle() == Lifecycle::Confirmed => {
                    if departs_from_standstill(t, &box_world.center, &self.config.tracker) {
                        boxes.push(moving_box(p.velocity_world_mps));
                    }
                    // otherwise a settled static object: its features stay
                }
                _ => boxes.push(Box::new(box_world)),
            }
        }
        boxes
    }

    /// Drops the feature points that lie in the variant's object boxes,
    /// testing each RAW point at its own time against the box then (the
    /// ego pose comes from the sweep motion), and the edge points in the
    /// edge-only boxes. Returns the dropped indices, ascending.
    fn filter_features(
        &self,
        scan: &LidarScan,
        motion: &SweepMotion,
        filter: &FeatureFilter,
        features: &mut ScanFeatures,
    ) -> Vec<u32> {
        let (boxes, edges_only): (Vec<&dyn BoxAtTime>, Vec<&dyn BoxAtTime>) = match filter {
            FeatureFilter::Keep => return Vec::new(),
            FeatureFilter::AllBoxes(boxes) => (
                boxes.iter().map(|b| b as &dyn BoxAtTime).collect(),
                Vec::new(),
            ),
            FeatureFilter::Moving { boxes, edges_only } => (
                boxes.iter().map(|b| b.as_ref()).collect(),
                edges_only.iter().map(|b| b as &dyn BoxAtTime).collect(),
            ),
        };
        let mut flags = vec![false; scan.points.len()];
        let mut removed = if boxes.is_empty() {
            Vec::new()
        } else {
            let in_scan_order = features_in_scan_order(features, &mut flags);
            self.points_in_boxes(scan, motion, &boxes, &in_scan_order)
        };
        for &i in &removed {
            flags[i as usize] = true;
        }
        if !edges_only.is_empty() {
            let mut edges: Vec<u32> = features
                .edge_indices
                .iter()
                .filter(|&&i| !flags[i])
                .map(|&i| i as u32)
                .collect();
            edges.sort_unstable();
            let more = self.points_in_boxes(scan, motion, &edges_only, &edges);
            for &i in &more {
                flags[i as usize] = true;
            }
            if !more.is_empty() {
                removed = merged(&removed, &more);
            }
        }
        if !removed.is_empty() {
            features.edge_indices.retain(|&i| !flags[i]);
            features.planar_indices.retain(|&i| !flags[i]);
        }
        removed
    }

    /// The points `in_scan_order` (ascending indices into the scan) that lie
    /// in `boxes`, each tested at its own time, ascending.
    fn points_in_boxes(
        &self,
        scan: &LidarScan,
        motion: &SweepMotion,
        boxes: &[&dyn BoxAtTime],
        in_scan_order: &[u32],
    ) -> Vec<u32> {
        if boxes.is_empty() {
            return Vec::new();
        }
        let point = |k: usize| &scan.points[in_scan_order[k] as usize];
        let pose_at = |t: f64| motion.pose_at(t);
        let mut mask = vec![false; in_scan_order.len()];
        // The point times are finite and the config is validated at
        // construction, so the filter cannot fail here; if it did, nothing
        // would be dropped.
        if moving_box_mask(
            |k| point(k).position(),
            |k| scan.t_s + f64::from(point(k).time_offset_s),
            &pose_at,
            boxes,
            &self.config.filter,
            &mut mask,
        )
        .is_err()
        {
            return Vec::new();
        }
        in_scan_order
            .iter()
            .zip(&mask)
            .filter(|(_, drop)| **drop)
            .map(|(&i, _)| i)
            .collect()
    }

    pub(super) fn match_features(
        &self,
        features: &SweepFeatures,
        initial_t_world_lidar: &Isometry3<f64>,
    ) -> Option<ScanMatchResult> {
        self.match_features_with(features, initial_t_world_lidar, &self.config.scan_match)
    }

    /// [`Estimator::match_features`] with other matcher settings.
    pub(super) fn match_features_with(
        &self,
        features: &SweepFeatures,
        initial_t_world_lidar: &Isometry3<f64>,
        config: &ScanMatchConfig,
    ) -> Option<ScanMatchResult> {
        if self.map.is_empty() {
            return None;
        }
        match_scan(
            &self.map,
            &features.edge_lidar,
            &features.planar_lidar,
            initial_t_world_lidar,
            config,
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

/// The feature points of `features` in scan order (ascending indices): the
/// lists are in ring order, and a scan stored by firing column (the
/// simulator's) read in ring order would touch a new cache line per point.
/// `flags` holds one flag per scan point, all false on entry and on return.
fn features_in_scan_order(features: &ScanFeatures, flags: &mut [bool]) -> Vec<u32> {
    for &i in features.edge_indices.iter().chain(&features.planar_indices) {
        flags[i] = true;
    }
    // Three in four points are features, in no predictable pattern: every
    // index is written and the end advanced only for a feature.
    let mut in_scan_order = vec![0u32; flags.len()];
    let mut end = 0;
    for (i, &feature) in flags.iter().enumerate() {
        in_scan_order[end] = i as u32;
        end += usize::from(feature);
    }
    in_scan_order.truncate(end);
    flags.fill(false);
    in_scan_order
}

/// The union of two ascending, disjoint index lists, ascending.
fn merged(a: &[u32], b: &[u32]) -> Vec<u32> {
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        if a[i] < b[j] {
            out.push(a[i]);
            i += 1;
        } else {
            out.push(b[j]);
            j += 1;
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

/// Whether the trajectory-based filter treats a track as moving: dynamic
/// now, or (with `stopped_movers`) dynamic once and standing now.
fn filters_as_moving(track: &Track, stopped_movers: bool) -> bool {
    track.motion() == Motion::Dynamic || (stopped_movers && track.has_moved())
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracking::TimedBox;

    /// A track of a car standing at x = 10 m for 12 frames, with the
    /// detector's ±σ scatter along y.
    fn standing_track(config: &TrackerConfig) -> Track {
        let at = |k: usize| TimedBox {
            t_s: 0.1 * k as f64,
            center_world: Vector3::new(
                10.0,
                config.detection_sigma_m * if k.is_multiple_of(2) { 1.0 } else { -1.0 },
                0.8,
            ),
            yaw_rad: 0.0,
            size_lwh: Vector3::new(4.2, 1.8, 1.6),
        };
        let mut track = Track::new(1, crate::input::ObjectClass::Car, at(0), config).unwrap();
        for k in 1..12 {
            track.record_hit(at(k), config).unwrap();
        }
        track
    }

    /// A car that drives at 8 m/s for a second and then stands: static by
    /// its speed, yet filtered as moving unless the rule is off; a car that
    /// only ever stood is not.
    #[test]
    fn a_car_that_drove_and_stopped_is_filtered_as_moving() {
        let config = TrackerConfig::default();
        let parked = standing_track(&config);
        assert!(!parked.has_moved());
        assert!(!filters_as_moving(&parked, true));
        let at = |k: usize| {
            let x = 8.0 * 0.1 * k.min(10) as f64;
            TimedBox {
                t_s: 0.1 * k as f64,
                center_world: Vector3::new(x, 0.0, 0.8),
                yaw_rad: 0.0,
                size_lwh: Vector3::new(4.2, 1.8, 1.6),
            }
        };
        let mut track = Track::new(2, crate::input::ObjectClass::Car, at(0), &config).unwrap();
        let mut was_dynamic = false;
        for k in 1..40 {
            track.record_hit(at(k), &config).unwrap();
            was_dynamic |= track.motion() == Motion::Dynamic;
        }
        assert!(was_dynamic);
        assert_eq!(track.motion(), Motion::Static, "{} m/s", track.speed_mps());
        assert!(track.has_moved());
        assert!(filters_as_moving(&track, true));
        assert!(!filters_as_moving(&track, false));
    }

    #[test]
    fn a_standing_car_explains_its_noisy_detections_but_not_a_departure() {
        let config = TrackerConfig::default();
        let track = standing_track(&config);
        assert_eq!(track.motion(), Motion::Static);
        assert_eq!(track.lifecycle(), Lifecycle::Confirmed);
        let sigma = config.detection_sigma_m;
        // within the detector's noise, in any direction: still standing
        for (dx, dy) in [(2.0, 0.0), (0.0, -2.0), (1.5, 1.5)] {
            let c = Vector3::new(10.0 + dx * sigma, dy * sigma, 0.8);
            assert!(!departs_from_standstill(&track, &c, &config), "{dx} {dy}");
        }
        // 0.6 m ahead (a car pulling away at 1.4 m/s², 0.9 s and 1.3 m/s
        // later; the 99 % bound is 0.48 m): departed
        let c = Vector3::new(10.6, 0.0, 0.8);
        assert!(departs_from_standstill(&track, &c, &config));
        // height is not a departure (the detector's box height varies)
        let c = Vector3::new(10.0, 0.0, 2.0);
        assert!(!departs_from_standstill(&track, &c, &config));
    }
}
