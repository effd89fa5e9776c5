//! Small geometric vocabulary shared by the estimator, the simulator and the
//! metrics: angle wrapping (and, beside it, the one oriented-box type).

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

#[cfg(test)]
mod tests {
    use super::*;

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
}
