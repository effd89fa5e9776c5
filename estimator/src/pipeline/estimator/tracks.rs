//! The tracker's side of a frame: detections moved into the world and
//! tracked, and (`limot`) the tracks given the joint graph's smoothed
//! object poses.

use super::{Estimator, EstimatorError};
use crate::lidar::SweepMotion;
use crate::pipeline::estimate::ModuleTimings;
use crate::pipeline::objects::yaw_of;
use crate::tracking::{TrackOutput, WorldDetection};
use nalgebra::Isometry3;
use std::time::{Duration, Instant};

impl Estimator {
    /// Moves the frame's detections into the world with the pose of the
    /// LiDAR when it saw each of them (`t_world_lidar` at the scan start,
    /// moved within the sweep by `motion`) and updates the tracker.
    pub(super) fn track_objects(
        &mut self,
        t_s: f64,
        t_world_lidar: &Isometry3<f64>,
        motion: &SweepMotion,
    ) -> Result<Vec<TrackOutput>, EstimatorError> {
        let start_inv = motion.pose_at(t_s).inverse();
        let detections: Vec<WorldDetection> = self
            .frame_detections
            .iter()
            .map(|d| {
                let pose = t_world_lidar * start_inv * motion.pose_at(t_s + d.time_offset_s);
                let box_world = d.box_lidar.transformed(&pose);
                WorldDetection {
                    box_world,
                    class: d.class,
                    score: d.score,
                    time_offset_s: d.time_offset_s,
                }
            })
            .collect();
        self.tracker
            .update(t_s, &detections)
            .map_err(EstimatorError::Tracker)
    }

    /// The tracks with the joint graph's smoothed pose and velocity for the
    /// objects it holds at frame `frame` (moved from each node's detection
    /// time to the frame time `t_s` with its velocity).
    fn with_object_estimates(
        &self,
        mut tracks: Vec<TrackOutput>,
        frame: u64,
        t_s: f64,
    ) -> Vec<TrackOutput> {
        let estimates = self.objects.estimates(&self.smoother, frame, t_s);
        for track in &mut tracks {
            if let Some(e) = estimates.get(&track.id) {
                // A chain's first node has no pose change yet: the tracker's
                // velocity moves it to the frame time.
                let v = e.velocity_world_mps.unwrap_or(track.velocity_world_mps);
                track.center_world = e.t_world_object.translation.vector - v * (e.t_s - t_s);
                track.yaw_rad = yaw_of(&e.t_world_object);
                track.velocity_world_mps = v;
            }
        }
        tracks
    }

    /// The frame's tracks: the joint graph's (`limot`, tracked before the
    /// graph, with the time that took), given the smoothed object estimates
    /// of frame `frame`; otherwise the tracker updated now on the optimized
    /// pose `t_world_lidar`.
    pub(super) fn frame_tracks(
        &mut self,
        joint_tracks: Option<(Vec<TrackOutput>, Duration)>,
        frame: u64,
        t_s: f64,
        t_world_lidar: &Isometry3<f64>,
        motion: &SweepMotion,
        timings: &mut ModuleTimings,
    ) -> Result<Vec<TrackOutput>, EstimatorError> {
        let clock = Instant::now();
        match joint_tracks {
            Some((tracks, tracking_time)) => {
                timings.tracking = tracking_time;
                Ok(self.with_object_estimates(tracks, frame, t_s))
            }
            None => {
                let tracks = self.track_objects(t_s, t_world_lidar, motion)?;
                timings.tracking = clock.elapsed();
                Ok(tracks)
            }
        }
    }
}
