//! `limot`: data sources, file formats and evaluation around the estimator.

pub mod demo;
pub mod eval;
pub mod evaluate;
pub mod kitti;
pub mod kitti_export;
pub mod kitti_report;
pub mod kitti_suite;
pub mod realism;
pub mod report;
pub mod run;
pub mod simulate;
pub mod suite;
pub mod suite_report;
pub mod track_kitti;
