//! Ride dynamics of a road vehicle's sprung body: heave, pitch and roll of
//! a rigid body on four equal spring-damper corners with rigid tyres.
//!
//! With equal corners the body's three modes decouple, and each follows
//! the same corner input mode of the road (mean wheel height, front-rear
//! and left-right height differences; the fourth, warp, moves no rigid
//! body) as a base-excited damped oscillator:
//!
//! ```text
//! x'' = w^2 (u + G a - x) + 2 zeta w (u' - x')
//! ```
//!
//! with `u` the road's mode, `a` the driving acceleration that loads the
//! mode (longitudinal for pitch: braking dips the nose; lateral for roll:
//! the body leans out of a turn) and `G` the static gradient. So pitch and
//! roll follow acceleration, braking and cornering with the body's own
//! lag and overshoot, and road roughness reaches the body (and every
//! sensor on it) filtered as a car filters it.

use limot_estimator::input::ObjectClass;

/// Standard gravity, for gradients given per g.
const G_MPS2: f64 = 9.80665;
/// Integration substep, s (w h < 0.02 for every body here).
const SUBSTEP_S: f64 = 1e-3;
/// Longest interval integrated in substeps; beyond it (a parked car's one
/// long sample gap) the substeps grow, which is exact for constant inputs.
const MAX_SUBSTEPS: usize = 1000;

/// One body's ride parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Suspension {
    /// Natural frequency of the heave mode, Hz.
    pub heave_hz: f64,
    /// Natural frequency of the pitch mode, Hz.
    pub pitch_hz: f64,
    /// Natural frequency of the roll mode, Hz.
    pub roll_hz: f64,
    /// Damping ratio of every mode.
    pub damping_ratio: f64,
    /// Static pitch per longitudinal deceleration (nose down), rad per m/s².
    pub pitch_per_decel_rad_per_mps2: f64,
    /// Static roll per lateral acceleration (leaning out of the turn), rad per m/s².
    pub roll_per_lateral_rad_per_mps2: f64,
}

impl Suspension {
    /// A passenger car: body modes 1.2-1.6 Hz, a quarter of critical
    /// damping, 2.5°/g of pitch and 4°/g of roll (typical sedan figures).
    pub fn car() -> Suspension {
        Suspension {
            heave_hz: 1.25,
            pitch_hz: 1.45,
            roll_hz: 1.6,
            damping_ratio: 0.25,
            pitch_per_decel_rad_per_mps2: 2.5_f64.to_radians() / G_MPS2,
            roll_per_lateral_rad_per_mps2: 4.0_f64.to_radians() / G_MPS2,
        }
    }

    /// A truck: stiffer springs, a high centre of mass (more roll).
    pub fn truck() -> Suspension {
        Suspension {
            heave_hz: 1.8,
            pitch_hz: 1.7,
            roll_hz: 1.2,
            damping_ratio: 0.2,
            pitch_per_decel_rad_per_mps2: 1.5_f64.to_radians() / G_MPS2,
            roll_per_lateral_rad_per_mps2: 6.0_f64.to_radians() / G_MPS2,
        }
    }

    /// The ride model of a class: cars and trucks ride on suspensions;
    /// cyclists and pedestrians are carried rigidly (None).
    pub fn for_class(class: ObjectClass) -> Option<Suspension> {
        match class {
            ObjectClass::Car => Some(Suspension::car()),
            ObjectClass::Truck => Some(Suspension::truck()),
            ObjectClass::Cyclist | ObjectClass::Pedestrian => None,
        }
    }
}

/// The road under the wheels and the driving accelerations at one sample.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RideInput {
    /// Mean height of the four wheel contacts, m.
    pub heave_m: f64,
    /// Pitch of the road under the wheels (rear above front positive), rad.
    pub pitch_rad: f64,
    /// Roll of the road under the wheels (left above right positive), rad.
    pub roll_rad: f64,
    /// Acceleration along the heading, m/s².
    pub longitudinal_mps2: f64,
    /// Acceleration to the left of the heading, m/s².
    pub lateral_mps2: f64,
}

/// The body's heave, pitch and roll at one sample (same conventions as
/// [`RideInput`]: pitch nose down positive, roll left side up positive).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BodyAttitude {
    /// Vertical displacement of the body, m.
    pub heave_m: f64,
    /// Pitch, nose down positive, rad.
    pub pitch_rad: f64,
    /// Roll, left side up positive, rad.
    pub roll_rad: f64,
}

/// One damped mode: position and rate.
#[derive(Debug, Clone, Copy)]
struct Mode {
    omega: f64,
    zeta: f64,
    x: f64,
    v: f64,
}

impl Mode {
    fn at_rest(hz: f64, zeta: f64, target: f64, target_rate: f64) -> Mode {
        Mode {
            omega: std::f64::consts::TAU * hz,
            zeta,
            x: target,
            v: target_rate,
        }
    }

    /// Semi-implicit Euler step towards `target` (road mode plus load) with
    /// the road mode's rate `u_rate`.
    fn step(&mut self, target: f64, u_rate: f64, h: f64) {
        let w = self.omega;
        let accel = w * w * (target - self.x) + 2.0 * self.zeta * w * (u_rate - self.v);
        self.v += accel * h;
        self.x += self.v * h;
    }
}

/// The body's response to `inputs` sampled every `dt_s`, starting in the
/// steady state of the first sample; one output per input.
pub fn ride(suspension: &Suspension, inputs: &[RideInput], dt_s: f64) -> Vec<BodyAttitude> {
    let mut out = Vec::with_capacity(inputs.len());
    let mut riding = Riding::new(suspension, dt_s);
    for input in inputs {
        riding.push(input, |attitude| out.push(attitude));
    }
    riding.finish(|attitude| out.push(attitude));
    out
}

/// [`ride`] one input at a time: the attitude of a sample is known once
/// the next one has come (the start rests on the first two inputs' rate),
/// the last one's at [`Riding::finish`] if there was only one.
#[derive(Debug, Clone)]
pub(crate) struct Riding {
    suspension: Suspension,
    dt_s: f64,
    substeps: usize,
    /// The first input, until the second comes.
    first: Option<RideInput>,
    /// The previous input and the modes there, from the second input on.
    state: Option<(RideInput, [Mode; 3])>,
}

impl Riding {
    /// Ready for the first input.
    pub(crate) fn new(suspension: &Suspension, dt_s: f64) -> Riding {
        Riding {
            suspension: *suspension,
            dt_s,
            substeps: ((dt_s / SUBSTEP_S).ceil() as usize).clamp(1, MAX_SUBSTEPS),
            first: None,
            state: None,
        }
    }

    fn pitch_load(&self, i: &RideInput) -> f64 {
        i.pitch_rad - self.suspension.pitch_per_decel_rad_per_mps2 * i.longitudinal_mps2
    }

    fn roll_load(&self, i: &RideInput) -> f64 {
        i.roll_rad + self.suspension.roll_per_lateral_rad_per_mps2 * i.lateral_mps2
    }

    /// The modes at rest at `first`, moving with the road's rate towards
    /// `second` (none without a second input).
    fn at_rest(&self, first: &RideInput, second: Option<&RideInput>) -> [Mode; 3] {
        let s = &self.suspension;
        let rate = |f: fn(&RideInput) -> f64| match second {
            Some(second) => (f(second) - f(first)) / self.dt_s,
            None => 0.0,
        };
        let z = s.damping_ratio;
        [
            Mode::at_rest(s.heave_hz, z, first.heave_m, rate(|i| i.heave_m)),
            Mode::at_rest(s.pitch_hz, z, self.pitch_load(first), rate(|i| i.pitch_rad)),
            Mode::at_rest(s.roll_hz, z, self.roll_load(first), rate(|i| i.roll_rad)),
        ]
    }

    /// Takes the next input; `out` gets the attitudes it completes (none
    /// for the first input, two for the second, one after).
    pub(crate) fn push(&mut self, input: &RideInput, mut out: impl FnMut(BodyAttitude)) {
        let (a, mut modes) = match (self.state.take(), self.first.take()) {
            (Some(state), _) => state,
            (None, None) => {
                self.first = Some(*input);
                return;
            }
            (None, Some(first)) => {
                let modes = self.at_rest(&first, Some(input));
                out(attitude(&modes));
                (first, modes)
            }
        };
        let b = input;
        let targets = [
            (a.heave_m, b.heave_m),
            (self.pitch_load(&a), self.pitch_load(b)),
            (self.roll_load(&a), self.roll_load(b)),
        ];
        // the damper sees the road's rate, not the load's
        let dt_s = self.dt_s;
        let road_rates = [
            (b.heave_m - a.heave_m) / dt_s,
            (b.pitch_rad - a.pitch_rad) / dt_s,
            (b.roll_rad - a.roll_rad) / dt_s,
        ];
        let substeps = self.substeps;
        let h = dt_s / substeps as f64;
        for j in 1..=substeps {
            let f = j as f64 / substeps as f64;
            for (m, ((t0, t1), u_rate)) in modes.iter_mut().zip(targets.iter().zip(road_rates)) {
                m.step(t0 + (t1 - t0) * f, u_rate, h);
            }
        }
        out(attitude(&modes));
        self.state = Some((*b, modes));
    }

    /// Ends the inputs: `out` gets the attitude of a lone first input.
    pub(crate) fn finish(self, mut out: impl FnMut(BodyAttitude)) {
        if let Some(first) = self.first {
            out(attitude(&self.at_rest(&first, None)));
        }
    }
}

fn attitude(m: &[Mode; 3]) -> BodyAttitude {
    BodyAttitude {
        heave_m: m[0].x,
        pitch_rad: m[1].x,
        roll_rad: m[2].x,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn constant(input: RideInput, n: usize) -> Vec<RideInput> {
        vec![input; n]
    }

    #[test]
    fn steady_braking_and_cornering_settle_at_the_static_gradients() {
        let s = Suspension::car();
        // 0.5 g braking on a level road: the nose dips 1.25°
        let mut inputs = constant(RideInput::default(), 20);
        inputs.extend(constant(
            RideInput {
                longitudinal_mps2: -0.5 * G_MPS2,
                lateral_mps2: 0.3 * G_MPS2,
                ..RideInput::default()
            },
            600,
        ));
        let out = ride(&s, &inputs, 0.01);
        assert_eq!(out.len(), inputs.len());
        assert_eq!(out[0], BodyAttitude::default());
        let last = out.last().unwrap();
        assert!(
            (last.pitch_rad.to_degrees() - 1.25).abs() < 1e-3,
            "{last:?}"
        );
        // a left turn (lateral acceleration to the left) rolls the body to
        // the right: left side up
        assert!((last.roll_rad.to_degrees() - 1.2).abs() < 1e-3, "{last:?}");
        // under-damped: the step overshoots by exp(-pi zeta / sqrt(1 - zeta^2))
        let peak = out.iter().map(|a| a.pitch_rad).fold(0.0, f64::max);
        let z = s.damping_ratio;
        let want = 1.0 + (-std::f64::consts::PI * z / (1.0 - z * z).sqrt()).exp();
        let got = peak / last.pitch_rad;
        // the load ramps over one 10 ms sample, close to a step for a 1.45 Hz mode
        assert!((got - want).abs() < 0.03, "overshoot {got} vs {want}");
    }

    #[test]
    fn slow_road_is_followed_and_fast_road_is_filtered() {
        let s = Suspension::car();
        let dt = 0.01;
        let response = |hz: f64| {
            let inputs: Vec<RideInput> = (0..3000)
                .map(|k| RideInput {
                    heave_m: 0.01 * (std::f64::consts::TAU * hz * k as f64 * dt).sin(),
                    ..RideInput::default()
                })
                .collect();
            let out = ride(&s, &inputs, dt);
            // amplitude over the last second (transients gone)
            out[2000..]
                .iter()
                .map(|a| a.heave_m.abs())
                .fold(0.0, f64::max)
                / 0.01
        };
        let (slow, resonant, fast) = (response(0.1), response(s.heave_hz), response(15.0));
        assert!((slow - 1.0).abs() < 0.02, "slow {slow}");
        // base excitation at resonance: sqrt(1 + (2 zeta)^2) / (2 zeta)
        let z = s.damping_ratio;
        let want = (1.0 + 4.0 * z * z).sqrt() / (2.0 * z);
        assert!(
            (resonant - want).abs() < 0.1 * want,
            "resonant {resonant} vs {want}"
        );
        assert!(fast < 0.1, "fast {fast}");
    }

    #[test]
    fn a_parked_car_in_one_long_sample_stays_at_rest() {
        let s = Suspension::truck();
        let input = RideInput {
            heave_m: 0.31,
            pitch_rad: 0.01,
            roll_rad: -0.02,
            ..RideInput::default()
        };
        let out = ride(&s, &[input, input], 60.0);
        for a in out {
            assert!((a.heave_m - 0.31).abs() < 1e-12);
            assert!((a.pitch_rad - 0.01).abs() < 1e-12);
            assert!((a.roll_rad + 0.02).abs() < 1e-12);
        }
        assert!(ride(&s, &[], 0.01).is_empty());
    }
}
