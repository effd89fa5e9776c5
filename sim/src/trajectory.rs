//! C2-smooth rigid-body trajectories sampled at uniform knots.
//!
//! Every scalar channel (x, y, z, yaw, pitch, roll) is stored at each knot with
//! its first and second time derivatives and interpolated by quintic Hermite
//! polynomials, so position, velocity and acceleration are continuous and the
//! IMU can be derived analytically at any time. A trajectory lifted from
//! samples stores their values alone and derives the knots' derivatives by
//! finite differences when they are read.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use std::sync::Arc;

/// A scalar value with its first and second time derivatives.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Jet {
    /// The value.
    pub value: f64,
    /// First time derivative, per s.
    pub rate: f64,
    /// Second time derivative, per s².
    pub accel: f64,
}

impl Jet {
    /// A jet from its value and two derivatives.
    pub const fn new(value: f64, rate: f64, accel: f64) -> Jet {
        Jet { value, rate, accel }
    }
}

/// Vehicle state at one knot: position of the body origin in the world and
/// intrinsic z-y-x Euler angles (yaw, pitch, roll), each with derivatives.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Knot {
    /// [x, y, z] of the body origin, world frame, m.
    pub position: [Jet; 3],
    /// [yaw, pitch, roll]; R = Rz(yaw) * Ry(pitch) * Rx(roll).
    pub euler: [Jet; 3],
}

/// The full kinematic state of a body at one instant, in the world frame
/// unless the name says otherwise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KinematicState {
    pub t_world_body: Isometry3<f64>,
    pub velocity_world_mps: Vector3<f64>,
    pub accel_world_mps2: Vector3<f64>,
    pub angular_velocity_body_radps: Vector3<f64>,
    pub angular_accel_body_radps2: Vector3<f64>,
}

/// A trajectory over `[t0_s, t0_s + (n - 1) * dt_s]`; queries outside are
/// clamped to the end knots (the body holds still there). Clones share the
/// knots.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Time of the first knot, s.
    pub t0_s: f64,
    /// Knot spacing, s.
    pub dt_s: f64,
    /// The knots at `t0_s + k dt_s`.
    knots: Knots,
}

/// How a [`Trajectory`] stores its knots.
#[derive(Debug, Clone, PartialEq)]
enum Knots {
    /// Every knot with its derivatives, as given.
    Jets(Arc<[Knot]>),
    /// Per knot the values alone, `[x, y, z, yaw, pitch, roll]`: the rates
    /// and accelerations are finite differences of them
    /// ([`differentiated`]), derived when a knot is read.
    Values(Arc<[[f64; 6]]>),
}

impl Trajectory {
    /// A trajectory from its knots.
    ///
    /// # Panics
    /// If `dt_s <= 0` or `knots` is empty.
    pub fn new(t0_s: f64, dt_s: f64, knots: Vec<Knot>) -> Trajectory {
        assert!(dt_s > 0.0 && !knots.is_empty());
        Trajectory {
            t0_s,
            dt_s,
            knots: Knots::Jets(knots.into()),
        }
    }

    /// A trajectory through sampled values, `[x, y, z, yaw, pitch, roll]`
    /// every `dt_s`, whose knots' rates and accelerations are the values'
    /// finite differences: second-order central ones inside, second-order
    /// one-sided ones at the ends, none (at rest) with fewer than four
    /// samples. Only the values are stored (48 bytes a knot instead of a
    /// [`Knot`]'s 144); the knots are those of [`Trajectory::new`] with the
    /// differences computed up front, bit for bit.
    ///
    /// # Panics
    /// If `dt_s <= 0` or `values` is empty.
    pub fn sampled(t0_s: f64, dt_s: f64, values: Vec<[f64; 6]>) -> Trajectory {
        assert!(dt_s > 0.0 && !values.is_empty());
        Trajectory {
            t0_s,
            dt_s,
            knots: Knots::Values(values.into()),
        }
    }

    /// A body at rest at one pose.
    pub fn stationary(t0_s: f64, t1_s: f64, pose: &Isometry3<f64>) -> Trajectory {
        let (roll, pitch, yaw) = pose.rotation.euler_angles();
        let p = pose.translation.vector;
        let knot = Knot {
            position: [
                Jet::new(p.x, 0.0, 0.0),
                Jet::new(p.y, 0.0, 0.0),
                Jet::new(p.z, 0.0, 0.0),
            ],
            euler: [
                Jet::new(yaw, 0.0, 0.0),
                Jet::new(pitch, 0.0, 0.0),
                Jet::new(roll, 0.0, 0.0),
            ],
        };
        Trajectory::new(t0_s, (t1_s - t0_s).max(1e-3), vec![knot, knot])
    }

    /// Time of the first knot, s.
    pub fn start_s(&self) -> f64 {
        self.t0_s
    }

    /// Time of the last knot, s.
    pub fn end_s(&self) -> f64 {
        self.t0_s + (self.knot_count() - 1) as f64 * self.dt_s
    }

    /// Number of knots.
    pub fn knot_count(&self) -> usize {
        match &self.knots {
            Knots::Jets(knots) => knots.len(),
            Knots::Values(values) => values.len(),
        }
    }

    /// Knot `index` (at `t0_s + index * dt_s`), values and derivatives.
    ///
    /// # Panics
    /// If `index >= knot_count()`.
    pub fn knot(&self, index: usize) -> Knot {
        match &self.knots {
            Knots::Jets(knots) => knots[index],
            Knots::Values(values) => {
                let jet = |c: usize| differentiated(values, c, index, self.dt_s);
                Knot {
                    position: [jet(0), jet(1), jet(2)],
                    euler: [jet(3), jet(4), jet(5)],
                }
            }
        }
    }

    /// The knots in time order.
    pub fn knots(&self) -> impl ExactSizeIterator<Item = Knot> + '_ {
        (0..self.knot_count()).map(|index| self.knot(index))
    }

    /// Bytes the knots take in memory (shared by clones).
    pub fn knot_bytes(&self) -> usize {
        match &self.knots {
            Knots::Jets(knots) => std::mem::size_of_val(&**knots),
            Knots::Values(values) => std::mem::size_of_val(&**values),
        }
    }

    /// Whether `self` and `other` share one store of knots (one is a clone
    /// of the other).
    pub fn shares_knots_with(&self, other: &Trajectory) -> bool {
        match (&self.knots, &other.knots) {
            (Knots::Jets(a), Knots::Jets(b)) => Arc::ptr_eq(a, b),
            (Knots::Values(a), Knots::Values(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }

    /// Where `t_s` falls: before the first or after the last knot (at
    /// rest there), or on the segment between knot `i` and `i + 1` at the
    /// normalised parameter `s`.
    fn place(&self, t_s: f64) -> Place {
        let n = self.knot_count();
        // strictly outside: a query exactly at an end knot keeps its motion
        if n == 1 || t_s < self.t0_s {
            return Place::Rest(0);
        }
        if t_s > self.end_s() {
            return Place::Rest(n - 1);
        }
        let u = (t_s - self.t0_s) / self.dt_s;
        let i = (u.floor() as usize).min(n - 2);
        Place::Between(i, u - i as f64)
    }

    /// Interpolated knot (values and derivatives) at time `t_s`.
    pub fn knot_at(&self, t_s: f64) -> Knot {
        let (a, b, s) = match self.place(t_s) {
            Place::Rest(k) => return at_rest(&self.knot(k)),
            Place::Between(i, s) => (self.knot(i), self.knot(i + 1), s),
        };
        let h = self.dt_s;
        let mut out = Knot::default();
        for c in 0..3 {
            out.position[c] = quintic_hermite(&a.position[c], &b.position[c], s, h);
            out.euler[c] = quintic_hermite(&a.euler[c], &b.euler[c], s, h);
        }
        out
    }

    /// The body pose `t_world_body` at `t_s` (clamped to the trajectory):
    /// that of [`Trajectory::knot_at`], from the values alone.
    pub fn pose_at(&self, t_s: f64) -> Isometry3<f64> {
        match self.place(t_s) {
            Place::Rest(k) => knot_pose(&self.knot(k)),
            Place::Between(i, s) => {
                let (a, b) = (&self.knot(i), &self.knot(i + 1));
                let h = self.dt_s;
                let at = |c: usize, jets: fn(&Knot) -> &[Jet; 3]| {
                    quintic_hermite_value(&jets(a)[c], &jets(b)[c], s, h)
                };
                pose_of(
                    std::array::from_fn(|c| at(c, |k| &k.position)),
                    std::array::from_fn(|c| at(c, |k| &k.euler)),
                )
            }
        }
    }

    /// Pose, velocities and accelerations at `t_s` (clamped to the trajectory).
    pub fn state_at(&self, t_s: f64) -> KinematicState {
        let k = self.knot_at(t_s);
        let [yaw, pitch, roll] = k.euler;
        let rates = Vector3::new(yaw.rate, pitch.rate, roll.rate);
        let accels = Vector3::new(yaw.accel, pitch.accel, roll.accel);
        let e = euler_rate_matrix(pitch.value, roll.value);
        let de = euler_rate_matrix_dot(pitch, roll);
        KinematicState {
            t_world_body: knot_pose(&k),
            velocity_world_mps: Vector3::new(
                k.position[0].rate,
                k.position[1].rate,
                k.position[2].rate,
            ),
            accel_world_mps2: Vector3::new(
                k.position[0].accel,
                k.position[1].accel,
                k.position[2].accel,
            ),
            angular_velocity_body_radps: e * rates,
            angular_accel_body_radps2: e * accels + de * rates,
        }
    }
}

fn at_rest(k: &Knot) -> Knot {
    let still = |j: &Jet| Jet::new(j.value, 0.0, 0.0);
    Knot {
        position: k.position.each_ref().map(still),
        euler: k.euler.each_ref().map(still),
    }
}

/// Where [`Trajectory::place`] puts a time.
enum Place {
    /// Outside the knots: at rest at this one.
    Rest(usize),
    /// Between this knot and the next, at the normalised parameter in [0, 1].
    Between(usize, f64),
}

/// Channel `c` of sample `k` of evenly spaced samples (spacing `h`) with its
/// rate and acceleration: second-order central differences inside,
/// second-order one-sided ones at the ends, none with fewer than four
/// samples.
fn differentiated(values: &[[f64; 6]], c: usize, k: usize, h: f64) -> Jet {
    let n = values.len();
    let p = |i: usize| values[i][c];
    let (rate, accel) = if n < 4 {
        // too short to difference: hold still (a hand-made stub track)
        (0.0, 0.0)
    } else if k == 0 {
        (
            (-3.0 * p(0) + 4.0 * p(1) - p(2)) / (2.0 * h),
            (2.0 * p(0) - 5.0 * p(1) + 4.0 * p(2) - p(3)) / (h * h),
        )
    } else if k == n - 1 {
        (
            (3.0 * p(k) - 4.0 * p(k - 1) + p(k - 2)) / (2.0 * h),
            (2.0 * p(k) - 5.0 * p(k - 1) + 4.0 * p(k - 2) - p(k - 3)) / (h * h),
        )
    } else {
        (
            (p(k + 1) - p(k - 1)) / (2.0 * h),
            (p(k + 1) - 2.0 * p(k) + p(k - 1)) / (h * h),
        )
    };
    Jet::new(p(k), rate, accel)
}

/// The pose of a knot (its values).
fn knot_pose(k: &Knot) -> Isometry3<f64> {
    pose_of(k.position.map(|j| j.value), k.euler.map(|j| j.value))
}

/// The pose of a knot's values: `position` (x, y, z) and `euler` (yaw,
/// pitch, roll).
fn pose_of(position: [f64; 3], euler: [f64; 3]) -> Isometry3<f64> {
    let [yaw, pitch, roll] = euler;
    let rotation =
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_euler_angles(roll, pitch, yaw));
    let t = Translation3::new(position[0], position[1], position[2]);
    Isometry3::from_parts(t, rotation)
}

/// Maps (yaw, pitch, roll) rates to the body angular velocity for
/// R = Rz(yaw) Ry(pitch) Rx(roll).
pub fn euler_rate_matrix(pitch: f64, roll: f64) -> Matrix3<f64> {
    let (sp, cp) = pitch.sin_cos();
    let (sr, cr) = roll.sin_cos();
    // columns: d/d yaw, d/d pitch, d/d roll
    Matrix3::new(
        -sp,
        0.0,
        1.0, //
        cp * sr,
        cr,
        0.0, //
        cp * cr,
        -sr,
        0.0,
    )
}

fn euler_rate_matrix_dot(pitch: Jet, roll: Jet) -> Matrix3<f64> {
    let (sp, cp) = pitch.value.sin_cos();
    let (sr, cr) = roll.value.sin_cos();
    let (dp, dr) = (pitch.rate, roll.rate);
    Matrix3::new(
        -cp * dp,
        0.0,
        0.0,
        -sp * dp * sr + cp * cr * dr,
        -sr * dr,
        0.0,
        -sp * dp * cr - cp * sr * dr,
        -cr * dr,
        0.0,
    )
}

/// Quintic Hermite interpolation on one segment of length `h` at the
/// normalised parameter `s` in [0, 1]; matches value, rate and accel at both ends.
fn quintic_hermite(a: &Jet, b: &Jet, s: f64, h: f64) -> Jet {
    let (s2, s3) = (s * s, s * s * s);
    let (s4, s5) = (s3 * s, s3 * s2);
    // basis functions and their derivatives with respect to s
    let h0 = [
        1.0 - 10.0 * s3 + 15.0 * s4 - 6.0 * s5,
        -30.0 * s2 + 60.0 * s3 - 30.0 * s4,
        -60.0 * s + 180.0 * s2 - 120.0 * s3,
    ];
    let h1 = [
        s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5,
        1.0 - 18.0 * s2 + 32.0 * s3 - 15.0 * s4,
        -36.0 * s + 96.0 * s2 - 60.0 * s3,
    ];
    let h2 = [
        0.5 * s2 - 1.5 * s3 + 1.5 * s4 - 0.5 * s5,
        s - 4.5 * s2 + 6.0 * s3 - 2.5 * s4,
        1.0 - 9.0 * s + 18.0 * s2 - 10.0 * s3,
    ];
    let h3 = [
        10.0 * s3 - 15.0 * s4 + 6.0 * s5,
        30.0 * s2 - 60.0 * s3 + 30.0 * s4,
        60.0 * s - 180.0 * s2 + 120.0 * s3,
    ];
    let h4 = [
        -4.0 * s3 + 7.0 * s4 - 3.0 * s5,
        -12.0 * s2 + 28.0 * s3 - 15.0 * s4,
        -24.0 * s + 84.0 * s2 - 60.0 * s3,
    ];
    let h5 = [
        0.5 * s3 - s4 + 0.5 * s5,
        1.5 * s2 - 4.0 * s3 + 2.5 * s4,
        3.0 * s - 12.0 * s2 + 10.0 * s3,
    ];
    let coef = [
        a.value,
        a.rate * h,
        a.accel * h * h,
        b.value,
        b.rate * h,
        b.accel * h * h,
    ];
    let basis = [h0, h1, h2, h3, h4, h5];
    let mut d = [0.0; 3];
    for (c, bf) in coef.iter().zip(basis.iter()) {
        for k in 0..3 {
            d[k] += c * bf[k];
        }
    }
    Jet::new(d[0], d[1] / h, d[2] / (h * h))
}

/// The value of [`quintic_hermite`] alone (the same operations).
fn quintic_hermite_value(a: &Jet, b: &Jet, s: f64, h: f64) -> f64 {
    let (s2, s3) = (s * s, s * s * s);
    let (s4, s5) = (s3 * s, s3 * s2);
    let basis = [
        1.0 - 10.0 * s3 + 15.0 * s4 - 6.0 * s5,
        s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5,
        0.5 * s2 - 1.5 * s3 + 1.5 * s4 - 0.5 * s5,
        10.0 * s3 - 15.0 * s4 + 6.0 * s5,
        -4.0 * s3 + 7.0 * s4 - 3.0 * s5,
        0.5 * s3 - s4 + 0.5 * s5,
    ];
    let coef = [
        a.value,
        a.rate * h,
        a.accel * h * h,
        b.value,
        b.rate * h,
        b.accel * h * h,
    ];
    let mut value = 0.0;
    for (c, bf) in coef.iter().zip(basis.iter()) {
        value += c * bf;
    }
    value
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jet_of_cubic(t: f64) -> Jet {
        // x(t) = 1 + 2t - 0.5t^2 + 0.3t^3
        Jet::new(
            1.0 + 2.0 * t - 0.5 * t * t + 0.3 * t * t * t,
            2.0 - t + 0.9 * t * t,
            -1.0 + 1.8 * t,
        )
    }

    #[test]
    fn quintic_hermite_reproduces_cubics_exactly() {
        let h = 0.1;
        for seg in 0..5 {
            let t0 = seg as f64 * h;
            let (a, b) = (jet_of_cubic(t0), jet_of_cubic(t0 + h));
            for i in 0..=10 {
                let s = i as f64 / 10.0;
                let got = quintic_hermite(&a, &b, s, h);
                let want = jet_of_cubic(t0 + s * h);
                assert!((got.value - want.value).abs() < 1e-12);
                assert!((got.rate - want.rate).abs() < 1e-10);
                assert!((got.accel - want.accel).abs() < 1e-8);
            }
        }
    }

    #[test]
    fn sampled_knots_are_the_values_finite_differences() {
        let h = 0.01;
        let values: Vec<[f64; 6]> = (0..50)
            .map(|i| {
                let t = i as f64 * h;
                let v = jet_of_cubic(t).value;
                [v, 2.0 * v, -v, 0.1 * v, 0.01 * t, -0.02 * t]
            })
            .collect();
        let sampled = Trajectory::sampled(0.0, h, values.clone());
        assert_eq!(sampled.knot_bytes(), 50 * 48);
        // exact for a quadratic inside, second order at the ends
        for k in [0, 1, 25, 48, 49] {
            let want = jet_of_cubic(k as f64 * h);
            let got = sampled.knot(k).position[0];
            assert_eq!(got.value, values[k][0]);
            assert!((got.rate - want.rate).abs() < 1e-3, "{k}: {got:?} {want:?}");
            assert!(
                (got.accel - want.accel).abs() < 2e-2,
                "{k}: {got:?} {want:?}"
            );
        }
        // the same trajectory as its knots stored whole, bit for bit
        let whole = Trajectory::new(0.0, h, sampled.knots().collect());
        for t in [0.0, 0.123, 0.25, 0.4901, 0.49] {
            assert_eq!(sampled.pose_at(t), whole.pose_at(t));
            assert_eq!(sampled.state_at(t), whole.state_at(t));
        }
        assert!(sampled.clone().shares_knots_with(&sampled));
        assert!(!whole.shares_knots_with(&sampled));
        // too few samples to difference: at rest
        let stub = Trajectory::sampled(0.0, h, values[..3].to_vec());
        assert_eq!(stub.knot(1).position[0].rate, 0.0);
    }

    #[test]
    fn end_knots_keep_their_motion() {
        let knots = (0..3)
            .map(|i| Knot {
                position: [
                    Jet::new(i as f64, 10.0, 0.0),
                    Jet::default(),
                    Jet::default(),
                ],
                euler: [Jet::default(); 3],
            })
            .collect();
        let traj = Trajectory::new(0.0, 0.1, knots);
        assert_eq!(traj.state_at(0.0).velocity_world_mps.x, 10.0);
        assert_eq!(traj.state_at(0.2).velocity_world_mps.x, 10.0);
        assert_eq!(traj.state_at(0.3).velocity_world_mps.x, 0.0);
    }

    #[test]
    fn angular_velocity_matches_finite_difference_of_rotation() {
        let knots: Vec<Knot> = (0..20)
            .map(|i| {
                let t = i as f64 * 0.1;
                Knot {
                    position: [Jet::new(t, 1.0, 0.0), Jet::default(), Jet::default()],
                    euler: [
                        Jet::new(0.3 * t * t, 0.6 * t, 0.6),
                        Jet::new(0.1 * t.sin(), 0.1 * t.cos(), -0.1 * t.sin()),
                        Jet::new(0.05 * t, 0.05, 0.0),
                    ],
                }
            })
            .collect();
        let traj = Trajectory::new(0.0, 0.1, knots);
        let (t, eps) = (0.73, 1e-5);
        let r0 = traj.pose_at(t - eps).rotation;
        let r1 = traj.pose_at(t + eps).rotation;
        let omega_fd = (r0.inverse() * r1).scaled_axis() / (2.0 * eps);
        let omega = traj.state_at(t).angular_velocity_body_radps;
        assert!((omega - omega_fd).norm() < 1e-6, "{omega} vs {omega_fd}");
        let w0 = traj.state_at(t - eps).angular_velocity_body_radps;
        let w1 = traj.state_at(t + eps).angular_velocity_body_radps;
        let alpha_fd = (w1 - w0) / (2.0 * eps);
        let alpha = traj.state_at(t).angular_accel_body_radps2;
        assert!((alpha - alpha_fd).norm() < 1e-5, "{alpha} vs {alpha_fd}");
    }
}
