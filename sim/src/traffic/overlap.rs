//! Overlap checks between the bodies of a scene over time: oriented boxes in
//! f64 by the separating-axis test, boxes against balls by the closest point,
//! boxes against cylinders through parry3d (f32, relative pose only).

use crate::scene::{Scene, Shape};
use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};

/// Every body is shrunk by this much so that touching does not count.
const SHRINK_M: f64 = 0.01;

/// A body of a scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Body {
    /// The ego vehicle.
    Ego,
    /// Agent id.
    Agent(u32),
    /// Index into `scene.statics`.
    Static(usize),
}

/// Two bodies overlapping at `t_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Overlap {
    /// Time of the overlap, s.
    pub t_s: f64,
    /// One body.
    pub a: Body,
    /// The other body.
    pub b: Body,
}

/// An oriented box: centre, rotation (columns = box axes), half extents.
#[derive(Debug, Clone, Copy)]
struct Obb {
    centre: Vector3<f64>,
    axes: Matrix3<f64>,
    half: Vector3<f64>,
}

impl Obb {
    fn new(pose: &Isometry3<f64>, size_lwh_m: &Vector3<f64>) -> Obb {
        Obb {
            centre: pose.translation.vector,
            axes: pose.rotation.to_rotation_matrix().into_inner(),
            half: (size_lwh_m * 0.5).map(|h| (h - SHRINK_M).max(0.0)),
        }
    }

    fn radius(&self) -> f64 {
        self.half.norm()
    }

    fn pose(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.centre),
            UnitQuaternion::from_matrix(&self.axes),
        )
    }
}

/// Separating-axis test of two oriented boxes (15 candidate axes).
fn obb_overlap(a: &Obb, b: &Obb) -> bool {
    if (a.centre - b.centre).norm() > a.radius() + b.radius() {
        return false;
    }
    // b's axes in a's frame
    let r = a.axes.transpose() * b.axes;
    let abs_r = r.map(|x| x.abs() + 1e-12);
    let t = a.axes.transpose() * (b.centre - a.centre);
    for i in 0..3 {
        let rb = (0..3).map(|j| b.half[j] * abs_r[(i, j)]).sum::<f64>();
        if t[i].abs() > a.half[i] + rb {
            return false;
        }
    }
    for j in 0..3 {
        let ra = (0..3).map(|i| a.half[i] * abs_r[(i, j)]).sum::<f64>();
        let tj = t[0] * r[(0, j)] + t[1] * r[(1, j)] + t[2] * r[(2, j)];
        if tj.abs() > ra + b.half[j] {
            return false;
        }
    }
    for i in 0..3 {
        let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
        for j in 0..3 {
            let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
            let ra = a.half[i1] * abs_r[(i2, j)] + a.half[i2] * abs_r[(i1, j)];
            let rb = b.half[j1] * abs_r[(i, j2)] + b.half[j2] * abs_r[(i, j1)];
            let tt = (t[i2] * r[(i1, j)] - t[i1] * r[(i2, j)]).abs();
            if tt > ra + rb {
                return false;
            }
        }
    }
    true
}

/// Whether two oriented boxes (their centres' poses and sizes l, w, h)
/// overlap, both shrunk as in [`first_overlap`] so that touching does not count.
pub(crate) fn boxes_overlap(
    pose_a: &Isometry3<f64>,
    size_a_lwh_m: &Vector3<f64>,
    pose_b: &Isometry3<f64>,
    size_b_lwh_m: &Vector3<f64>,
) -> bool {
    let (a, b) = (
        Obb::new(pose_a, size_a_lwh_m),
        Obb::new(pose_b, size_b_lwh_m),
    );
    (a.centre - b.centre).norm() <= a.radius() + b.radius() && obb_overlap(&a, &b)
}

/// Oriented box against a static shape.
fn box_vs_shape(a: &Obb, shape: &Shape, pose: &Isometry3<f64>) -> bool {
    match *shape {
        Shape::Cuboid { half_extents_m } => {
            let b = Obb::new(pose, &(half_extents_m * 2.0));
            obb_overlap(a, &b)
        }
        Shape::Ball { radius_m } => {
            let r = radius_m - SHRINK_M;
            if r <= 0.0 {
                return false;
            }
            let local = a.axes.transpose() * (pose.translation.vector - a.centre);
            let closest = local.zip_map(&a.half, |x, h| x.clamp(-h, h));
            (local - closest).norm() < r
        }
        Shape::Cylinder {
            radius_m,
            half_height_m,
        } => {
            let (r, hh) = (radius_m - SHRINK_M, half_height_m - SHRINK_M);
            if r <= 0.0 || hh <= 0.0 {
                return false;
            }
            let bound = (r * r + hh * hh).sqrt();
            if (pose.translation.vector - a.centre).norm() > a.radius() + bound {
                return false;
            }
            box_vs_cylinder(a, r, hh, pose)
        }
    }
}

/// parry3d (f32) on the relative pose; parry's cylinder axis is local y, ours z.
fn box_vs_cylinder(a: &Obb, radius_m: f64, half_height_m: f64, pose: &Isometry3<f64>) -> bool {
    use parry3d::math::{Pose, Vector};
    use parry3d::shape::{Cuboid, Cylinder};
    let y_to_z = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2);
    let rel = a.pose().inverse() * pose * y_to_z;
    let t = rel.translation.vector;
    let axis = rel.rotation.scaled_axis();
    let cyl_pose = Pose::new(
        Vector::new(t.x as f32, t.y as f32, t.z as f32),
        Vector::new(axis.x as f32, axis.y as f32, axis.z as f32),
    );
    let cuboid = Cuboid::new(Vector::new(
        a.half.x as f32,
        a.half.y as f32,
        a.half.z as f32,
    ));
    let cylinder = Cylinder::new(half_height_m as f32, radius_m as f32);
    parry3d::query::intersection_test(&Pose::identity(), &cuboid, &cyl_pose, &cylinder)
        .map(|r| r.intersecting)
        .unwrap_or(false)
}

/// First time two bodies overlap in `scene` (agents vs agents, agents vs ego box,
/// agents/ego vs static objects), checked every dt_s over [0, duration] (the end
/// included); None if never. A non-positive or non-finite `dt_s` checks every 0.01 s.
pub fn first_overlap(scene: &Scene, dt_s: f64) -> Option<Overlap> {
    let dt = if dt_s.is_finite() && dt_s > 0.0 {
        dt_s
    } else {
        0.01
    };
    let duration = scene.duration_s.max(0.0);
    let n = (duration / dt).floor() as usize;
    let statics: Vec<(f64, Vector3<f64>)> = scene
        .statics
        .iter()
        .map(|s| {
            let r = match s.shape {
                Shape::Cuboid { half_extents_m } => half_extents_m.norm(),
                Shape::Cylinder {
                    radius_m,
                    half_height_m,
                } => (radius_m * radius_m + half_height_m * half_height_m).sqrt(),
                Shape::Ball { radius_m } => radius_m,
            };
            (r, s.t_world_object.translation.vector)
        })
        .collect();
    let mut times: Vec<f64> = (0..=n).map(|k| k as f64 * dt).collect();
    if duration - n as f64 * dt > 1e-9 {
        times.push(duration);
    }
    for t in times {
        let mut bodies: Vec<(Body, Obb)> = Vec::with_capacity(scene.agents.len() + 1);
        let ego_pose = scene.ego.t_world_box_at(t);
        bodies.push((Body::Ego, Obb::new(&ego_pose, &scene.ego.size_lwh_m)));
        for agent in &scene.agents {
            bodies.push((
                Body::Agent(agent.id),
                Obb::new(&agent.trajectory.pose_at(t), &agent.size_lwh_m),
            ));
        }
        for i in 0..bodies.len() {
            for j in i + 1..bodies.len() {
                if obb_overlap(&bodies[i].1, &bodies[j].1) {
                    return Some(Overlap {
                        t_s: t,
                        a: bodies[i].0,
                        b: bodies[j].0,
                    });
                }
            }
            let (body, obb) = &bodies[i];
            for (k, (s, (radius, centre))) in scene.statics.iter().zip(&statics).enumerate() {
                if (centre - obb.centre).norm() > radius + obb.radius() {
                    continue;
                }
                if box_vs_shape(obb, &s.shape, &s.t_world_object) {
                    return Some(Overlap {
                        t_s: t,
                        a: *body,
                        b: Body::Static(k),
                    });
                }
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obb(x: f64, y: f64, yaw: f64, size: Vector3<f64>) -> Obb {
        let pose = Isometry3::new(Vector3::new(x, y, 0.0), Vector3::z() * yaw);
        Obb::new(&pose, &size)
    }

    /// Brute force: does any grid point of a lie inside b?
    fn sampled_overlap(a: &Obb, b: &Obb) -> bool {
        let n = 24;
        for i in 0..=n {
            for j in 0..=n {
                for k in 0..=n {
                    let u = Vector3::new(i as f64, j as f64, k as f64) / n as f64 * 2.0
                        - Vector3::repeat(1.0);
                    let p = a.centre + a.axes * u.component_mul(&a.half);
                    let q = b.axes.transpose() * (p - b.centre);
                    if (0..3).all(|c| q[c].abs() <= b.half[c]) {
                        return true;
                    }
                }
            }
        }
        false
    }

    #[test]
    fn sat_matches_sampling_for_rotated_boxes() {
        let size_a = Vector3::new(4.5, 1.8, 1.5);
        let size_b = Vector3::new(2.0, 0.8, 1.7);
        let mut disagreements = 0;
        for k in 0..200 {
            let f = k as f64;
            let b = obb(
                (f * 0.37).sin() * 4.0,
                (f * 0.91).cos() * 2.5,
                f * 0.23,
                size_b,
            );
            let a = obb(0.0, 0.0, 0.1, size_a);
            let sat = obb_overlap(&a, &b);
            let sampled = sampled_overlap(&a, &b) || sampled_overlap(&b, &a);
            if sat != sampled {
                disagreements += 1;
            }
        }
        // sampling misses only razor-thin corner overlaps
        assert!(disagreements <= 3, "{disagreements} disagreements");
        assert!(!obb_overlap(
            &obb(0.0, 0.0, 0.0, size_a),
            &obb(4.51, 0.0, 0.0, size_a)
        ));
        // touching does not count (1 cm shrink)
        assert!(!obb_overlap(
            &obb(0.0, 0.0, 0.0, size_a),
            &obb(4.5, 0.0, 0.0, size_a)
        ));
        assert!(obb_overlap(
            &obb(0.0, 0.0, 0.0, size_a),
            &obb(4.45, 0.0, 0.0, size_a)
        ));
        // rotated 90 degrees: corner region
        assert!(obb_overlap(
            &obb(0.0, 0.0, 0.0, size_a),
            &obb(3.0, 0.0, std::f64::consts::FRAC_PI_2, size_a)
        ));
        assert!(!obb_overlap(
            &obb(0.0, 0.0, 0.0, size_a),
            &obb(3.2, 0.0, std::f64::consts::FRAC_PI_2, size_a)
        ));
    }

    #[test]
    fn box_against_ball_and_cylinder() {
        let a = obb(0.0, 0.0, 0.0, Vector3::new(4.0, 2.0, 1.5));
        let at = |x: f64, y: f64| Isometry3::translation(x, y, 0.0);
        let ball = Shape::Ball { radius_m: 0.5 };
        assert!(box_vs_shape(&a, &ball, &at(2.4, 0.0)));
        assert!(!box_vs_shape(&a, &ball, &at(2.6, 0.0)));
        assert!(!box_vs_shape(&a, &ball, &at(2.35, 1.35)));
        let pole = Shape::Cylinder {
            radius_m: 0.3,
            half_height_m: 3.0,
        };
        assert!(box_vs_shape(&a, &pole, &at(2.2, 0.5)));
        assert!(!box_vs_shape(&a, &pole, &at(2.4, 0.5)));
        // corner: inside the axis-aligned bound but clear of the round pole
        assert!(!box_vs_shape(&a, &pole, &at(2.25, 1.25)));
        // a lying cylinder (axis along world x) above the box misses it
        let lying = Isometry3::new(
            Vector3::new(0.0, 0.0, 1.2),
            Vector3::y() * std::f64::consts::FRAC_PI_2,
        );
        assert!(!box_vs_shape(
            &a,
            &Shape::Cylinder {
                radius_m: 0.4,
                half_height_m: 5.0
            },
            &lying
        ));
        let lying_low = Isometry3::new(
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::y() * std::f64::consts::FRAC_PI_2,
        );
        assert!(box_vs_shape(
            &a,
            &Shape::Cylinder {
                radius_m: 0.4,
                half_height_m: 5.0
            },
            &lying_low
        ));
    }
}
