//! LIMOT estimator: pure estimation, no simulator, no file formats.
//!
//! Everything a source (simulator or KITTI reader) delivers is described by
//! [`input`]; the estimator never knows which source fed it.

pub mod eigen3;
pub mod filter;
pub mod graph;
pub mod imu;
pub mod input;
pub mod lidar;
pub mod lie;
pub mod pipeline;
pub mod polygon;
pub mod tracking;
