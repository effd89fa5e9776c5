//! `limot`: data sources, file formats and evaluation around the estimator.

#![warn(missing_docs)]

pub mod cli;
pub mod demo;
pub mod experiments;
pub mod io;
pub mod metrics;
pub mod report;
pub mod run;
pub mod simulate;
