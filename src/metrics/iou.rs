//! Intersection over union of oriented 3D boxes that rotate about z only
//! (yaw), as used by KITTI/AB3DMOT 3D tracking evaluation.
//!
//! BEV IoU: exact area of the intersection of the two rotated rectangles
//! (convex polygon clipping, Sutherland–Hodgman) over the union area.
//! 3D IoU: BEV intersection area × overlap of the z intervals, over the union
//! volume. Both are exact for yaw-rotated boxes.
//!
//! Image IoU: axis-aligned 2D boxes in pixels ([`Box2`]), as the KITTI 2D
//! tracking benchmark and TrackEval's `Kitti2DBox` evaluate them. The
//! CLEAR-MOT matching core is generic over [`MotBox`], implemented by both.

use limot_estimator::geometry::OrientedBox;

/// Which overlap the tracking metrics use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum IouKind {
    /// Bird's-eye view (x-y) IoU.
    Bev,
    /// Full 3D IoU.
    #[default]
    ThreeD,
}

/// Checks a 3D box for the metrics: finite centre, size and yaw, and a
/// non-negative size; `Err((field, why))` names the first problem.
///
/// # Errors
///
/// The offending field and why, for a non-finite value or a negative size.
pub fn validate_box(b: &OrientedBox) -> Result<(), (&'static str, String)> {
    let c = b.center;
    if !(c.x.is_finite() && c.y.is_finite() && c.z.is_finite()) {
        return Err(("center", "not finite".into()));
    }
    let s = b.size_lwh;
    if !(s.x.is_finite() && s.y.is_finite() && s.z.is_finite()) {
        return Err(("size_lwh", "not finite".into()));
    }
    if s.x < 0.0 || s.y < 0.0 || s.z < 0.0 {
        return Err(("size_lwh", format!("negative size {s:?}")));
    }
    if !b.yaw_rad.is_finite() {
        return Err(("yaw_rad", "not finite".into()));
    }
    Ok(())
}

/// Bottom and top of a box, `center.z ∓ h/2`.
fn z_range(b: &OrientedBox) -> (f64, f64) {
    let h = 0.5 * b.size_lwh.z;
    (b.center.z - h, b.center.z + h)
}

pub use limot_estimator::polygon::{convex_intersection, polygon_area};

/// Area of the footprint intersection.
pub fn bev_intersection_area(a: &OrientedBox, b: &OrientedBox) -> f64 {
    if a.bev_area() <= 0.0 || b.bev_area() <= 0.0 {
        return 0.0;
    }
    // Quick reject on circumscribed circles.
    let ra = 0.5 * (a.size_lwh.x.hypot(a.size_lwh.y));
    let rb = 0.5 * (b.size_lwh.x.hypot(b.size_lwh.y));
    let d = (a.center.xy() - b.center.xy()).norm();
    if d > ra + rb {
        return 0.0;
    }
    polygon_area(&convex_intersection(&a.bev_corners(), &b.bev_corners())).max(0.0)
}

fn ratio(intersection: f64, union: f64) -> f64 {
    if union > 0.0 {
        (intersection / union).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Bird's-eye-view IoU in [0, 1] (0 when both footprints are empty).
pub fn iou_bev(a: &OrientedBox, b: &OrientedBox) -> f64 {
    let inter = bev_intersection_area(a, b);
    ratio(inter, a.bev_area() + b.bev_area() - inter)
}

/// 3D IoU in [0, 1] (0 when both volumes are empty).
///
/// Kept apart from the tracker's `limot_estimator::tracking::iou_3d`: this one
/// returns exactly 0 for empty footprints and for circumscribed circles apart
/// before clipping, where the tracker's clips and may give a rounding-sized sliver.
///
/// # Examples
///
/// Two 2 m cubes offset by 1 m along x and along z share a 1 × 2 × 1 m block:
/// 3D IoU = 2 / (8 + 8 − 2) = 1/7, and their footprints 2 / (4 + 4 − 2) = 1/3.
///
/// ```
/// use limot::metrics::{iou_3d, iou_bev};
/// use limot_estimator::geometry::OrientedBox;
/// use nalgebra::Vector3;
///
/// let cube = Vector3::new(2.0, 2.0, 2.0);
/// let a = OrientedBox::new(Vector3::new(0.0, 0.0, 0.0), cube, 0.0);
/// let b = OrientedBox::new(Vector3::new(1.0, 0.0, 1.0), cube, 0.0);
/// assert!((iou_3d(&a, &b) - 1.0 / 7.0).abs() < 1e-12);
/// assert!((iou_bev(&a, &b) - 1.0 / 3.0).abs() < 1e-12);
/// ```
pub fn iou_3d(a: &OrientedBox, b: &OrientedBox) -> f64 {
    let (a_lo, a_hi) = z_range(a);
    let (b_lo, b_hi) = z_range(b);
    let dz = (a_hi.min(b_hi) - a_lo.max(b_lo)).max(0.0);
    if dz <= 0.0 {
        return 0.0;
    }
    let inter = bev_intersection_area(a, b) * dz;
    ratio(inter, a.volume() + b.volume() - inter)
}

/// An axis-aligned box in the image (pixels; x right, y down), stored as
/// KITTI stores `bbox_2d`: left, top, right, bottom.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Box2 {
    /// Left edge, px.
    pub left_px: f64,
    /// Top edge, px.
    pub top_px: f64,
    /// Right edge, px.
    pub right_px: f64,
    /// Bottom edge, px.
    pub bottom_px: f64,
}

/// TrackEval's guard for empty areas and near-threshold comparisons
/// (`np.finfo('float').eps`).
pub const AREA_EPS: f64 = f64::EPSILON;

impl Box2 {
    /// From KITTI's `[left, top, right, bottom]` order.
    pub fn from_ltrb(ltrb_px: [f64; 4]) -> Box2 {
        Box2 {
            left_px: ltrb_px[0],
            top_px: ltrb_px[1],
            right_px: ltrb_px[2],
            bottom_px: ltrb_px[3],
        }
    }

    /// Width, px (0 for an inverted box).
    pub fn width_px(&self) -> f64 {
        self.right_px - self.left_px
    }

    /// Height, px (0 for an inverted box).
    pub fn height_px(&self) -> f64 {
        self.bottom_px - self.top_px
    }

    /// Area, px².
    pub fn area_px2(&self) -> f64 {
        self.width_px() * self.height_px()
    }

    /// Checks finiteness and `left ≤ right`, `top ≤ bottom`.
    ///
    /// # Errors
    ///
    /// The offending field and why, for a non-finite or inverted box.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        for (field, v) in [
            ("left_px", self.left_px),
            ("top_px", self.top_px),
            ("right_px", self.right_px),
            ("bottom_px", self.bottom_px),
        ] {
            if !v.is_finite() {
                return Err((field, "not finite".into()));
            }
        }
        if self.right_px < self.left_px {
            return Err((
                "right_px",
                format!("right {} < left {}", self.right_px, self.left_px),
            ));
        }
        if self.bottom_px < self.top_px {
            return Err((
                "bottom_px",
                format!("bottom {} < top {}", self.bottom_px, self.top_px),
            ));
        }
        Ok(())
    }

    /// Intersection area (0 when disjoint).
    pub fn intersection_area_px2(&self, other: &Box2) -> f64 {
        let w = (self.right_px.min(other.right_px) - self.left_px.max(other.left_px)).max(0.0);
        let h = (self.bottom_px.min(other.bottom_px) - self.top_px.max(other.top_px)).max(0.0);
        w * h
    }
}

/// Image IoU in [0, 1], computed as TrackEval's `_calculate_box_ious`
/// (x0y0x1y1): 0 when either area or the union is not above `AREA_EPS` (machine epsilon).
pub fn iou_image(a: &Box2, b: &Box2) -> f64 {
    let (area_a, area_b) = (a.area_px2(), b.area_px2());
    if area_a <= AREA_EPS || area_b <= AREA_EPS {
        return 0.0;
    }
    let inter = a.intersection_area_px2(b);
    let union = area_a + area_b - inter;
    if union <= AREA_EPS {
        return 0.0;
    }
    inter / union
}

/// Fraction of `a`'s area inside `region` (intersection over `a`'s area;
/// TrackEval's `do_ioa`, used for DontCare regions); 0 for an empty `a`.
pub fn image_fraction_inside(a: &Box2, region: &Box2) -> f64 {
    let area = a.area_px2();
    if area <= AREA_EPS {
        return 0.0;
    }
    a.intersection_area_px2(region) / area
}

/// Geometry the CLEAR-MOT matching core works on: one overlap measure for
/// matching and one "inside a DontCare region" measure.
pub trait MotBox: Copy + PartialEq + std::fmt::Debug {
    /// Checks the box; `Err((field, why))` names the first problem.
    fn validate(&self) -> Result<(), (&'static str, String)>;
    /// IoU in [0, 1]. `kind` chooses BEV or 3D for [`OrientedBox`]; an image box
    /// has a single IoU and ignores it.
    fn overlap(&self, other: &Self, kind: IouKind) -> f64;
    /// Fraction of this box inside `region` (BEV footprint for [`OrientedBox`],
    /// image area for [`Box2`]).
    fn fraction_inside(&self, region: &Self) -> f64;
}

impl MotBox for OrientedBox {
    fn validate(&self) -> Result<(), (&'static str, String)> {
        validate_box(self)
    }
    fn overlap(&self, other: &OrientedBox, kind: IouKind) -> f64 {
        iou(self, other, kind)
    }
    fn fraction_inside(&self, region: &OrientedBox) -> f64 {
        bev_fraction_inside(self, region)
    }
}

impl MotBox for Box2 {
    fn validate(&self) -> Result<(), (&'static str, String)> {
        Box2::validate(self)
    }
    fn overlap(&self, other: &Box2, _kind: IouKind) -> f64 {
        iou_image(self, other)
    }
    fn fraction_inside(&self, region: &Box2) -> f64 {
        image_fraction_inside(self, region)
    }
}

/// IoU of two 3D boxes of the given kind (3D or bird's-eye view).
pub fn iou(a: &OrientedBox, b: &OrientedBox, kind: IouKind) -> f64 {
    match kind {
        IouKind::Bev => iou_bev(a, b),
        IouKind::ThreeD => iou_3d(a, b),
    }
}

/// Fraction of `a`'s footprint that lies inside `region` (KITTI's DontCare
/// test uses this with threshold 0.5).
pub fn bev_fraction_inside(a: &OrientedBox, region: &OrientedBox) -> f64 {
    let area = a.bev_area();
    if area <= 0.0 {
        return 0.0;
    }
    (bev_intersection_area(a, region) / area).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use std::f64::consts::FRAC_PI_4;

    fn b(x: f64, y: f64, z: f64, l: f64, w: f64, h: f64, yaw: f64) -> OrientedBox {
        OrientedBox::new(Vector3::new(x, y, z), Vector3::new(l, w, h), yaw)
    }

    #[test]
    fn corners_are_counter_clockwise() {
        let c = b(1.0, 2.0, 0.0, 4.0, 2.0, 1.5, 0.7).bev_corners();
        assert!((polygon_area(&c) - 8.0).abs() < 1e-12);
    }

    #[test]
    fn identical_is_one_disjoint_is_zero() {
        let a = b(1.0, 2.0, 0.5, 4.0, 2.0, 1.5, 0.3);
        assert!((iou_3d(&a, &a) - 1.0).abs() < 1e-12);
        assert!((iou_bev(&a, &a) - 1.0).abs() < 1e-12);
        let far = b(20.0, 2.0, 0.5, 4.0, 2.0, 1.5, 0.3);
        assert_eq!(iou_3d(&a, &far), 0.0);
        assert_eq!(iou_bev(&a, &far), 0.0);
        // Same footprint, stacked vertically without overlap.
        let above = b(1.0, 2.0, 3.0, 4.0, 2.0, 1.5, 0.3);
        assert_eq!(iou_3d(&a, &above), 0.0);
        assert!((iou_bev(&a, &above) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn axis_aligned_hand_case() {
        // 2x2x2 cubes offset by 1 in x and 1 in z: inter = 1*2*1 = 2, union = 16 - 2.
        let a = b(0.0, 0.0, 0.0, 2.0, 2.0, 2.0, 0.0);
        let c = b(1.0, 0.0, 1.0, 2.0, 2.0, 2.0, 0.0);
        assert!((iou_3d(&a, &c) - 2.0 / 14.0).abs() < 1e-12);
        assert!((iou_bev(&a, &c) - 2.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn rotated_45_degree_square() {
        // Unit-half-size square (side 2) and the same square turned 45°: the
        // intersection is a regular octagon of area 8(√2 − 1).
        let a = b(0.0, 0.0, 0.0, 2.0, 2.0, 1.0, 0.0);
        let r = b(0.0, 0.0, 0.0, 2.0, 2.0, 1.0, FRAC_PI_4);
        let inter = 8.0 * (2f64.sqrt() - 1.0);
        let expected = inter / (8.0 - inter);
        assert!((iou_bev(&a, &r) - expected).abs() < 1e-12);
        assert!((iou_3d(&a, &r) - expected).abs() < 1e-12);
        // Square [0,2]² and a diamond centred at (2, 1) with half-diagonal 1
        // (vertices (3,1), (2,2), (1,1), (2,0)).
        let sq = b(1.0, 1.0, 0.0, 2.0, 2.0, 1.0, 0.0);
        let d = 2f64.sqrt(); // side so that the half-diagonal is 1
        let diamond = b(2.0, 1.0, 0.0, d, d, 1.0, FRAC_PI_4);
        // Overlap: the left half of the diamond, a triangle with base 2 and height 1.
        assert!((bev_intersection_area(&sq, &diamond) - 1.0).abs() < 1e-12);
        assert!((iou_bev(&sq, &diamond) - 1.0 / (4.0 + 2.0 - 1.0)).abs() < 1e-12);
    }

    #[test]
    fn symmetric_and_3d_not_above_bev() {
        let boxes = [
            b(0.0, 0.0, 0.0, 4.0, 2.0, 1.5, 0.1),
            b(0.7, 0.4, 0.3, 3.5, 1.8, 1.6, -0.6),
            b(-1.0, 0.5, -0.2, 4.5, 2.1, 1.4, 1.2),
            b(0.2, -0.3, 0.9, 1.0, 1.0, 2.0, 2.9),
        ];
        for x in &boxes {
            for y in &boxes {
                let (a3, b3) = (iou_3d(x, y), iou_3d(y, x));
                assert!((a3 - b3).abs() < 1e-12);
                assert!((iou_bev(x, y) - iou_bev(y, x)).abs() < 1e-12);
                assert!(a3 <= iou_bev(x, y) + 1e-12);
            }
        }
    }

    #[test]
    fn degenerate_boxes_give_zero() {
        let z = b(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        assert_eq!(iou_3d(&z, &z), 0.0);
        assert_eq!(iou_bev(&z, &z), 0.0);
        assert!(validate_box(&z).is_ok());
        assert!(validate_box(&b(0.0, 0.0, 0.0, -1.0, 1.0, 1.0, 0.0)).is_err());
        assert!(validate_box(&b(f64::NAN, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0)).is_err());
    }

    #[test]
    fn image_iou_hand_cases() {
        let a = Box2::from_ltrb([0.0, 0.0, 10.0, 10.0]);
        // Shifted by 5 px in x: inter 50, union 150.
        let b = Box2::from_ltrb([5.0, 0.0, 15.0, 10.0]);
        assert!((iou_image(&a, &b) - 1.0 / 3.0).abs() < 1e-15);
        assert_eq!(iou_image(&a, &b), iou_image(&b, &a));
        assert_eq!(iou_image(&a, &a), 1.0);
        let far = Box2::from_ltrb([20.0, 20.0, 30.0, 30.0]);
        assert_eq!(iou_image(&a, &far), 0.0);
        let flat = Box2::from_ltrb([0.0, 5.0, 10.0, 5.0]);
        assert_eq!(iou_image(&a, &flat), 0.0);
        assert_eq!(image_fraction_inside(&b, &a), 0.5);
        assert_eq!(image_fraction_inside(&flat, &a), 0.0);
        assert_eq!(a.height_px(), 10.0);
        // The trait dispatches to the same functions and ignores the kind for images.
        assert_eq!(a.overlap(&b, IouKind::Bev), iou_image(&a, &b));
        assert_eq!(MotBox::fraction_inside(&b, &a), 0.5);
        assert!(MotBox::validate(&a).is_ok());
        assert!(Box2::from_ltrb([5.0, 0.0, 4.0, 1.0]).validate().is_err());
        assert!(
            Box2::from_ltrb([0.0, 0.0, 1.0, f64::NAN])
                .validate()
                .is_err()
        );
    }
}
