//! Convex polygons in the plane: signed area, intersection of two convex
//! polygons, area of a convex hull. The footprint geometry of box overlaps
//! (the tracker's 3D IoU/GIoU and the evaluation's IoU share it).

use nalgebra::Vector2;

/// Cross product of `a − o` and `b − o` (positive when o→a→b turns left).
fn cross(o: Vector2<f64>, a: Vector2<f64>, b: Vector2<f64>) -> f64 {
    (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x)
}

/// Signed area of a simple polygon (positive for counter-clockwise vertices;
/// 0 for fewer than three).
pub fn polygon_area(poly: &[Vector2<f64>]) -> f64 {
    let n = poly.len();
    if n < 3 {
        return 0.0;
    }
    0.5 * (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            a.x * b.y - a.y * b.x
        })
        .sum::<f64>()
}

/// Intersection of two convex counter-clockwise polygons (Sutherland–Hodgman:
/// `subject` clipped by each edge half-plane of `clip`); empty when they do
/// not overlap.
///
/// ```
/// use limot_estimator::polygon::{convex_intersection, polygon_area};
/// use nalgebra::Vector2;
///
/// let square = |x: f64, y: f64| {
///     vec![
///         Vector2::new(x, y),
///         Vector2::new(x + 1.0, y),
///         Vector2::new(x + 1.0, y + 1.0),
///         Vector2::new(x, y + 1.0),
///     ]
/// };
/// // Two unit squares shifted by half a side overlap in half a square.
/// let overlap = convex_intersection(&square(0.0, 0.0), &square(0.5, 0.0));
/// assert!((polygon_area(&overlap) - 0.5).abs() < 1e-12);
/// assert!(convex_intersection(&square(0.0, 0.0), &square(2.0, 0.0)).is_empty());
/// ```
pub fn convex_intersection(subject: &[Vector2<f64>], clip: &[Vector2<f64>]) -> Vec<Vector2<f64>> {
    let mut output = subject.to_vec();
    for i in 0..clip.len() {
        if output.is_empty() {
            break;
        }
        let (a, b) = (clip[i], clip[(i + 1) % clip.len()]);
        let input = std::mem::take(&mut output);
        for j in 0..input.len() {
            let (p, q) = (input[j], input[(j + 1) % input.len()]);
            // Inside = left of (or on) the directed edge a→b.
            let (dp, dq) = (cross(a, b, p), cross(a, b, q));
            if dp >= 0.0 {
                output.push(p);
            }
            if (dp >= 0.0) != (dq >= 0.0) {
                output.push(p + (q - p) * (dp / (dp - dq)));
            }
        }
    }
    output
}

/// Area of the convex hull of `points` (Andrew's monotone chain; reorders
/// `points`).
pub fn hull_area(points: &mut [Vector2<f64>]) -> f64 {
    points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    let mut hull: Vec<Vector2<f64>> = Vec::with_capacity(2 * points.len());
    for pass in 0..2 {
        let start = hull.len();
        let ordered: Box<dyn Iterator<Item = &Vector2<f64>>> = if pass == 0 {
            Box::new(points.iter())
        } else {
            Box::new(points.iter().rev())
        };
        for &p in ordered {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        // The last point of each chain starts the other one.
        hull.pop();
    }
    polygon_area(&hull)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x0: f64, y0: f64, side: f64) -> Vec<Vector2<f64>> {
        vec![
            Vector2::new(x0, y0),
            Vector2::new(x0 + side, y0),
            Vector2::new(x0 + side, y0 + side),
            Vector2::new(x0, y0 + side),
        ]
    }

    #[test]
    fn areas_of_squares_their_overlap_and_hull() {
        let (a, b) = (square(0.0, 0.0, 2.0), square(1.0, 1.0, 2.0));
        assert_eq!(polygon_area(&a), 4.0);
        let reversed: Vec<_> = a.iter().rev().copied().collect();
        assert_eq!(polygon_area(&reversed), -4.0);
        assert!((polygon_area(&convex_intersection(&a, &b)) - 1.0).abs() < 1e-12);
        assert!(convex_intersection(&a, &square(5.0, 5.0, 1.0)).is_empty());
        // Hull of both: the 3×3 square minus two corner triangles of area 1/2.
        let mut all: Vec<_> = a.iter().chain(&b).copied().collect();
        assert!((hull_area(&mut all) - 8.0).abs() < 1e-12);
    }
}
