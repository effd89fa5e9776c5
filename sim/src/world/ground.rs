//! Exact f64 ray intersection with the analytic ground height field.

use super::{GroundSample, ShapeHit};
use crate::scene::Ground;
use nalgebra::{Point3, Unit, Vector3};

/// Rays descending at least this steeply (sin of the depression) trust the
/// fast path's crossing beyond the maximum range and start from a
/// neighbouring ray's range; shallower ones, and all the fast path leaves
/// unsettled, go the safe way. The cast uses the same bound to meet the
/// ground before the objects: a shallower ray may skip its ground search
/// (and hand the next column no range) because its search ignores the
/// start anyway.
pub(super) const FAST_PATH_MIN_DESCENT: f64 = 0.05;

/// Clearance [`clears_ground`] asks beyond its bound, m: far above the
/// rounding of the bound's few operations.
const CLEARANCE_MARGIN_M: f64 = 1e-6;

/// A bound of |d²h/ds²| of the terrain (plane and undulations) along the
/// ray's horizontal direction.
fn curvature_bound_along(ground: &Ground, dir: &Vector3<f64>) -> f64 {
    ground
        .undulations
        .iter()
        .map(|w| {
            let k_dot_d = w.wave_vector.x * dir.x + w.wave_vector.y * dir.y;
            w.amplitude_m.abs() * k_dot_d * k_dot_d
        })
        .sum()
}

/// Whether the ray surely stays above the ground over `[0, range_m]`, from
/// the terrain's (plane and undulations, no detail) height and gradient
/// under the origin: along the ray the terrain lies below its tangent at
/// the origin plus `m s² / 2` (`m` bounds the undulations' curvature along
/// the ray), and the detail raises it by at most its bound, so the ray's
/// height over that concave bound is checked at both ends. False when
/// unsure, never false-positive.
pub(super) fn clears_ground(
    ground: &Ground,
    terrain_under_origin: &GroundSample,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    range_m: f64,
) -> bool {
    let (t0, tx, ty) = *terrain_under_origin;
    let curvature_bound = curvature_bound_along(ground, dir);
    let at_origin = origin.z - t0 - ground.detail_bound_m() - CLEARANCE_MARGIN_M;
    let at_range = at_origin + (dir.z - tx * dir.x - ty * dir.y) * range_m
        - 0.5 * curvature_bound * range_m * range_m;
    at_origin > 0.0 && at_range > 0.0
}

/// Nearest ground hit within `max_range_m` and the upward normal there.
/// The terrain (plane, undulations) is intersected by
/// [`intersect_terrain`]; the road's detail (crown, roughness texture) then
/// moves that root by Newton steps on the detail alone (the terrain
/// linearised at its root: over the centimetres to metres the detail moves
/// a hit, the terrain's curvature changes its height by micrometres) and
/// one exact polish on the whole surface. For rays steeper than the
/// detail's slopes (all but grazing rays beyond ~50 m on a typical road)
/// this is the first crossing; a grazing ray may see the crossing next to
/// the terrain's and miss a bump earlier along it. Most rays settle sooner,
/// by Newton steps on the whole surface; a steep ray's steps start at
/// `start_m` (a neighbouring ray's range, say; NaN: none) if they settle
/// from there, else from the tangent plane under the origin.
pub(super) fn intersect_ground(
    ground: &Ground,
    undulation_bound_m: f64,
    origin: &Point3<f64>,
    under_origin: &GroundSample,
    dir: &Vector3<f64>,
    max_range_m: f64,
    start_m: f64,
) -> Option<ShapeHit> {
    if !ground.has_detail() {
        let (s, (_, gx, gy)) =
            intersect_terrain(ground, undulation_bound_m, origin, dir, max_range_m)?;
        return Some((s, Unit::new_normalize(Vector3::new(-gx, -gy, 1.0))));
    }
    // the detail may lower the surface under a ray that meets the terrain
    // just beyond max range: search the terrain that much farther
    let margin_m = (ground.detail_bound_m() / dir.z.abs().max(0.005)).min(60.0);
    let at = |s: f64| origin + dir * s;
    let whole = |s: f64| {
        let p = at(s);
        let (h, hx, hy) = ground.height_and_gradient(p.x, p.y);
        (p.z - h, dir.z - hx * dir.x - hy * dir.y, (hx, hy))
    };
    // fast path: Newton on the whole surface from the tangent plane under
    // the sensor; every ray steeper than the surface's slopes meets it once,
    // so a steep ray may start anywhere (from `start_m` if it settles there)
    let (h0, hx0, hy0) = *under_origin;
    let (f0, df0) = (origin.z - h0, dir.z - hx0 * dir.x - hy0 * dir.y);
    if f0 <= 0.0 {
        return None;
    }
    if df0 < 0.0 {
        let beyond = max_range_m + margin_m;
        let steep = dir.z < -FAST_PATH_MIN_DESCENT;
        let newton = |start: f64| safeguarded_newton(whole, start, 1e-9, 0.0, beyond);
        let settled = (steep && start_m > 0.0 && start_m <= beyond)
            .then(|| newton(start_m))
            .flatten()
            .or_else(|| newton(-f0 / df0));
        if let Some((s, (gx, gy))) = settled {
            if (0.0..=max_range_m).contains(&s) {
                return Some((s, Unit::new_normalize(Vector3::new(-gx, -gy, 1.0))));
            }
            if s > max_range_m && steep {
                return None;
            }
        }
    }
    let (s0, (_, gx0, gy0)) = intersect_terrain(
        ground,
        undulation_bound_m,
        origin,
        dir,
        max_range_m + margin_m,
    )?;
    // terrain linearised at s0: g(s) ~ g0' (s - s0) with g = z - terrain
    let dg0 = dir.z - gx0 * dir.x - gy0 * dir.y;
    if dg0 >= 0.0 {
        return None;
    }
    let detail_only = |s: f64| {
        let p = at(s);
        let (r, rx, ry) = ground.detail_height_and_gradient(p.x, p.y);
        (dg0 * (s - s0) - r, dg0 - rx * dir.x - ry * dir.y, ())
    };
    // cheap steps on the detail first, then a polish on the whole surface:
    // from a good start one Newton step squares the error (|f| < 1e-6 m
    // leaves ~1e-12 m), else safeguarded steps
    let near =
        safeguarded_newton(detail_only, s0, 1e-6, f64::NAN, f64::INFINITY).map_or(s0, |(s, _)| s);
    let (f, df, gradient) = whole(near);
    let (s, (gx, gy)) = if f.abs() < 1e-6 && df < 0.0 {
        (near - f / df, gradient)
    } else {
        match safeguarded_newton(whole, near, 1e-9, f64::NAN, f64::INFINITY) {
            Some(hit) => hit,
            None => {
                let s = march_to_crossing(ground, origin, dir, s0, dg0, max_range_m + margin_m)?;
                (s, whole(s).2)
            }
        }
    };
    if !(0.0..=max_range_m).contains(&s) {
        return None;
    }
    Some((s, Unit::new_normalize(Vector3::new(-gx, -gy, 1.0))))
}

/// Newton steps shorter than this end the iteration without a check: the
/// error after one is ~ curvature x step², far below a micrometre.
const FINAL_STEP_M: f64 = 1e-5;

/// A root of `f` near `start` by Newton steps (`f_df` gives f, f' and a
/// payload), kept inside the bracket once a sign change is seen (a bilinear
/// texture cell edge can make plain Newton cycle), bisecting when a step
/// would leave it; with the payload of the evaluation there. `above` is a
/// point known to have f > 0 (NaN if none). None when it does not settle to
/// |f| < `tolerance` in 24 steps, or when, unbracketed, it steps beyond
/// `beyond` still above the surface.
fn safeguarded_newton<T>(
    f_df: impl Fn(f64) -> (f64, f64, T),
    start: f64,
    tolerance: f64,
    mut above: f64,
    beyond: f64,
) -> Option<(f64, T)> {
    let mut s = start;
    let mut below = f64::NAN;
    for _ in 0..24 {
        let (f, df, payload) = f_df(s);
        if f.abs() < tolerance {
            return Some((s, payload));
        }
        // a last step this small squares the error: take it unchecked
        if df < 0.0 && f.abs() < FINAL_STEP_M * -df {
            return Some((s - f / df, payload));
        }
        if f > 0.0 && s > beyond && below.is_nan() {
            return None;
        }
        if f > 0.0 {
            above = s;
        } else {
            below = s;
        }
        let newton = if df < 0.0 { s - f / df } else { f64::NAN };
        s = if above.is_finite() && below.is_finite() {
            let (lo, hi) = (above.min(below), above.max(below));
            if newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            }
        } else if newton.is_finite() {
            newton
        } else {
            return None;
        };
    }
    None
}

/// The fallback when Newton does not settle (a ray nearly tangent to a
/// detail slope): sphere tracing from where the ray can first meet the
/// detailed surface (each step `f / L` with `L` bounding the rate at which
/// the surface can rise towards the ray, so no crossing is passed), then
/// bisection over the first sign change. `dg0` is the ray's descent rate
/// over the terrain at `s0`.
fn march_to_crossing(
    ground: &Ground,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    s0: f64,
    dg0: f64,
    max_range_m: f64,
) -> Option<f64> {
    const MAX_STEPS: usize = 400;
    const MIN_STEP_M: f64 = 0.01;
    let f = |s: f64| {
        let p = origin + dir * s;
        p.z - ground.height(p.x, p.y)
    };
    // the terrain is linearised at s0, as in the Newton steps
    let lipschitz = -dg0 + ground.detail_slope_bound() * dir.xy().norm() + 1e-9;
    let raise = ground.roughness.as_ref().map_or(0.0, |r| r.bound_m());
    let mut lo = (s0 - raise / -dg0).max(0.0);
    let mut f_lo = f(lo);
    if f_lo <= 0.0 {
        return None;
    }
    let mut hi = lo;
    for _ in 0..MAX_STEPS {
        hi = lo + (f_lo / lipschitz).max(MIN_STEP_M);
        if hi > max_range_m {
            return None;
        }
        let f_hi = f(hi);
        if f_hi <= 0.0 {
            break;
        }
        (lo, f_lo) = (hi, f_hi);
    }
    if f(hi) > 0.0 {
        return None;
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if f(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

/// First root of z(s) - h(x(s), y(s)) along the ray within `max_range_m`
/// for the terrain h (plane and undulations, no detail), with h and its
/// gradient there. `undulation_bound_m` bounds |h - plane|. The step from s is the first root of
/// the quadratic lower bound f(s) + f'(s) d - M d^2 / 2 (M bounds |f''|),
/// so it never jumps over a crossing and is Newton-fast near a transversal
/// root.
fn intersect_terrain(
    ground: &Ground,
    undulation_bound_m: f64,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    max_range_m: f64,
) -> Option<(f64, (f64, f64, f64))> {
    const TOLERANCE_M: f64 = 1e-9;
    const MAX_STEPS: usize = 200;
    // plane part: f_plane(s) = a + b s; f lies within +-U of it
    let a = origin.z - ground.base_height_m - ground.slope.x * origin.x - ground.slope.y * origin.y;
    let b = dir.z - ground.slope.x * dir.x - ground.slope.y * dir.y;
    let u = undulation_bound_m;
    let curvature_bound = curvature_bound_along(ground, dir);
    let surface = |s: f64| {
        let p = origin + dir * s;
        let hg = ground.terrain_height_and_gradient(p.x, p.y);
        (p.z - hg.0, dir.z - hg.1 * dir.x - hg.2 * dir.y, hg)
    };
    // no crossing is possible where a + b s > U
    let mut s = 0.0_f64;
    if a > u {
        if b >= 0.0 {
            return None;
        }
        s = (u - a) / b;
    }
    if s > max_range_m {
        return None;
    }
    let (mut f, mut df, mut hg) = surface(s);
    if s == 0.0 && f <= 0.0 {
        // origin at or below the ground
        return None;
    }
    let mut steps = 0;
    while f > TOLERANCE_M {
        steps += 1;
        if steps > MAX_STEPS {
            // grazing a crest (f' ~ 0): too shallow to matter for a sensor
            return None;
        }
        let m = curvature_bound;
        let step = if m <= 0.0 {
            if df >= 0.0 {
                return None;
            }
            f / -df
        } else {
            let root = (df * df + 2.0 * m * f).sqrt();
            if df <= 0.0 {
                2.0 * f / (root - df)
            } else {
                (df + root) / m
            }
        };
        s += step;
        if s > max_range_m {
            return None;
        }
        (f, df, hg) = surface(s);
        if step < TOLERANCE_M * 1e-3 && f > TOLERANCE_M {
            // stalled on a tangency
            return None;
        }
    }
    // f may be slightly negative after the exact planar step; one Newton
    // correction polishes either way (the gradient before it is kept: the
    // correction is below the tolerance)
    if df.abs() > 1e-12 {
        s -= f / df;
    }
    if !(0.0..=max_range_m).contains(&s) {
        return None;
    }
    Some((s, hg))
}
