//! Local feature map of recent keyframes in the world frame (LIO-SAM's
//! "surrounding keyframes" map), with neighbour search for scan matching.
//!
//! Each keyframe keeps its edge and planar feature points in the world
//! frame, voxel-downsampled at the map's sizes (edge 0.2 m, planar 0.4 m:
//! LIO-SAM's `mappingCornerLeafSize` / `mappingSurfLeafSize`). After every
//! new keyframe the map keeps only the last `max_keyframes` keyframes that
//! lie within `max_radius_m` of the newest one (dropped keyframes are gone
//! for good). The map clouds are the voxel centroids of the kept keyframes'
//! points, maintained incrementally as per-voxel running sums (a keyframe
//! costs one hash update per added or dropped point, not a voxelisation of
//! the whole union). Per cloud the map then rebuilds:
//! * a hash grid for the radius-bounded k-NN that LOAM matching needs
//!   ([`MapCloud::nearest_k_within`]), several times faster than the k-d
//!   tree on these clouds (figures in `docs/estimator-notes.md`);
//! * a kiddo [`ImmutableKdTree`] for general k-NN ([`MapCloud::nearest_k`]),
//!   built lazily on first use. Immutable rather than mutable: it is kiddo's
//!   fastest to query, and kiddo's mutable tree fails to build
//!   (`UnsplittableBucket`) on clouds with many equal coordinates, such as a
//!   flat voxelised ground.

use std::collections::VecDeque;
use std::collections::hash_map::Entry;
use std::num::NonZeroUsize;
use std::sync::OnceLock;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Isometry3, Vector3};
use thiserror::Error;

use super::voxel::{VoxelKey, VoxelMap, floor_to_i64, voxel_downsample, voxel_key};

/// Errors of [`LocalMap`].
#[derive(Debug, Error, Clone, PartialEq)]
pub enum LocalMapError {
    /// A configuration field is out of range.
    #[error("invalid local map config: `{field}` = {value} ({reason})")]
    InvalidConfig {
        /// Name of the field.
        field: &'static str,
        /// Its value (counts as `f64`).
        value: f64,
        /// What the field must satisfy.
        reason: &'static str,
    },
    /// The keyframe pose has a non-finite translation or rotation.
    #[error("keyframe pose t_world_lidar is not finite")]
    NonFinitePose,
}

/// Settings of the local map. Defaults are LIO-SAM's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalMapConfig {
    /// Keep at most this many most recent keyframes (default 25).
    pub max_keyframes: usize,
    /// Drop keyframes whose position is farther than this from the newest
    /// keyframe, m (default 50, LIO-SAM's `surroundingKeyframeSearchRadius`).
    pub max_radius_m: f64,
    /// Voxel edge of the edge-feature map, m (default 0.2).
    pub edge_voxel_m: f64,
    /// Voxel edge of the planar-feature map, m (default 0.4).
    pub planar_voxel_m: f64,
    /// Cell edge of the hash grid that answers radius-bounded k-NN queries
    /// (exactly) for radii up to one cell, m; larger radii fall back to the
    /// k-d tree. Default 2.0 = twice LOAM's 1 m neighbour distance, so a
    /// query touches at most 2×2×2 cells.
    pub grid_cell_m: f64,
}

impl Default for LocalMapConfig {
    fn default() -> Self {
        Self {
            max_keyframes: 25,
            max_radius_m: 50.0,
            edge_voxel_m: 0.2,
            planar_voxel_m: 0.4,
            grid_cell_m: 2.0,
        }
    }
}

impl LocalMapConfig {
    /// Checks every field (counts ≥ 1, distances positive and finite).
    ///
    /// # Errors
    /// [`LocalMapError::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<(), LocalMapError> {
        if self.max_keyframes == 0 {
            return Err(LocalMapError::InvalidConfig {
                field: "max_keyframes",
                value: 0.0,
                reason: "must be at least 1",
            });
        }
        for (field, value) in [
            ("max_radius_m", self.max_radius_m),
            ("edge_voxel_m", self.edge_voxel_m),
            ("planar_voxel_m", self.planar_voxel_m),
            ("grid_cell_m", self.grid_cell_m),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(LocalMapError::InvalidConfig {
                    field,
                    value,
                    reason: "must be positive and finite",
                });
            }
        }
        Ok(())
    }
}

/// A nearest-neighbour result: a map point and its squared distance (m²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neighbour {
    /// The map point, world frame (m).
    pub point_world: Vector3<f64>,
    /// Its squared distance to the query point (m²).
    pub dist_sq_m2: f64,
}

/// Packs a cell key into one `u64` (21 bits per axis, two's complement) so
/// that a lookup hashes one word. Cells 2²¹ cells apart alias; that only adds
/// far-away candidates, which the distance test rejects, so queries stay
/// exact. The top bit is always clear, so [`CellTable::EMPTY`] is no key.
#[inline]
fn pack_cell((x, y, z): VoxelKey) -> u64 {
    const MASK: u64 = (1 << 21) - 1;
    ((x as u64 & MASK) << 42) | ((y as u64 & MASK) << 21) | (z as u64 & MASK)
}

/// One slot of [`CellTable`]: a packed cell key and its range of points.
#[derive(Debug, Clone, Copy)]
struct CellSlot {
    key: u64,
    start: u32,
    len: u32,
}

/// Open-addressing hash table (linear probing, at most half full) from
/// packed cell keys to their point ranges: a lookup is one hash and, almost
/// always, one 16-byte slot read, with no tag groups or indirection.
#[derive(Debug, Default)]
struct CellTable {
    /// Power-of-two length (or empty); empty slots have key [`Self::EMPTY`].
    slots: Vec<CellSlot>,
}

impl CellTable {
    const EMPTY: u64 = u64::MAX;

    /// murmur3's fmix64: every key bit reaches the low bits used as index.
    #[inline]
    fn hash(key: u64) -> u64 {
        let mut h = key;
        h ^= h >> 33;
        h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^= h >> 33;
        h = h.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        h ^= h >> 33;
        h
    }

    /// A table with room for `cells` keys at most half full.
    fn with_cells(cells: usize) -> Self {
        let len = (2 * cells).next_power_of_two().max(16);
        Self {
            slots: vec![
                CellSlot {
                    key: Self::EMPTY,
                    start: 0,
                    len: 0,
                };
                len
            ],
        }
    }

    /// The slot of `key`, inserted (range 0, 0) if absent. The table must
    /// have a free slot.
    #[inline]
    fn entry(&mut self, key: u64) -> &mut CellSlot {
        let mask = self.slots.len() - 1;
        let mut i = Self::hash(key) as usize & mask;
        loop {
            let slot_key = self.slots[i].key;
            if slot_key == key {
                break;
            }
            if slot_key == Self::EMPTY {
                self.slots[i].key = key;
                break;
            }
            i = (i + 1) & mask;
        }
        &mut self.slots[i]
    }

    /// The range `(start, len)` of `key`, if present.
    #[inline]
    fn get(&self, key: u64) -> Option<(u32, u32)> {
        if self.slots.is_empty() {
            return None;
        }
        let mask = self.slots.len() - 1;
        let mut i = Self::hash(key) as usize & mask;
        loop {
            let slot = self.slots[i];
            if slot.key == key {
                return Some((slot.start, slot.len));
            }
            if slot.key == Self::EMPTY {
                return None;
            }
            i = (i + 1) & mask;
        }
    }
}

/// Hash grid over a cloud for exact radius-bounded k-NN: the points grouped
/// by cell, each cell a contiguous range. A query of radius `r` visits the
/// cells that the ball around it touches (for `r ≤ cell` at most 3×3×3),
/// nearest first, and stops at the first cell farther than the current
/// k-th neighbour: several times faster than a k-d tree query on the flat,
/// tie-rich clouds of LiDAR maps (see the timing test in
/// `tests/scan_matching_props.rs`).
#[derive(Default)]
struct NeighbourGrid {
    cell_m: f64,
    /// Packed cell key ([`pack_cell`]) → (first index, count) into
    /// `points_world`.
    cells: CellTable,
    /// The cloud's points, grouped by cell.
    points_world: Vec<Vector3<f64>>,
}

impl NeighbourGrid {
    fn build(points_world: &[Vector3<f64>], cell_m: f64) -> Self {
        let keys: Vec<u64> = points_world
            .iter()
            .map(|p| pack_cell(voxel_key(p, cell_m)))
            .collect();
        let mut cells = CellTable::with_cells(points_world.len() / 4 + 16);
        let mut distinct = 0usize;
        for &key in &keys {
            let slot = cells.entry(key);
            distinct += usize::from(slot.len == 0);
            slot.len += 1;
            // Grow before the table is more than half full.
            if 2 * distinct >= cells.slots.len() {
                let mut grown = CellTable::with_cells(2 * distinct);
                for old in cells.slots.iter().filter(|s| s.key != CellTable::EMPTY) {
                    *grown.entry(old.key) = *old;
                }
                cells = grown;
            }
        }
        // Prefix sums give each cell its range, cells laid out in packed-key
        // order (z fastest) so that a query's neighbouring cells are close
        // in memory; then scatter the points (in input order within a cell).
        let mut occupied: Vec<u64> = cells
            .slots
            .iter()
            .filter(|s| s.key != CellTable::EMPTY)
            .map(|s| s.key)
            .collect();
        occupied.sort_unstable();
        let mut start = 0u32;
        for &key in &occupied {
            let slot = cells.entry(key);
            slot.start = start;
            start += slot.len;
            slot.len = 0;
        }
        let mut grouped = vec![Vector3::zeros(); points_world.len()];
        for (p, &key) in points_world.iter().zip(&keys) {
            let slot = cells.entry(key);
            grouped[(slot.start + slot.len) as usize] = *p;
            slot.len += 1;
        }
        Self {
            cell_m,
            cells,
            points_world: grouped,
        }
    }

    /// See [`MapCloud::nearest_k_within`]; exact for a radius up to one cell
    /// (the caller's condition).
    fn nearest_k_within(
        &self,
        q: &Vector3<f64>,
        k: usize,
        radius_m: f64,
        out: &mut Vec<Neighbour>,
    ) {
        let r_sq = radius_m * radius_m;
        let c = self.cell_m;
        // Cells overlapping the box [q − r, q + r] on each axis.
        let span = |v: f64| {
            (
                floor_to_i64((v - radius_m) / c),
                floor_to_i64((v + radius_m) / c),
            )
        };
        // Squared distance from coordinate v to cell i along one axis.
        let gap_sq = |v: f64, i: i64| {
            let (lo, hi) = (i as f64 * c, (i + 1) as f64 * c);
            let d = if v < lo {
                lo - v
            } else if v > hi {
                v - hi
            } else {
                0.0
            };
            d * d
        };
        // The cells the ball touches (at most 3 per axis for a radius up to
        // one cell), visited nearest first: once `k` points are found, the
        // k-th distance bounds the search and the farther cells are skipped
        // without a lookup.
        let (xs, ys, zs) = (span(q.x), span(q.y), span(q.z));
        let mut near = [(0.0, (0i64, 0i64, 0i64)); 27];
        let mut count = 0;
        for ix in xs.0..=xs.1 {
            let gx = gap_sq(q.x, ix);
            for iy in ys.0..=ys.1 {
                let gxy = gx + gap_sq(q.y, iy);
                if gxy > r_sq {
                    continue;
                }
                for iz in zs.0..=zs.1 {
                    let g = gxy + gap_sq(q.z, iz);
                    if g > r_sq || count == near.len() {
                        continue;
                    }
                    // insertion keeps equal gaps in loop order
                    let mut at = count;
                    while at > 0 && near[at - 1].0 > g {
                        near[at] = near[at - 1];
                        at -= 1;
                    }
                    near[at] = (g, (ix, iy, iz));
                    count += 1;
                }
            }
        }
        // The top-k list as distances and point indices, moved as 12 bytes
        // instead of a 32-byte `Neighbour` per shift; on the stack up to
        // `MAX_STACK_K`.
        const MAX_STACK_K: usize = 16;
        let (mut stack_dists, mut stack_indices) = ([0.0f64; MAX_STACK_K], [0u32; MAX_STACK_K]);
        let (mut heap_dists, mut heap_indices) = (Vec::new(), Vec::new());
        let (dists, indices) = if k <= MAX_STACK_K {
            (&mut stack_dists[..k], &mut stack_indices[..k])
        } else {
            heap_dists.resize(k, 0.0);
            heap_indices.resize(k, 0);
            (&mut heap_dists[..], &mut heap_indices[..])
        };
        let len = self.top_k(q, &near[..count], r_sq, dists, indices);
        out.extend(
            dists[..len]
                .iter()
                .zip(&indices[..len])
                .map(|(&d, &i)| Neighbour {
                    point_world: self.points_world[i as usize],
                    dist_sq_m2: d,
                }),
        );
    }

    /// The `dists.len()` nearest points within the squared distance `bound`
    /// in the cells `near` (nearest first, with their gaps to the query),
    /// written as squared distances and point indices into `dists` and
    /// `indices`, closest first (a tie goes after the equal ones); returns
    /// how many were found.
    fn top_k(
        &self,
        q: &Vector3<f64>,
        near: &[(f64, (i64, i64, i64))],
        mut bound: f64,
        dists: &mut [f64],
        indices: &mut [u32],
    ) -> usize {
        let k = dists.len();
        let mut len = 0usize;
        for &(gap, cell) in near {
            if gap > bound {
                break;
            }
            let Some((start, cell_len)) = self.cells.get(pack_cell(cell)) else {
                continue;
            };
            let cell = &self.points_world[start as usize..(start + cell_len) as usize];
            for (offset, p) in cell.iter().enumerate() {
                let d_sq = (p - q).norm_squared();
                // One well-predicted test per candidate: `bound` is r²
                // until the list is full, then the k-th distance.
                if d_sq > bound {
                    continue;
                }
                // A tie with the k-th changes nothing and is skipped.
                let mut at = if len < k {
                    len += 1;
                    len - 1
                } else if d_sq < bound {
                    k - 1
                } else {
                    continue;
                };
                while at > 0 && dists[at - 1] > d_sq {
                    dists[at] = dists[at - 1];
                    indices[at] = indices[at - 1];
                    at -= 1;
                }
                dists[at] = d_sq;
                indices[at] = start + offset as u32;
                if len == k {
                    bound = dists[k - 1];
                }
            }
        }
        len
    }
}

/// One downsampled world-frame cloud with its neighbour grid and (built on
/// first use) k-d tree.
#[derive(Default)]
pub struct MapCloud {
    points_world: Vec<Vector3<f64>>,
    /// Built lazily by [`MapCloud::nearest_k`]: scan matching only uses the
    /// grid, so keyframe insertion does not pay for the tree. `None`
    /// inside = construction failed (only possible
    /// beyond u32::MAX points); queries then fall back to brute force.
    tree: OnceLock<Option<ImmutableKdTree<f64, 3>>>,
    grid: NeighbourGrid,
}

impl std::fmt::Debug for MapCloud {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MapCloud")
            .field("len", &self.points_world.len())
            .finish()
    }
}

impl MapCloud {
    fn build(points_world: Vec<Vector3<f64>>, grid_cell_m: f64) -> Self {
        let grid = NeighbourGrid::build(&points_world, grid_cell_m);
        Self {
            points_world,
            tree: OnceLock::new(),
            grid,
        }
    }

    /// The k-d tree, built on first call.
    fn tree(&self) -> Option<&ImmutableKdTree<f64, 3>> {
        self.tree
            .get_or_init(|| {
                if self.points_world.is_empty() {
                    return None;
                }
                let coords: Vec<[f64; 3]> =
                    self.points_world.iter().map(|p| [p.x, p.y, p.z]).collect();
                ImmutableKdTree::<f64, 3>::new_from_slice(&coords).ok()
            })
            .as_ref()
    }

    /// The downsampled points (world frame).
    pub fn points_world(&self) -> &[Vector3<f64>] {
        &self.points_world
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points_world.len()
    }

    /// True when the cloud has no points.
    pub fn is_empty(&self) -> bool {
        self.points_world.is_empty()
    }

    /// The `k` nearest points to `query_world` (k-d tree), closest first,
    /// written into `out` (cleared first; fewer than `k` when the cloud is
    /// smaller).
    pub fn nearest_k(&self, query_world: &Vector3<f64>, k: NonZeroUsize, out: &mut Vec<Neighbour>) {
        out.clear();
        let Some(tree) = self.tree() else {
            // No tree (empty cloud, or construction failed): brute force.
            out.extend(self.points_world.iter().map(|p| Neighbour {
                point_world: *p,
                dist_sq_m2: (p - query_world).norm_squared(),
            }));
            out.sort_by(|a, b| a.dist_sq_m2.total_cmp(&b.dist_sq_m2));
            out.truncate(k.get());
            return;
        };
        let q = [query_world.x, query_world.y, query_world.z];
        let found = tree
            .query(&q)
            .nearest_n::<SquaredEuclidean<f64>>(k)
            .execute();
        out.extend(found.iter().map(|r| Neighbour {
            point_world: self.points_world[r.item as usize],
            dist_sq_m2: r.distance,
        }));
    }

    /// The `k` nearest points within `radius_m` of `query_world`, closest
    /// first, written into `out` (cleared first; fewer than `k` when fewer
    /// lie within the radius). Exact; uses the hash grid when `radius_m` is
    /// at most one grid cell (no allocation for `k` up to 16 once `out` has
    /// capacity `k`),
    /// the k-d tree otherwise.
    pub fn nearest_k_within(
        &self,
        query_world: &Vector3<f64>,
        k: NonZeroUsize,
        radius_m: f64,
        out: &mut Vec<Neighbour>,
    ) {
        out.clear();
        if self.is_empty() || radius_m.is_nan() || radius_m < 0.0 {
            return;
        }
        if radius_m <= self.grid.cell_m {
            out.reserve(k.get());
            self.grid
                .nearest_k_within(query_world, k.get(), radius_m, out);
        } else {
            self.nearest_k(query_world, k, out);
            let r_sq = radius_m * radius_m;
            out.retain(|n| n.dist_sq_m2 <= r_sq);
        }
    }
}

/// A keyframe's features in the world frame.
#[derive(Debug, Clone)]
struct Keyframe {
    t_world_lidar: Isometry3<f64>,
    edge_world: Vec<Vector3<f64>>,
    planar_world: Vec<Vector3<f64>>,
}

/// Running per-voxel sums of the kept keyframes' points, so that a new
/// keyframe costs one hash update per added or dropped point instead of a
/// voxelisation of the whole union. The centroid of a voxel is the same as
/// [`voxel_downsample`] of the union would give (up to rounding of the
/// running sums, ~1e-14 m; a voxel's sum restarts when it empties).
#[derive(Debug, Default)]
struct VoxelAccumulator {
    voxels: VoxelMap<(Vector3<f64>, u32)>,
}

impl VoxelAccumulator {
    fn add(&mut self, points_world: &[Vector3<f64>], voxel_m: f64) {
        self.voxels.reserve(points_world.len());
        for p in points_world {
            let acc = self
                .voxels
                .entry(voxel_key(p, voxel_m))
                .or_insert((Vector3::zeros(), 0));
            acc.0 += p;
            acc.1 += 1;
        }
    }

    fn remove(&mut self, points_world: &[Vector3<f64>], voxel_m: f64) {
        for p in points_world {
            if let Entry::Occupied(mut e) = self.voxels.entry(voxel_key(p, voxel_m)) {
                let acc = e.get_mut();
                acc.0 -= p;
                acc.1 -= 1;
                if acc.1 == 0 {
                    e.remove();
                }
            }
        }
    }

    fn centroids(&self) -> Vec<Vector3<f64>> {
        self.voxels
            .values()
            .map(|(sum, n)| sum / f64::from(*n))
            .collect()
    }
}

/// Map of recent keyframes' edge and planar features (world frame).
#[derive(Debug)]
pub struct LocalMap {
    config: LocalMapConfig,
    keyframes: VecDeque<Keyframe>,
    edge_voxels: VoxelAccumulator,
    planar_voxels: VoxelAccumulator,
    edge: MapCloud,
    planar: MapCloud,
}

impl LocalMap {
    /// An empty map. The config is checked by [`LocalMap::add_keyframe`].
    pub fn new(config: LocalMapConfig) -> Self {
        Self {
            config,
            keyframes: VecDeque::new(),
            edge_voxels: VoxelAccumulator::default(),
            planar_voxels: VoxelAccumulator::default(),
            edge: MapCloud::default(),
            planar: MapCloud::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &LocalMapConfig {
        &self.config
    }

    /// Adds a keyframe: transforms its features to the world frame, drops old
    /// or distant keyframes and rebuilds the downsampled clouds and grids
    /// (the k-d trees are rebuilt on their first query).
    /// Non-finite points are dropped.
    ///
    /// # Errors
    /// [`LocalMapError::InvalidConfig`] when the map's config is invalid,
    /// [`LocalMapError::NonFinitePose`] for a non-finite pose; the map is
    /// unchanged in both cases.
    pub fn add_keyframe(
        &mut self,
        t_world_lidar: &Isometry3<f64>,
        edge_points_lidar: &[Vector3<f64>],
        planar_points_lidar: &[Vector3<f64>],
    ) -> Result<(), LocalMapError> {
        self.config.validate()?;
        let finite_pose = t_world_lidar
            .translation
            .vector
            .iter()
            .all(|v| v.is_finite())
            && t_world_lidar.rotation.coords.iter().all(|v| v.is_finite());
        if !finite_pose {
            return Err(LocalMapError::NonFinitePose);
        }
        let (edge_m, planar_m) = (self.config.edge_voxel_m, self.config.planar_voxel_m);
        let to_world = |pts: &[Vector3<f64>]| -> Vec<Vector3<f64>> {
            pts.iter()
                .filter(|p| p.iter().all(|v| v.is_finite()))
                .map(|p| (t_world_lidar * nalgebra::Point3::from(*p)).coords)
                .collect()
        };
        // Each keyframe is stored downsampled at the map's voxel sizes (as
        // LIO-SAM stores its keyframe clouds), which keeps the map's
        // per-voxel sums small to update.
        let keyframe = Keyframe {
            t_world_lidar: *t_world_lidar,
            edge_world: voxel_downsample(&to_world(edge_points_lidar), edge_m),
            planar_world: voxel_downsample(&to_world(planar_points_lidar), planar_m),
        };
        self.edge_voxels.add(&keyframe.edge_world, edge_m);
        self.planar_voxels.add(&keyframe.planar_world, planar_m);
        self.keyframes.push_back(keyframe);

        // Drop keyframes beyond the radius of the newest, then the oldest
        // beyond the count (the newest is at distance 0 and always kept).
        let newest = t_world_lidar.translation.vector;
        let radius = self.config.max_radius_m;
        let mut kept = VecDeque::with_capacity(self.keyframes.len());
        let mut dropped = Vec::new();
        for kf in self.keyframes.drain(..) {
            if (kf.t_world_lidar.translation.vector - newest).norm() <= radius {
                kept.push_back(kf);
            } else {
                dropped.push(kf);
            }
        }
        while kept.len() > self.config.max_keyframes {
            dropped.extend(kept.pop_front());
        }
        self.keyframes = kept;
        for kf in &dropped {
            self.edge_voxels.remove(&kf.edge_world, edge_m);
            self.planar_voxels.remove(&kf.planar_world, planar_m);
        }

        let cell = self.config.grid_cell_m;
        self.edge = MapCloud::build(self.edge_voxels.centroids(), cell);
        self.planar = MapCloud::build(self.planar_voxels.centroids(), cell);
        Ok(())
    }

    /// Removes every keyframe and point.
    pub fn clear(&mut self) {
        self.keyframes.clear();
        self.edge_voxels = VoxelAccumulator::default();
        self.planar_voxels = VoxelAccumulator::default();
        self.edge = MapCloud::default();
        self.planar = MapCloud::default();
    }

    /// The downsampled edge-feature cloud and its tree.
    pub fn edge_cloud(&self) -> &MapCloud {
        &self.edge
    }

    /// The downsampled planar-feature cloud and its tree.
    pub fn planar_cloud(&self) -> &MapCloud {
        &self.planar
    }

    /// Number of (downsampled) edge points in the map.
    pub fn edge_len(&self) -> usize {
        self.edge.len()
    }

    /// Number of (downsampled) planar points in the map.
    pub fn planar_len(&self) -> usize {
        self.planar.len()
    }

    /// Number of keyframes kept.
    pub fn keyframe_count(&self) -> usize {
        self.keyframes.len()
    }

    /// Poses of the kept keyframes, oldest first.
    pub fn keyframe_poses(&self) -> impl Iterator<Item = &Isometry3<f64>> {
        self.keyframes.iter().map(|kf| &kf.t_world_lidar)
    }

    /// True when the map has no points at all.
    pub fn is_empty(&self) -> bool {
        self.edge.is_empty() && self.planar.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(x: f64) -> Isometry3<f64> {
        Isometry3::translation(x, 0.0, 0.0)
    }

    #[test]
    fn keeps_last_n_and_within_radius() {
        let config = LocalMapConfig {
            max_keyframes: 3,
            max_radius_m: 10.0,
            ..Default::default()
        };
        let mut map = LocalMap::new(config);
        assert!(map.is_empty());
        let pts = [Vector3::new(1.0, 2.0, 3.0)];
        for i in 0..5 {
            map.add_keyframe(&pose(f64::from(i)), &pts, &pts).unwrap();
        }
        assert_eq!(map.keyframe_count(), 3);
        let xs: Vec<f64> = map.keyframe_poses().map(|t| t.translation.x).collect();
        assert_eq!(xs, vec![2.0, 3.0, 4.0]);
        // A jump of 20 m drops every older keyframe (radius 10 m).
        map.add_keyframe(&pose(24.0), &pts, &pts).unwrap();
        assert_eq!(map.keyframe_count(), 1);
        assert_eq!(map.edge_len(), 1);
        assert!((map.edge_cloud().points_world()[0] - Vector3::new(25.0, 2.0, 3.0)).norm() < 1e-12);
    }

    #[test]
    fn rejects_bad_config_and_pose() {
        let mut map = LocalMap::new(LocalMapConfig {
            planar_voxel_m: -1.0,
            ..Default::default()
        });
        let err = map.add_keyframe(&pose(0.0), &[], &[]).unwrap_err();
        assert!(matches!(
            err,
            LocalMapError::InvalidConfig {
                field: "planar_voxel_m",
                ..
            }
        ));
        let mut map = LocalMap::new(LocalMapConfig::default());
        let bad = Isometry3::translation(f64::NAN, 0.0, 0.0);
        assert_eq!(
            map.add_keyframe(&bad, &[], &[]),
            Err(LocalMapError::NonFinitePose)
        );
        map.add_keyframe(&pose(0.0), &[], &[]).unwrap();
        assert!(map.is_empty());
        let mut out = Vec::new();
        map.planar_cloud()
            .nearest_k(&Vector3::zeros(), NonZeroUsize::new(5).unwrap(), &mut out);
        assert!(out.is_empty());
    }

    /// A cloud with (nearly) one point per grid cell makes the cell table
    /// grow while it is built; queries still equal brute force.
    #[test]
    fn grid_with_one_point_per_cell_equals_brute_force() {
        let points: Vec<Vector3<f64>> = (0..2000)
            .map(|i| {
                let f = f64::from(i);
                Vector3::new(
                    2.1 * (f % 13.0),
                    2.3 * ((f / 13.0).floor() % 11.0),
                    0.37 * f % 29.0,
                )
            })
            .collect();
        let cloud = MapCloud::build(points.clone(), 2.0);
        let k = NonZeroUsize::new(4).unwrap();
        let mut out = Vec::new();
        for q in points.iter().step_by(7) {
            let q = q + Vector3::new(0.3, -0.4, 0.5);
            cloud.nearest_k_within(&q, k, 2.0, &mut out);
            let mut brute: Vec<f64> = points
                .iter()
                .map(|p| (p - q).norm_squared())
                .filter(|&d| d <= 4.0)
                .collect();
            brute.sort_by(f64::total_cmp);
            brute.truncate(4);
            let found: Vec<f64> = out.iter().map(|n| n.dist_sq_m2).collect();
            assert_eq!(found, brute);
        }
    }

    /// The pipeline may match scans on another thread than the one that
    /// inserts keyframes.
    #[test]
    fn local_map_is_send_and_sync() {
        fn assert_send_sync<T: Send + Sync>() {}
        assert_send_sync::<LocalMap>();
    }
}
