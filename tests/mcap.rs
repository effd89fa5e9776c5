//! `--mcap`: the Foxglove recording of a short simulated dataset and of a
//! `limot` run on it, read back with the `mcap` crate's reader.

use foxglove::Decode;
use foxglove::schemas::{FrameTransforms, PointCloud, PosesInFrame, SceneUpdate};
use limot::io::Source;
use limot::io::mcap::{
    McapInput, McapRequest, POINT_STRIDE_BYTES, REMOVED, TOPIC_CLOUD, TOPIC_DETECTIONS, TOPIC_PATH,
    TOPIC_TF, TOPIC_TRACKS, TOPIC_TRUTH_BOXES, TOPIC_TRUTH_PATH, write_mcap,
};
use limot::run::{RunOptions, run};
use limot::simulate::{record_dataset_mcap, resolve_scenario, simulate};
use std::collections::BTreeMap;
use std::fs;

/// Messages per topic and the schema of each topic's channel.
fn topics(bytes: &[u8]) -> BTreeMap<String, (String, usize)> {
    let mut topics: BTreeMap<String, (String, usize)> = BTreeMap::new();
    for message in mcap::MessageStream::new(bytes).unwrap() {
        let message = message.unwrap();
        let schema = message.channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "protobuf");
        assert_eq!(message.channel.message_encoding, "protobuf");
        assert_eq!(message.log_time, message.publish_time);
        let entry = topics
            .entry(message.channel.topic.clone())
            .or_insert((schema.name.clone(), 0));
        assert_eq!(entry.0, schema.name);
        entry.1 += 1;
    }
    topics
}

#[test]
fn dataset_and_run_recordings_hold_every_topic_at_the_data_times() {
    let mut spec = resolve_scenario("urban").unwrap();
    spec.duration_s = 2.0;
    let dir = std::env::temp_dir().join(format!("limot-mcap-{}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    let dataset_dir = dir.join("dataset");
    simulate(&spec, &dataset_dir, false, false).unwrap();
    let frames = 20;

    // the dataset alone: no tracks or estimated path
    let sim_mcap = dir.join("sim.mcap");
    let sim_request = McapRequest {
        path: sim_mcap.clone(),
        max_cloud_points: None,
    };
    let sim_stats = record_dataset_mcap(&dataset_dir, &sim_request).unwrap();
    let sim_bytes = fs::read(&sim_mcap).unwrap();
    let sim_topics = topics(&sim_bytes);
    let names: Vec<&str> = sim_topics.keys().map(String::as_str).collect();
    assert_eq!(
        names,
        [
            TOPIC_DETECTIONS,
            TOPIC_CLOUD,
            TOPIC_TF,
            TOPIC_TRUTH_BOXES,
            TOPIC_TRUTH_PATH
        ]
    );
    assert!(sim_topics.values().all(|(_, n)| *n == frames));
    assert_eq!(sim_stats.messages, 5 * frames as u64);

    // a run of the full system on it
    let source = Source::open(&dataset_dir).unwrap();
    let options = RunOptions {
        variant: limot_estimator::Variant::Limot,
        ..RunOptions::default()
    };
    let output = run(&source, &dataset_dir, &options, None).unwrap();
    let run_mcap = dir.join("run.mcap");
    let input = McapInput {
        source: &source,
        frames: source.frame_range(0, None),
        estimates: &output.estimates,
        max_cloud_points: None,
    };
    let stats = write_mcap(&run_mcap, &input).unwrap();
    let bytes = fs::read(&run_mcap).unwrap();
    assert_eq!(bytes.len() as u64, stats.bytes);
    let run_topics = topics(&bytes);
    let expected = [
        (TOPIC_DETECTIONS, "foxglove.SceneUpdate"),
        (TOPIC_PATH, "foxglove.PosesInFrame"),
        (TOPIC_CLOUD, "foxglove.PointCloud"),
        (TOPIC_TF, "foxglove.FrameTransforms"),
        (TOPIC_TRACKS, "foxglove.SceneUpdate"),
        (TOPIC_TRUTH_BOXES, "foxglove.SceneUpdate"),
        (TOPIC_TRUTH_PATH, "foxglove.PosesInFrame"),
    ];
    let got: Vec<(&str, &str)> = run_topics
        .iter()
        .map(|(t, (s, _))| (t.as_str(), s.as_str()))
        .collect();
    assert_eq!(got, expected);
    assert!(run_topics.values().all(|(_, n)| *n == frames));

    // the summary agrees: counts per channel and the data's time range
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let stats_record = summary.stats.unwrap();
    assert_eq!(stats_record.message_count, 7 * frames as u64);
    assert_eq!(stats_record.channel_count, 7);
    assert_eq!(stats_record.schema_count, 4);
    let t0 = output.estimates.first().unwrap().t_s;
    let t1 = output.estimates.last().unwrap().t_s;
    let ns = |t: f64| (t * 1e9).round() as u64;
    assert_eq!(stats_record.message_start_time, ns(t0));
    assert_eq!(stats_record.message_end_time, ns(t1));
    assert_eq!(stats.time_range_ns, Some((ns(t0), ns(t1))));
    assert!(
        t1 - t0 > 1.8,
        "the data's clock, not the wall's: {t0}..{t1}"
    );

    // the messages carry the run's values
    let mut clouds = 0;
    let mut removed_flags = 0usize;
    let mut removed_indices = 0usize;
    let mut track_boxes = 0;
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        let frame = output
            .estimates
            .iter()
            .position(|e| ns(e.t_s) == message.log_time)
            .expect("every message at an estimate's time");
        let e = &output.estimates[frame];
        let data = &message.data[..];
        match message.channel.topic.as_str() {
            TOPIC_CLOUD => {
                let cloud = PointCloud::decode(data).unwrap();
                let scan = source.frame(e.frame_index as usize).unwrap().scan;
                assert_eq!(cloud.frame_id, "lidar");
                assert_eq!(cloud.data.len(), scan.points.len() * POINT_STRIDE_BYTES);
                removed_flags += cloud
                    .data
                    .chunks_exact(POINT_STRIDE_BYTES)
                    .filter(|p| p[12] == REMOVED)
                    .count();
                removed_indices += e.removed_feature_indices.len();
                clouds += 1;
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
            TOPIC_PATH => {
                let path = PosesInFrame::decode(data).unwrap();
                assert_eq!(path.poses.len(), frame + 1, "the path up to the frame");
            }
            _ => {}
        }
    }
    assert_eq!(clouds, frames);
    assert!(removed_indices > 0, "limot's filter removed features");
    assert_eq!(
        removed_flags, removed_indices,
        "every removed feature flagged"
    );
    assert!(track_boxes > 0);

    // thinned: at most the cap per sweep besides the removed points, every
    // removed point kept
    let cap = 4000;
    let thin = dir.join("thin.mcap");
    let thin_input = McapInput {
        frames: input.frames.clone(),
        max_cloud_points: Some(cap),
        ..input
    };
    let thin_stats = write_mcap(&thin, &thin_input).unwrap();
    assert!(
        thin_stats.bytes * 3 < stats.bytes,
        "{} vs {}",
        thin_stats.bytes,
        stats.bytes
    );
    let mut thin_removed = 0;
    for message in mcap::MessageStream::new(&fs::read(&thin).unwrap()).unwrap() {
        let message = message.unwrap();
        if message.channel.topic == TOPIC_CLOUD {
            let cloud = PointCloud::decode(&message.data[..]).unwrap();
            let points: Vec<&[u8]> = cloud.data.chunks_exact(POINT_STRIDE_BYTES).collect();
            let removed = points.iter().filter(|p| p[12] == REMOVED).count();
            assert!(points.len() <= cap + removed, "{} points", points.len());
            assert!(points.len() > cap / 2, "{} points", points.len());
            thin_removed += removed;
        }
    }
    assert_eq!(thin_removed, removed_indices, "every removed point kept");

    // deterministic: the same run writes the same bytes
    let again = dir.join("again.mcap");
    write_mcap(&again, &input).unwrap();
    assert!(fs::read(&again).unwrap() == bytes, "byte-identical");

    // an unwritable file is an error naming it, and leaves nothing behind
    let blocked = dir.join("no-such-dir").join("x.mcap");
    let e = write_mcap(&blocked, &input).unwrap_err();
    assert!(e.to_string().contains("no-such-dir"), "{e}");
    assert!(!blocked.exists());
    let _ = fs::remove_dir_all(&dir);
}
