//! `--mcap`: the Foxglove recording of a short simulated dataset and of a
//! `limot` run on it, read back with the `mcap` crate's reader: channels,
//! schemas, message counts, time range, and the messages' values against
//! what the estimator computed.

use foxglove::Decode;
use foxglove::schemas::{FrameTransforms, PointCloud, PosesInFrame, SceneUpdate};
use limot::io::Source;
use limot::io::mcap::{
    McapRecorder, McapRequest, POINT_STRIDE_BYTES, REMOVED, TOPIC_CLOUD, TOPIC_DETECTIONS,
    TOPIC_PATH, TOPIC_TF, TOPIC_TRACKS, TOPIC_TRUTH_BOXES, TOPIC_TRUTH_PATH,
};
use limot::run::{RunOptions, run_observed, run_recorded};
use limot::simulate::{record_dataset_mcap, resolve_scenario, simulate};
use limot_test_support::ScratchDir;
use nalgebra::Isometry3;
use std::collections::BTreeMap;
use std::fs;

/// What one channel of a file holds: its schema, and the log times of its
/// messages in file order.
#[derive(Debug)]
struct ChannelContents {
    schema: String,
    log_times_ns: Vec<u64>,
}

/// Every channel of an MCAP file by topic, read message by message; checks
/// that every message is a protobuf message of a protobuf schema carried in
/// the file, logged at its publish time.
fn channels(bytes: &[u8]) -> BTreeMap<String, ChannelContents> {
    let mut channels: BTreeMap<String, ChannelContents> = BTreeMap::new();
    for message in mcap::MessageStream::new(bytes).unwrap() {
        let message = message.unwrap();
        let schema = message.channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "protobuf");
        assert!(
            !schema.data.is_empty(),
            "{}: the schema is in the file",
            schema.name
        );
        assert_eq!(message.channel.message_encoding, "protobuf");
        assert_eq!(message.log_time, message.publish_time);
        let entry = channels
            .entry(message.channel.topic.clone())
            .or_insert(ChannelContents {
                schema: schema.name.clone(),
                log_times_ns: Vec::new(),
            });
        assert_eq!(entry.schema, schema.name);
        entry.log_times_ns.push(message.log_time);
    }
    channels
}

/// Checks the file's summary against `expected` (topic, schema, messages
/// each) and the time range `[first_ns, last_ns]`, and that every channel
/// has one message per frame time in `frame_times_ns`, in order.
fn check_summary(
    bytes: &[u8],
    expected: &[(&str, &str)],
    frame_times_ns: &[u64],
) -> BTreeMap<String, ChannelContents> {
    let read = channels(bytes);
    let got: Vec<(&str, &str)> = read
        .iter()
        .map(|(topic, c)| (topic.as_str(), c.schema.as_str()))
        .collect();
    assert_eq!(got, expected, "channels and their schemas");
    for (topic, c) in &read {
        assert_eq!(
            c.log_times_ns, frame_times_ns,
            "{topic}: one message a frame"
        );
    }
    let summary = mcap::Summary::read(bytes).unwrap().unwrap();
    let stats = summary.stats.unwrap();
    let frames = frame_times_ns.len() as u64;
    assert_eq!(stats.message_count, expected.len() as u64 * frames);
    assert_eq!(stats.channel_count as usize, expected.len());
    let schemas: std::collections::BTreeSet<&str> = expected.iter().map(|(_, s)| *s).collect();
    assert_eq!(stats.schema_count as usize, schemas.len());
    assert_eq!(stats.message_start_time, frame_times_ns[0]);
    assert_eq!(stats.message_end_time, *frame_times_ns.last().unwrap());
    // the summary's channel records and per-channel counts agree
    assert_eq!(summary.channels.len(), expected.len());
    for (id, channel) in &summary.channels {
        let schema = channel.schema.as_ref().unwrap();
        assert!(expected.contains(&(channel.topic.as_str(), schema.name.as_str())));
        assert_eq!(
            stats.channel_message_counts[id], frames,
            "{}",
            channel.topic
        );
    }
    read
}

/// The points of a recorded cloud: x, y, z (f32) and the `removed` flag.
fn cloud_points(cloud: &PointCloud) -> Vec<([f32; 3], u8)> {
    assert_eq!(cloud.point_stride as usize, POINT_STRIDE_BYTES);
    let names: Vec<&str> = cloud.fields.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["x", "y", "z", "removed"]);
    cloud
        .data
        .chunks_exact(POINT_STRIDE_BYTES)
        .map(|p| {
            let f = |k: usize| f32::from_le_bytes(p[4 * k..4 * k + 4].try_into().unwrap());
            ([f(0), f(1), f(2)], p[12])
        })
        .collect()
}

/// A Foxglove pose as an isometry.
fn isometry(pose: &foxglove::schemas::Pose) -> Isometry3<f64> {
    let p = pose.position.unwrap();
    let q = pose.orientation.unwrap();
    Isometry3::from_parts(
        nalgebra::Translation3::new(p.x, p.y, p.z),
        nalgebra::UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z)),
    )
}

/// One sweep as the estimator de-skewed it, kept by the test.
struct SeenSweep {
    frame_index: u64,
    t_s: f64,
    t_ref_s: f64,
    points_f32: Vec<[f32; 3]>,
    removed: Vec<u32>,
    t_lidar_lidar_ref: Isometry3<f64>,
}

#[test]
fn dataset_and_run_recordings_hold_every_topic_at_the_data_times() {
    let mut spec = resolve_scenario("urban").unwrap();
    spec.duration_s = 2.0;
    let dir = ScratchDir::new("mcap-recording");
    let dataset_dir = dir.join("dataset");
    simulate(&spec, &dataset_dir, false, false).unwrap();
    let source = Source::open(&dataset_dir).unwrap();
    let frames = 20;
    assert_eq!(source.frame_count(), frames);
    let ns = |t: f64| (t * 1e9).round() as u64;
    let scan_times_ns: Vec<u64> = (0..frames)
        .map(|i| ns(source.frame(i).unwrap().scan.t_s))
        .collect();

    // the dataset alone, placed by its truth: no tracks or estimated path
    let sim_mcap = dir.join("sim.mcap");
    let sim_request = McapRequest {
        path: sim_mcap.clone(),
        max_cloud_points: None,
    };
    let sim_stats = record_dataset_mcap(&dataset_dir, &sim_request).unwrap();
    let sim_bytes = fs::read(&sim_mcap).unwrap();
    assert_eq!(sim_bytes.len() as u64, sim_stats.bytes);
    check_summary(
        &sim_bytes,
        &[
            (TOPIC_DETECTIONS, "foxglove.SceneUpdate"),
            (TOPIC_CLOUD, "foxglove.PointCloud"),
            (TOPIC_TF, "foxglove.FrameTransforms"),
            (TOPIC_TRUTH_BOXES, "foxglove.SceneUpdate"),
            (TOPIC_TRUTH_PATH, "foxglove.PosesInFrame"),
        ],
        &scan_times_ns,
    );
    assert_eq!(sim_stats.messages, 5 * frames as u64);

    // a run of the full system, recorded as it goes, the test keeping a copy
    // of every sweep the estimator de-skewed
    let options = RunOptions {
        variant: limot_estimator::Variant::Limot,
        ..RunOptions::default()
    };
    let run_mcap = dir.join("run.mcap");
    let request = McapRequest {
        path: run_mcap.clone(),
        max_cloud_points: None,
    };
    let mut recorder = McapRecorder::create(&request, &source).unwrap();
    let mut seen = Vec::new();
    let output = run_observed(&source, &dataset_dir, &options, None, |step| {
        recorder.sweep(step.source_index, step.frame, &step.sweep)?;
        recorder.estimates(step.completed)?;
        let sweep = &step.sweep;
        seen.push(SeenSweep {
            frame_index: sweep.frame_index,
            t_s: sweep.t_s,
            t_ref_s: sweep.t_ref_s,
            points_f32: sweep
                .points_lidar
                .iter()
                .map(|p| [p.x as f32, p.y as f32, p.z as f32])
                .collect(),
            removed: sweep.removed_feature_indices.to_vec(),
            t_lidar_lidar_ref: sweep.t_lidar_lidar_at(sweep.t_ref_s),
        });
        Ok(())
    })
    .unwrap();
    let stats = recorder.finish().unwrap();
    assert_eq!(output.estimates.len(), frames);
    assert!(
        output.frames_before_init > 0,
        "some sweeps ran LiDAR-only before the initialisation"
    );
    let bytes = fs::read(&run_mcap).unwrap();
    assert_eq!(bytes.len() as u64, stats.bytes);
    check_summary(
        &bytes,
        &[
            (TOPIC_DETECTIONS, "foxglove.SceneUpdate"),
            (TOPIC_PATH, "foxglove.PosesInFrame"),
            (TOPIC_CLOUD, "foxglove.PointCloud"),
            (TOPIC_TF, "foxglove.FrameTransforms"),
            (TOPIC_TRACKS, "foxglove.SceneUpdate"),
            (TOPIC_TRUTH_BOXES, "foxglove.SceneUpdate"),
            (TOPIC_TRUTH_PATH, "foxglove.PosesInFrame"),
        ],
        &scan_times_ns,
    );
    assert_eq!(stats.messages, 7 * frames as u64);
    let (t0, t1) = (scan_times_ns[0], scan_times_ns[frames - 1]);
    assert_eq!(stats.time_range_ns, Some((t0, t1)));
    assert!(t1 - t0 > 1_800_000_000, "the data's clock, not the wall's");

    // the messages carry the run's values; the cloud is the estimator's own
    let mut removed_flags = 0usize;
    let mut track_boxes = 0;
    let mut clouds_mid_sweep = 0;
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        let frame = scan_times_ns
            .iter()
            .position(|&t| t == message.log_time)
            .unwrap();
        let e = &output.estimates[frame];
        assert_eq!(ns(e.t_s), message.log_time);
        let data = &message.data[..];
        match message.channel.topic.as_str() {
            TOPIC_CLOUD => {
                let cloud = PointCloud::decode(data).unwrap();
                assert_eq!(cloud.frame_id, "lidar");
                let sweep = &seen[frame];
                assert_eq!(sweep.frame_index, frame as u64);
                assert_eq!(sweep.removed, e.removed_feature_indices);
                assert_eq!(ns(sweep.t_s), message.log_time);
                let points = cloud_points(&cloud);
                assert_eq!(points.len(), sweep.points_f32.len(), "every point kept");
                for (i, ((xyz, flag), expected)) in points.iter().zip(&sweep.points_f32).enumerate()
                {
                    assert_eq!(
                        xyz, expected,
                        "frame {frame} point {i}: the de-skewed cloud"
                    );
                    let removed = sweep.removed.binary_search(&(i as u32)).is_ok();
                    assert_eq!(*flag, if removed { REMOVED } else { 0 });
                }
                removed_flags += points.iter().filter(|(_, f)| *f == REMOVED).count();
                let pose = isometry(cloud.pose.as_ref().unwrap());
                assert_eq!(
                    pose, sweep.t_lidar_lidar_ref,
                    "frame {frame}: the cloud's instant"
                );
                if sweep.t_ref_s != sweep.t_s {
                    clouds_mid_sweep += 1;
                } else {
                    assert_eq!(pose, Isometry3::identity());
                }
            }
            TOPIC_TF => {
                let tf = FrameTransforms::decode(data).unwrap();
                let pairs: Vec<(&str, &str)> = tf
                    .transforms
                    .iter()
                    .map(|t| (t.parent_frame_id.as_str(), t.child_frame_id.as_str()))
                    .collect();
                assert_eq!(
                    pairs,
                    [
                        ("world", "lidar"),
                        ("lidar", "imu"),
                        ("world", "world_truth")
                    ]
                );
                let t = tf.transforms[0].translation.unwrap();
                let expected = e.t_world_lidar.translation.vector;
                assert_eq!((t.x, t.y, t.z), (expected.x, expected.y, expected.z));
            }
            TOPIC_TRACKS => {
                let update = SceneUpdate::decode(data).unwrap();
                assert_eq!(update.deletions.len(), 1, "each update replaces the last");
                assert_eq!(update.entities.len(), e.tracks.len());
                for (entity, track) in update.entities.iter().zip(&e.tracks) {
                    assert_eq!(entity.id, format!("track {}", track.id));
                    assert_eq!(entity.cubes.len(), 1);
                    let size = entity.cubes[0].size.unwrap();
                    assert_eq!(size.x, track.size_lwh.x);
                }
                track_boxes += update.entities.len();
            }
            TOPIC_DETECTIONS => {
                let update = SceneUpdate::decode(data).unwrap();
                let detections = source.frame(frame).unwrap().detections.len();
                assert_eq!(update.entities.len(), detections);
            }
            TOPIC_PATH => {
                let path = PosesInFrame::decode(data).unwrap();
                assert_eq!(path.poses.len(), frame + 1, "the path up to the frame");
            }
            _ => {}
        }
    }
    let removed_indices: usize = output
        .estimates
        .iter()
        .map(|e| e.removed_feature_indices.len())
        .sum();
    assert!(removed_indices > 0, "limot's filter removed features");
    assert_eq!(
        removed_flags, removed_indices,
        "every removed feature flagged"
    );
    assert!(track_boxes > 0);
    assert_eq!(
        clouds_mid_sweep, output.frames_before_init,
        "the LiDAR-only sweeps are de-skewed to their middle, the others to their start"
    );

    // deterministic: the same run writes the same bytes
    let again = dir.join("again.mcap");
    let again_request = McapRequest {
        path: again.clone(),
        ..request.clone()
    };
    let (again_output, _) =
        run_recorded(&source, &dataset_dir, &options, None, &again_request).unwrap();
    assert_eq!(again_output.estimates.len(), frames);
    assert!(fs::read(&again).unwrap() == bytes, "byte-identical");

    // from a later frame and thinned: the frames keep their own times and
    // truth, at most the cap per sweep besides the removed points, every
    // removed point kept
    let (first, count, cap) = (5, 12, 4000);
    let thin = dir.join("thin.mcap");
    let thin_request = McapRequest {
        path: thin.clone(),
        max_cloud_points: Some(cap),
    };
    let thin_options = RunOptions {
        first_frame: first,
        max_frames: Some(count),
        ..options.clone()
    };
    let (thin_output, thin_stats) =
        run_recorded(&source, &dataset_dir, &thin_options, None, &thin_request).unwrap();
    assert_eq!(thin_output.estimates.len(), count);
    assert!(
        thin_stats.bytes * 2 < stats.bytes,
        "{} vs {}",
        thin_stats.bytes,
        stats.bytes
    );
    let thin_bytes = fs::read(&thin).unwrap();
    let thin_channels = channels(&thin_bytes);
    assert_eq!(
        thin_channels[TOPIC_CLOUD].log_times_ns,
        scan_times_ns[first..first + count]
    );
    let Source::Dataset(dataset) = &source else {
        unreachable!("a limot dataset")
    };
    let truth_boxes = dataset.box_truth().unwrap();
    let mut thin_removed = 0;
    for message in mcap::MessageStream::new(&thin_bytes).unwrap() {
        let message = message.unwrap();
        let index = scan_times_ns
            .iter()
            .position(|&t| t == message.log_time)
            .unwrap();
        match message.channel.topic.as_str() {
            TOPIC_CLOUD => {
                let points = cloud_points(&PointCloud::decode(&message.data[..]).unwrap());
                let removed = points.iter().filter(|(_, f)| *f == REMOVED).count();
                assert!(points.len() <= cap + removed, "{} points", points.len());
                assert!(points.len() > cap / 2, "{} points", points.len());
                thin_removed += removed;
            }
            TOPIC_TRUTH_BOXES => {
                let update = SceneUpdate::decode(&message.data[..]).unwrap();
                assert_eq!(
                    update.entities.len(),
                    truth_boxes[index].len(),
                    "frame {index}"
                );
            }
            _ => {}
        }
    }
    let thin_removed_indices: usize = thin_output
        .estimates
        .iter()
        .map(|e| e.removed_feature_indices.len())
        .sum();
    assert_eq!(
        thin_removed, thin_removed_indices,
        "every removed point kept"
    );

    // an unwritable file is an error naming it, and leaves nothing behind
    let blocked = dir.join("no-such-dir").join("x.mcap");
    let blocked_request = McapRequest {
        path: blocked.clone(),
        max_cloud_points: None,
    };
    let e = run_recorded(&source, &dataset_dir, &options, None, &blocked_request).unwrap_err();
    assert!(e.to_string().contains("no-such-dir"), "{e}");
    assert!(!blocked.exists());
}
