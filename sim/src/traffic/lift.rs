//! Lifting a planar track onto the ground height field as a C2 trajectory,
//! with the ride dynamics of the vehicle's body.

use super::suspension::{BodyAttitude, RideInput, Riding, Suspension};
use super::{PlanarSample, PlanarTrack};
use crate::scene::Ground;
use crate::trajectory::{Knot, Trajectory};
use nalgebra::{Vector2, Vector3};
use std::collections::VecDeque;

/// Wheel track as a fraction of the body width.
const TRACK_OVER_WIDTH: f64 = 0.85;
/// Wheelbase as a fraction of the body length (same as the bicycle model).
const WHEELBASE_OVER_LENGTH: f64 = 0.6;

/// 3-D C2 trajectory of the box centre over the ground; knots every
/// `track.dt_s`. A body with a [`Suspension`] (cars, trucks) rides on it:
/// the road under its four wheel contacts (wheelbase and track from the
/// box size) and its accelerations drive heave, pitch and roll
/// ([`super::ride`]). A body without one (cyclists, pedestrians) is
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
    let mut lifting = Lifting::new(
        track.t0_s,
        track.dt_s,
        track.samples.len(),
        ground,
        raised,
        size_lwh_m,
        suspension,
    );
    for sample in &track.samples {
        lifting.push(sample);
    }
    lifting.finish()
}

/// [`lift_onto`] one sample at a time, as the traffic simulation records
/// them: only the lifted values are kept, never the planar track.
pub(crate) struct Lifting<'a> {
    ground: &'a Ground,
    raised: &'a dyn Fn(f64, f64) -> f64,
    sprung: bool,
    half_wheelbase: f64,
    half_track: f64,
    centre_height: f64,
    t0_s: f64,
    dt_s: f64,
    /// The body's ride, for a body with a suspension.
    riding: Option<Riding>,
    /// x, y, yaw of the samples whose ride is not known yet.
    waiting: VecDeque<[f64; 3]>,
    /// The lifted values so far.
    values: Vec<[f64; 6]>,
}

impl<'a> Lifting<'a> {
    /// Ready for the samples of a track starting at `t0_s`, one every
    /// `dt_s` (read as 0.01 s if not positive and finite), with room for
    /// `samples` of them.
    pub(crate) fn new(
        t0_s: f64,
        dt_s: f64,
        samples: usize,
        ground: &'a Ground,
        raised: &'a dyn Fn(f64, f64) -> f64,
        size_lwh_m: &Vector3<f64>,
        suspension: Option<&Suspension>,
    ) -> Lifting<'a> {
        // a hand-made track with a bad step or no samples must not panic
        let dt_s = if dt_s.is_finite() && dt_s > 0.0 {
            dt_s
        } else {
            0.01
        };
        Lifting {
            ground,
            raised,
            sprung: suspension.is_some(),
            half_wheelbase: 0.5 * WHEELBASE_OVER_LENGTH * size_lwh_m.x,
            half_track: 0.5 * TRACK_OVER_WIDTH * size_lwh_m.y,
            centre_height: 0.5 * size_lwh_m.z,
            t0_s,
            dt_s,
            riding: suspension.map(|s| Riding::new(s, dt_s)),
            waiting: VecDeque::with_capacity(2),
            values: Vec::with_capacity(samples),
        }
    }

    /// The road under the four wheels: heave, pitch (rear above front
    /// positive, i.e. nose down for R = Rz Ry Rx) and roll (left side up).
    fn road(&self, s: &PlanarSample) -> RideInput {
        let (sin, cos) = s.yaw.sin_cos();
        let (fwd, left) = (Vector2::new(cos, sin), Vector2::new(-sin, cos));
        let p = Vector2::new(s.x, s.y);
        let at = |q: Vector2<f64>| {
            (self.raised)(q.x, q.y)
                + if self.sprung {
                    self.ground.height(q.x, q.y)
                } else {
                    self.ground.untextured_height(q.x, q.y)
                }
        };
        let (half_wheelbase, half_track) = (self.half_wheelbase, self.half_track);
        let [fl, fr, rl, rr] = [
            at(p + fwd * half_wheelbase + left * half_track),
            at(p + fwd * half_wheelbase - left * half_track),
            at(p - fwd * half_wheelbase + left * half_track),
            at(p - fwd * half_wheelbase - left * half_track),
        ];
        // a sprung body rests on its four wheels; a rigid one stands where it is
        let heave_m = if self.sprung {
            0.25 * (fl + fr + rl + rr)
        } else {
            at(p)
        };
        RideInput {
            heave_m,
            pitch_rad: (0.5 * (rl + rr - fl - fr)).atan2(2.0 * half_wheelbase),
            roll_rad: (0.5 * (fl + rl - fr - rr)).atan2(2.0 * half_track),
            longitudinal_mps2: cos * s.ax_mps2 + sin * s.ay_mps2,
            lateral_mps2: -sin * s.ax_mps2 + cos * s.ay_mps2,
        }
    }

    /// Takes the next sample.
    pub(crate) fn push(&mut self, sample: &PlanarSample) {
        let input = self.road(sample);
        self.waiting.push_back([sample.x, sample.y, sample.yaw]);
        let Lifting {
            riding,
            waiting,
            values,
            centre_height,
            ..
        } = self;
        let mut lifted = lifted_with(waiting, values, *centre_height);
        match riding {
            Some(riding) => riding.push(&input, lifted),
            // a rigid body takes the road's attitude
            None => lifted(BodyAttitude {
                heave_m: input.heave_m,
                pitch_rad: input.pitch_rad,
                roll_rad: input.roll_rad,
            }),
        }
    }

    /// The lifted trajectory (a body at rest at the origin without samples).
    pub(crate) fn finish(mut self) -> Trajectory {
        if let Some(riding) = self.riding.take() {
            riding.finish(lifted_with(
                &mut self.waiting,
                &mut self.values,
                self.centre_height,
            ));
        }
        if self.values.is_empty() {
            return Trajectory::new(self.t0_s, self.dt_s, vec![Knot::default()]);
        }
        Trajectory::sampled(self.t0_s, self.dt_s, self.values)
    }
}

/// Completes the oldest waiting sample with its body attitude.
fn lifted_with<'v>(
    waiting: &'v mut VecDeque<[f64; 3]>,
    values: &'v mut Vec<[f64; 6]>,
    centre_height: f64,
) -> impl FnMut(BodyAttitude) + 'v {
    move |b| {
        let [x, y, yaw] = waiting
            .pop_front()
            .expect("every body attitude belongs to a waiting sample");
        values.push([
            x,
            y,
            b.heave_m + centre_height,
            yaw,
            b.pitch_rad,
            b.roll_rad,
        ]);
    }
}
