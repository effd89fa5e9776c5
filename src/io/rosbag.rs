//! ROS 2 bags (MCAP, as rosbag2 writes them) in and out.
//!
//! - [`RosBag`]: a bag opened for the estimator (`limot run BAG.mcap
//!   --lidar-topic T --imu-topic T [--detections-topic T] [--extrinsic F]`):
//!   `sensor_msgs/PointCloud2` sweeps with per-point times
//!   ([`pointcloud2`] says which conventions), `sensor_msgs/Imu`, the
//!   LiDAR-IMU extrinsic from a file or `/tf_static`, and
//!   `vision_msgs/Detection3DArray` boxes.
//! - [`write_bag`]: a source's raw streams as such a bag (`limot simulate
//!   --bag FILE`), which [`RosBag`] reads back to the same frames.
//!
//! Messages are CDR with `ros2msg` schemas ([`msgs`]), in chunks that are
//! uncompressed or zstd-compressed (rosbag2's default); errors
//! ([`BagError`]) name the bag, topic, message index and field.
mod bag;
mod detections;
mod error;
mod extrinsic;
mod imu;
pub mod msgs;
pub mod pointcloud2;
mod writer;
mod zstd;

pub use bag::{BagOptions, RosBag, TOPIC_TF_STATIC, topic_listing};
pub use error::BagError;
pub use extrinsic::read_extrinsic_file;
pub use writer::{TOPIC_DETECTIONS, TOPIC_IMU, TOPIC_POINTS, write_bag};
