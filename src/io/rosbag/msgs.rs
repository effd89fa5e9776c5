//! The ROS 2 messages limot reads and writes, as serde types in the field
//! order of their `.msg` definitions, their CDR encoding (with the 4-byte
//! encapsulation header rosbag2 stores) and their `ros2msg` schema texts.
//!
//! CDR is XCDR1 ("plain" CDR, what every ROS 2 middleware writes): little or
//! big endian per the encapsulation header, each primitive aligned to its
//! size from the start of the payload. The byte-level work is the
//! `cdr-encoding` crate's.

use byteorder::{BigEndian, LittleEndian};
use serde::de::{self, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::borrow::Cow;
use std::fmt;

/// `sensor_msgs/msg/PointCloud2`.
pub const POINT_CLOUD2: &str = "sensor_msgs/msg/PointCloud2";
/// `sensor_msgs/msg/Imu`.
pub const IMU: &str = "sensor_msgs/msg/Imu";
/// `tf2_msgs/msg/TFMessage`.
pub const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";
/// `vision_msgs/msg/Detection3DArray` (vision_msgs 3 and later: ROS 2 Galactic on).
pub const DETECTION3D_ARRAY: &str = "vision_msgs/msg/Detection3DArray";

/// The MCAP message encoding of ROS 2 messages.
pub const MESSAGE_ENCODING: &str = "cdr";
/// The MCAP schema encoding rosbag2 writes: the `.msg` text with its dependencies.
pub const SCHEMA_ENCODING: &str = "ros2msg";

/// CDR little endian, the encapsulation rosbag2 writes on x86 and ARM.
const CDR_LE: [u8; 4] = [0, 1, 0, 0];

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds in `0..1e9`.
    pub nanosec: u32,
}

impl Time {
    /// The time `ns` nanoseconds after the epoch, when a `Time` holds it.
    pub fn from_ns(ns: i64) -> Option<Time> {
        let sec = i32::try_from(ns.div_euclid(1_000_000_000)).ok()?;
        Some(Time {
            sec,
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        })
    }

    /// Nanoseconds after the epoch.
    pub fn ns(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

/// Seconds (f64) of a nanosecond count: the nearest double to `ns / 1e9`.
pub fn ns_to_s(ns: i64) -> f64 {
    ns as f64 / 1e9
}

/// The nanosecond count nearest to `t_s`, when finite and in range.
pub fn s_to_ns(t_s: f64) -> Option<i64> {
    let ns = (t_s * 1e9).round();
    (ns.is_finite() && ns.abs() < 9.0e18).then_some(ns as i64)
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Header {
    /// Time of the data.
    pub stamp: Time,
    /// Frame of the data.
    pub frame_id: String,
}

/// `sensor_msgs/msg/PointField`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointField {
    /// Field name (`x`, `intensity`, `time`, ...).
    pub name: String,
    /// Byte offset inside a point.
    pub offset: u32,
    /// `INT8 = 1` .. `FLOAT64 = 8`.
    pub datatype: u8,
    /// Elements in the field.
    pub count: u32,
}

/// `sensor_msgs/msg/PointCloud2`; `data` borrows from the message when decoded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointCloud2<'a> {
    /// Stamp and frame.
    pub header: Header,
    /// Rows (1 for an unordered cloud).
    pub height: u32,
    /// Points per row.
    pub width: u32,
    /// The layout of a point.
    pub fields: Vec<PointField>,
    /// Byte order of `data`.
    pub is_bigendian: bool,
    /// Bytes per point.
    pub point_step: u32,
    /// Bytes per row.
    pub row_step: u32,
    /// The points.
    #[serde(borrow)]
    pub data: Bytes<'a>,
    /// No invalid points.
    pub is_dense: bool,
}

/// `geometry_msgs/msg/Vector3` (and `Point`: the same fields).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `sensor_msgs/msg/Imu`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Imu {
    /// Stamp and IMU frame.
    pub header: Header,
    /// Orientation estimate (unused by limot).
    pub orientation: Quaternion,
    /// Its covariance; element 0 is -1 when there is no estimate.
    pub orientation_covariance: Fixed<9>,
    /// Angular rate, rad/s.
    pub angular_velocity: Vector3,
    /// Its covariance.
    pub angular_velocity_covariance: Fixed<9>,
    /// Specific force (gravity's reaction included), m/s².
    pub linear_acceleration: Vector3,
    /// Its covariance.
    pub linear_acceleration_covariance: Fixed<9>,
}

/// `geometry_msgs/msg/Transform`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Transform {
    /// Translation, m.
    pub translation: Vector3,
    /// Rotation.
    pub rotation: Quaternion,
}

/// `geometry_msgs/msg/TransformStamped`: maps `child_frame_id` points into
/// `header.frame_id`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// Stamp and parent frame.
    pub header: Header,
    /// Child frame.
    pub child_frame_id: String,
    /// The parent-from-child transform.
    pub transform: Transform,
}

/// `tf2_msgs/msg/TFMessage`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

/// `geometry_msgs/msg/Pose`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose {
    /// Position, m.
    pub position: Vector3,
    /// Orientation.
    pub orientation: Quaternion,
}

/// `vision_msgs/msg/ObjectHypothesisWithPose` (`ObjectHypothesis` inlined:
/// CDR has no struct boundaries).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectHypothesisWithPose {
    /// `hypothesis.class_id`.
    pub class_id: String,
    /// `hypothesis.score`.
    pub score: f64,
    /// `pose.pose`.
    pub pose: Pose,
    /// `pose.covariance`.
    pub covariance: Fixed<36>,
}

/// `vision_msgs/msg/BoundingBox3D`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct BoundingBox3D {
    /// Centre and orientation.
    pub center: Pose,
    /// Extent along the box axes, m.
    pub size: Vector3,
}

/// `vision_msgs/msg/Detection3D`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection3D {
    /// When and in which frame the object was seen.
    pub header: Header,
    /// Class hypotheses.
    pub results: Vec<ObjectHypothesisWithPose>,
    /// The box.
    pub bbox: BoundingBox3D,
    /// Tracking id (unused).
    pub id: String,
}

/// `vision_msgs/msg/Detection3DArray`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection3DArray {
    /// Stamp (the sweep's) and frame.
    pub header: Header,
    /// The detections.
    pub detections: Vec<Detection3D>,
}

/// A CDR `uint8[]`: encoded as one block, borrowed when decoded.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Bytes<'a>(pub Cow<'a, [u8]>);

impl Serialize for Bytes<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_bytes(&self.0)
    }
}

impl<'de: 'a, 'a> Deserialize<'de> for Bytes<'a> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct BytesVisitor;
        impl<'de> Visitor<'de> for BytesVisitor {
            type Value = Bytes<'de>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a byte sequence")
            }
            fn visit_borrowed_bytes<E: de::Error>(self, v: &'de [u8]) -> Result<Self::Value, E> {
                Ok(Bytes(Cow::Borrowed(v)))
            }
            fn visit_bytes<E: de::Error>(self, v: &[u8]) -> Result<Self::Value, E> {
                Ok(Bytes(Cow::Owned(v.to_vec())))
            }
        }
        deserializer.deserialize_bytes(BytesVisitor)
    }
}

/// A CDR `float64[N]`: N values, no length (serde's arrays stop at 32).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fixed<const N: usize>(pub [f64; N]);

impl<const N: usize> Default for Fixed<N> {
    fn default() -> Self {
        Fixed([0.0; N])
    }
}

impl<const N: usize> Serialize for Fixed<N> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut tuple = serializer.serialize_tuple(N)?;
        for v in &self.0 {
            tuple.serialize_element(v)?;
        }
        tuple.end()
    }
}

impl<'de, const N: usize> Deserialize<'de> for Fixed<N> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct FixedVisitor<const N: usize>;
        impl<'de, const N: usize> Visitor<'de> for FixedVisitor<N> {
            type Value = Fixed<N>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "{N} float64 values")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
                let mut values = [0.0; N];
                for (i, v) in values.iter_mut().enumerate() {
                    *v = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                Ok(Fixed(values))
            }
        }
        deserializer.deserialize_tuple(N, FixedVisitor::<N>)
    }
}

/// Decodes one CDR message (encapsulation header, then the payload).
///
/// # Errors
/// A message shorter than its header, an encapsulation other than plain
/// CDR (XCDR1, either byte order), or a payload that does not hold a `T`;
/// the text says which.
pub fn decode<'a, T: Deserialize<'a>>(data: &'a [u8]) -> Result<T, String> {
    let Some((header, payload)) = data.split_first_chunk::<4>() else {
        return Err(format!(
            "{} bytes, shorter than the 4-byte CDR encapsulation header",
            data.len()
        ));
    };
    let decoded = match [header[0], header[1]] {
        [0, 1] => cdr_encoding::from_bytes::<T, LittleEndian>(payload),
        [0, 0] => cdr_encoding::from_bytes::<T, BigEndian>(payload),
        other => {
            return Err(format!(
                "encapsulation 0x{:02x}{:02x} is not plain CDR (0x0000 or 0x0001; XCDR2 and parameter lists are not read)",
                other[0], other[1]
            ));
        }
    };
    decoded
        .map(|(message, _)| message)
        .map_err(|e| format!("CDR payload: {e}"))
}

/// Encodes `message` as CDR little endian with its encapsulation header.
///
/// # Panics
/// Never for these types: CDR serialization only fails on maps and
/// unsized sequences, which none of them has.
pub fn encode<T: Serialize>(message: &T) -> Vec<u8> {
    let mut out = CDR_LE.to_vec();
    cdr_encoding::to_writer::<T, LittleEndian, _>(&mut out, message)
        .expect("ROS 2 messages serialize to CDR");
    out
}

const SEPARATOR: &str =
    "================================================================================\n";

/// The `ros2msg` schema text of `schema_name` as rosbag2 writes it (the
/// type's definition, then each dependency after a separator and `MSG:`
/// line), or `None` for a type limot does not write.
pub fn schema_text(schema_name: &str) -> Option<String> {
    let (main, deps): (&str, &[&str]) = match schema_name {
        POINT_CLOUD2 => (
            "std_msgs/Header header\nuint32 height\nuint32 width\nPointField[] fields\nbool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n",
            &[
                "std_msgs/Header",
                "builtin_interfaces/Time",
                "sensor_msgs/PointField",
            ],
        ),
        IMU => (
            "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n",
            &[
                "std_msgs/Header",
                "builtin_interfaces/Time",
                "geometry_msgs/Quaternion",
                "geometry_msgs/Vector3",
            ],
        ),
        TF_MESSAGE => (
            "geometry_msgs/TransformStamped[] transforms\n",
            &[
                "geometry_msgs/TransformStamped",
                "std_msgs/Header",
                "builtin_interfaces/Time",
                "geometry_msgs/Transform",
                "geometry_msgs/Vector3",
                "geometry_msgs/Quaternion",
            ],
        ),
        DETECTION3D_ARRAY => (
            "std_msgs/Header header\nDetection3D[] detections\n",
            &[
                "std_msgs/Header",
                "builtin_interfaces/Time",
                "vision_msgs/Detection3D",
                "vision_msgs/ObjectHypothesisWithPose",
                "vision_msgs/ObjectHypothesis",
                "geometry_msgs/PoseWithCovariance",
                "geometry_msgs/Pose",
                "geometry_msgs/Point",
                "geometry_msgs/Quaternion",
                "vision_msgs/BoundingBox3D",
                "geometry_msgs/Vector3",
            ],
        ),
        _ => return None,
    };
    let mut text = main.to_string();
    for dep in deps {
        text.push_str(SEPARATOR);
        text.push_str(&format!("MSG: {dep}\n"));
        text.push_str(dependency_text(dep));
    }
    Some(text)
}

fn dependency_text(name: &str) -> &'static str {
    match name {
        "std_msgs/Header" => "builtin_interfaces/Time stamp\nstring frame_id\n",
        "builtin_interfaces/Time" => "int32 sec\nuint32 nanosec\n",
        "sensor_msgs/PointField" => {
            "uint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\nuint8 INT32=5\nuint8 UINT32=6\nuint8 FLOAT32=7\nuint8 FLOAT64=8\nstring name\nuint32 offset\nuint8 datatype\nuint32 count\n"
        }
        "geometry_msgs/Quaternion" => "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
        "geometry_msgs/Vector3" | "geometry_msgs/Point" => "float64 x\nfloat64 y\nfloat64 z\n",
        "geometry_msgs/TransformStamped" => {
            "std_msgs/Header header\nstring child_frame_id\nTransform transform\n"
        }
        "geometry_msgs/Transform" => "Vector3 translation\nQuaternion rotation\n",
        "vision_msgs/Detection3D" => {
            "std_msgs/Header header\nObjectHypothesisWithPose[] results\nBoundingBox3D bbox\nstring id\n"
        }
        "vision_msgs/ObjectHypothesisWithPose" => {
            "ObjectHypothesis hypothesis\ngeometry_msgs/PoseWithCovariance pose\n"
        }
        "vision_msgs/ObjectHypothesis" => "string class_id\nfloat64 score\n",
        "geometry_msgs/PoseWithCovariance" => "Pose pose\nfloat64[36] covariance\n",
        "geometry_msgs/Pose" => "Point position\nQuaternion orientation\n",
        "vision_msgs/BoundingBox3D" => "geometry_msgs/Pose center\ngeometry_msgs/Vector3 size\n",
        _ => "",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cloud_round_trips_and_borrows_its_points() {
        let cloud = PointCloud2 {
            header: Header {
                stamp: Time {
                    sec: 3,
                    nanosec: 500,
                },
                frame_id: "lidar".into(),
            },
            height: 1,
            width: 2,
            fields: vec![PointField {
                name: "x".into(),
                offset: 0,
                datatype: 7,
                count: 1,
            }],
            is_bigendian: false,
            point_step: 4,
            row_step: 8,
            data: Bytes(Cow::Owned(vec![1, 2, 3, 4, 5, 6, 7, 8])),
            is_dense: true,
        };
        let bytes = encode(&cloud);
        let decoded: PointCloud2 = decode(&bytes).unwrap();
        assert_eq!(decoded, cloud);
        assert!(matches!(decoded.data.0, Cow::Borrowed(_)));
    }

    #[test]
    fn imu_layout_is_the_ros_one() {
        // header (stamp 8 + string 4+6 "imu0\0"... ) then 8-aligned f64s: the
        // payload is 4 + 4 + 4 + 5 bytes, padded to 24, then 4 + 9 + 3 + 9 + 3 + 9 f64
        let imu = Imu {
            header: Header {
                stamp: Time::default(),
                frame_id: "imu0".into(),
            },
            orientation: Quaternion::default(),
            orientation_covariance: Fixed([0.0; 9]),
            angular_velocity: Vector3::default(),
            angular_velocity_covariance: Fixed([0.0; 9]),
            linear_acceleration: Vector3 {
                x: 0.0,
                y: 0.0,
                z: 9.81,
            },
            linear_acceleration_covariance: Fixed([0.0; 9]),
        };
        let bytes = encode(&imu);
        assert_eq!(bytes.len(), 4 + 24 + 8 * (4 + 9 + 3 + 9 + 3 + 9));
        assert_eq!(decode::<Imu>(&bytes).unwrap(), imu);
    }

    #[test]
    fn bad_headers_and_short_payloads_are_errors() {
        assert!(decode::<TfMessage>(&[0, 1]).unwrap_err().contains("4-byte"));
        let e = decode::<TfMessage>(&[0, 7, 0, 0, 1, 0, 0, 0]).unwrap_err();
        assert!(e.contains("0x0007"), "{e}");
        let e = decode::<TfMessage>(&[0, 1, 0, 0, 1, 0, 0, 0]).unwrap_err();
        assert!(e.contains("CDR payload"), "{e}");
    }

    #[test]
    fn times_split_into_seconds_and_nanoseconds() {
        let t = Time::from_ns(-1).unwrap();
        assert_eq!((t.sec, t.nanosec), (-1, 999_999_999));
        assert_eq!(t.ns(), -1);
        assert_eq!(s_to_ns(0.3), Some(300_000_000));
        assert!(Time::from_ns(i64::MAX).is_none());
        assert!(
            schema_text(POINT_CLOUD2)
                .unwrap()
                .contains("MSG: sensor_msgs/PointField\n")
        );
    }
}
