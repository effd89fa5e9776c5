//! ROS 2 bags: a simulated dataset written as a bag (`limot simulate --bag`)
//! and run from it reproduces the run on the dataset; bad bags are refused
//! with errors naming the topic, message index and field, and nothing is
//! written.

use limot::io::Source;
use limot::io::mcap::McapFile;
use limot::io::rosbag::msgs::{
    self, Header, IMU, Imu, MESSAGE_ENCODING, POINT_CLOUD2, PointCloud2, SCHEMA_ENCODING,
    TF_MESSAGE, TfMessage, Time, Transform, TransformStamped,
};
use limot::io::rosbag::pointcloud2::{RingSource, cloud_message, read_sweep};
use limot::io::rosbag::{BagError, BagOptions, RosBag, TOPIC_DETECTIONS, TOPIC_IMU, TOPIC_POINTS};
use limot::run::{RunOptions, run};
use limot::simulate::{resolve_scenario, simulate, write_dataset_bag};
use limot_estimator::input::LidarPoint;
use limot_test_support::ScratchDir;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

fn temp_dir(name: &str) -> ScratchDir {
    ScratchDir::new(&format!("rosbag-{name}"))
}

fn simulated(dir: &Path, duration_s: f64) -> PathBuf {
    let mut spec = resolve_scenario("urban").unwrap();
    spec.duration_s = duration_s;
    let dataset = dir.join("dataset");
    simulate(&spec, &dataset, false, false).unwrap();
    dataset
}

fn options(detections: bool) -> BagOptions {
    BagOptions {
        lidar_topic: TOPIC_POINTS.into(),
        imu_topic: TOPIC_IMU.into(),
        detections_topic: detections.then(|| TOPIC_DETECTIONS.into()),
        extrinsic: None,
    }
}

#[test]
fn a_dataset_run_from_its_bag_reproduces_the_dataset_run() {
    let dir = temp_dir("round-trip");
    let dataset = simulated(&dir, 2.5);
    let bag_path = dir.join("drive.mcap");
    write_dataset_bag(&dataset, &bag_path).unwrap();

    let from_dataset = Source::open(&dataset).unwrap();
    let from_bag = Source::open_bag(&bag_path, &options(true)).unwrap();
    assert_eq!(from_bag.frame_count(), from_dataset.frame_count());
    let (imu_d, ext_d) = from_dataset.imu().unwrap();
    let (imu_b, ext_b) = from_bag.imu().unwrap();
    assert_eq!(imu_b.len(), imu_d.len());
    for (b, d) in imu_b.iter().zip(imu_d) {
        assert!((b.t_s - d.t_s).abs() < 1e-12);
        assert_eq!((b.accel_mps2, b.gyro_radps), (d.accel_mps2, d.gyro_radps));
    }
    let ext_error = (ext_b.t_lidar_imu.inverse() * ext_d.t_lidar_imu)
        .translation
        .vector
        .norm();
    assert!(ext_error < 1e-12, "{ext_error}");
    let Source::Bag(bag) = &from_bag else {
        unreachable!()
    };
    let mut frames = 0;
    bag.for_each_frame(0..usize::MAX, |index, b| {
        let d = from_dataset.frame(index).unwrap();
        assert_eq!(
            b.scan.points, d.scan.points,
            "frame {index}: every point, bit for bit"
        );
        assert!((b.scan.t_s - d.scan.t_s).abs() < 1e-12);
        assert_eq!(b.scan.sweep_duration_s, d.scan.sweep_duration_s);
        assert_eq!(b.scan.num_rings, d.scan.num_rings);
        assert_eq!(b.detections.len(), d.detections.len());
        for (x, y) in b.detections.iter().zip(&d.detections) {
            assert_eq!(
                (x.class, x.score, x.box_lidar.center),
                (y.class, y.score, y.box_lidar.center)
            );
            assert!((x.time_offset_s - y.time_offset_s).abs() < 1e-9);
            assert!((x.box_lidar.yaw_rad - y.box_lidar.yaw_rad).abs() < 1e-12);
        }
        frames += 1;
        true
    })
    .unwrap();
    assert_eq!(frames, from_dataset.frame_count());

    let run_options = RunOptions {
        variant: limot_estimator::Variant::Limot,
        ..RunOptions::default()
    };
    let expected = run(&from_dataset, &dataset, &run_options, None).unwrap();
    let got = run(&from_bag, &bag_path, &run_options, None).unwrap();
    assert_eq!(got.estimates.len(), expected.estimates.len());
    let worst_m = got
        .estimates
        .iter()
        .zip(&expected.estimates)
        .map(|(g, e)| {
            (g.t_world_lidar.translation.vector - e.t_world_lidar.translation.vector).norm()
        })
        .fold(0.0, f64::max);
    println!(
        "bag vs dataset run ({} frames, limot): largest position difference {worst_m:e} m",
        got.estimates.len()
    );
    assert!(worst_m < 1e-6, "{worst_m} m");
}

#[test]
fn rings_from_elevation_recover_the_simulated_lasers() {
    let dir = temp_dir("rings");
    let dataset = simulated(&dir, 1.2);
    let source = Source::open(&dataset).unwrap();
    let frame = source.frame(1).unwrap();
    let mut cloud = cloud_message(Time::default(), "lidar", &frame.scan.points);
    cloud.fields.retain(|f| f.name != "ring");
    let sweep = read_sweep(&cloud).unwrap();
    assert_eq!(sweep.ring_source, RingSource::Elevation);
    // the clusters are the lasers, in order (a laser with no return leaves no cluster)
    let mut pairs: Vec<(u16, u16)> = frame
        .scan
        .points
        .iter()
        .zip(&sweep.points)
        .map(|(truth, computed)| (truth.ring, computed.ring))
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    let lasers = pairs.len();
    assert!(
        pairs.windows(2).all(|w| w[0].1 < w[1].1),
        "one cluster per laser, in order: {pairs:?}"
    );
    assert_eq!(usize::from(sweep.rings), lasers);
    assert!(lasers > 60, "{lasers} lasers");
}

/// A small hand-made bag: `clouds` clouds 0.1 s apart, IMU at 100 Hz over
/// them, and `/tf_static` `lidar -> imu`, each message as `edit` leaves it.
struct TinyBag {
    clouds: Vec<PointCloud2<'static>>,
    imu: Vec<Imu>,
    tf: bool,
    lidar_encoding: &'static str,
    lidar_schema: &'static str,
    cloud_bytes: Option<(usize, Vec<u8>)>,
}

impl TinyBag {
    fn new() -> TinyBag {
        let points: Vec<LidarPoint> = (0..50)
            .map(|i| {
                let azimuth = f64::from(i) * 0.12;
                LidarPoint {
                    x: (8.0 * azimuth.cos()) as f32,
                    y: (8.0 * azimuth.sin()) as f32,
                    z: -1.0 + (i % 2) as f32 * 0.5,
                    intensity: 0.3,
                    ring: (i % 2) as u16,
                    time_offset_s: i as f32 * 0.002,
                }
            })
            .collect();
        let at = |ns: i64| Time::from_ns(ns).unwrap();
        let clouds = (0..3)
            .map(|k| cloud_message(at(1_000_000_000 + k * 100_000_000), "lidar", &points))
            .collect();
        let imu = (0..40)
            .map(|i| Imu {
                header: Header {
                    stamp: at(950_000_000 + i * 10_000_000),
                    frame_id: "imu".into(),
                },
                orientation: msgs::Quaternion::default(),
                orientation_covariance: msgs::Fixed([0.0; 9]),
                angular_velocity: msgs::Vector3::default(),
                angular_velocity_covariance: msgs::Fixed([0.0; 9]),
                linear_acceleration: msgs::Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: 9.81,
                },
                linear_acceleration_covariance: msgs::Fixed([0.0; 9]),
            })
            .collect();
        TinyBag {
            clouds,
            imu,
            tf: true,
            lidar_encoding: MESSAGE_ENCODING,
            lidar_schema: POINT_CLOUD2,
            cloud_bytes: None,
        }
    }

    fn write(&self, path: &Path) {
        let mut file = McapFile::create_with_profile(path, "ros2").unwrap();
        let schema = |name: &str| {
            Some(foxglove::Schema::new(
                name,
                SCHEMA_ENCODING,
                msgs::schema_text(name).unwrap_or_default().into_bytes(),
            ))
        };
        if self.tf {
            let tf = TfMessage {
                transforms: vec![TransformStamped {
                    header: Header {
                        stamp: Time::default(),
                        frame_id: "lidar".into(),
                    },
                    child_frame_id: "imu".into(),
                    transform: Transform::default(),
                }],
            };
            let data = msgs::encode(&tf);
            file.write_encoded("/tf_static", schema(TF_MESSAGE), MESSAGE_ENCODING, 0, &data)
                .unwrap();
        }
        for m in &self.imu {
            let data = msgs::encode(m);
            file.write_encoded(TOPIC_IMU, schema(IMU), MESSAGE_ENCODING, 1, &data)
                .unwrap();
        }
        for (k, c) in self.clouds.iter().enumerate() {
            let data = match &self.cloud_bytes {
                Some((index, bytes)) if *index == k => bytes.clone(),
                _ => msgs::encode(c),
            };
            file.write_encoded(
                TOPIC_POINTS,
                schema(self.lidar_schema),
                self.lidar_encoding,
                2,
                &data,
            )
            .unwrap();
        }
        file.finish().unwrap();
    }

    /// Writes the bag into a scratch dir and opens it; the bag re-reads
    /// its file for each frame, so the dir lives as long as the caller
    /// keeps it.
    fn open(&self, name: &str) -> (ScratchDir, Result<RosBag, BagError>) {
        let dir = temp_dir(name);
        let path = dir.join("tiny.mcap");
        self.write(&path);
        let bag = RosBag::open(&path, &options(false));
        (dir, bag)
    }
}

/// The error's text, which must name `topic`, `message N` and `field`.
fn assert_names(e: &BagError, topic: &str, index: usize, field: &str) {
    let text = e.to_string();
    assert!(
        matches!(e, BagError::Message { .. })
            && text.contains(&format!("topic `{topic}` message {index}: field `{field}`")),
        "{text}"
    );
}

#[test]
fn a_tiny_bag_opens() {
    let (_dir, bag) = TinyBag::new().open("tiny-ok");
    let bag = bag.unwrap();
    assert_eq!(bag.frame_count(), 3);
    assert_eq!(bag.imu().len(), 40);
    assert!((bag.sweep_duration_s() - 0.1).abs() < 1e-15);
    let frame = bag.frame(2).unwrap();
    assert_eq!(frame.scan.points.len(), 50);
    assert_eq!(frame.scan.num_rings, 2);
    assert!((frame.scan.t_s - 1.2).abs() < 1e-12);
}

#[test]
fn clouds_without_position_or_time_fields_are_named() {
    let mut tiny = TinyBag::new();
    tiny.clouds[1].fields.retain(|f| f.name != "time");
    let e = tiny.open("no-time").1.unwrap_err();
    assert_names(&e, TOPIC_POINTS, 1, "time");
    assert!(e.to_string().contains("[x, y, z, intensity, ring]"), "{e}");

    let mut tiny = TinyBag::new();
    tiny.clouds[2].fields.retain(|f| f.name != "z");
    assert_names(&tiny.open("no-z").1.unwrap_err(), TOPIC_POINTS, 2, "z");
}

#[test]
fn unsupported_encodings_are_refused() {
    let mut tiny = TinyBag::new();
    tiny.lidar_encoding = "protobuf";
    let e = tiny.open("protobuf").1.unwrap_err();
    assert!(matches!(e, BagError::Unsupported { .. }), "{e}");
    assert!(
        e.to_string()
            .contains("`/points_raw`: the message encoding is `protobuf`"),
        "{e}"
    );

    let mut tiny = TinyBag::new();
    tiny.lidar_schema = "sensor_msgs/msg/LaserScan";
    let e = tiny.open("laserscan").1.unwrap_err();
    assert!(
        e.to_string()
            .contains("`sensor_msgs/msg/LaserScan`, but limot reads `sensor_msgs/msg/PointCloud2`"),
        "{e}"
    );

    // XCDR2 encapsulation
    let mut tiny = TinyBag::new();
    let mut bytes = msgs::encode(&tiny.clouds[0]);
    bytes[1] = 7;
    tiny.cloud_bytes = Some((0, bytes));
    let e = tiny.open("xcdr2").1.unwrap_err();
    assert_names(&e, TOPIC_POINTS, 0, "data");
    assert!(e.to_string().contains("0x0007"), "{e}");

    // a cloud cut short
    let mut tiny = TinyBag::new();
    let mut bytes = msgs::encode(&tiny.clouds[1]);
    bytes.truncate(bytes.len() / 2);
    tiny.cloud_bytes = Some((1, bytes));
    assert_names(
        &tiny.open("short-cloud").1.unwrap_err(),
        TOPIC_POINTS,
        1,
        "data",
    );
}

#[test]
fn duplicate_and_unordered_stamps_are_named() {
    let mut tiny = TinyBag::new();
    tiny.imu[7].header.stamp = tiny.imu[6].header.stamp;
    let e = tiny.open("duplicate").1.unwrap_err();
    assert_names(&e, TOPIC_IMU, 7, "header.stamp");
    assert!(e.to_string().contains("the same as message 6"), "{e}");

    let mut tiny = TinyBag::new();
    tiny.clouds.swap(1, 2);
    let e = tiny.open("unordered").1.unwrap_err();
    assert_names(&e, TOPIC_POINTS, 2, "header.stamp");
    assert!(e.to_string().contains("before message 1"), "{e}");
}

#[test]
fn a_bag_without_extrinsic_asks_for_one() {
    let mut tiny = TinyBag::new();
    tiny.tf = false;
    let e = tiny.open("no-tf").1.unwrap_err();
    assert!(matches!(e, BagError::Extrinsic { .. }), "{e}");
    assert!(e.to_string().contains("--extrinsic"), "{e}");

    let dir = temp_dir("extrinsic-file");
    let path = dir.join("tiny.mcap");
    tiny.write(&path);
    let file = dir.join("extrinsic.toml");
    fs::write(&file, "t_lidar_imu = [0.5, 0, 0, 0, 0, 0, 1]\n").unwrap();
    let bag = RosBag::open(
        &path,
        &BagOptions {
            extrinsic: Some(file),
            ..options(false)
        },
    )
    .unwrap();
    assert_eq!(bag.extrinsics().t_lidar_imu.translation.vector.x, 0.5);
}

#[test]
fn truncated_bags_are_errors_not_panics() {
    let dir = temp_dir("truncated");
    let path = dir.join("tiny.mcap");
    TinyBag::new().write(&path);
    let bytes = fs::read(&path).unwrap();
    let cut = dir.join("cut.mcap");
    for len in (0..bytes.len()).step_by(61) {
        fs::write(&cut, &bytes[..len]).unwrap();
        let e = RosBag::open(&cut, &options(false)).unwrap_err();
        assert!(
            matches!(e, BagError::Mcap { .. } | BagError::UnknownTopic { .. }),
            "{len}: {e}"
        );
    }
}

#[test]
fn the_cli_lists_the_topics_and_writes_nothing_for_a_bad_bag() {
    let dir = temp_dir("cli");
    let path = dir.join("tiny.mcap");
    TinyBag::new().write(&path);
    let out = dir.join("out");
    let limot = |topic: &str| {
        Command::new(env!("CARGO_BIN_EXE_limot"))
            .args([
                "run",
                path.to_str().unwrap(),
                "--lidar-topic",
                topic,
                "--imu-topic",
                TOPIC_IMU,
            ])
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap()
    };
    let failed = limot("/velodyne_points");
    assert!(!failed.status.success());
    let stderr = String::from_utf8_lossy(&failed.stderr);
    assert!(
        stderr.contains("`/velodyne_points`")
            && stderr.contains("/imu (sensor_msgs/msg/Imu), /points_raw (sensor_msgs/msg/PointCloud2), /tf_static (tf2_msgs/msg/TFMessage)"),
        "{stderr}"
    );
    assert!(!out.exists(), "nothing written for a bad bag");

    let mut tiny = TinyBag::new();
    tiny.clouds[2].fields.retain(|f| f.name != "x");
    tiny.write(&path);
    let failed = limot(TOPIC_POINTS);
    assert!(!failed.status.success());
    let stderr = String::from_utf8_lossy(&failed.stderr);
    assert!(
        stderr.contains("topic `/points_raw` message 2: field `x`"),
        "{stderr}"
    );
    assert!(!out.exists(), "nothing written for a bad bag");
}

#[test]
fn a_zstd_bag_of_another_writer_in_ouster_conventions_reads() {
    // scripts/ros2_bag_fixture.py: Foxglove's mcap_ros2 writer, zstd chunks,
    // `t` u32 ns, `ring` u16, base_link -> {os_lidar, imu_link} on /tf_static
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/ros2_ouster_zstd.mcap");
    let bag = RosBag::open(
        &path,
        &BagOptions {
            lidar_topic: "/os_cloud".into(),
            imu_topic: "/imu/data".into(),
            ..BagOptions::default()
        },
    )
    .unwrap();
    let start_s = 1.7e9;
    assert_eq!((bag.frame_count(), bag.imu().len()), (3, 40));
    assert!((bag.sweep_duration_s() - 0.1).abs() < 1e-12);
    let imu = &bag.imu()[7];
    assert!((imu.t_s - (start_s + 0.07)).abs() < 1e-6);
    assert_eq!(imu.gyro_radps, nalgebra::Vector3::new(0.0, 0.0, 0.07));
    assert_eq!(imu.accel_mps2, nalgebra::Vector3::new(0.1, 0.0, 9.81));
    // the IMU sits 1.5 m behind the LiDAR, turned a quarter left
    let t = bag.extrinsics().t_lidar_imu;
    assert!((t.translation.vector - nalgebra::Vector3::new(-1.5, 0.0, 0.0)).norm() < 1e-12);
    assert!((t.rotation.euler_angles().2 - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    let mut seen = 0;
    bag.for_each_frame(0..3, |k, frame| {
        assert!((frame.scan.t_s - (start_s + 0.05 + 0.1 * k as f64)).abs() < 1e-6);
        assert_eq!((frame.scan.points.len(), frame.scan.num_rings), (64, 4));
        for (i, p) in frame.scan.points.iter().enumerate() {
            assert_eq!(p.ring, (i % 4) as u16);
            assert!((f64::from(p.time_offset_s) - i as f64 * 1e-3).abs() < 1e-8); // f32
            assert_eq!(p.intensity, 0.25 * i as f32);
        }
        seen += 1;
        true
    })
    .unwrap();
    assert_eq!(seen, 3);
}
