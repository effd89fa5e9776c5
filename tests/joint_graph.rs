//! The `limot` variant (objects in the joint graph) against the tracker-only
//! estimate of `dynafilt` and the raw detections, on the congested highway
//! (default and fully joint graph) and the urban streets: object centre
//! error relative to the ego (each frame's LiDAR frame), object speed error
//! (all moving objects and those at a constant speed) and ego ATE, scored
//! against the simulator's ground truth.

mod common;

use common::{ate, simulate};
use limot::io::Source;
use limot::run::{RunOptions, RunOutput, run};
use limot::simulate::resolve_scenario;
use limot_estimator::Variant;
use limot_estimator::pipeline::EstimatorConfig;
use limot_estimator::tracking::Lifecycle;
use limot_sim::record::{BoxTruth, Dataset, EgoTruth};
use nalgebra::{Isometry3, Vector3};
use std::collections::BTreeSet;
use std::path::Path;

/// An estimate's match is the nearest true box closer than this; it is
/// scored when that box moves (faster than 1 m/s). Matching among the moving
/// boxes only would score the track of a parked car a cyclist passes as that
/// cyclist's estimate, 2 m off.
const MATCH_RADIUS_M: f64 = 2.0;
const MOVING_MPS: f64 = 1.0;

/// The true LiDAR pose at `t_s` (interpolated between the 100 Hz samples).
fn ego_at(ego: &[EgoTruth], t_s: f64) -> Isometry3<f64> {
    limot::experiments::ego_pose_at(ego, t_s, Path::new("gt/ego.csv")).unwrap()
}

/// An object's truth in a frame's LiDAR frame.
#[derive(Debug, Clone, Copy)]
struct BoxInLidar {
    center_lidar: Vector3<f64>,
    velocity_lidar_mps: Vector3<f64>,
    /// Driving at a constant speed: |Δv| below 0.3 m/s² over ±1 frame.
    steady: bool,
}

/// Ids of the boxes of `frame` whose velocity changes by less than
/// 0.3 m/s² between the frames before and after it.
fn steady_ids(boxes: &[Vec<BoxTruth>], frame: usize) -> BTreeSet<u32> {
    let (Some(before), Some(after)) = (
        frame.checked_sub(1).and_then(|f| boxes.get(f)),
        boxes.get(frame + 1),
    ) else {
        return BTreeSet::new();
    };
    let velocity = |set: &[BoxTruth], id| {
        set.iter()
            .find(|b| b.id == id)
            .map(|b| (b.velocity_world_mps, b.t_s))
    };
    boxes[frame]
        .iter()
        .filter(|b| match (velocity(before, b.id), velocity(after, b.id)) {
            (Some((v0, t0)), Some((v1, t1))) => (v1 - v0).norm() / (t1 - t0) < 0.3,
            _ => false,
        })
        .map(|b| b.id)
        .collect()
}

/// Truth boxes of `frame` at `t_s`: centre and velocity in the true LiDAR
/// frame at `t_s`.
fn truth_in_lidar(
    boxes: &[Vec<BoxTruth>],
    frame: usize,
    t_world_lidar: &Isometry3<f64>,
    t_s: f64,
) -> Vec<BoxInLidar> {
    let inv = t_world_lidar.inverse();
    let steady = steady_ids(boxes, frame);
    boxes[frame]
        .iter()
        .map(|b| {
            let c = b.t_world_box.translation.vector + b.velocity_world_mps * (t_s - b.t_s);
            BoxInLidar {
                center_lidar: inv.transform_point(&c.into()).coords,
                velocity_lidar_mps: inv.rotation * b.velocity_world_mps,
                steady: steady.contains(&b.id),
            }
        })
        .collect()
}

#[derive(Debug, Default)]
struct ErrorStats {
    position_sq_m2: Vec<f64>,
    speed_err_mps: Vec<f64>,
    /// Velocity errors (horizontal) for objects at a constant speed.
    steady_velocity_err_mps: Vec<f64>,
}

impl ErrorStats {
    fn add(&mut self, truth: &[BoxInLidar], p: Vector3<f64>, v: Option<Vector3<f64>>) {
        let Some(t) = truth
            .iter()
            .map(|t| (t, (t.center_lidar - p).norm()))
            .filter(|(_, d)| *d < MATCH_RADIUS_M)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(t, _)| *t)
            .filter(|t| t.velocity_lidar_mps.norm() > MOVING_MPS)
        else {
            return;
        };
        self.position_sq_m2
            .push((t.center_lidar - p).norm_squared());
        if let Some(v) = v {
            let err = (v.xy() - t.velocity_lidar_mps.xy()).norm();
            self.speed_err_mps.push(err);
            if t.steady {
                self.steady_velocity_err_mps.push(err);
            }
        }
    }

    fn rmse_m(&self) -> f64 {
        (self.position_sq_m2.iter().sum::<f64>() / self.position_sq_m2.len() as f64).sqrt()
    }

    fn median_speed_err_mps(&self) -> f64 {
        median(&self.speed_err_mps)
    }

    fn median_steady_velocity_err_mps(&self) -> f64 {
        median(&self.steady_velocity_err_mps)
    }
}

fn median(values: &[f64]) -> f64 {
    let mut e = values.to_vec();
    e.sort_by(f64::total_cmp);
    e[e.len() / 2]
}

/// Confirmed tracks matched this frame, moved into the frame's LiDAR frame
/// with the run's own ego estimate.
fn track_errors(dataset: &Dataset, output: &RunOutput) -> ErrorStats {
    let boxes = dataset.box_truth().unwrap();
    let ego = dataset.ego_truth().unwrap();
    let mut stats = ErrorStats::default();
    for e in &output.estimates {
        let truth = truth_in_lidar(&boxes, e.frame_index as usize, &ego_at(&ego, e.t_s), e.t_s);
        let inv = e.t_world_lidar.inverse();
        for t in &e.tracks {
            if t.lifecycle != Lifecycle::Confirmed || t.predicted {
                continue;
            }
            let p = inv.transform_point(&t.center_world.into()).coords;
            stats.add(&truth, p, Some(inv.rotation * t.velocity_world_mps));
        }
    }
    stats
}

/// Every true detection in the LiDAR frame of its own time.
fn detection_errors(dataset: &Dataset) -> ErrorStats {
    let boxes = dataset.box_truth().unwrap();
    let ego = dataset.ego_truth().unwrap();
    let mut stats = ErrorStats::default();
    for index in 0..boxes.len() {
        let frame = dataset.frame(index).unwrap();
        for d in &frame.detections {
            let t_s = frame.scan.t_s + d.detection.time_offset_s;
            let truth = truth_in_lidar(&boxes, index, &ego_at(&ego, t_s), t_s);
            stats.add(&truth, d.detection.box_lidar.center, None);
        }
    }
    stats
}

fn run_variant(dir: &Path, variant: Variant, config: Option<EstimatorConfig>) -> RunOutput {
    let source = Source::open(dir).unwrap();
    let options = RunOptions {
        variant,
        ..RunOptions::default()
    };
    run(&source, dir, &options, config).unwrap()
}

/// Objects and ego of `dynafilt` and `limot` (optionally with a config)
/// against the truth and the raw detections.
struct Comparison {
    raw: ErrorStats,
    dynafilt: ErrorStats,
    limot: ErrorStats,
    ate_dynafilt_m: f64,
    ate_limot_m: f64,
    /// When asked for.
    ate_lio_m: Option<f64>,
}

/// A drive to compare on: the built-in `scenario`, optionally another seed.
struct Drive<'a> {
    /// Names the dataset directory (tests run in parallel in one process).
    test: &'a str,
    scenario: &'a str,
    seed: Option<u64>,
    duration_s: f64,
}

fn compare(drive: &Drive, limot_config: Option<EstimatorConfig>, with_lio: bool) -> Comparison {
    let mut spec = resolve_scenario(drive.scenario).unwrap();
    spec.duration_s = drive.duration_s;
    if let Some(seed) = drive.seed {
        spec.seed = seed;
    }
    let dir = simulate(&spec, &format!("joint-graph-{}", drive.test));
    let dataset = Dataset::open(&dir).unwrap();
    let raw = detection_errors(&dataset);
    let dynafilt_run = run_variant(&dir, Variant::Dynafilt, None);
    let limot_run = run_variant(&dir, Variant::Limot, limot_config);
    let c = Comparison {
        raw,
        dynafilt: track_errors(&dataset, &dynafilt_run),
        limot: track_errors(&dataset, &limot_run),
        ate_dynafilt_m: ate(&dir, &dynafilt_run).0,
        ate_limot_m: ate(&dir, &limot_run).0,
        ate_lio_m: with_lio.then(|| ate(&dir, &run_variant(&dir, Variant::Lio, None)).0),
    };
    eprintln!(
        "{} seed {} {} s: object centre RMSE: detections {:.3} m ({}), dynafilt {:.3} m ({}), \
         limot {:.3} m ({}); median speed error: dynafilt {:.3} m/s, limot {:.3} m/s; \
         constant-speed objects: dynafilt {:.3} m/s, limot {:.3} m/s ({}); ego ATE_T dynafilt {:.3} m, \
         limot {:.3} m, lio {:?}",
        drive.scenario,
        spec.seed,
        drive.duration_s,
        c.raw.rmse_m(),
        c.raw.position_sq_m2.len(),
        c.dynafilt.rmse_m(),
        c.dynafilt.position_sq_m2.len(),
        c.limot.rmse_m(),
        c.limot.position_sq_m2.len(),
        c.dynafilt.median_speed_err_mps(),
        c.limot.median_speed_err_mps(),
        c.dynafilt.median_steady_velocity_err_mps(),
        c.limot.median_steady_velocity_err_mps(),
        c.limot.steady_velocity_err_mps.len(),
        c.ate_dynafilt_m,
        c.ate_limot_m,
        c.ate_lio_m,
    );
    let _ = std::fs::remove_dir_all(&dir);
    c
}

/// What every drive must show: more than `min_matches` scored estimates,
/// limot's objects well below the detections and below the tracker in
/// position and speed.
fn assert_limot_objects_beat_the_tracker(c: &Comparison, min_matches: usize) {
    assert!(c.limot.position_sq_m2.len() > min_matches);
    assert!(c.limot.rmse_m() < 0.7 * c.raw.rmse_m());
    assert!(
        c.limot.rmse_m() < c.dynafilt.rmse_m(),
        "position: limot {:.3} m vs dynafilt {:.3} m",
        c.limot.rmse_m(),
        c.dynafilt.rmse_m()
    );
    assert!(c.limot.median_speed_err_mps() < c.dynafilt.median_speed_err_mps());
    assert!(c.limot.median_steady_velocity_err_mps() < c.dynafilt.median_steady_velocity_err_mps());
}

#[test]
fn limot_objects_beat_the_tracker_and_the_detections_on_the_congested_highway() {
    let drive = Drive {
        test: "conditioned",
        scenario: "highway-dense",
        seed: None,
        duration_s: 20.0,
    };
    let c = compare(&drive, None, false);
    // Measured (seed 1, 20 s): detections 0.355 m, dynafilt 0.239 m, limot
    // 0.163 m; median speed error dynafilt 0.77 m/s, limot 0.20 m/s.
    assert_limot_objects_beat_the_tracker(&c, 1000);
    assert!(c.limot.rmse_m() < 0.8 * c.dynafilt.rmse_m());
    assert!(c.limot.median_speed_err_mps() < 0.4);
    // Vehicles at a constant speed: their velocity is what the constant-
    // velocity chain estimates best.
    assert!(c.limot.steady_velocity_err_mps.len() > 300);
    assert!(c.limot.median_steady_velocity_err_mps() < 0.3);
    // Ego: dynamic objects' observations are conditioned on the ego (see
    // ObjectGraphConfig::dynamic_objects_inform_ego), static ones inform it,
    // so limot's ego stays within noise of dynafilt's: the ordering itself
    // flips with 1e-11 m changes of scan matching (making the coupling pay
    // for the ego is issue 17). Measured: 0.115 m vs 0.116 m (lio 1.91 m).
    assert!(
        c.ate_limot_m <= 1.1 * c.ate_dynafilt_m,
        "{} vs {}",
        c.ate_limot_m,
        c.ate_dynafilt_m
    );
}

#[test]
fn limot_objects_beat_the_tracker_on_the_urban_streets() {
    let drive = Drive {
        test: "urban",
        scenario: "urban",
        seed: None,
        duration_s: 20.0,
    };
    let c = compare(&drive, None, false);
    // Measured (seed 2, the scenario's, 20 s): detections 0.250 m, dynafilt
    // 0.172 m, limot 0.153 m; median speed error dynafilt 0.59 m/s, limot
    // 0.29 m/s (constant-speed objects 0.54 vs 0.18 m/s); ego 0.011 m both.
    assert_limot_objects_beat_the_tracker(&c, 500);
    assert!(c.ate_limot_m <= 1.1 * c.ate_dynafilt_m);
}

/// Other seeds of the urban streets (cyclists, more pedestrians) and the
/// parked street, 20 s each.
fn limot_objects_beat_the_tracker_on(test: &str, scenario: &str, seed: u64) {
    let drive = Drive {
        test,
        scenario,
        seed: Some(seed),
        duration_s: 20.0,
    };
    let c = compare(&drive, None, false);
    assert_limot_objects_beat_the_tracker(&c, 300);
}

#[test]
fn limot_objects_beat_the_tracker_on_urban_seed_1() {
    // Measured: detections 0.234 m, dynafilt 0.164 m, limot 0.132 m.
    limot_objects_beat_the_tracker_on("urban-s1", "urban", 1);
}

#[test]
fn limot_objects_beat_the_tracker_on_urban_seed_3() {
    // Measured: detections 0.242 m, dynafilt 0.172 m, limot 0.142 m.
    limot_objects_beat_the_tracker_on("urban-s3", "urban", 3);
}

#[test]
fn limot_objects_beat_the_tracker_on_the_parked_street() {
    // Measured: detections 0.254 m, dynafilt 0.165 m, limot 0.151 m.
    limot_objects_beat_the_tracker_on("parked", "urban-parked", 1);
}

#[test]
fn fully_joint_graph_runs_and_beats_the_detections() {
    // The paper's form: moving objects' observations correct the ego too.
    // Measured (seed 1, 20 s): objects 0.164 m, speed 0.22 m/s, as good as
    // the default; ego ATE_T 0.44 m vs dynafilt 0.12 m and lio 1.91 m: the
    // congested traffic's departures from constant velocity (every car
    // ahead speeds up at once) pull the ego along the road, the more the
    // stiffer the chains. Why the default conditions them.
    let mut config = EstimatorConfig::default();
    config.objects.dynamic_objects_inform_ego = true;
    let drive = Drive {
        test: "fully-joint",
        scenario: "highway-dense",
        seed: None,
        duration_s: 20.0,
    };
    let c = compare(&drive, Some(config), true);
    assert_limot_objects_beat_the_tracker(&c, 1000);
    let lio = c.ate_lio_m.expect("lio was run");
    assert!(c.ate_limot_m < lio, "{} vs lio {lio}", c.ate_limot_m);
}
