//! Lifting a planar track onto the ground height field as a C2 trajectory,
//! with the ride dynamics of the vehicle's body.

use super::suspension::{self, BodyAttitude, RideInput, Suspension};
use super::{PlanarSample, PlanarTrack};
use crate::scene::Ground;
use crate::trajectory::{Knot, Trajectory};
use nalgebra::{Vector2, Vector3};

/// Wheel track as a fraction of the body width.
const TRACK_OVER_WIDTH: f64 = 0.85;
/// Wheelbase as a fraction of the body length (same as the bicycle model).
const WHEELBASE_OVER_LENGTH: f64 = 0.6;

/// 3-D C2 trajectory of the box centre over the ground; knots every
/// `track.dt_s`. A body with a [`Suspension`] (cars, trucks) rides on it:
/// the road under its four wheel contacts (wheelbase and track from the
/// box size) and its accelerations drive heave, pitch and roll
/// ([`suspension::ride`]). A body without one (cyclists, pedestrians) is
/// carried rigidly by the untextured ground: its centre's height and the
/// slopes under its wheelbase and track (no roughness texture: people and
/// bicycles do not rattle with the asphalt).
///
/// Every knot's rate and acceleration are finite differences of the sampled
/// values themselves (x, y, yaw, z, pitch, roll; [`Trajectory::sampled`],
/// which stores the values alone), not the model's instantaneous
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
    suspension: Option<&Suspension>,
) -> Trajectory {
    lift_onto(track, ground, &|_, _| 0.0, size_lwh_m, suspension)
}

/// [`lift_to_ground`] onto the ground raised by `raised(x, y)` (m), e.g.
/// by the sidewalks a pedestrian walks on.
pub fn lift_onto(
    track: &PlanarTrack,
    ground: &Ground,
    raised: &dyn Fn(f64, f64) -> f64,
    size_lwh_m: &Vector3<f64>,
    suspension: Option<&Suspension>,
) -> Trajectory {
    let half_wheelbase = 0.5 * WHEELBASE_OVER_LENGTH * size_lwh_m.x;
    let half_track = 0.5 * TRACK_OVER_WIDTH * size_lwh_m.y;
    let centre_height = 0.5 * size_lwh_m.z;
    // a hand-made track with a bad step or no samples must not panic
    let dt_s = if track.dt_s.is_finite() && track.dt_s > 0.0 {
        track.dt_s
    } else {
        0.01
    };
    if track.samples.is_empty() {
        return Trajectory::new(track.t0_s, dt_s, vec![Knot::default()]);
    }
    // the road under the four wheels: heave, pitch (rear above front
    // positive, i.e. nose down for R = Rz Ry Rx) and roll (left side up)
    let road = |s: &PlanarSample| -> RideInput {
        let (sin, cos) = s.yaw.sin_cos();
        let (fwd, left) = (Vector2::new(cos, sin), Vector2::new(-sin, cos));
        let p = Vector2::new(s.x, s.y);
        let at = |q: Vector2<f64>| {
            raised(q.x, q.y)
                + match suspension {
                    Some(_) => ground.height(q.x, q.y),
                    None => ground.untextured_height(q.x, q.y),
                }
        };
        let [fl, fr, rl, rr] = [
            at(p + fwd * half_wheelbase + left * half_track),
            at(p + fwd * half_wheelbase - left * half_track),
            at(p - fwd * half_wheelbase + left * half_track),
            at(p - fwd * half_wheelbase - left * half_track),
        ];
        // a sprung body rests on its four wheels; a rigid one stands where it is
        let heave_m = match suspension {
            Some(_) => 0.25 * (fl + fr + rl + rr),
            None => at(p),
        };
        RideInput {
            heave_m,
            pitch_rad: (0.5 * (rl + rr - fl - fr)).atan2(2.0 * half_wheelbase),
            roll_rad: (0.5 * (fl + rl - fr - rr)).atan2(2.0 * half_track),
            longitudinal_mps2: cos * s.ax_mps2 + sin * s.ay_mps2,
            lateral_mps2: -sin * s.ax_mps2 + cos * s.ay_mps2,
        }
    };
    let inputs: Vec<RideInput> = track.samples.iter().map(road).collect();
    let body: Vec<BodyAttitude> = match suspension {
        Some(suspension) => suspension::ride(suspension, &inputs, dt_s),
        None => inputs
            .iter()
            .map(|i| BodyAttitude {
                heave_m: i.heave_m,
                pitch_rad: i.pitch_rad,
                roll_rad: i.roll_rad,
            })
            .collect(),
    };
    let values = track
        .samples
        .iter()
        .zip(&body)
        .map(|(s, b)| {
            [
                s.x,
                s.y,
                b.heave_m + centre_height,
                s.yaw,
                b.pitch_rad,
                b.roll_rad,
            ]
        })
        .collect();
    Trajectory::sampled(track.t0_s, dt_s, values)
}
