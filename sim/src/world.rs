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
//!   agent pose once at that time and rays are cast against the boxes
//!   directly (exact f64 slab test after a bounding-sphere cull).
//!   [`World::snapshot_agents`] + [`World::agent_sweep_spheres`] let the
//!   LiDAR skip agents outside a column's plane altogether.
//! - A ray starting inside a solid sees nothing of that solid.
//! - Ground: the analytic height field of [`Ground`], intersected exactly by
//!   safe (never-overshooting) steps from a curvature bound, which converge
//!   like Newton's method (to 1e-9 m) and take one step on a plane.

use crate::scene::{Ground, STATIC_INSTANCE_ID, Scene, Shape, StaticKind};
use crate::trajectory::Trajectory;
use limot_estimator::input::ObjectClass;
use nalgebra::{Isometry3, Point3, Unit, Vector3};
use rapier3d::prelude::{
    BroadPhaseBvh, ColliderBuilder, ColliderHandle, ColliderSet, IntegrationParameters,
    QueryFilter, Ray, RigidBodyBuilder, RigidBodyHandle, RigidBodySet,
};
use std::cell::Cell;

/// What a ray hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Surface {
    Ground,
    Static(StaticKind),
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
    pub surface: Surface,
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
    half_extents_m: Vector3<f64>,
    bounding_radius_m: f64,
    trajectory: Trajectory,
    body: RigidBodyHandle,
    collider: ColliderHandle,
}

/// The simulated world built from a [`Scene`].
pub struct World {
    ground: Ground,
    /// Upper bound of the total undulation amplitude, m.
    ground_undulation_bound_m: f64,
    statics: Vec<StaticGeom>,
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
}

/// The world with every agent pose evaluated at one time.
pub struct WorldAt<'w> {
    world: &'w World,
    t_s: f64,
    agents: Vec<AgentPose>,
    /// The ground (height, gradient) under the last ray origin: a column's
    /// 64 beams share their origin.
    ground_under_origin: Cell<Option<(Point3<f64>, GroundSample)>>,
}

/// Height and gradient (dh/dx, dh/dy) of the ground at one point.
type GroundSample = (f64, f64, f64);

#[derive(Debug, Clone, Copy)]
struct AgentPose {
    index: usize,
    t_world_box: Isometry3<f64>,
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
    pub fn new(scene: &Scene) -> World {
        let mut bodies = RigidBodySet::new();
        let mut colliders = ColliderSet::new();
        let mut static_broad_phase = BroadPhaseBvh::new();
        let params = IntegrationParameters::default();
        let mut static_of_collider = Vec::new();
        let statics: Vec<StaticGeom> = scene
            .statics
            .iter()
            .map(|s| StaticGeom {
                kind: s.kind,
                shape: s.shape,
                t_world_object: s.t_world_object,
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
                    half_extents_m: half,
                    bounding_radius_m: half.norm(),
                    trajectory: agent.trajectory.clone(),
                    body,
                    collider,
                }
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

    pub fn rigid_bodies(&self) -> &RigidBodySet {
        &self.bodies
    }

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
    /// with [`World::agent_sweep_spheres`]. Out-of-range indices are skipped.
    pub fn snapshot_agents(
        &self,
        t_s: f64,
        agent_indices: impl IntoIterator<Item = usize>,
    ) -> WorldAt<'_> {
        let agents = agent_indices
            .into_iter()
            .filter_map(|index| {
                let agent = self.agents.get(index)?;
                let t_world_box = agent.trajectory.pose_at(t_s);
                Some(AgentPose {
                    index,
                    t_world_box,
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
    ) -> Option<ShapeHit> {
        intersect_ground(
            &self.ground,
            self.ground_undulation_bound_m,
            origin,
            under_origin,
            dir,
            max_range_m,
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
                intersect_shape(&s.shape, &s.t_world_object, origin, dir, max_range_m)?;
            if best.get().is_none_or(|(r, _, _)| range < r) {
                best.set(Some((range, normal, index)));
            }
            Some(range as f32)
        });
        best.get()
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
        if max_range_m.is_nan() || max_range_m <= 0.0 {
            return None;
        }
        let world = self.world;
        let dir = dir_world.as_ref();
        let mut best: Option<RayHit> = None;
        let mut limit = max_range_m;
        let under_origin = match self.ground_under_origin.get() {
            Some((o, sample)) if o == *origin_world => sample,
            _ => {
                let sample = world
                    .ground
                    .height_and_gradient(origin_world.x, origin_world.y);
                self.ground_under_origin.set(Some((*origin_world, sample)));
                sample
            }
        };
        // ground first: cheap, and its range prunes the static BVH
        if let Some((range_m, normal_world)) =
            world.cast_ground(origin_world, &under_origin, dir, limit)
        {
            limit = range_m;
            best = Some(RayHit {
                range_m,
                normal_world,
                instance_id: STATIC_INSTANCE_ID,
                surface: Surface::Ground,
            });
        }
        if let Some((range_m, normal_world, index)) = world.cast_statics(origin_world, dir, limit)
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
            if let Some((range_m, normal_world)) = intersect_cuboid(
                &agent.half_extents_m,
                &pose.t_world_box,
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
        best
    }
}

/// Rays descending at least this steeply (sin of the depression) trust the
/// fast path's verdict; shallower ones it leaves unsettled go the safe way.
const FAST_PATH_MIN_DESCENT: f64 = 0.05;

/// Nearest ground hit within `max_range_m` and the upward normal there.
/// The terrain (plane, undulations) is intersected by
/// [`intersect_terrain`]; the road's detail (crown, roughness texture) then
/// moves that root by Newton steps on the detail alone (the terrain
/// linearised at its root: over the centimetres to metres the detail moves
/// a hit, the terrain's curvature changes its height by micrometres) and
/// one exact polish on the whole surface. For rays steeper than the
/// detail's slopes (all but grazing rays beyond ~50 m on a typical road)
/// this is the first crossing; a grazing ray may see the crossing next to
/// the terrain's and miss a bump earlier along it.
fn intersect_ground(
    ground: &Ground,
    undulation_bound_m: f64,
    origin: &Point3<f64>,
    under_origin: &GroundSample,
    dir: &Vector3<f64>,
    max_range_m: f64,
) -> Option<ShapeHit> {
    if !ground.has_detail() {
        let (s, (_, gx, gy)) =
            intersect_terrain(ground, undulation_bound_m, origin, dir, max_range_m)?;
        return Some((s, Unit::new_normalize(Vector3::new(-gx, -gy, 1.0))));
    }
    // the detail may lower the surface under a ray that meets the terrain
    // just beyond max range: search the terrain that much farther
    let margin_m = (ground.detail_bound_m() / dir.z.abs().max(0.005)).min(60.0);
    let at = |s: f64| origin + dir * s;
    let whole = |s: f64| {
        let p = at(s);
        let (h, hx, hy) = ground.height_and_gradient(p.x, p.y);
        (p.z - h, dir.z - hx * dir.x - hy * dir.y, (hx, hy))
    };
    // fast path: Newton on the whole surface from the tangent plane under
    // the sensor; every ray steeper than the surface's slopes meets it once
    let (h0, hx0, hy0) = *under_origin;
    let (f0, df0) = (origin.z - h0, dir.z - hx0 * dir.x - hy0 * dir.y);
    if f0 <= 0.0 {
        return None;
    }
    if df0 < 0.0 {
        let beyond = max_range_m + margin_m;
        if let Some((s, (gx, gy))) = safeguarded_newton(whole, -f0 / df0, 1e-9, 0.0, beyond) {
            if (0.0..=max_range_m).contains(&s) {
                return Some((s, Unit::new_normalize(Vector3::new(-gx, -gy, 1.0))));
            }
            if s > max_range_m && dir.z < -FAST_PATH_MIN_DESCENT {
                return None;
            }
        } else if dir.z < -FAST_PATH_MIN_DESCENT {
            return None;
        }
    }
    let (s0, (_, gx0, gy0)) = intersect_terrain(
        ground,
        undulation_bound_m,
        origin,
        dir,
        max_range_m + margin_m,
    )?;
    // terrain linearised at s0: g(s) ~ g0' (s - s0) with g = z - terrain
    let dg0 = dir.z - gx0 * dir.x - gy0 * dir.y;
    if dg0 >= 0.0 {
        return None;
    }
    let detail_only = |s: f64| {
        let p = at(s);
        let (r, rx, ry) = ground.detail_height_and_gradient(p.x, p.y);
        (dg0 * (s - s0) - r, dg0 - rx * dir.x - ry * dir.y, ())
    };
    // cheap steps on the detail first, then a polish on the whole surface:
    // from a good start one Newton step squares the error (|f| < 1e-6 m
    // leaves ~1e-12 m), else safeguarded steps
    let near =
        safeguarded_newton(detail_only, s0, 1e-6, f64::NAN, f64::INFINITY).map_or(s0, |(s, _)| s);
    let (f, df, gradient) = whole(near);
    let (s, (gx, gy)) = if f.abs() < 1e-6 && df < 0.0 {
        (near - f / df, gradient)
    } else {
        match safeguarded_newton(whole, near, 1e-9, f64::NAN, f64::INFINITY) {
            Some(hit) => hit,
            None => {
                let s = march_to_crossing(ground, origin, dir, s0, dg0, max_range_m + margin_m)?;
                (s, whole(s).2)
            }
        }
    };
    if !(0.0..=max_range_m).contains(&s) {
        return None;
    }
    Some((s, Unit::new_normalize(Vector3::new(-gx, -gy, 1.0))))
}

/// Newton steps shorter than this end the iteration without a check: the
/// error after one is ~ curvature x step², far below a micrometre.
const FINAL_STEP_M: f64 = 1e-5;

/// A root of `f` near `start` by Newton steps (`f_df` gives f, f' and a
/// payload), kept inside the bracket once a sign change is seen (a bilinear
/// texture cell edge can make plain Newton cycle), bisecting when a step
/// would leave it; with the payload of the evaluation there. `above` is a
/// point known to have f > 0 (NaN if none). None when it does not settle to
/// |f| < `tolerance` in 24 steps, or when, unbracketed, it steps beyond
/// `beyond` still above the surface.
fn safeguarded_newton<T>(
    f_df: impl Fn(f64) -> (f64, f64, T),
    start: f64,
    tolerance: f64,
    mut above: f64,
    beyond: f64,
) -> Option<(f64, T)> {
    let mut s = start;
    let mut below = f64::NAN;
    for _ in 0..24 {
        let (f, df, payload) = f_df(s);
        if f.abs() < tolerance {
            return Some((s, payload));
        }
        // a last step this small squares the error: take it unchecked
        if df < 0.0 && f.abs() < FINAL_STEP_M * -df {
            return Some((s - f / df, payload));
        }
        if f > 0.0 && s > beyond && below.is_nan() {
            return None;
        }
        if f > 0.0 {
            above = s;
        } else {
            below = s;
        }
        let newton = if df < 0.0 { s - f / df } else { f64::NAN };
        s = if above.is_finite() && below.is_finite() {
            let (lo, hi) = (above.min(below), above.max(below));
            if newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            }
        } else if newton.is_finite() {
            newton
        } else {
            return None;
        };
    }
    None
}

/// The fallback when Newton does not settle (a ray nearly tangent to a
/// detail slope): sphere tracing from where the ray can first meet the
/// detailed surface (each step `f / L` with `L` bounding the rate at which
/// the surface can rise towards the ray, so no crossing is passed), then
/// bisection over the first sign change. `dg0` is the ray's descent rate
/// over the terrain at `s0`.
fn march_to_crossing(
    ground: &Ground,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    s0: f64,
    dg0: f64,
    max_range_m: f64,
) -> Option<f64> {
    const MAX_STEPS: usize = 400;
    const MIN_STEP_M: f64 = 0.01;
    let f = |s: f64| {
        let p = origin + dir * s;
        p.z - ground.height(p.x, p.y)
    };
    // the terrain is linearised at s0, as in the Newton steps
    let lipschitz = -dg0 + ground.detail_slope_bound() * dir.xy().norm() + 1e-9;
    let raise = ground.roughness.as_ref().map_or(0.0, |r| r.bound_m());
    let mut lo = (s0 - raise / -dg0).max(0.0);
    let mut f_lo = f(lo);
    if f_lo <= 0.0 {
        return None;
    }
    let mut hi = lo;
    for _ in 0..MAX_STEPS {
        hi = lo + (f_lo / lipschitz).max(MIN_STEP_M);
        if hi > max_range_m {
            return None;
        }
        let f_hi = f(hi);
        if f_hi <= 0.0 {
            break;
        }
        (lo, f_lo) = (hi, f_hi);
    }
    if f(hi) > 0.0 {
        return None;
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if f(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

/// First root of z(s) - h(x(s), y(s)) along the ray within `max_range_m`
/// for the terrain h (plane and undulations, no detail), with h and its
/// gradient there. `undulation_bound_m` bounds |h - plane|. The step from s is the first root of
/// the quadratic lower bound f(s) + f'(s) d - M d^2 / 2 (M bounds |f''|),
/// so it never jumps over a crossing and is Newton-fast near a transversal
/// root.
fn intersect_terrain(
    ground: &Ground,
    undulation_bound_m: f64,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    max_range_m: f64,
) -> Option<(f64, (f64, f64, f64))> {
    const TOLERANCE_M: f64 = 1e-9;
    const MAX_STEPS: usize = 200;
    // plane part: f_plane(s) = a + b s; f lies within +-U of it
    let a = origin.z - ground.base_height_m - ground.slope.x * origin.x - ground.slope.y * origin.y;
    let b = dir.z - ground.slope.x * dir.x - ground.slope.y * dir.y;
    let u = undulation_bound_m;
    let curvature_bound: f64 = ground
        .undulations
        .iter()
        .map(|w| {
            let k_dot_d = w.wave_vector.x * dir.x + w.wave_vector.y * dir.y;
            w.amplitude_m.abs() * k_dot_d * k_dot_d
        })
        .sum();
    let surface = |s: f64| {
        let p = origin + dir * s;
        let hg = ground.terrain_height_and_gradient(p.x, p.y);
        (p.z - hg.0, dir.z - hg.1 * dir.x - hg.2 * dir.y, hg)
    };
    // no crossing is possible where a + b s > U
    let mut s = 0.0_f64;
    if a > u {
        if b >= 0.0 {
            return None;
        }
        s = (u - a) / b;
    }
    if s > max_range_m {
        return None;
    }
    let (mut f, mut df, mut hg) = surface(s);
    if s == 0.0 && f <= 0.0 {
        // origin at or below the ground
        return None;
    }
    let mut steps = 0;
    while f > TOLERANCE_M {
        steps += 1;
        if steps > MAX_STEPS {
            // grazing a crest (f' ~ 0): too shallow to matter for a sensor
            return None;
        }
        let m = curvature_bound;
        let step = if m <= 0.0 {
            if df >= 0.0 {
                return None;
            }
            f / -df
        } else {
            let root = (df * df + 2.0 * m * f).sqrt();
            if df <= 0.0 {
                2.0 * f / (root - df)
            } else {
                (df + root) / m
            }
        };
        s += step;
        if s > max_range_m {
            return None;
        }
        (f, df, hg) = surface(s);
        if step < TOLERANCE_M * 1e-3 && f > TOLERANCE_M {
            // stalled on a tangency
            return None;
        }
    }
    // f may be slightly negative after the exact planar step; one Newton
    // correction polishes either way (the gradient before it is kept: the
    // correction is below the tolerance)
    if df.abs() > 1e-12 {
        s -= f / df;
    }
    if !(0.0..=max_range_m).contains(&s) {
        return None;
    }
    Some((s, hg))
}

/// Exact f64 ray intersection with a shape placed at `t_world_object`:
/// nearest entry within (0, max_range_m] and the outward world normal.
fn intersect_shape(
    shape: &Shape,
    t_world_object: &Isometry3<f64>,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    max_range_m: f64,
) -> Option<ShapeHit> {
    match shape {
        Shape::Cuboid { half_extents_m } => {
            intersect_cuboid(half_extents_m, t_world_object, origin, dir, max_range_m)
        }
        Shape::Cylinder {
            radius_m,
            half_height_m,
        } => {
            let o = t_world_object.inverse_transform_point(origin);
            let d = t_world_object.inverse_transform_vector(dir);
            let (t_in, n_local) = cylinder_entry(*radius_m, *half_height_m, &o, &d)?;
            accept(t_in, max_range_m, t_world_object, n_local)
        }
        Shape::Ball { radius_m } => {
            let c = Point3::from(t_world_object.translation.vector);
            let oc = origin - c;
            let half_b = oc.dot(dir);
            let c_term = oc.norm_squared() - radius_m * radius_m;
            let disc = half_b * half_b - c_term;
            if disc < 0.0 || c_term <= 0.0 {
                // miss, or the origin is inside the ball
                return None;
            }
            let t = -half_b - disc.sqrt();
            if t <= 0.0 || t > max_range_m {
                return None;
            }
            let n = Unit::new_normalize(origin + dir * t - c);
            Some((t, n))
        }
    }
}

fn accept(
    t_in: f64,
    max_range_m: f64,
    t_world_object: &Isometry3<f64>,
    n_local: Vector3<f64>,
) -> Option<ShapeHit> {
    if t_in <= 0.0 || t_in > max_range_m {
        return None;
    }
    Some((t_in, Unit::new_normalize(t_world_object.rotation * n_local)))
}

/// Slab test of an oriented box; entry range and outward world normal.
fn intersect_cuboid(
    half_extents_m: &Vector3<f64>,
    t_world_box: &Isometry3<f64>,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    max_range_m: f64,
) -> Option<ShapeHit> {
    let o = t_world_box.inverse_transform_point(origin);
    let d = t_world_box.inverse_transform_vector(dir);
    let mut t_in = f64::NEG_INFINITY;
    let mut t_out = f64::INFINITY;
    let mut axis_in = 0;
    let mut sign_in = 0.0;
    for i in 0..3 {
        let h = half_extents_m[i];
        if d[i] == 0.0 {
            if o[i].abs() > h {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d[i];
        let (mut t0, mut t1) = ((-h - o[i]) * inv, (h - o[i]) * inv);
        // entering through the -h face when moving in +, else the +h face
        let mut sign = -1.0;
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
            sign = 1.0;
        }
        if t0 > t_in {
            t_in = t0;
            axis_in = i;
            sign_in = sign;
        }
        t_out = t_out.min(t1);
        if t_in > t_out {
            return None;
        }
    }
    let mut n_local = Vector3::zeros();
    n_local[axis_in] = sign_in;
    accept(t_in, max_range_m, t_world_box, n_local)
}

/// Entry of a ray into a z-axis cylinder (local frame): (t, outward normal).
fn cylinder_entry(
    radius_m: f64,
    half_height_m: f64,
    o: &Point3<f64>,
    d: &Vector3<f64>,
) -> Option<(f64, Vector3<f64>)> {
    // side: |o_xy + t d_xy|^2 <= r^2
    let dd = d.x * d.x + d.y * d.y;
    let od = o.x * d.x + o.y * d.y;
    let oo = o.x * o.x + o.y * o.y - radius_m * radius_m;
    let (side_in, side_out) = if dd < 1e-18 {
        if oo > 0.0 {
            return None;
        }
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        let disc = od * od - dd * oo;
        if disc < 0.0 {
            return None;
        }
        let root = disc.sqrt();
        // stable roots of dd t^2 + 2 od t + oo = 0
        let q = -(od + od.signum() * root);
        let (r0, r1) = if q == 0.0 {
            (0.0, 0.0)
        } else {
            let (x0, x1) = (q / dd, oo / q);
            (x0.min(x1), x0.max(x1))
        };
        (r0, r1)
    };
    // caps: |o_z + t d_z| <= hh
    let (cap_in, cap_out, cap_sign) = if d.z == 0.0 {
        if o.z.abs() > half_height_m {
            return None;
        }
        (f64::NEG_INFINITY, f64::INFINITY, 0.0)
    } else {
        let t0 = (-half_height_m - o.z) / d.z;
        let t1 = (half_height_m - o.z) / d.z;
        if t0 < t1 {
            (t0, t1, -1.0)
        } else {
            (t1, t0, 1.0)
        }
    };
    let t_in = side_in.max(cap_in);
    let t_out = side_out.min(cap_out);
    if t_in > t_out {
        return None;
    }
    let normal = if cap_in >= side_in {
        Vector3::new(0.0, 0.0, cap_sign)
    } else {
        let p = o + d * t_in;
        Vector3::new(p.x, p.y, 0.0)
    };
    Some((t_in, normal))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Ego, StaticObject, Undulation};
    use crate::trajectory::{Jet, Knot};
    use nalgebra::{Translation3, UnitQuaternion, Vector2};

    pub(crate) fn scene_with(ground: Ground, statics: Vec<StaticObject>) -> Scene {
        Scene {
            duration_s: 1.0,
            ground,
            statics,
            agents: Vec::new(),
            ego: Ego {
                trajectory: Trajectory::stationary(0.0, 1.0, &Isometry3::identity()),
                size_lwh_m: Vector3::new(4.5, 1.8, 1.5),
                box_center_lidar_m: Vector3::new(0.0, 0.0, -0.9),
                t_lidar_imu: Isometry3::identity(),
            },
        }
    }

    fn unit(x: f64, y: f64, z: f64) -> Unit<Vector3<f64>> {
        Unit::new_normalize(Vector3::new(x, y, z))
    }

    #[test]
    fn ray_against_flat_ground_returns_the_exact_range() {
        let world = World::new(&scene_with(Ground::flat(0.0), Vec::new()));
        let snap = world.snapshot(0.0);
        let origin = Point3::new(12.0, -3.0, 1.73);
        for elevation_deg in [-24.8_f64, -10.0, -2.0, -0.5] {
            let el = elevation_deg.to_radians();
            let az = 0.7_f64;
            let dir = unit(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
            let hit = snap.cast_ray(&origin, &dir, 1000.0).expect("hit");
            let expected = 1.73 / (-el).sin();
            assert!((hit.range_m - expected).abs() < 1e-9, "{elevation_deg}");
            assert_eq!(hit.surface, Surface::Ground);
            assert_eq!(hit.instance_id, 0);
            assert!((hit.normal_world.z - 1.0).abs() < 1e-12);
            // max range respected
            assert!(snap.cast_ray(&origin, &dir, expected - 1e-3).is_none());
        }
        // upward ray never hits a flat ground
        assert!(snap.cast_ray(&origin, &unit(1.0, 0.0, 0.01), 1e4).is_none());
    }

    #[test]
    fn ray_against_undulating_ground_lands_on_the_surface() {
        let ground = Ground {
            base_height_m: 0.3,
            slope: Vector2::new(0.01, -0.02),
            undulations: vec![
                Undulation {
                    amplitude_m: 0.6,
                    wave_vector: Vector2::new(0.05, 0.02),
                    phase_rad: 0.3,
                },
                Undulation {
                    amplitude_m: 0.2,
                    wave_vector: Vector2::new(-0.01, 0.2),
                    phase_rad: 1.0,
                },
            ],
            ..Ground::flat(0.0)
        };
        let world = World::new(&scene_with(ground.clone(), Vec::new()));
        let snap = world.snapshot(0.0);
        let origin = Point3::new(5.0, 2.0, ground.height(5.0, 2.0) + 1.73);
        let mut hits = 0;
        for i in 0..400 {
            let az = i as f64 * 0.157;
            let el = -(0.005 + 0.4 * (i as f64 / 400.0));
            let dir = unit(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
            let Some(hit) = snap.cast_ray(&origin, &dir, 200.0) else {
                continue;
            };
            hits += 1;
            let p = origin + dir.as_ref() * hit.range_m;
            assert!((p.z - ground.height(p.x, p.y)).abs() < 1e-6);
            // no earlier crossing: the ray stays above ground before the hit
            for k in 1..200 {
                let q = origin + dir.as_ref() * (hit.range_m * k as f64 / 200.0);
                assert!(q.z - ground.height(q.x, q.y) > -1e-9);
            }
        }
        assert!(hits > 300, "{hits}");
    }

    #[test]
    fn ray_against_crowned_rough_ground_lands_on_the_first_crossing() {
        use crate::roughness::Roughness;
        use crate::scene::Crown;
        use rand::SeedableRng;
        let ground = Ground {
            base_height_m: 0.3,
            slope: Vector2::new(0.01, -0.02),
            undulations: vec![Undulation {
                amplitude_m: 0.6,
                wave_vector: Vector2::new(0.05, 0.02),
                phase_rad: 0.3,
            }],
            crown: Some(Crown {
                axis_point: Vector2::new(0.0, 1.0),
                lateral: Vector2::new(0.0, 1.0),
                height_m: 0.25,
                width_m: 8.0,
            }),
            // ISO class C, rougher than any built-in road
            roughness: Some(Roughness::iso8608(
                &mut rand_chacha::ChaCha8Rng::seed_from_u64(4),
                256e-6,
                0.3,
                20.0,
            )),
        };
        let world = World::new(&scene_with(ground.clone(), Vec::new()));
        let snap = world.snapshot(0.0);
        let mut hits = 0;
        let mut first_crossing_checked = 0;
        for origin_xy in [(5.0, 2.0), (-40.0, -3.5), (2500.0, 4.0)] {
            let origin = Point3::new(
                origin_xy.0,
                origin_xy.1,
                ground.height(origin_xy.0, origin_xy.1) + 1.73,
            );
            for i in 0..600 {
                let az = i as f64 * 0.157;
                let el = -(0.01 + 0.42 * (i as f64 / 600.0));
                let dir = unit(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
                let Some(hit) = snap.cast_ray(&origin, &dir, 120.0) else {
                    continue;
                };
                hits += 1;
                let p = origin + dir.as_ref() * hit.range_m;
                assert!(
                    (p.z - ground.height(p.x, p.y)).abs() < 1e-6,
                    "{el} {az} {origin_xy:?} range {} f {}",
                    hit.range_m,
                    p.z - ground.height(p.x, p.y)
                );
                // the normal of the surface there, up to the polish's last
                // step (either side of a texture cell edge it may have crossed)
                let normal_at = |q: Point3<f64>| {
                    let (_, gx, gy) = ground.height_and_gradient(q.x, q.y);
                    Vector3::new(-gx, -gy, 1.0).normalize()
                };
                let n = hit.normal_world.into_inner();
                let q = p - dir.as_ref() * 1e-6;
                assert!((n - normal_at(p)).norm() < 1e-3 || (n - normal_at(q)).norm() < 1e-3);
                // steeper than every slope of the surface: nothing earlier
                if dir.z < -0.12 {
                    first_crossing_checked += 1;
                    for k in 1..400 {
                        let q = origin + dir.as_ref() * (hit.range_m * k as f64 / 400.0);
                        assert!(q.z - ground.height(q.x, q.y) > -1e-9, "{el} {az} {k}");
                    }
                }
            }
        }
        assert!(
            hits > 1500 && first_crossing_checked > 300,
            "{hits} {first_crossing_checked}"
        );
    }

    fn placed(kind: StaticKind, shape: Shape, x: f64, y: f64, z: f64, yaw: f64) -> StaticObject {
        StaticObject {
            kind,
            shape,
            t_world_object: Isometry3::from_parts(
                Translation3::new(x, y, z),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
            ),
        }
    }

    #[test]
    fn rays_against_box_cylinder_and_ball_return_exact_ranges() {
        let statics = [
            // wall facing the origin: front face at x = 20 - 0.5
            placed(
                StaticKind::Wall,
                Shape::Cuboid {
                    half_extents_m: Vector3::new(0.5, 5.0, 2.0),
                },
                20.0,
                0.0,
                2.0,
                0.0,
            ),
            placed(
                StaticKind::Pole,
                Shape::Cylinder {
                    radius_m: 0.3,
                    half_height_m: 3.0,
                },
                0.0,
                15.0,
                3.0,
                0.4,
            ),
            placed(
                StaticKind::TreeCrown,
                Shape::Ball { radius_m: 2.0 },
                -30.0,
                0.0,
                1.73,
                0.0,
            ),
        ];
        // far from the origin, as late in a long drive: f64 must keep exactness
        let offset = Vector3::new(3000.0, -2500.0, 0.0);
        let shifted: Vec<StaticObject> = statics
            .iter()
            .map(|s| StaticObject {
                t_world_object: Isometry3::from_parts(
                    Translation3::from(s.t_world_object.translation.vector + offset),
                    s.t_world_object.rotation,
                ),
                ..*s
            })
            .collect();
        let world = World::new(&scene_with(Ground::flat(-100.0), shifted));
        let snap = world.snapshot(0.0);
        let origin = Point3::new(0.0, 0.0, 1.73) + offset;
        // box: oblique ray in the xz plane
        let el = 0.05_f64;
        let dir = unit(el.cos(), 0.0, el.sin());
        let hit = snap.cast_ray(&origin, &dir, 120.0).expect("wall");
        assert!((hit.range_m - 19.5 / el.cos()).abs() < 1e-9);
        assert_eq!(hit.surface, Surface::Static(StaticKind::Wall));
        assert!((hit.normal_world.x + 1.0).abs() < 1e-12);
        assert!(snap.cast_ray(&origin, &dir, 19.0).is_none());
        // cylinder: horizontal ray offset 0.1 m from the axis
        let o2 = origin + Vector3::new(0.1, 0.0, 0.0);
        let hit = snap
            .cast_ray(&o2, &unit(0.0, 1.0, 0.0), 120.0)
            .expect("pole");
        let expected = 15.0 - (0.3f64 * 0.3 - 0.1 * 0.1).sqrt();
        assert!((hit.range_m - expected).abs() < 1e-9, "{}", hit.range_m);
        assert_eq!(hit.surface, Surface::Static(StaticKind::Pole));
        assert!((hit.normal_world.z).abs() < 1e-12 && hit.normal_world.y < 0.0);
        // cylinder top cap from above
        let o3 = origin + Vector3::new(0.05, 15.0, 10.0);
        let hit = snap
            .cast_ray(&o3, &unit(0.0, 0.0, -1.0), 120.0)
            .expect("cap");
        assert!((hit.range_m - (10.0 + 1.73 - 6.0)).abs() < 1e-9);
        assert!((hit.normal_world.z - 1.0).abs() < 1e-12);
        // ball straight behind
        let hit = snap
            .cast_ray(&origin, &unit(-1.0, 0.0, 0.0), 120.0)
            .expect("crown");
        assert!((hit.range_m - 28.0).abs() < 1e-9);
        assert_eq!(hit.instance_id, 0);
        assert_eq!(hit.surface, Surface::Static(StaticKind::TreeCrown));
        // nothing to the right
        assert!(
            snap.cast_ray(&origin, &unit(0.0, -1.0, 0.0), 120.0)
                .is_none()
        );
    }

    fn moving_agent(id: u32, x0: f64, speed_mps: f64) -> crate::scene::Agent {
        let knots = (0..11)
            .map(|i| {
                let t = i as f64 * 0.1;
                Knot {
                    position: [
                        Jet::new(x0 + speed_mps * t, speed_mps, 0.0),
                        Jet::new(0.0, 0.0, 0.0),
                        Jet::new(0.75, 0.0, 0.0),
                    ],
                    euler: [Jet::default(); 3],
                }
            })
            .collect();
        crate::scene::Agent {
            id,
            class: ObjectClass::Car,
            size_lwh_m: Vector3::new(4.0, 2.0, 1.5),
            parked: false,
            trajectory: Trajectory::new(0.0, 0.1, knots),
        }
    }

    #[test]
    fn agents_are_hit_where_they_are_at_the_snapshot_time() {
        let mut scene = scene_with(Ground::flat(0.0), Vec::new());
        scene.agents.push(moving_agent(7, 10.0, 10.0));
        let mut world = World::new(&scene);
        let origin = Point3::new(0.0, 0.0, 0.75);
        let dir = unit(1.0, 0.0, 0.0);
        for t in [0.0, 0.3, 0.55] {
            let hit = world.snapshot(t).cast_ray(&origin, &dir, 120.0).unwrap();
            assert!((hit.range_m - (10.0 + 10.0 * t - 2.0)).abs() < 1e-9);
            assert_eq!(hit.instance_id, 7);
            assert_eq!(hit.surface, Surface::Agent(ObjectClass::Car));
        }
        // rapier body follows set_time
        world.set_time(0.5);
        let body = &world.rigid_bodies()[world.agents[0].body];
        assert!((body.translation().x - 15.0).abs() < 1e-5);
        let collider = &world.colliders()[world.agents[0].collider];
        assert_eq!(collider.user_data, 7);
    }

    #[test]
    fn analytic_shapes_agree_with_parry() {
        use parry3d::query::RayCast;
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let shapes = [
            Shape::Cuboid {
                half_extents_m: Vector3::new(1.0, 0.5, 2.0),
            },
            Shape::Cylinder {
                radius_m: 0.8,
                half_height_m: 1.5,
            },
            Shape::Ball { radius_m: 1.2 },
        ];
        let mut compared = 0;
        let mut normals_agree = 0;
        for _ in 0..3000 {
            let shape = shapes[rng.random_range(0..3)];
            let pose = Isometry3::from_parts(
                Translation3::new(
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                ),
                UnitQuaternion::from_euler_angles(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-3.0..3.0),
                ),
            );
            let origin = Point3::new(
                rng.random_range(-10.0..10.0),
                rng.random_range(-10.0..10.0),
                rng.random_range(-10.0..10.0),
            );
            // aim near the shape so most rays hit, some graze or miss
            let target = Point3::from(pose.translation.vector)
                + Vector3::new(
                    rng.random_range(-1.5..1.5),
                    rng.random_range(-1.5..1.5),
                    rng.random_range(-1.5..1.5),
                );
            let dir = Unit::new_normalize(target - origin);
            let ours = intersect_shape(&shape, &pose, &origin, &dir, 100.0);
            // parry in the local frame of the ray origin
            let rel = Isometry3::from_parts(
                Translation3::from(pose.translation.vector - origin.coords),
                pose.rotation,
            );
            let ray = parry3d::query::Ray::new(
                parry3d::math::Vector::ZERO,
                parry3d::math::Vector::new(dir.x as f32, dir.y as f32, dir.z as f32),
            );
            let theirs = match shape {
                Shape::Cuboid { half_extents_m: h } => parry3d::shape::Cuboid::new(
                    parry3d::math::Vector::new(h.x as f32, h.y as f32, h.z as f32),
                )
                .cast_ray_and_get_normal(&to_glam_pose(&rel), &ray, 100.0, false),
                Shape::Cylinder {
                    radius_m,
                    half_height_m,
                } => parry3d::shape::Cylinder::new(half_height_m as f32, radius_m as f32)
                    .cast_ray_and_get_normal(
                        &to_glam_pose(
                            &(rel
                                * Isometry3::rotation(Vector3::x() * std::f64::consts::FRAC_PI_2)),
                        ),
                        &ray,
                        100.0,
                        false,
                    ),
                Shape::Ball { radius_m } => parry3d::shape::Ball::new(radius_m as f32)
                    .cast_ray_and_get_normal(&to_glam_pose(&rel), &ray, 100.0, false),
            };
            match (ours, theirs) {
                (Some((r, n)), Some(hit)) => {
                    compared += 1;
                    assert!(
                        (r - hit.time_of_impact as f64).abs() < 2e-3,
                        "{shape:?} {r} {hit:?}"
                    );
                    let pn = Vector3::new(
                        hit.normal.x as f64,
                        hit.normal.y as f64,
                        hit.normal.z as f64,
                    );
                    // normals may differ on edges/rims (either face is right
                    // there); parry's GJK cylinder normals are off by ~5e-3
                    if (n.into_inner() - pn).norm() < 2e-2 {
                        normals_agree += 1;
                    }
                }
                (None, None) => {}
                (ours, theirs) => {
                    // parry (solid = false) reports the exit of a ray starting
                    // inside; we report nothing there
                    let local = pose.inverse_transform_point(&origin);
                    let inside = match shape {
                        Shape::Cuboid { half_extents_m: h } => {
                            (0..3).all(|i| local[i].abs() <= h[i])
                        }
                        Shape::Cylinder {
                            radius_m,
                            half_height_m,
                        } => local.xy().coords.norm() <= radius_m && local.z.abs() <= half_height_m,
                        Shape::Ball { radius_m } => local.coords.norm() <= radius_m,
                    };
                    assert!(
                        inside && ours.is_none(),
                        "{shape:?} {local}: ours {ours:?}, parry {theirs:?}"
                    );
                }
            }
        }
        assert!(compared > 1000, "{compared}");
        assert!(
            normals_agree as f64 > 0.99 * compared as f64,
            "{normals_agree}/{compared}"
        );
    }
}
