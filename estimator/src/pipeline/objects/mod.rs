//! Tracked objects in the joint sliding-window graph (the `limot` variant):
//! which pose and motion nodes each object has, the factors tying them to
//! the ego (the paper's r_obs, r_moti, r_smoo), their marginalization, and
//! the smoothed object estimates.
//!
//! * A confirmed track judged dynamic gets a pose node per frame it is
//!   observed in and, between consecutive frames, a pose-change (motion)
//!   node; consecutive motions are tied by the smooth-motion factor.
//! * A confirmed track judged static (and slower than
//!   [`ObjectGraphConfig::static_max_speed_mps`]) gets one pose node for as
//!   long as it stays static and is observed. When it starts moving, the
//!   node is no longer observed and leaves the graph once its observations
//!   have left the window; meanwhile the object is modelled as dynamic.
//! * An object node's time is the frame's scan start, like the ego state's:
//!   the detection (seen at its own time within the sweep) is moved into the
//!   sweep-start LiDAR frame with the IMU-predicted sweep motion, and back to
//!   the scan start along the tracker's velocity. Node times at the
//!   detections' own times would make the intervals between an object's
//!   nodes uneven (for an object at the sweep's seam, behind the ego, they
//!   jump between ~0 and ~0.2 s), which the constant-velocity factor cannot
//!   represent; the shift costs |velocity error| x offset (a few cm).
//! * A new chain starts with the window's earlier detections of the track
//!   (those of its tentative frames), so it has the tracker's evidence at
//!   confirmation. It starts heading along the tracker's velocity, and each
//!   later detection is folded (half turn) onto the chain's own heading.
//! * Before the oldest frame is marginalized, its object observations are
//!   conditioned on the ego pose (see [`crate::graph::ConditionedFactor`]):
//!   each object keeps its own small prior and the cost stays linear in the
//!   number of objects. A static node's observations are dropped instead
//!   when [`ObjectGraphConfig::static_keeps_old_observations`] is off.
//!
//! Per frame, the owner of the window calls [`ObjectGraph::add_frame`] once
//! the frame's ego state is in the smoother, [`ObjectGraph::optimize`], and
//! [`ObjectGraph::marginalize_oldest`] for each frame leaving the window;
//! [`ObjectGraph::estimates`] reads the smoothed objects back.

mod config;

pub use config::ObjectGraphConfig;

use crate::geometry::wrap_angle_rad;
use crate::graph::{
    ConditionedFactor, Factor, Key, NoiseModel, ObjectMotionFactor, ObjectObservationFactor,
    RobustKernel, SlidingWindowSmoother, SmoothMotionFactor, SolverConfig, Values, Variable,
    WindowError,
};
use crate::input::{Detection, ObjectClass};
use crate::lidar::SweepMotion;
use crate::tracking::{Lifecycle, Motion, TrackOutput};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use std::collections::BTreeMap;
use std::f64::consts::PI;

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
    /// The node's time, s (the frame's scan start).
    pub t_s: f64,
    /// World velocity from the pose change into this frame; zero for a
    /// static object, `None` at the start of a chain (no pose change yet).
    pub velocity_world_mps: Option<Vector3<f64>>,
    /// Modelled by one static node.
    pub is_static: bool,
}

/// A track's detection in one frame, as the graph observes it: the box in
/// the sweep-start LiDAR frame, at the scan start.
#[derive(Debug, Clone, Copy)]
struct FrameObservation {
    t_lidar_object: Isometry3<f64>,
    class: ObjectClass,
}

/// A track's detection in one frame as the LiDAR saw it: the box in the
/// sweep-start LiDAR frame at its own time within the sweep.
#[derive(Debug, Clone, Copy)]
struct SeenBox {
    t_lidar_object: Isometry3<f64>,
    time_offset_s: f64,
    class: ObjectClass,
    /// It went to the object's static node.
    on_static_node: bool,
}

impl SeenBox {
    /// Moved back to the scan start along `velocity_lidar_mps` (the latest
    /// estimate: a box kept from a tentative frame is moved with the
    /// velocity known now, not the one known then).
    fn at_scan_start(&self, velocity_lidar_mps: &Vector3<f64>) -> FrameObservation {
        let mut t_lidar_object = self.t_lidar_object;
        t_lidar_object.translation.vector -= velocity_lidar_mps * self.time_offset_s;
        FrameObservation {
            t_lidar_object,
            class: self.class,
        }
    }
}

impl FrameObservation {
    /// The box turned by a half turn if that brings its world heading
    /// (through `t_world_lidar`) closer to `reference_yaw_rad`: a box is
    /// symmetric under a half turn, and detectors confuse front and back.
    fn folded(&self, t_world_lidar: &Isometry3<f64>, reference_yaw_rad: f64) -> FrameObservation {
        let mut out = *self;
        if wrap_angle_rad(yaw_of(&(t_world_lidar * self.t_lidar_object)) - reference_yaw_rad).abs()
            > 0.5 * PI
        {
            out.t_lidar_object.rotation *= UnitQuaternion::from_axis_angle(&Vector3::z_axis(), PI);
        }
        out
    }
}

/// Heading of a pose: the angle of its x axis in the xy-plane.
pub(crate) fn yaw_of(pose: &Isometry3<f64>) -> f64 {
    let x = pose.rotation * Vector3::x();
    x.y.atan2(x.x)
}

/// What the window holds for one object.
#[derive(Debug, Default)]
struct ObjectNodes {
    /// Frames with a pose node, and the node's time (the scan start).
    pose_times_s: BTreeMap<u64, f64>,
    /// The track's detections in the window's frames, whatever its state
    /// then: a chain that starts late (at confirmation) begins with the
    /// window's earlier detections, not with one.
    seen: BTreeMap<u64, SeenBox>,
    /// A static node is in the window.
    has_static: bool,
    /// The static node is still being observed (the track is static).
    static_active: bool,
    /// Latest frame whose observation went to the static node.
    static_last_frame: u64,
}

impl ObjectNodes {
    /// The object's chain has a node at `frame` (the window's previous
    /// frame, when there is one): a new node there extends it.
    fn chain_ends_at(&self, frame: Option<u64>) -> bool {
        frame.is_some_and(|f| self.pose_times_s.contains_key(&f))
    }
}

/// A frame of the window: its scan start and the frame before it.
#[derive(Debug, Clone, Copy)]
struct WindowFrame {
    t_s: f64,
    previous: Option<u64>,
}

/// Bookkeeping of the objects in the smoother.
#[derive(Debug, Default)]
pub struct ObjectGraph {
    config: ObjectGraphConfig,
    objects: BTreeMap<u64, ObjectNodes>,
    frames: BTreeMap<u64, WindowFrame>,
}

impl ObjectGraph {
    /// No objects yet.
    pub fn new(config: ObjectGraphConfig) -> ObjectGraph {
        ObjectGraph {
            config,
            objects: BTreeMap::new(),
            frames: BTreeMap::new(),
        }
    }

    /// Number of objects with nodes in the window.
    pub fn len(&self) -> usize {
        self.objects
            .values()
            .filter(|n| n.has_static || !n.pose_times_s.is_empty())
            .count()
    }

    /// Whether no object has nodes in the window.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
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

    /// The observation factor of `observation` (frame `frame`) on
    /// `object_key`: on the ego too when `informs_ego`, otherwise
    /// conditioned on the ego pose `t_world_imu`.
    #[allow(clippy::too_many_arguments)]
    fn add_observation(
        &self,
        smoother: &mut SlidingWindowSmoother,
        frame: u64,
        object_key: Key,
        observation: &FrameObservation,
        t_world_imu: &Isometry3<f64>,
        t_imu_lidar: &Isometry3<f64>,
        informs_ego: bool,
    ) -> Result<(), WindowError> {
        let ego_key = Key::EgoPose(frame);
        let factor = ObjectObservationFactor::new(
            ego_key,
            object_key,
            *t_imu_lidar,
            observation.t_lidar_object,
            self.observation_noise(observation.class),
        );
        if informs_ego {
            return smoother.add_factor(Box::new(factor));
        }
        let mut ego_fixed = Values::new();
        ego_fixed.insert(ego_key, Variable::Pose(*t_world_imu));
        smoother.add_factor(Box::new(
            ConditionedFactor::new(Box::new(factor), ego_fixed)
                .map_err(|_| WindowError::UnknownKey(object_key))?,
        ))
    }

    /// Appends frame `frame`'s pose node to object `id`'s chain (linked by
    /// a motion node when the chain ends at the window's previous frame),
    /// with its observation if there is one (without, the chain only
    /// bridges a missed detection: the node is its prediction, and nothing is
    /// added to a chain too short to predict); `t_world_imu` is the ego's
    /// best guess then.
    /// `reference_yaw_rad` picks the half turn of a new chain's first
    /// detection; a chain that continues folds onto its own heading.
    #[allow(clippy::too_many_arguments)]
    fn extend_chain(
        &mut self,
        smoother: &mut SlidingWindowSmoother,
        id: u64,
        frame: u64,
        observation: Option<&FrameObservation>,
        reference_yaw_rad: f64,
        t_world_imu: &Isometry3<f64>,
        t_imu_lidar: &Isometry3<f64>,
        informs_ego: bool,
    ) -> Result<(), WindowError> {
        let window_frame = self.frames[&frame];
        let nodes = self.objects.entry(id).or_default();
        let key = Key::ObjectPose { id, frame };
        let chain_end = window_frame
            .previous
            .filter(|p| nodes.pose_times_s.contains_key(p));
        // The motion into the chain's end, if the chain is that long.
        let before = chain_end.and_then(|prev| {
            nodes
                .pose_times_s
                .range(..prev)
                .next_back()
                .map(|(f, _)| Key::ObjectMotion { id, frame: *f })
                .filter(|k| smoother.values().contains(k))
        });
        let t_prev =
            chain_end.map(|prev| *smoother.values().pose(&Key::ObjectPose { id, frame: prev }));
        // A chain with a motion continues it (the constant-velocity
        // prediction, consistent with every factor but the new observation).
        let prediction = t_prev.zip(before).map(|(t_prev, before)| {
            let m = *smoother.values().pose(&before);
            (t_prev * m, m)
        });
        // The chain's own heading once it has a node: folding detections
        // onto anything else (the tracker's heading, which follows a
        // pedestrian's detections: noisy to 0.3 rad, flipped one time in
        // ten) would start the chain turning, and the tight yaw smoothing
        // keeps it spinning in place, a wrong minimum.
        let reference_yaw_rad = match (&prediction, &t_prev) {
            (Some((t_pred, _)), _) => yaw_of(t_pred),
            (None, Some(t_prev)) => yaw_of(t_prev),
            (None, None) => reference_yaw_rad,
        };
        let t_world_lidar = t_world_imu * t_imu_lidar;
        let observation = observation.map(|o| o.folded(&t_world_lidar, reference_yaw_rad));
        let (t_new, prev_motion) = match (prediction, &observation, t_prev) {
            (Some((t_new, m)), _, _) => (t_new, Some(m)),
            // The second node starts with the first one's heading: two
            // detected headings would start the chain turning.
            (None, Some(observation), Some(t_prev)) => {
                let detected = t_world_lidar * observation.t_lidar_object;
                (
                    Isometry3::from_parts(detected.translation, t_prev.rotation),
                    None,
                )
            }
            // The first node is the detection, folded onto the reference.
            (None, Some(observation), None) => (t_world_lidar * observation.t_lidar_object, None),
            (None, None, _) => return Ok(()),
        };
        smoother.add_variable(key, Variable::Pose(t_new))?;
        nodes.pose_times_s.insert(frame, window_frame.t_s);
        if let (Some(prev), Some(t_prev)) = (chain_end, t_prev) {
            let prev_key = Key::ObjectPose { id, frame: prev };
            let motion_key = Key::ObjectMotion { id, frame: prev };
            let m = prev_motion.unwrap_or_else(|| t_prev.inverse() * t_new);
            smoother.add_variable(motion_key, Variable::Pose(m))?;
            smoother.add_factor(Box::new(ObjectMotionFactor::new(
                prev_key,
                key,
                motion_key,
                self.motion_noise(),
            )))?;
            if let Some(before) = before {
                smoother.add_factor(Box::new(SmoothMotionFactor::new(
                    before,
                    motion_key,
                    self.smooth_noise(),
                )))?;
            }
        }
        match observation {
            Some(observation) => self.add_observation(
                smoother,
                frame,
                key,
                &observation,
                t_world_imu,
                t_imu_lidar,
                informs_ego,
            ),
            None => Ok(()),
        }
    }

    /// Adds frame `frame`'s object nodes and factors. `previous_frame` is
    /// the window's frame before it (motion nodes link consecutive frames
    /// only); `t_world_lidar` is the best current guess of the sweep-start
    /// LiDAR pose (initial values); `motion` the sweep's IMU motion. The ego
    /// pose of `frame` must be in the smoother.
    ///
    /// # Errors
    /// A node or factor the smoother rejects ([`WindowError`]).
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
        self.frames.insert(
            frame,
            WindowFrame {
                t_s,
                previous: previous_frame,
            },
        );
        let start_inv = motion.pose_at(t_s).inverse();
        let t_world_imu = t_world_lidar * t_imu_lidar.inverse();
        for track in tracks {
            let Some(detection) = track.detection_index.and_then(|j| detections.get(j)) else {
                // Missed this frame: a confirmed track's chain is bridged,
                // so the detections on both sides of the gap stay one chain.
                let chain_continues = self
                    .objects
                    .get(&track.id)
                    .is_some_and(|nodes| nodes.chain_ends_at(previous_frame));
                if track.lifecycle == Lifecycle::Confirmed && chain_continues {
                    self.extend_chain(
                        smoother,
                        track.id,
                        frame,
                        None,
                        track.yaw_rad,
                        &t_world_imu,
                        t_imu_lidar,
                        false,
                    )?;
                }
                continue;
            };
            let t_det_s = t_s + detection.time_offset_s;
            // Detection box → sweep-start LiDAR frame.
            let seen = SeenBox {
                t_lidar_object: start_inv
                    * motion.pose_at(t_det_s)
                    * Isometry3::from_parts(
                        Translation3::from(detection.box_lidar.center),
                        UnitQuaternion::from_axis_angle(
                            &Vector3::z_axis(),
                            detection.box_lidar.yaw_rad,
                        ),
                    ),
                time_offset_s: detection.time_offset_s,
                class: track.class,
                on_static_node: false,
            };
            // Back to the scan start along the tracker's velocity.
            let velocity_lidar = t_world_lidar.rotation.inverse() * track.velocity_world_mps;
            let observation = seen.at_scan_start(&velocity_lidar);
            let nodes = self.objects.entry(track.id).or_default();
            nodes.seen.insert(frame, seen);
            if track.lifecycle != Lifecycle::Confirmed {
                continue;
            }
            let looks_static = track.motion == Motion::Static
                && track.speed_mps <= self.config.static_max_speed_mps;
            let use_static = looks_static && (nodes.static_active || !nodes.has_static);
            if use_static {
                let key = Key::StaticObjectPose { id: track.id };
                let observation = match nodes.has_static {
                    true => observation.folded(t_world_lidar, yaw_of(smoother.values().pose(&key))),
                    false => observation.folded(t_world_lidar, track.yaw_rad),
                };
                if !nodes.has_static {
                    let initial = t_world_lidar * observation.t_lidar_object;
                    smoother.add_variable(key, Variable::Pose(initial))?;
                    nodes.has_static = true;
                    nodes.static_active = true;
                }
                nodes.static_last_frame = frame;
                if let Some(seen) = nodes.seen.get_mut(&frame) {
                    seen.on_static_node = true;
                }
                // A static object is a landmark: it always informs the ego.
                self.add_observation(
                    smoother,
                    frame,
                    key,
                    &observation,
                    &t_world_imu,
                    t_imu_lidar,
                    true,
                )?;
                continue;
            }
            // No longer (or not yet) static: the static node, if any, is
            // observed no more and ages out.
            nodes.static_active = false;
            // The half turn of a new chain's first detection: the one along
            // the direction of travel once the object moves (vehicles and
            // pedestrians go forwards; the tracker's heading of a pedestrian
            // flips with its detections), the tracker's heading before.
            let reference_yaw_rad = if track.speed_mps > self.config.static_max_speed_mps {
                track.velocity_world_mps.y.atan2(track.velocity_world_mps.x)
            } else {
                track.yaw_rad
            };
            if !nodes.chain_ends_at(previous_frame) {
                // A new chain starts with the window's earlier detections of
                // the object: those of the consecutive frames up to this one
                // that have no node (tentative frames; the walk stops at a
                // frame without a detection). Detections that went to the static
                // node stay there: a car that was parked did not move at
                // constant velocity (and measured on 12 generated drives,
                // adding them changes the object error by < 1 mm). They are
                // past frames, whose ego is settled: they are conditioned on
                // it and never inform it.
                let mut earlier = Vec::new();
                let mut f = previous_frame;
                while let Some(p) = f {
                    match nodes.seen.get(&p) {
                        Some(seen)
                            if !seen.on_static_node && !nodes.pose_times_s.contains_key(&p) =>
                        {
                            earlier.push((p, *seen))
                        }
                        _ => break,
                    }
                    f = self.frames.get(&p).and_then(|w| w.previous);
                }
                for (p, seen) in earlier.into_iter().rev() {
                    let t_world_imu_then = *smoother.values().pose(&Key::EgoPose(p));
                    let t_world_lidar_then = t_world_imu_then * t_imu_lidar;
                    let observation = seen.at_scan_start(
                        &(t_world_lidar_then.rotation.inverse() * track.velocity_world_mps),
                    );
                    self.extend_chain(
                        smoother,
                        track.id,
                        p,
                        Some(&observation),
                        reference_yaw_rad,
                        &t_world_imu_then,
                        t_imu_lidar,
                        false,
                    )?;
                }
            }
            let informs_ego = self.config.dynamic_objects_inform_ego;
            self.extend_chain(
                smoother,
                track.id,
                frame,
                Some(&observation),
                reference_yaw_rad,
                &t_world_imu,
                t_imu_lidar,
                informs_ego,
            )?;
        }
        Ok(())
    }

    /// Optimizes the window holding the objects. When dynamic objects inform
    /// the ego ([`ObjectGraphConfig::dynamic_objects_inform_ego`]) the window
    /// is solved jointly with `ego_solver`. Otherwise they do not move the
    /// ego, so the window splits into independent parts: the ego's (with the
    /// static objects) is solved first with `ego_solver`, the dynamic
    /// objects' observations are then conditioned on that estimate, and each
    /// object's part is solved on its own with [`ObjectGraphConfig::solver`].
    ///
    /// # Errors
    /// A failed solve of any part ([`WindowError`]).
    pub fn optimize(
        &self,
        smoother: &mut SlidingWindowSmoother,
        ego_solver: &SolverConfig,
    ) -> Result<(), WindowError> {
        if self.config.dynamic_objects_inform_ego {
            smoother.optimize(ego_solver)?;
            return Ok(());
        }
        let has_ego = |keys: &[Key]| keys.iter().any(|k| matches!(k, Key::EgoPose(_)));
        smoother.optimize_parts(ego_solver, has_ego)?;
        smoother.refresh_conditioned();
        smoother.optimize_parts(&self.config.solver, |keys| !has_ego(keys))?;
        Ok(())
    }

    /// Marginalizes `frame`, the window's oldest frame, out of `smoother`
    /// with the objects' bookkeeping around it: that frame's object
    /// observations are first conditioned on its ego pose (so the ego and
    /// each object get separate marginal priors), the smoother then
    /// marginalizes the frame, and the objects forget its nodes, fold each
    /// static node's old observations into one prior and drop the static
    /// nodes no frame of the window observes any more. With no objects in
    /// the graph this is `smoother.marginalize_frame(frame)`.
    ///
    /// # Errors
    /// A failed conditioning or marginalization ([`WindowError`]).
    pub fn marginalize_oldest(
        &mut self,
        smoother: &mut SlidingWindowSmoother,
        frame: u64,
    ) -> Result<(), WindowError> {
        self.condition_oldest(smoother, frame)?;
        smoother.marginalize_frame(frame)?;
        self.after_marginalize(smoother, frame)
    }

    /// Call right before the smoother marginalizes frame `frame`: holds the
    /// ego pose fixed in that frame's object observations, so the ego and
    /// each object get separate marginal priors. Without
    /// [`ObjectGraphConfig::static_keeps_old_observations`], that frame's
    /// observations of static nodes are dropped.
    fn condition_oldest(
        &self,
        smoother: &mut SlidingWindowSmoother,
        frame: u64,
    ) -> Result<(), WindowError> {
        if self.objects.is_empty() {
            return Ok(());
        }
        if !self.config.static_keeps_old_observations {
            // Held fixed on every key, a factor constrains nothing and the
            // smoother drops it.
            let ego = Key::EgoPose(frame);
            let mut held = vec![ego];
            held.extend(
                self.objects
                    .iter()
                    .filter(|(_, nodes)| nodes.has_static)
                    .map(|(&id, _)| Key::StaticObjectPose { id }),
            );
            smoother.condition_factors(&held, |f: &dyn Factor| {
                f.keys().contains(&ego)
                    && f.keys()
                        .iter()
                        .any(|k| matches!(k, Key::StaticObjectPose { .. }))
            })?;
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
    fn after_marginalize(
        &mut self,
        smoother: &mut SlidingWindowSmoother,
        frame: u64,
    ) -> Result<(), WindowError> {
        let mut gone = Vec::new();
        for (&id, nodes) in self.objects.iter_mut() {
            nodes.pose_times_s.retain(|&f, _| f > frame);
            nodes.seen.retain(|&f, _| f > frame);
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
            if nodes.pose_times_s.is_empty() && !nodes.has_static && nodes.seen.is_empty() {
                gone.push(id);
            }
        }
        for id in gone {
            self.objects.remove(&id);
        }
        self.frames.retain(|&f, _| f > frame);
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
mod tests;
