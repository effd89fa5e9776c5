//! `limot`: data sources, file formats and evaluation around the estimator.

pub mod demo;
pub mod experiments;
pub mod kitti;
pub mod kitti_export;
pub mod metrics;
pub mod report;
pub mod run;
pub mod simulate;
