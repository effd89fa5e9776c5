//! Everything that reads or writes a file format or a dataset.
//!
//! - [`kitti`]: KITTI tracking and raw-drive files (calibration, labels,
//!   detections, OXTS, poses, results, seqmaps, Velodyne scans), the raw
//!   drive and tracking-sequence openers, and the KITTI-style export of a
//!   simulated dataset.
//! - [`Source`]: a dataset opened for the estimator (a limot dataset, a KITTI
//!   raw drive, bare scans or a KITTI tracking sequence), with [`ImuFeed`],
//!   which hands the estimator the IMU samples due before each sweep.
#![warn(missing_docs)]

pub mod kitti;
