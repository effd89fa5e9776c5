//! A source's raw sensor streams written as a ROS 2 bag (MCAP, profile
//! `ros2`, CDR messages with `ros2msg` schemas): the form
//! [`RosBag`](super::RosBag) reads, and an example of it for users.
//!
//! | topic | type | content |
//! |---|---|---|
//! | [`TOPIC_POINTS`] `/points_raw` | `sensor_msgs/PointCloud2` | every point of the sweep as Velodyne's driver lays it out: x, y, z, intensity f32, ring u16, time f32 (s after `header.stamp` = the sweep start) |
//! | [`TOPIC_IMU`] `/imu` | `sensor_msgs/Imu` | angular rate and specific force, no orientation |
//! | [`TOPIC_TF_STATIC`](super::TOPIC_TF_STATIC) `/tf_static` | `tf2_msgs/TFMessage` | `lidar -> imu`: `T_lidar_imu` |
//! | [`TOPIC_DETECTIONS`] `/detections3d` | `vision_msgs/Detection3DArray` | the sweep's boxes (LiDAR frame), each stamped when it was seen |
//!
//! Every message is logged at its `header.stamp`, in time order.

use super::bag::TOPIC_TF_STATIC;
use super::detections::detection_array;
use super::imu::imu_message;
use super::msgs::{
    self, DETECTION3D_ARRAY, Header, IMU, MESSAGE_ENCODING, POINT_CLOUD2, SCHEMA_ENCODING,
    TF_MESSAGE, TfMessage, Time, Transform, TransformStamped, s_to_ns,
};
use super::pointcloud2::cloud_message;
use crate::io::Source;
use crate::io::mcap::{FRAME_IMU, FRAME_LIDAR, FrameError, McapError, McapFile, McapStats};
use limot_estimator::input::ImuSample;
use std::path::Path;

/// The raw clouds.
pub const TOPIC_POINTS: &str = "/points_raw";
/// The IMU samples.
pub const TOPIC_IMU: &str = "/imu";
/// The detections.
pub const TOPIC_DETECTIONS: &str = "/detections3d";

/// The MCAP profile of a ROS 2 bag.
const PROFILE: &str = "ros2";

/// Writes `source`'s sweeps, IMU samples, extrinsic and detections as the
/// ROS 2 bag `path` (see the module docs), atomically.
///
/// # Errors
/// A frame that cannot be read, a time before 1970 or beyond a ROS time,
/// or a file that cannot be written (each names the file); the file is
/// then not created.
pub fn write_bag(path: &Path, source: &Source) -> Result<McapStats, McapError> {
    let mut file = McapFile::create_with_profile(path, PROFILE)?;
    let time_error = |frame, t_s| McapError::Time {
        path: path.to_path_buf(),
        frame,
        t_s,
    };
    let (imu, t_lidar_imu) = match source.imu() {
        Some((imu, extrinsics)) => (imu, Some(extrinsics.t_lidar_imu)),
        None => (&[][..], None),
    };
    let stamp = |frame: usize, t_s: f64| {
        s_to_ns(t_s)
            .filter(|ns| *ns >= 0)
            .and_then(|ns| Time::from_ns(ns).map(|time| (ns, time)))
            .ok_or_else(|| time_error(frame, t_s))
    };
    let mut next_imu = 0;
    let mut write_imu_until = |file: &mut McapFile, end_s: f64| -> Result<(), McapError> {
        while let Some(sample) = imu.get(next_imu).filter(|s: &&ImuSample| s.t_s <= end_s) {
            let (ns, time) = stamp(0, sample.t_s)?;
            let message = msgs::encode(&imu_message(time, FRAME_IMU, sample));
            write(file, TOPIC_IMU, IMU, ns, &message)?;
            next_imu += 1;
        }
        Ok(())
    };

    let mut first_frame = true;
    source
        .for_each_frame(
            source.frame_range(0, None),
            |index, frame| -> Result<(), FrameError> {
                let t_s = frame.scan.t_s;
                let (ns, time) = stamp(index, t_s)?;
                if std::mem::take(&mut first_frame)
                    && let Some(t) = &t_lidar_imu
                {
                    // static, so stamped with the first message of the bag
                    let first_s = imu.first().map_or(t_s, |s| s.t_s.min(t_s));
                    let (tf_ns, tf_time) = stamp(index, first_s)?;
                    let message = static_transform(tf_time, t);
                    write(
                        &mut file,
                        TOPIC_TF_STATIC,
                        TF_MESSAGE,
                        tf_ns,
                        &msgs::encode(&message),
                    )?;
                }
                write_imu_until(&mut file, t_s)?;
                let cloud = msgs::encode(&cloud_message(time, FRAME_LIDAR, &frame.scan.points));
                write(&mut file, TOPIC_POINTS, POINT_CLOUD2, ns, &cloud)?;
                let array = detection_array(time, FRAME_LIDAR, &frame.detections, |offset_s| {
                    s_to_ns(offset_s)
                        .and_then(|offset_ns| Time::from_ns(ns + offset_ns))
                        .unwrap_or(time)
                });
                let array = msgs::encode(&array);
                write(&mut file, TOPIC_DETECTIONS, DETECTION3D_ARRAY, ns, &array)?;
                Ok(())
            },
        )
        .map_err(|e| e.into_mcap(path))?;
    write_imu_until(&mut file, f64::INFINITY)?;
    file.finish()
}

/// One CDR message of `schema` on `topic`, logged at `stamp_ns`.
fn write(
    file: &mut McapFile,
    topic: &str,
    schema: &str,
    stamp_ns: i64,
    data: &[u8],
) -> Result<(), McapError> {
    let text = msgs::schema_text(schema).unwrap_or_default();
    let schema = foxglove::Schema::new(schema, SCHEMA_ENCODING, text.into_bytes());
    file.write_encoded(topic, Some(schema), MESSAGE_ENCODING, stamp_ns as u64, data)
}

/// `/tf_static`'s message: `lidar -> imu` is `t_lidar_imu`.
fn static_transform(stamp: Time, t_lidar_imu: &nalgebra::Isometry3<f64>) -> TfMessage {
    let q = t_lidar_imu.rotation;
    let v = t_lidar_imu.translation.vector;
    TfMessage {
        transforms: vec![TransformStamped {
            header: Header {
                stamp,
                frame_id: FRAME_LIDAR.to_string(),
            },
            child_frame_id: FRAME_IMU.to_string(),
            transform: Transform {
                translation: msgs::Vector3 {
                    x: v.x,
                    y: v.y,
                    z: v.z,
                },
                rotation: msgs::Quaternion {
                    x: q.i,
                    y: q.j,
                    z: q.k,
                    w: q.w,
                },
            },
        }],
    }
}
