//! End-to-end properties of the simulator: determinism of whole datasets and
//! ground-truth labels of LiDAR points on moving objects.

use limot_sim::Simulation;
use limot_sim::record::Dataset;
use limot_sim::scenario::ScenarioSpec;
use proptest::prelude::*;
use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};

fn short_spec(family: &str, seed: u64, duration_s: f64) -> ScenarioSpec {
    let mut spec = ScenarioSpec::builtin(family).expect("builtin scenario");
    spec.seed = seed;
    spec.duration_s = duration_s;
    spec
}

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("limot-sim-test-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    dir
}

/// Every file below `dir`, relative path -> bytes.
fn read_tree(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path.strip_prefix(dir).unwrap().to_path_buf();
                out.insert(rel, fs::read(&path).unwrap());
            }
        }
    }
    out
}

fn check_determinism(family: &str, seed: u64) {
    let spec = short_spec(family, seed, 1.2);
    let tag = format!("{family}-{seed}");
    let (a, b, c) = (
        scratch_dir(&format!("det-a-{tag}")),
        scratch_dir(&format!("det-b-{tag}")),
        scratch_dir(&format!("det-c-{tag}")),
    );
    Simulation::new(&spec)
        .unwrap()
        .write_dataset(&a, |_, _| {})
        .unwrap();
    // a second, independently built simulation, run on a 1-thread pool
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    pool.install(|| Simulation::new(&spec).unwrap().write_dataset(&b, |_, _| {}))
        .unwrap();
    let (tree_a, tree_b) = (read_tree(&a), read_tree(&b));
    assert!(tree_a.len() > 10, "dataset has {} files", tree_a.len());
    assert_eq!(
        tree_a.keys().collect::<Vec<_>>(),
        tree_b.keys().collect::<Vec<_>>()
    );
    for (path, bytes) in &tree_a {
        assert!(
            bytes == &tree_b[path],
            "{} differs between runs",
            path.display()
        );
    }
    let other = short_spec(family, seed + 1, 1.2);
    Simulation::new(&other)
        .unwrap()
        .write_dataset(&c, |_, _| {})
        .unwrap();
    let tree_c = read_tree(&c);
    assert_ne!(
        tree_a[Path::new("scans/000000.bin")],
        tree_c[Path::new("scans/000000.bin")]
    );
    // and the dataset reads back
    let ds = Dataset::open(&a).unwrap();
    assert_eq!(ds.frame_count(), 12);
    assert_eq!(
        ds.frame(3).unwrap().scan.points.len(),
        ds.frame(3).unwrap().labels.len()
    );
    for d in [a, b, c] {
        let _ = fs::remove_dir_all(d);
    }
}

#[test]
fn same_seed_gives_identical_dataset_bytes_and_another_seed_does_not() {
    check_determinism("urban", 7);
}

/// With noise off, a point labelled with an agent id lies on that agent's box
/// at the point's own firing time, and no static-labelled point lies inside
/// any agent box: every moving object's points carry its id.
fn check_labels(spec: &ScenarioSpec, frames: &[usize]) -> Result<usize, TestCaseError> {
    let sim = Simulation::new(spec).unwrap();
    let scene = sim.scene();
    let mut moving_points = 0;
    for &index in frames {
        let frame = sim.frame(index).unwrap();
        let scan = &frame.recorded.scan;
        for (p, &label) in scan.points.iter().zip(&frame.recorded.labels) {
            let t = scan.t_s + f64::from(p.time_offset_s);
            let p_world = scene.ego.trajectory.pose_at(t) * nalgebra::Point3::from(p.position());
            if label == 0 {
                for agent in &scene.agents {
                    let b = agent.box_at(t);
                    prop_assert!(
                        !b.contains(&p_world, -0.02),
                        "frame {index}: static point inside agent {}",
                        agent.id
                    );
                }
            } else {
                let agent = scene.agents.iter().find(|a| a.id == label);
                prop_assert!(agent.is_some(), "label {label} is no agent");
                let agent = agent.unwrap();
                prop_assert!(
                    agent.box_at(t).contains(&p_world, 0.01),
                    "frame {index}: point labelled {label} is off its box"
                );
                if !agent.parked {
                    moving_points += 1;
                }
            }
        }
    }
    Ok(moving_points)
}

fn noise_free(mut spec: ScenarioSpec) -> ScenarioSpec {
    spec.lidar.range_noise_sigma_m = 0.0;
    spec.lidar.dropout_probability = 0.0;
    spec
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3, ..ProptestConfig::default() })]

    #[test]
    fn datasets_are_byte_identical_per_seed(seed in 0u64..1_000_000, urban in any::<bool>()) {
        check_determinism(if urban { "urban" } else { "highway" }, seed);
    }

    #[test]
    fn moving_object_points_carry_their_ids(seed in 0u64..1000, urban in any::<bool>()) {
        let family = if urban { "urban" } else { "highway" };
        let spec = noise_free(short_spec(family, seed, 4.0));
        let moving = check_labels(&spec, &[0, 17, 35])?;
        prop_assert!(moving > 100, "only {moving} points on moving agents");
    }
}

#[test]
fn the_estimator_view_of_a_dataset_holds_no_ground_truth() {
    let spec = short_spec("highway", 3, 1.0);
    let dir = scratch_dir("input-view");
    Simulation::new(&spec)
        .unwrap()
        .write_dataset(&dir, |_, _| {})
        .unwrap();
    let ds = Dataset::open(&dir).unwrap();
    let scene = spec.build().unwrap();
    assert_eq!(ds.extrinsics().t_lidar_imu, scene.ego.t_lidar_imu);
    for index in [0, 9] {
        let recorded = ds.frame(index).unwrap();
        let input = ds.input_frame(index).unwrap();
        assert_eq!(input.scan, recorded.scan);
        let dets: Vec<_> = recorded.detections.iter().map(|d| d.detection).collect();
        assert_eq!(input.detections, dets);
    }
    let _ = fs::remove_dir_all(dir);
}

#[test]
fn a_scan_that_cannot_be_written_is_an_error_naming_it_and_stops_the_run() {
    use limot_sim::{RecordError, SimulationError};
    let spec = short_spec("urban", 4, 1.2);
    let dir = scratch_dir("write-error");
    // a directory where the fourth scan belongs
    let blocked = dir.join("scans/000003.bin");
    fs::create_dir_all(&blocked).unwrap();
    let mut simulated = 0;
    let err = Simulation::new(&spec)
        .unwrap()
        .write_dataset(&dir, |_, _| simulated += 1)
        .unwrap_err();
    let SimulationError::Record(RecordError::Io { path, .. }) = &err else {
        panic!("{err:?}")
    };
    assert_eq!(path, &blocked);
    assert!(err.to_string().contains(&blocked.display().to_string()));
    assert!(dir.join("scans/000002.bin").is_file());
    assert!(!dir.join("scans/000004.bin").exists());
    assert!(
        !dir.join("meta.toml").exists(),
        "the dataset was not finished"
    );
    // the writer stops the simulation within the frames in flight
    assert!(simulated <= 7, "{simulated} frames simulated");
    let _ = fs::remove_dir_all(dir);
}

#[test]
fn the_callers_own_output_runs_on_every_frame_in_order_and_its_error_stops_the_run() {
    use limot_sim::SimulationError;
    use limot_sim::record::WriteMode;
    let spec = short_spec("highway", 2, 1.0);
    let sim = Simulation::new(&spec).unwrap();
    let dir = scratch_dir("also");
    let mut seen = Vec::new();
    sim.write_dataset_with(
        &dir,
        WriteMode::Buffered,
        |frame| {
            seen.push(frame.index);
            Ok::<(), std::io::Error>(())
        },
        |_, _| {},
    )
    .unwrap();
    assert_eq!(seen, (0..10).collect::<Vec<_>>());
    // the same dataset as the default mode writes
    let direct = scratch_dir("also-direct");
    sim.write_dataset(&direct, |_, _| {}).unwrap();
    assert!(read_tree(&dir) == read_tree(&direct));

    let failing = scratch_dir("also-error");
    let err = sim
        .write_dataset_with(
            &failing,
            WriteMode::Direct,
            |frame| {
                if frame.index == 2 {
                    Err(std::io::Error::other("copy failed at frame 2"))
                } else {
                    Ok(())
                }
            },
            |_, _| {},
        )
        .unwrap_err();
    assert!(matches!(err, SimulationError::Output(_)), "{err:?}");
    assert_eq!(err.to_string(), "copy failed at frame 2");
    assert!(failing.join("scans/000002.bin").is_file());
    assert!(!failing.join("scans/000003.bin").exists());
    assert!(!failing.join("meta.toml").exists());
    for d in [dir, direct, failing] {
        let _ = fs::remove_dir_all(d);
    }
}
