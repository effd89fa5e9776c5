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
//! * for the planar cloud, a plane per octant of that grid's cells where the
//!   octant's points make one ([`MapCloud::plane_at`], `cell_planes.rs`);
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

use super::cell_planes::{CellPlaneConfig, CellPlanes, MapPlane};
use super::neighbour_grid::{Neighbour, NeighbourGrid};
use super::voxel::{VoxelMap, voxel_downsample, voxel_key};

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
    /// Planes of the planar map's octants of grid cells (edge
    /// `grid_cell_m / 2`), which scan matching uses instead of a k-NN fit
    /// where an octant has one; `None` = k-NN for every planar point.
    pub cell_planes: Option<CellPlaneConfig>,
}

impl Default for LocalMapConfig {
    fn default() -> Self {
        Self {
            max_keyframes: 25,
            max_radius_m: 50.0,
            edge_voxel_m: 0.2,
            planar_voxel_m: 0.4,
            grid_cell_m: 2.0,
            cell_planes: Some(CellPlaneConfig::default()),
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
        if let Some(planes) = &self.cell_planes {
            if planes.min_points < 3 {
                return Err(LocalMapError::InvalidConfig {
                    field: "cell_planes.min_points",
                    value: planes.min_points as f64,
                    reason: "a plane needs at least 3 points",
                });
            }
            for (field, value, least, reason) in [
                (
                    "cell_planes.max_residual_m",
                    planes.max_residual_m,
                    0.0,
                    "must be positive and finite",
                ),
                (
                    "cell_planes.min_eigenvalue_ratio",
                    planes.min_eigenvalue_ratio,
                    1.0,
                    "must be finite and above 1",
                ),
            ] {
                if !(value.is_finite() && value > least) {
                    return Err(LocalMapError::InvalidConfig {
                        field,
                        value,
                        reason,
                    });
                }
            }
        }
        Ok(())
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
    /// Empty unless the cloud was built with a [`CellPlaneConfig`].
    planes: CellPlanes,
}

impl std::fmt::Debug for MapCloud {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MapCloud")
            .field("len", &self.points_world.len())
            .finish()
    }
}

impl MapCloud {
    fn build(
        points_world: Vec<Vector3<f64>>,
        grid_cell_m: f64,
        planes: Option<&CellPlaneConfig>,
    ) -> Self {
        let grid = NeighbourGrid::build(&points_world, grid_cell_m);
        let planes = planes.map_or_else(CellPlanes::default, |c| CellPlanes::build(&grid, c));
        Self {
            points_world,
            tree: OnceLock::new(),
            grid,
            planes,
        }
    }

    /// The plane of the grid octant (edge half a grid cell) that holds
    /// `query_world`, if the cloud was built with planes, that octant's
    /// points make one and `query_world` lies within
    /// [`CellPlaneConfig::max_residual_m`] of it.
    #[inline]
    pub fn plane_at(&self, query_world: &Vector3<f64>) -> Option<MapPlane> {
        self.planes.plane_at(query_world)
    }

    /// Number of grid octants with a plane.
    pub fn plane_count(&self) -> usize {
        self.planes.len()
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
        self.edge = MapCloud::build(self.edge_voxels.centroids(), cell, None);
        self.planar = MapCloud::build(
            self.planar_voxels.centroids(),
            cell,
            self.config.cell_planes.as_ref(),
        );
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
        let planes = CellPlaneConfig::default();
        for (bad, field) in [
            (
                CellPlaneConfig {
                    min_points: 2,
                    ..planes
                },
                "cell_planes.min_points",
            ),
            (
                CellPlaneConfig {
                    max_residual_m: f64::NAN,
                    ..planes
                },
                "cell_planes.max_residual_m",
            ),
            (
                CellPlaneConfig {
                    min_eigenvalue_ratio: 1.0,
                    ..planes
                },
                "cell_planes.min_eigenvalue_ratio",
            ),
        ] {
            let config = LocalMapConfig {
                cell_planes: Some(bad),
                ..Default::default()
            };
            match config.validate() {
                Err(LocalMapError::InvalidConfig { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
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
        let cloud = MapCloud::build(points.clone(), 2.0, None);
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
