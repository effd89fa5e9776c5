//! Exact f64 ray intersection with the static and agent shapes (box,
//! cylinder, ball).

use super::ShapeHit;
use crate::scene::Shape;
use nalgebra::{Isometry3, Point3, Unit, Vector3};

/// Where a shape is, for the ray tests: the object's axes in the world (the
/// columns of its rotation) and its origin. A ray goes into the object's
/// frame by three dot products, cheaper than rotating by a quaternion.
#[derive(Debug, Clone, Copy)]
pub(super) struct Placement {
    /// The object's x, y and z axes, world frame.
    axes: [Vector3<f64>; 3],
    /// The object's origin, world frame.
    origin: Point3<f64>,
}

impl Placement {
    /// The placement of an object at `t_world_object`.
    pub(super) fn of(t_world_object: &Isometry3<f64>) -> Placement {
        let rotation = t_world_object.rotation.to_rotation_matrix();
        let m = rotation.matrix();
        Placement {
            axes: [0, 1, 2].map(|i| m.column(i).into_owned()),
            origin: Point3::from(t_world_object.translation.vector),
        }
    }

    /// A world vector in the object's frame.
    #[inline]
    fn vector_to_local(&self, v: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(
            self.axes[0].dot(v),
            self.axes[1].dot(v),
            self.axes[2].dot(v),
        )
    }

    /// A world point in the object's frame.
    #[inline]
    fn point_to_local(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.vector_to_local(&(p - self.origin)))
    }

    /// An object-frame vector in the world.
    #[inline]
    fn vector_to_world(&self, v: &Vector3<f64>) -> Vector3<f64> {
        self.axes[0] * v.x + self.axes[1] * v.y + self.axes[2] * v.z
    }
}

/// Exact f64 ray intersection with a shape placed at `placement`:
/// nearest entry within (0, max_range_m] and the outward world normal.
pub(super) fn intersect_shape(
    shape: &Shape,
    placement: &Placement,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    max_range_m: f64,
) -> Option<ShapeHit> {
    match shape {
        Shape::Cuboid { half_extents_m } => intersect_offset_cuboid(
            half_extents_m,
            &Vector3::zeros(),
            placement,
            origin,
            dir,
            max_range_m,
        ),
        Shape::Cylinder {
            radius_m,
            half_height_m,
        } => {
            let o = placement.point_to_local(origin);
            let d = placement.vector_to_local(dir);
            let (t_in, n_local) = cylinder_entry(*radius_m, *half_height_m, &o, &d)?;
            accept(t_in, max_range_m, placement, n_local)
        }
        Shape::Ball { radius_m } => {
            let c = placement.origin;
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
    placement: &Placement,
    n_local: Vector3<f64>,
) -> Option<ShapeHit> {
    if t_in <= 0.0 || t_in > max_range_m {
        return None;
    }
    Some((
        t_in,
        Unit::new_normalize(placement.vector_to_world(&n_local)),
    ))
}

/// Slab test of a box centred at `offset_m` in the frame of `placement`
/// (axes shared; zero for a box placed at its centre, else one part of a
/// compound body): entry range and outward world normal.
pub(super) fn intersect_offset_cuboid(
    half_extents_m: &Vector3<f64>,
    offset_m: &Vector3<f64>,
    placement: &Placement,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    max_range_m: f64,
) -> Option<ShapeHit> {
    let o = placement.point_to_local(origin) - offset_m;
    let d = placement.vector_to_local(dir);
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
    accept(t_in, max_range_m, placement, n_local)
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
