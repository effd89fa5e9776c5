//! Overlap of two upright boxes ([`OrientedBox`]: yaw about z only):
//! 3D IoU and 3D generalised IoU (GIoU, Rezatofighi et al. 2019), the
//! association affinity of AB3DMOT.
//!
//! IoU: the exact footprint intersection (convex polygon clipping,
//! Sutherland–Hodgman) times the overlap of the z intervals, over the union
//! volume. GIoU subtracts the part of the smallest enclosing volume not
//! covered by the union: `GIoU = IoU − (C − U)/C`, with `C` the area of the
//! convex hull of both footprints times the height spanned by both boxes
//! (AB3DMOT's `giou_3d`). IoU is in [0, 1]; GIoU in (−1, 1] and keeps
//! decreasing with distance once the boxes no longer touch, so it can rank
//! disjoint pairs.

use crate::geometry::OrientedBox;
use crate::polygon::{convex_intersection, hull_area, polygon_area};
use nalgebra::Vector2;

/// Intersection volume, union volume and enclosing volume of two boxes.
fn volumes(a: &OrientedBox, b: &OrientedBox) -> (f64, f64, f64) {
    let (fa, fb) = (a.bev_corners(), b.bev_corners());
    let (a_lo, a_hi) = (
        a.center.z - 0.5 * a.size_lwh.z,
        a.center.z + 0.5 * a.size_lwh.z,
    );
    let (b_lo, b_hi) = (
        b.center.z - 0.5 * b.size_lwh.z,
        b.center.z + 0.5 * b.size_lwh.z,
    );
    let dz = (a_hi.min(b_hi) - a_lo.max(b_lo)).max(0.0);
    let inter_area = if dz > 0.0 {
        polygon_area(&convex_intersection(&fa, &fb)).max(0.0)
    } else {
        0.0
    };
    let inter = inter_area * dz;
    let union = a.size_lwh.product() + b.size_lwh.product() - inter;
    let mut corners: Vec<Vector2<f64>> = fa.iter().chain(fb.iter()).copied().collect();
    let enclosing = hull_area(&mut corners) * (a_hi.max(b_hi) - a_lo.min(b_lo));
    (inter, union, enclosing)
}

/// 3D IoU of two upright boxes, in [0, 1] (0 for empty boxes).
///
/// Kept apart from the evaluation's `limot::metrics::iou_3d`, which returns
/// exactly 0 for empty footprints and for circumscribed circles apart before
/// clipping; here such pairs are clipped and may give a rounding-sized sliver.
pub fn iou_3d(a: &OrientedBox, b: &OrientedBox) -> f64 {
    let (inter, union, _) = volumes(a, b);
    if union > 0.0 {
        (inter / union).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// 3D generalised IoU of two upright boxes, in (−1, 1] (−1 for empty boxes).
pub fn giou_3d(a: &OrientedBox, b: &OrientedBox) -> f64 {
    let (inter, union, enclosing) = volumes(a, b);
    if union <= 0.0 || enclosing <= 0.0 {
        return -1.0;
    }
    (inter / union - (enclosing - union) / enclosing).clamp(-1.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use std::f64::consts::PI;

    fn boxed(x: f64, y: f64, z: f64, yaw: f64) -> OrientedBox {
        OrientedBox {
            center: Vector3::new(x, y, z),
            yaw_rad: yaw,
            size_lwh: Vector3::new(4.0, 2.0, 1.5),
        }
    }

    #[test]
    fn identical_and_half_turned_boxes_overlap_fully() {
        let a = boxed(3.0, -1.0, 0.5, 0.4);
        assert!((iou_3d(&a, &a) - 1.0).abs() < 1e-12);
        assert!((giou_3d(&a, &a) - 1.0).abs() < 1e-12);
        // A box turned by π is the same volume.
        let flipped = boxed(3.0, -1.0, 0.5, 0.4 + PI);
        assert!((iou_3d(&a, &flipped) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn shifted_boxes_match_closed_form() {
        // Shifted by 1 m along the length: intersection 3·2·1.5 = 9,
        // union 12 + 12 − 9 = 15, hull 5·2·1.5 = 15: IoU = GIoU = 0.6.
        let a = boxed(0.0, 0.0, 0.0, 0.0);
        let b = boxed(1.0, 0.0, 0.0, 0.0);
        assert!((iou_3d(&a, &b) - 0.6).abs() < 1e-12);
        assert!((giou_3d(&a, &b) - 0.6).abs() < 1e-12);
        // Also 0.5 m up: intersection 3·2·1 = 6, union 18, enclosing
        // 5·2·2 = 20: IoU 1/3, GIoU 1/3 − 2/20.
        let c = boxed(1.0, 0.0, 0.5, 0.0);
        assert!((iou_3d(&a, &c) - 1.0 / 3.0).abs() < 1e-12);
        assert!((giou_3d(&a, &c) - (1.0 / 3.0 - 0.1)).abs() < 1e-12);
    }

    #[test]
    fn disjoint_boxes_rank_by_distance_in_giou_only() {
        let a = boxed(0.0, 0.0, 0.0, 0.0);
        // 6 m apart along x: a 2 m gap, enclosing 10·2·1.5 = 30, union 24.
        let near = boxed(6.0, 0.0, 0.0, 0.0);
        let far = boxed(10.0, 0.0, 0.0, 0.0);
        assert_eq!(iou_3d(&a, &near), 0.0);
        assert_eq!(iou_3d(&a, &far), 0.0);
        assert!((giou_3d(&a, &near) - (-6.0 / 30.0)).abs() < 1e-12);
        assert!(giou_3d(&a, &far) < giou_3d(&a, &near));
        assert!(giou_3d(&a, &far) > -1.0);
    }

    #[test]
    fn rotated_overlap_matches_the_octagon() {
        // Two 2×2 squares about the same centre, one turned by 45°: the
        // intersection is a regular octagon of area 8(√2 − 1); the hull is
        // the regular octagon through all eight corners (circumradius √2),
        // of area 2√2·R² = 4√2.
        let square = |yaw: f64| OrientedBox {
            center: Vector3::zeros(),
            yaw_rad: yaw,
            size_lwh: Vector3::new(2.0, 2.0, 1.0),
        };
        let inter = 8.0 * (2.0_f64.sqrt() - 1.0);
        let union = 8.0 - inter;
        let hull = 4.0 * 2.0_f64.sqrt();
        let (a, b) = (square(0.0), square(PI / 4.0));
        assert!((iou_3d(&a, &b) - inter / union).abs() < 1e-12);
        assert!((giou_3d(&a, &b) - (inter / union - (hull - union) / hull)).abs() < 1e-12);
        // Symmetric in its arguments.
        let (a, b) = (boxed(0.3, 0.2, 0.0, 0.3), boxed(1.0, -0.4, 0.2, -0.5));
        assert!((giou_3d(&a, &b) - giou_3d(&b, &a)).abs() < 1e-12);
        assert!(giou_3d(&a, &b) <= iou_3d(&a, &b));
    }
}
