//! The Foxglove MCAP recording of a dataset and of a run on it
//! (`--mcap FILE` of `limot simulate`, `run` and `demo`): one file that
//! Foxglove shows with the layout `docs/foxglove-layout.json`.
//!
//! Every message is a Foxglove well-known schema, protobuf-encoded, logged
//! at the time of the data (the sweep start), never the wall clock:
//!
//! | topic | schema | frame |
//! |---|---|---|
//! | [`TOPIC_TF`] `/tf` | `foxglove.FrameTransforms` | `world -> lidar`, `lidar -> imu`, `world -> world_truth` |
//! | [`TOPIC_CLOUD`] `/lidar/points` | `foxglove.PointCloud` (x, y, z f32 + `removed` u8) | `lidar` |
//! | [`TOPIC_DETECTIONS`] `/detections` | `foxglove.SceneUpdate` | `lidar` |
//! | [`TOPIC_TRACKS`] `/tracks` | `foxglove.SceneUpdate` (box, label, velocity arrow) | `world` |
//! | [`TOPIC_PATH`] `/ego/path` | `foxglove.PosesInFrame` | `world` |
//! | [`TOPIC_TRUTH_BOXES`] `/truth/boxes` | `foxglove.SceneUpdate` | `world_truth` |
//! | [`TOPIC_TRUTH_PATH`] `/truth/path` | `foxglove.PosesInFrame` | `world_truth` |
//!
//! The tracks and the estimated path need a run; the truth topics a limot
//! dataset. [`McapFile`] is the container (atomic, deterministic, channels
//! by topic); [`McapFile::write_encoded`] takes messages of other schemas
//! (ROS 2 `sensor_msgs` in CDR, say) beside these.
mod messages;
mod recording;
mod writer;

pub use messages::{POINT_STRIDE_BYTES, REMOVED};
pub use recording::{
    FRAME_IMU, FRAME_LIDAR, FRAME_WORLD, FRAME_WORLD_TRUTH, McapRecorder, McapRequest, TOPIC_CLOUD,
    TOPIC_DETECTIONS, TOPIC_PATH, TOPIC_TF, TOPIC_TRACKS, TOPIC_TRUTH_BOXES, TOPIC_TRUTH_PATH,
    record_dataset,
};
pub(crate) use writer::FrameError;
pub use writer::{LIBRARY, McapError, McapFile, McapStats};
