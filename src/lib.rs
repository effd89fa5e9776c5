//! `limot`: data sources, file formats and evaluation around the estimator.
//!
//! - [`allocator`]: the binary's allocator settings;
//! - [`cli`]: the command line, one module per subcommand;
//! - [`io`]: datasets for the estimator ([`io::Source`]) and every file format
//!   (KITTI tracking, raw and odometry files, the KITTI copy of a simulation);
//! - [`run`], [`simulate`], [`demo`]: what `limot run`, `simulate` and `demo` do;
//! - [`metrics`]: all metric code (trajectories, boxes, tracking, filtering,
//!   realism, timing);
//! - [`experiments`]: runs of the variants on datasets and their scores
//!   (result files, the simulated suite, the KITTI suite, the tracker alone);
//! - [`report`]: tables shaped like the paper's, SVG plots, suite and KITTI reports.
//!
//! `docs/architecture.md` follows a frame from disk to poses.

#![warn(missing_docs)]

pub mod allocator;
pub mod cli;
pub mod demo;
pub mod experiments;
pub mod io;
pub mod metrics;
pub mod report;
pub mod run;
pub mod simulate;
