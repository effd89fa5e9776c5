//! LOAM edge and planar features, as LOAM / LIO-SAM's `featureExtraction`.
//!
//! Per ring, points are ordered by measurement time and split into segments
//! wherever consecutive points are far apart in azimuth (missing returns).
//! Within a segment, the curvature of a point is LIO-SAM's range curvature
//! `c = (Σ_{j=-w..w, j≠0} r_{i+j} − 2w·r_i)²` over `±w` neighbours. Points
//! on the far side of a depth jump (possibly occluded: their neighbourhood
//! changes with the viewpoint) and points on surfaces nearly parallel to the
//! beam (both neighbours far in range) are rejected. Edges are picked per
//! sector of a ring by decreasing curvature above a threshold, at most a few
//! per sector, each suppressing its `±w` neighbours; planar points are the
//! accepted points of low curvature (the pipeline voxel-downsamples them).
//!
//! Everything is order-independent: the same points in any storage order
//! give the same feature sets (ties in time are broken by the coordinates).

use crate::input::{LidarPoint, LidarScan};
use nalgebra::Vector3;
use std::cmp::Ordering;

/// Feature extraction settings (defaults: LIO-SAM's).
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureConfig {
    /// Neighbours on each side used for the curvature (LIO-SAM: 5).
    pub curvature_half_window: usize,
    /// Points with a curvature above this can be edges (LIO-SAM: 1.0, m²).
    pub edge_curvature_threshold: f64,
    /// Points with a curvature below this are planar (LIO-SAM: 0.1, m²).
    pub surface_curvature_threshold: f64,
    /// Each ring is split into this many sectors of equal point count so that
    /// edges spread around the sensor (LIO-SAM: 6).
    pub sectors_per_ring: usize,
    /// Edges kept per sector (LIO-SAM: 20).
    pub max_edges_per_sector: usize,
    /// Points closer than this are ignored (ego vehicle returns; LIO-SAM: 1 m).
    pub min_range_m: f64,
    /// Points farther than this are ignored (LIO-SAM: 1000 m).
    pub max_range_m: f64,
    /// A range step larger than this between neighbours marks the far side
    /// as possibly occluded (LIO-SAM: 0.3 m).
    pub occlusion_depth_jump_m: f64,
    /// A point whose range differs from both neighbours by more than this
    /// fraction of its range lies on a surface nearly parallel to the beam
    /// (LIO-SAM: 0.02).
    pub parallel_beam_ratio: f64,
    /// Consecutive points of a ring farther apart than this in azimuth belong
    /// to different segments (curvature and suppression never cross a gap).
    /// Default 1° ≈ 5.5 columns of a 2000-column HDL-64E: single dropouts do
    /// not split a segment, longer runs of missing returns do.
    pub max_azimuth_gap_rad: f64,
}

impl Default for FeatureConfig {
    fn default() -> Self {
        FeatureConfig {
            curvature_half_window: 5,
            edge_curvature_threshold: 1.0,
            surface_curvature_threshold: 0.1,
            sectors_per_ring: 6,
            max_edges_per_sector: 20,
            min_range_m: 1.0,
            max_range_m: 1000.0,
            occlusion_depth_jump_m: 0.3,
            parallel_beam_ratio: 0.02,
            max_azimuth_gap_rad: 1f64.to_radians(),
        }
    }
}

/// Why a [`FeatureConfig`] is unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FeatureConfigError {
    /// A field is out of its valid range.
    #[error("feature config field `{field}` is invalid: {why}")]
    Invalid {
        /// Name of the field.
        field: &'static str,
        /// What the field must satisfy.
        why: &'static str,
    },
}

impl FeatureConfig {
    /// Rejects values that make no sense (zero windows or sectors, negative
    /// or non-finite thresholds, an empty range interval).
    ///
    /// # Errors
    /// [`FeatureConfigError::Invalid`] naming the first bad field.
    pub fn validate(&self) -> Result<(), FeatureConfigError> {
        let bad = |field, why| Err(FeatureConfigError::Invalid { field, why });
        if self.curvature_half_window == 0 {
            return bad("curvature_half_window", "must be at least 1");
        }
        if self.sectors_per_ring == 0 {
            return bad("sectors_per_ring", "must be at least 1");
        }
        let non_negative = [
            ("edge_curvature_threshold", self.edge_curvature_threshold),
            (
                "surface_curvature_threshold",
                self.surface_curvature_threshold,
            ),
            ("min_range_m", self.min_range_m),
            ("occlusion_depth_jump_m", self.occlusion_depth_jump_m),
            ("parallel_beam_ratio", self.parallel_beam_ratio),
            ("max_azimuth_gap_rad", self.max_azimuth_gap_rad),
        ];
        for (field, value) in non_negative {
            if !(value.is_finite() && value >= 0.0) {
                return bad(field, "must be finite and non-negative");
            }
        }
        if self.max_range_m.is_nan() || self.max_range_m <= self.min_range_m {
            return bad("max_range_m", "must be greater than min_range_m");
        }
        Ok(())
    }
}

/// Indices into `scan.points` (and the de-skewed positions) of the features
/// of one scan, each list in ring then time order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScanFeatures {
    /// Edge points (high curvature).
    pub edge_indices: Vec<usize>,
    /// Planar points (low curvature).
    pub planar_indices: Vec<usize>,
}

/// Ring buffers kept between calls (more than any real sensor's rings).
const MAX_KEPT_RING_BUFFERS: usize = 256;

/// Per-point flags (in ring/time order).
const HAS_CURVATURE: u8 = 1;
/// Occluded or parallel to the beam: neither edge nor planar.
const REJECTED: u8 = 2;
/// Suppressed by a neighbouring edge.
const SUPPRESSED: u8 = 4;
const EDGE: u8 = 8;

/// Feature extractor holding scratch buffers so that repeated calls do not
/// allocate once warmed up.
///
/// ```
/// use limot_estimator::input::{LidarPoint, LidarScan};
/// use limot_estimator::lidar::{FeatureConfig, FeatureExtractor};
///
/// // One ring sweeping a room corner 10 m ahead: walls x = 10 − 2|y|.
/// let points: Vec<LidarPoint> = (0..=400)
///     .map(|k| {
///         let az = (-40.0 + 0.2 * k as f64).to_radians();
///         let range = 10.0 / (az.cos() + 2.0 * az.sin().abs());
///         LidarPoint {
///             x: (range * az.cos()) as f32,
///             y: (range * az.sin()) as f32,
///             z: 0.0,
///             intensity: 0.0,
///             ring: 0,
///             time_offset_s: k as f32 * 1e-4,
///         }
///     })
///     .collect();
/// let scan = LidarScan { t_s: 0.0, sweep_duration_s: 0.1, num_rings: 1, points };
/// let positions: Vec<_> = scan.points.iter().map(|p| p.position()).collect();
///
/// let mut extractor = FeatureExtractor::new(FeatureConfig::default());
/// let features = extractor.extract(&positions, &scan);
/// // One edge, at the corner (index 200, ± one point of rounding); the flat
/// // walls give planar points.
/// assert_eq!(features.edge_indices.len(), 1);
/// assert!((199..=201).contains(&features.edge_indices[0]));
/// assert!(features.planar_indices.len() > 100);
/// ```
#[derive(Debug, Clone, Default)]
pub struct FeatureExtractor {
    /// The settings used by every call.
    pub config: FeatureConfig,
    /// The accepted points of each ring (storage order, then time order);
    /// a ring is processed whole while its buffers are in cache.
    rings: Vec<Vec<OrderedPoint>>,
    /// Per position of the ring being processed: range, curvature, flags,
    /// segment bounds.
    range: Vec<f64>,
    curvature: Vec<f64>,
    flags: Vec<u8>,
    segment_start: Vec<u32>,
    segment_end: Vec<u32>,
    candidates: Vec<u32>,
}

/// Total order of the points of one ring: time, then coordinates (so ties
/// do not depend on storage order), then index.
fn ring_order(a: &LidarPoint, ia: u32, b: &LidarPoint, ib: u32) -> Ordering {
    a.time_offset_s
        .total_cmp(&b.time_offset_s)
        .then_with(|| a.x.total_cmp(&b.x))
        .then_with(|| a.y.total_cmp(&b.y))
        .then_with(|| a.z.total_cmp(&b.z))
        .then_with(|| ia.cmp(&ib))
}

/// A point in ring/time order: sort key `(time key << 32) | scan index`,
/// range and the raw horizontal direction (for azimuth gaps).
#[derive(Debug, Clone, Copy, Default)]
struct OrderedPoint {
    key: u64,
    range: f64,
    x: f32,
    y: f32,
}

/// Sorts one ring by key (see [`sort_ring_by`]).
fn sort_ring(slice: &mut [OrderedPoint]) {
    sort_ring_by(slice, |a, b| a.key.cmp(&b.key));
}

/// Sorts one ring of a spinning sensor by `cmp`, a total order (no two
/// elements equal). The storage is usually the time order rotated,
/// ascending (simulator: sweep from the rear) or descending (KITTI: each
/// laser stored counter-clockwise while the head spins clockwise): a
/// reversal and a rotation sort those in three linear passes; anything
/// else goes to a sort (with a total order every route gives the same
/// order).
pub fn sort_ring_by<T>(slice: &mut [T], mut cmp: impl FnMut(&T, &T) -> Ordering) {
    if let Some(start) = rotated_start(slice, &mut cmp) {
        slice.rotate_left(start);
        return;
    }
    slice.reverse();
    if let Some(start) = rotated_start(slice, &mut cmp) {
        slice.rotate_left(start);
        return;
    }
    slice.sort_by(cmp);
}

/// If `slice` is an ascending sequence rotated (at most one descent, and
/// the last element below the first when there is one), the index where it
/// starts.
fn rotated_start<T>(slice: &[T], cmp: &mut impl FnMut(&T, &T) -> Ordering) -> Option<usize> {
    let mut start = None;
    for (i, pair) in slice.windows(2).enumerate() {
        if cmp(&pair[0], &pair[1]) == Ordering::Greater {
            if start.is_some() {
                return None;
            }
            start = Some(i + 1);
        }
    }
    match start {
        None => Some(0),
        Some(i) => (cmp(&slice[slice.len() - 1], &slice[0]) == Ordering::Less).then_some(i),
    }
}

/// Curvature and rejection settings for one segment.
struct Rejection {
    half_window: usize,
    depth_jump_m: f64,
    parallel_ratio: f64,
}

impl Rejection {
    /// Curvature (with [`HAS_CURVATURE`] where the window fits) and
    /// [`REJECTED`] flags for one segment's ranges `r`.
    fn process_segment(&self, r: &[f64], curvature: &mut [f64], flags: &mut [u8]) {
        let w = self.half_window;
        let len = r.len();
        curvature.fill(0.0);
        if len > 2 * w {
            // running window sum (a serial (2w+1)-term sum per point costs
            // its add latency; the drift is ~1e-13 m)
            let mut sum: f64 = r[..2 * w + 1].iter().sum();
            for k in w..len - w {
                if k > w {
                    sum += r[k + w] - r[k - w - 1];
                }
                let diff = sum - (2 * w + 1) as f64 * r[k];
                curvature[k] = diff * diff;
                flags[k] |= HAS_CURVATURE;
            }
        }
        for k in 0..len.saturating_sub(1) {
            let (d1, d2) = (r[k], r[k + 1]);
            if d1 - d2 > self.depth_jump_m {
                // k (and the w before it) is the far side: occluded
                for f in &mut flags[k.saturating_sub(w)..=k] {
                    *f |= REJECTED;
                }
            } else if d2 - d1 > self.depth_jump_m {
                for f in &mut flags[k + 1..=(k + 1 + w).min(len - 1)] {
                    *f |= REJECTED;
                }
            }
            // surface nearly parallel to the beam: far from both neighbours
            if k > 0 {
                let lim = self.parallel_ratio * d1;
                if (r[k - 1] - d1).abs() > lim && (d2 - d1).abs() > lim {
                    flags[k] |= REJECTED;
                }
            }
        }
    }
}

/// Maps an f32 to a u32 with the same order as `f32::total_cmp`.
#[inline]
fn time_key(t: f32) -> u32 {
    let bits = t.to_bits();
    if bits >> 31 == 1 {
        !bits
    } else {
        bits | 0x8000_0000
    }
}

impl FeatureExtractor {
    /// An extractor with empty scratch buffers.
    pub fn new(config: FeatureConfig) -> FeatureExtractor {
        FeatureExtractor {
            config,
            ..Default::default()
        }
    }

    /// Extracts the features of `scan` from its de-skewed positions
    /// `points_lidar` (same indexing as `scan.points`; ring and time come from
    /// `scan.points`). If the lengths differ, only the common prefix is used.
    /// Writes into `out` (cleared first).
    pub fn extract_into(
        &mut self,
        points_lidar: &[Vector3<f64>],
        scan: &LidarScan,
        out: &mut ScanFeatures,
    ) {
        out.edge_indices.clear();
        out.planar_indices.clear();
        let n = points_lidar
            .len()
            .min(scan.points.len())
            .min(u32::MAX as usize);
        let points = &scan.points[..n];
        // clamped so that window arithmetic cannot overflow on absurd configs
        let w = self.config.curvature_half_window.clamp(1, 1 << 16);
        let min_range = self.config.min_range_m;
        let max_range = self.config.max_range_m;

        // 1. ranges, and the accepted points of each ring (one pass in
        //    storage order; the rings are then processed one at a time)
        let mut num_rings = 0;
        // (a scan with an absurd ring number must not leave every later
        // call clearing thousands of buffers)
        self.rings.truncate(MAX_KEPT_RING_BUFFERS);
        for ring in &mut self.rings {
            ring.clear();
        }
        for (i, (p, raw)) in points_lidar[..n].iter().zip(points).enumerate() {
            let range = p.norm();
            if range.is_finite() && range >= min_range && range <= max_range {
                let ring = raw.ring as usize;
                if ring >= self.rings.len() {
                    self.rings.resize_with(ring + 1, Vec::new);
                }
                num_rings = num_rings.max(ring + 1);
                self.rings[ring].push(OrderedPoint {
                    key: ((time_key(raw.time_offset_s) as u64) << 32) | i as u64,
                    range,
                    x: raw.x,
                    y: raw.y,
                });
            }
        }
        let cos_gap = self
            .config
            .max_azimuth_gap_rad
            .min(std::f64::consts::PI)
            .cos();
        let rejection = Rejection {
            half_window: w,
            depth_jump_m: self.config.occlusion_depth_jump_m,
            parallel_ratio: self.config.parallel_beam_ratio,
        };
        let sectors = self.config.sectors_per_ring.max(1);
        let edge_threshold = self.config.edge_curvature_threshold;
        let surface_threshold = self.config.surface_curvature_threshold;
        for ordered in &mut self.rings[..num_rings] {
            let len = ordered.len();
            if len == 0 {
                continue;
            }
            // 2. time order within the ring (a rotation of the storage
            //    order, usually; see `sort_ring_by`)
            sort_ring(ordered);
            // Equal times (duplicates, coarse time stamps): order by the
            // coordinates so that storage order does not matter.
            let mut a = 0;
            while a < len {
                let t = ordered[a].key >> 32;
                let mut b = a + 1;
                while b < len && ordered[b].key >> 32 == t {
                    b += 1;
                }
                if b - a > 1 {
                    ordered[a..b].sort_unstable_by(|x, y| {
                        let (ix, iy) = (x.key as u32, y.key as u32);
                        ring_order(&points[ix as usize], ix, &points[iy as usize], iy)
                    });
                }
                a = b;
            }
            self.range.clear();
            self.range.extend(ordered.iter().map(|o| o.range));

            // 3. segments: split the ring where consecutive points are far
            //    apart in azimuth (angle between their horizontal
            //    directions); then curvature and rejection per segment
            self.segment_start.resize(len, 0);
            self.segment_end.resize(len, 0);
            self.curvature.resize(len, 0.0);
            self.flags.clear();
            self.flags.resize(len, 0);
            let mut seg_start = 0;
            for k in 0..=len {
                let ends_segment = k == len || {
                    k > 0 && {
                        let (a, b) = (&ordered[k - 1], &ordered[k]);
                        let (ax, ay, bx, by) = (a.x as f64, a.y as f64, b.x as f64, b.y as f64);
                        let dot = ax * bx + ay * by;
                        let nn = (ax * ax + ay * ay) * (bx * bx + by * by);
                        nn == 0.0 || dot < cos_gap * nn.sqrt()
                    }
                };
                if ends_segment && k > seg_start {
                    self.segment_start[seg_start..k].fill(seg_start as u32);
                    self.segment_end[seg_start..k].fill(k as u32);
                    rejection.process_segment(
                        &self.range[seg_start..k],
                        &mut self.curvature[seg_start..k],
                        &mut self.flags[seg_start..k],
                    );
                    seg_start = k;
                }
            }

            // 4. edges per ring sector by decreasing curvature, with
            //    suppression
            for sector in 0..sectors {
                let sp = len * sector / sectors;
                let ep = len * (sector + 1) / sectors;
                self.candidates.clear();
                for k in sp..ep {
                    if self.flags[k] & (HAS_CURVATURE | REJECTED) == HAS_CURVATURE
                        && self.curvature[k] > edge_threshold
                    {
                        self.candidates.push(k as u32);
                    }
                }
                let curvature = &self.curvature;
                self.candidates.sort_unstable_by(|a, b| {
                    curvature[*b as usize]
                        .total_cmp(&curvature[*a as usize])
                        .then(a.cmp(b))
                });
                let mut picked = 0;
                for &k in &self.candidates {
                    if picked >= self.config.max_edges_per_sector {
                        break;
                    }
                    let k = k as usize;
                    if self.flags[k] & SUPPRESSED != 0 {
                        continue;
                    }
                    self.flags[k] |= EDGE | SUPPRESSED;
                    picked += 1;
                    let lo = (self.segment_start[k] as usize).max(k.saturating_sub(w));
                    let hi = (self.segment_end[k] as usize).min(k + w + 1);
                    for f in &mut self.flags[lo..hi] {
                        *f |= SUPPRESSED;
                    }
                }
            }

            // 5. collect, in ring then time order
            // Most points are planar, but not predictably: each is written
            // and the list's end advanced only when it is one (no branch).
            let planar = &mut out.planar_indices;
            let mut end = planar.len();
            planar.resize(end + len, 0);
            for (k, o) in ordered.iter().enumerate() {
                let f = self.flags[k];
                let index = o.key as u32 as usize;
                if f & EDGE != 0 {
                    out.edge_indices.push(index);
                }
                planar[end] = index;
                end += usize::from(
                    (f & (HAS_CURVATURE | REJECTED | EDGE) == HAS_CURVATURE)
                        & (self.curvature[k] < surface_threshold),
                );
            }
            planar.truncate(end);
        }
    }

    /// Like [`FeatureExtractor::extract_into`], returning a new result.
    pub fn extract(&mut self, points_lidar: &[Vector3<f64>], scan: &LidarScan) -> ScanFeatures {
        let mut out = ScanFeatures::default();
        self.extract_into(points_lidar, scan, &mut out);
        out
    }
}

/// One-shot feature extraction (allocates scratch buffers; keep a
/// [`FeatureExtractor`] for repeated use).
pub fn extract_features(
    points_lidar: &[Vector3<f64>],
    scan: &LidarScan,
    config: &FeatureConfig,
) -> ScanFeatures {
    FeatureExtractor::new(config.clone()).extract(points_lidar, scan)
}

#[cfg(test)]
mod tests {
    use super::*;

    const STEP_DEG: f64 = 0.2;

    /// One ring whose k-th point is at azimuth `az0 + k·STEP_DEG` with the
    /// given range, in the horizontal plane, times increasing with k.
    fn ring(ring: u16, az0_deg: f64, ranges: &[f64]) -> Vec<(u16, f32, Vector3<f64>)> {
        ranges
            .iter()
            .enumerate()
            .map(|(k, &r)| {
                let az = (az0_deg + k as f64 * STEP_DEG).to_radians();
                (
                    ring,
                    k as f32 * 1e-4,
                    Vector3::new(r * az.cos(), r * az.sin(), 0.0),
                )
            })
            .collect()
    }

    fn scan_of(points: &[(u16, f32, Vector3<f64>)]) -> (LidarScan, Vec<Vector3<f64>>) {
        let scan = LidarScan {
            t_s: 0.0,
            sweep_duration_s: 0.1,
            num_rings: 1,
            points: points
                .iter()
                .map(|(ring, t, p)| LidarPoint {
                    x: p.x as f32,
                    y: p.y as f32,
                    z: p.z as f32,
                    intensity: 0.0,
                    ring: *ring,
                    time_offset_s: *t,
                })
                .collect(),
        };
        let positions = scan.points.iter().map(|p| p.position()).collect();
        (scan, positions)
    }

    fn run(points: &[(u16, f32, Vector3<f64>)], config: &FeatureConfig) -> ScanFeatures {
        let (scan, positions) = scan_of(points);
        extract_features(&positions, &scan, config)
    }

    /// Ranges of a straight wall at distance `d` along x seen at azimuths
    /// `az0 + k·STEP`.
    fn wall_x(d: f64, az0_deg: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| d / (az0_deg + k as f64 * STEP_DEG).to_radians().cos())
            .collect()
    }

    #[test]
    fn empty_and_degenerate_scans_do_not_panic() {
        let config = FeatureConfig::default();
        let f = run(&[], &config);
        assert!(f.edge_indices.is_empty() && f.planar_indices.is_empty());
        // every point inside min range, identical points, extreme ring index
        let origin = vec![(0u16, 0.0f32, Vector3::zeros()); 50];
        assert_eq!(run(&origin, &config), ScanFeatures::default());
        let same = vec![(u16::MAX, 0.0f32, Vector3::new(5.0, 0.0, 0.0)); 50];
        let f = run(&same, &config);
        assert!(f.edge_indices.is_empty());
        // straight up: no azimuth, every point its own segment
        let up = vec![(3u16, 0.01f32, Vector3::new(0.0, 0.0, 5.0)); 50];
        assert_eq!(run(&up, &config), ScanFeatures::default());
        // absurd settings: no overflow, no panic
        let absurd = FeatureConfig {
            curvature_half_window: usize::MAX,
            sectors_per_ring: 0,
            max_edges_per_sector: 0,
            ..FeatureConfig::default()
        };
        assert_eq!(
            run(&ring(0, 0.0, &[10.0; 100]), &absurd),
            ScanFeatures::default()
        );
        // fewer positions than points, NaN positions: ignored, no panic
        let (scan, mut positions) = scan_of(&ring(0, 0.0, &[10.0; 100]));
        positions.truncate(60);
        positions[10] = Vector3::new(f64::NAN, 0.0, 0.0);
        let f = extract_features(&positions, &scan, &config);
        assert!(f.planar_indices.iter().all(|&i| i < 60 && i != 10));
        assert!(!f.planar_indices.is_empty());
    }

    #[test]
    fn constant_range_ring_is_planar() {
        let n = 200;
        let f = run(&ring(0, -20.0, &vec![10.0; n]), &FeatureConfig::default());
        assert!(f.edge_indices.is_empty());
        // all but the w points at each end (incomplete curvature window)
        let mut planar = f.planar_indices.clone();
        planar.sort_unstable();
        assert_eq!(planar, (5..n - 5).collect::<Vec<_>>());
    }

    #[test]
    fn concave_corner_gives_one_edge_at_the_corner() {
        // walls x = 10 and y = 10 meet at azimuth 45°
        let n = 300;
        let az0 = 15.0;
        let ranges: Vec<f64> = (0..n)
            .map(|k| {
                let az = (az0 + k as f64 * STEP_DEG).to_radians();
                (10.0 / az.cos()).min(10.0 / az.sin())
            })
            .collect();
        let f = run(&ring(0, az0, &ranges), &FeatureConfig::default());
        assert_eq!(f.edge_indices.len(), 1, "{:?}", f.edge_indices);
        let corner = ((45.0 - az0) / STEP_DEG).round() as usize;
        assert!(
            f.edge_indices[0].abs_diff(corner) <= 1,
            "{:?}",
            f.edge_indices
        );
        // points next to the corner are not planar
        for k in corner - 2..=corner + 2 {
            assert!(!f.planar_indices.contains(&k), "{k}");
        }
    }

    #[test]
    fn occluded_far_side_is_rejected_and_near_side_is_an_edge() {
        // wall x = 10 from -20° to 20°, a pole in front (range 5) at ±1°
        let az0 = -20.0;
        let mut ranges = wall_x(10.0, az0, 201);
        let pole = 95..106;
        for k in pole.clone() {
            ranges[k] = 5.0;
        }
        let f = run(&ring(0, az0, &ranges), &FeatureConfig::default());
        // near side: the pole's two silhouette points
        let mut edges = f.edge_indices.clone();
        edges.sort_unstable();
        assert_eq!(edges, vec![pole.start, pole.end - 1]);
        // far side: the 6 wall points next to each silhouette are rejected
        for k in (pole.start - 6..pole.start).chain(pole.end..pole.end + 6) {
            assert!(!f.planar_indices.contains(&k), "{k}");
        }
        // wall farther away is planar again
        assert!(f.planar_indices.contains(&(pole.start - 8)));
        assert!(f.planar_indices.contains(&(pole.end + 8)));
    }

    #[test]
    fn beams_parallel_to_the_surface_are_rejected() {
        // ranges growing 3 % per step (a surface almost along the beam),
        // between two constant-range stretches
        let mut ranges = vec![5.0; 40];
        let mut r = 5.0;
        for _ in 0..20 {
            r *= 1.03;
            ranges.push(r);
        }
        ranges.extend(std::iter::repeat_n(r, 40));
        let f = run(&ring(0, 0.0, &ranges), &FeatureConfig::default());
        for k in 41..59 {
            assert!(!f.planar_indices.contains(&k), "{k}");
            assert!(!f.edge_indices.contains(&k), "{k}");
        }
        // the same ring with the check disabled keeps some of them
        let lax = FeatureConfig {
            parallel_beam_ratio: 1.0,
            ..FeatureConfig::default()
        };
        let f = run(&ring(0, 0.0, &ranges), &lax);
        assert!((41..59).any(|k| f.edge_indices.contains(&k) || f.planar_indices.contains(&k)));
    }

    #[test]
    fn an_azimuth_gap_splits_the_ring() {
        // 100 points at 5 m, a 10° gap, 100 points at 8 m
        let mut points = ring(0, 0.0, &[5.0; 100]);
        let after = ring(0, 100.0 * STEP_DEG + 10.0, &[8.0; 100]);
        points.extend(after.into_iter().map(|(r, t, p)| (r, t + 0.02, p)));
        let f = run(&points, &FeatureConfig::default());
        assert!(f.edge_indices.is_empty(), "{:?}", f.edge_indices);
        // two segments, each losing w points at both ends
        assert_eq!(f.planar_indices.len(), 200 - 4 * 5);
        // without splitting, the depth step makes an edge at the near side
        let no_split = FeatureConfig {
            max_azimuth_gap_rad: std::f64::consts::PI,
            ..FeatureConfig::default()
        };
        let f = run(&points, &no_split);
        assert_eq!(f.edge_indices, vec![99]);
    }

    #[test]
    fn edges_per_sector_are_limited() {
        // zig-zag ranges: a corner every 12 points
        let ranges: Vec<f64> = (0..600)
            .map(|k| 10.0 + 0.05 * ((k % 24) as f64 - 12.0).abs())
            .collect();
        let all = run(&ring(0, -60.0, &ranges), &FeatureConfig::default());
        assert!(all.edge_indices.len() > 12, "{}", all.edge_indices.len());
        let one = FeatureConfig {
            max_edges_per_sector: 1,
            ..FeatureConfig::default()
        };
        let f = run(&ring(0, -60.0, &ranges), &one);
        assert_eq!(f.edge_indices.len(), 6);
        // picked edges are more than w apart (suppression)
        let mut e = all.edge_indices.clone();
        e.sort_unstable();
        assert!(e.windows(2).all(|p| p[1] - p[0] > 5), "{e:?}");
    }

    #[test]
    fn rings_are_independent_and_the_extractor_is_reusable() {
        let a = ring(0, -20.0, &wall_x(10.0, -20.0, 201));
        let mut b = ring(1, -20.0, &wall_x(12.0, -20.0, 201));
        for p in b.iter_mut().skip(95).take(11) {
            p.2 *= 0.5;
        }
        let fa = run(&a, &FeatureConfig::default());
        let fb = run(&b, &FeatureConfig::default());
        let mut both = a.clone();
        both.extend(b.iter().copied());
        let mut extractor = FeatureExtractor::new(FeatureConfig::default());
        let (scan, positions) = scan_of(&both);
        let _ = extractor.extract(&positions[..10], &scan);
        let (far_ring, far_positions) = scan_of(&ring(4000, 0.0, &[10.0; 100]));
        let _ = extractor.extract(&far_positions, &far_ring);
        let f = extractor.extract(&positions, &scan);
        assert_eq!(f, extract_features(&positions, &scan, &extractor.config));
        let mut expected_edges: Vec<usize> = fa.edge_indices.clone();
        expected_edges.extend(fb.edge_indices.iter().map(|i| i + a.len()));
        let mut edges = f.edge_indices.clone();
        edges.sort_unstable();
        expected_edges.sort_unstable();
        assert_eq!(edges, expected_edges);
        assert_eq!(
            f.planar_indices.len(),
            fa.planar_indices.len() + fb.planar_indices.len()
        );
    }

    #[test]
    fn ring_sort_handles_rotated_and_reversed_storage() {
        let sorted: Vec<u64> = (0..50).map(|k| k * 3).collect();
        let mut cases = vec![sorted.clone()];
        let mut rotated = sorted.clone();
        rotated.rotate_left(17);
        cases.push(rotated.clone());
        rotated.reverse();
        cases.push(rotated);
        let mut reversed = sorted.clone();
        reversed.reverse();
        cases.push(reversed);
        let mut scrambled = sorted.clone();
        scrambled.swap(3, 40);
        scrambled.swap(10, 11);
        scrambled.rotate_left(5);
        cases.push(scrambled);
        // the keys `sort_ring` leaves in a ring stored as `keys`
        fn sorted_by_ring_sort(keys: &[u64]) -> Vec<u64> {
            let mut ring: Vec<OrderedPoint> = keys
                .iter()
                .map(|&key| OrderedPoint {
                    key,
                    ..OrderedPoint::default()
                })
                .collect();
            sort_ring(&mut ring);
            ring.iter().map(|o| o.key).collect()
        }
        for keys in cases {
            assert_eq!(sorted_by_ring_sort(&keys), sorted);
        }
        // every order of up to 6 keys (rotations, reversals, near misses)
        fn permutations(n: usize) -> Vec<Vec<u64>> {
            if n == 0 {
                return vec![vec![]];
            }
            let mut all = Vec::new();
            for p in permutations(n - 1) {
                for at in 0..=p.len() {
                    let mut q = p.clone();
                    q.insert(at, (n - 1) as u64);
                    all.push(q);
                }
            }
            all
        }
        for n in 0..=6 {
            for keys in permutations(n) {
                let expected: Vec<u64> = (0..n as u64).collect();
                assert_eq!(sorted_by_ring_sort(&keys), expected, "{keys:?}");
            }
        }
    }

    #[test]
    fn config_validation_names_the_field() {
        assert!(FeatureConfig::default().validate().is_ok());
        let bad = FeatureConfig {
            curvature_half_window: 0,
            ..FeatureConfig::default()
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("curvature_half_window")
        );
        let bad = FeatureConfig {
            edge_curvature_threshold: f64::NAN,
            ..FeatureConfig::default()
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("edge_curvature_threshold")
        );
        let bad = FeatureConfig {
            max_range_m: 0.5,
            ..FeatureConfig::default()
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("max_range_m")
        );
    }
}
