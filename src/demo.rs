//! `limot demo`: on a fresh clone, one command simulates the default urban
//! scenario, runs the estimator (`lio` and the full `limot`), scores it and
//! writes a small report.
//!
//! The detector model is scored too, as an oracle-associated "tracker"
//! (detections carry their true ids, so its MOTA and MOTP are the ceiling a
//! tracker fed these detections can reach), against the same truth as the
//! tracks (`detector`); every error of the tracks is given its cause
//! (`tracks`, `tables`).
mod detector;
mod tables;
mod tracks;

use crate::experiments::{ScoredTruth, TrackEvalOptions};
use crate::metrics::EvalError;
use crate::metrics::IouKind;
use crate::metrics::{ClearMotConfig, ClearMotResult, MotLoss, PAPER_IOU_THRESHOLDS, clear_mot};
use crate::report::{Cell, Table};
use crate::report::{ColourScale, EgoErrorSeries, Series2D, ego_error_series};
use crate::report::{Plot, PlotKind, Report, ReportError, Section, write_report};
use detector::{DetectorFrame, detector_frames};
use limot_sim::scenario::ScenarioSpec;
use limot_sim::{Simulation, SimulationError};
use std::collections::BTreeSet;
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
    /// The estimator skipped detections, so its detection indices no
    /// longer name the dataset's detections.
    #[error("the {variant} run skipped {count} invalid detections")]
    SkippedDetections {
        /// The variant.
        variant: &'static str,
        /// Detections skipped.
        count: u64,
    },
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
    /// Confirmed, matched tracks vs the camera-visible truth at 3D IoU 0.25
    /// and 0.5 (the thresholds of `DemoSummary::detector`).
    pub tracks: [ClearMotResult; 2],
    /// The errors at 3D IoU 0.25 by cause (`loss.tracks` is `tracks[0]`).
    pub loss: MotLoss,
    /// Per-pose ego error, as plot series.
    pub errors: EgoErrorSeries,
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
    /// Detector scored at 3D IoU 0.25 and 0.5 against the tracks' truth.
    pub detector: [(f64, ClearMotResult); 2],
    /// `lio` then `limot`.
    pub estimators: Vec<EstimatorSummary>,
    /// The Foxglove recording of the `limot` run, when one was asked for.
    pub mcap: Option<crate::io::mcap::McapStats>,
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
    let mut seen = Vec::with_capacity(total);
    let mut points = 0usize;
    // the demo owns its output: a dataset left by an earlier demo is replaced
    crate::simulate::prepare_output_dir(&out.join("dataset"), true)
        .map_err(|e| DemoError::Output(Box::new(e)))?;
    let dataset_dir = sim.write_dataset(&out.join("dataset"), |frame, _| {
        points += frame.recorded.scan.points.len();
        seen.push(DetectorFrame::new(sim.scene(), &spec.lidar, frame));
        bar.inc(1);
    })?;
    bar.finish_and_clear();

    // The one truth every row is scored against: the tracks' (camera-visible
    // boxes, what a KITTI-format result can hold and `limot eval` scores).
    let truth = ScoredTruth::read(&dataset_dir, &TrackEvalOptions::default())?;
    let det_frames = detector_frames(&seen, &truth);
    let configs = PAPER_IOU_THRESHOLDS.map(|threshold| ClearMotConfig {
        iou_kind: IouKind::ThreeD,
        ..ClearMotConfig::with_threshold(threshold)
    });
    let [a, b] = configs.map(|cfg| clear_mot(&det_frames, &cfg).map(|r| (cfg.iou_threshold, r)));
    let detector = [a?, b?];
    // truth ids the detector found, per frame, at the loss breakdown's threshold
    let detected: Vec<BTreeSet<u64>> = detector[0]
        .1
        .per_frame
        .iter()
        .map(|m| m.iter().map(|m| m.gt_id).collect())
        .collect();
    let scoring = Scoring {
        truth: &truth,
        seen: &seen,
        detected: &detected,
        configs: &configs,
    };

    // The estimator on the dataset just written, scored against its truth.
    let source = crate::io::Source::open(&dataset_dir).map_err(crate::run::RunError::from)?;
    let mut estimators = Vec::new();
    let mut mcap_stats = None;
    for variant in [
        limot_estimator::Variant::Lio,
        limot_estimator::Variant::Limot,
    ] {
        let recording = mcap.filter(|_| variant == limot_estimator::Variant::Limot);
        let (summary, stats) = run_variant(
            &source,
            &dataset_dir,
            out,
            variant,
            progress,
            recording,
            &scoring,
        )?;
        estimators.push(summary);
        mcap_stats = mcap_stats.or(stats);
    }
    let mut estimator_table = Table::new(
        "Ego trajectory vs ground truth (SE(3)-aligned)",
        [
            "variant",
            "ATE_T [m]",
            "ATE_R [rad]",
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
            Cell::from(e.frames_estimated),
            Cell::from(e.frames_before_init),
            Cell::Num(e.mean_frame_ms),
            Cell::Num(e.fps),
        ])?;
    }
    estimator_table.set_decimals(1, 3);
    estimator_table.set_decimals(2, 4);
    estimator_table.set_decimals(5, 1);
    estimator_table.set_decimals(6, 1);
    let same_truth = tables::same_truth_table(&detector, &estimators)?;
    let loss = tables::loss_table(&estimators)?;
    let loss_text = estimators
        .iter()
        .map(|e| tables::loss_sentence(&detector[0].1, e))
        .collect::<Vec<_>>()
        .join("\n\n");
    let error_plots = error_plots(&estimators);

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
                                Series2D::line("ego (lio, aligned)", xy_of(&estimators[0].errors)),
                                Series2D::line(
                                    "ego (limot, aligned)",
                                    xy_of(&estimators[1].errors),
                                ),
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
                heading: "Estimator".into(),
                text: format!(
                    "`limot run {0} --variant lio` (LiDAR-inertial odometry, no object \
                     handling) and `--variant limot` (moving objects' features filtered by \
                     their tracked trajectories, objects optimized jointly with the ego). \
                     Trajectories: `{1}`, `{2}`. The straight top view hides centimetres: \
                     the error over time and the path coloured by it show them.",
                    dataset_dir.display(),
                    estimators[0].trajectory.display(),
                    estimators[1].trajectory.display()
                ),
                tables: vec![estimator_table],
                plots: error_plots,
            },
            Section {
                heading: "Tracking: the detector's ceiling and the tracks, like with like".into(),
                text: format!(
                    "Every row is scored against the same truth: the camera-visible boxes \
                     (within {range} m, hit by a LiDAR point, with a box in the camera \
                     image), the truth `limot eval tracks` judges the tracks on, since a \
                     KITTI-format result holds only boxes in the image. The detector keeps \
                     the true ids (no association errors), its boxes and the truth's are \
                     taken at the instant the sweep saw each object, and only detections in \
                     the image count, as for the tracks: its MOTA is the ceiling of a \
                     tracker fed these detections. Tracks: the confirmed tracks matched to a \
                     detection in the frame (what `limot run` writes), world frame.\n\n\
                     Every FN, FP and ID switch of the tracks has one cause below \
                     (`limot::metrics::mot_loss`): a truth box the detector missed is the \
                     ceiling's own FN; a found one is lost when no track takes its \
                     detection, while the track that took it is still tentative (confirmed \
                     after {init} consecutive matched frames), or when the confirmed track's \
                     box misses the truth at the IoU.\n\n{loss_text}",
                    range = crate::io::kitti::export::LABEL_RANGE_M,
                    init = limot_estimator::tracking::TrackerConfig::default().init_frames,
                ),
                tables: vec![same_truth, loss],
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

/// What [`run_variant`] returns: the summary and the recording's statistics.
type VariantRun = (EstimatorSummary, Option<crate::io::mcap::McapStats>);

/// What every variant's tracks are scored with.
struct Scoring<'a> {
    /// The truth of every row.
    truth: &'a ScoredTruth,
    /// What the detector saw, per frame.
    seen: &'a [DetectorFrame],
    /// Truth ids the detector found per frame, at `configs[0]`.
    detected: &'a [BTreeSet<u64>],
    /// CLEAR-MOT at 3D IoU 0.25 and 0.5.
    configs: &'a [ClearMotConfig; 2],
}

/// The aligned ego path of an estimate.
fn xy_of(errors: &EgoErrorSeries) -> Vec<(f64, f64)> {
    errors.path.points.iter().map(|&(x, y, _)| (x, y)).collect()
}

/// Translation and rotation error over time of every variant, and each
/// variant's path coloured by its translation error on one shared scale.
fn error_plots(estimators: &[EstimatorSummary]) -> Vec<Plot> {
    let max_error_m = estimators
        .iter()
        .flat_map(|e| e.errors.path.points.iter().map(|p| p.2))
        .fold(0.0, f64::max);
    let scale = ColourScale {
        lo: 0.0,
        hi: max_error_m,
        desc: "error [m]".into(),
    };
    let mut plots = vec![
        Plot {
            file_name: "ego_translation_error.svg".into(),
            title: "Ego translation error after SE(3) alignment".into(),
            kind: PlotKind::ErrorOverTime {
                y_desc: "translation error [m]".into(),
                series: estimators
                    .iter()
                    .map(|e| e.errors.translation_m.clone())
                    .collect(),
            },
        },
        Plot {
            file_name: "ego_rotation_error.svg".into(),
            title: "Ego rotation error after SE(3) alignment".into(),
            kind: PlotKind::ErrorOverTime {
                y_desc: "rotation error [deg]".into(),
                series: estimators
                    .iter()
                    .map(|e| e.errors.rotation_deg.clone())
                    .collect(),
            },
        },
    ];
    for e in estimators {
        plots.push(Plot {
            file_name: format!("ego_error_path_{}.svg", e.variant),
            title: format!(
                "{}: aligned path coloured by translation error (0 to {:.3} m)",
                e.variant, max_error_m
            ),
            kind: PlotKind::ColouredPath {
                background: vec![],
                path: e.errors.path.clone(),
                scale: scale.clone(),
            },
        });
    }
    plots
}

/// Runs one variant on the demo dataset into `out/<variant>`, scores its ego
/// trajectory and tracks and, with `mcap`, records the run there.
fn run_variant(
    source: &crate::io::Source,
    dataset_dir: &Path,
    out: &Path,
    variant: limot_estimator::Variant,
    progress: bool,
    mcap: Option<&crate::io::mcap::McapRequest>,
    scoring: &Scoring<'_>,
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
    let errors = ego_error_series(variant.name(), &estimate.poses, &eval.ate);
    if output.invalid_detections > 0 {
        return Err(DemoError::SkippedDetections {
            variant: variant.name(),
            count: output.invalid_detections,
        });
    }
    let results = crate::run::write_dataset_kitti_tracks(
        &run_dir.join("kitti_results"),
        &output,
        &scoring.truth.calib,
    )?;
    let live = tracks::live_tracks(&output, scoring.seen, scoring.truth);
    let loss = tracks::track_loss(
        &results,
        scoring.truth,
        &live,
        scoring.detected,
        &scoring.configs[0],
    )?;
    let frames = scoring.truth.tracking_input(&results)?.frames;
    let strict = clear_mot(&frames, &scoring.configs[1])?;
    let mean_frame_ms = output
        .mean_timings()
        .last()
        .map_or(0.0, |(_, d)| d.as_secs_f64() * 1e3);
    let summary = EstimatorSummary {
        variant: variant.name(),
        tracks: [loss.tracks.clone(), strict],
        loss,
        errors,
        ate_t_m: eval.ate.ate_t_rmse_m,
        ate_r_rad: eval.ate.ate_r_rmse_rad,
        frames_estimated: output.estimates.len(),
        frames_before_init: output.frames_before_init,
        mean_frame_ms,
        fps: output.estimates.len() as f64 / output.wall_time.as_secs_f64().max(1e-9),
        trajectory: run_dir.join("poses_tum.txt"),
    };
    Ok((summary, mcap_stats))
}
