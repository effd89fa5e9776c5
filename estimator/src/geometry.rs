//! Small geometric vocabulary shared by the estimator, the simulator and the
//! metrics: angle wrapping, the floor of a coordinate as an integer (grid
//! and voxel keys, texture cells) and the one oriented-box type,
//! [`OrientedBox`].

use nalgebra::{Isometry3, Point3, Vector2, Vector3};
use std::f64::consts::{PI, TAU};

/// Wraps an angle to (−π, π], radians.
///
/// Angles already in range come back unchanged, bit for bit; others are
/// reduced modulo 2π (−π maps to π).
///
/// ```
/// use limot_estimator::geometry::wrap_angle_rad;
/// use std::f64::consts::PI;
/// assert_eq!(wrap_angle_rad(0.25), 0.25);
/// assert_eq!(wrap_angle_rad(-PI), PI);
/// assert!((wrap_angle_rad(3.0 * PI) - PI).abs() < 1e-12);
/// assert!((wrap_angle_rad(-7.0) - (-7.0 + 2.0 * PI)).abs() < 1e-12);
/// ```
pub fn wrap_angle_rad(angle_rad: f64) -> f64 {
    if angle_rad > -PI && angle_rad <= PI {
        return angle_rad;
    }
    let wrapped = angle_rad.rem_euclid(TAU);
    if wrapped > PI { wrapped - TAU } else { wrapped }
}

/// `floor(v)` as an integer. `f64::floor` is a libm call on baseline x86-64
/// (no SSE4.1 `roundsd`); truncation plus a
/// correction is exact for every `v` in the `i64` range and saturates
/// beyond it (NaN gives 0). Magnitudes below 2^62 (every voxel, grid and
/// texture coordinate) skip the saturating cast's range checks: they were a
/// fifth of the voxel downsampling's time.
#[inline]
pub fn floor_to_i64(v: f64) -> i64 {
    if v.abs() < TRUNCATION_EXACT_BELOW {
        // SAFETY: |v| < 2^62, so its truncation is an i64.
        let t: i64 = unsafe { v.to_int_unchecked() };
        // Without a branch: half the coordinates of a scan are negative,
        // which makes "truncation rounded up" unpredictable.
        t - i64::from((t as f64) > v)
    } else {
        let t = v as i64;
        t.saturating_sub(i64::from((t as f64) > v))
    }
}

/// Below this magnitude (2^62) a truncation needs no saturation.
const TRUNCATION_EXACT_BELOW: f64 = 4_611_686_018_427_387_904.0;

/// An upright 3D box: centre, size and heading about the z axis of its frame.
///
/// The fields do not name a frame; the variable holding the box does
/// (`box_world`, `box_lidar`). The box length runs along the heading; the
/// vertical extent is `center.z ± h/2`.
///
/// ```
/// use limot_estimator::geometry::OrientedBox;
/// use nalgebra::Vector3;
/// let car = OrientedBox::new(Vector3::new(10.0, 0.0, 0.8), Vector3::new(4.0, 2.0, 1.5), 0.0);
/// assert!(car.contains(&Vector3::new(11.9, 0.9, 0.8), 0.0));
/// assert!(!car.contains(&Vector3::new(12.1, 0.0, 0.8), 0.0));
/// assert_eq!(car.volume(), 12.0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrientedBox {
    /// Geometric centre, metres.
    pub center: Vector3<f64>,
    /// Length (along the heading), width, height, metres.
    pub size_lwh: Vector3<f64>,
    /// Heading about +z, radians, 0 = along +x.
    pub yaw_rad: f64,
}

impl OrientedBox {
    /// A box from its centre, size (l, w, h) and yaw.
    pub fn new(center: Vector3<f64>, size_lwh: Vector3<f64>, yaw_rad: f64) -> OrientedBox {
        OrientedBox {
            center,
            size_lwh,
            yaw_rad,
        }
    }

    /// The box whose pose in some frame is `t_frame_box` (box x axis along the
    /// length); roll and pitch are dropped (the yaw is that of the box x axis
    /// projected onto the x-y plane).
    pub fn from_pose(t_frame_box: &Isometry3<f64>, size_lwh: Vector3<f64>) -> OrientedBox {
        let heading = t_frame_box.rotation * Vector3::x();
        OrientedBox {
            center: t_frame_box.translation.vector,
            size_lwh,
            yaw_rad: heading.y.atan2(heading.x),
        }
    }

    /// This box, given in frame `a`, in frame `b` (`t_b_a` maps points of `a`
    /// into `b`). The heading is the box's heading direction mapped into `b`
    /// and levelled: the box stays upright even when `t_b_a` pitches or rolls.
    /// The yaw is not wrapped beyond what `atan2` returns.
    pub fn transformed(&self, t_b_a: &Isometry3<f64>) -> OrientedBox {
        let center = t_b_a * Point3::from(self.center);
        let heading_a = Vector3::new(self.yaw_rad.cos(), self.yaw_rad.sin(), 0.0);
        let heading_b = t_b_a.rotation * heading_a;
        OrientedBox {
            center: center.coords,
            size_lwh: self.size_lwh,
            yaw_rad: heading_b.y.atan2(heading_b.x),
        }
    }

    /// True when `p` (same frame as the box) lies inside the box grown by
    /// `inflate_m` on every face (boundary included). A negative inflation
    /// shrinks the box.
    pub fn contains(&self, p: &Vector3<f64>, inflate_m: f64) -> bool {
        self.contains_inflated(p, inflate_m, inflate_m)
    }

    /// As [`OrientedBox::contains`], but the bottom face moves by
    /// `inflate_bottom_m` (down for positive values) while the four sides and
    /// the top move by `inflate_m`.
    pub fn contains_inflated(
        &self,
        p: &Vector3<f64>,
        inflate_m: f64,
        inflate_bottom_m: f64,
    ) -> bool {
        let d = p - self.center;
        let (sin_yaw, cos_yaw) = self.yaw_rad.sin_cos();
        // offset rotated into the box frame (x along the heading)
        let x_box = cos_yaw * d.x + sin_yaw * d.y;
        let y_box = -sin_yaw * d.x + cos_yaw * d.y;
        let half = 0.5 * self.size_lwh;
        x_box.abs() <= half.x + inflate_m
            && y_box.abs() <= half.y + inflate_m
            && d.z <= half.z + inflate_m
            && d.z >= -half.z - inflate_bottom_m
    }

    /// Footprint corners (x-y plane), counter-clockwise seen from above.
    pub fn bev_corners(&self) -> [Vector2<f64>; 4] {
        let (s, c) = self.yaw_rad.sin_cos();
        let hl = 0.5 * self.size_lwh.x;
        let hw = 0.5 * self.size_lwh.y;
        let centre = Vector2::new(self.center.x, self.center.y);
        let along = Vector2::new(c, s);
        let across = Vector2::new(-s, c);
        [
            centre + along * hl + across * hw,
            centre - along * hl + across * hw,
            centre - along * hl - across * hw,
            centre + along * hl - across * hw,
        ]
    }

    /// Footprint area, m².
    pub fn bev_area(&self) -> f64 {
        self.size_lwh.x * self.size_lwh.y
    }

    /// Volume, m³.
    pub fn volume(&self) -> f64 {
        self.size_lwh.x * self.size_lwh.y * self.size_lwh.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_to_i64_matches_floor() {
        let small = [
            -2.5, -2.0, -1.0, -0.5, -1e-300, 0.0, 1e-300, 0.5, 1.0, 2.999, 1e15, -1e15,
        ];
        // either side of the unsaturated path's bound, 2^62, both signs
        let near_bound = [4.0e18, 4.611686018427388e18, 9.2e18];
        let near_bound = near_bound.into_iter().flat_map(|v| [v, -v]);
        for v in small.into_iter().chain(near_bound) {
            assert_eq!(floor_to_i64(v), v.floor() as i64, "{v}");
        }
        assert_eq!(floor_to_i64(f64::NAN), 0);
        assert_eq!(floor_to_i64(1e300), i64::MAX);
        assert_eq!(floor_to_i64(-1e300), i64::MIN);
    }

    #[test]
    fn wrapped_angles_land_in_the_half_open_interval() {
        for k in -2000..=2000 {
            let a = k as f64 * 0.0137;
            let w = wrap_angle_rad(a);
            assert!(w > -PI && w <= PI, "{a} -> {w}");
            // same direction
            assert!((w.sin() - a.sin()).abs() < 1e-9 && (w.cos() - a.cos()).abs() < 1e-9);
        }
        assert_eq!(wrap_angle_rad(PI), PI);
        assert_eq!(wrap_angle_rad(-PI), PI);
        assert_eq!(wrap_angle_rad(TAU), 0.0);
        assert!(wrap_angle_rad(f64::NAN).is_nan());
    }

    #[test]
    fn from_pose_reads_yaw() {
        let pose = Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::z() * 0.8);
        let bx = OrientedBox::from_pose(&pose, Vector3::new(4.0, 2.0, 1.5));
        assert!((bx.yaw_rad - 0.8).abs() < 1e-12);
        assert_eq!(bx.center, Vector3::new(1.0, 2.0, 3.0));
    }

    #[test]
    fn transformed_and_back_is_the_same_box() {
        let b = OrientedBox::new(
            Vector3::new(12.0, -2.5, -0.8),
            Vector3::new(4.0, 2.0, 1.5),
            0.3,
        );
        let t_world_lidar =
            Isometry3::new(Vector3::new(5.0, 1.0, 0.2), Vector3::new(0.0, 0.0, 1.1));
        let world = b.transformed(&t_world_lidar);
        assert!((world.yaw_rad - 1.4).abs() < 1e-12);
        let back = world.transformed(&t_world_lidar.inverse());
        assert!((back.center - b.center).norm() < 1e-12);
        assert!((back.yaw_rad - b.yaw_rad).abs() < 1e-12);
        assert_eq!(back.size_lwh, b.size_lwh);
    }
}
