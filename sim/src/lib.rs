//! LIMOT simulation testbed: scenario generation, traffic, a rolling 64-beam
//! LiDAR ray-cast against a rapier3d world, a noisy IMU, a detector model and
//! exact ground truth. Knows nothing about estimation.

pub mod detector;
mod fast_trig;
pub mod hdl64;
pub mod imu;
pub mod lidar;
pub mod lidar_scan;
pub mod record;
pub mod roughness;
pub mod scenario;
pub mod scene;
pub mod simulation;
pub mod traffic;
pub mod trajectory;
pub mod world;
