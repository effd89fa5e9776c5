"""Writes tests/data/ros2_ouster_zstd.mcap: a tiny ROS 2 bag as another
writer makes it (Foxglove's mcap_ros2 Python writer: its own CDR encoder,
zstd chunks), in Ouster's conventions: `t` u32 ns after header.stamp,
`ring` u16, frames base_link -> os_lidar and base_link -> imu_link on
/tf_static. tests/rosbag.rs reads it.

    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install -r scripts/ros2-fixture-requirements.txt
    /tmp/venv/bin/python scripts/ros2_bag_fixture.py tests/data/ros2_ouster_zstd.mcap
"""
import math
import struct
import sys

from mcap_ros2.writer import Writer

SEP = "=" * 80 + "\n"
HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
VECTOR3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
QUATERNION = "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
POINT_FIELD = (
    "MSG: sensor_msgs/PointField\nuint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\n"
    "uint8 INT32=5\nuint8 UINT32=6\nuint8 FLOAT32=7\nuint8 FLOAT64=8\n"
    "string name\nuint32 offset\nuint8 datatype\nuint32 count\n"
)
CLOUD = SEP.join([
    "std_msgs/Header header\nuint32 height\nuint32 width\nPointField[] fields\nbool is_bigendian\n"
    "uint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n",
    HEADER, TIME, POINT_FIELD,
])
IMU = SEP.join([
    "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
    "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
    "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n",
    HEADER, TIME, QUATERNION, VECTOR3,
])
TF = SEP.join([
    "geometry_msgs/TransformStamped[] transforms\n",
    "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\nTransform transform\n",
    HEADER, TIME,
    "MSG: geometry_msgs/Transform\nVector3 translation\nQuaternion rotation\n",
    VECTOR3, QUATERNION,
])

START_NS = 1_700_000_000_000_000_000  # an absolute stamp, as a real bag has


def stamp(ns):
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def cloud(ns):
    # Ouster-like layout: x y z (f32) pad, intensity f32, t u32, reflectivity u16, ring u16
    data = bytearray()
    for i in range(64):
        a = i * 2 * math.pi / 64
        elevation = math.radians(-3 + 2 * (i % 4))
        r = 10.0 + i % 3
        x = r * math.cos(elevation) * math.cos(a)
        y = r * math.cos(elevation) * math.sin(a)
        z = r * math.sin(elevation)
        data += struct.pack("<fff4xfIHH", x, y, z, 0.25 * i, i * 1_000_000, 100, i % 4)
    fields = [
        ("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 16, 7),
        ("t", 20, 6), ("reflectivity", 24, 4), ("ring", 26, 4),
    ]
    return {
        "header": {"stamp": stamp(ns), "frame_id": "os_lidar"},
        "height": 1, "width": 64,
        "fields": [{"name": n, "offset": o, "datatype": d, "count": 1} for n, o, d in fields],
        "is_bigendian": False, "point_step": 28, "row_step": 28 * 64,
        "data": bytes(data), "is_dense": True,
    }


def transform(child, x, yaw):
    return {
        "header": {"stamp": stamp(START_NS), "frame_id": "base_link"},
        "child_frame_id": child,
        "transform": {
            "translation": {"x": x, "y": 0.0, "z": 0.0},
            "rotation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
        },
    }


def main(path):
    with open(path, "wb") as f:
        writer = Writer(f)  # zstd chunks by default
        cloud_schema = writer.register_msgdef("sensor_msgs/msg/PointCloud2", CLOUD)
        imu_schema = writer.register_msgdef("sensor_msgs/msg/Imu", IMU)
        tf_schema = writer.register_msgdef("tf2_msgs/msg/TFMessage", TF)
        writer.write_message(
            "/tf_static", tf_schema,
            {"transforms": [transform("os_lidar", 1.0, 0.0), transform("imu_link", -0.5, math.pi / 2)]},
            log_time=START_NS,
        )
        zeros = [0.0] * 9
        for i in range(40):
            ns = START_NS + i * 10_000_000
            writer.write_message("/imu/data", imu_schema, {
                "header": {"stamp": stamp(ns), "frame_id": "imu_link"},
                "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                "orientation_covariance": [-1.0] + zeros[1:],
                "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.01 * i},
                "angular_velocity_covariance": zeros,
                "linear_acceleration": {"x": 0.1, "y": 0.0, "z": 9.81},
                "linear_acceleration_covariance": zeros,
            }, log_time=ns)
        for k in range(3):
            ns = START_NS + 50_000_000 + k * 100_000_000
            writer.write_message("/os_cloud", cloud_schema, cloud(ns), log_time=ns)
        writer.finish()


if __name__ == "__main__":
    main(sys.argv[1])
