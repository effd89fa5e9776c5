//! Hash grid over a point cloud for exact radius-bounded k-NN, the search
//! LOAM matching runs once per feature point: the points grouped by cell,
//! each cell a contiguous range found through an open-addressing table.

use nalgebra::Vector3;

use super::voxel::{VoxelKey, voxel_key};
use crate::geometry::floor_to_i64;

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
pub(super) fn pack_cell((x, y, z): VoxelKey) -> u64 {
    const MASK: u64 = (1 << 21) - 1;
    ((x as u64 & MASK) << 42) | ((y as u64 & MASK) << 21) | (z as u64 & MASK)
}

/// One slot of [`CellTable`]: a packed cell key and its range of points.
#[derive(Debug, Clone, Copy)]
pub(super) struct CellSlot {
    pub(super) key: u64,
    pub(super) start: u32,
    pub(super) len: u32,
}

/// Open-addressing hash table (linear probing, at most half full) from
/// packed cell keys to their point ranges: a lookup is one hash and, almost
/// always, one 16-byte slot read, with no tag groups or indirection.
#[derive(Debug, Default)]
pub(super) struct CellTable {
    /// Power-of-two length (or empty); empty slots have key [`Self::EMPTY`].
    slots: Vec<CellSlot>,
}

impl CellTable {
    pub(super) const EMPTY: u64 = u64::MAX;

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
    pub(super) fn with_cells(cells: usize) -> Self {
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
    pub(super) fn entry(&mut self, key: u64) -> &mut CellSlot {
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
    pub(super) fn get(&self, key: u64) -> Option<(u32, u32)> {
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
pub(super) struct NeighbourGrid {
    pub(super) cell_m: f64,
    /// Packed cell key ([`pack_cell`]) → (first index, count) into
    /// `points_world`.
    cells: CellTable,
    /// The cloud's points, grouped by cell.
    points_world: Vec<Vector3<f64>>,
}

impl NeighbourGrid {
    pub(super) fn build(points_world: &[Vector3<f64>], cell_m: f64) -> Self {
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

    /// The occupied cells' points, one slice per cell.
    pub(super) fn cells(&self) -> impl Iterator<Item = &[Vector3<f64>]> {
        self.cells
            .slots
            .iter()
            .filter(|s| s.key != CellTable::EMPTY)
            .map(|s| &self.points_world[s.start as usize..(s.start + s.len) as usize])
    }

    /// See [`super::MapCloud::nearest_k_within`]; exact for a radius up to one cell
    /// (the caller's condition).
    pub(super) fn nearest_k_within(
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
