//! What a generated scenario contains: ground, static geometry, moving and
//! parked agents, and the ego vehicle. Built by `scenario`, consumed by
//! `world` (ray casting), `imu`, `detector` and `record`.

use crate::trajectory::Trajectory;
use limot_estimator::input::ObjectClass;
use nalgebra::{Isometry3, Point3, Vector2, Vector3};

/// Instance id of everything that is not an agent (ground, buildings, ...).
pub const STATIC_INSTANCE_ID: u32 = 0;

/// A smooth ground height field z = h(x, y): a plane plus a few gentle
/// sinusoidal undulations, so pitch and z move along any drive.
#[derive(Debug, Clone, PartialEq)]
pub struct Ground {
    /// Height at the origin.
    pub base_height_m: f64,
    /// Constant slope (dz/dx, dz/dy).
    pub slope: Vector2<f64>,
    pub undulations: Vec<Undulation>,
}

/// One term `amplitude * sin(k . (x, y) + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Undulation {
    pub amplitude_m: f64,
    /// Wave vector, rad/m.
    pub wave_vector: Vector2<f64>,
    pub phase_rad: f64,
}

impl Ground {
    pub fn flat(height_m: f64) -> Ground {
        Ground {
            base_height_m: height_m,
            slope: Vector2::zeros(),
            undulations: Vec::new(),
        }
    }

    pub fn height(&self, x: f64, y: f64) -> f64 {
        let p = Vector2::new(x, y);
        self.base_height_m
            + self.slope.dot(&p)
            + self
                .undulations
                .iter()
                .map(|u| u.amplitude_m * (u.wave_vector.dot(&p) + u.phase_rad).sin())
                .sum::<f64>()
    }

    /// (dh/dx, dh/dy).
    pub fn gradient(&self, x: f64, y: f64) -> Vector2<f64> {
        let p = Vector2::new(x, y);
        self.slope
            + self
                .undulations
                .iter()
                .map(|u| {
                    u.wave_vector * (u.amplitude_m * (u.wave_vector.dot(&p) + u.phase_rad).cos())
                })
                .sum::<Vector2<f64>>()
    }

    /// Second derivatives [[h_xx, h_xy], [h_xy, h_yy]].
    pub fn hessian(&self, x: f64, y: f64) -> nalgebra::Matrix2<f64> {
        let p = Vector2::new(x, y);
        self.undulations
            .iter()
            .map(|u| {
                let s = -u.amplitude_m * (u.wave_vector.dot(&p) + u.phase_rad).sin();
                u.wave_vector * u.wave_vector.transpose() * s
            })
            .sum()
    }
}

/// Collision/ray-cast geometry, in the object's local frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    Cuboid {
        half_extents_m: Vector3<f64>,
    },
    /// Axis along local z.
    Cylinder {
        radius_m: f64,
        half_height_m: f64,
    },
    Ball {
        radius_m: f64,
    },
}

/// What a static object is, for intensity and reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum StaticKind {
    Building,
    GuardRail,
    Pole,
    TreeTrunk,
    TreeCrown,
    Wall,
    Sign,
}

#[derive(Debug, Clone, PartialEq)]
pub struct StaticObject {
    pub kind: StaticKind,
    pub shape: Shape,
    pub t_world_object: Isometry3<f64>,
}

/// A vehicle, cyclist or pedestrian. Its trajectory is the pose of the box
/// centre (geometric centre, x along the heading).
#[derive(Debug, Clone, PartialEq)]
pub struct Agent {
    /// Instance id, >= 1 (0 is the static scene).
    pub id: u32,
    pub class: ObjectClass,
    pub size_lwh_m: Vector3<f64>,
    /// True for vehicles that never move in this scenario.
    pub parked: bool,
    pub trajectory: Trajectory,
}

impl Agent {
    pub fn box_at(&self, t_s: f64) -> GroundTruthBox {
        GroundTruthBox {
            id: self.id,
            class: self.class,
            size_lwh_m: self.size_lwh_m,
            t_world_box: self.trajectory.pose_at(t_s),
            velocity_world_mps: self.trajectory.state_at(t_s).velocity_world_mps,
        }
    }
}

/// One ground-truth object box at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundTruthBox {
    pub id: u32,
    pub class: ObjectClass,
    pub size_lwh_m: Vector3<f64>,
    pub t_world_box: Isometry3<f64>,
    pub velocity_world_mps: Vector3<f64>,
}

impl GroundTruthBox {
    /// True when `p_world` lies inside the box grown by `margin_m` on every side.
    pub fn contains(&self, p_world: &Point3<f64>, margin_m: f64) -> bool {
        let local = self.t_world_box.inverse_transform_point(p_world);
        let half = self.size_lwh_m * 0.5;
        (0..3).all(|i| local[i].abs() <= half[i] + margin_m)
    }
}

/// The ego vehicle. Its trajectory is `t_world_lidar` (the LiDAR frame is the
/// ego frame); the car body box is placed relative to it for overlap checks.
#[derive(Debug, Clone, PartialEq)]
pub struct Ego {
    pub trajectory: Trajectory,
    pub size_lwh_m: Vector3<f64>,
    /// Box centre of the ego car in the LiDAR frame.
    pub box_center_lidar_m: Vector3<f64>,
    /// Maps IMU-frame points into the LiDAR frame.
    pub t_lidar_imu: Isometry3<f64>,
}

/// A generated world: everything the sensors can see, over `[0, duration_s]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub duration_s: f64,
    pub ground: Ground,
    pub statics: Vec<StaticObject>,
    pub agents: Vec<Agent>,
    pub ego: Ego,
}

impl Scene {
    pub fn boxes_at(&self, t_s: f64) -> Vec<GroundTruthBox> {
        self.agents.iter().map(|a| a.box_at(t_s)).collect()
    }
}
