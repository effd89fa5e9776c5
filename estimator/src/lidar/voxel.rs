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

use crate::geometry::floor_to_i64;
use nalgebra::Vector3;

/// Integer voxel coordinates `(floor(x/v), floor(y/v), floor(z/v))`.
pub type VoxelKey = (i64, i64, i64);

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
