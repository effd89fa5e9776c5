//! The sensor models: the rolling 64-beam LiDAR ray-cast against the
//! [`World`], the IMU, and the object detector.
//!
//! Each model is deterministic given its seed; [`crate::Simulation`] derives
//! one seed per sensor from the scenario seed.

pub use crate::detector::{
    ClassNoise, DetectionWithTruth, Detector, DetectorConfig, DetectorError,
};
pub use crate::imu::{ImuConfig, ImuError, ImuSimulator, ImuStream};
pub use crate::lidar::LidarConfig;
pub use crate::lidar_scan::{LidarError, LidarSimulator, SimulatedScan};
pub use crate::world::{RayHit, Surface, World};

/// The Velodyne HDL-64E: beam elevations and the beam -> ring order, and a
/// reader for its calibration file.
pub mod hdl64 {
    pub use crate::hdl64::{
        Hdl64Error, LaserCalib, NUM_LASERS, elevation_table_from, elevation_table_rad,
        parse_calibration, ring_of_beam,
    };
}
