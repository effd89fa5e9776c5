//! `limot`: data sources, file formats and evaluation around the estimator.

pub mod eval;
pub mod kitti;
pub mod report;
