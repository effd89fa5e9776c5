//! Tracked objects in the joint sliding-window graph (the `limot` variant):
//! which pose and motion nodes each object has, the factors tying them to
//! the ego (the paper's r_obs, r_moti, r_smoo), their marginalization, and
//! the smoothed object estimates.
//!
//! * A confirmed track judged dynamic gets a pose node per frame it is
//!   observed in and, between consecutive frames, a pose-change (motion)
//!   node; consecutive motions are tied by the smooth-motion factor.
//! * A confirmed track judged static gets one pose node for as long as it
//!   stays static and is observed. When it starts moving, the node is no
//!   longer observed and leaves the graph once its observations have left
//!   the window; meanwhile the object is modelled as dynamic.
//! * An object node's time is the frame's scan start, like the ego state's:
//!   the detection (seen at its own time within the sweep) is moved into the
//!   sweep-start LiDAR frame with the IMU-predicted sweep motion, and back to
//!   the scan start along the tracker's velocity. Node times at the
//!   detections' own times would make the intervals between an object's
//!   nodes uneven (for an object at the sweep's seam, behind the ego, they
//!   jump between ~0 and ~0.2 s), which the constant-velocity factor cannot
//!   represent; the shift costs |velocity error| x offset (a few cm).
//! * Before the oldest frame is marginalized, its object observations are
//!   conditioned on the ego pose (see [`crate::graph::ConditionedFactor`]):
//!   each object keeps its own small prior and the cost stays linear in the
//!   number of objects.

use crate::graph::{
    ConditionedFactor, Factor, Key, NoiseModel, ObjectMotionFactor, ObjectObservationFactor,
    RobustKernel, SlidingWindowSmoother, SmoothMotionFactor, SolverConfig, Values, Variable,
    WindowError,
};
use crate::input::{Detection, ObjectClass};
use crate::lidar::deskew::SweepMotion;
use crate::tracking::tracker::wrap_angle;
use crate::tracking::{Lifecycle, Motion, TrackOutput};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use std::collections::BTreeMap;
use std::f64::consts::PI;

/// Noise of the object factors (one sigma), with the reasons for the
/// defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectGraphConfig {
    /// Observation: box centre, m, per class (car, truck, cyclist,
    /// pedestrian): twice the detector's per-axis centre noise (0.15 / 0.3 /
    /// 0.15 / 0.12 m in the simulator), a compromise between smoothing on the
    /// highway and following the less regular urban motion. Object centre
    /// RMSE at 1x / 2x / 3x: congested highway 0.223 / 0.220 / 0.219 m,
    /// urban 0.179 / 0.182 / 0.191 m (tracker alone: 0.239 and 0.176 m).
    pub observation_position_sigma_m: [f64; 4],
    /// Observation: heading, rad, per class (twice the detector's yaw noise).
    pub observation_yaw_sigma_rad: [f64; 4],
    /// Observation: roll and pitch, rad. Boxes are upright in the LiDAR
    /// frame; the object's true tilt relative to the ego is the difference
    /// of road grades (a few percent).
    pub observation_tilt_sigma_rad: f64,
    /// Huber threshold on the whitened observation residual (6 dof): a
    /// detection from the wrong object or a bad box is down-weighted.
    pub observation_huber_k: f64,
    /// r_moti: the pose change must equal the relative pose of the two
    /// frames' nodes ("must always satisfy", the paper), so tight.
    pub motion_sigma_m: f64,
    pub motion_sigma_rad: f64,
    /// r_smoo, translation (longitudinal, lateral, vertical) per frame:
    /// an acceleration of 3 m/s² changes the 0.1 s pose change by 0.03 m.
    pub smooth_sigma_m: [f64; 3],
    /// r_smoo, rotation (roll, pitch, yaw) per frame: a yaw rate changing by
    /// 0.05 rad/s per frame changes the pose change's yaw by 0.005 rad.
    pub smooth_sigma_rad: [f64; 3],
    /// Whether dynamic objects' observations also correct the ego (the
    /// paper's fully joint graph). A moving object tells the ego something
    /// only through its constant-velocity model, and real traffic breaks it
    /// (a congestion wave accelerates every car ahead at once), so by default
    /// their observations are conditioned on the ego's scan-matched pose:
    /// the ego informs the objects, not the reverse. Static objects (one
    /// node, a landmark) always inform the ego. Measured on the congested
    /// highway, ego ATE_T: 20 s 0.319 m joint vs 0.295 m conditioned
    /// (dynafilt 0.309 m); 30 s seed 3: 0.754 m vs 0.603 m (dynafilt 0.602 m),
    /// with the same object errors.
    pub dynamic_objects_inform_ego: bool,
    /// Pose changes a chain needs before its velocity is reported (fewer
    /// rest on two or three detections: 0.15 m of noise makes 2-3 m/s).
    pub min_motions_for_velocity: usize,
    /// Levenberg–Marquardt for each dynamic object's own part of the window
    /// (solved after the ego when `dynamic_objects_inform_ego` is off): two
    /// linearizations per frame. A new node starts from the chain's
    /// constant-velocity prediction, so the first step moves it by about the
    /// detection noise (~5 cm), the second by under a millimetre and a third
    /// would by micrometres (measured in `benches/joint_graph.rs`); the
    /// window is warm-started next frame, so nothing is lost over time.
    pub solver: SolverConfig,
}

impl Default for ObjectGraphConfig {
    fn default() -> Self {
        ObjectGraphConfig {
            observation_position_sigma_m: [0.3, 0.6, 0.3, 0.24],
            observation_yaw_sigma_rad: [0.06, 0.06, 0.2, 0.6],
            observation_tilt_sigma_rad: 0.1,
            observation_huber_k: 3.0,
            motion_sigma_m: 0.01,
            motion_sigma_rad: 0.002,
            smooth_sigma_m: [0.03, 0.02, 0.01],
            smooth_sigma_rad: [0.003, 0.003, 0.005],
            min_motions_for_velocity: 3,
            dynamic_objects_inform_ego: false,
            solver: SolverConfig {
                max_iterations: 2,
                function_tolerance: 1e-6,
                gradient_tolerance: 1e-9,
                step_tolerance: 1e-5,
                ..SolverConfig::default()
            },
        }
    }
}

fn class_index(class: ObjectClass) -> usize {
    match class {
        ObjectClass::Car => 0,
        ObjectClass::Truck => 1,
        ObjectClass::Cyclist => 2,
        ObjectClass::Pedestrian => 3,
    }
}

/// The smoothed state of one object at a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectEstimate {
    /// World pose of the box centre at `t_s` (the node's time, the scan start).
    pub t_world_object: Isometry3<f64>,
    pub t_s: f64,
    /// World velocity from the pose change into this frame; zero for a
    /// static object, `None` at the start of a chain (no pose change yet).
    pub velocity_world_mps: Option<Vector3<f64>>,
    /// Modelled by one static node.
    pub is_static: bool,
}

/// What the window holds for one object.
#[derive(Debug, Default)]
struct ObjectNodes {
    /// Frames with a pose node, and the node's time (the scan start).
    pose_times_s: BTreeMap<u64, f64>,
    /// A static node is in the window.
    has_static: bool,
    /// The static node is still being observed (the track is static).
    static_active: bool,
    /// Latest frame whose observation went to the static node.
    static_last_frame: u64,
}

/// Bookkeeping of the objects in the smoother.
#[derive(Debug, Default)]
pub struct ObjectGraph {
    config: ObjectGraphConfig,
    objects: BTreeMap<u64, ObjectNodes>,
}

impl ObjectGraph {
    pub fn new(config: ObjectGraphConfig) -> ObjectGraph {
        ObjectGraph {
            config,
            objects: BTreeMap::new(),
        }
    }

    /// Number of objects with nodes in the window.
    pub fn len(&self) -> usize {
        self.objects.len()
    }

    pub fn is_empty(&self) -> bool {
        self.objects.is_empty()
    }

    fn observation_noise(&self, class: ObjectClass) -> NoiseModel {
        let c = &self.config;
        let i = class_index(class);
        let p = c.observation_position_sigma_m[i];
        let tilt = c.observation_tilt_sigma_rad;
        NoiseModel::diagonal_sigmas(&[p, p, p, tilt, tilt, c.observation_yaw_sigma_rad[i]])
            .with_robust(RobustKernel::Huber {
                k: c.observation_huber_k,
            })
    }

    fn motion_noise(&self) -> NoiseModel {
        let (m, r) = (self.config.motion_sigma_m, self.config.motion_sigma_rad);
        NoiseModel::diagonal_sigmas(&[m, m, m, r, r, r])
    }

    fn smooth_noise(&self) -> NoiseModel {
        let (t, r) = (self.config.smooth_sigma_m, self.config.smooth_sigma_rad);
        NoiseModel::diagonal_sigmas(&[t[0], t[1], t[2], r[0], r[1], r[2]])
    }

    /// Adds frame `frame`'s object nodes and factors. `previous_frame` is
    /// the window's frame before it (motion nodes link consecutive frames
    /// only); `t_world_lidar` is the best current guess of the sweep-start
    /// LiDAR pose (initial values); `motion` the sweep's IMU motion.
    #[allow(clippy::too_many_arguments)]
    pub fn add_frame(
        &mut self,
        smoother: &mut SlidingWindowSmoother,
        frame: u64,
        previous_frame: Option<u64>,
        t_s: f64,
        tracks: &[TrackOutput],
        detections: &[Detection],
        motion: &SweepMotion,
        t_world_lidar: &Isometry3<f64>,
        t_imu_lidar: &Isometry3<f64>,
    ) -> Result<(), WindowError> {
        let start_inv = motion.pose_at(t_s).inverse();
        let motion_noise = self.motion_noise();
        // The ego as dynamic objects' observations see it (when they do not
        // inform it): the scan-matched IMU pose.
        let mut ego_fixed = Values::new();
        ego_fixed.insert(
            Key::EgoPose(frame),
            Variable::Pose(t_world_lidar * t_imu_lidar.inverse()),
        );
        let smooth_noise = self.smooth_noise();
        for track in tracks {
            if track.lifecycle != Lifecycle::Confirmed {
                continue;
            }
            let Some(detection) = track.detection_index.and_then(|j| detections.get(j)) else {
                continue;
            };
            let t_det_s = t_s + detection.time_offset_s;
            // Detection box → sweep-start LiDAR frame.
            let mut t_lidar_object = start_inv
                * motion.pose_at(t_det_s)
                * Isometry3::from_parts(
                    Translation3::from(detection.center_lidar),
                    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), detection.yaw_rad),
                );
            // A box is symmetric under a half turn: take the heading closest
            // to the track's, or one flipped detection would twist the chain.
            let heading = (t_world_lidar * t_lidar_object).rotation * Vector3::x();
            if wrap_angle(heading.y.atan2(heading.x) - track.yaw_rad).abs() > 0.5 * PI {
                t_lidar_object.rotation *= UnitQuaternion::from_axis_angle(&Vector3::z_axis(), PI);
            }
            // Back to the scan start along the tracker's velocity.
            let velocity_lidar = t_world_lidar.rotation.inverse() * track.velocity_world_mps;
            t_lidar_object.translation.vector -= velocity_lidar * detection.time_offset_s;
            let initial = t_world_lidar * t_lidar_object;
            let noise = self.observation_noise(track.class);
            let nodes = self.objects.entry(track.id).or_default();
            let use_static =
                track.motion == Motion::Static && (nodes.static_active || !nodes.has_static);
            let object_key = if use_static {
                let key = Key::StaticObjectPose { id: track.id };
                if !nodes.has_static {
                    smoother.add_variable(key, Variable::Pose(initial))?;
                    nodes.has_static = true;
                    nodes.static_active = true;
                }
                nodes.static_last_frame = frame;
                key
            } else {
                // No longer (or not yet) static: the static node, if any,
                // is observed no more and ages out.
                nodes.static_active = false;
                let key = Key::ObjectPose {
                    id: track.id,
                    frame,
                };
                let chain_end = previous_frame.filter(|p| nodes.pose_times_s.contains_key(p));
                // The motion into the chain's end, if the chain is that long.
                let before = chain_end.and_then(|prev| {
                    nodes
                        .pose_times_s
                        .range(..prev)
                        .next_back()
                        .map(|(f, _)| Key::ObjectMotion {
                            id: track.id,
                            frame: *f,
                        })
                        .filter(|k| smoother.values().contains(k))
                });
                // Initial values: a chain with a motion continues it (the
                // constant-velocity prediction, consistent with every factor
                // but the new observation); otherwise the detection.
                let (t_new, prev_motion) = match (chain_end, before) {
                    (Some(prev), Some(before)) => {
                        let t_prev = *smoother.values().pose(&Key::ObjectPose {
                            id: track.id,
                            frame: prev,
                        });
                        let m = *smoother.values().pose(&before);
                        (t_prev * m, Some(m))
                    }
                    _ => (initial, None),
                };
                smoother.add_variable(key, Variable::Pose(t_new))?;
                nodes.pose_times_s.insert(frame, t_s);
                if let Some(prev) = chain_end {
                    let prev_key = Key::ObjectPose {
                        id: track.id,
                        frame: prev,
                    };
                    let motion_key = Key::ObjectMotion {
                        id: track.id,
                        frame: prev,
                    };
                    let t_prev = *smoother.values().pose(&prev_key);
                    let m = prev_motion.unwrap_or_else(|| t_prev.inverse() * t_new);
                    smoother.add_variable(motion_key, Variable::Pose(m))?;
                    smoother.add_factor(Box::new(ObjectMotionFactor::new(
                        prev_key,
                        key,
                        motion_key,
                        motion_noise.clone(),
                    )))?;
                    if let Some(before) = before {
                        smoother.add_factor(Box::new(SmoothMotionFactor::new(
                            before,
                            motion_key,
                            smooth_noise.clone(),
                        )))?;
                    }
                }
                key
            };
            let observation = ObjectObservationFactor::new(
                Key::EgoPose(frame),
                object_key,
                *t_imu_lidar,
                t_lidar_object,
                noise,
            );
            if use_static || self.config.dynamic_objects_inform_ego {
                smoother.add_factor(Box::new(observation))?;
            } else {
                smoother.add_factor(Box::new(
                    ConditionedFactor::new(Box::new(observation), ego_fixed.clone())
                        .map_err(|_| WindowError::UnknownKey(object_key))?,
                ))?;
            }
        }
        Ok(())
    }

    /// Call right before the smoother marginalizes frame `frame`: holds the
    /// ego pose fixed in that frame's object observations, so the ego and
    /// each object get separate marginal priors.
    pub fn condition_oldest(
        &self,
        smoother: &mut SlidingWindowSmoother,
        frame: u64,
    ) -> Result<(), WindowError> {
        if self.objects.is_empty() {
            return Ok(());
        }
        smoother.condition_factors(&[Key::EgoPose(frame)], |f: &dyn Factor| {
            f.keys()
                .iter()
                .any(|k| matches!(k, Key::ObjectPose { .. } | Key::StaticObjectPose { .. }))
        })?;
        Ok(())
    }

    /// Call right after frame `frame` (the oldest) was marginalized:
    /// forgets its nodes, compresses each static node's accumulated
    /// observations into one prior, and removes static nodes no frame in the
    /// window observes any more.
    pub fn after_marginalize(
        &mut self,
        smoother: &mut SlidingWindowSmoother,
        frame: u64,
    ) -> Result<(), WindowError> {
        let mut gone = Vec::new();
        for (&id, nodes) in self.objects.iter_mut() {
            nodes.pose_times_s.retain(|&f, _| f > frame);
            if nodes.has_static {
                let key = Key::StaticObjectPose { id };
                if nodes.static_last_frame <= frame {
                    // Not observed within the window: summarised and gone.
                    smoother.marginalize(&[key])?;
                    nodes.has_static = false;
                    nodes.static_active = false;
                } else {
                    smoother.fold_factors(&[key])?;
                }
            }
            if nodes.pose_times_s.is_empty() && !nodes.has_static {
                gone.push(id);
            }
        }
        for id in gone {
            self.objects.remove(&id);
        }
        Ok(())
    }

    /// The smoothed estimate of every object with a node for `frame`.
    pub fn estimates(
        &self,
        smoother: &SlidingWindowSmoother,
        frame: u64,
        t_s: f64,
    ) -> BTreeMap<u64, ObjectEstimate> {
        let values = smoother.values();
        let mut out = BTreeMap::new();
        for (&id, nodes) in &self.objects {
            if let Some(&node_t_s) = nodes.pose_times_s.get(&frame) {
                let pose = *values.pose(&Key::ObjectPose { id, frame });
                // Velocity from the pose change into this frame, once the
                // chain is long enough.
                let chain = nodes
                    .pose_times_s
                    .range(..frame)
                    .rev()
                    .take_while(|(f, _)| values.contains(&Key::ObjectMotion { id, frame: **f }))
                    .count();
                let velocity = nodes
                    .pose_times_s
                    .range(..frame)
                    .next_back()
                    .and_then(|(&prev, &t_prev)| {
                        let key = Key::ObjectMotion { id, frame: prev };
                        values.contains(&key).then(|| {
                            let prev_pose = values.pose(&Key::ObjectPose { id, frame: prev });
                            let change = values.pose(&key);
                            prev_pose.rotation * change.translation.vector
                                / (node_t_s - t_prev).max(1e-3)
                        })
                    })
                    .filter(|_| chain >= self.config.min_motions_for_velocity);
                out.insert(
                    id,
                    ObjectEstimate {
                        t_world_object: pose,
                        t_s: node_t_s,
                        velocity_world_mps: velocity,
                        is_static: false,
                    },
                );
            } else if nodes.has_static && nodes.static_last_frame == frame {
                out.insert(
                    id,
                    ObjectEstimate {
                        t_world_object: *values.pose(&Key::StaticObjectPose { id }),
                        t_s,
                        velocity_world_mps: Some(Vector3::zeros()),
                        is_static: true,
                    },
                );
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::PriorFactor;

    const WINDOW: usize = 3;

    fn ego_pose(k: u64) -> Isometry3<f64> {
        Isometry3::translation(2.0 * k as f64, 0.0, 0.0)
    }

    /// One object seen every frame, static for the first `static_frames`
    /// frames (parked at x = 20) then driving off along x at 5 m/s.
    fn object_at(k: u64, static_frames: u64) -> Vector3<f64> {
        let moving = k.saturating_sub(static_frames) as f64 * 0.5;
        Vector3::new(20.0 + moving, 3.0, 0.0)
    }

    #[test]
    fn a_parked_object_that_drives_off_switches_from_one_node_to_a_chain() {
        let t_imu_lidar = Isometry3::translation(0.3, 0.0, 0.2);
        let mut smoother = SlidingWindowSmoother::new();
        let mut objects = ObjectGraph::new(ObjectGraphConfig::default());
        let mut frames: std::collections::VecDeque<u64> = Default::default();
        let static_frames = 4;
        let mut seen_static = false;
        for k in 0..12u64 {
            let t_s = 0.1 * k as f64;
            let t_world_lidar = ego_pose(k);
            let ego_key = Key::EgoPose(k);
            let t_world_imu = t_world_lidar * t_imu_lidar.inverse();
            smoother
                .add_variable(ego_key, Variable::Pose(t_world_imu))
                .unwrap();
            smoother
                .add_factor(Box::new(PriorFactor::new(
                    ego_key,
                    Variable::Pose(t_world_imu),
                    NoiseModel::diagonal_sigmas(&[0.01; 6]),
                )))
                .unwrap();
            let center_world = object_at(k, static_frames);
            let moving = k >= static_frames;
            let track = TrackOutput {
                id: 7,
                class: ObjectClass::Car,
                center_world,
                yaw_rad: 0.0,
                size_lwh: Vector3::new(4.5, 1.8, 1.5),
                velocity_world_mps: if moving {
                    Vector3::new(5.0, 0.0, 0.0)
                } else {
                    Vector3::zeros()
                },
                lifecycle: Lifecycle::Confirmed,
                motion: if moving {
                    Motion::Dynamic
                } else {
                    Motion::Static
                },
                predicted: false,
                detection_index: Some(0),
                detection_score: None,
            };
            let detection = Detection {
                center_lidar: t_world_lidar
                    .inverse_transform_point(&center_world.into())
                    .coords,
                size_lwh: track.size_lwh,
                yaw_rad: 0.0,
                class: ObjectClass::Car,
                score: 0.9,
                time_offset_s: 0.0,
            };
            let motion = SweepMotion::from_poses(vec![(t_s, t_world_lidar)]).unwrap();
            objects
                .add_frame(
                    &mut smoother,
                    k,
                    frames.back().copied(),
                    t_s,
                    &[track],
                    &[detection],
                    &motion,
                    &t_world_lidar,
                    &t_imu_lidar,
                )
                .unwrap();
            frames.push_back(k);
            smoother.optimize(&SolverConfig::default()).unwrap();
            let estimates = objects.estimates(&smoother, k, t_s);
            let e = estimates[&7];
            let error = (e.t_world_object.translation.vector - center_world).norm();
            assert!(error < 1e-6, "frame {k}: error {error}");
            assert_eq!(e.is_static, !moving, "frame {k}");
            seen_static |= e.is_static;
            if k >= static_frames + 3 {
                let v = e.velocity_world_mps.expect("a chain of 3 pose changes");
                assert!(
                    (v - Vector3::new(5.0, 0.0, 0.0)).norm() < 1e-6,
                    "frame {k}: {v}"
                );
            }
            while frames.len() > WINDOW {
                let oldest = frames.pop_front().unwrap();
                objects.condition_oldest(&mut smoother, oldest).unwrap();
                smoother.marginalize_frame(oldest).unwrap();
                objects.after_marginalize(&mut smoother, oldest).unwrap();
            }
            // The static node leaves once no frame in the window observes it.
            let has_static = smoother.values().contains(&Key::StaticObjectPose { id: 7 });
            assert_eq!(
                has_static,
                k < static_frames + WINDOW as u64 - 1,
                "frame {k}"
            );
            // Its observations were folded: never more than one factor on it.
            let on_static = smoother
                .factors()
                .iter()
                .filter(|f| f.keys() == [Key::StaticObjectPose { id: 7 }])
                .count();
            assert!(on_static <= 1, "frame {k}: {on_static} unary factors");
        }
        assert!(seen_static);
        assert_eq!(objects.len(), 1);
    }
}
