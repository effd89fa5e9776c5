//! Why a ROS 2 bag cannot be read. Every variant names the bag; a message's
//! fault names its topic, its index on that topic (0-based, in file order)
//! and the field.

use std::path::PathBuf;

/// Why a ROS 2 bag cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The bag could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// The bag.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The MCAP container is malformed, truncated or compressed in a way
    /// this build does not read.
    #[error("{path}: not a readable MCAP file: {message}")]
    Mcap {
        /// The bag.
        path: PathBuf,
        /// What the MCAP reader found.
        message: String,
    },
    /// A topic the command names has no messages in the bag.
    #[error("{path}: no messages on the {role} topic `{topic}`; the bag's topics: {topics}")]
    UnknownTopic {
        /// The bag.
        path: PathBuf,
        /// `LiDAR`, `IMU` or `detections`.
        role: &'static str,
        /// The topic asked for.
        topic: String,
        /// Every topic with messages and its schema.
        topics: String,
    },
    /// A topic's channel is not what limot reads.
    #[error("{path}: topic `{topic}`: {what} is `{found}`, but limot reads {expected}")]
    Unsupported {
        /// The bag.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// `message encoding`, `schema` or `schema encoding`.
        what: &'static str,
        /// What the channel has.
        found: String,
        /// What would be read.
        expected: String,
    },
    /// A message cannot be used.
    #[error("{path}: topic `{topic}` message {index}: field `{field}`: {message}")]
    Message {
        /// The bag.
        path: PathBuf,
        /// The message's topic.
        topic: String,
        /// Its index on the topic, 0-based, in file order.
        index: usize,
        /// The field at fault (`data` for a message that does not decode).
        field: String,
        /// What is wrong.
        message: String,
    },
    /// The LiDAR-IMU extrinsic is neither given nor in `/tf_static`, or its
    /// file is invalid.
    #[error("{path}: {message}")]
    Extrinsic {
        /// The bag, or the extrinsic file.
        path: PathBuf,
        /// What is missing or wrong.
        message: String,
    },
}
