//! Typed variable keys. Ordered so that a window's variables sort by kind,
//! then by frame.

use std::fmt;

/// Names one variable of the graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Key {
    /// `t_world_imu` of the ego at frame `k` (SE(3), dim 6).
    EgoPose(u64),
    /// Ego velocity in the world frame at frame `k` (dim 3).
    EgoVelocity(u64),
    /// IMU biases at frame `k` (dim 6: accelerometer then gyroscope).
    EgoBias(u64),
    /// World pose of object `id` at frame `k` (SE(3), dim 6).
    ObjectPose {
        /// Track id.
        id: u64,
        /// Frame index.
        frame: u64,
    },
    /// Pose change of object `id` from frame `k` to `k + 1`, in the object
    /// frame (SE(3), dim 6); the paper's motion node.
    ObjectMotion {
        /// Track id.
        id: u64,
        /// Frame index of the change's start.
        frame: u64,
    },
    /// Pose of a static object `id`, one node while it stays static (SE(3), dim 6).
    StaticObjectPose {
        /// Track id.
        id: u64,
    },
    /// Gravity in the world frame, m/s² (dim 3): one node for the whole run.
    Gravity,
}

impl Key {
    /// Frame index the key belongs to, if any.
    pub fn frame(&self) -> Option<u64> {
        match *self {
            Key::EgoPose(k) | Key::EgoVelocity(k) | Key::EgoBias(k) => Some(k),
            Key::ObjectPose { frame, .. } | Key::ObjectMotion { frame, .. } => Some(frame),
            Key::StaticObjectPose { .. } | Key::Gravity => None,
        }
    }
}

impl fmt::Display for Key {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Key::EgoPose(k) => write!(f, "x{k}"),
            Key::EgoVelocity(k) => write!(f, "v{k}"),
            Key::EgoBias(k) => write!(f, "b{k}"),
            Key::ObjectPose { id, frame } => write!(f, "o{id}@{frame}"),
            Key::ObjectMotion { id, frame } => write!(f, "m{id}@{frame}"),
            Key::StaticObjectPose { id } => write!(f, "s{id}"),
            Key::Gravity => write!(f, "g"),
        }
    }
}
