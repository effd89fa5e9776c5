//! The ray-cast world: the scene's ground, static geometry and moving agents.
//!
//! - Statics are rapier colliders (user_data = instance id 0) in a
//!   [`BroadPhaseBvh`]; its BVH (f32 AABBs, fattened by rapier's skin, so
//!   culling is conservative) selects candidates, and each candidate is then
//!   intersected exactly in f64 by the analytic routines below. This keeps
//!   ranges exact far from the world origin (rapier/parry work in glam f32)
//!   and is faster than parry's iterative GJK ray cast for cylinders.
//! - Agents are kinematic rapier bodies with cuboid colliders (user_data =
//!   agent id), kept up to date by [`World::set_time`] for users who want the
//!   physics state. Ray casting does not need them: a rolling sweep sees each
//!   agent at its own column time, so [`World::snapshot`] evaluates every
//!   agent pose once at that time and rays are cast against the agents'
//!   bodies directly (exact f64 slab tests after a bounding-sphere cull): a
//!   vehicle's body is its box, a cyclist's and a pedestrian's the thinner
//!   solids inside theirs (`body_parts`).
//!   [`World::snapshot_agents`] + [`World::agent_sweep_spheres`] let the
//!   LiDAR skip agents outside a column's plane altogether;
//!   [`World::static_bounding_spheres`], [`World::static_bounding_corners`]
//!   and [`WorldAt::cast_ray_with_candidates`] let it skip the statics' BVH
//!   for every ray that can hit no static.
//! - A ray starting inside a solid sees nothing of that solid.
//! - Ground: the analytic height field of [`Ground`], intersected exactly by
//!   safe (never-overshooting) steps from a curvature bound, which converge
//!   like Newton's method (to 1e-9 m) and take one step on a plane. A steep
//!   ray meets the ground first; any other meets the objects first and
//!   searches the ground only if a bound says it may reach it before them.

use crate::scene::{Ground, Presence, STATIC_INSTANCE_ID, Scene, Shape, StaticKind};
use crate::trajectory::Trajectory;
use limot_estimator::input::ObjectClass;
use nalgebra::{Isometry3, Point3, Unit, Vector3};
use rapier3d::prelude::{
    BroadPhaseBvh, ColliderBuilder, ColliderHandle, ColliderSet, IntegrationParameters,
    QueryFilter, Ray, RigidBodyBuilder, RigidBodyHandle, RigidBodySet,
};
use std::cell::Cell;

mod ground;
mod shapes;

use ground::{FAST_PATH_MIN_DESCENT, clears_ground, intersect_ground};
use shapes::{Placement, intersect_offset_cuboid, intersect_shape};

/// What a ray hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Surface {
    /// The ground height field.
    Ground,
    /// A static object of this kind.
    Static(StaticKind),
    /// An agent of this class.
    Agent(ObjectClass),
}

/// The nearest hit of one ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Distance from the ray origin along the unit direction, m.
    pub range_m: f64,
    /// Outward surface normal at the hit point, world frame.
    pub normal_world: Unit<Vector3<f64>>,
    /// Ground-truth instance id: 0 for ground and statics, the agent id otherwise.
    pub instance_id: u32,
    /// What was hit.
    pub surface: Surface,
}

/// How far inside its AABB the ray must pass a static it hits for the
/// BVH's f32 culling to surely keep that static, m (f32 rounding of the
/// ray and the box far from the origin is ~1e-4 m at 1 km).
pub const BVH_EDGE_MARGIN_M: f64 = 1e-3;
/// Hits on two statics closer together along a ray than this may come out
/// of the BVH in its own order, m.
pub const NEAR_TIE_M: f64 = 1e-3;

/// How far the ground range [`WorldAt::cast_ray`] or
/// [`WorldAt::cast_ray_next_to`] finds may lie from the ray's exact first
/// crossing with the ground (a ray steeper than the ground's slopes), m:
/// far below an f32's resolution at the LiDAR's ranges (4e-6 m at 32 m).
pub const GROUND_RANGE_TOLERANCE_M: f64 = 1e-7;

/// What the listed statics say about a ray.
enum ListedHit {
    /// The hit (or none) the BVH finds too.
    Sure(Option<StaticHit>),
    /// Too close to an edge or a tie: only the BVH knows.
    AskTheBvh,
}

/// Range along the ray and outward world normal.
type ShapeHit = (f64, Unit<Vector3<f64>>);
/// Range, normal and index into `World::statics`.
type StaticHit = (f64, Unit<Vector3<f64>>, usize);

/// One agent as the ray caster sees it.
#[derive(Debug, Clone)]
struct AgentBody {
    id: u32,
    class: ObjectClass,
    /// The solids of its body ([`body_parts`]).
    parts: Vec<BodyPart>,
    bounding_radius_m: f64,
    trajectory: Trajectory,
    presence: Presence,
    body: RigidBodyHandle,
    collider: ColliderHandle,
}

/// A solid box of an agent's body, in the frame of its ground-truth box.
#[derive(Debug, Clone, Copy, PartialEq)]
struct BodyPart {
    /// Centre of the part in the box frame, m.
    offset_m: Vector3<f64>,
    half_extents_m: Vector3<f64>,
}

/// Width of a bicycle (wheels and frame) as the LiDAR sees it, m.
const BICYCLE_WIDTH_M: f64 = 0.12;
/// Shoulder width of a rider or a pedestrian, m.
const SHOULDER_WIDTH_M: f64 = 0.45;
/// Depth of a pedestrian's body (chest to back), m.
const BODY_DEPTH_M: f64 = 0.3;

/// The solids a ray can hit of an agent of `class` whose ground-truth box is
/// `size_lwh_m`: a vehicle fills its box; a cyclist's box spans the bicycle
/// and the rider's arms and knees, so the body is a bicycle (the box's
/// length, [`BICYCLE_WIDTH_M`] wide, up to the saddle at 55 % of the height)
/// under a rider (a third of the length, [`SHOULDER_WIDTH_M`] wide, from 45 %
/// of the height to the top); a pedestrian's box spans the stride and the
/// arms' swing, the body is a column [`BODY_DEPTH_M`] deep and shoulder-wide.
/// Every part lies inside the box.
fn body_parts(class: ObjectClass, size_lwh_m: &Vector3<f64>) -> Vec<BodyPart> {
    let (l, w, h) = (size_lwh_m.x, size_lwh_m.y, size_lwh_m.z);
    // a part spanning heights [from, to] (fractions of h) of the box
    let part = |length: f64, width: f64, from: f64, to: f64| BodyPart {
        offset_m: Vector3::new(0.0, 0.0, h * (0.5 * (from + to) - 0.5)),
        half_extents_m: Vector3::new(
            0.5 * length.min(l),
            0.5 * width.min(w),
            0.5 * h * (to - from),
        ),
    };
    match class {
        ObjectClass::Car | ObjectClass::Truck => vec![part(l, w, 0.0, 1.0)],
        ObjectClass::Cyclist => vec![
            part(l, BICYCLE_WIDTH_M, 0.0, 0.55),
            part(l / 3.0, SHOULDER_WIDTH_M, 0.45, 1.0),
        ],
        ObjectClass::Pedestrian => vec![part(BODY_DEPTH_M, SHOULDER_WIDTH_M, 0.0, 1.0)],
    }
}

/// The simulated world built from a [`Scene`].
pub struct World {
    ground: Ground,
    /// Upper bound of the total undulation amplitude, m.
    ground_undulation_bound_m: f64,
    statics: Vec<StaticGeom>,
    /// Per static: a world sphere containing it (centre, radius).
    static_spheres: Vec<(Point3<f64>, f64)>,
    /// Per static: the world corners of an oriented box containing it.
    static_corners: Vec<[Point3<f64>; 8]>,
    /// Per static: its collider's AABB in the BVH (f32 values), min and max corner.
    static_aabbs: Vec<(Point3<f64>, Point3<f64>)>,
    /// Collider index (leaf index of the static BVH) -> index into `statics`.
    static_of_collider: Vec<Option<usize>>,
    agents: Vec<AgentBody>,
    bodies: RigidBodySet,
    colliders: ColliderSet,
    /// Broad phase over the static colliders only.
    static_broad_phase: BroadPhaseBvh,
    time_s: f64,
}

#[derive(Debug, Clone, Copy)]
struct StaticGeom {
    kind: StaticKind,
    shape: Shape,
    t_world_object: Isometry3<f64>,
    placement: Placement,
}

/// The world with every agent pose evaluated at one time.
pub struct WorldAt<'w> {
    world: &'w World,
    t_s: f64,
    agents: Vec<AgentPose>,
    /// The ground under the last ray origin, the whole surface's and the
    /// terrain's alone: a column's 64 beams share their origin.
    ground_under_origin: Cell<Option<(Point3<f64>, GroundUnder)>>,
}

/// Height and gradient (dh/dx, dh/dy) of the ground at one point.
type GroundSample = (f64, f64, f64);

/// The ground under a ray origin: the whole surface and the terrain alone.
#[derive(Debug, Clone, Copy)]
struct GroundUnder {
    whole: GroundSample,
    terrain: GroundSample,
}

#[derive(Debug, Clone, Copy)]
struct AgentPose {
    index: usize,
    box_placement: Placement,
    center_world: Point3<f64>,
}

fn to_glam_pose(pose: &Isometry3<f64>) -> rapier3d::math::Pose {
    let t = pose.translation.vector;
    let q = pose.rotation.coords; // (i, j, k, w)
    rapier3d::math::Pose::from_parts(
        rapier3d::math::Vector::new(t.x as f32, t.y as f32, t.z as f32),
        rapier3d::math::Rotation::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32)
            .normalize(),
    )
}

impl World {
    /// Whether every agent's trajectory is the scene's own (shared, not
    /// copied).
    #[cfg(test)]
    pub(crate) fn shares_trajectories_with(&self, scene: &Scene) -> bool {
        self.agents.len() == scene.agents.len()
            && self
                .agents
                .iter()
                .zip(&scene.agents)
                .all(|(body, agent)| body.trajectory.shares_knots_with(&agent.trajectory))
    }

    /// The ray-cast world of `scene`, at time 0.
    pub fn new(scene: &Scene) -> World {
        let mut bodies = RigidBodySet::new();
        let mut colliders = ColliderSet::new();
        let mut static_broad_phase = BroadPhaseBvh::new();
        let params = IntegrationParameters::default();
        let mut static_of_collider = Vec::new();
        let mut static_aabbs = Vec::with_capacity(scene.statics.len());
        let statics: Vec<StaticGeom> = scene
            .statics
            .iter()
            .map(|s| StaticGeom {
                kind: s.kind,
                shape: s.shape,
                t_world_object: s.t_world_object,
                placement: Placement::of(&s.t_world_object),
            })
            .collect();
        for (index, s) in statics.iter().enumerate() {
            let builder = match s.shape {
                Shape::Cuboid { half_extents_m: h } => {
                    ColliderBuilder::cuboid(h.x as f32, h.y as f32, h.z as f32)
                }
                Shape::Cylinder {
                    radius_m,
                    half_height_m,
                } => ColliderBuilder::cylinder(half_height_m as f32, radius_m as f32),
                Shape::Ball { radius_m } => ColliderBuilder::ball(radius_m as f32),
            };
            // rapier cylinders are along local y, ours along local z
            let pose = match s.shape {
                Shape::Cylinder { .. } => {
                    s.t_world_object
                        * Isometry3::rotation(Vector3::x() * std::f64::consts::FRAC_PI_2)
                }
                _ => s.t_world_object,
            };
            let handle = colliders.insert(
                builder
                    .position(to_glam_pose(&pose))
                    .user_data(STATIC_INSTANCE_ID as u128)
                    .build(),
            );
            let slot = handle.into_raw_parts().0 as usize;
            if static_of_collider.len() <= slot {
                static_of_collider.resize(slot + 1, None);
            }
            static_of_collider[slot] = Some(index);
            let aabb = colliders[handle].compute_aabb();
            let corner = |v: rapier3d::math::Vector| {
                Point3::new(f64::from(v.x), f64::from(v.y), f64::from(v.z))
            };
            static_aabbs.push((corner(aabb.mins), corner(aabb.maxs)));
            static_broad_phase.set_aabb(&params, handle, aabb);
        }
        let agents = scene
            .agents
            .iter()
            .map(|agent| {
                let pose = agent.trajectory.pose_at(0.0);
                let body = bodies.insert(
                    RigidBodyBuilder::kinematic_position_based()
                        .pose(to_glam_pose(&pose))
                        .user_data(agent.id as u128),
                );
                let half = agent.size_lwh_m * 0.5;
                let collider = colliders.insert_with_parent(
                    ColliderBuilder::cuboid(half.x as f32, half.y as f32, half.z as f32)
                        .user_data(agent.id as u128),
                    body,
                    &mut bodies,
                );
                AgentBody {
                    id: agent.id,
                    class: agent.class,
                    parts: body_parts(agent.class, &agent.size_lwh_m),
                    bounding_radius_m: half.norm(),
                    // a clone shares the knots
                    trajectory: agent.trajectory.clone(),
                    presence: agent.presence,
                    body,
                    collider,
                }
            })
            .collect();
        let static_spheres = statics
            .iter()
            .map(|s| {
                let radius = match s.shape {
                    Shape::Cuboid { half_extents_m } => half_extents_m.norm(),
                    Shape::Cylinder {
                        radius_m,
                        half_height_m,
                    } => radius_m.hypot(half_height_m),
                    Shape::Ball { radius_m } => radius_m,
                };
                (Point3::from(s.t_world_object.translation.vector), radius)
            })
            .collect();
        let static_corners = statics
            .iter()
            .map(|s| {
                let h = match s.shape {
                    Shape::Cuboid { half_extents_m } => half_extents_m,
                    Shape::Cylinder {
                        radius_m,
                        half_height_m,
                    } => Vector3::new(radius_m, radius_m, half_height_m),
                    Shape::Ball { radius_m } => Vector3::repeat(radius_m),
                };
                std::array::from_fn(|k| {
                    let sign = |bit: usize| if k & bit == 0 { -1.0 } else { 1.0 };
                    s.t_world_object * Point3::new(sign(1) * h.x, sign(2) * h.y, sign(4) * h.z)
                })
            })
            .collect();
        let ground_undulation_bound_m = scene
            .ground
            .undulations
            .iter()
            .map(|u| u.amplitude_m.abs())
            .sum();
        let mut world = World {
            ground: scene.ground.clone(),
            ground_undulation_bound_m,
            statics,
            static_spheres,
            static_corners,
            static_aabbs,
            static_of_collider,
            agents,
            bodies,
            colliders,
            static_broad_phase,
            time_s: f64::NAN,
        };
        world.set_time(0.0);
        world
    }

    /// Moves the rapier agent bodies (and their colliders) to their poses at
    /// `t_s`. Ray casting does not depend on this (see [`World::snapshot`]).
    pub fn set_time(&mut self, t_s: f64) {
        for agent in &self.agents {
            let pose = to_glam_pose(&agent.trajectory.pose_at(t_s));
            if let Some(body) = self.bodies.get_mut(agent.body) {
                body.set_next_kinematic_position(pose);
                body.set_position(pose, true);
            }
            if let Some(collider) = self.colliders.get_mut(agent.collider) {
                collider.set_position(pose);
            }
        }
        self.time_s = t_s;
    }

    /// Time of the last [`World::set_time`].
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The agents' kinematic rigid bodies (rapier).
    pub fn rigid_bodies(&self) -> &RigidBodySet {
        &self.bodies
    }

    /// The colliders: statics (user data 0) and agent boxes (user data = agent id).
    pub fn colliders(&self) -> &ColliderSet {
        &self.colliders
    }

    /// The broad phase holding the static colliders (leaf index = collider index).
    pub fn static_broad_phase(&self) -> &BroadPhaseBvh {
        &self.static_broad_phase
    }

    /// The world at `t_s`: agent poses evaluated once, for all rays cast at that time.
    pub fn snapshot(&self, t_s: f64) -> WorldAt<'_> {
        self.snapshot_agents(t_s, 0..self.agents.len())
    }

    /// Like [`World::snapshot`], but only the listed agents (indices into
    /// `Scene::agents`) exist in it: for callers that culled the others, e.g.
    /// with [`World::agent_sweep_spheres`]. Out-of-range indices and agents
    /// not present at `t_s` ([`crate::scene::Agent::presence`]) are skipped.
    pub fn snapshot_agents(
        &self,
        t_s: f64,
        agent_indices: impl IntoIterator<Item = usize>,
    ) -> WorldAt<'_> {
        let agents = agent_indices
            .into_iter()
            .filter_map(|index| {
                let agent = self.agents.get(index)?;
                if !agent.presence.contains(t_s) {
                    return None;
                }
                let t_world_box = agent.trajectory.pose_at(t_s);
                Some(AgentPose {
                    index,
                    box_placement: Placement::of(&t_world_box),
                    center_world: Point3::from(t_world_box.translation.vector),
                })
            })
            .collect();
        WorldAt {
            world: self,
            t_s,
            agents,
            ground_under_origin: Cell::new(None),
        }
    }

    /// Number of statics (indices `0..n` of [`World::static_bounding_spheres`]).
    pub fn static_count(&self) -> usize {
        self.statics.len()
    }

    /// For each static (in `Scene::statics` order), a world sphere
    /// containing it: (centre, radius).
    pub fn static_bounding_spheres(&self) -> &[(Point3<f64>, f64)] {
        &self.static_spheres
    }

    /// For each static (in `Scene::statics` order), the eight world corners
    /// of an oriented box containing it (the shape's own box for a cuboid).
    pub fn static_bounding_corners(&self) -> &[[Point3<f64>; 8]] {
        &self.static_corners
    }

    /// Number of agents (indices `0..n` of [`World::snapshot_agents`]).
    pub fn agent_count(&self) -> usize {
        self.agents.len()
    }

    /// For each agent, a world sphere containing its whole box at every time
    /// in `[t0_s, t1_s]`: the box centre sampled every <= 5 ms, the ball
    /// around those samples, grown by the half diagonal and a 5 cm margin
    /// (between samples a centre leaves the sample hull by a * dt^2 / 8,
    /// under 0.1 mm for any road vehicle).
    pub fn agent_sweep_spheres(&self, t0_s: f64, t1_s: f64) -> Vec<(Point3<f64>, f64)> {
        const MAX_SAMPLE_STEP_S: f64 = 0.005;
        const MARGIN_M: f64 = 0.05;
        let span = (t1_s - t0_s).max(0.0);
        let samples = ((span / MAX_SAMPLE_STEP_S).ceil() as usize).clamp(1, 10_000) + 1;
        self.agents
            .iter()
            .map(|agent| {
                let centres: Vec<Point3<f64>> = (0..samples)
                    .map(|i| {
                        let t = t0_s + span * i as f64 / (samples - 1).max(1) as f64;
                        Point3::from(agent.trajectory.pose_at(t).translation.vector)
                    })
                    .collect();
                let (mut lo, mut hi) = (centres[0].coords, centres[0].coords);
                for c in &centres {
                    lo = lo.inf(&c.coords);
                    hi = hi.sup(&c.coords);
                }
                let centre = Point3::from((lo + hi) * 0.5);
                let spread = centres
                    .iter()
                    .map(|c| (c - centre).norm())
                    .fold(0.0, f64::max);
                (centre, spread + agent.bounding_radius_m + MARGIN_M)
            })
            .collect()
    }

    /// Nearest ground hit within `max_range_m`.
    fn cast_ground(
        &self,
        origin: &Point3<f64>,
        under_origin: &GroundSample,
        dir: &Vector3<f64>,
        max_range_m: f64,
        start_m: f64,
    ) -> Option<ShapeHit> {
        intersect_ground(
            &self.ground,
            self.ground_undulation_bound_m,
            origin,
            under_origin,
            dir,
            max_range_m,
            start_m,
        )
    }

    /// Nearest static hit closer than `max_range_m`: (range, normal, static index).
    fn cast_statics(
        &self,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        max_range_m: f64,
    ) -> Option<StaticHit> {
        if self.statics.is_empty() {
            return None;
        }
        let dispatcher = parry3d::query::DefaultQueryDispatcher;
        let pipeline = self.static_broad_phase.as_query_pipeline(
            &dispatcher,
            &self.bodies,
            &self.colliders,
            QueryFilter::default(),
        );
        let ray = Ray::new(
            rapier3d::math::Vector::new(origin.x as f32, origin.y as f32, origin.z as f32),
            rapier3d::math::Vector::new(dir.x as f32, dir.y as f32, dir.z as f32),
        );
        // f32 culling bound slightly above the f64 one so no candidate is lost to rounding
        let max_toi = (max_range_m * (1.0 + 1e-6) + 1e-3) as f32;
        let best: Cell<Option<StaticHit>> = Cell::new(None);
        pipeline.bvh.cast_ray(&ray, max_toi, |leaf, _best_toi| {
            let index = (*self.static_of_collider.get(leaf as usize)?)?;
            let s = &self.statics[index];
            let (range, normal) =
                intersect_shape(&s.shape, &s.placement, origin, dir, max_range_m)?;
            if best.get().is_none_or(|(r, _, _)| range < r) {
                best.set(Some((range, normal, index)));
            }
            Some(range as f32)
        });
        best.get()
    }

    /// The nearest hit among the listed statics within `max_range_m` (a
    /// bounding-sphere cull, then the exact intersection), when it is sure
    /// to be what [`World::cast_statics`] finds (see
    /// [`WorldAt::cast_ray_with_candidates`]).
    fn nearest_listed_static(
        &self,
        listed: &[usize],
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        max_range_m: f64,
    ) -> ListedHit {
        let mut best: Option<StaticHit> = None;
        let mut second = f64::INFINITY;
        for &index in listed {
            let (centre, radius) = self.static_spheres[index];
            // loosened so that rounding never culls a hit on the sphere itself
            let radius = radius * (1.0 + 1e-9) + 1e-6;
            let to_centre = centre - origin;
            let along = to_centre.dot(dir);
            // hits beyond the best so far and its tie margin change nothing
            let bound = best.map_or(max_range_m, |(r, _, _)| r + NEAR_TIE_M);
            if along + radius < 0.0 || along - radius > bound {
                continue;
            }
            if (to_centre - dir * along).norm_squared() > radius * radius {
                continue;
            }
            let s = &self.statics[index];
            let Some((range, normal)) =
                intersect_shape(&s.shape, &s.placement, origin, dir, max_range_m)
            else {
                continue;
            };
            match best {
                Some((r, _, _)) if range >= r => second = second.min(range),
                _ => {
                    second = best.map_or(second, |(r, _, _)| r);
                    best = Some((range, normal, index));
                }
            }
        }
        let Some((range, _, index)) = best else {
            return ListedHit::Sure(None);
        };
        if second < range + NEAR_TIE_M {
            return ListedHit::AskTheBvh;
        }
        // the ray must pass well inside the static's AABB, so that the BVH's
        // f32 test surely visits it
        let (lo, hi) = self.static_aabbs[index];
        let (mut t_in, mut t_out) = (f64::NEG_INFINITY, f64::INFINITY);
        for axis in 0..3 {
            let (a, b) = (lo[axis] + BVH_EDGE_MARGIN_M, hi[axis] - BVH_EDGE_MARGIN_M);
            if a >= b {
                return ListedHit::AskTheBvh;
            }
            if dir[axis] == 0.0 {
                if origin[axis] <= a || origin[axis] >= b {
                    return ListedHit::AskTheBvh;
                }
                continue;
            }
            let (t0, t1) = (
                (a - origin[axis]) / dir[axis],
                (b - origin[axis]) / dir[axis],
            );
            t_in = t_in.max(t0.min(t1));
            t_out = t_out.min(t0.max(t1));
        }
        if t_in < t_out && t_out > 0.0 {
            ListedHit::Sure(best)
        } else {
            ListedHit::AskTheBvh
        }
    }
}

impl WorldAt<'_> {
    /// Time of this snapshot.
    pub fn time_s(&self) -> f64 {
        self.t_s
    }

    /// Nearest hit of ground, statics and agents within `max_range_m`
    /// (rays starting inside a solid see nothing of it).
    pub fn cast_ray(
        &self,
        origin_world: &Point3<f64>,
        dir_world: &Unit<Vector3<f64>>,
        max_range_m: f64,
    ) -> Option<RayHit> {
        self.cast(origin_world, dir_world, max_range_m, None, f64::NAN)
            .0
    }

    /// [`WorldAt::cast_ray`] for a caller that knows which statics the ray
    /// can hit at all: `candidates` (indices into `Scene::statics`) hold
    /// every one of them, e.g. from [`World::static_bounding_spheres`] and
    /// [`World::static_bounding_corners`]. They are intersected directly;
    /// the ray searches the statics' BVH only when that cannot be sure to
    /// give the BVH's answer, so the hit is always [`WorldAt::cast_ray`]'s.
    /// (The BVH culls in f32 and can miss a hit that grazes the edge of a
    /// box, and it resolves near ties by its own order: a nearest hit
    /// within `BVH_EDGE_MARGIN_M` (1 mm) of its static's AABB boundary, or
    /// another hit within `NEAR_TIE_M` (1 mm) behind it, goes to the BVH.)
    ///
    /// # Panics
    /// If an index is out of range.
    pub fn cast_ray_with_candidates(
        &self,
        origin_world: &Point3<f64>,
        dir_world: &Unit<Vector3<f64>>,
        max_range_m: f64,
        candidates: &[usize],
    ) -> Option<RayHit> {
        self.cast(
            origin_world,
            dir_world,
            max_range_m,
            Some(candidates),
            f64::NAN,
        )
        .0
    }

    /// [`WorldAt::cast_ray_with_candidates`] for a ray next to one cast
    /// before (the same beam of the neighbouring column, say):
    /// `ground_range_m` holds that ray's ground range on entry (NaN if
    /// none), where the search for this ray's ground crossing starts, and
    /// this ray's own ground range on return (NaN if none), for the next
    /// ray. The start changes only the last digits of the ground's range:
    /// it is found to the same tolerance as by [`WorldAt::cast_ray`]
    /// ([`GROUND_RANGE_TOLERANCE_M`]), and everything else is the same.
    ///
    /// # Panics
    /// If an index of `candidates` is out of range.
    pub fn cast_ray_next_to(
        &self,
        origin_world: &Point3<f64>,
        dir_world: &Unit<Vector3<f64>>,
        max_range_m: f64,
        candidates: &[usize],
        ground_range_m: &mut f64,
    ) -> Option<RayHit> {
        let (hit, range_m) = self.cast(
            origin_world,
            dir_world,
            max_range_m,
            Some(candidates),
            *ground_range_m,
        );
        *ground_range_m = range_m;
        hit
    }

    /// Ground, statics and agents: statics from the BVH, skipped when
    /// `candidates` are given and none of them is hit; the ground's search
    /// starts at `ground_start_m` (NaN: from the tangent plane under the
    /// origin). A steep ray (most of them end on the ground) meets the
    /// ground first, whose range then prunes the objects; any other ray
    /// meets the objects first, and the ground is searched only when the ray
    /// may reach it before the nearest object ([`clears_ground`]): the hit
    /// is the same either way (the ground wins a tie). With the ground's own
    /// range (NaN if none, or not searched).
    fn cast(
        &self,
        origin_world: &Point3<f64>,
        dir_world: &Unit<Vector3<f64>>,
        max_range_m: f64,
        candidates: Option<&[usize]>,
        ground_start_m: f64,
    ) -> (Option<RayHit>, f64) {
        if max_range_m.is_nan() || max_range_m <= 0.0 {
            return (None, f64::NAN);
        }
        let world = self.world;
        let dir = dir_world.as_ref();
        let under = match self.ground_under_origin.get() {
            Some((o, under)) if o == *origin_world => under,
            _ => {
                let (x, y) = (origin_world.x, origin_world.y);
                let under = GroundUnder {
                    whole: world.ground.height_and_gradient(x, y),
                    terrain: world.ground.terrain_height_and_gradient(x, y),
                };
                self.ground_under_origin.set(Some((*origin_world, under)));
                under
            }
        };
        let ground_hit = |ground_start_m: f64| {
            world
                .cast_ground(origin_world, &under.whole, dir, max_range_m, ground_start_m)
                .map(|(range_m, normal_world)| RayHit {
                    range_m,
                    normal_world,
                    instance_id: STATIC_INSTANCE_ID,
                    surface: Surface::Ground,
                })
        };
        if dir.z < -FAST_PATH_MIN_DESCENT {
            let ground = ground_hit(ground_start_m);
            let limit = ground.map_or(max_range_m, |hit| hit.range_m);
            let best = self.nearest_object(origin_world, dir, limit, candidates);
            (best.or(ground), ground.map_or(f64::NAN, |hit| hit.range_m))
        } else {
            let object = self.nearest_object(origin_world, dir, max_range_m, candidates);
            let limit = object.map_or(max_range_m, |hit| hit.range_m);
            if clears_ground(&world.ground, &under.terrain, origin_world, dir, limit) {
                return (object, f64::NAN);
            }
            let ground = ground_hit(ground_start_m);
            let ground_range_m = ground.map_or(f64::NAN, |hit| hit.range_m);
            match ground {
                Some(hit) if hit.range_m <= limit => (Some(hit), ground_range_m),
                _ => (object, ground_range_m),
            }
        }
    }

    /// The nearest static or agent hit closer than `limit_m` (statics first:
    /// an agent replaces a static only when strictly nearer).
    fn nearest_object(
        &self,
        origin_world: &Point3<f64>,
        dir: &Vector3<f64>,
        mut limit: f64,
        candidates: Option<&[usize]>,
    ) -> Option<RayHit> {
        let world = self.world;
        let mut best = None;
        let static_hit =
            match candidates.map(|c| world.nearest_listed_static(c, origin_world, dir, limit)) {
                Some(ListedHit::Sure(hit)) => hit,
                Some(ListedHit::AskTheBvh) | None => world.cast_statics(origin_world, dir, limit),
            };
        if let Some((range_m, normal_world, index)) = static_hit
            && range_m < limit
        {
            limit = range_m;
            best = Some(RayHit {
                range_m,
                normal_world,
                instance_id: STATIC_INSTANCE_ID,
                surface: Surface::Static(world.statics[index].kind),
            });
        }
        for pose in &self.agents {
            let agent = &world.agents[pose.index];
            // bounding-sphere cull: closest approach of the ray to the box centre
            let to_center = pose.center_world - origin_world;
            let along = to_center.dot(dir);
            let radius = agent.bounding_radius_m;
            if along + radius < 0.0 || along - radius > limit {
                continue;
            }
            if (to_center - dir * along).norm_squared() > radius * radius {
                continue;
            }
            for part in &agent.parts {
                if let Some((range_m, normal_world)) = intersect_offset_cuboid(
                    &part.half_extents_m,
                    &part.offset_m,
                    &pose.box_placement,
                    origin_world,
                    dir,
                    limit,
                ) && range_m < limit
                {
                    limit = range_m;
                    best = Some(RayHit {
                        range_m,
                        normal_world,
                        instance_id: agent.id,
                        surface: Surface::Agent(agent.class),
                    });
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests;
