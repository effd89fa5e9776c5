//! LiDAR front end: de-skew, LOAM features, voxel grid, local map and scan-to-map matching.

pub mod deskew;
pub mod features;
