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
/// beyond it (NaN gives 0).
#[inline]
pub(crate) fn floor_to_i64(v: f64) -> i64 {
    let t = v as i64;
    if (t as f64) > v {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// Voxel key of `p` for voxel edge `voxel_m` (> 0). Coordinates beyond the
/// `i64` range saturate, which only merges voxels at absurd distances.
#[inline]
pub fn voxel_key(p: &Vector3<f64>, voxel_m: f64) -> VoxelKey {
    VoxelIndexer::new(voxel_m).key(p)
}

/// [`voxel_key`] for one voxel edge, with its reciprocal computed once:
/// `floor(v / voxel_m)` by a multiplication wherever that gives the same
/// integer, the division only within rounding distance of a voxel boundary.
#[derive(Debug, Clone, Copy)]
pub(crate) struct VoxelIndexer {
    voxel_m: f64,
    inv_voxel: f64,
}

impl VoxelIndexer {
    /// Coordinates at most this many voxels from the origin take the fast path.
    const FAST_RANGE: f64 = 1e6;
    /// `v · (1/voxel_m)` is within ~4e-16 relative of the correctly rounded
    /// `v / voxel_m`, so within `4e-10` of it below [`Self::FAST_RANGE`]: a
    /// fractional part farther than this from 0 and 1 floors the same.
    const BOUNDARY_MARGIN: f64 = 1e-9;

    #[inline]
    pub(crate) fn new(voxel_m: f64) -> Self {
        Self {
            voxel_m,
            inv_voxel: 1.0 / voxel_m,
        }
    }

    /// `floor_to_i64(v / voxel_m)`, bit for bit.
    #[inline]
    fn index(&self, v: f64) -> i64 {
        let q = v * self.inv_voxel;
        let floor = floor_to_i64(q);
        // exact for |q| < 2^52; NaN and infinities fail every test below
        let frac = q - floor as f64;
        if q.abs() < Self::FAST_RANGE
            && frac > Self::BOUNDARY_MARGIN
            && frac < 1.0 - Self::BOUNDARY_MARGIN
        {
            floor
        } else {
            floor_to_i64(v / self.voxel_m)
        }
    }

    /// The voxel key of `p`, equal to [`voxel_key`]`(p, voxel_m)`.
    #[inline]
    pub(crate) fn key(&self, p: &Vector3<f64>) -> VoxelKey {
        (self.index(p.x), self.index(p.y), self.index(p.z))
    }
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
        let indexer = VoxelIndexer::new(voxel_m);
        for p in points.iter().filter(finite) {
            let key = indexer.key(p);
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
        for v in [
            -2.5, -2.0, -1.0, -0.5, -1e-300, 0.0, 1e-300, 0.5, 1.0, 2.999, 1e15, -1e15,
        ] {
            assert_eq!(floor_to_i64(v), v.floor() as i64, "{v}");
        }
        assert_eq!(floor_to_i64(f64::NAN), 0);
        assert_eq!(floor_to_i64(1e300), i64::MAX);
        assert_eq!(floor_to_i64(-1e300), i64::MIN);
    }

    #[test]
    fn the_indexer_floors_exactly_like_the_division() {
        let mut rng = limot_test_support::SplitMix64(7);
        for voxel_m in [0.4, 0.2, 0.1, 1.0, 0.3, 0.05, 1e-3, 7.3] {
            let indexer = VoxelIndexer::new(voxel_m);
            for i in 0..20_000 {
                // random coordinates, and ones a few ulps around voxel boundaries
                let v = if i % 2 == 0 {
                    rng.range(-1e3, 1e3)
                } else {
                    let k = rng.range(-1e4, 1e4).round();
                    let mut b = k * voxel_m;
                    for _ in 0..(i % 7) {
                        b = if i % 3 == 0 {
                            b.next_up()
                        } else {
                            b.next_down()
                        };
                    }
                    b
                };
                assert_eq!(
                    indexer.index(v),
                    floor_to_i64(v / voxel_m),
                    "{v} / {voxel_m}"
                );
            }
            for v in [
                0.0,
                -0.0,
                f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY,
                1e300,
                -1e300,
                4e5,
                -4e5,
            ] {
                assert_eq!(
                    indexer.index(v),
                    floor_to_i64(v / voxel_m),
                    "{v} / {voxel_m}"
                );
            }
        }
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
