//! Voxel-grid downsampling (PCL `VoxelGrid` semantics, as LOAM / LIO-SAM use).
//!
//! Each occupied voxel of an axis-aligned grid with edge `voxel_m` (cell
//! `[i·v, (i+1)·v)` on every axis) yields ONE point: the **centroid** of the
//! input points that fall into it. The centroid (rather than the input point
//! closest to it) is what PCL's `VoxelGrid` returns and what LIO-SAM's map
//! voxel sizes were tuned with; it averages range noise over the voxel, which
//! makes the line/plane fits of scan matching less noisy, and because a voxel
//! is convex the centroid always lies inside its voxel. Points on one plane or
//! one line keep their centroid on that plane / line.
//!
//! Output order is deterministic: voxels appear in the order of their first
//! input point, so equal inputs give bit-identical outputs.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use nalgebra::Vector3;

/// Integer voxel coordinates `(floor(x/v), floor(y/v), floor(z/v))`.
pub type VoxelKey = (i64, i64, i64);

/// `floor(v)` as an integer. `f64::floor` is a libm call on baseline x86-64
/// (no SSE4.1 `roundsd`); truncation plus a
/// correction is exact for every `v` in the `i64` range and saturates
/// beyond it (NaN gives 0). Magnitudes below 2^62, every coordinate a map
/// holds, skip the saturating cast's range checks: they were a fifth of the
/// voxel downsampling's time.
#[inline]
pub(crate) fn floor_to_i64(v: f64) -> i64 {
    if v.abs() < TRUNCATION_EXACT_BELOW {
        // SAFETY: |v| < 2^62, so its truncation is an i64.
        let t: i64 = unsafe { v.to_int_unchecked() };
        // Without a branch: half the coordinates of a scan are negative,
        // which makes "truncation rounded up" unpredictable.
        t - i64::from((t as f64) > v)
    } else {
        let t = v as i64;
        t.saturating_sub(i64::from((t as f64) > v))
    }
}

/// Below this magnitude (2^62) a truncation needs no saturation.
const TRUNCATION_EXACT_BELOW: f64 = 4_611_686_018_427_387_904.0;

/// Voxel key of `p` for voxel edge `voxel_m` (> 0). Coordinates beyond the
/// `i64` range saturate, which only merges voxels at absurd distances.
#[inline]
pub fn voxel_key(p: &Vector3<f64>, voxel_m: f64) -> VoxelKey {
    (
        floor_to_i64(p.x / voxel_m),
        floor_to_i64(p.y / voxel_m),
        floor_to_i64(p.z / voxel_m),
    )
}

/// A small multiplicative (Fx-style) hasher for integer voxel keys: the
/// default SipHash costs more than the rest of the downsampling, and voxel
/// keys are not attacker controlled.
#[derive(Default, Clone, Copy)]
pub(crate) struct VoxelKeyHasher {
    hash: u64,
}

impl Hasher for VoxelKeyHasher {
    #[inline]
    fn finish(&self) -> u64 {
        // Final avalanche (murmur3 fmix64) so that the low bits, which the
        // hash table uses for its buckets, depend on every input bit.
        let mut h = self.hash;
        h ^= h >> 33;
        h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^= h >> 33;
        h
    }

    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    #[inline]
    fn write_u64(&mut self, i: u64) {
        self.hash = (self.hash.rotate_left(5) ^ i).wrapping_mul(0x517c_c1b7_2722_0a95);
    }

    #[inline]
    fn write_i64(&mut self, i: i64) {
        self.write_u64(i as u64);
    }
}

/// Hash map keyed by voxel coordinates with [`VoxelKeyHasher`].
pub(crate) type VoxelMap<V> = HashMap<VoxelKey, V, BuildHasherDefault<VoxelKeyHasher>>;

/// One point per occupied voxel of edge `voxel_m` (m): the centroid of the
/// input points in it, in order of each voxel's first point.
///
/// Non-finite input points are dropped. A voxel size that is not a positive
/// finite number means "no downsampling": the finite points are returned
/// unchanged (in input order). Allocates its scratch; keep a
/// [`VoxelDownsampler`] for repeated use.
///
/// ```
/// use limot_estimator::lidar::voxel_downsample;
/// use nalgebra::Vector3;
///
/// let points = [
///     Vector3::new(0.1, 0.1, 0.1),
///     Vector3::new(0.3, 0.3, 0.3),
///     Vector3::new(1.5, 0.0, 0.0),
/// ];
/// let kept = voxel_downsample(&points, 1.0);
/// // The first two share the voxel [0, 1)³ and become their centroid.
/// assert_eq!(kept.len(), 2);
/// assert!((kept[0] - Vector3::new(0.2, 0.2, 0.2)).norm() < 1e-12);
/// assert_eq!(kept[1], points[2]);
/// ```
pub fn voxel_downsample(points: &[Vector3<f64>], voxel_m: f64) -> Vec<Vector3<f64>> {
    VoxelDownsampler::default().downsample(points, voxel_m)
}

/// [`voxel_downsample`] with its hash map and accumulators kept between
/// calls, so that downsampling every sweep does not allocate (and fault in)
/// them again once warmed up. Same output as [`voxel_downsample`], bit for
/// bit.
#[derive(Debug, Clone, Default)]
pub struct VoxelDownsampler {
    /// Index of each voxel's accumulator in `sums` (first-occurrence order).
    index: VoxelMap<u32>,
    sums: Vec<(Vector3<f64>, u32)>,
}

impl VoxelDownsampler {
    /// See [`voxel_downsample`].
    pub fn downsample(&mut self, points: &[Vector3<f64>], voxel_m: f64) -> Vec<Vector3<f64>> {
        let finite = |p: &&Vector3<f64>| p.x.is_finite() && p.y.is_finite() && p.z.is_finite();
        if !(voxel_m.is_finite() && voxel_m > 0.0) {
            return points.iter().filter(finite).copied().collect();
        }
        self.index.clear();
        self.sums.clear();
        // Scan-ordered input (points along a ring) mostly repeats the
        // previous voxel: remembering it skips most hash lookups.
        let mut last: Option<(VoxelKey, u32)> = None;
        for p in points.iter().filter(finite) {
            let key = voxel_key(p, voxel_m);
            let slot = match last {
                Some((k, slot)) if k == key => slot,
                _ => {
                    let next = self.sums.len() as u32;
                    let slot = *self.index.entry(key).or_insert(next);
                    if slot == next {
                        self.sums.push((Vector3::zeros(), 0));
                    }
                    last = Some((key, slot));
                    slot
                }
            };
            let acc = &mut self.sums[slot as usize];
            acc.0 += p;
            acc.1 += 1;
        }
        self.sums
            .iter()
            .map(|(sum, n)| sum / f64::from(*n))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_points_in_one_voxel_give_their_centroid() {
        let pts = [
            Vector3::new(0.01, 0.01, 0.01),
            Vector3::new(0.09, 0.05, 0.03),
            Vector3::new(0.15, 0.0, 0.0),
        ];
        let out = voxel_downsample(&pts, 0.1);
        assert_eq!(out.len(), 2);
        assert!((out[0] - Vector3::new(0.05, 0.03, 0.02)).norm() < 1e-12);
        assert_eq!(out[1], pts[2]);
    }

    #[test]
    fn floor_to_i64_matches_floor() {
        let small = [
            -2.5, -2.0, -1.0, -0.5, -1e-300, 0.0, 1e-300, 0.5, 1.0, 2.999, 1e15, -1e15,
        ];
        // either side of the unsaturated path's bound, 2^62, both signs
        let near_bound = [4.0e18, 4.611686018427388e18, 9.2e18];
        let near_bound = near_bound.into_iter().flat_map(|v| [v, -v]);
        for v in small.into_iter().chain(near_bound) {
            assert_eq!(floor_to_i64(v), v.floor() as i64, "{v}");
        }
        assert_eq!(floor_to_i64(f64::NAN), 0);
        assert_eq!(floor_to_i64(1e300), i64::MAX);
        assert_eq!(floor_to_i64(-1e300), i64::MIN);
    }

    #[test]
    fn negative_coordinates_floor_correctly() {
        // -0.05 and 0.05 are in different voxels for v = 0.1.
        let pts = [Vector3::new(-0.05, 0.0, 0.0), Vector3::new(0.05, 0.0, 0.0)];
        assert_eq!(voxel_downsample(&pts, 0.1).len(), 2);
    }

    #[test]
    fn non_finite_points_are_dropped_and_bad_voxel_means_no_downsampling() {
        let pts = [
            Vector3::new(f64::NAN, 0.0, 0.0),
            Vector3::new(1.0, 2.0, 3.0),
            Vector3::new(1.0, 2.0, 3.0),
            Vector3::new(0.0, f64::INFINITY, 0.0),
        ];
        assert_eq!(voxel_downsample(&pts, 0.5).len(), 1);
        assert_eq!(voxel_downsample(&pts, 0.0).len(), 2);
        assert_eq!(voxel_downsample(&pts, f64::NAN).len(), 2);
        assert!(voxel_downsample(&[], 0.5).is_empty());
    }

    #[test]
    fn a_reused_downsampler_forgets_the_previous_call() {
        let a: Vec<Vector3<f64>> = (0..500)
            .map(|i| Vector3::new(0.013 * i as f64, (0.7 * i as f64).sin(), -0.002 * i as f64))
            .collect();
        let b: Vec<Vector3<f64>> = a.iter().rev().map(|p| p * 1.5).collect();
        let mut reused = VoxelDownsampler::default();
        for (points, voxel_m) in [(&a, 0.1), (&b, 0.1), (&a, 0.25), (&b, 0.0), (&a, 0.1)] {
            let out = reused.downsample(points, voxel_m);
            assert_eq!(out, voxel_downsample(points, voxel_m));
        }
    }
}
