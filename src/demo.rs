//! `limot demo`: on a fresh clone, one command simulates the default urban
//! scenario, runs the estimator (`lio` and the full `limot`), scores it and
//! writes a small report.
//!
//! The detector model is scored too, as an oracle-associated "tracker"
//! (detections carry their true ids, so its MOTA and MOTP are the ceiling a
//! tracker fed these detections can reach).
use crate::metrics::EvalError;
use crate::metrics::IouKind;
use crate::metrics::{ClearMotConfig, ClearMotResult, MotFrame, TrackedBox, clear_mot};
use crate::report::Series2D;
use crate::report::{Cell, Table};
use crate::report::{Plot, PlotKind, Report, ReportError, Section, write_report};
use limot_estimator::geometry::OrientedBox;
use limot_sim::record::points_per_instance;
use limot_sim::scenario::ScenarioSpec;
use limot_sim::sensors::Detector;
use limot_sim::{SimulatedFrame, Simulation, SimulationError};
use std::path::{Path, PathBuf};

/// Why the demo failed.
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// The scenario could not be simulated.
    #[error(transparent)]
    Simulation(#[from] SimulationError),
    /// A metric could not be computed.
    #[error(transparent)]
    Eval(#[from] EvalError),
    /// The report could not be written.
    #[error(transparent)]
    Report(#[from] ReportError),
    /// The dataset could not be written.
    #[error(transparent)]
    Output(Box<crate::simulate::SimulateError>),
    /// The estimator run failed.
    #[error(transparent)]
    Run(Box<crate::run::RunError>),
    /// The run could not be scored.
    #[error(transparent)]
    Evaluate(Box<crate::experiments::EvaluateError>),
    /// The dataset could not be read back.
    #[error(transparent)]
    Record(#[from] limot_sim::record::RecordError),
    /// The Foxglove recording could not be written.
    #[error(transparent)]
    Mcap(#[from] crate::io::mcap::McapError),
    /// The track evaluation lacks its 3D IoU 0.25 score.
    #[error("the track evaluation has no 3D IoU 0.25 score")]
    NoTrackScore,
}

impl From<crate::run::RunError> for DemoError {
    fn from(e: crate::run::RunError) -> Self {
        DemoError::Run(Box::new(e))
    }
}

impl From<crate::experiments::EvaluateError> for DemoError {
    fn from(e: crate::experiments::EvaluateError) -> Self {
        DemoError::Evaluate(Box::new(e))
    }
}

/// How one estimator variant did on the demo scenario.
#[derive(Debug, Clone)]
pub struct EstimatorSummary {
    /// Variant name.
    pub variant: &'static str,
    /// Confirmed, matched tracks vs the camera-visible truth at 3D IoU 0.25.
    pub tracks: ClearMotResult,
    /// Translational ATE (RMSE) after SE(3) alignment (m).
    pub ate_t_m: f64,
    /// Rotational ATE (RMSE) after SE(3) alignment (rad).
    pub ate_r_rad: f64,
    /// Frames with an estimate.
    pub frames_estimated: usize,
    /// Frames estimated LiDAR-only before the inertial initialisation.
    pub frames_before_init: usize,
    /// Mean estimator time per frame (ms).
    pub mean_frame_ms: f64,
    /// Frames estimated per second of the run's wall time.
    pub fps: f64,
    /// The written trajectory (`poses_tum.txt`).
    pub trajectory: PathBuf,
}

/// Id offset of false-positive detections (they have no ground-truth id).
const FALSE_POSITIVE_ID_BASE: u64 = 1 << 40;

/// The headline figures of a demo run.
#[derive(Debug, Clone)]
pub struct DemoSummary {
    /// The simulated dataset.
    pub dataset_dir: PathBuf,
    /// The report (`README.md`).
    pub report_readme: PathBuf,
    /// Sweeps simulated.
    pub frames: usize,
    /// Mean points per sweep.
    pub mean_points_per_scan: f64,
    /// Moving agents in the scene.
    pub moving_agents: usize,
    /// Parked agents in the scene.
    pub parked_agents: usize,
    /// Length of the ego path (m).
    pub ego_path_length_m: f64,
    /// Detector scored at 3D IoU 0.25 and 0.5.
    pub detector: [(f64, ClearMotResult); 2],
    /// `lio` then `limot`.
    pub estimators: Vec<EstimatorSummary>,
    /// The Foxglove recording of the `limot` run, when one was asked for.
    pub mcap: Option<crate::io::mcap::McapStats>,
}

/// Ground truth and detections of one frame as CLEAR-MOT input. Ground truth
/// is every agent the detector could see (enough LiDAR points, in range),
/// boxed where the sweep saw it (the same instant as the detection).
fn mot_frame(sim: &Simulation, frame: &SimulatedFrame) -> MotFrame {
    let spec = sim.spec();
    let scene = sim.scene();
    let points = points_per_instance(&frame.recorded.labels);
    let gt = scene
        .agents
        .iter()
        .filter(|a| points.get(&a.id).copied().unwrap_or(0) >= spec.detector.min_points)
        .map(|a| {
            (
                a.id,
                Detector::sighted_box(a, &scene.ego, frame.t_s, &spec.lidar),
            )
        })
        .filter(|(_, d)| d.box_lidar.center.xy().norm() <= spec.detector.max_range_m)
        .map(|(id, d)| TrackedBox {
            id: u64::from(id),
            class: d.class,
            bbox: OrientedBox::new(
                d.box_lidar.center,
                d.box_lidar.size_lwh,
                d.box_lidar.yaw_rad,
            ),
        })
        .collect();
    let tracks = frame
        .recorded
        .detections
        .iter()
        .enumerate()
        .map(|(k, d)| TrackedBox {
            id: d.truth_id.map_or(
                FALSE_POSITIVE_ID_BASE + (frame.index as u64) * 1000 + k as u64,
                u64::from,
            ),
            class: d.detection.class,
            bbox: OrientedBox::new(
                d.detection.box_lidar.center,
                d.detection.box_lidar.size_lwh,
                d.detection.box_lidar.yaw_rad,
            ),
        })
        .collect();
    MotFrame {
        gt,
        tracks,
        dont_care: Vec::new(),
    }
}

/// Runs the demo into `out` (dataset in `out/dataset`, report in `out/report`) and, with
/// `mcap`, records the `limot` run for Foxglove there (the CLI's default: `out/limot.mcap`).
///
/// # Errors
/// A scenario that cannot be simulated, a run or score that fails, or a report or
/// recording that cannot be written.
pub fn run_demo(
    spec: &ScenarioSpec,
    out: &Path,
    progress: bool,
    mcap: Option<&crate::io::mcap::McapRequest>,
) -> Result<DemoSummary, DemoError> {
    let sim = Simulation::new(spec)?;
    let total = sim.frame_count();
    let bar = crate::cli::frame_progress_bar(total, progress, "simulate");
    let mut mot_frames = Vec::with_capacity(total);
    let mut points = 0usize;
    // the demo owns its output: a dataset left by an earlier demo is replaced
    crate::simulate::prepare_output_dir(&out.join("dataset"), true)
        .map_err(|e| DemoError::Output(Box::new(e)))?;
    let dataset_dir = sim.write_dataset(&out.join("dataset"), |frame, _| {
        points += frame.recorded.scan.points.len();
        mot_frames.push(mot_frame(&sim, frame));
        bar.inc(1);
    })?;
    bar.finish_and_clear();

    let detector = [0.25, 0.5].map(|threshold| {
        let cfg = ClearMotConfig {
            iou_kind: IouKind::ThreeD,
            ..ClearMotConfig::with_threshold(threshold)
        };
        clear_mot(&mot_frames, &cfg).map(|r| (threshold, r))
    });
    let [a, b] = detector;
    let detector = [a?, b?];

    // The estimator on the dataset just written, scored against its truth.
    let source = crate::io::Source::open(&dataset_dir).map_err(crate::run::RunError::from)?;
    let mut estimators = Vec::new();
    let mut estimated_xy = Vec::new();
    let mut mcap_stats = None;
    for variant in [
        limot_estimator::Variant::Lio,
        limot_estimator::Variant::Limot,
    ] {
        let recording = mcap.filter(|_| variant == limot_estimator::Variant::Limot);
        let (summary, xy, stats) =
            run_variant(&source, &dataset_dir, out, variant, progress, recording)?;
        estimators.push(summary);
        estimated_xy.push(xy);
        mcap_stats = mcap_stats.or(stats);
    }
    let mut estimator_table = Table::new(
        "Ego trajectory vs ground truth (SE(3)-aligned)",
        [
            "variant",
            "ATE_T [m]",
            "ATE_R [rad]",
            "MOTA %",
            "MOTP %",
            "frames",
            "before init",
            "ms / frame",
            "FPS",
        ]
        .map(String::from)
        .to_vec(),
    );
    for e in &estimators {
        estimator_table.push_row(vec![
            Cell::from(e.variant),
            Cell::Num(e.ate_t_m),
            Cell::Num(e.ate_r_rad),
            Cell::Num(e.tracks.mota.unwrap_or(f64::NAN) * 100.0),
            Cell::Num(e.tracks.motp.unwrap_or(f64::NAN) * 100.0),
            Cell::from(e.frames_estimated),
            Cell::from(e.frames_before_init),
            Cell::Num(e.mean_frame_ms),
            Cell::Num(e.fps),
        ])?;
    }
    estimator_table.set_decimals(1, 3);
    estimator_table.set_decimals(2, 4);
    estimator_table.set_decimals(3, 1);
    estimator_table.set_decimals(4, 1);
    estimator_table.set_decimals(7, 1);
    estimator_table.set_decimals(8, 1);

    let scene = sim.scene();
    let dt = 0.1;
    let steps = (scene.duration_s / dt).floor() as usize;
    let ego_xy: Vec<(f64, f64)> = (0..=steps)
        .map(|k| {
            let p = scene
                .ego
                .trajectory
                .pose_at(k as f64 * dt)
                .translation
                .vector;
            (p.x, p.y)
        })
        .collect();
    let ego_path_length_m = ego_xy
        .windows(2)
        .map(|w| ((w[1].0 - w[0].0).powi(2) + (w[1].1 - w[0].1).powi(2)).sqrt())
        .sum();
    let ego_speed: Vec<(f64, f64)> = (0..=steps)
        .map(|k| {
            let t = k as f64 * dt;
            (
                t,
                scene.ego.trajectory.state_at(t).velocity_world_mps.norm(),
            )
        })
        .collect();
    let moving: Vec<_> = scene.agents.iter().filter(|a| !a.parked).collect();
    let parked_agents = scene.agents.len() - moving.len();
    // the moving agents that came within 40 m of the ego, drawn as tracks
    let near_tracks: Vec<Series2D> = moving
        .iter()
        .filter(|a| {
            (0..=steps).any(|k| {
                let t = k as f64 * dt;
                let d = a.trajectory.pose_at(t).translation.vector
                    - scene.ego.trajectory.pose_at(t).translation.vector;
                d.xy().norm() < 40.0
            })
        })
        .take(12)
        .map(|a| {
            // only the stretch where the ego could see it, so the plot stays readable
            let pts = (0..=steps)
                .map(|k| k as f64 * dt)
                .map(|t| {
                    let p = a.trajectory.pose_at(t).translation.vector;
                    let ego = scene.ego.trajectory.pose_at(t).translation.vector;
                    (p, (p - ego).xy().norm())
                })
                .filter(|(_, d)| *d < 40.0)
                .map(|(p, _)| (p.x, p.y))
                .collect();
            Series2D::line(format!("{} {}", a.class, a.id), pts)
        })
        .collect();

    let mut stats = Table::new("Scenario", ["quantity", "value"].map(String::from).to_vec());
    let frames = total;
    let mean_points_per_scan = points as f64 / frames.max(1) as f64;
    for (name, value) in [
        ("frames (10 Hz sweeps)", Cell::from(frames)),
        ("mean points per sweep", Cell::Num(mean_points_per_scan)),
        ("moving agents", Cell::from(moving.len())),
        ("parked agents", Cell::from(parked_agents)),
        ("ego path length [m]", Cell::Num(ego_path_length_m)),
    ] {
        stats.push_row(vec![Cell::from(name), value])?;
    }
    stats.set_decimals(1, 1);
    let mut det_table = Table::new(
        "Detector model vs ground truth (oracle association, 3D IoU)",
        [
            "IoU thr.",
            "MOTA %",
            "MOTP %",
            "recall %",
            "precision %",
            "FP",
            "FN",
        ]
        .map(String::from)
        .to_vec(),
    );
    for (threshold, r) in &detector {
        let recall = r.matches as f64 / r.gt_count.max(1) as f64 * 100.0;
        let precision = r.matches as f64 / (r.matches + r.false_positives).max(1) as f64 * 100.0;
        det_table.push_row(vec![
            Cell::Num(*threshold),
            Cell::from(r.mota.map(|m| m * 100.0)),
            Cell::from(r.motp.map(|m| m * 100.0)),
            Cell::Num(recall),
            Cell::Num(precision),
            Cell::from(r.false_positives),
            Cell::from(r.false_negatives),
        ])?;
    }
    for column in 1..5 {
        det_table.set_decimals(column, 1);
    }
    det_table.set_decimals(0, 2);

    let report = Report {
        title: format!("limot demo: `{}` (seed {})", spec.name, spec.seed),
        sections: vec![
            Section {
                heading: "Scenario and ground truth".into(),
                text: format!(
                    "Dataset: `{}`. Regenerate with `limot simulate {} --seed {} --out DIR`.",
                    dataset_dir.display(),
                    spec.name,
                    spec.seed
                ),
                tables: vec![stats],
                plots: vec![
                    Plot {
                        file_name: "ego_trajectory.svg".into(),
                        title: "Ego trajectory (ground truth), top view".into(),
                        kind: PlotKind::TrajectoriesXy {
                            series: vec![
                                Series2D::truth("ego (truth)", ego_xy.clone()),
                                Series2D::line("ego (lio, aligned)", estimated_xy[0].clone()),
                                Series2D::line("ego (limot, aligned)", estimated_xy[1].clone()),
                            ],
                        },
                    },
                    Plot {
                        file_name: "ego_speed.svg".into(),
                        title: "Ego speed (ground truth): stop-and-go".into(),
                        kind: PlotKind::Speed {
                            series: vec![Series2D::truth("ego speed", ego_speed)],
                        },
                    },
                    Plot {
                        file_name: "objects.svg".into(),
                        title: "Moving objects near the ego (ground truth)".into(),
                        kind: PlotKind::ObjectTracks {
                            truth: vec![Series2D::truth("ego", ego_xy)],
                            est: near_tracks,
                        },
                    },
                ],
            },
            Section {
                heading: "Detector model".into(),
                text: "Detections scored against the boxes of every agent with at least \
                       `min_points` LiDAR returns within the detector range, at the instant \
                       the sweep saw it. Detections keep their true ids, so this is the \
                       ceiling of a tracker fed these detections."
                    .into(),
                tables: vec![det_table],
                plots: vec![],
            },
            Section {
                heading: "Estimator".into(),
                text: format!(
                    "`limot run {0} --variant lio` (LiDAR-inertial odometry, no object \
                     handling) and `--variant limot` (moving objects' features filtered by \
                     their tracked trajectories, objects optimized jointly with the ego). \
                     Tracks: confirmed tracks matched in the frame, scored against the \
                     camera-visible ground truth at 3D IoU 0.25 (all classes). Trajectories: \
                     `{1}`, `{2}`.",
                    dataset_dir.display(),
                    estimators[0].trajectory.display(),
                    estimators[1].trajectory.display()
                ),
                tables: vec![estimator_table],
                plots: vec![],
            },
        ],
    };
    let report_readme = write_report(&out.join("report"), &report)?;
    Ok(DemoSummary {
        dataset_dir,
        report_readme,
        frames,
        mean_points_per_scan,
        moving_agents: moving.len(),
        parked_agents,
        ego_path_length_m,
        detector,
        estimators,
        mcap: mcap_stats,
    })
}

/// What [`run_variant`] returns: the summary, the aligned ego XY path and
/// the recording's statistics.
type VariantRun = (
    EstimatorSummary,
    Vec<(f64, f64)>,
    Option<crate::io::mcap::McapStats>,
);

/// Runs one variant on the demo dataset into `out/<variant>`, scores its ego
/// trajectory and tracks and, with `mcap`, records the run there.
fn run_variant(
    source: &crate::io::Source,
    dataset_dir: &Path,
    out: &Path,
    variant: limot_estimator::Variant,
    progress: bool,
    mcap: Option<&crate::io::mcap::McapRequest>,
) -> Result<VariantRun, DemoError> {
    let run_options = crate::run::RunOptions {
        variant,
        progress,
        ..crate::run::RunOptions::default()
    };
    let (output, mcap_stats) = match mcap {
        Some(request) => {
            let (output, stats) =
                crate::run::run_recorded(source, dataset_dir, &run_options, None, request)?;
            (output, Some(stats))
        }
        None => (
            crate::run::run(source, dataset_dir, &run_options, None)?,
            None,
        ),
    };
    let run_dir = out.join(variant.name());
    crate::run::write_output(&run_dir, &output)?;
    let eval_options = crate::experiments::EgoEvalOptions::default();
    let truth = crate::experiments::load_truth(dataset_dir, &eval_options)?;
    let estimate = crate::experiments::Trajectory {
        path: run_dir.join("poses_tum.txt"),
        kind: format!("{} estimate", variant.name()),
        poses: output
            .estimates
            .iter()
            .map(|e| (e.t_s, e.t_world_lidar))
            .collect(),
        frame_times: None,
    };
    let eval = crate::experiments::evaluate_trajectories(&truth, &estimate, &eval_options)?;
    let xy = output
        .estimates
        .iter()
        .map(|e| {
            let p = eval.ate.alignment.transform_pose(&e.t_world_lidar);
            (p.translation.vector.x, p.translation.vector.y)
        })
        .collect();
    let dataset = limot_sim::record::Dataset::open(dataset_dir)?;
    let (calib, _) = crate::experiments::dataset_calib(&dataset, 0)?;
    let results =
        crate::run::write_dataset_kitti_tracks(&run_dir.join("kitti_results"), &output, &calib)?;
    let tracks_eval = crate::experiments::evaluate_tracks(
        dataset_dir,
        &results,
        &crate::experiments::TrackEvalOptions::default(),
    )?;
    let tracks = tracks_eval
        .score(IouKind::ThreeD, 0.25)
        .cloned()
        .ok_or(DemoError::NoTrackScore)?;
    let mean_frame_ms = output
        .mean_timings()
        .last()
        .map_or(0.0, |(_, d)| d.as_secs_f64() * 1e3);
    let summary = EstimatorSummary {
        variant: variant.name(),
        tracks,
        ate_t_m: eval.ate.ate_t_rmse_m,
        ate_r_rad: eval.ate.ate_r_rmse_rad,
        frames_estimated: output.estimates.len(),
        frames_before_init: output.frames_before_init,
        mean_frame_ms,
        fps: output.estimates.len() as f64 / output.wall_time.as_secs_f64().max(1e-9),
        trajectory: run_dir.join("poses_tum.txt"),
    };
    Ok((summary, xy, mcap_stats))
}
