//! What a generated scenario contains: ground, static geometry, moving and
//! parked agents, and the ego vehicle. Built by `scenario`, consumed by
//! `world` (ray casting), `imu`, `detector` and `record`.

pub use crate::roughness::Roughness;
pub use crate::trajectory::{Jet, Knot, Trajectory};
use limot_estimator::input::ObjectClass;
use nalgebra::{Isometry3, Point3, Translation3, Vector2, Vector3};

/// Instance id of everything that is not an agent (ground, buildings, ...).
pub const STATIC_INSTANCE_ID: u32 = 0;

/// The ground height field z = h(x, y): the terrain (a plane plus a few
/// gentle sinusoidal undulations, so pitch and z move along any drive) and
/// the road's detail on it (an optional crown, i.e. camber, and an optional
/// roughness texture).
#[derive(Debug, Clone, PartialEq)]
pub struct Ground {
    /// Height at the origin.
    pub base_height_m: f64,
    /// Constant slope (dz/dx, dz/dy).
    pub slope: Vector2<f64>,
    /// Sinusoidal undulations added to the plane.
    pub undulations: Vec<Undulation>,
    /// Road crown (camber), if any.
    pub crown: Option<Crown>,
    /// Road roughness texture, if any.
    pub roughness: Option<Roughness>,
}

/// One term `amplitude * sin(k . (x, y) + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Undulation {
    /// Amplitude, m.
    pub amplitude_m: f64,
    /// Wave vector, rad/m.
    pub wave_vector: Vector2<f64>,
    /// Phase, rad.
    pub phase_rad: f64,
}

/// A road crown: a ridge along a straight axis,
/// `-height l² / (l² + width²)` at lateral distance `l`, so the carriageway
/// falls away to both sides (camber) and the terrain far from the axis lies
/// `height` below it. Never above 0; the steepest cross slope,
/// `0.65 height / width`, is at `l = width / √3`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crown {
    /// A point of the axis.
    pub axis_point: Vector2<f64>,
    /// Unit normal of the axis in the plane (the lateral direction).
    pub lateral: Vector2<f64>,
    /// Depth of the terrain far from the axis below the axis, m.
    pub height_m: f64,
    /// Lateral length scale, m.
    pub width_m: f64,
}

impl Crown {
    /// Height offset and its gradient at (x, y).
    #[inline]
    pub fn height_and_gradient(&self, x: f64, y: f64) -> (f64, Vector2<f64>) {
        let l = self.lateral.dot(&(Vector2::new(x, y) - self.axis_point));
        let w2 = self.width_m * self.width_m;
        let q = 1.0 / (l * l + w2);
        (
            -self.height_m * l * l * q,
            self.lateral * (-2.0 * self.height_m * l * w2 * q * q),
        )
    }
}

impl Ground {
    /// Level ground at `height_m`, no detail.
    pub fn flat(height_m: f64) -> Ground {
        Ground {
            base_height_m: height_m,
            slope: Vector2::zeros(),
            undulations: Vec::new(),
            crown: None,
            roughness: None,
        }
    }

    /// Height of the ground at (x, y), world frame, m.
    pub fn height(&self, x: f64, y: f64) -> f64 {
        self.height_and_gradient(x, y).0
    }

    /// (dh/dx, dh/dy).
    pub fn gradient(&self, x: f64, y: f64) -> Vector2<f64> {
        let (_, gx, gy) = self.height_and_gradient(x, y);
        Vector2::new(gx, gy)
    }

    /// Height and gradient in one pass: terrain plus detail.
    #[inline]
    pub fn height_and_gradient(&self, x: f64, y: f64) -> (f64, f64, f64) {
        let (h, gx, gy) = self.terrain_height_and_gradient(x, y);
        let (dh, dx, dy) = self.detail_height_and_gradient(x, y);
        (h + dh, gx + dx, gy + dy)
    }

    /// The large-scale terrain: plane and undulations (one sin_cos per
    /// undulation).
    #[inline(always)]
    pub fn terrain_height_and_gradient(&self, x: f64, y: f64) -> (f64, f64, f64) {
        let mut h = self.base_height_m + self.slope.x * x + self.slope.y * y;
        let (mut gx, mut gy) = (self.slope.x, self.slope.y);
        let trig = crate::fast_trig::table();
        for u in &self.undulations {
            let (sin, cos) = trig.sin_cos(u.wave_vector.x * x + u.wave_vector.y * y + u.phase_rad);
            h += u.amplitude_m * sin;
            gx += u.amplitude_m * cos * u.wave_vector.x;
            gy += u.amplitude_m * cos * u.wave_vector.y;
        }
        (h, gx, gy)
    }

    /// The road's detail on the terrain: crown and roughness texture.
    #[inline(always)]
    pub fn detail_height_and_gradient(&self, x: f64, y: f64) -> (f64, f64, f64) {
        let (mut h, mut gx, mut gy) = (0.0, 0.0, 0.0);
        if let Some(c) = &self.crown {
            let (ch, cg) = c.height_and_gradient(x, y);
            h += ch;
            gx += cg.x;
            gy += cg.y;
        }
        if let Some(r) = &self.roughness {
            let (rh, rx, ry) = r.height_and_gradient(x, y);
            h += rh;
            gx += rx;
            gy += ry;
        }
        (h, gx, gy)
    }

    /// Whether the ground has any detail (crown or texture).
    pub fn has_detail(&self) -> bool {
        self.crown.is_some() || self.roughness.is_some()
    }

    /// Upper bound of |detail|, m.
    pub fn detail_bound_m(&self) -> f64 {
        self.crown.map_or(0.0, |c| c.height_m.abs())
            + self.roughness.as_ref().map_or(0.0, Roughness::bound_m)
    }

    /// Upper bound of |gradient of the detail|.
    pub fn detail_slope_bound(&self) -> f64 {
        // the crown's steepest cross slope: 3 sqrt(3) / 8 height / width
        self.crown
            .map_or(0.0, |c| 0.65 * c.height_m.abs() / c.width_m)
            + self.roughness.as_ref().map_or(0.0, Roughness::slope_bound)
    }

    /// Height of everything but the roughness texture: terrain and crown.
    pub fn untextured_height(&self, x: f64, y: f64) -> f64 {
        let crown = self.crown.map_or(0.0, |c| c.height_and_gradient(x, y).0);
        self.terrain_height_and_gradient(x, y).0 + crown
    }

    /// Second derivatives [[h_xx, h_xy], [h_xy, h_yy]] of the undulations
    /// (the crown and the piecewise-bilinear roughness are left out).
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
    /// A box.
    Cuboid {
        /// Half length, width, height, m.
        half_extents_m: Vector3<f64>,
    },
    /// Axis along local z.
    /// A cylinder.
    Cylinder {
        /// Radius, m.
        radius_m: f64,
        /// Half the height, m.
        half_height_m: f64,
    },
    /// A sphere.
    Ball {
        /// Radius, m.
        radius_m: f64,
    },
}

/// What a static object is, for intensity and reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum StaticKind {
    /// A building's block.
    Building,
    /// A highway guard rail.
    GuardRail,
    /// A pole (street light, signal, sign post).
    Pole,
    /// A tree trunk.
    TreeTrunk,
    /// A tree crown.
    TreeCrown,
    /// A wall (noise barrier, retaining wall).
    Wall,
    /// A traffic sign's plate.
    Sign,
    /// Raised sidewalk slabs (their sides are the kerbs).
    Kerb,
    /// Detail on a building's street face: pilasters, sills, balconies,
    /// awnings, canopies, steps, cornices.
    Facade,
    /// A fence.
    Fence,
    /// Bushes and hedges.
    Shrub,
    /// Overpass decks, piers and gantry beams.
    Bridge,
    /// Earth slopes beside a road (cuttings and embankments).
    Embankment,
}

/// A piece of static geometry: what it is, its shape and where.
#[derive(Debug, Clone, PartialEq)]
pub struct StaticObject {
    /// What the object is.
    pub kind: StaticKind,
    /// Geometry in the object's frame.
    pub shape: Shape,
    /// Object pose in the world.
    pub t_world_object: Isometry3<f64>,
}

/// A vehicle, cyclist or pedestrian. Its trajectory is the pose of the box
/// centre (geometric centre, x along the heading).
#[derive(Debug, Clone, PartialEq)]
pub struct Agent {
    /// Instance id, >= 1 (0 is the static scene).
    pub id: u32,
    /// Object class.
    pub class: ObjectClass,
    /// Box length, width, height, m.
    pub size_lwh_m: Vector3<f64>,
    /// True for vehicles that never move in this scenario.
    pub parked: bool,
    /// Pose of the box centre over time (world frame).
    pub trajectory: Trajectory,
    /// When the agent exists: outside it the sensors see nothing of it and
    /// the ground truth has no box for it.
    pub presence: Presence,
    /// When the ground truth labels it, within `presence` (see [`Labelling`]).
    pub labelled: Labelling,
}

/// When an agent is in the tracking ground truth.
#[derive(Debug, Clone, PartialEq)]
pub enum Labelling {
    /// Whenever it exists and the simulated sensors see it (the scoring's
    /// LiDAR-hit and camera tests decide): a generated agent, labelled as
    /// an annotator of the simulated scans would label it.
    Seen,
    /// During these spans, seen by the simulated sensors or not: an object of
    /// a recorded drive, whose annotators already judged what was visible.
    /// A twin is then scored against the real sequence's truth, not against
    /// the occlusions of its generated scene; a replayed parked car stays in
    /// the world for the whole drive but is labelled only where its source
    /// labelled it.
    Annotated(Vec<Presence>),
}

/// A time interval `[from_s, until_s)`: when an agent exists (a replayed
/// object exists from its first to its last label, or for the whole drive;
/// generated agents exist always) or one run of its annotated labels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Presence {
    /// First instant of existence, s.
    pub from_s: f64,
    /// End of existence (exclusive), s.
    pub until_s: f64,
}

impl Presence {
    /// An agent that exists at every time.
    pub const ALWAYS: Presence = Presence {
        from_s: f64::NEG_INFINITY,
        until_s: f64::INFINITY,
    };

    /// Whether `t_s` lies in `[from_s, until_s)`.
    pub fn contains(&self, t_s: f64) -> bool {
        self.from_s <= t_s && t_s < self.until_s
    }
}

impl Agent {
    /// Whether the agent exists at `t_s` (see [`Presence`]).
    pub fn is_present(&self, t_s: f64) -> bool {
        self.presence.contains(t_s)
    }

    /// Whether the ground truth has a box for the agent at `t_s` (see
    /// [`Agent::labelled`]).
    pub fn is_labelled(&self, t_s: f64) -> bool {
        self.is_present(t_s)
            && match &self.labelled {
                Labelling::Seen => true,
                Labelling::Annotated(spans) => spans.iter().any(|s| s.contains(t_s)),
            }
    }

    /// Whether the agent's labels come from a recording's annotation
    /// ([`Labelling::Annotated`]).
    pub fn is_annotated(&self) -> bool {
        matches!(self.labelled, Labelling::Annotated(_))
    }

    /// The agent's ground-truth box at `t_s`.
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
    /// Instance id of the agent.
    pub id: u32,
    /// Object class.
    pub class: ObjectClass,
    /// Box length, width, height, m.
    pub size_lwh_m: Vector3<f64>,
    /// Box pose in the world (centre, x along the heading).
    pub t_world_box: Isometry3<f64>,
    /// Box-centre velocity, world frame, m/s.
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
    /// `t_world_lidar` over time.
    pub trajectory: Trajectory,
    /// Car body length, width, height, m.
    pub size_lwh_m: Vector3<f64>,
    /// Box centre of the ego car in the LiDAR frame.
    pub box_center_lidar_m: Vector3<f64>,
    /// Maps IMU-frame points into the LiDAR frame.
    pub t_lidar_imu: Isometry3<f64>,
}

impl Ego {
    /// The pose of the car body box's centre at `t_s` (box x along the
    /// heading); its size is [`Ego::size_lwh_m`].
    pub fn t_world_box_at(&self, t_s: f64) -> Isometry3<f64> {
        self.trajectory.pose_at(t_s) * Translation3::from(self.box_center_lidar_m)
    }
}

/// A generated world: everything the sensors can see, over `[0, duration_s]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// End of the scene's time span, s.
    pub duration_s: f64,
    /// The ground height field.
    pub ground: Ground,
    /// Static geometry.
    pub statics: Vec<StaticObject>,
    /// Moving and parked agents.
    pub agents: Vec<Agent>,
    /// The ego vehicle.
    pub ego: Ego,
}

impl Scene {
    /// The ground-truth box of every agent present at `t_s`, in `agents` order.
    pub fn boxes_at(&self, t_s: f64) -> Vec<GroundTruthBox> {
        self.agents
            .iter()
            .filter(|a| a.is_present(t_s))
            .map(|a| a.box_at(t_s))
            .collect()
    }
}
