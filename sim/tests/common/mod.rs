//! Helpers shared by the sim crate's test binaries.
//!
//! Jet arithmetic: exact value, first and second time derivative of analytic
//! paths, so tests can build trajectories whose rates are known in closed form.
#![allow(dead_code)] // each test binary uses a subset

use limot_sim::scene::Jet;

pub fn add(a: Jet, b: Jet) -> Jet {
    Jet::new(a.value + b.value, a.rate + b.rate, a.accel + b.accel)
}

pub fn scale(a: Jet, s: f64) -> Jet {
    Jet::new(a.value * s, a.rate * s, a.accel * s)
}

/// f(g(t)) given f, f', f'' evaluated at g.
pub fn compose(f0: f64, f1: f64, f2: f64, g: Jet) -> Jet {
    Jet::new(f0, f1 * g.rate, f2 * g.rate * g.rate + f1 * g.accel)
}

pub fn sin(g: Jet) -> Jet {
    let (s, c) = g.value.sin_cos();
    compose(s, c, -s, g)
}

pub fn cos(g: Jet) -> Jet {
    let (s, c) = g.value.sin_cos();
    compose(c, -s, -c, g)
}

pub fn atan(g: Jet) -> Jet {
    let d = 1.0 + g.value * g.value;
    compose(g.value.atan(), 1.0 / d, -2.0 * g.value / (d * d), g)
}

pub fn mul(a: Jet, b: Jet) -> Jet {
    Jet::new(
        a.value * b.value,
        a.rate * b.value + a.value * b.rate,
        a.accel * b.value + 2.0 * a.rate * b.rate + a.value * b.accel,
    )
}

pub fn time(t: f64) -> Jet {
    Jet::new(t, 1.0, 0.0)
}

pub fn constant(c: f64) -> Jet {
    Jet::new(c, 0.0, 0.0)
}
