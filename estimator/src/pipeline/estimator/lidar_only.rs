//! LiDAR-only odometry: scan-to-map matching with a constant-velocity
//! motion model on mid-sweep poses, for sources without an IMU and for the
//! sweeps before the inertial initialization.

use super::frontend::{SweepFeatures, summary};
use super::{Estimator, EstimatorError};
use crate::imu::ImuBias;
use crate::input::LidarScan;
use crate::lidar::{ScanMatchConfig, ScanMatchResult, SweepMotion};
use crate::lie;
use crate::pipeline::estimate::{FrameEstimate, ModuleTimings};
use nalgebra::{Isometry3, Vector3, Vector6};
use std::time::Instant;

impl Estimator {
    pub(super) fn process_lidar_only(
        &mut self,
        frame_index: u64,
        scan: &LidarScan,
    ) -> Result<FrameEstimate, EstimatorError> {
        let mut timings = ModuleTimings::default();
        let t_s = scan.t_s;
        let clock = Instant::now();
        // Without an IMU the sweep is de-skewed to its MIDDLE and matched
        // there, and the constant-velocity model runs on mid-sweep poses: a
        // velocity error then distorts the cloud symmetrically instead of
        // shifting it, which would feed the error back through the
        // prediction (an oscillation that grows).
        let half_s = 0.5 * scan.sweep_duration_s.max(1e-3);
        let mid_s = t_s + half_s;
        let (predicted_mid, twist_per_s) = match (
            self.lidar_only_history.front(),
            self.lidar_only_history.back(),
        ) {
            (Some(&(t_a, pose_a)), Some(&(t_b, pose_b))) if t_b > t_a => {
                let twist = lie::se3_log(&(pose_a.inverse() * pose_b)) / (t_b - t_a);
                (pose_b * lie::se3_exp(&(twist * (mid_s - t_b))), twist)
            }
            (_, Some(&(_, pose_b))) => (pose_b, Vector6::zeros()),
            _ => (Isometry3::identity(), Vector6::zeros()),
        };
        timings.imu_prediction = clock.elapsed();
        // When the match moves far from the prediction (start-up, sudden
        // acceleration), the de-skew used the wrong velocity: redo it with the
        // velocity the match implies and match again.
        let mut guess_mid = predicted_mid;
        let mut twist_per_s = twist_per_s;
        let mut features;
        let mut matched;
        let mut rounds = 0;
        // One pose so far: no velocity to predict from, and the ego may
        // already move metres per sweep (a drive recorded in traffic).
        if let (1, Some(&(t_b, pose_b))) = (
            self.lidar_only_history.len(),
            self.lidar_only_history.back(),
        ) && mid_s > t_b
        {
            (guess_mid, twist_per_s) =
                self.search_start_speed(frame_index, scan, (t_b, pose_b), &mut timings)?;
        }
        loop {
            let motion = SweepMotion::constant_velocity(
                t_s,
                guess_mid * lie::se3_exp(&(-twist_per_s * half_s)),
                mid_s + half_s,
                guess_mid * lie::se3_exp(&(twist_per_s * half_s)),
            )
            .map_err(|source| EstimatorError::Deskew {
                frame_index,
                t_s,
                source,
            })?;
            let filter = self.feature_filter(scan, &motion);
            features = self.sweep_features(scan, &motion, mid_s, &filter, &mut timings);
            let clock = Instant::now();
            matched = self.match_features(&features, &guess_mid);
            timings.scan_matching += clock.elapsed();
            rounds += 1;
            let (Some(m), Some(&(t_b, pose_b))) = (&matched, self.lidar_only_history.back()) else {
                break;
            };
            let change = lie::se3_log(&(guess_mid.inverse() * m.t_world_lidar));
            let small = lie::xi_rho(&change).norm() < self.config.redeskew_translation_m
                && lie::xi_phi(&change).norm() < self.config.redeskew_rotation_rad;
            if small || rounds > self.config.max_redeskew_rounds || mid_s <= t_b {
                break;
            }
            twist_per_s = lie::se3_log(&(pose_b.inverse() * m.t_world_lidar)) / (mid_s - t_b);
            guess_mid = m.t_world_lidar;
        }
        let t_world_lidar_mid = matched.as_ref().map_or(predicted_mid, |m| m.t_world_lidar);
        // The reported state is at the scan start, like the IMU mode's.
        let t_world_lidar = t_world_lidar_mid * lie::se3_exp(&(-twist_per_s * half_s));
        let velocity_world_mps = match self.lidar_only_history.back() {
            Some(&(t_b, pose_b)) if mid_s > t_b => {
                (t_world_lidar_mid.translation.vector - pose_b.translation.vector) / (mid_s - t_b)
            }
            _ => Vector3::zeros(),
        };
        self.lidar_only_history
            .push_back((mid_s, t_world_lidar_mid));
        while self.lidar_only_history.len() > 2 {
            self.lidar_only_history.pop_front();
        }
        let clock = Instant::now();
        self.update_map(frame_index, scan.t_s, &t_world_lidar_mid, &features, false)?;
        timings.map_update = clock.elapsed();
        let clock = Instant::now();
        let final_motion = SweepMotion::constant_velocity(
            t_s,
            t_world_lidar,
            t_s + 2.0 * half_s,
            t_world_lidar * lie::se3_exp(&(twist_per_s * 2.0 * half_s)),
        )
        .map_err(|source| EstimatorError::Deskew {
            frame_index,
            t_s,
            source,
        })?;
        let tracks = self.track_objects(t_s, &t_world_lidar, &final_motion)?;
        timings.tracking = clock.elapsed();
        Ok(FrameEstimate {
            frame_index,
            t_s,
            t_world_lidar,
            velocity_world_mps,
            bias: ImuBias::default(),
            scan_match: matched.as_ref().map(|m| summary(m, &features)),
            removed_feature_indices: features.removed.clone(),
            feature_indices: features.all_indices.clone(),
            edge_feature_indices: features.all_edge_indices.clone(),
            tracks,
            timings,
        })
    }

    /// The second sweep's start: the pose and velocity of the forward speed,
    /// among `0, step, 2 step, … max` ([`EstimatorConfig::start_speed_step_mps`],
    /// along the LiDAR's x axis), whose de-skewed sweep, matched from where
    /// that speed puts it, finds the most correspondences. Matching from a
    /// standstill guess alone would lock onto traffic moving with the ego
    /// when the static world lies more than the correspondence distance
    /// away; the speed that explains the most of the scene wins instead.
    ///
    /// Each speed's match gets at most
    /// [`EstimatorConfig::start_speed_max_iterations`]: a speed near the true
    /// one starts within a quarter step of the answer and settles in a few,
    /// the far ones would run to the matcher's limit without settling. The
    /// speeds whose match converged compete; only when none did, the most
    /// correspondences among all, whose match is then run to the limit.
    ///
    /// [`EstimatorConfig::start_speed_step_mps`]: crate::pipeline::config::EstimatorConfig::start_speed_step_mps
    /// [`EstimatorConfig::start_speed_max_iterations`]: crate::pipeline::config::EstimatorConfig::start_speed_max_iterations
    fn search_start_speed(
        &mut self,
        frame_index: u64,
        scan: &LidarScan,
        (t_b, pose_b): (f64, Isometry3<f64>),
        timings: &mut ModuleTimings,
    ) -> Result<(Isometry3<f64>, Vector6<f64>), EstimatorError> {
        let half_s = 0.5 * scan.sweep_duration_s.max(1e-3);
        let mid_s = scan.t_s + half_s;
        let step = self.config.start_speed_step_mps;
        let speeds = if step > 0.0 {
            (self.config.start_max_speed_mps / step).floor().max(0.0) as usize
        } else {
            0
        };
        let capped = ScanMatchConfig {
            max_iterations: self
                .config
                .start_speed_max_iterations
                .clamp(1, self.config.scan_match.max_iterations),
            ..self.config.scan_match
        };
        // (correspondences, converged, guess, features, match) of the best
        // speed so far: converged beats unconverged, then more correspondences.
        let mut best: Option<(usize, bool, Isometry3<f64>, SweepFeatures, ScanMatchResult)> = None;
        for k in 0..=speeds {
            let mut twist = Vector6::zeros();
            twist[0] = k as f64 * step;
            let guess = pose_b * lie::se3_exp(&(twist * (mid_s - t_b)));
            let motion = SweepMotion::constant_velocity(
                scan.t_s,
                guess * lie::se3_exp(&(-twist * half_s)),
                mid_s + half_s,
                guess * lie::se3_exp(&(twist * half_s)),
            )
            .map_err(|source| EstimatorError::Deskew {
                frame_index,
                t_s: scan.t_s,
                source,
            })?;
            let filter = self.feature_filter(scan, &motion);
            let features = self.sweep_features(scan, &motion, mid_s, &filter, timings);
            let clock = Instant::now();
            let matched = self.match_features_with(&features, &guess, &capped);
            timings.scan_matching += clock.elapsed();
            let Some(m) = matched else { continue };
            let found = m.edge_matches + m.planar_matches;
            let better = best
                .as_ref()
                .is_none_or(|(most, converged, ..)| (m.converged, found) > (*converged, *most));
            if better {
                best = Some((found, m.converged, guess, features, m));
            }
        }
        let Some((_, converged, guess, features, mut m)) = best else {
            return Ok((pose_b, Vector6::zeros()));
        };
        if !converged && capped.max_iterations < self.config.scan_match.max_iterations {
            let clock = Instant::now();
            let full = self.match_features(&features, &guess);
            timings.scan_matching += clock.elapsed();
            match full {
                Some(full) => m = full,
                None => return Ok((pose_b, Vector6::zeros())),
            }
        }
        let twist = lie::se3_log(&(pose_b.inverse() * m.t_world_lidar)) / (mid_s - t_b);
        Ok((m.t_world_lidar, twist))
    }
}
