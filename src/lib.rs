//! `limot`: data sources, file formats and evaluation around the estimator.

pub mod cli;
pub mod demo;
pub mod experiments;
pub mod io;
pub mod metrics;
pub mod report;
pub mod run;
pub mod simulate;
