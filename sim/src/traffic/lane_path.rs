//! Lane centrelines in the ground plane: dense, arc-length parametrised
//! polylines with a unit tangent at every vertex. Between vertices the curve is
//! a cubic Hermite segment, so straight and constant-curvature pieces are
//! reproduced to far below a millimetre, and the heading (stored unwrapped) is
//! interpolated linearly in arc length, which is exact on straights and arcs.

use super::TrafficError;
use limot_estimator::geometry::wrap_angle_rad;
use nalgebra::{Point2, Vector2};
use std::collections::HashMap;

/// Maximum vertex spacing of the dense polyline.
const MAX_SPACING_M: f64 = 0.5;
/// Cell size of the spatial hash used by local projections.
const GRID_CELL_M: f64 = 8.0;

/// A lane centreline in the ground plane (x, y), arc-length parametrised, built from
/// straight and constant-curvature pieces, optionally offset sideways (parallel lanes).
#[derive(Debug, Clone, PartialEq)]
pub struct LanePath {
    points: Vec<Point2<f64>>,
    /// Cumulative arc length at every vertex, starting at 0.
    s_m: Vec<f64>,
    /// Unwrapped heading at every vertex.
    heading_rad: Vec<f64>,
    /// Unit tangent `(cos, sin)` of the heading at every vertex.
    tangent: Vec<Vector2<f64>>,
    /// Spatial hash: cell -> indices of the segments whose bounding box touches it.
    grid: HashMap<(i64, i64), Vec<u32>>,
}

/// One piece of a lane built by [`LanePath::from_pieces`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PathPiece {
    /// A straight segment.
    Straight {
        /// Length, m.
        length_m: f64,
    },
    /// +curvature = left turn.
    /// A circular arc.
    Arc {
        /// Length, m.
        length_m: f64,
        /// Signed curvature, 1/m.
        curvature_1pm: f64,
    },
}

impl PathPiece {
    /// Length along the reference line, m.
    pub fn length_m(&self) -> f64 {
        match *self {
            PathPiece::Straight { length_m } | PathPiece::Arc { length_m, .. } => length_m,
        }
    }

    /// The same piece, at most `max_length_m` long.
    pub fn cut_to(&self, max_length_m: f64) -> PathPiece {
        match *self {
            PathPiece::Straight { length_m } => PathPiece::Straight {
                length_m: length_m.min(max_length_m),
            },
            PathPiece::Arc {
                length_m,
                curvature_1pm,
            } => PathPiece::Arc {
                length_m: length_m.min(max_length_m),
                curvature_1pm,
            },
        }
    }
}

fn invalid(reason: String) -> TrafficError {
    TrafficError::InvalidPath { reason }
}

impl LanePath {
    /// Builds a lane from pieces along a reference line starting at `start` with
    /// `heading_rad`; `lateral_offset_m` (+ = left) shifts the whole lane sideways,
    /// so arcs get curvature k / (1 - k d) and length L (1 - k d).
    ///
    /// # Errors
    /// [`TrafficError::InvalidPath`] for a non-finite start, heading, offset
    /// or curvature, no pieces, a non-positive length, or an offset that
    /// reaches an arc's centre of curvature.
    pub fn from_pieces(
        start: Point2<f64>,
        heading_rad: f64,
        pieces: &[PathPiece],
        lateral_offset_m: f64,
    ) -> Result<LanePath, TrafficError> {
        if !(start.x.is_finite() && start.y.is_finite()) {
            return Err(invalid(format!("start point {start} is not finite")));
        }
        if !heading_rad.is_finite() {
            return Err(invalid(format!("heading_rad {heading_rad} is not finite")));
        }
        if !lateral_offset_m.is_finite() {
            return Err(invalid(format!(
                "lateral_offset_m {lateral_offset_m} is not finite"
            )));
        }
        if pieces.is_empty() {
            return Err(invalid("no pieces".into()));
        }
        let d = lateral_offset_m;
        let normal = |h: f64| Vector2::new(-h.sin(), h.cos());
        // reference-line state at the start of the current piece
        let mut p_ref = start;
        let mut h = heading_rad;
        let mut points = vec![start + normal(h) * d];
        let mut s_m = vec![0.0];
        let mut heading = vec![h];
        for (i, piece) in pieces.iter().enumerate() {
            let (len, k) = match *piece {
                PathPiece::Straight { length_m } => (length_m, 0.0),
                PathPiece::Arc {
                    length_m,
                    curvature_1pm,
                } => (length_m, curvature_1pm),
            };
            if !(len.is_finite() && len > 0.0) {
                return Err(invalid(format!(
                    "piece {i}: length_m {len} must be finite and > 0"
                )));
            }
            if !k.is_finite() {
                return Err(invalid(format!(
                    "piece {i}: curvature_1pm {k} is not finite"
                )));
            }
            let stretch = 1.0 - k * d;
            if stretch <= 1e-6 {
                return Err(invalid(format!(
                    "piece {i}: lateral offset {d} m reaches the centre of curvature (radius {} m)",
                    1.0 / k
                )));
            }
            let n = (len * stretch / MAX_SPACING_M).ceil().max(1.0) as usize;
            let s0 = *s_m.last().unwrap_or(&0.0);
            for j in 1..=n {
                let u = len * j as f64 / n as f64; // reference arc length inside the piece
                let (pr, hr) = advance(p_ref, h, k, u);
                points.push(pr + normal(hr) * d);
                s_m.push(s0 + u * stretch);
                heading.push(hr);
            }
            let (pr, hr) = advance(p_ref, h, k, len);
            p_ref = pr;
            h = hr;
        }
        Ok(LanePath::from_dense(points, s_m, heading))
    }

    /// Builds a lane through `points` (at least two, consecutive points distinct),
    /// with tangents from neighbouring points and densified to <= 0.5 m spacing.
    ///
    /// # Errors
    /// [`TrafficError::InvalidPath`] for fewer than two points, non-finite
    /// points or repeated consecutive points.
    pub fn from_points(points: &[Point2<f64>]) -> Result<LanePath, TrafficError> {
        if points.len() < 2 {
            return Err(invalid(format!(
                "from_points needs at least 2 points, got {}",
                points.len()
            )));
        }
        for (i, p) in points.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite()) {
                return Err(invalid(format!("point {i} = {p} is not finite")));
            }
        }
        for i in 1..points.len() {
            if (points[i] - points[i - 1]).norm() < 1e-6 {
                return Err(invalid(format!("points {} and {i} coincide", i - 1)));
            }
        }
        let n = points.len();
        // unit tangent at each input point (Catmull-Rom style)
        let mut tangents: Vec<Vector2<f64>> = (0..n)
            .map(|i| {
                let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
                let v = points[b] - points[a];
                let norm = v.norm();
                if norm < 1e-9 {
                    // the path doubles back here: use the outgoing (or incoming) chord
                    let (a, b) = if i + 1 < n { (i, i + 1) } else { (i - 1, i) };
                    (points[b] - points[a]).normalize()
                } else {
                    v / norm
                }
            })
            .collect();
        if n >= 3 {
            // end tangents mirrored about the end chords (exact on circles)
            let first = (points[1] - points[0]).normalize();
            tangents[0] = (first * 2.0 * first.dot(&tangents[1]) - tangents[1]).normalize();
            let last = (points[n - 1] - points[n - 2]).normalize();
            tangents[n - 1] =
                (last * 2.0 * last.dot(&tangents[n - 2]) - tangents[n - 2]).normalize();
        }
        let mut dense = vec![points[0]];
        let mut dense_tangent = vec![tangents[0]];
        for i in 0..n - 1 {
            let chord = (points[i + 1] - points[i]).norm();
            let m = (chord / MAX_SPACING_M).ceil().max(1.0) as usize;
            for j in 1..=m {
                let u = j as f64 / m as f64;
                let (p, dp) = hermite(
                    &points[i],
                    &(tangents[i] * chord),
                    &points[i + 1],
                    &(tangents[i + 1] * chord),
                    u,
                );
                dense.push(p);
                let norm = dp.norm();
                dense_tangent.push(if norm > 1e-12 {
                    dp / norm
                } else {
                    tangents[i + 1]
                });
            }
        }
        let mut s_m = vec![0.0];
        for i in 1..dense.len() {
            let ds = (dense[i] - dense[i - 1]).norm();
            if ds < 1e-9 {
                return Err(invalid(format!(
                    "degenerate geometry near point {} (cusp)",
                    i / 2
                )));
            }
            s_m.push(s_m[i - 1] + ds);
        }
        let mut heading = Vec::with_capacity(dense.len());
        let mut prev = dense_tangent[0].y.atan2(dense_tangent[0].x);
        for t in &dense_tangent {
            let h = t.y.atan2(t.x);
            let unwrapped = prev + wrap_angle_rad(h - prev);
            heading.push(unwrapped);
            prev = unwrapped;
        }
        Ok(LanePath::from_dense(dense, s_m, heading))
    }

    fn from_dense(points: Vec<Point2<f64>>, s_m: Vec<f64>, heading_rad: Vec<f64>) -> LanePath {
        let mut grid: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
        for i in 0..points.len() - 1 {
            let (a, b) = (points[i], points[i + 1]);
            let (lo, hi) = (cell_of(&a.inf(&b)), cell_of(&a.sup(&b)));
            for cx in lo.0..=hi.0 {
                for cy in lo.1..=hi.1 {
                    grid.entry((cx, cy)).or_default().push(i as u32);
                }
            }
        }
        let tangent = heading_rad.iter().map(|&h| unit(h)).collect();
        LanePath {
            points,
            s_m,
            heading_rad,
            tangent,
            grid,
        }
    }

    /// Total arc length of the path, m.
    pub fn length_m(&self) -> f64 {
        *self.s_m.last().unwrap_or(&0.0)
    }

    /// Highest speed at arc length `s_m` from which a vehicle braking at
    /// `decel_mps2` keeps speed^2 * |curvature| <= `lateral_accel_mps2` on every
    /// segment in [s_m, s_m + horizon_m] (the curvature of a segment is its
    /// heading change over its length); infinite if that stretch is straight.
    pub(crate) fn curve_speed_limit_mps(
        &self,
        s_m: f64,
        horizon_m: f64,
        lateral_accel_mps2: f64,
        decel_mps2: f64,
    ) -> f64 {
        let s = s_m.clamp(0.0, self.length_m());
        let mut limit = f64::INFINITY;
        for i in self.segment_of(s)..self.s_m.len() - 1 {
            if self.s_m[i] > s + horizon_m {
                break;
            }
            let ds = self.s_m[i + 1] - self.s_m[i];
            let curvature = ((self.heading_rad[i + 1] - self.heading_rad[i]) / ds).abs();
            if curvature > 1e-9 {
                let v_curve_sq = lateral_accel_mps2 / curvature;
                let ahead_m = (self.s_m[i] - s).max(0.0);
                limit = limit.min((v_curve_sq + 2.0 * decel_mps2 * ahead_m).sqrt());
            }
        }
        limit
    }

    /// Index of the segment containing arc length `s` (clamped).
    fn segment_of(&self, s_m: f64) -> usize {
        let n = self.s_m.len();
        let i = self.s_m.partition_point(|&v| v <= s_m);
        i.saturating_sub(1).min(n - 2)
    }

    /// [`segment_of`](Self::segment_of), looking first at segment `hint` and
    /// its neighbours (a Newton step rarely leaves them).
    fn segment_near(&self, s_m: f64, hint: usize) -> usize {
        let last = self.s_m.len() - 2;
        let holds = |i: usize| self.s_m[i] <= s_m && (i == last || s_m < self.s_m[i + 1]);
        let i = hint.min(last);
        for candidate in [i, i + 1, i.wrapping_sub(1)] {
            if candidate <= last && holds(candidate) {
                return candidate;
            }
        }
        self.segment_of(s_m)
    }

    /// Point at arc length `s_m`, clamped to [0, length].
    pub fn point_at(&self, s_m: f64) -> Point2<f64> {
        let s = s_m.clamp(0.0, self.length_m());
        self.point_in(self.segment_of(s), s)
    }

    /// Point at arc length `s` (in [0, length]) of segment `i` (the one holding `s`).
    fn point_in(&self, i: usize, s: f64) -> Point2<f64> {
        let ds = self.s_m[i + 1] - self.s_m[i];
        let u = ((s - self.s_m[i]) / ds).clamp(0.0, 1.0);
        let t0 = self.tangent[i] * ds;
        let t1 = self.tangent[i + 1] * ds;
        hermite(&self.points[i], &t0, &self.points[i + 1], &t1, u).0
    }

    /// Unwrapped heading at arc length `s_m`, clamped to [0, length].
    pub fn heading_at(&self, s_m: f64) -> f64 {
        let s = s_m.clamp(0.0, self.length_m());
        self.heading_in(self.segment_of(s), s)
    }

    /// Heading at arc length `s` (in [0, length]) of segment `i` (the one holding `s`).
    fn heading_in(&self, i: usize, s: f64) -> f64 {
        let ds = self.s_m[i + 1] - self.s_m[i];
        let u = ((s - self.s_m[i]) / ds).clamp(0.0, 1.0);
        self.heading_rad[i] + u * (self.heading_rad[i + 1] - self.heading_rad[i])
    }

    /// Point at arc length `s_m`, extended along the end tangents beyond the ends.
    pub(crate) fn point_at_extended(&self, s_m: f64) -> Point2<f64> {
        let len = self.length_m();
        if s_m < 0.0 {
            self.points[0] + self.tangent[0] * s_m
        } else if s_m > len {
            let last = self.points.len() - 1;
            self.points[last] + self.tangent[last] * (s_m - len)
        } else {
            self.point_at(s_m)
        }
    }

    /// [`heading_at`](Self::heading_at), [`point_at_extended`](Self::point_at_extended)
    /// and the curvature at `s_m` (0 beyond the ends), the same values from one
    /// segment search that starts at segment `hint`; with the segment.
    pub(crate) fn local_at(&self, s_m: f64, hint: usize) -> (f64, Point2<f64>, f64, usize) {
        let len = self.length_m();
        let s = s_m.clamp(0.0, len);
        let i = self.segment_near(s, hint);
        let heading = self.heading_in(i, s);
        let outside = s_m < 0.0 || s_m > len;
        let point = if s_m < 0.0 {
            self.points[0] + self.tangent[0] * s_m
        } else if s_m > len {
            let last = self.points.len() - 1;
            self.points[last] + self.tangent[last] * (s_m - len)
        } else {
            self.point_in(i, s)
        };
        let curvature = if outside {
            0.0
        } else {
            (self.heading_rad[i + 1] - self.heading_rad[i]) / (self.s_m[i + 1] - self.s_m[i])
        };
        (heading, point, curvature, i)
    }

    /// (s_m, lateral_m, + = left) of the closest point of the lane; s is clamped
    /// to [0, length] and the lateral offset is measured against the tangent there.
    pub fn project(&self, p: &Point2<f64>) -> (f64, f64) {
        let mut best = (f64::INFINITY, 0usize, 0.0);
        for i in 0..self.points.len() - 1 {
            let (d2, u) = segment_distance2(&self.points[i], &self.points[i + 1], p);
            if d2 < best.0 {
                best = (d2, i, u);
            }
        }
        let (s, d) = self.refine(p, best.1, best.2);
        let s = s.clamp(0.0, self.length_m());
        (s, d)
    }

    /// Like [`project`](Self::project) but only looks at segments within about
    /// `radius_m` of `p` (spatial hash) and extends the lane along its end
    /// tangents, so s may lie outside [0, length]. None if nothing is near.
    pub(crate) fn project_near(&self, p: &Point2<f64>, radius_m: f64) -> Option<(f64, f64)> {
        let lo = cell_of(&Point2::new(p.x - radius_m, p.y - radius_m));
        let hi = cell_of(&Point2::new(p.x + radius_m, p.y + radius_m));
        let mut best = (f64::INFINITY, 0usize, 0.0);
        for cx in lo.0..=hi.0 {
            for cy in lo.1..=hi.1 {
                if let Some(segments) = self.grid.get(&(cx, cy)) {
                    for &i in segments {
                        let i = i as usize;
                        let (d2, u) = segment_distance2(&self.points[i], &self.points[i + 1], p);
                        if d2 < best.0 {
                            best = (d2, i, u);
                        }
                    }
                }
            }
        }
        if best.0 > radius_m * radius_m {
            return None;
        }
        Some(self.refine(p, best.1, best.2))
    }

    /// Newton refinement of a chord projection onto the Hermite curve; beyond
    /// the ends the lane is extended along its end tangents.
    fn refine(&self, p: &Point2<f64>, seg: usize, u: f64) -> (f64, f64) {
        let s0 = self.s_m[seg] + u * (self.s_m[seg + 1] - self.s_m[seg]);
        self.newton(p, s0).unwrap_or_else(|| {
            let t = unit(self.heading_at(s0));
            let r = p - self.point_at_extended(s0);
            (s0, t.x * r.y - t.y * r.x)
        })
    }

    /// Local projection of `p` starting from arc length `s_hint` (e.g. the
    /// previous projection of a moving body): a few Newton steps, no search.
    /// None if it does not converge.
    pub(crate) fn project_from(&self, p: &Point2<f64>, s_hint_m: f64) -> Option<(f64, f64)> {
        self.newton(p, s_hint_m)
    }

    /// Newton iterations on the tangential residual (p - c(s)) . t(s) = 0.
    fn newton(&self, p: &Point2<f64>, s0: f64) -> Option<(f64, f64)> {
        let mut s = s0;
        let mut segment = self.segment_of(s0.clamp(0.0, self.length_m()));
        for _ in 0..12 {
            let (heading, point, curvature, i) = self.local_at(s, segment);
            segment = i;
            let t = unit(heading);
            let r = p - point;
            let d = t.x * r.y - t.y * r.x;
            // d/ds of the residual is -(1 - curvature * lateral)
            let denom = (1.0 - curvature * d).max(0.2);
            let step = (r.dot(&t) / denom).clamp(-10.0, 10.0);
            s += step;
            if step.abs() < 1e-9 {
                let (heading, point, _, _) = self.local_at(s, segment);
                let t = unit(heading);
                let r = p - point;
                return Some((s, t.x * r.y - t.y * r.x));
            }
        }
        None
    }
}

fn cell_of(p: &Point2<f64>) -> (i64, i64) {
    (
        (p.x / GRID_CELL_M).floor() as i64,
        (p.y / GRID_CELL_M).floor() as i64,
    )
}

fn unit(h: f64) -> Vector2<f64> {
    Vector2::new(h.cos(), h.sin())
}

/// Moves along a circle (or line for k = 0) by arc length u.
fn advance(p: Point2<f64>, h: f64, k: f64, u: f64) -> (Point2<f64>, f64) {
    let h1 = h + k * u;
    if (k * u).abs() < 1e-9 {
        // straight (or nearly): second-order series of the arc
        let mid = h + 0.5 * k * u;
        return (p + unit(mid) * u, h1);
    }
    let dx = (h1.sin() - h.sin()) / k;
    let dy = -(h1.cos() - h.cos()) / k;
    (p + Vector2::new(dx, dy), h1)
}

/// Cubic Hermite point and derivative (with respect to u) on [0, 1].
fn hermite(
    p0: &Point2<f64>,
    m0: &Vector2<f64>,
    p1: &Point2<f64>,
    m1: &Vector2<f64>,
    u: f64,
) -> (Point2<f64>, Vector2<f64>) {
    let (u2, u3) = (u * u, u * u * u);
    let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
    let h10 = u3 - 2.0 * u2 + u;
    let h01 = -2.0 * u3 + 3.0 * u2;
    let h11 = u3 - u2;
    let p = p0.coords * h00 + m0 * h10 + p1.coords * h01 + m1 * h11;
    let d00 = 6.0 * u2 - 6.0 * u;
    let d10 = 3.0 * u2 - 4.0 * u + 1.0;
    let d01 = -6.0 * u2 + 6.0 * u;
    let d11 = 3.0 * u2 - 2.0 * u;
    let dp = p0.coords * d00 + m0 * d10 + p1.coords * d01 + m1 * d11;
    (Point2::from(p), dp)
}

/// Squared distance from `p` to segment ab and the clamped parameter u.
fn segment_distance2(a: &Point2<f64>, b: &Point2<f64>, p: &Point2<f64>) -> (f64, f64) {
    let ab = b - a;
    let u = ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
    ((a + ab * u - p).norm_squared(), u)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curve_speed_limit_reaches_the_arc_speed_by_braking() {
        let (radius, a_lat, decel) = (8.0, 2.0, 1.25);
        let pieces = [
            PathPiece::Straight { length_m: 50.0 },
            PathPiece::Arc {
                length_m: 0.5 * std::f64::consts::PI * radius,
                curvature_1pm: -1.0 / radius,
            },
            PathPiece::Straight { length_m: 50.0 },
        ];
        let lane = LanePath::from_pieces(Point2::origin(), 0.0, &pieces, 0.0).unwrap();
        let v_arc = (a_lat * radius).sqrt();
        // in the arc: the arc speed (the curvature of its segments is 1 / radius)
        let inside = lane.curve_speed_limit_mps(55.0, 30.0, a_lat, decel);
        assert!((inside - v_arc).abs() < 1e-6 * v_arc, "{inside} vs {v_arc}");
        // 20 m before it: what braking at `decel` brings down to it
        let before = lane.curve_speed_limit_mps(30.0, 30.0, a_lat, decel);
        let want = (v_arc * v_arc + 2.0 * decel * 20.0).sqrt();
        assert!((before - want).abs() < 0.05, "{before} vs {want}");
        // arc beyond the horizon, or behind: no limit
        assert_eq!(
            lane.curve_speed_limit_mps(0.0, 40.0, a_lat, decel),
            f64::INFINITY
        );
        assert_eq!(
            lane.curve_speed_limit_mps(75.0, 20.0, a_lat, decel),
            f64::INFINITY
        );
    }

    #[test]
    fn a_piece_cut_short_keeps_its_kind_and_curvature() {
        let arc = PathPiece::Arc {
            length_m: 50.0,
            curvature_1pm: 0.01,
        };
        assert_eq!(arc.length_m(), 50.0);
        assert_eq!(
            arc.cut_to(20.0),
            PathPiece::Arc {
                length_m: 20.0,
                curvature_1pm: 0.01
            }
        );
        assert_eq!(arc.cut_to(80.0), arc);
        let straight = PathPiece::Straight { length_m: 30.0 };
        assert_eq!(straight.cut_to(10.0).length_m(), 10.0);
    }

    #[test]
    fn straight_and_arc_lengths_are_exact() {
        let path = LanePath::from_pieces(
            Point2::new(1.0, 2.0),
            0.3,
            &[
                PathPiece::Straight { length_m: 37.3 },
                PathPiece::Arc {
                    length_m: 25.0,
                    curvature_1pm: 0.02,
                },
            ],
            0.0,
        )
        .unwrap();
        assert!((path.length_m() - 62.3).abs() < 1e-12);
        // end of the arc lies where the analytic circle puts it
        let end = path.point_at(62.3);
        let p_arc0 = Point2::new(1.0, 2.0) + unit(0.3) * 37.3;
        let (want, h) = advance(p_arc0, 0.3, 0.02, 25.0);
        assert!((end - want).norm() < 1e-9, "{end} vs {want}");
        assert!((path.heading_at(62.3) - h).abs() < 1e-12);
        // mid-segment points lie on the circle to well below a millimetre
        let centre = p_arc0 + Vector2::new(-0.3f64.sin(), 0.3f64.cos()) * 50.0;
        for i in 0..=250 {
            let s = 37.3 + i as f64 * 0.1;
            let r = (path.point_at(s) - centre).norm();
            assert!((r - 50.0).abs() < 1e-6, "radius {r} at s {s}");
        }
    }

    #[test]
    fn offset_lane_is_parallel_at_the_offset() {
        let pieces = [
            PathPiece::Straight { length_m: 20.0 },
            PathPiece::Arc {
                length_m: 40.0,
                curvature_1pm: -0.03,
            },
            PathPiece::Arc {
                length_m: 30.0,
                curvature_1pm: 0.05,
            },
        ];
        let reference = LanePath::from_pieces(Point2::origin(), 1.0, &pieces, 0.0).unwrap();
        let left = LanePath::from_pieces(Point2::origin(), 1.0, &pieces, 3.5).unwrap();
        let want_len = 20.0 + 40.0 * (1.0 + 0.03 * 3.5) + 30.0 * (1.0 - 0.05 * 3.5);
        assert!((left.length_m() - want_len).abs() < 1e-9);
        for i in 0..=100 {
            let s = left.length_m() * i as f64 / 100.0;
            let (s_ref, d) = reference.project(&left.point_at(s));
            assert!((d - 3.5).abs() < 1e-6, "lateral {d} at s {s}");
            let dh = wrap_angle_rad(left.heading_at(s) - reference.heading_at(s_ref));
            assert!(dh.abs() < 1e-6);
        }
    }

    #[test]
    fn point_heading_and_project_are_consistent() {
        let path = LanePath::from_pieces(
            Point2::new(-5.0, 3.0),
            -2.0,
            &[
                PathPiece::Arc {
                    length_m: 30.0,
                    curvature_1pm: 0.1,
                },
                PathPiece::Straight { length_m: 10.0 },
            ],
            0.0,
        )
        .unwrap();
        for i in 0..=80 {
            let s = 0.5 * i as f64;
            let p = path.point_at(s);
            let h = path.heading_at(s);
            // heading is the direction of motion of point_at
            let e = 1e-5;
            let fd =
                (path.point_at((s + e).min(40.0)) - path.point_at((s - e).max(0.0))).normalize();
            assert!((fd - unit(h)).norm() < 1e-5, "tangent at {s}");
            for d in [-2.0, 0.0, 1.5] {
                let q = p + Vector2::new(-h.sin(), h.cos()) * d;
                let (s_p, d_p) = path.project(&q);
                assert!((s_p - s).abs() < 1e-6, "s {s_p} vs {s}");
                assert!((d_p - d).abs() < 1e-6, "d {d_p} vs {d}");
                let near = path.project_near(&q, 4.0).unwrap();
                assert!((near.0 - s).abs() < 1e-6 && (near.1 - d).abs() < 1e-6);
            }
        }
        assert!(path.project_near(&Point2::new(500.0, 500.0), 5.0).is_none());
    }

    #[test]
    fn from_points_follows_a_densified_polyline() {
        let pts: Vec<Point2<f64>> = (0..=10)
            .map(|i| {
                let a = i as f64 * 0.1;
                Point2::new(20.0 * a.cos(), 20.0 * a.sin())
            })
            .collect();
        let path = LanePath::from_points(&pts).unwrap();
        // length close to the arc length 20 * 1.0
        // one-sided end tangents cost a little length at the ends
        assert!((path.length_m() - 20.0).abs() < 3e-3, "{}", path.length_m());
        for i in 0..=100 {
            let s = path.length_m() * i as f64 / 100.0;
            let r = path.point_at(s).coords.norm();
            assert!((r - 20.0).abs() < 1e-3, "radius {r} at s {s}");
        }
        assert!(LanePath::from_points(&pts[..1]).is_err());
        assert!(LanePath::from_points(&[pts[0], pts[0]]).is_err());
        assert!(
            LanePath::from_pieces(
                Point2::origin(),
                0.0,
                &[PathPiece::Arc {
                    length_m: 5.0,
                    curvature_1pm: 0.5
                }],
                2.5
            )
            .is_err()
        );
    }
}
