//! A ROS 2 bag (MCAP) opened for the estimator.
//!
//! [`RosBag::open`] reads the whole file once: it checks every channel it
//! uses (CDR messages, the expected schema), decodes every IMU sample, the
//! static transforms and the detections, and reads every cloud as a sweep
//! (so a bad message is reported before the estimator starts), keeping only
//! each sweep's times. [`RosBag::for_each_frame`] then streams the file
//! again and hands out one sweep at a time, so memory does not grow with
//! the bag.

use super::detections::detections;
use super::error::BagError;
use super::extrinsic::{StaticTree, read_extrinsic_file};
use super::imu::imu_sample;
use super::msgs::{
    self, DETECTION3D_ARRAY, Detection3DArray, IMU, Imu, MESSAGE_ENCODING, POINT_CLOUD2,
    PointCloud2, TF_MESSAGE, TfMessage, ns_to_s,
};
use super::pointcloud2::{Sweep, read_sweep};
use super::zstd::ZstdChunks;
use limot_estimator::input::{Detection, Extrinsics, Frame, ImuSample, LidarScan};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufReader;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The topic of the static transforms (tf2's).
pub const TOPIC_TF_STATIC: &str = "/tf_static";

/// Schema encodings whose types are read (both name the same CDR layout).
const SCHEMA_ENCODINGS: [&str; 2] = [msgs::SCHEMA_ENCODING, "ros2idl"];

/// Which topics carry what, and where the extrinsic comes from.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct BagOptions {
    /// The `sensor_msgs/PointCloud2` topic.
    pub lidar_topic: String,
    /// The `sensor_msgs/Imu` topic.
    pub imu_topic: String,
    /// A `vision_msgs/Detection3DArray` topic (boxes in the LiDAR frame).
    pub detections_topic: Option<String>,
    /// An extrinsic file ([`read_extrinsic_file`]); without it, `/tf_static`.
    pub extrinsic: Option<PathBuf>,
}

/// A LiDAR message's times.
#[derive(Debug, Clone, Copy)]
struct SweepTimes {
    stamp_ns: i64,
    t_s: f64,
}

/// A ROS 2 bag opened for the estimator (see the module docs).
#[derive(Debug, Clone)]
pub struct RosBag {
    path: PathBuf,
    lidar_topic: String,
    sweeps: Vec<SweepTimes>,
    imu: Vec<ImuSample>,
    extrinsics: Extrinsics,
    detections: Vec<Vec<Detection>>,
    num_rings: u16,
    sweep_duration_s: f64,
    skipped_detections: usize,
}

/// What a topic is used for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    Lidar,
    Imu,
    TfStatic,
    Detections,
}

impl Role {
    fn schema(self) -> &'static str {
        match self {
            Role::Lidar => POINT_CLOUD2,
            Role::Imu => IMU,
            Role::TfStatic => TF_MESSAGE,
            Role::Detections => DETECTION3D_ARRAY,
        }
    }
}

/// The messages of `path` in file order, with the decompressors this build has.
fn messages(path: &Path) -> Result<mcap::io::MessageReader<BufReader<File>>, BagError> {
    let file = File::open(path).map_err(|source| BagError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut reader = mcap::io::MessageReader::new(BufReader::new(file));
    reader
        .add_decompressor(ZstdChunks::default())
        .map_err(|e| mcap_error(path, e))?;
    Ok(reader)
}

fn mcap_error(path: &Path, e: mcap::McapError) -> BagError {
    let message = match e {
        mcap::McapError::UnsupportedCompression(c) => format!(
            "its chunks are compressed with `{c}`, which this build does not read; \
             write it uncompressed or with zstd (e.g. `mcap compress --compression zstd`)"
        ),
        e => e.to_string(),
    };
    BagError::Mcap {
        path: path.to_path_buf(),
        message,
    }
}

/// Checks that `channel` carries `role`'s schema in CDR.
fn check_channel(path: &Path, role: Role, channel: &mcap::Channel) -> Result<(), BagError> {
    let unsupported = |what, found: &str, expected: String| BagError::Unsupported {
        path: path.to_path_buf(),
        topic: channel.topic.clone(),
        what,
        found: found.to_string(),
        expected,
    };
    if channel.message_encoding != MESSAGE_ENCODING {
        return Err(unsupported(
            "the message encoding",
            &channel.message_encoding,
            format!("`{MESSAGE_ENCODING}` (ROS 2)"),
        ));
    }
    let Some(schema) = &channel.schema else {
        return Err(unsupported(
            "the schema",
            "none",
            format!("`{}`", role.schema()),
        ));
    };
    if schema.name != role.schema() {
        return Err(unsupported(
            "the schema",
            &schema.name,
            format!("`{}`", role.schema()),
        ));
    }
    if !SCHEMA_ENCODINGS.contains(&schema.encoding.as_str()) {
        return Err(unsupported(
            "the schema encoding",
            &schema.encoding,
            "`ros2msg` or `ros2idl`".to_string(),
        ));
    }
    Ok(())
}

/// Stamps must increase strictly along a topic.
fn check_stamp_order(
    path: &Path,
    topic: &str,
    index: usize,
    previous_ns: Option<i64>,
    stamp_ns: i64,
) -> Result<(), BagError> {
    match previous_ns {
        Some(previous) if stamp_ns <= previous => Err(BagError::Message {
            path: path.to_path_buf(),
            topic: topic.to_string(),
            index,
            field: "header.stamp".into(),
            message: format!(
                "{} s is {} message {}'s {} s",
                ns_to_s(stamp_ns),
                if stamp_ns == previous {
                    "the same as"
                } else {
                    "before"
                },
                index - 1,
                ns_to_s(previous)
            ),
        }),
        _ => Ok(()),
    }
}

/// `topic (schema), ...` for every topic, or `none`.
fn listing(topics: &BTreeMap<String, String>) -> String {
    let list: Vec<String> = topics.iter().map(|(t, s)| format!("{t} ({s})")).collect();
    if list.is_empty() {
        "none".to_string()
    } else {
        list.join(", ")
    }
}

/// The topics with messages in the bag `path` and their schemas, as
/// `topic (schema), ...` (sorted by topic), or `none`.
///
/// # Errors
/// An unreadable or malformed file.
pub fn topic_listing(path: &Path) -> Result<String, BagError> {
    let mut topics = BTreeMap::new();
    for message in messages(path)? {
        let message = message.map_err(|e| mcap_error(path, e))?;
        let channel = &message.channel;
        if !topics.contains_key(&channel.topic) {
            let schema = channel.schema.as_ref().map_or("no schema", |s| &s.name);
            topics.insert(channel.topic.clone(), schema.to_string());
        }
    }
    Ok(listing(&topics))
}

impl RosBag {
    /// Opens the bag `path` with the topics of `options` (see the module docs).
    ///
    /// # Errors
    /// An unreadable or malformed file; a topic of `options` without
    /// messages (listing the bag's topics); a channel that is not CDR of
    /// the expected schema; a message that does not decode, a cloud without
    /// `x`, `y`, `z` or a time field, or stamps that do not increase along
    /// a topic (naming topic, index and field); detections matching no
    /// sweep's stamp or in another frame; no extrinsic.
    pub fn open(path: &Path, options: &BagOptions) -> Result<RosBag, BagError> {
        let mut roles = BTreeMap::new();
        roles.insert(options.lidar_topic.as_str(), Role::Lidar);
        roles.insert(options.imu_topic.as_str(), Role::Imu);
        if options.extrinsic.is_none() {
            roles.insert(TOPIC_TF_STATIC, Role::TfStatic);
        }
        if let Some(topic) = &options.detections_topic {
            roles.insert(topic.as_str(), Role::Detections);
        }
        let mut topics: BTreeMap<String, String> = BTreeMap::new();
        let mut counts: BTreeMap<String, usize> = BTreeMap::new();
        let mut checked: Vec<u16> = Vec::new();
        let mut sweeps: Vec<SweepTimes> = Vec::new();
        let mut sweep_spans_s: Vec<f64> = Vec::new();
        let mut num_rings = 0;
        let mut imu: Vec<ImuSample> = Vec::new();
        let mut last_imu_ns = None;
        let mut tree = StaticTree::default();
        let mut arrays: Vec<(usize, Detection3DArray)> = Vec::new();
        let mut lidar_frame = None;
        let mut imu_frame = None;

        for message in messages(path)? {
            let message = message.map_err(|e| mcap_error(path, e))?;
            let channel = &message.channel;
            let topic = channel.topic.as_str();
            if !topics.contains_key(topic) {
                let schema = channel.schema.as_ref().map_or("no schema", |s| &s.name);
                topics.insert(topic.to_string(), schema.to_string());
            }
            let Some(&role) = roles.get(topic) else {
                continue;
            };
            if !checked.contains(&channel.id) {
                check_channel(path, role, channel)?;
                checked.push(channel.id);
            }
            let count = counts.entry(topic.to_string()).or_insert(0);
            let index = *count;
            *count += 1;
            let bad = |field: &str, message: String| BagError::Message {
                path: path.to_path_buf(),
                topic: topic.to_string(),
                index,
                field: field.to_string(),
                message,
            };
            match role {
                Role::Lidar => {
                    let cloud: PointCloud2 =
                        msgs::decode(&message.data).map_err(|m| bad("data", m))?;
                    let sweep = read_sweep(&cloud).map_err(|e| bad(&e.field, e.message))?;
                    check_stamp_order(
                        path,
                        topic,
                        index,
                        sweeps.last().map(|s| s.stamp_ns),
                        sweep.stamp_ns,
                    )?;
                    lidar_frame.get_or_insert_with(|| cloud.header.frame_id.clone());
                    num_rings = num_rings.max(sweep.rings);
                    let span_s = sweep
                        .points
                        .iter()
                        .map(|p| f64::from(p.time_offset_s))
                        .fold(0.0, f64::max);
                    sweep_spans_s.push(span_s);
                    sweeps.push(SweepTimes {
                        stamp_ns: sweep.stamp_ns,
                        t_s: sweep.t_s,
                    });
                }
                Role::Imu => {
                    let message: Imu = msgs::decode(&message.data).map_err(|m| bad("data", m))?;
                    let stamp_ns = message.header.stamp.ns();
                    check_stamp_order(path, topic, index, last_imu_ns, stamp_ns)?;
                    last_imu_ns = Some(stamp_ns);
                    let sample = imu_sample(&message);
                    if let Err(e) = sample.validate() {
                        let field = match e {
                            limot_estimator::input::InputError::ImuNotFinite {
                                field: "gyro_radps",
                                ..
                            } => "angular_velocity",
                            _ => "linear_acceleration",
                        };
                        return Err(bad(field, "not finite".into()));
                    }
                    imu_frame.get_or_insert_with(|| message.header.frame_id.clone());
                    imu.push(sample);
                }
                Role::TfStatic => {
                    let message: TfMessage =
                        msgs::decode(&message.data).map_err(|m| bad("data", m))?;
                    tree.add(&message.transforms);
                }
                Role::Detections => {
                    let array: Detection3DArray =
                        msgs::decode(&message.data).map_err(|m| bad("data", m))?;
                    arrays.push((index, array));
                }
            }
        }

        let listing = || listing(&topics);
        let mut required = vec![("LiDAR", &options.lidar_topic), ("IMU", &options.imu_topic)];
        if let Some(topic) = &options.detections_topic {
            required.push(("detections", topic));
        }
        for (role, topic) in required {
            if !counts.contains_key(topic.as_str()) {
                return Err(BagError::UnknownTopic {
                    path: path.to_path_buf(),
                    role,
                    topic: topic.clone(),
                    topics: listing(),
                });
            }
        }
        let lidar_frame = lidar_frame.unwrap_or_default();
        let imu_frame = imu_frame.unwrap_or_default();

        let extrinsic_error = |path: &Path, message: String| BagError::Extrinsic {
            path: path.to_path_buf(),
            message,
        };
        let t_lidar_imu = match &options.extrinsic {
            Some(file) => read_extrinsic_file(file).map_err(|m| extrinsic_error(file, m))?,
            None => tree.lookup(&lidar_frame, &imu_frame).ok_or_else(|| {
                extrinsic_error(
                    path,
                    format!(
                        "no LiDAR-IMU extrinsic: {TOPIC_TF_STATIC} has no path from `{lidar_frame}` \
                         (the clouds' frame) to `{imu_frame}` (the IMU's; static frames: [{}]); \
                         give --extrinsic FILE",
                        tree.frames().join(", ")
                    ),
                )
            })?,
        };

        // the nominal sweep: the median step between stamps (one sweep: its span)
        let mut steps_ns: Vec<i64> = sweeps
            .windows(2)
            .map(|w| w[1].stamp_ns - w[0].stamp_ns)
            .collect();
        steps_ns.sort_unstable();
        let sweep_duration_s = match steps_ns.get(steps_ns.len() / 2) {
            Some(&step) => ns_to_s(step),
            None => sweep_spans_s
                .first()
                .copied()
                .filter(|s| *s > 0.0)
                .unwrap_or(0.1),
        };

        let mut frame_detections = vec![Vec::new(); sweeps.len()];
        let mut skipped_detections = 0;
        if let Some(topic) = &options.detections_topic {
            for (index, array) in &arrays {
                let bad = |field: &str, message: String| BagError::Message {
                    path: path.to_path_buf(),
                    topic: topic.clone(),
                    index: *index,
                    field: field.to_string(),
                    message,
                };
                let stamp_ns = array.header.stamp.ns();
                let frame = sweeps
                    .binary_search_by_key(&stamp_ns, |s| s.stamp_ns)
                    .map_err(|_| {
                        bad(
                            "header.stamp",
                            format!(
                                "{} s is no {} message's header.stamp",
                                ns_to_s(stamp_ns),
                                options.lidar_topic
                            ),
                        )
                    })?;
                if array.header.frame_id != lidar_frame {
                    return Err(bad(
                        "header.frame_id",
                        format!(
                            "`{}`, but the boxes must be in the clouds' frame `{lidar_frame}`",
                            array.header.frame_id
                        ),
                    ));
                }
                let (found, skipped) =
                    detections(array, sweeps[frame].t_s).map_err(|m| bad("detections", m))?;
                skipped_detections += skipped;
                frame_detections[frame].extend(found);
            }
        }

        Ok(RosBag {
            path: path.to_path_buf(),
            lidar_topic: options.lidar_topic.clone(),
            sweeps,
            imu,
            extrinsics: Extrinsics { t_lidar_imu },
            detections: frame_detections,
            num_rings,
            sweep_duration_s,
            skipped_detections,
        })
    }

    /// The bag file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Number of sweeps (LiDAR messages).
    pub fn frame_count(&self) -> usize {
        self.sweeps.len()
    }

    /// The IMU samples, in time order.
    pub fn imu(&self) -> &[ImuSample] {
        &self.imu
    }

    /// The LiDAR-IMU extrinsic (from the file, or `/tf_static`).
    pub fn extrinsics(&self) -> Extrinsics {
        self.extrinsics
    }

    /// The nominal sweep duration: the median step between cloud stamps, s.
    pub fn sweep_duration_s(&self) -> f64 {
        self.sweep_duration_s
    }

    /// Detections left out for a class limot does not track.
    pub fn skipped_detections(&self) -> usize {
        self.skipped_detections
    }

    /// Calls `deliver(index, frame)` for the sweeps `frames`, in order,
    /// streaming the file; stops early when `deliver` returns `false`.
    ///
    /// # Errors
    /// The file cannot be read again or a cloud no longer decodes (it
    /// changed since [`RosBag::open`]).
    pub fn for_each_frame(
        &self,
        frames: Range<usize>,
        mut deliver: impl FnMut(usize, Frame) -> bool,
    ) -> Result<(), BagError> {
        let mut index = 0;
        for message in messages(&self.path)? {
            if index >= frames.end {
                break;
            }
            let message = message.map_err(|e| mcap_error(&self.path, e))?;
            if message.channel.topic != self.lidar_topic {
                continue;
            }
            if index >= frames.start {
                let frame = self.frame_of(index, &message.data)?;
                if !deliver(index, frame) {
                    return Ok(());
                }
            }
            index += 1;
        }
        Ok(())
    }

    /// Sweep `index` (streaming the file up to it: use
    /// [`RosBag::for_each_frame`] for many).
    ///
    /// # Errors
    /// As [`RosBag::for_each_frame`], and an index beyond the sweeps.
    pub fn frame(&self, index: usize) -> Result<Frame, BagError> {
        let mut found = None;
        self.for_each_frame(index..index + 1, |_, frame| {
            found = Some(frame);
            false
        })?;
        found.ok_or_else(|| BagError::Message {
            path: self.path.clone(),
            topic: self.lidar_topic.clone(),
            index,
            field: "header".into(),
            message: format!("no such message: the topic has {}", self.sweeps.len()),
        })
    }

    fn frame_of(&self, index: usize, data: &[u8]) -> Result<Frame, BagError> {
        let bad = |field: &str, message: String| BagError::Message {
            path: self.path.clone(),
            topic: self.lidar_topic.clone(),
            index,
            field: field.to_string(),
            message,
        };
        let cloud: PointCloud2 = msgs::decode(data).map_err(|m| bad("data", m))?;
        let Sweep { t_s, points, .. } = read_sweep(&cloud).map_err(|e| bad(&e.field, e.message))?;
        if self.sweeps.get(index).map(|s| s.t_s) != Some(t_s) {
            return Err(bad(
                "header.stamp",
                "the bag changed since it was opened".into(),
            ));
        }
        Ok(Frame {
            scan: LidarScan {
                t_s,
                sweep_duration_s: self.sweep_duration_s,
                num_rings: self.num_rings,
                points,
            },
            detections: self.detections.get(index).cloned().unwrap_or_default(),
        })
    }
}
