//! Trajectory-based dynamic feature filtering (paper, "Trajectory-based
//! Dynamic Feature Filtering"): before scan matching, every point that lies
//! inside the (slightly inflated) predicted box of a *moving* object at the
//! point's own time is dropped, while points on parked cars are kept.
//!
//! The tracker is not a dependency: a moving box is anything implementing
//! [`BoxAtTime`] (the tracker's fitted trajectory, or the simple
//! [`ConstantVelocityBox`]). The `allfilt` ablation variant, which drops the
//! points inside every detected box without any motion, is
//! [`all_boxes_mask`].
//!
//! # Time handling
//! A LiDAR sweep takes ~0.1 s; a car crossing at 15 m/s moves 1.5 m during
//! it, far more than any sensible inflation. Each point is therefore tested
//! against the box *at its own time*. Evaluating a trajectory and the ego pose
//! per point would be wasteful, so the sweep's time span is cut into
//! [`FilterConfig::time_bins`] equal bins and boxes and ego pose are
//! evaluated once per bin, at its centre: with 10 bins of a 0.1 s sweep the
//! timing error is at most 5 ms (7.5 cm at 15 m/s relative speed).
//!
//! # Frames
//! `t_world_lidar_at(t)` maps points of time `t` from the LiDAR frame into
//! the world frame. For raw points (each in the LiDAR frame at its own time)
//! pass the (IMU-predicted) ego pose as a function of time. For points
//! already de-skewed to a reference time `t_ref`, pass the constant pose
//! `|_| t_world_lidar(t_ref)`: the points' world positions are then right,
//! and the boxes are still evaluated at each point's own time, which is
//! where the object was when the point was measured.

use crate::geometry::OrientedBox;
use nalgebra::{Isometry3, Matrix3, Vector3};
use thiserror::Error;

/// A box that may move: the tracker's predicted box of one track at time
/// `t_s` (seconds on the sensor clock).
pub trait BoxAtTime {
    /// The box at time `t_s`, world frame.
    fn box_at(&self, t_s: f64) -> OrientedBox;
}

/// A box that never moves (parked car, or a detection for `allfilt`).
impl BoxAtTime for OrientedBox {
    fn box_at(&self, _t_s: f64) -> OrientedBox {
        *self
    }
}

/// A box moving with constant world velocity and yaw rate from a reference
/// box at `t_ref_s` (for callers without a fitted trajectory, and tests).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantVelocityBox {
    /// The box at `t_ref_s`.
    pub box_ref: OrientedBox,
    /// Reference time, s.
    pub t_ref_s: f64,
    /// Velocity of the centre, world frame.
    pub velocity_world_mps: Vector3<f64>,
    /// Rate of change of the heading.
    pub yaw_rate_radps: f64,
}

impl BoxAtTime for ConstantVelocityBox {
    fn box_at(&self, t_s: f64) -> OrientedBox {
        let dt_s = t_s - self.t_ref_s;
        OrientedBox {
            center: self.box_ref.center + self.velocity_world_mps * dt_s,
            yaw_rad: self.box_ref.yaw_rad + self.yaw_rate_radps * dt_s,
            size_lwh: self.box_ref.size_lwh,
        }
    }
}

/// Settings of the dynamic feature filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilterConfig {
    /// Growth of the four sides and the top of every box, metres. The paper
    /// only says the boxes are inflated "slightly"; 0.3 m covers typical
    /// detection/prediction errors (detector centre sigma ~0.15 m) and the
    /// per-bin timing error, while staying well below the ~1 m gap between
    /// parked cars.
    pub inflate_m: f64,
    /// Growth of the bottom face, metres (negative raises it). Default 0:
    /// the ground returns around a car lie on the plane of its bottom face,
    /// and growing the box downwards would strip the ground's planar
    /// features from a ring around every moving car. The cost: a box whose
    /// bottom sits too high misses the car's lowest slice (in the synthetic
    /// sweep of `tests/filter_props.rs`, 5 cm of bottom error or -0.05 here
    /// loses ~3.6% of the car's returns, while 0 removes ~3% of ground
    /// returns around the car as false positives).
    pub inflate_bottom_m: f64,
    /// Number of equal time bins per sweep at which boxes and ego pose are
    /// evaluated (>= 1). More bins: closer to exact per-point time, slower.
    pub time_bins: usize,
    /// A detection belongs to the track whose predicted centre is nearest
    /// to it within this distance, metres (for the detections the
    /// trajectory-based filter also uses; default 2 m: half a car length,
    /// below the spacing of queued cars, above the detector's and the
    /// prediction's errors).
    pub detection_track_gate_m: f64,
}

impl Default for FilterConfig {
    fn default() -> Self {
        FilterConfig {
            inflate_m: 0.3,
            inflate_bottom_m: 0.0,
            time_bins: 10,
            detection_track_gate_m: 2.0,
        }
    }
}

impl FilterConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`FilterError`] naming the first setting that is non-finite or out of
    /// range.
    pub fn validate(&self) -> Result<(), FilterError> {
        if !self.inflate_m.is_finite() {
            return Err(FilterError::Config {
                field: "inflate_m",
                reason: "not finite",
            });
        }
        if !self.inflate_bottom_m.is_finite() {
            return Err(FilterError::Config {
                field: "inflate_bottom_m",
                reason: "not finite",
            });
        }
        if !(self.detection_track_gate_m.is_finite() && self.detection_track_gate_m >= 0.0) {
            return Err(FilterError::Config {
                field: "detection_track_gate_m",
                reason: "must be finite and non-negative",
            });
        }
        if self.time_bins == 0 {
            return Err(FilterError::Config {
                field: "time_bins",
                reason: "must be at least 1",
            });
        }
        Ok(())
    }
}

/// Bad input to the filter functions.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FilterError {
    /// Points and point times differ in length.
    #[error("{points} points but {times} point times")]
    TimesLength {
        /// Number of points.
        points: usize,
        /// Number of point times.
        times: usize,
    },
    /// A point time is not finite.
    #[error("point {index}: time {t_s} s is not finite")]
    NonFiniteTime {
        /// Index of the point.
        index: usize,
        /// Its time.
        t_s: f64,
    },
    /// A setting of [`FilterConfig`] is out of range.
    #[error("filter config field `{field}`: {reason}")]
    Config {
        /// The setting.
        field: &'static str,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// Mask and labels differ in length ([`filter_stats`]).
    #[error("mask has {mask} entries but labels have {labels}")]
    LabelsLength {
        /// Entries of the mask.
        mask: usize,
        /// Entries of the labels.
        labels: usize,
    },
}

/// One box at one time bin, prepared for fast tests of LiDAR-frame points.
#[derive(Debug, Clone, Copy)]
struct BinBox {
    /// Box centre in the LiDAR frame of the bin's time.
    center_lidar: Vector3<f64>,
    /// Rows: the box's x/y/z axes expressed in the LiDAR frame, so that
    /// `axes_lidar * (p - center_lidar)` is the point in the box frame.
    axes_lidar: Matrix3<f64>,
    half_x: f64,
    half_y: f64,
    z_low: f64,
    z_high: f64,
    /// Squared radius of the inflated box's bounding sphere (cheap cull).
    radius_sq: f64,
}

impl BinBox {
    fn new(b: &OrientedBox, t_world_lidar: &Isometry3<f64>, config: &FilterConfig) -> BinBox {
        let rot_lidar_world = t_world_lidar.rotation.inverse();
        let center_lidar = t_world_lidar
            .inverse_transform_point(&nalgebra::Point3::from(b.center))
            .coords;
        let (sin_yaw, cos_yaw) = b.yaw_rad.sin_cos();
        let x_axis = rot_lidar_world * Vector3::new(cos_yaw, sin_yaw, 0.0);
        let y_axis = rot_lidar_world * Vector3::new(-sin_yaw, cos_yaw, 0.0);
        let z_axis = rot_lidar_world * Vector3::z();
        let axes_lidar =
            Matrix3::from_rows(&[x_axis.transpose(), y_axis.transpose(), z_axis.transpose()]);
        let half = 0.5 * b.size_lwh;
        let half_x = half.x + config.inflate_m;
        let half_y = half.y + config.inflate_m;
        let z_low = -half.z - config.inflate_bottom_m;
        let z_high = half.z + config.inflate_m;
        // An empty (over-shrunk) box gets a negative radius: culls everything.
        let radius_sq = if half_x < 0.0 || half_y < 0.0 || z_low > z_high {
            -1.0
        } else {
            let half_z = z_low.abs().max(z_high.abs());
            half_x * half_x + half_y * half_y + half_z * half_z
        };
        BinBox {
            center_lidar,
            axes_lidar,
            half_x,
            half_y,
            z_low,
            z_high,
            radius_sq,
        }
    }

    #[inline]
    fn contains(&self, p_lidar: &Vector3<f64>) -> bool {
        let d = p_lidar - self.center_lidar;
        if d.norm_squared() > self.radius_sq {
            return false;
        }
        let q = self.axes_lidar * d;
        q.x.abs() <= self.half_x
            && q.y.abs() <= self.half_y
            && q.z >= self.z_low
            && q.z <= self.z_high
    }
}

/// Cell edge of [`BoxCells`], m: about a third of a car's bounding sphere,
/// so that most points far from every box are rejected by one lookup.
const BOX_CELL_M: f64 = 1.0;

/// The most cells [`BoxCells`] allocates: boxes spread wider get coarser
/// cells.
const BOX_CELLS_MAX: f64 = 65_536.0;

/// The most cells [`BoxCells`] has along a side (boxes in a long line).
const BOX_CELLS_PER_SIDE_MAX: f64 = 4096.0;

/// A grid over the LiDAR frame's x-y plane recording, per cell, which boxes'
/// bounding spheres (in any time bin) reach it: a conservative cull, so that
/// a point is tested only against the boxes that can contain it.
struct BoxCells {
    x0: f64,
    y0: f64,
    inv_cell_m: f64,
    nx: usize,
    ny: usize,
    /// u64 words per cell; bit j of a cell's words is set when box j may
    /// reach the cell.
    words: usize,
    bits: Vec<u64>,
}

impl BoxCells {
    /// The grid for `bin_boxes`, bin-major with `boxes` boxes per bin.
    fn new(bin_boxes: &[BinBox], boxes: usize) -> BoxCells {
        let words = boxes.div_ceil(64).max(1);
        let reach = |b: &BinBox| (b.radius_sq >= 0.0).then(|| b.radius_sq.sqrt());
        let (mut lo_x, mut lo_y) = (f64::INFINITY, f64::INFINITY);
        let (mut hi_x, mut hi_y) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        for b in bin_boxes {
            if let Some(r) = reach(b) {
                lo_x = lo_x.min(b.center_lidar.x - r);
                lo_y = lo_y.min(b.center_lidar.y - r);
                hi_x = hi_x.max(b.center_lidar.x + r);
                hi_y = hi_y.max(b.center_lidar.y + r);
            }
        }
        let mut cells = BoxCells {
            x0: lo_x,
            y0: lo_y,
            inv_cell_m: 0.0,
            nx: 0,
            ny: 0,
            words,
            bits: Vec::new(),
        };
        // no box can hold a point (or the extent is not finite)
        if !(lo_x <= hi_x && lo_y <= hi_y && (hi_x - lo_x + hi_y - lo_y).is_finite()) {
            return cells;
        }
        let (width_m, height_m) = (hi_x - lo_x, hi_y - lo_y);
        let cell_m = BOX_CELL_M
            .max((width_m * height_m / BOX_CELLS_MAX).sqrt())
            .max(width_m.max(height_m) / BOX_CELLS_PER_SIDE_MAX);
        cells.inv_cell_m = 1.0 / cell_m;
        cells.nx = ((hi_x - lo_x) * cells.inv_cell_m) as usize + 1;
        cells.ny = ((hi_y - lo_y) * cells.inv_cell_m) as usize + 1;
        cells.bits = vec![0; cells.nx * cells.ny * words];
        for (k, b) in bin_boxes.iter().enumerate() {
            let Some(r) = reach(b) else { continue };
            let (j, c) = (k % boxes, &b.center_lidar);
            // the sphere's bounding square: a point inside the sphere lies
            // in it, and the cell index is monotone in the coordinates
            let (ix0, iy0) = cells.cell(c.x - r, c.y - r);
            let (ix1, iy1) = cells.cell(c.x + r, c.y + r);
            for iy in iy0..=iy1 {
                for ix in ix0..=ix1 {
                    cells.bits[(iy * cells.nx + ix) * words + j / 64] |= 1 << (j % 64);
                }
            }
        }
        cells
    }

    /// Cell coordinates of a point of the grid's extent (clamped to it).
    fn cell(&self, x: f64, y: f64) -> (usize, usize) {
        let ix = ((x - self.x0) * self.inv_cell_m).max(0.0) as usize;
        let iy = ((y - self.y0) * self.inv_cell_m).max(0.0) as usize;
        (ix.min(self.nx - 1), iy.min(self.ny - 1))
    }

    /// The words of the boxes that may contain `p_lidar`; None when none
    /// may (outside the grid, in an empty cell, or not finite).
    #[inline]
    fn boxes_reaching(&self, p_lidar: &Vector3<f64>) -> Option<&[u64]> {
        let fx = (p_lidar.x - self.x0) * self.inv_cell_m;
        let fy = (p_lidar.y - self.y0) * self.inv_cell_m;
        if !(fx >= 0.0 && fy >= 0.0 && fx < self.nx as f64 && fy < self.ny as f64) {
            return None;
        }
        // SAFETY: 0 <= fx < nx and 0 <= fy < ny, so both truncate to usize
        // (the saturating `as` costs a range check per point).
        let (ix, iy): (usize, usize) = unsafe { (fx.to_int_unchecked(), fy.to_int_unchecked()) };
        let cell = iy * self.nx + ix;
        let words = &self.bits[cell * self.words..][..self.words];
        words.iter().any(|&w| w != 0).then_some(words)
    }
}

/// Marks the points inside some inflated moving box at the point's own time:
/// `true` = on a moving object, drop it before scan matching.
///
/// `points_lidar[i]` was measured at `point_times_s[i]`; `t_world_lidar_at`
/// maps it into the world (see the module docs for raw vs de-skewed points).
/// `boxes` are the predicted boxes of the dynamic tracks.
///
/// # Errors
/// [`FilterError::Config`] for an invalid `config`,
/// [`FilterError::TimesLength`] when points and times differ in length,
/// [`FilterError::NonFiniteTime`] for a non-finite point time.
pub fn dynamic_feature_mask(
    points_lidar: &[Vector3<f64>],
    point_times_s: &[f64],
    t_world_lidar_at: &dyn Fn(f64) -> Isometry3<f64>,
    boxes: &[&dyn BoxAtTime],
    config: &FilterConfig,
) -> Result<Vec<bool>, FilterError> {
    if points_lidar.len() != point_times_s.len() {
        config.validate()?;
        return Err(FilterError::TimesLength {
            points: points_lidar.len(),
            times: point_times_s.len(),
        });
    }
    let mut mask = vec![false; points_lidar.len()];
    moving_box_mask(
        |i| points_lidar[i],
        |i| point_times_s[i],
        t_world_lidar_at,
        boxes,
        config,
        &mut mask,
    )?;
    Ok(mask)
}

/// [`dynamic_feature_mask`] for points read through accessors (point `i`
/// at `position_lidar(i)`, measured at `time_s(i)`, for `i` below
/// `mask.len()`), so that a caller holding indices into a scan need not
/// gather the points first. Sets `mask[i]` for the dropped points and leaves
/// the others as they were.
pub(crate) fn moving_box_mask(
    position_lidar: impl Fn(usize) -> Vector3<f64>,
    time_s: impl Fn(usize) -> f64,
    t_world_lidar_at: &dyn Fn(f64) -> Isometry3<f64>,
    boxes: &[&dyn BoxAtTime],
    config: &FilterConfig,
    mask: &mut [bool],
) -> Result<(), FilterError> {
    config.validate()?;
    let n = mask.len();
    // Four running extremes with plain comparisons (the times are checked
    // finite): one serial chain of `f64::min`, with its NaN handling, was a
    // large part of the filter's time.
    let mut t_min_s = [f64::INFINITY; 4];
    let mut t_max_s = [f64::NEG_INFINITY; 4];
    for index in 0..n {
        let t_s = time_s(index);
        if !t_s.is_finite() {
            return Err(FilterError::NonFiniteTime { index, t_s });
        }
        let lane = index % 4;
        if t_s < t_min_s[lane] {
            t_min_s[lane] = t_s;
        }
        if t_s > t_max_s[lane] {
            t_max_s[lane] = t_s;
        }
    }
    let t_min_s = t_min_s.into_iter().fold(f64::INFINITY, f64::min);
    let t_max_s = t_max_s.into_iter().fold(f64::NEG_INFINITY, f64::max);
    if n == 0 || boxes.is_empty() {
        return Ok(());
    }

    let span_s = t_max_s - t_min_s;
    let bins = if span_s > 0.0 { config.time_bins } else { 1 };
    let bin_width_s = span_s / bins as f64;
    let bin_of = |t_s: f64| {
        if bins == 1 {
            0
        } else {
            // `as usize` saturates; the max time lands in the last bin
            (((t_s - t_min_s) / bin_width_s) as usize).min(bins - 1)
        }
    };

    // Boxes and ego pose once per bin: bin b owns
    // bin_boxes[b * boxes.len()..(b + 1) * boxes.len()].
    let mut bin_boxes = Vec::with_capacity(bins * boxes.len());
    for bin in 0..bins {
        let t_bin_s = t_min_s + (bin as f64 + 0.5) * bin_width_s;
        let t_world_lidar = t_world_lidar_at(t_bin_s);
        bin_boxes.extend(
            boxes
                .iter()
                .map(|b| BinBox::new(&b.box_at(t_bin_s), &t_world_lidar, config)),
        );
    }
    let cells = BoxCells::new(&bin_boxes, boxes.len());

    for (index, drop) in mask.iter_mut().enumerate() {
        let p_lidar = position_lidar(index);
        let Some(reaching) = cells.boxes_reaching(&p_lidar) else {
            continue;
        };
        let row = &bin_boxes[bin_of(time_s(index)) * boxes.len()..][..boxes.len()];
        let inside = reaching.iter().enumerate().any(|(word, &bits)| {
            let mut bits = bits;
            while bits != 0 {
                if row[word * 64 + bits.trailing_zeros() as usize].contains(&p_lidar) {
                    return true;
                }
                bits &= bits - 1;
            }
            false
        });
        *drop |= inside;
    }
    Ok(())
}

/// The `allfilt` variant: marks the points inside any inflated box of
/// `boxes_world` (every detection of the scan, mapped into the world at the
/// scan time, e.g. with [`OrientedBox::transformed`]), with no motion.
/// Points and poses are handled as in [`dynamic_feature_mask`].
///
/// # Errors
/// As [`dynamic_feature_mask`].
pub fn all_boxes_mask(
    points_lidar: &[Vector3<f64>],
    point_times_s: &[f64],
    t_world_lidar_at: &dyn Fn(f64) -> Isometry3<f64>,
    boxes_world: &[OrientedBox],
    config: &FilterConfig,
) -> Result<Vec<bool>, FilterError> {
    let boxes: Vec<&dyn BoxAtTime> = boxes_world.iter().map(|b| b as &dyn BoxAtTime).collect();
    dynamic_feature_mask(
        points_lidar,
        point_times_s,
        t_world_lidar_at,
        &boxes,
        config,
    )
}

/// Quality of a removal mask against ground-truth "on a moving object" labels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilterStats {
    /// Points evaluated.
    pub total: usize,
    /// Points the mask removes.
    pub removed: usize,
    /// Points truly on moving objects.
    pub moving: usize,
    /// Removed points that are truly on moving objects.
    pub true_positive: usize,
    /// Removed points that are not on moving objects (e.g. on parked cars).
    pub false_positive: usize,
    /// Moving points that were kept.
    pub false_negative: usize,
    /// `true_positive / removed`; 1 when nothing is removed (no false removal).
    pub precision: f64,
    /// `true_positive / moving`; 1 when nothing moves (nothing to miss).
    pub recall: f64,
}

/// Precision and recall of `mask` (true = removed) against `labels_moving`
/// (true = the point lies on a moving object).
///
/// # Errors
/// [`FilterError::LabelsLength`] when the two slices differ in length.
pub fn filter_stats(mask: &[bool], labels_moving: &[bool]) -> Result<FilterStats, FilterError> {
    if mask.len() != labels_moving.len() {
        return Err(FilterError::LabelsLength {
            mask: mask.len(),
            labels: labels_moving.len(),
        });
    }
    let mut removed = 0;
    let mut moving = 0;
    let mut true_positive = 0;
    for (&m, &l) in mask.iter().zip(labels_moving) {
        removed += m as usize;
        moving += l as usize;
        true_positive += (m && l) as usize;
    }
    let ratio = |num: usize, den: usize| {
        if den == 0 {
            1.0
        } else {
            num as f64 / den as f64
        }
    };
    Ok(FilterStats {
        total: mask.len(),
        removed,
        moving,
        true_positive,
        false_positive: removed - true_positive,
        false_negative: moving - true_positive,
        precision: ratio(true_positive, removed),
        recall: ratio(true_positive, moving),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::{Detection, ObjectClass};
    use nalgebra::{Translation3, UnitQuaternion};

    fn car(center: Vector3<f64>, yaw_rad: f64) -> OrientedBox {
        OrientedBox {
            center,
            yaw_rad,
            size_lwh: Vector3::new(4.0, 2.0, 1.5),
        }
    }

    fn identity_pose(_t: f64) -> Isometry3<f64> {
        Isometry3::identity()
    }

    #[test]
    fn contains_respects_yaw_and_inflation() {
        let b = car(Vector3::new(10.0, 0.0, 0.75), std::f64::consts::FRAC_PI_2);
        // length now runs along world y
        assert!(b.contains(&Vector3::new(10.0, 1.9, 0.75), 0.0));
        assert!(!b.contains(&Vector3::new(11.9, 0.0, 0.75), 0.0));
        assert!(b.contains(&Vector3::new(11.2, 0.0, 0.75), 0.3));
        assert!(!b.contains(&Vector3::new(11.4, 0.0, 0.75), 0.3));
        // top grows with inflate_m, bottom with inflate_bottom_m only
        assert!(b.contains_inflated(&Vector3::new(10.0, 0.0, 1.7), 0.3, 0.0));
        assert!(!b.contains_inflated(&Vector3::new(10.0, 0.0, -0.1), 0.3, 0.0));
        assert!(b.contains_inflated(&Vector3::new(10.0, 0.0, -0.1), 0.3, 0.2));
    }

    #[test]
    fn constant_velocity_box_moves_linearly() {
        let cv = ConstantVelocityBox {
            box_ref: car(Vector3::new(0.0, 0.0, 0.75), 0.1),
            t_ref_s: 2.0,
            velocity_world_mps: Vector3::new(15.0, -1.0, 0.0),
            yaw_rate_radps: 0.5,
        };
        let b = cv.box_at(2.1);
        assert!((b.center - Vector3::new(1.5, -0.1, 0.75)).norm() < 1e-12);
        assert!((b.yaw_rad - 0.15).abs() < 1e-12);
        assert_eq!(b.size_lwh, cv.box_ref.size_lwh);
        let still = cv.box_ref;
        assert_eq!(still.box_at(123.0), still);
    }

    #[test]
    fn from_detection_maps_center_and_heading() {
        let t_world_lidar = Isometry3::from_parts(
            Translation3::new(5.0, -2.0, 1.7),
            UnitQuaternion::from_euler_angles(0.02, -0.01, 0.8),
        );
        let det = Detection {
            box_lidar: OrientedBox {
                center: Vector3::new(8.0, 3.0, -0.9),
                size_lwh: Vector3::new(4.2, 1.8, 1.5),
                yaw_rad: 0.3,
            },
            class: ObjectClass::Car,
            score: 0.9,
            time_offset_s: 0.0,
        };
        let b = det.box_lidar.transformed(&t_world_lidar);
        let c = t_world_lidar * nalgebra::Point3::from(det.box_lidar.center);
        assert!((b.center - c.coords).norm() < 1e-12);
        // small roll/pitch: world yaw ~ ego yaw + detection yaw
        assert!((b.yaw_rad - 1.1).abs() < 1e-3, "{}", b.yaw_rad);
        assert_eq!(b.size_lwh, det.box_lidar.size_lwh);
    }

    #[test]
    fn bad_input_is_an_error() {
        let pts = [Vector3::new(1.0, 0.0, 0.0)];
        let b = car(Vector3::zeros(), 0.0);
        let boxes: [&dyn BoxAtTime; 1] = [&b];
        let cfg = FilterConfig::default();
        let err = dynamic_feature_mask(&pts, &[], &identity_pose, &boxes, &cfg).unwrap_err();
        assert_eq!(
            err,
            FilterError::TimesLength {
                points: 1,
                times: 0
            }
        );
        let err =
            dynamic_feature_mask(&pts, &[f64::NAN], &identity_pose, &boxes, &cfg).unwrap_err();
        assert!(err.to_string().contains("point 0"), "{err}");
        let zero_bins = FilterConfig {
            time_bins: 0,
            ..cfg
        };
        let err =
            dynamic_feature_mask(&pts, &[0.0], &identity_pose, &boxes, &zero_bins).unwrap_err();
        assert!(err.to_string().contains("time_bins"), "{err}");
        let nan_inflate = FilterConfig {
            inflate_m: f64::NAN,
            ..cfg
        };
        let err =
            dynamic_feature_mask(&pts, &[0.0], &identity_pose, &boxes, &nan_inflate).unwrap_err();
        assert!(err.to_string().contains("inflate_m"), "{err}");
        assert!(filter_stats(&[true], &[]).is_err());
    }

    #[test]
    fn empty_inputs_give_empty_or_all_kept_masks() {
        let cfg = FilterConfig::default();
        let b = car(Vector3::zeros(), 0.0);
        let boxes: [&dyn BoxAtTime; 1] = [&b];
        assert!(
            dynamic_feature_mask(&[], &[], &identity_pose, &boxes, &cfg)
                .unwrap()
                .is_empty()
        );
        let pts = [Vector3::zeros(), Vector3::new(50.0, 0.0, 0.0)];
        let mask = dynamic_feature_mask(&pts, &[0.0, 0.1], &identity_pose, &[], &cfg).unwrap();
        assert_eq!(mask, vec![false, false]);
        // non-finite coordinates are never "inside" (and do not poison the culling)
        let odd = [
            Vector3::new(f64::NAN, 0.0, 0.0),
            Vector3::new(f64::INFINITY, 0.0, 0.0),
            Vector3::new(0.0, 0.5, 0.0),
        ];
        let mask =
            dynamic_feature_mask(&odd, &[0.0, 0.05, 0.1], &identity_pose, &boxes, &cfg).unwrap();
        assert_eq!(mask, vec![false, false, true]);
        // an over-shrunk box contains nothing, not even its centre
        let shrunk = FilterConfig {
            inflate_m: -3.0,
            ..cfg
        };
        let mask =
            dynamic_feature_mask(&pts, &[0.0, 0.1], &identity_pose, &boxes, &shrunk).unwrap();
        assert_eq!(mask, vec![false, false]);
    }

    /// Bin-centre evaluation agrees with the exact per-point test except
    /// within (relative speed x half a bin) of a face.
    #[test]
    fn binned_mask_matches_exact_per_point_test() {
        let cv = ConstantVelocityBox {
            box_ref: car(Vector3::new(10.0, 0.0, 0.75), 0.0),
            t_ref_s: 0.0,
            velocity_world_mps: Vector3::new(0.0, 20.0, 0.0),
            yaw_rate_radps: 0.0,
        };
        let pose = |t: f64| Isometry3::translation(10.0 * t, 0.0, 0.0);
        let cfg = FilterConfig::default();
        let mut pts = Vec::new();
        let mut times = Vec::new();
        for i in 0..2000 {
            let t = 0.1 * i as f64 / 1999.0;
            let y = -3.0 + 6.0 * ((i * 7919) % 2000) as f64 / 2000.0;
            // a point on the box's centre line, in the LiDAR frame of time t
            pts.push(Vector3::new(10.0 - 10.0 * t, y, 0.75));
            times.push(t);
        }
        let boxes: [&dyn BoxAtTime; 1] = [&cv];
        let mask = dynamic_feature_mask(&pts, &times, &pose, &boxes, &cfg).unwrap();
        // max timing error: half a bin of 0.01 s at 20 m/s = 0.1 m
        let tol_m = 0.1 + 1e-9;
        let mut checked = 0;
        for ((p, &t), &m) in pts.iter().zip(&times).zip(&mask) {
            let p_world = pose(t) * nalgebra::Point3::from(*p);
            let b = cv.box_at(t);
            let dist_to_face = ((p_world.y - b.center.y).abs() - (1.0 + cfg.inflate_m)).abs();
            if dist_to_face > tol_m {
                assert_eq!(m, b.contains(&p_world.coords, cfg.inflate_m), "t {t} p {p}");
                checked += 1;
            }
        }
        assert!(checked > 1500, "{checked}");
        assert!(mask.iter().any(|&m| m) && mask.iter().any(|&m| !m));
    }

    /// The culled, bin-prepared fast path equals a naive per-point world test
    /// at the same bin-centre times, for many boxes around a rolling sweep.
    #[test]
    fn fast_path_equals_naive_reference() {
        let pose = |t: f64| {
            Isometry3::from_parts(
                Translation3::new(12.0 * t, 1.0, 1.7),
                UnitQuaternion::from_euler_angles(0.01, -0.02, 0.5 * t),
            )
        };
        let cars: Vec<ConstantVelocityBox> = (0..12)
            .map(|i| {
                let a = 0.5 * i as f64;
                ConstantVelocityBox {
                    box_ref: car(Vector3::new(6.0 * a.cos(), 6.0 * a.sin(), -0.9), a),
                    t_ref_s: 0.0,
                    velocity_world_mps: Vector3::new(-10.0 + 2.0 * i as f64, 5.0, 0.0),
                    yaw_rate_radps: 0.2,
                }
            })
            .collect();
        let boxes: Vec<&dyn BoxAtTime> = cars.iter().map(|c| c as &dyn BoxAtTime).collect();
        let cfg = FilterConfig {
            inflate_bottom_m: 0.1,
            time_bins: 7,
            ..FilterConfig::default()
        };
        let n = 20_000;
        let mut pts = Vec::with_capacity(n);
        let mut times = Vec::with_capacity(n);
        for i in 0..n {
            let t = 0.1 * i as f64 / n as f64;
            let az = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
            let r = 3.0 + 6.0 * ((i * 7919) % 1000) as f64 / 1000.0;
            let z = -2.0 + 2.5 * ((i * 104_729) % 997) as f64 / 997.0;
            pts.push(Vector3::new(r * az.cos(), r * az.sin(), z));
            times.push(t);
        }
        let mask = dynamic_feature_mask(&pts, &times, &pose, &boxes, &cfg).unwrap();
        let width = (times[n - 1] - times[0]) / cfg.time_bins as f64;
        let mut removed = 0;
        for ((p, &t), &m) in pts.iter().zip(&times).zip(&mask) {
            let bin = (((t - times[0]) / width) as usize).min(cfg.time_bins - 1);
            let t_bin = times[0] + (bin as f64 + 0.5) * width;
            let p_world = (pose(t_bin) * nalgebra::Point3::from(*p)).coords;
            let expected = cars.iter().any(|c| {
                c.box_at(t_bin)
                    .contains_inflated(&p_world, cfg.inflate_m, cfg.inflate_bottom_m)
            });
            assert_eq!(m, expected, "t {t} p {p}");
            removed += m as usize;
        }
        assert!(removed > 100 && removed < n / 2, "{removed}");
    }

    /// More boxes than one word of the cull grid holds, spread over a wide
    /// area (coarser cells): the mask still equals the naive test.
    #[test]
    fn many_scattered_boxes_equal_the_naive_test() {
        let cars: Vec<OrientedBox> = (0..150)
            .map(|i| {
                let a = 0.37 * i as f64;
                let r = 5.0 + 3.0 * i as f64;
                car(Vector3::new(r * a.cos(), r * a.sin(), 0.0), a)
            })
            .collect();
        let boxes: Vec<&dyn BoxAtTime> = cars.iter().map(|c| c as &dyn BoxAtTime).collect();
        let cfg = FilterConfig::default();
        let n = 30_000;
        let pts: Vec<Vector3<f64>> = (0..n)
            .map(|i| {
                // near the box centres half the time, anywhere otherwise
                let c = cars[(i * 7919) % cars.len()].center;
                let u = |k: usize| ((i * k) % 1000) as f64 / 1000.0 - 0.5;
                if i % 2 == 0 {
                    c + Vector3::new(8.0 * u(104_729), 4.0 * u(1_299_709), 2.0 * u(15_485_863))
                } else {
                    Vector3::new(900.0 * u(104_729), 900.0 * u(1_299_709), 2.0 * u(7))
                }
            })
            .collect();
        let mut pts = pts;
        pts.push(Vector3::new(f64::NAN, 0.0, 0.0));
        let times = vec![0.0; pts.len()];
        let mask = dynamic_feature_mask(&pts, &times, &identity_pose, &boxes, &cfg).unwrap();
        let mut removed = 0;
        for (p, &m) in pts.iter().zip(&mask) {
            let expected = cars
                .iter()
                .any(|c| c.contains_inflated(p, cfg.inflate_m, cfg.inflate_bottom_m));
            assert_eq!(m, expected, "{p}");
            removed += m as usize;
        }
        assert!(removed > 1000 && removed < n / 2, "{removed}");
    }

    #[test]
    fn all_boxes_mask_uses_static_boxes() {
        let parked = car(Vector3::new(10.0, 5.0, 0.75), 0.0);
        let pts = [
            Vector3::new(10.0, 5.0, 0.75),
            Vector3::new(10.0, -5.0, 0.75),
        ];
        let mask = all_boxes_mask(
            &pts,
            &[0.0, 0.05],
            &identity_pose,
            &[parked],
            &FilterConfig::default(),
        )
        .unwrap();
        assert_eq!(mask, vec![true, false]);
    }

    #[test]
    fn stats_count_hand_cases() {
        let mask = [true, true, false, false, true];
        let labels = [true, false, true, false, true];
        let s = filter_stats(&mask, &labels).unwrap();
        assert_eq!(
            (s.total, s.removed, s.moving, s.true_positive),
            (5, 3, 3, 2)
        );
        assert_eq!((s.false_positive, s.false_negative), (1, 1));
        assert!((s.precision - 2.0 / 3.0).abs() < 1e-12);
        assert!((s.recall - 2.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn config_validation_names_the_field() {
        assert!(FilterConfig::default().validate().is_ok());
        for (config, field) in [
            (
                FilterConfig {
                    inflate_m: f64::NAN,
                    ..FilterConfig::default()
                },
                "inflate_m",
            ),
            (
                FilterConfig {
                    time_bins: 0,
                    ..FilterConfig::default()
                },
                "time_bins",
            ),
            (
                FilterConfig {
                    detection_track_gate_m: -1.0,
                    ..FilterConfig::default()
                },
                "detection_track_gate_m",
            ),
            (
                FilterConfig {
                    detection_track_gate_m: f64::INFINITY,
                    ..FilterConfig::default()
                },
                "detection_track_gate_m",
            ),
        ] {
            let err = config.validate().unwrap_err();
            assert!(err.to_string().contains(field), "{err}");
        }
    }
}
