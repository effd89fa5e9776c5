//! Motion compensation ("de-skew") of a rolling LiDAR sweep.
//!
//! A spinning LiDAR measures each point at its own time while the sensor
//! moves; the raw points of one sweep are therefore each in a different
//! LiDAR frame. [`deskew`] moves every point into the single LiDAR frame at a
//! reference time with the sensor motion over the sweep, given as timed pose
//! samples ([`SweepMotion`], filled by the pipeline from IMU propagation, so
//! the motion model is nonlinear: piecewise constant twist between samples).

use crate::input::LidarScan;
use crate::lie::{so3_exp_quat, so3_log_quat};
use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};

/// Why a [`SweepMotion`] could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DeskewError {
    /// No pose sample was given.
    #[error("sweep motion needs at least one pose sample")]
    NoSamples,
    /// A sample's time, translation or rotation is NaN or infinite.
    #[error("sweep motion sample {index}: field `{field}` is not finite")]
    NotFinite {
        /// Index of the offending sample.
        index: usize,
        /// `"t_s"`, `"translation"` or `"rotation"`.
        field: &'static str,
    },
    /// Sample times are not strictly increasing.
    #[error(
        "sweep motion sample {index} at t={t_s} s is not after the previous sample at t={previous_t_s} s"
    )]
    TimeNotIncreasing {
        /// Index of the offending sample.
        index: usize,
        /// Its time (s).
        t_s: f64,
        /// Time of the sample before it (s).
        previous_t_s: f64,
    },
}

/// The LiDAR pose `t_world_lidar` over a sweep, as timed samples.
///
/// Between samples the rotation is interpolated by slerp
/// (`R_k·Exp(α·Log(R_k⁻¹R_{k+1}))`) and the translation linearly; before the
/// first and after the last sample the end segment's velocity is
/// extrapolated. One sample means no motion.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepMotion {
    times_s: Vec<f64>,
    poses: Vec<Isometry3<f64>>,
    /// `Log(R_k⁻¹R_{k+1})` per segment (one fewer than samples).
    segment_rotvec: Vec<Vector3<f64>>,
}

impl SweepMotion {
    /// Builds the motion from `(t_s, t_world_lidar)` samples with strictly
    /// increasing, finite times.
    ///
    /// # Errors
    /// [`DeskewError::NoSamples`] for an empty list,
    /// [`DeskewError::NotFinite`] for a non-finite time or pose,
    /// [`DeskewError::TimeNotIncreasing`] when times do not strictly increase.
    pub fn from_poses(samples: Vec<(f64, Isometry3<f64>)>) -> Result<SweepMotion, DeskewError> {
        if samples.is_empty() {
            return Err(DeskewError::NoSamples);
        }
        let mut times_s = Vec::with_capacity(samples.len());
        let mut poses = Vec::with_capacity(samples.len());
        for (index, (t_s, pose)) in samples.into_iter().enumerate() {
            if !t_s.is_finite() {
                return Err(DeskewError::NotFinite {
                    index,
                    field: "t_s",
                });
            }
            if !pose.translation.vector.iter().all(|v| v.is_finite()) {
                return Err(DeskewError::NotFinite {
                    index,
                    field: "translation",
                });
            }
            if !pose.rotation.coords.iter().all(|v| v.is_finite()) {
                return Err(DeskewError::NotFinite {
                    index,
                    field: "rotation",
                });
            }
            if let Some(&previous_t_s) = times_s.last()
                && t_s <= previous_t_s
            {
                return Err(DeskewError::TimeNotIncreasing {
                    index,
                    t_s,
                    previous_t_s,
                });
            }
            times_s.push(t_s);
            poses.push(pose);
        }
        let segment_rotvec = poses
            .windows(2)
            .map(|w| so3_log_quat(&(w[0].rotation.inverse() * w[1].rotation)))
            .collect();
        Ok(SweepMotion {
            times_s,
            poses,
            segment_rotvec,
        })
    }

    /// Constant linear and angular velocity between two poses (the classic
    /// LOAM assumption; prefer IMU samples when available).
    ///
    /// # Errors
    /// As [`SweepMotion::from_poses`] on the two samples.
    pub fn constant_velocity(
        t0_s: f64,
        t_world_lidar_t0: Isometry3<f64>,
        t1_s: f64,
        t_world_lidar_t1: Isometry3<f64>,
    ) -> Result<SweepMotion, DeskewError> {
        SweepMotion::from_poses(vec![(t0_s, t_world_lidar_t0), (t1_s, t_world_lidar_t1)])
    }

    /// Sample times (strictly increasing).
    pub fn times_s(&self) -> &[f64] {
        &self.times_s
    }

    /// Sample poses `t_world_lidar`.
    pub fn poses(&self) -> &[Isometry3<f64>] {
        &self.poses
    }

    /// Index `k` of the segment `[t_k, t_{k+1}]` used at `t_s` (the end
    /// segments extend to ±∞); `None` for a single sample.
    fn segment_of(&self, t_s: f64) -> Option<usize> {
        let n = self.times_s.len();
        if n < 2 {
            return None;
        }
        // number of samples at or before t, minus one, clamped to a segment
        let after = self.times_s.partition_point(|&t| t <= t_s);
        Some(after.saturating_sub(1).min(n - 2))
    }

    /// `(α, k)`: the interpolation parameter in segment `k` (outside [0, 1]
    /// when extrapolating).
    fn alpha(&self, k: usize, t_s: f64) -> f64 {
        (t_s - self.times_s[k]) / (self.times_s[k + 1] - self.times_s[k])
    }

    /// `t_world_lidar` at `t_s`; returns the samples exactly at their times.
    pub fn pose_at(&self, t_s: f64) -> Isometry3<f64> {
        let Some(k) = self.segment_of(t_s) else {
            return self.poses[0];
        };
        if t_s == self.times_s[k] {
            return self.poses[k];
        }
        if t_s == self.times_s[k + 1] {
            return self.poses[k + 1];
        }
        let alpha = self.alpha(k, t_s);
        let (p0, p1) = (&self.poses[k], &self.poses[k + 1]);
        let rotation = p0.rotation * so3_exp_quat(&(self.segment_rotvec[k] * alpha));
        let translation = p0.translation.vector.lerp(&p1.translation.vector, alpha);
        Isometry3::from_parts(Translation3::from(translation), rotation)
    }
}

/// Per-segment pieces of `pose_at(t_ref)⁻¹·pose_at(t)`, so that a point costs
/// one axis-angle rotation instead of a full interpolation and inversion:
/// `T_ref⁻¹·T(t)·p = A·Exp(α·θ·axis)·p + b + α·c`.
#[derive(Debug, Clone, Copy)]
struct SegmentTransform {
    t0_s: f64,
    inv_dt: f64,
    /// `R_ref⁻¹·R_k`.
    a: Matrix3<f64>,
    axis: Vector3<f64>,
    angle_rad: f64,
    /// `R_ref⁻¹·(p_k − p_ref)`.
    b: Vector3<f64>,
    /// `R_ref⁻¹·(p_{k+1} − p_k)`.
    c: Vector3<f64>,
}

/// `(sin x, cos x)`; Taylor series for the small angles of one segment
/// (truncated below 1e-15, i.e. exact to rounding, and several times
/// faster than `sin_cos`), `sin_cos` beyond |x| = 0.25.
#[inline]
fn sin_cos(x: f64) -> (f64, f64) {
    let ax = x.abs();
    if ax < 0.02 {
        // the usual case (a segment turns < 0.02 rad); truncation < 3e-16
        let x2 = x * x;
        let s = x * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0)));
        let c = 1.0 + x2 * (-0.5 + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0)));
        (s, c)
    } else if ax < 0.25 {
        // Horner with reciprocal factorials (multiplications only)
        let x2 = x * x;
        let s = x
            * (1.0
                + x2 * (-1.0 / 6.0
                    + x2 * (1.0 / 120.0
                        + x2 * (-1.0 / 5040.0
                            + x2 * (1.0 / 362_880.0 + x2 * (-1.0 / 39_916_800.0))))));
        let c = 1.0
            + x2 * (-0.5
                + x2 * (1.0 / 24.0
                    + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40_320.0 + x2 * (-1.0 / 3_628_800.0)))));
        (s, c)
    } else {
        x.sin_cos()
    }
}

impl SegmentTransform {
    #[inline]
    fn alpha(&self, t_s: f64) -> f64 {
        (t_s - self.t0_s) * self.inv_dt
    }

    /// `(rotation, translation)` of `T_ref⁻¹·T(t)` at `t_s`.
    #[inline]
    fn at(&self, t_s: f64) -> (Matrix3<f64>, Vector3<f64>) {
        let alpha = self.alpha(t_s);
        if self.angle_rad == 0.0 {
            return (self.a, self.b + self.c * alpha);
        }
        let r = self.rotation_at(alpha);
        (self.a * r, self.b + self.c * alpha)
    }

    /// `Exp(α·θ·axis)` by Rodrigues: `R = cI + s[k]× + (1−c)kkᵀ`.
    #[inline]
    fn rotation_at(&self, alpha: f64) -> Matrix3<f64> {
        let (s, c) = sin_cos(alpha * self.angle_rad);
        let k = &self.axis;
        let omc = 1.0 - c;
        Matrix3::new(
            c + omc * k.x * k.x,
            omc * k.x * k.y - s * k.z,
            omc * k.x * k.z + s * k.y,
            omc * k.y * k.x + s * k.z,
            c + omc * k.y * k.y,
            omc * k.y * k.z - s * k.x,
            omc * k.z * k.x - s * k.y,
            omc * k.z * k.y + s * k.x,
            c + omc * k.z * k.z,
        )
    }

    /// `T_ref⁻¹·T(t)·p` for a single point (vector form of Rodrigues, cheaper
    /// than building the matrix when no other point shares the time).
    #[inline]
    fn apply(&self, t_s: f64, p: &Vector3<f64>) -> Vector3<f64> {
        let alpha = self.alpha(t_s);
        let (s, c) = sin_cos(alpha * self.angle_rad);
        let k = &self.axis;
        let v = p * c + k.cross(p) * s + k * (k.dot(p) * (1.0 - c));
        self.a * v + self.b + self.c * alpha
    }

    /// `T_ref⁻¹·T(t)` at `steps + 1` equal steps of α over `alpha_lo ..
    /// alpha_lo + alpha_span`: the rotation at each step but the last and its
    /// difference to the next, for [`RotationSteps::apply`].
    fn push_steps(
        &self,
        alpha_lo: f64,
        alpha_span: f64,
        steps: usize,
        out: &mut Vec<(Matrix3<f64>, Matrix3<f64>)>,
    ) {
        let rotation_at_step =
            |j: usize| self.a * self.rotation_at(alpha_lo + alpha_span * (j as f64 / steps as f64));
        let mut next = rotation_at_step(0);
        for j in 0..steps {
            let current = next;
            next = rotation_at_step(j + 1);
            out.push((current, next - current));
        }
    }
}

/// Largest rotation between two table steps, rad: linear interpolation
/// between the exact rotations at a step's ends is off by at most
/// `step² / 8` of the point's range (the chord's sagitta).
const MAX_STEP_RAD: f64 = 5.0e-5;

/// How far a de-skewed point may be from its exact transform
/// `pose_at(t_ref)⁻¹·pose_at(t)·p`, as a fraction of its range, beyond
/// rounding: the rotation table's `MAX_STEP_RAD² / 8`, 3.2e-10 (4e-8 m at
/// 120 m, far below an f32 coordinate's resolution there).
pub const DESKEW_RELATIVE_TOLERANCE: f64 = MAX_STEP_RAD * MAX_STEP_RAD / 8.0;

/// Segments that would need more steps keep the exact per-point rotation
/// (fast spins: the table would cost more than it saves).
const MAX_STEPS: usize = 1024;

/// One segment's rotation table.
#[derive(Debug, Default, Clone, Copy)]
enum SegmentSteps {
    /// Not built yet (no point with its own time has reached the segment).
    #[default]
    Unbuilt,
    /// The segment turns too fast: every point gets the exact rotation.
    Exact,
    /// `steps` steps of α from `alpha_lo`, from `entries[first]`.
    Table {
        first: usize,
        steps: usize,
        alpha_lo: f64,
        /// `steps / alpha_span`.
        steps_per_alpha: f64,
    },
}

/// For sweeps whose points each have their own time (KITTI, rosbag clouds):
/// each segment's rotation tabulated in steps of at most [`MAX_STEP_RAD`],
/// so that a point costs a linear interpolation instead of a sine and a
/// cosine. A segment's table spans its α range within the sweep
/// (`0..1`, beyond it in the first and last segments, which extrapolate);
/// it is built on the segment's first such point.
#[derive(Debug, Default, Clone)]
struct RotationSteps {
    segments: Vec<SegmentSteps>,
    /// `(rotation at the step's start, difference to the next step's)`.
    entries: Vec<(Matrix3<f64>, Matrix3<f64>)>,
    /// The sweep's time span, s.
    sweep_s: (f64, f64),
}

impl RotationSteps {
    fn reset(&mut self, segments: usize, sweep_s: (f64, f64)) {
        self.segments.clear();
        self.segments.resize(segments, SegmentSteps::default());
        self.entries.clear();
        self.sweep_s = sweep_s;
    }

    /// Tabulates segment `k` of `n`, or marks it exact-only.
    fn build(&mut self, k: usize, n: usize, segment: &SegmentTransform) {
        let mut lo: f64 = 0.0;
        let mut hi: f64 = 1.0;
        if k == 0 {
            lo = lo.min(segment.alpha(self.sweep_s.0));
        }
        if k + 1 == n {
            hi = hi.max(segment.alpha(self.sweep_s.1));
        }
        let needed = ((hi - lo) * segment.angle_rad / MAX_STEP_RAD).ceil();
        self.segments[k] = if needed.is_finite() && needed <= MAX_STEPS as f64 {
            let steps = (needed as usize).max(1);
            let first = self.entries.len();
            segment.push_steps(lo, hi - lo, steps, &mut self.entries);
            SegmentSteps::Table {
                first,
                steps,
                alpha_lo: lo,
                steps_per_alpha: steps as f64 / (hi - lo),
            }
        } else {
            SegmentSteps::Exact
        };
    }

    /// `T_ref⁻¹·T(t)·p` in segment `k` of the sweep's segments, within
    /// [`DESKEW_RELATIVE_TOLERANCE`]` · |p|` of [`SegmentTransform::apply`]; that
    /// function itself outside the table's span and for segments that turn
    /// too fast.
    #[inline]
    fn apply(
        &mut self,
        k: usize,
        segment: &SegmentTransform,
        t_s: f64,
        p: &Vector3<f64>,
    ) -> Vector3<f64> {
        if segment.angle_rad == 0.0 {
            return segment.apply(t_s, p);
        }
        if matches!(self.segments[k], SegmentSteps::Unbuilt) {
            self.build(k, self.segments.len(), segment);
        }
        let SegmentSteps::Table {
            first,
            steps,
            alpha_lo,
            steps_per_alpha,
        } = self.segments[k]
        else {
            return segment.apply(t_s, p);
        };
        let alpha = segment.alpha(t_s);
        let u = (alpha - alpha_lo) * steps_per_alpha;
        if !(u >= 0.0 && u < steps as f64) {
            return segment.apply(t_s, p);
        }
        // 0 <= u < steps <= MAX_STEPS: a u32 conversion is exact and cheap
        let j = (u as u32 as usize).min(steps - 1);
        let f = u - j as f64;
        let (rotation, difference) = &self.entries[first + j];
        (rotation + difference * f) * p + segment.b + segment.c * alpha
    }
}

/// Reusable de-skew state (per-segment transforms); [`deskew`] builds a
/// temporary one.
#[derive(Debug, Default, Clone)]
pub struct Deskewer {
    segments: Vec<SegmentTransform>,
    steps: RotationSteps,
}

impl Deskewer {
    /// An empty de-skewer; its buffers grow on first use and are reused.
    pub fn new() -> Deskewer {
        Deskewer::default()
    }

    /// Same as [`deskew`], reusing this de-skewer's per-segment buffers.
    pub fn deskew(
        &mut self,
        scan: &LidarScan,
        motion: &SweepMotion,
        t_ref_s: f64,
        out: &mut Vec<Vector3<f64>>,
    ) {
        self.prepare(motion, t_ref_s);
        let sweep_s = (scan.t_s, scan.t_s + scan.sweep_duration_s);
        self.steps.reset(self.segments.len(), sweep_s);
        out.clear();
        out.reserve(scan.points.len());
        let n_seg = self.segments.len();
        let points = &scan.points;
        let mut current = 0usize;
        let mut i = 0;
        while i < points.len() {
            let tau = points[i].time_offset_s;
            let t_s = scan.t_s + tau as f64;
            // Points come in (roughly) time order: try the current segment
            // first, fall back to a binary search.
            if n_seg > 1 {
                let inside_lo = current == 0 || t_s >= self.segments[current].t0_s;
                let inside_hi = current + 1 == n_seg || t_s < self.segments[current + 1].t0_s;
                if !(inside_lo && inside_hi) {
                    current = motion.segment_of(t_s).unwrap_or(0);
                }
            }
            let segment = &self.segments[current];
            // a run of points sharing the time (one firing column) shares
            // the transform
            let mut j = i + 1;
            while j < points.len() && points[j].time_offset_s == tau {
                j += 1;
            }
            if j - i >= 3 {
                let (rotation, translation) = segment.at(t_s);
                for p in &points[i..j] {
                    out.push(rotation * p.position() + translation);
                }
            } else {
                for p in &points[i..j] {
                    out.push(self.steps.apply(current, segment, t_s, &p.position()));
                }
            }
            i = j;
        }
    }

    fn prepare(&mut self, motion: &SweepMotion, t_ref_s: f64) {
        let t_ref = motion.pose_at(t_ref_s);
        let r_ref_inv = t_ref.rotation.inverse();
        let p_ref = t_ref.translation.vector;
        self.segments.clear();
        let n = motion.times_s.len();
        if n == 1 {
            let p0 = &motion.poses[0];
            self.segments.push(SegmentTransform {
                t0_s: motion.times_s[0],
                inv_dt: 0.0,
                a: (r_ref_inv * p0.rotation).to_rotation_matrix().into_inner(),
                axis: Vector3::z(),
                angle_rad: 0.0,
                b: r_ref_inv * (p0.translation.vector - p_ref),
                c: Vector3::zeros(),
            });
            return;
        }
        for k in 0..n - 1 {
            let (p0, p1) = (&motion.poses[k], &motion.poses[k + 1]);
            let rotvec = motion.segment_rotvec[k];
            let angle_rad = rotvec.norm();
            let (axis, angle_rad) = if angle_rad > 0.0 {
                (rotvec / angle_rad, angle_rad)
            } else {
                (Vector3::z(), 0.0)
            };
            let a: UnitQuaternion<f64> = r_ref_inv * p0.rotation;
            self.segments.push(SegmentTransform {
                t0_s: motion.times_s[k],
                inv_dt: 1.0 / (motion.times_s[k + 1] - motion.times_s[k]),
                a: a.to_rotation_matrix().into_inner(),
                axis,
                angle_rad,
                b: r_ref_inv * (p0.translation.vector - p_ref),
                c: r_ref_inv * (p1.translation.vector - p0.translation.vector),
            });
        }
    }
}

/// Moves every point of `scan` (measured at `scan.t_s + time_offset_s`, in the
/// LiDAR frame of that instant) into the LiDAR frame at `t_ref_s`:
/// `pose_at(t_ref)⁻¹·pose_at(t)·p`. `out[i]` corresponds to `scan.points[i]`.
///
/// Exact with respect to [`SweepMotion::pose_at`] (up to floating-point
/// rounding, ~1e-15 relative): the per-segment pieces of the relative
/// transform are precomputed once, each point then costs one axis-angle
/// rotation, and points sharing a time (one firing column) share it. The
/// only approximation is the motion model itself (piecewise slerp/linear
/// between samples), so the samples must be dense enough for the motion.
///
/// ```
/// use limot_estimator::input::{LidarPoint, LidarScan};
/// use limot_estimator::lidar::{SweepMotion, deskew};
/// use nalgebra::{Isometry3, Vector3};
///
/// // The sensor moves 1 m along x during a 0.1 s sweep.
/// let motion = SweepMotion::constant_velocity(
///     0.0,
///     Isometry3::identity(),
///     0.1,
///     Isometry3::translation(1.0, 0.0, 0.0),
/// )
/// .unwrap();
/// // A point 5 m ahead, measured half-way through the sweep.
/// let point = LidarPoint { x: 5.0, y: 0.0, z: 0.0, intensity: 0.0, ring: 0, time_offset_s: 0.05 };
/// let scan = LidarScan { t_s: 0.0, sweep_duration_s: 0.1, num_rings: 1, points: vec![point] };
/// let mut out = Vec::new();
/// deskew(&scan, &motion, 0.0, &mut out);
/// // In the LiDAR frame at the start of the sweep it is 5.5 m ahead
/// // (`time_offset_s` is an f32, hence the tolerance).
/// assert!((out[0] - Vector3::new(5.5, 0.0, 0.0)).norm() < 1e-6);
/// ```
pub fn deskew(scan: &LidarScan, motion: &SweepMotion, t_ref_s: f64, out: &mut Vec<Vector3<f64>>) {
    Deskewer::new().deskew(scan, motion, t_ref_s, out);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::LidarPoint;

    fn pose(x: f64, y: f64, z: f64, rx: f64, ry: f64, rz: f64) -> Isometry3<f64> {
        Isometry3::new(Vector3::new(x, y, z), Vector3::new(rx, ry, rz))
    }

    fn sample_motion() -> SweepMotion {
        SweepMotion::from_poses(vec![
            (10.0, pose(0.0, 0.0, 0.0, 0.0, 0.0, 0.1)),
            (10.03, pose(0.3, 0.01, 0.0, 0.01, 0.0, 0.12)),
            (10.07, pose(0.7, 0.04, 0.01, 0.02, -0.01, 0.15)),
            (10.1, pose(1.0, 0.08, 0.01, 0.02, -0.02, 0.19)),
        ])
        .unwrap()
    }

    #[test]
    fn pose_at_returns_samples_exactly() {
        let m = sample_motion();
        for (t, p) in m.times_s().iter().zip(m.poses()) {
            assert_eq!(m.pose_at(*t), *p);
        }
    }

    #[test]
    fn pose_at_interpolates_and_extrapolates_linearly() {
        let m = sample_motion();
        // midpoint of the first segment: half translation, half rotation
        let mid = m.pose_at(10.015);
        let expected_t = (m.poses()[0].translation.vector + m.poses()[1].translation.vector) / 2.0;
        assert!((mid.translation.vector - expected_t).norm() < 1e-12);
        let q0 = m.poses()[0].rotation;
        let q1 = m.poses()[1].rotation;
        assert!(mid.rotation.angle_to(&q0.slerp(&q1, 0.5)) < 1e-12);
        // extrapolation after the end continues the last segment's velocity
        let last = &m.poses()[3];
        let prev = &m.poses()[2];
        let after = m.pose_at(10.13);
        let v = (last.translation.vector - prev.translation.vector) / 0.03;
        assert!((after.translation.vector - (last.translation.vector + v * 0.03)).norm() < 1e-9);
        let before = m.pose_at(9.97);
        let v0 = (m.poses()[1].translation.vector - m.poses()[0].translation.vector) / 0.03;
        assert!(
            (before.translation.vector - (m.poses()[0].translation.vector - v0 * 0.03)).norm()
                < 1e-9
        );
    }

    #[test]
    fn small_angle_sin_cos_is_exact_to_rounding() {
        for k in -3000..=3000 {
            let x = k as f64 * 0.25 / 3000.0 * 0.999_999;
            let (s, c) = sin_cos(x);
            assert!((s - x.sin()).abs() < 4e-16, "{x}"); // a few ulps
            assert!((c - x.cos()).abs() < 4e-16, "{x}"); // a few ulps
        }
    }

    #[test]
    fn bad_samples_are_rejected() {
        assert_eq!(
            SweepMotion::from_poses(vec![]).unwrap_err(),
            DeskewError::NoSamples
        );
        let err = SweepMotion::from_poses(vec![
            (1.0, Isometry3::identity()),
            (1.0, Isometry3::identity()),
        ])
        .unwrap_err();
        assert!(matches!(
            err,
            DeskewError::TimeNotIncreasing { index: 1, .. }
        ));
        assert!(err.to_string().contains("sample 1"), "{err}");
        let err = SweepMotion::from_poses(vec![(f64::NAN, Isometry3::identity())]).unwrap_err();
        assert!(matches!(
            err,
            DeskewError::NotFinite {
                index: 0,
                field: "t_s"
            }
        ));
        let err =
            SweepMotion::constant_velocity(0.0, Isometry3::identity(), -1.0, Isometry3::identity())
                .unwrap_err();
        assert!(matches!(err, DeskewError::TimeNotIncreasing { .. }));
        let bad = pose(f64::INFINITY, 0.0, 0.0, 0.0, 0.0, 0.0);
        let err = SweepMotion::from_poses(vec![(0.0, bad)]).unwrap_err();
        assert!(matches!(
            err,
            DeskewError::NotFinite {
                field: "translation",
                ..
            }
        ));
    }

    #[test]
    fn single_sample_means_no_motion() {
        let p = pose(1.0, 2.0, 3.0, 0.1, 0.2, 0.3);
        let m = SweepMotion::from_poses(vec![(5.0, p)]).unwrap();
        assert_eq!(m.pose_at(-100.0), p);
        assert_eq!(m.pose_at(100.0), p);
        let scan = LidarScan {
            t_s: 5.0,
            sweep_duration_s: 0.1,
            num_rings: 1,
            points: vec![LidarPoint {
                x: 1.0,
                y: 2.0,
                z: 3.0,
                intensity: 0.0,
                ring: 0,
                time_offset_s: 0.05,
            }],
        };
        let mut out = Vec::new();
        deskew(&scan, &m, 5.1, &mut out);
        assert!((out[0] - Vector3::new(1.0, 2.0, 3.0)).norm() < 1e-12);
    }

    /// Every `out[i]` is within `1e-12 + relative_tolerance · |p|` of the
    /// definition `pose_at(t_ref)⁻¹·pose_at(t)·p` of `scan.points[i]`.
    fn assert_matches_definition(
        scan: &LidarScan,
        motion: &SweepMotion,
        t_ref: f64,
        out: &[Vector3<f64>],
        relative_tolerance: f64,
    ) {
        assert_eq!(out.len(), scan.points.len());
        let inv_ref = motion.pose_at(t_ref).inverse();
        for (p, q) in scan.points.iter().zip(out) {
            let t = scan.t_s + p.time_offset_s as f64;
            let expected = inv_ref * motion.pose_at(t) * nalgebra::Point3::from(p.position());
            let bound = 1e-12 + relative_tolerance * p.position().norm();
            assert!((expected.coords - q).norm() < bound, "{t}");
        }
    }

    /// The fast path equals the definition `pose_at(t_ref)⁻¹·pose_at(t)·p`
    /// (to the rotation table's bound), also for unordered times and times
    /// outside the samples.
    #[test]
    fn deskew_matches_the_definition() {
        let m = sample_motion();
        let times = [
            0.05f32, 0.0, 0.1, 0.02, 0.02, 0.099, -0.01, 0.12, 0.071, 0.03,
        ];
        let points: Vec<LidarPoint> = times
            .iter()
            .enumerate()
            .map(|(i, &tau)| LidarPoint {
                x: 10.0 + i as f32,
                y: -3.0 * i as f32,
                z: 0.5,
                intensity: 0.0,
                ring: 0,
                time_offset_s: tau,
            })
            .collect();
        let scan = LidarScan {
            t_s: 10.0,
            sweep_duration_s: 0.1,
            num_rings: 1,
            points,
        };
        let mut out = Vec::new();
        for t_ref in [10.0, 10.05, 10.1] {
            deskew(&scan, &m, t_ref, &mut out);
            assert_eq!(out.len(), scan.points.len());
            // single-time points go through the rotation table
            assert_matches_definition(&scan, &m, t_ref, &out, DESKEW_RELATIVE_TOLERANCE);
        }
    }

    /// Points that each have their own time (KITTI) go through the rotation
    /// table: within its documented bound of the definition, and a segment
    /// that turns too fast keeps the exact rotation.
    #[test]
    fn per_point_times_use_the_table_within_its_bound() {
        // 0.3 rad/s of yaw and some roll, IMU-rate samples (10 ms)
        let samples: Vec<(f64, Isometry3<f64>)> = (0..=10)
            .map(|i| {
                let t = i as f64 * 0.01;
                (
                    5.0 + t,
                    pose(12.0 * t, 0.5 * t * t, 0.0, 0.05 * t, 0.0, 0.3 * t),
                )
            })
            .collect();
        let m = SweepMotion::from_poses(samples).unwrap();
        let points: Vec<LidarPoint> = (0..5000)
            .map(|i| {
                let az = i as f32 * 0.0123;
                let range = 2.0 + (i % 97) as f32;
                LidarPoint {
                    x: range * az.cos(),
                    y: range * az.sin(),
                    z: -1.7,
                    intensity: 0.0,
                    ring: (i % 64) as u16,
                    // distinct times, as KITTI's, and a few beyond the samples
                    time_offset_s: i as f32 * 2.1e-5 - 0.001,
                }
            })
            .collect();
        let scan = LidarScan {
            t_s: 5.0,
            sweep_duration_s: 0.1,
            num_rings: 64,
            points,
        };
        let mut deskewer = Deskewer::new();
        let mut out = Vec::new();
        for t_ref in [5.0, 5.05, 5.1] {
            deskewer.deskew(&scan, &m, t_ref, &mut out);
            assert!(deskewer.steps.entries.len() >= 10 * 45, "the table is used");
            assert_matches_definition(&scan, &m, t_ref, &out, DESKEW_RELATIVE_TOLERANCE);
        }
        // 20 rad/s: 0.2 rad per segment is beyond MAX_STEPS steps, exact
        let fast = SweepMotion::constant_velocity(
            5.0,
            Isometry3::identity(),
            5.1,
            pose(1.0, 0.0, 0.0, 0.0, 0.0, 2.0),
        )
        .unwrap();
        deskewer.deskew(&scan, &fast, 5.0, &mut out);
        assert!(deskewer.steps.entries.is_empty());
        assert_matches_definition(&scan, &fast, 5.0, &out, 0.0);
    }
}
