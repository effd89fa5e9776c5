//! [`ObjectGraphConfig`]: the noise of the object factors and the rules
//! that shape the objects' part of the graph.

use crate::graph::SolverConfig;

/// Noise of the object factors (one sigma) and the rules that shape the
/// objects' part of the graph. The measurements behind the defaults are in
/// `docs/estimator-notes.md`.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectGraphConfig {
    /// Observation: box centre, m, per class (car, truck, cyclist,
    /// pedestrian); by default twice the simulated detector's per-axis
    /// centre noise.
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
    /// r_moti, translation, m: the pose change must equal the relative pose
    /// of the two frames' nodes ("must always satisfy", the paper), so tight.
    pub motion_sigma_m: f64,
    /// r_moti, rotation, rad (see [`ObjectGraphConfig::motion_sigma_m`]).
    pub motion_sigma_rad: f64,
    /// r_smoo, translation (longitudinal, lateral, vertical) per frame, m:
    /// an acceleration of 3 m/s² changes the 0.1 s pose change by 0.03 m.
    pub smooth_sigma_m: [f64; 3],
    /// r_smoo, rotation (roll, pitch, yaw) per frame, rad: a yaw rate
    /// changing by 0.05 rad/s per frame changes the pose change's yaw by
    /// 0.005 rad.
    pub smooth_sigma_rad: [f64; 3],
    /// Whether dynamic objects' observations also correct the ego (the
    /// paper's fully joint graph). A moving object tells the ego something
    /// only through its constant-velocity model, and real traffic breaks it
    /// (a congestion wave accelerates every car ahead at once), so by default
    /// their observations are conditioned on the ego's scan-matched pose:
    /// the ego informs the objects, not the reverse. Static objects (one
    /// node, a landmark) always inform the ego.
    pub dynamic_objects_inform_ego: bool,
    /// A track the tracker calls static but whose speed
    /// ([`TrackOutput::speed_mps`](crate::tracking::TrackOutput::speed_mps), the line fit the tracker decides on)
    /// exceeds this, m/s, is a chain in the graph. The tracker wants
    /// confidence before it calls a track dynamic (two sigmas of that speed
    /// above its threshold), but one node for a pedestrian walking at
    /// 1.4 m/s trails it by 0.2-0.3 m within a few frames: the graph takes
    /// the tracker's threshold without the margin.
    pub static_max_speed_mps: f64,
    /// Whether a static node keeps, folded into its prior, the observations
    /// of the frames that have left the window. The node is a landmark in
    /// the odometry's world frame, and each observation places it with the
    /// ego pose of its frame. Where the odometry drifts against the
    /// detections, the observations made from poses that have left the
    /// window hold the node where the object was in an older version of
    /// that frame. Off: the node rests on the window's observations only
    /// (the ego poses that are still estimated together). On (the default):
    /// it averages every detection since it was created, which is right for
    /// an odometry that does not drift measurably over the life of a node.
    pub static_keeps_old_observations: bool,
    /// Pose changes a chain needs before its velocity is reported (fewer
    /// rest on two or three detections: 0.15 m of noise makes 2-3 m/s).
    pub min_motions_for_velocity: usize,
    /// Levenberg–Marquardt for each dynamic object's own part of the window
    /// (solved after the ego when `dynamic_objects_inform_ego` is off). A
    /// new node starts from the chain's constant-velocity prediction and the
    /// window is warm-started every frame, so two linearizations per frame
    /// suffice.
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
            static_max_speed_mps: 1.0,
            static_keeps_old_observations: true,
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
