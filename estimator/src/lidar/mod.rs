//! LiDAR processing: motion compensation and LOAM feature extraction.

pub mod deskew;
pub mod features;
pub mod local_map;
pub mod scan_matching;
pub mod voxel;
