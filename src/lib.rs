//! `limot`: data sources, file formats and evaluation around the estimator.

pub mod kitti;
