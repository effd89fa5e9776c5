//! One LiDAR-inertial frame once the inertial state exists, as a list of
//! stages: IMU prediction, the sweep's features from the predicted motion,
//! scan-to-map matching, the new state and its factors in the sliding
//! window (with the tracked objects, `limot`), optimization,
//! marginalization of the oldest frame, the map update and the tracks.

use super::error::{deskew_error, factor_error, graph_error};
use super::frontend::summary;
use super::{EgoState, Estimator, EstimatorError};
use crate::graph::{BiasRandomWalkFactor, ImuFactor, Key, NoiseModel, PriorFactor, Variable};
use crate::imu::Preintegration;
use crate::input::LidarScan;
use crate::lidar::ScanMatchResult;
use crate::lidar::SweepMotion;
use crate::lie;
use crate::pipeline::config::Variant;
use crate::pipeline::estimate::{FrameEstimate, ModuleTimings};
use crate::tracking::TrackOutput;
use nalgebra::{DMatrix, Matrix6, SymmetricEigen};
use std::time::{Duration, Instant};

impl Estimator {
    /// Estimates frame `frame_index` from the latest inertial state.
    pub(super) fn process_inertial(
        &mut self,
        frame_index: u64,
        scan: &LidarScan,
    ) -> Result<FrameEstimate, EstimatorError> {
        let previous = self.latest.expect("initialised");
        let t_s = scan.t_s;
        let mut timings = ModuleTimings::default();

        let (preintegration, predicted) =
            self.predict_state(&previous, frame_index, t_s, &mut timings)?;
        let motion = self
            .imu_sweep_motion(&predicted, scan, &mut timings)
            .map_err(deskew_error(frame_index, t_s))?;
        let filter = self.feature_filter(scan, &motion);
        let features = self.sweep_features(scan, &motion, t_s, &filter, &mut timings);
        let initial_t_world_lidar = predicted.t_world_imu * self.t_imu_lidar;
        let clock = Instant::now();
        let matched = self.match_features(&features, &initial_t_world_lidar);
        timings.scan_matching = clock.elapsed();

        let clock = Instant::now();
        self.add_ego_state(&previous, &predicted, preintegration, matched.as_ref())?;
        let joint_tracks = self.add_joint_objects(&predicted, matched.as_ref(), &motion)?;
        self.window_frames.push_back(frame_index);
        self.optimize_window(joint_tracks.is_some(), frame_index, t_s)?;
        self.marginalize_old_frames(frame_index, t_s)?;
        let state = self.window_state(frame_index, t_s);
        self.latest = Some(state);
        timings.graph = clock.elapsed();

        let t_world_lidar = state.t_world_imu * self.t_imu_lidar;
        let clock = Instant::now();
        self.update_map(frame_index, t_s, &t_world_lidar, &features, false)?;
        timings.map_update = clock.elapsed();
        let tracks = self.frame_tracks(
            joint_tracks,
            frame_index,
            t_s,
            &t_world_lidar,
            &motion,
            &mut timings,
        )?;
        Ok(FrameEstimate {
            frame_index,
            t_s,
            t_world_lidar,
            velocity_world_mps: state.velocity_world_mps,
            bias: state.bias,
            scan_match: matched.as_ref().map(|m| summary(m, &features)),
            removed_feature_indices: features.removed.clone(),
            feature_indices: features.all_indices.clone(),
            edge_feature_indices: features.all_edge_indices.clone(),
            tracks,
            timings,
        })
    }

    /// Preintegrates the IMU from `previous` to the scan start `t_s` and
    /// predicts the state there (bias unchanged).
    fn predict_state(
        &self,
        previous: &EgoState,
        frame_index: u64,
        t_s: f64,
        timings: &mut ModuleTimings,
    ) -> Result<(Preintegration, EgoState), EstimatorError> {
        let clock = Instant::now();
        let preintegration = Preintegration::from_samples(
            &self.imu,
            previous.t_s,
            t_s,
            previous.bias,
            self.config.imu_noise,
            self.config.max_imu_gap_s,
        )
        .map_err(|source| EstimatorError::Imu {
            frame_index,
            t_s,
            source,
        })?;
        let (t_world_imu, velocity_world_mps) = preintegration.predict(
            &previous.t_world_imu,
            &previous.velocity_world_mps,
            &previous.bias,
            &self.gravity_world(),
        );
        let predicted = EgoState {
            frame_index,
            t_s,
            t_world_imu,
            velocity_world_mps,
            bias: previous.bias,
        };
        timings.imu_prediction = clock.elapsed();
        Ok((preintegration, predicted))
    }

    /// Adds the state `predicted` (initial values) to the window with the
    /// IMU and bias random-walk factors from `previous`, and the LiDAR
    /// odometry factor of the match, if any.
    fn add_ego_state(
        &mut self,
        previous: &EgoState,
        predicted: &EgoState,
        preintegration: Preintegration,
        matched: Option<&ScanMatchResult>,
    ) -> Result<(), EstimatorError> {
        let (j, k) = (previous.frame_index, predicted.frame_index);
        let window_error = graph_error(k, predicted.t_s);
        let factor_error = factor_error(k, predicted.t_s);
        self.smoother
            .add_variable(Key::EgoPose(k), Variable::Pose(predicted.t_world_imu))
            .map_err(&window_error)?;
        self.smoother
            .add_variable(
                Key::EgoVelocity(k),
                Variable::Vector3(predicted.velocity_world_mps),
            )
            .map_err(&window_error)?;
        self.smoother
            .add_variable(Key::EgoBias(k), Variable::Bias(predicted.bias))
            .map_err(&window_error)?;
        let dt_s = preintegration.delta_t_s();
        let imu_factor = if self.config.estimate_gravity {
            ImuFactor::with_estimated_gravity(j, k, preintegration)
        } else {
            ImuFactor::new(j, k, preintegration, self.gravity_world())
        }
        .map_err(&factor_error)?;
        let bias_factor =
            BiasRandomWalkFactor::new(j, k, dt_s, &self.config.imu_noise).map_err(&factor_error)?;
        self.smoother
            .add_factor(Box::new(imu_factor))
            .map_err(&window_error)?;
        self.smoother
            .add_factor(Box::new(bias_factor))
            .map_err(&window_error)?;
        if let Some(result) = matched {
            // LiDAR odometry (the paper's r_odo): the scan-to-map result is a
            // pose in the map, i.e. world, frame, so it constrains this state
            // directly (with the map's keyframe poses held fixed, r_odo between
            // the map anchor and this frame reduces to it). Relative factors
            // between consecutive matches would let the estimate drift from
            // the map; relative to the previous *estimate* they would feed its
            // own corrections back as measurements (unstable).
            let t_world_imu_matched = result.t_world_lidar * self.t_lidar_imu;
            if let Some(noise) = self.odometry_noise(result) {
                self.smoother
                    .add_factor(Box::new(PriorFactor::new(
                        Key::EgoPose(k),
                        Variable::Pose(t_world_imu_matched),
                        noise,
                    )))
                    .map_err(&window_error)?;
            }
        }
        Ok(())
    }

    /// `limot`: tracks the frame's detections on the matched pose (the
    /// prediction without a match) and adds the confirmed objects' nodes and
    /// factors to the window, so they join this frame's optimization.
    /// Returns the tracks and the time spent; `None` for the other variants.
    fn add_joint_objects(
        &mut self,
        predicted: &EgoState,
        matched: Option<&ScanMatchResult>,
        motion: &SweepMotion,
    ) -> Result<Option<(Vec<TrackOutput>, Duration)>, EstimatorError> {
        if self.config.variant != Variant::Limot {
            return Ok(None);
        }
        let (k, t_s) = (predicted.frame_index, predicted.t_s);
        let clock = Instant::now();
        let guess = matched.map_or(predicted.t_world_imu * self.t_imu_lidar, |m| {
            m.t_world_lidar
        });
        let tracks = self.track_objects(t_s, &guess, motion)?;
        self.objects
            .add_frame(
                &mut self.smoother,
                k,
                self.window_frames.back().copied(),
                t_s,
                &tracks,
                &self.frame_detections,
                motion,
                &guess,
                &self.t_imu_lidar,
            )
            .map_err(graph_error(k, t_s))?;
        Ok(Some((tracks, clock.elapsed())))
    }

    /// Optimizes the window: with the objects' protocol when it holds them
    /// (`with_objects`), otherwise in one solve.
    fn optimize_window(
        &mut self,
        with_objects: bool,
        frame_index: u64,
        t_s: f64,
    ) -> Result<(), EstimatorError> {
        let result = if with_objects {
            self.objects
                .optimize(&mut self.smoother, &self.config.solver)
        } else {
            self.smoother.optimize(&self.config.solver).map(|_| ())
        };
        result.map_err(graph_error(frame_index, t_s))
    }

    /// Marginalizes the oldest frames until the window has its size.
    fn marginalize_old_frames(&mut self, frame_index: u64, t_s: f64) -> Result<(), EstimatorError> {
        while self.window_frames.len() > self.config.window_size.max(2) {
            let oldest = self.window_frames.pop_front().expect("non-empty window");
            self.objects
                .marginalize_oldest(&mut self.smoother, oldest)
                .map_err(graph_error(frame_index, t_s))?;
        }
        Ok(())
    }

    /// The optimized state of frame `k` (scan start `t_s`).
    fn window_state(&self, k: u64, t_s: f64) -> EgoState {
        let values = self.smoother.values();
        EgoState {
            frame_index: k,
            t_s,
            t_world_imu: *values.pose(&Key::EgoPose(k)),
            velocity_world_mps: *values.vector3(&Key::EgoVelocity(k)),
            bias: *values.bias(&Key::EgoBias(k)),
        }
    }

    /// The matching information moved to the IMU pose tangent, scaled by the
    /// point sigma and inflation, with degenerate directions floored.
    fn odometry_noise(&self, result: &ScanMatchResult) -> Option<NoiseModel> {
        let c = &self.config;
        let scale = 1.0 / (c.point_sigma_m * c.point_sigma_m * c.odometry_information_inflation);
        // ξ_lidar = Ad(T_lidar_imu)·ξ_imu for a right perturbation of t_world_imu.
        let ad = lie::se3_adjoint(&self.t_lidar_imu);
        let info_imu: Matrix6<f64> = ad.transpose() * (result.information * scale) * ad;
        let sym = (info_imu + info_imu.transpose()) * 0.5;
        let eigen = SymmetricEigen::new(sym);
        let floored = eigen.eigenvalues.map(|v| v.max(c.odometry_min_information));
        let info =
            eigen.eigenvectors * Matrix6::from_diagonal(&floored) * eigen.eigenvectors.transpose();
        NoiseModel::from_information(&DMatrix::from_column_slice(6, 6, info.as_slice()))
    }
}
