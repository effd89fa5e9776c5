//! Lifting a planar track onto the ground height field as a C2 trajectory.

use super::PlanarTrack;
use crate::scene::Ground;
use crate::trajectory::{Jet, Knot, Trajectory};
use nalgebra::{Vector2, Vector3};

/// Wheel track as a fraction of the body width.
const TRACK_OVER_WIDTH: f64 = 0.85;
/// Wheelbase as a fraction of the body length (same as the bicycle model).
const WHEELBASE_OVER_LENGTH: f64 = 0.6;
/// Time step of the central differences for pitch/roll derivatives.
const DIFF_STEP_S: f64 = 1e-3;

/// 3-D C2 trajectory of the box centre on the ground: z = ground height + centre height,
/// pitch/roll from the ground under the wheelbase/track; knots every track.dt_s.
///
/// x, y, yaw come with the model's exact derivatives; z uses the ground gradient
/// and Hessian; pitch and roll are differentiated by central differences of
/// the planar state's second-order Taylor expansion around each sample.
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
    let knots = track
        .samples
        .iter()
        .map(|s| {
            let grad = ground.gradient(s.x, s.y);
            let hess = ground.hessian(s.x, s.y);
            let vel = Vector2::new(s.vx_mps, s.vy_mps);
            let acc = Vector2::new(s.ax_mps2, s.ay_mps2);
            let z = Jet::new(
                ground.height(s.x, s.y) + centre_height,
                grad.dot(&vel),
                grad.dot(&acc) + vel.dot(&(hess * vel)),
            );
            let state_at = |tau: f64| {
                attitude(
                    s.x + s.vx_mps * tau + 0.5 * s.ax_mps2 * tau * tau,
                    s.y + s.vy_mps * tau + 0.5 * s.ay_mps2 * tau * tau,
                    s.yaw + s.yaw_rate_radps * tau + 0.5 * s.yaw_accel_radps2 * tau * tau,
                )
            };
            let h = DIFF_STEP_S;
            let (pm, rm) = state_at(-h);
            let (p0, r0) = state_at(0.0);
            let (pp, rp) = state_at(h);
            Knot {
                position: [
                    Jet::new(s.x, s.vx_mps, s.ax_mps2),
                    Jet::new(s.y, s.vy_mps, s.ay_mps2),
                    z,
                ],
                euler: [
                    Jet::new(s.yaw, s.yaw_rate_radps, s.yaw_accel_radps2),
                    Jet::new(p0, (pp - pm) / (2.0 * h), (pp - 2.0 * p0 + pm) / (h * h)),
                    Jet::new(r0, (rp - rm) / (2.0 * h), (rp - 2.0 * r0 + rm) / (h * h)),
                ],
            }
        })
        .collect::<Vec<_>>();
    // a hand-made track with a bad step or no samples must not panic
    let dt_s = if track.dt_s.is_finite() && track.dt_s > 0.0 {
        track.dt_s
    } else {
        0.01
    };
    if knots.is_empty() {
        return Trajectory::new(track.t0_s, dt_s, vec![Knot::default()]);
    }
    Trajectory::new(track.t0_s, dt_s, knots)
}
