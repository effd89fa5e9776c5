//! Experiments: the glue that runs variants on datasets and scores them.

pub mod kitti_suite;
pub mod realism;
pub mod score;
pub mod suite;
pub mod track_kitti;
