//! The sensor models: the rolling 64-beam LiDAR ray-cast against the
//! [`World`], the IMU, and the object detector.
//!
//! Each model is deterministic given its seed; [`crate::Simulation`] derives
//! one seed per sensor from the scenario seed.

mod detector;
mod imu;
mod lidar;
mod lidar_scan;

pub use crate::world::{GROUND_RANGE_TOLERANCE_M, RayHit, Surface, World, WorldAt};
pub use detector::{ClassNoise, DetectionWithTruth, Detector, DetectorConfig, DetectorError};
pub use imu::{ImuConfig, ImuError, ImuSimulator, ImuStream};
pub use lidar::LidarConfig;
pub use lidar_scan::{LidarError, LidarSimulator, SimulatedScan};

pub mod hdl64;
