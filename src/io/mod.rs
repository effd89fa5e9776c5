//! Everything that reads or writes a file format or a dataset.
//!
//! - [`kitti`]: KITTI tracking and raw-drive files (calibration, labels,
//!   detections, OXTS, poses, results, seqmaps, Velodyne scans), the raw
//!   drive and tracking-sequence openers, and the KITTI-style export of a
//!   simulated dataset.
//! - [`Source`]: a dataset opened for the estimator (a limot dataset, a KITTI
//!   raw drive, bare scans, a KITTI tracking sequence or a ROS 2 bag), with [`ImuFeed`],
//!   which hands the estimator the IMU samples due before each sweep.
//! - [`write_run_files`]: the files of a run of the estimator (poses,
//!   estimates, timings, tracks).
//! - [`mcap`]: the Foxglove MCAP recording of a dataset and of a run.
//! - [`rosbag`]: ROS 2 bags (MCAP): read as a source, written from one.
pub mod kitti;
pub mod mcap;
pub mod rosbag;
mod run_files;
mod source;

pub use run_files::{WriteError, write_run_files};
pub use source::{
    GRAVITY_ESTIMATION_MAX_IMU_PERIOD_S, IMU_GAP_PERIODS, IMU_LOOKBACK_S, ImuFeed,
    SWEEP_END_TOLERANCE_S, Source, SourceError, imu_gap_limit_s, imu_noise_for_rate,
    imu_resolves_gravity,
};
