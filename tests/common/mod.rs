//! Helpers shared by the integration tests.

use std::path::PathBuf;

#[allow(dead_code)] // not every test binary reads real data
/// `../shared/data` when it exists. When it does not, says loudly that the
/// `what` tests did not run (they never skip silently while it is there).
pub fn data_root(what: &str) -> Option<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if root.is_dir() {
        Some(root)
    } else {
        eprintln!(
            "\n!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!\n\
             !!! NOTE: {} is absent: {what} tests NOT RUN\n\
             !!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!\n",
            root.display()
        );
        None
    }
}

#[allow(dead_code)] // not every test binary reads the real scans
/// A KITTI tracking `training` directory with the real scans of 0000,
/// unpacked by `DATA/unpack-kitti.sh` under the test target's temporary
/// directory; a failing unpack fails the test.
pub fn kitti_training(data: &std::path::Path) -> PathBuf {
    let root = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let dest = root.join("kitti_training");
    // One unpack at a time across test processes (`cargo nextest` runs each
    // test in its own); the script leaves a complete directory as it is.
    std::fs::create_dir_all(&root).unwrap();
    let lock = std::fs::File::create(root.join("kitti_training.lock")).unwrap();
    lock.lock().unwrap();
    let script = data.join("unpack-kitti.sh");
    let status = std::process::Command::new("bash")
        .arg(&script)
        .arg(&dest)
        .status()
        .unwrap_or_else(|e| panic!("{}: {e}", script.display()));
    assert!(
        status.success(),
        "{} {} failed",
        script.display(),
        dest.display()
    );
    dest
}

#[allow(dead_code)] // not every test binary keeps a fixture
/// This test process's own directory under the test target's temporary
/// directory, for fixtures built once per process: `cargo test` runs a
/// binary's tests in one process, which shares them; `cargo nextest` runs
/// each test in a process of its own, which must not remove and rebuild a
/// fixture under another one's feet. Each process holds a lock on its
/// directory's lock file while it runs, so the directories of processes
/// that have ended (their lock free) are removed here.
pub fn process_dir() -> PathBuf {
    use std::fs::{self, File};
    static DIR: std::sync::OnceLock<(PathBuf, File)> = std::sync::OnceLock::new();
    let (dir, _lock) = DIR.get_or_init(|| {
        let root = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
        fs::create_dir_all(&root).unwrap();
        for entry in fs::read_dir(&root).unwrap().flatten() {
            let path = entry.path();
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
            let Some(pid) = name
                .strip_prefix("process-")
                .and_then(|n| n.strip_suffix(".lock"))
            else {
                continue;
            };
            if let Ok(lock) = File::open(&path)
                && lock.try_lock().is_ok()
            {
                let _ = fs::remove_dir_all(root.join(format!("process-{pid}")));
                let _ = fs::remove_file(&path);
            }
        }
        let pid = std::process::id();
        // locked before it appears under the name the loop above looks for
        let pending = root.join(format!("process-{pid}.lock.new"));
        let lock = File::create(&pending).unwrap();
        lock.lock().unwrap();
        fs::rename(&pending, root.join(format!("process-{pid}.lock"))).unwrap();
        let dir = root.join(format!("process-{pid}"));
        let _ = fs::remove_dir_all(&dir); // left by an ended process of the same id
        fs::create_dir_all(&dir).unwrap();
        (dir, lock)
    });
    dir.clone()
}

/// Simulates `spec` into a fresh temporary dataset directory named after
/// `name` and the process.
#[allow(dead_code)] // not every test binary simulates
pub fn simulate(spec: &limot_sim::scenario::ScenarioSpec, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("limot-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    limot_sim::Simulation::new(spec)
        .unwrap()
        .write_dataset(&dir, |_, _| {})
        .unwrap()
}

/// ATE_T [m] and ATE_R [rad] (SE(3) alignment) of a run against the
/// dataset's ground truth.
#[allow(dead_code)]
pub fn ate(dataset: &std::path::Path, output: &limot::run::RunOutput) -> (f64, f64) {
    use limot::experiments::{EgoEvalOptions, Trajectory, evaluate_trajectories, load_truth};
    let opts = EgoEvalOptions::default();
    let truth = load_truth(dataset, &opts).unwrap();
    let estimate = Trajectory {
        path: dataset.join("estimate"),
        kind: "estimate".into(),
        poses: output
            .estimates
            .iter()
            .map(|e| (e.t_s, e.t_world_lidar))
            .collect(),
        frame_times: None,
    };
    let eval = evaluate_trajectories(&truth, &estimate, &opts).unwrap();
    (eval.ate.ate_t_rmse_m, eval.ate.ate_r_rmse_rad)
}

/// The figures of a suite without its wall-clock measurements (which differ
/// from run to run).
#[allow(dead_code)] // only the suite tests compare whole suites
pub fn without_timings(
    mut results: limot::experiments::SuiteResults,
) -> limot::experiments::SuiteResults {
    for s in &mut results.sequences {
        let variants = s.variants.iter_mut().map(|v| &mut v.metrics);
        let ablations = s.ablations.iter_mut().map(|a| &mut a.metrics);
        for m in variants.chain(ablations).flatten() {
            m.wall_time_s = 0.0;
            m.fps = 0.0;
            m.timings.clear();
        }
    }
    results
}
