//! Lifting a planar track onto the ground height field as a C2 trajectory.

use super::PlanarTrack;
use crate::scene::Ground;
use crate::trajectory::{Jet, Knot, Trajectory};
use nalgebra::{Vector2, Vector3};

/// Wheel track as a fraction of the body width.
const TRACK_OVER_WIDTH: f64 = 0.85;
/// Wheelbase as a fraction of the body length (same as the bicycle model).
const WHEELBASE_OVER_LENGTH: f64 = 0.6;

/// 3-D C2 trajectory of the box centre on the ground: z = ground height + centre height,
/// pitch/roll from the ground under the wheelbase/track; knots every track.dt_s.
///
/// Every knot's rate and acceleration are finite differences of the sampled
/// values themselves (x, y, yaw, z, pitch, roll), not the model's instantaneous
/// derivatives: the 1 kHz integrator's steps differ from those by O(a dt), and
/// a quintic piece forced through inconsistent end data over 10 ms swings its
/// acceleration by ~1 m/s^2 at 100 Hz, which no car does and which IMU
/// preintegration would see as error. Differences of the samples are
/// consistent with the samples, so the pieces stay smooth.
/// A track with a non-positive or non-finite `dt_s` is read with 0.01 s.
pub fn lift_to_ground(
    track: &PlanarTrack,
    ground: &Ground,
    size_lwh_m: &Vector3<f64>,
) -> Trajectory {
    let half_wheelbase = 0.5 * WHEELBASE_OVER_LENGTH * size_lwh_m.x;
    let half_track = 0.5 * TRACK_OVER_WIDTH * size_lwh_m.y;
    let centre_height = 0.5 * size_lwh_m.z;
    // pitch (nose down positive, R = Rz Ry Rx) and roll (left side up positive)
    let attitude = |x: f64, y: f64, yaw: f64| -> (f64, f64) {
        let (s, c) = yaw.sin_cos();
        let (fwd, left) = (Vector2::new(c, s), Vector2::new(-s, c));
        let p = Vector2::new(x, y);
        let at = |q: Vector2<f64>| ground.height(q.x, q.y);
        let pitch = (at(p - fwd * half_wheelbase) - at(p + fwd * half_wheelbase))
            .atan2(2.0 * half_wheelbase);
        let roll = (at(p + left * half_track) - at(p - left * half_track)).atan2(2.0 * half_track);
        (pitch, roll)
    };
    // a hand-made track with a bad step or no samples must not panic
    let dt_s = if track.dt_s.is_finite() && track.dt_s > 0.0 {
        track.dt_s
    } else {
        0.01
    };
    if track.samples.is_empty() {
        return Trajectory::new(track.t0_s, dt_s, vec![Knot::default()]);
    }
    let channels: [Vec<f64>; 6] = {
        let mut c: [Vec<f64>; 6] = Default::default();
        for s in &track.samples {
            let (pitch, roll) = attitude(s.x, s.y, s.yaw);
            let values = [
                s.x,
                s.y,
                ground.height(s.x, s.y) + centre_height,
                s.yaw,
                pitch,
                roll,
            ];
            for (channel, value) in c.iter_mut().zip(values) {
                channel.push(value);
            }
        }
        c
    };
    let jets = channels.map(|values| differentiate(&values, dt_s));
    let knots = (0..track.samples.len())
        .map(|k| Knot {
            position: [jets[0][k], jets[1][k], jets[2][k]],
            euler: [jets[3][k], jets[4][k], jets[5][k]],
        })
        .collect();
    Trajectory::new(track.t0_s, dt_s, knots)
}

/// Value, rate and acceleration of evenly spaced samples: second-order
/// central differences inside, second-order one-sided ones at the ends.
fn differentiate(values: &[f64], h: f64) -> Vec<Jet> {
    let n = values.len();
    (0..n)
        .map(|k| {
            let p = |i: usize| values[i];
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
            Jet::new(values[k], rate, accel)
        })
        .collect()
}
