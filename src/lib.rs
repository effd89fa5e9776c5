//! `limot`: data sources, file formats and evaluation around the estimator.

pub mod cli;
pub mod demo;
pub mod eval;
pub mod evaluate;
pub mod io;
pub mod kitti_report;
pub mod kitti_suite;
pub mod realism;
pub mod report;
pub mod run;
pub mod simulate;
pub mod suite;
pub mod suite_report;
pub mod track_kitti;
