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
    let dest = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("kitti_training");
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
