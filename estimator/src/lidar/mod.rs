//! LiDAR front end: motion compensation, LOAM feature extraction, the local
//! feature map and scan-to-map matching.
//!
//! One sweep goes through the stages in this order:
//! [`Deskewer`] (every point into the LiDAR frame at one reference time,
//! driven by a [`SweepMotion`]) -> [`FeatureExtractor`] (edge and planar
//! points, [`ScanFeatures`]) -> [`VoxelDownsampler`] -> [`match_scan`]
//! against the [`LocalMap`] of recent keyframes -> [`LocalMap::add_keyframe`].
//! Points are in metres; `_lidar` names the sensor frame, `_world` the map
//! frame.

pub use cell_planes::{CellPlaneConfig, MapPlane};
pub use deskew::{DESKEW_RELATIVE_TOLERANCE, DeskewError, Deskewer, SweepMotion, deskew};
pub use features::{
    FeatureConfig, FeatureConfigError, FeatureExtractor, ScanFeatures, extract_features,
    sort_ring_by,
};
pub use local_map::{LocalMap, LocalMapConfig, LocalMapError, MapCloud};
pub use neighbour_grid::Neighbour;
pub use scan_matching::{
    ScanMatchConfig, ScanMatchError, ScanMatchResult, match_scan, point_to_line_residual,
    point_to_plane_residual,
};
pub use voxel::{VoxelDownsampler, VoxelKey, voxel_downsample, voxel_key};

mod cell_planes;
mod deskew;
mod features;
mod local_map;
mod neighbour_grid;
mod scan_matching;
mod voxel;
