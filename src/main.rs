//! `limot`: command-line interface.

use clap::{Parser, Subcommand};
use limot::demo::run_demo as demo;
use limot::experiments::EvaluateError;
use limot::experiments::{EgoEvalOptions, evaluate_ego, parse_rpe_delta};
use limot::experiments::{TrackEvalOptions, evaluate_tracks};
use limot::simulate::{Overrides, prepare_output_dir, resolve_scenario, simulate};
use std::path::PathBuf;
use std::process::ExitCode;

/// mimalloc keeps freed pages for reuse: with the system allocator every
/// sweep's scan-sized buffers went back to the kernel and were faulted in
/// again (~2k page faults per frame of `limot run`).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser)]
#[command(
    name = "limot",
    version,
    about = "LiDAR-inertial odometry and multi-object tracking, with a simulation testbed"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a scenario into a dataset (limot format plus a KITTI-style copy in OUT/kitti).
    Simulate {
        /// Scenario TOML file, or a built-in scenario name (highway, urban, highway-dense, urban-parked).
        scenario: String,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Override the scenario's seed.
        #[arg(long)]
        seed: Option<u64>,
        /// Override the scenario's duration, s.
        #[arg(long)]
        duration: Option<f64>,
        /// Skip the KITTI-style copy.
        #[arg(long)]
        no_kitti: bool,
        /// Print the resolved scenario as TOML and exit.
        #[arg(long)]
        print: bool,
        /// Replace an existing dataset in OUT.
        #[arg(long)]
        force: bool,
    },
    /// Simulate the default urban scenario, score it and write a small report (OUT/report).
    Demo {
        /// Output directory.
        #[arg(long, default_value = "out/demo")]
        out: PathBuf,
        /// Scenario TOML file or built-in name.
        #[arg(long, default_value = "urban")]
        scenario: String,
        /// Override the scenario's duration, s.
        #[arg(long)]
        duration: Option<f64>,
    },
    /// Run the estimator on a dataset and write its trajectory (OUT/poses_tum.txt, ...).
    Run {
        /// A limot dataset, a KITTI raw drive dir (velodyne_points/, oxts/) or a dir of KITTI .bin scans.
        dataset: PathBuf,
        /// Output directory (default: DATASET/<variant>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// System variant: lio, allfilt, dynafilt or limot.
        #[arg(long, default_value = "lio")]
        variant: String,
        /// Ignore the IMU (scan-to-map matching with a constant-velocity model).
        #[arg(long)]
        lidar_only: bool,
        /// Start at frame N (e.g. to try a moving start).
        #[arg(long, default_value_t = 0)]
        first_frame: usize,
        /// Process at most N frames.
        #[arg(long)]
        max_frames: Option<usize>,
        /// DATASET is a KITTI tracking directory (training/ or a limot
        /// dataset's kitti/ copy: velodyne/SSSS/, oxts/SSSS.txt, calib/SSSS.txt):
        /// run sequence N with its 10 Hz OXTS IMU.
        #[arg(long)]
        sequence: Option<u32>,
        /// With --sequence: AB3DMOT-format detections (a file, or a directory
        /// of SSSS.txt; default DATASET/detections/SSSS.txt when it exists).
        #[arg(long)]
        detections: Option<PathBuf>,
        /// With --detections: `sigmoid` for logit scores (PointRCNN in AB3DMOT
        /// files) or `clamp01` for probabilities (limot's KITTI copies).
        #[arg(long, default_value = "clamp01")]
        score_map: String,
        /// Tracker settings of the object variants and the rules of their
        /// KITTI result files: `paper`, `tuned` (chosen on the KITTI val split
        /// with PointRCNN boxes, docs/tracking-kitti.md) or `offline` (tuned,
        /// with AB3DMOT's whole-track score gate on the result files).
        #[arg(long, default_value = "paper")]
        tracker: String,
    },
    /// Evaluate result files against ground truth (ego trajectory or tracks).
    Eval {
        #[command(subcommand)]
        what: EvalCommand,
    },
    /// Run the tracker alone on KITTI tracking sequences (detections + OXTS poses),
    /// write KITTI result files to OUT/NNNN.txt and print CLEAR-MOT (2D, 3D) and
    /// AB3DMOT's sAMOTA/AMOTA for Car; or score a results directory (--score-only).
    TrackKitti(TrackKittiArgs),
    /// Re-render the report of `limot eval suite` from its results.json (no re-running).
    Report {
        /// OUT/results.json of a suite, or the suite directory holding it;
        /// with --merge, every shard's results file (OUT/results-shard-K-of-N.json).
        #[arg(required = true, num_args = 1..)]
        results: Vec<PathBuf>,
        /// Join the results files of all shards of one suite into
        /// OUT/results.json (OUT: their directory), then render the report.
        #[arg(long)]
        merge: bool,
        /// Report directory (default: the suite directory's report/).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Realism statistics of a sequence from its scans and ground truth alone (attitude
    /// change, ground-ring displacement, along-track information, range/intensity), written
    /// to OUT/realism.json and OUT/realism.md, optionally beside a reference (real KITTI).
    Realism {
        /// A limot dataset, its KITTI copy (DATASET/kitti) or a KITTI tracking `training` dir.
        path: PathBuf,
        /// Sequence of PATH's KITTI layout.
        #[arg(long, default_value_t = 0)]
        sequence: u32,
        /// Output directory (default: DATASET/realism for a limot dataset, else reports/realism).
        #[arg(long)]
        out: Option<PathBuf>,
        /// A KITTI tracking `training` dir (or a dataset) to put beside PATH.
        #[arg(long)]
        reference: Option<PathBuf>,
        /// Sequence of the reference.
        #[arg(long, default_value_t = 0)]
        reference_sequence: u32,
    },
    /// Print the version of every component.
    Version,
}

#[derive(Subcommand)]
enum EvalCommand {
    /// ATE (after alignment) and RPE of an estimated ego trajectory.
    Ego {
        /// Ground truth: a limot dataset dir, a KITTI-style dir (oxts/, calib/) or a pose file.
        #[arg(long)]
        truth: PathBuf,
        /// Estimated trajectory: TUM or KITTI pose file.
        #[arg(long)]
        estimate: PathBuf,
        /// Estimate format (tum|kitti); detected from the column count if omitted.
        #[arg(long)]
        format: Option<String>,
        /// Times of a KITTI estimate (one per line); default: the truth's frame times.
        #[arg(long)]
        times: Option<PathBuf>,
        /// Format of a truth pose file (tum|kitti); detected if omitted.
        #[arg(long)]
        truth_format: Option<String>,
        /// Times of a KITTI truth pose file; default: 0.1 s steps.
        #[arg(long)]
        truth_times: Option<PathBuf>,
        /// KITTI sequence number in a KITTI-style truth dir.
        #[arg(long, default_value_t = 0)]
        sequence: u32,
        /// Alignment before ATE: se3, sim3 or none.
        #[arg(long, default_value = "se3")]
        align: String,
        /// Largest time difference of an associated pose pair, s.
        #[arg(long, default_value_t = 0.01)]
        max_dt: f64,
        /// RPE step: N frames (1) or metres (10m).
        #[arg(long, default_value = "1")]
        rpe_delta: String,
        /// Use every pose as an RPE start (evo --all_pairs).
        #[arg(long)]
        rpe_all_pairs: bool,
        /// Also write the results as JSON.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Also write the results as markdown.
        #[arg(long)]
        markdown: Option<PathBuf>,
    },
    /// CLEAR-MOT (3D and BEV IoU 0.25/0.5), TP % and per-object ATE of KITTI-format tracking results.
    Tracks {
        /// The limot dataset the results were computed on.
        #[arg(long)]
        truth: PathBuf,
        /// KITTI tracking result file (label_02 lines, optional score column).
        #[arg(long)]
        results: PathBuf,
        /// Ground truth scored: camera (as the KITTI copy labels it) or all.
        #[arg(long, default_value = "camera")]
        gt_filter: String,
        /// Sequence number of the calibration in DATASET/kitti/calib.
        #[arg(long, default_value_t = 0)]
        sequence: u32,
        /// Also write the results as JSON.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Also write the results as markdown.
        #[arg(long)]
        markdown: Option<PathBuf>,
    },
    /// Simulate a scenario suite (families × seeds), run every variant on each
    /// sequence, score it and write OUT/results.json and OUT/report/README.md.
    Suite {
        /// Scenario families: built-in names (highway, urban, highway-dense, urban-parked) or TOML files, comma-separated.
        #[arg(long, default_value = "highway,highway-dense,urban,urban-parked")]
        families: String,
        /// Seeds, comma-separated.
        #[arg(long, default_value = "1,2")]
        seeds: String,
        /// Duration of each sequence, s.
        #[arg(long, default_value_t = 30.0)]
        duration: f64,
        /// Variants, comma-separated: lio, allfilt, dynafilt, limot.
        #[arg(long, default_value = "lio,allfilt,dynafilt,limot")]
        variants: String,
        /// Output directory (datasets in OUT/data are reused when their scenario matches).
        #[arg(long, default_value = "reports/suite")]
        out: PathBuf,
        /// Run only shard K of N (sequence i of the family-major list is in
        /// shard i mod N + 1) into OUT/results-shard-K-of-N.json; join the
        /// shards with `limot report --merge OUT/results-shard-*.json`.
        #[arg(long, value_name = "K/N")]
        shard: Option<String>,
        /// Sequences run at once (default: one per core). Use 1 for the
        /// per-stage times of a quiet machine; the scores do not change.
        #[arg(long, value_name = "N")]
        jobs: Option<usize>,
    },
    /// Real KITTI tracking data: every variant on each sequence with scans, the
    /// tracker alone on each with detections, scored against OXTS and label_02;
    /// writes OUT/results.json and OUT/report/README.md (the paper's Tables I-III).
    Kitti {
        /// KITTI tracking `training` dir (calib/, oxts/, label_02/, velodyne/SSSS/).
        #[arg(long)]
        training: PathBuf,
        /// AB3DMOT-format detection dir (SSSS.txt), e.g. detections/pointrcnn_Car_val.
        #[arg(long)]
        detections: Option<PathBuf>,
        /// How the detections' raw scores become [0, 1]: sigmoid (PointRCNN logits) or clamp01.
        #[arg(long, default_value = "sigmoid")]
        score_map: String,
        /// Sequences, comma-separated (default: every sequence with OXTS).
        #[arg(long)]
        sequences: Option<String>,
        /// Variants, comma-separated: lio, allfilt, dynafilt, limot.
        #[arg(long, default_value = "lio,allfilt,dynafilt,limot")]
        variants: String,
        /// Tracker settings and result-file rules of the object variants and
        /// of the tracker alone: `tuned` (chosen on the KITTI val split with
        /// PointRCNN boxes, see docs/tracking-kitti.md), `offline` (tuned,
        /// with AB3DMOT's whole-track score gate) or `paper`.
        #[arg(long, default_value = "tuned")]
        tracker: String,
        /// A peer tracker's KITTI result files, NAME=DIR (DIR/SSSS.txt), scored beside ours.
        #[arg(long)]
        tracking_peer: Option<String>,
        /// A peer odometry's LiDAR poses, NAME=DIR (DIR/SSSS.txt, TUM, stamped like
        /// limot's: sweep i starts at 0.1 i s), scored beside ours; repeatable.
        #[arg(long)]
        ego_peer: Vec<String>,
        /// Output directory.
        #[arg(long, default_value = "reports/kitti")]
        out: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Simulate {
            scenario,
            out,
            seed,
            duration,
            no_kitti,
            print,
            force,
        } => run_simulate(
            &scenario,
            &out,
            Overrides {
                seed,
                duration_s: duration,
            },
            !no_kitti,
            print,
            force,
        ),
        Command::Demo {
            out,
            scenario,
            duration,
        } => run_demo(&scenario, &out, duration),
        Command::Run {
            dataset,
            out,
            variant,
            lidar_only,
            first_frame,
            max_frames,
            sequence,
            detections,
            score_map,
            tracker,
        } => run_estimator(
            &dataset,
            out,
            &variant,
            lidar_only,
            first_frame,
            max_frames,
            KittiTracking {
                sequence,
                detections,
                score_map,
            },
            &tracker,
        ),
        Command::Eval { what } => run_eval(what),
        Command::TrackKitti(args) => run_track_kitti(args),
        Command::Report {
            results,
            merge,
            out,
        } => run_report(&results, merge, out),
        Command::Realism {
            path,
            sequence,
            out,
            reference,
            reference_sequence,
        } => limot::experiments::run_realism(&limot::experiments::RealismOptions {
            path,
            sequence,
            out,
            reference,
            reference_sequence,
            progress: true,
        })
        .map(|_| ())
        .map_err(Into::into),
        Command::Version => {
            println!("limot {}", env!("CARGO_PKG_VERSION"));
            Ok(())
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            let mut source = e.source();
            while let Some(s) = source {
                eprintln!("  caused by: {s}");
                source = s.source();
            }
            ExitCode::FAILURE
        }
    }
}

fn run_simulate(
    scenario: &str,
    out: &std::path::Path,
    overrides: Overrides,
    kitti: bool,
    print: bool,
    force: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut spec = resolve_scenario(scenario)?;
    overrides.apply(&mut spec)?;
    if print {
        print!("{}", spec.to_toml());
        return Ok(());
    }
    prepare_output_dir(out, force)?;
    let s = simulate(&spec, out, kitti, true)?;
    println!(
        "simulated `{}` (seed {}): {} frames, {} agents, {} points, {} detections in {:.1} s ({:.1} frames/s)",
        spec.name,
        spec.seed,
        s.frames,
        s.agents,
        s.points,
        s.detections,
        s.wall_time_s,
        s.frames as f64 / s.wall_time_s.max(1e-9)
    );
    println!("dataset: {}", s.dataset_dir.display());
    if let Some(k) = &s.kitti_dir {
        println!("KITTI-style copy: {}", k.display());
    }
    Ok(())
}

/// `limot run --sequence N [--detections P] [--score-map M]`: a KITTI
/// tracking sequence.
struct KittiTracking {
    sequence: Option<u32>,
    detections: Option<PathBuf>,
    score_map: String,
}

/// Options of `limot track-kitti`.
#[derive(clap::Args, Debug)]
struct TrackKittiArgs {
    /// KITTI tracking `training` dir (calib/, oxts/, label_02/).
    #[arg(long)]
    training: PathBuf,
    /// AB3DMOT detection CSV dir (NNNN.txt), e.g. detections/pointrcnn_Car_val.
    #[arg(long, required_unless_present = "score_only")]
    detections: Option<PathBuf>,
    /// Score the KITTI result files RESULTS_DIR/NNNN.txt (any tracker's)
    /// with the same evaluators instead of tracking.
    #[arg(long, value_name = "RESULTS_DIR", conflicts_with = "detections")]
    score_only: Option<PathBuf>,
    /// Sequence map (default: TRAINING/evaluate_tracking.seqmap.val).
    #[arg(long)]
    seqmap: Option<PathBuf>,
    /// Output directory of the result files.
    #[arg(long, required_unless_present = "score_only")]
    out: Option<PathBuf>,
    /// Tracker settings: `paper` (defaults), `tuned` (KITTI val tuned,
    /// online) or `offline` (KITTI val tuned, with AB3DMOT's offline
    /// whole-track score gate).
    #[arg(long, default_value = "tuned")]
    config: String,
    /// Override the detection score gate (sigmoid of the raw score).
    #[arg(long)]
    min_score: Option<f64>,
    /// Override the number of misses a track survives.
    #[arg(long)]
    max_misses: Option<usize>,
    /// Override the association gate, m.
    #[arg(long)]
    d_thres: Option<f64>,
    /// Override the association score: `distance` (the paper's eq. 1 on
    /// centre distance) or `giou:MIN` (AB3DMOT's 3D GIoU above MIN, also
    /// gated by --d-thres).
    #[arg(long, value_name = "distance|giou:MIN", allow_hyphen_values = true)]
    association: Option<String>,
    /// Override the prediction of a missed track: `fit` (the cubic
    /// extrapolated) or `constant-velocity`.
    #[arg(long, value_name = "fit|constant-velocity")]
    extrapolation: Option<String>,
    /// Override: frames a lost track can still be revived by a match.
    #[arg(long, value_name = "N")]
    revive_frames: Option<usize>,
    /// Override the heading rule: `first` (the first detection's) or
    /// `motion-or-majority`.
    #[arg(long, value_name = "first|motion-or-majority")]
    heading_rule: Option<String>,
    /// Also write coasting (predicted) confirmed tracks.
    #[arg(long)]
    with_predicted: bool,
    /// Override: write confirmed tracks coasting for at most N frames.
    #[arg(long, value_name = "N", conflicts_with = "with_predicted")]
    coast: Option<usize>,
    /// Override: matched frames a track needs before its coasting boxes are written.
    #[arg(long, value_name = "N")]
    coast_min_hits: Option<usize>,
    /// Override the consecutive hits that confirm a track.
    #[arg(long)]
    init_frames: Option<usize>,
    /// Override: write matched tentative tracks in the first N frames.
    #[arg(long, value_name = "N")]
    startup_frames: Option<u32>,
    /// Override the minimum mean raw detection score of a written track.
    #[arg(long, allow_negative_numbers = true)]
    min_track_score: Option<f64>,
    /// Override the offline gate: whole tracks whose mean raw detection
    /// score over the sequence is below this are removed (not causal).
    #[arg(long, allow_negative_numbers = true)]
    offline_track_score: Option<f64>,
    /// Override the score (sigmoid of the raw score) a detection needs to start a track.
    #[arg(long)]
    birth_min_score: Option<f64>,
    /// Confirm tracks on matched frames in all, not consecutive ones.
    #[arg(long)]
    total_hits: bool,
    /// Write the matched detection's box instead of the fitted one.
    #[arg(long)]
    detection_boxes: bool,
    /// Skip seqmap sequences whose detection (or result) file is missing.
    #[arg(long)]
    skip_missing: bool,
}

fn parse_score_map(name: &str) -> Result<limot::kitti::detections::ScoreMap, String> {
    use limot::kitti::detections::ScoreMap;
    match name {
        "sigmoid" => Ok(ScoreMap::Sigmoid),
        "clamp01" => Ok(ScoreMap::Clamp01),
        other => Err(format!("unknown --score-map `{other}` (sigmoid, clamp01)")),
    }
}

#[allow(clippy::too_many_arguments)]
fn run_estimator(
    dataset: &std::path::Path,
    out: Option<PathBuf>,
    variant: &str,
    lidar_only: bool,
    first_frame: usize,
    max_frames: Option<usize>,
    kitti_tracking: KittiTracking,
    tracker: &str,
) -> Result<(), Box<dyn std::error::Error>> {
    use limot::report::Variant;
    use limot::run::{RunOptions, Source, run, write_output};
    let variant = Variant::ALL
        .into_iter()
        .find(|v| v.name() == variant)
        .ok_or_else(|| format!("unknown variant `{variant}` (lio, allfilt, dynafilt, limot)"))?;
    let out = out.unwrap_or_else(|| dataset.join(variant.name()));
    let source = match (kitti_tracking.sequence, &kitti_tracking.detections) {
        (Some(sequence), detections) => Source::open_kitti_tracking(
            dataset,
            sequence,
            detections.as_deref(),
            parse_score_map(&kitti_tracking.score_map)?,
        )?,
        (None, Some(_)) => {
            return Err("--detections needs --sequence (a KITTI tracking directory)".into());
        }
        (None, None) => Source::open(dataset)?,
    };
    let options = RunOptions {
        variant,
        lidar_only,
        first_frame,
        max_frames,
        progress: true,
    };
    let tracking = kitti_tracking_options(tracker, parse_score_map(&kitti_tracking.score_map)?)?;
    let config = if kitti_tracking.sequence.is_some() {
        limot::run::kitti_tracking_config(tracking.tracker.clone())
    } else {
        limot_estimator::pipeline::EstimatorConfig {
            tracker: tracking.tracker.clone(),
            ..Default::default()
        }
    };
    let output = run(&source, dataset, &options, Some(config))?;
    write_output(&out, &output)?;
    let n = output.estimates.len();
    println!(
        "{}: {} frames estimated ({} of them LiDAR-only before the inertial initialisation), {:?} mode, {:.1} s wall ({:.1} FPS)",
        variant.name(),
        n,
        output.frames_before_init,
        output.mode,
        output.wall_time.as_secs_f64(),
        n as f64 / output.wall_time.as_secs_f64().max(1e-9)
    );
    let timings: Vec<String> = output
        .mean_timings()
        .iter()
        .map(|(name, d)| format!("{name} {:.2}", d.as_secs_f64() * 1e3))
        .collect();
    println!("mean ms per frame: {}", timings.join(", "));
    if output.invalid_detections > 0 {
        eprintln!(
            "warning: {} detections skipped (non-finite or non-positive fields, score outside [0, 1], or seen outside their sweep)",
            output.invalid_detections
        );
    }
    if dataset.join("gt").join("ego.csv").is_file() {
        let opts = EgoEvalOptions::default();
        let e = evaluate_ego(dataset, &out.join("poses_tum.txt"), &opts)?;
        println!(
            "ego vs truth: ATE_T {:.3} m, ATE_R {:.4} rad over {} poses",
            e.ate.ate_t_rmse_m, e.ate.ate_r_rmse_rad, e.ate.n
        );
    }
    if let Some(sequence) = kitti_tracking.sequence {
        use limot::experiments::{KittiScoreOptions, score_run};
        let (scores, results) = score_run(
            dataset,
            sequence,
            &output,
            &out.join("kitti_results"),
            &KittiScoreOptions {
                result: tracking.result.clone(),
                score_map: tracking.score_map,
                ..KittiScoreOptions::default()
            },
        )?;
        println!("ego vs OXTS: {}", scores.ego.summary_line());
        match &scores.tracks {
            Some(tracks) => {
                for line in tracks.summary_lines(KittiScoreOptions::default().longest_objects) {
                    println!("tracks vs label_02: {line}");
                }
            }
            None if !variant.tracks_objects() => {}
            None => println!(
                "tracks: no {} here, so no MOT score",
                limot::kitti::sequence_file(&dataset.join("label_02"), sequence).display()
            ),
        }
        let scores_path = out.join("scores.json");
        std::fs::write(&scores_path, serde_json::to_string_pretty(&scores)? + "\n")
            .map_err(|e| format!("{}: {e}", scores_path.display()))?;
        println!("KITTI tracking results: {}", results.display());
        println!("scores: {}", scores_path.display());
    }
    if let Source::Dataset(dataset) = &source {
        let (calib, _) = limot::experiments::dataset_calib(dataset, 0)?;
        let results =
            limot::run::write_dataset_kitti_tracks(&out.join("kitti_results"), &output, &calib)?;
        let e = evaluate_tracks(
            dataset_dir_of(dataset),
            &results,
            &TrackEvalOptions::default(),
        )?;
        for score in &e.scores {
            println!(
                "tracks vs truth ({:?} IoU {}): MOTA {:.1} %, MOTP {:.1} %, IDSW {}, FP {}, FN {}",
                score.iou_kind,
                score.iou_threshold,
                score.all.mota.unwrap_or(f64::NAN) * 100.0,
                score.all.motp.unwrap_or(f64::NAN) * 100.0,
                score.all.id_switches,
                score.all.false_positives,
                score.all.false_negatives
            );
        }
        println!("KITTI tracking results: {}", results.display());
    }
    println!("trajectory: {}", out.join("poses_tum.txt").display());
    Ok(())
}

fn dataset_dir_of(dataset: &limot_sim::record::Dataset) -> &std::path::Path {
    &dataset.dir
}

fn run_demo(
    scenario: &str,
    out: &std::path::Path,
    duration_s: Option<f64>,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut spec = resolve_scenario(scenario)?;
    Overrides {
        seed: None,
        duration_s,
    }
    .apply(&mut spec)?;
    println!(
        "limot demo: simulating `{}` ({} s, seed {}) into {}",
        spec.name,
        spec.duration_s,
        spec.seed,
        out.display()
    );
    let s = demo(&spec, out, true)?;
    println!(
        "{} sweeps, {:.0} points per sweep, {} moving and {} parked agents, ego drove {:.0} m",
        s.frames, s.mean_points_per_scan, s.moving_agents, s.parked_agents, s.ego_path_length_m
    );
    for (threshold, r) in &s.detector {
        println!(
            "detector at 3D IoU {threshold}: MOTA {:.1} %, MOTP {:.1} % ({} matches, {} FP, {} FN; oracle ids)",
            r.mota.unwrap_or(f64::NAN) * 100.0,
            r.motp.unwrap_or(f64::NAN) * 100.0,
            r.matches,
            r.false_positives,
            r.false_negatives
        );
    }
    for e in &s.estimators {
        println!(
            "estimator {}: ego ATE_T {:.3} m, ATE_R {:.4} rad over {} frames ({} LiDAR-only before initialisation); \
             tracks MOTA {:.1} %, MOTP {:.1} % (3D IoU 0.25); {:.1} ms/frame, {:.1} FPS; {}",
            e.variant,
            e.ate_t_m,
            e.ate_r_rad,
            e.frames_estimated,
            e.frames_before_init,
            e.tracks.mota.unwrap_or(f64::NAN) * 100.0,
            e.tracks.motp.unwrap_or(f64::NAN) * 100.0,
            e.mean_frame_ms,
            e.fps,
            e.trajectory.display()
        );
    }
    println!("report: {}", s.report_readme.display());
    Ok(())
}

fn parse_align(s: &str) -> Result<limot::metrics::AlignMode, EvaluateError> {
    use limot::metrics::AlignMode;
    match s.to_ascii_lowercase().as_str() {
        "se3" => Ok(AlignMode::Se3),
        "sim3" => Ok(AlignMode::Sim3),
        "none" => Ok(AlignMode::None),
        _ => Err(EvaluateError::Argument(format!(
            "--align `{s}`: expected se3, sim3 or none"
        ))),
    }
}

fn write_output(path: &std::path::Path, text: &str) -> Result<(), EvaluateError> {
    std::fs::write(path, text).map_err(|source| EvaluateError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn run_eval(what: EvalCommand) -> Result<(), Box<dyn std::error::Error>> {
    match what {
        EvalCommand::Ego {
            truth,
            estimate,
            format,
            times,
            truth_format,
            truth_times,
            sequence,
            align,
            max_dt,
            rpe_delta,
            rpe_all_pairs,
            json,
            markdown,
        } => {
            let opts = EgoEvalOptions {
                estimate_format: format.as_deref().map(str::parse).transpose()?,
                estimate_times: times,
                truth_format: truth_format.as_deref().map(str::parse).transpose()?,
                truth_times,
                sequence,
                align: parse_align(&align)?,
                max_dt_s: max_dt,
                rpe_delta: parse_rpe_delta(&rpe_delta)?,
                rpe_all_pairs,
            };
            let r = evaluate_ego(&truth, &estimate, &opts)?;
            println!("{}", r.summary_line());
            println!();
            print!("{}", r.table()?.to_markdown()?);
            if let Some(note) = r.alignment_note() {
                println!("note: {note}");
            }
            if let Some(path) = json {
                write_output(&path, &r.to_json().render())?;
            }
            if let Some(path) = markdown {
                write_output(&path, &r.to_markdown()?)?;
            }
        }
        EvalCommand::Tracks {
            truth,
            results,
            gt_filter,
            sequence,
            json,
            markdown,
        } => {
            let opts = TrackEvalOptions {
                gt_filter: gt_filter.parse()?,
                sequence,
                ..TrackEvalOptions::default()
            };
            let r = evaluate_tracks(&truth, &results, &opts)?;
            for line in r.summary_lines() {
                println!("{line}");
            }
            println!();
            print!("{}", r.clear_mot_table()?.to_markdown()?);
            println!();
            print!("{}", r.object_table()?.to_markdown()?);
            if let Some(path) = json {
                write_output(&path, &r.to_json().render())?;
            }
            if let Some(path) = markdown {
                write_output(&path, &r.to_markdown()?)?;
            }
        }
        EvalCommand::Suite {
            families,
            seeds,
            duration,
            variants,
            out,
            shard,
            jobs,
        } => run_eval_suite(
            &families,
            &seeds,
            duration,
            &variants,
            out,
            shard.as_deref(),
            jobs,
        )?,
        EvalCommand::Kitti {
            training,
            detections,
            score_map,
            sequences,
            variants,
            tracker,
            tracking_peer,
            ego_peer,
            out,
        } => run_eval_kitti(
            training,
            detections,
            &score_map,
            sequences,
            &variants,
            &tracker,
            tracking_peer,
            ego_peer,
            out,
        )?,
    }
    Ok(())
}

/// `limot eval suite`: runs the suite, writes OUT/report and prints the ego table.
fn run_eval_suite(
    families: &str,
    seeds: &str,
    duration_s: f64,
    variants: &str,
    out: PathBuf,
    shard: Option<&str>,
    jobs: Option<usize>,
) -> Result<(), Box<dyn std::error::Error>> {
    use limot::experiments::{Shard, SuiteSpec, parse_list, run_suite};
    use limot::report::Variant;
    let spec = SuiteSpec {
        families: parse_list("families", families, |s| Ok(s.to_string()))?,
        seeds: parse_list("seeds", seeds, |s| {
            s.parse::<u64>().map_err(|e| e.to_string())
        })?,
        duration_s,
        variants: parse_list("variants", variants, |s| {
            Variant::parse(s).map_err(|e| e.to_string())
        })?,
        out_dir: out,
        shard: shard.map(Shard::parse).transpose()?,
        jobs,
    };
    let runs = spec.families.len() * spec.seeds.len() * spec.variants.len();
    println!(
        "limot eval suite: {} sequence(s) x {} variant(s) = {runs} runs of {} s into {}",
        spec.families.len() * spec.seeds.len(),
        spec.variants.len(),
        spec.duration_s,
        spec.out_dir.display()
    );
    let results = run_suite(&spec, true)?;
    if let Some(shard) = spec.shard {
        println!(
            "shard {}/{}: {} sequence(s) in {}; join all shards with `limot report --merge {}`",
            shard.index,
            shard.count,
            results.sequences.len(),
            spec.out_dir.join(shard.results_file_name()).display(),
            spec.out_dir.join("results-shard-*.json").display()
        );
        return Ok(());
    }
    print_suite_report(&results, &spec.out_dir, &spec.out_dir.join("report"))
}

/// `limot report`: re-renders a suite report from its results.json, or
/// joins the shards' results files first (`--merge`).
fn run_report(
    results: &[PathBuf],
    merge: bool,
    out: Option<PathBuf>,
) -> Result<(), Box<dyn std::error::Error>> {
    if merge {
        let (merged, suite_dir) = limot::experiments::merge_shards(results)?;
        let file = merged.save(&suite_dir)?;
        println!(
            "merged {} shard(s), {} sequence(s): {}",
            results.len(),
            merged.sequences.len(),
            file.display()
        );
        let out = out.unwrap_or_else(|| suite_dir.join("report"));
        return print_suite_report(&merged, &suite_dir, &out);
    }
    let [results] = results else {
        return Err(
            "one results file or suite directory (or --merge with the shards' files)".into(),
        );
    };
    let results = results.as_path();
    let file = if results.is_dir() {
        results.join(limot::experiments::RESULTS_FILE)
    } else {
        results.to_path_buf()
    };
    let text = std::fs::read_to_string(&file).map_err(|e| format!("{}: {e}", file.display()))?;
    if limot::experiments::is_kitti_results(&text) {
        let kitti = limot::experiments::KittiSuiteResults::parse(&text, &file)?;
        let dir = file
            .parent()
            .map_or_else(|| PathBuf::from("."), PathBuf::from);
        let out = out.unwrap_or_else(|| dir.join("report"));
        return print_kitti_report(&kitti, &file, &out);
    }
    let (results, suite_dir) = limot::experiments::SuiteResults::load(results)?;
    let out = out.unwrap_or_else(|| suite_dir.join("report"));
    print_suite_report(&results, &suite_dir, &out)
}

fn print_kitti_report(
    results: &limot::experiments::KittiSuiteResults,
    results_file: &std::path::Path,
    report_dir: &std::path::Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let readme = limot::report::write_kitti_report(report_dir, results)?;
    println!();
    print!(
        "{}",
        limot::report::kitti_ego_table(results)?.to_markdown()?
    );
    println!();
    print!(
        "{}",
        limot::report::kitti_tracking_table(results)?.to_markdown()?
    );
    println!("results: {}", results_file.display());
    println!("report: {}", readme.display());
    Ok(())
}

/// The KITTI tracking settings (tracker and result-file rules) named `paper`
/// (the paper's tracker; every matched confirmed track written), `tuned`
/// (online, chosen on the KITTI val split with PointRCNN boxes) or `offline`
/// (tuned, with AB3DMOT's whole-track score gate; not causal).
fn kitti_tracking_options(
    name: &str,
    score_map: limot::kitti::detections::ScoreMap,
) -> Result<limot::experiments::TrackKittiOptions, String> {
    use limot::experiments::{TrackKittiOptions, kitti_val_offline_options};
    let options = match name {
        "paper" => TrackKittiOptions::default(),
        "tuned" => limot::experiments::kitti_val_tuned_options(),
        "offline" => kitti_val_offline_options(),
        other => {
            return Err(format!(
                "tracker settings `{other}`: expected paper, tuned or offline"
            ));
        }
    };
    Ok(limot::experiments::TrackKittiOptions {
        score_map,
        ..options
    })
}

/// `NAME=DIR` of a peer option.
fn parse_peer(option: &str, text: &str) -> Result<(String, PathBuf), String> {
    match text.split_once('=') {
        Some((name, dir)) if !name.trim().is_empty() && !dir.is_empty() => {
            Ok((name.trim().to_string(), PathBuf::from(dir)))
        }
        _ => Err(format!("--{option} `{text}`: expected NAME=DIR")),
    }
}

#[allow(clippy::too_many_arguments)]
fn run_eval_kitti(
    training: PathBuf,
    detections: Option<PathBuf>,
    score_map: &str,
    sequences: Option<String>,
    variants: &str,
    tracker: &str,
    tracking_peer: Option<String>,
    ego_peer: Vec<String>,
    out: PathBuf,
) -> Result<(), Box<dyn std::error::Error>> {
    use limot::experiments::parse_list;
    use limot::experiments::{KittiSuiteSpec, run_kitti_suite};
    use limot::report::Variant;
    let spec = KittiSuiteSpec {
        training,
        detections,
        tracking: kitti_tracking_options(tracker, parse_score_map(score_map)?)?,
        variants: parse_list("variants", variants, |s| {
            Variant::parse(s).map_err(|e| e.to_string())
        })?,
        sequences: sequences
            .map(|s| {
                parse_list("sequences", &s, |x| {
                    x.parse::<u32>().map_err(|e| e.to_string())
                })
            })
            .transpose()?,
        tracking_peer: tracking_peer
            .map(|p| parse_peer("tracking-peer", &p))
            .transpose()?,
        ego_peers: ego_peer
            .iter()
            .map(|p| parse_peer("ego-peer", p))
            .collect::<Result<_, _>>()?,
        out_dir: out,
    };
    println!(
        "limot eval kitti: {} into {}",
        spec.training.display(),
        spec.out_dir.display()
    );
    let results = run_kitti_suite(&spec, true)?;
    let file = spec.out_dir.join(limot::experiments::RESULTS_FILE);
    print_kitti_report(&results, &file, &spec.out_dir.join("report"))
}

fn print_suite_report(
    results: &limot::experiments::SuiteResults,
    suite_dir: &std::path::Path,
    report_dir: &std::path::Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let readme = limot::report::write_suite_report(report_dir, results, suite_dir)?;
    println!();
    print!(
        "{}",
        limot::report::suite_ego_table(results)?.to_markdown()?
    );
    for s in &results.sequences {
        if let Some(e) = &s.error {
            println!("{}: not available: {e}", s.name);
        }
        for r in s.variants.iter().filter(|r| r.error.is_some()) {
            println!(
                "{} / {}: not available: {}",
                s.name,
                r.variant.label(),
                r.error.as_deref().unwrap_or_default()
            );
        }
    }
    println!(
        "results: {}",
        suite_dir.join(limot::experiments::RESULTS_FILE).display()
    );
    println!("report: {}", readme.display());
    Ok(())
}

/// `limot track-kitti`: tracks, writes result files and prints the scores.
fn run_track_kitti(args: TrackKittiArgs) -> Result<(), Box<dyn std::error::Error>> {
    use limot::experiments::{OutputPolicy, evaluate_sequences, read_results_dir, score_results};
    use limot::kitti::results::write_results_file;
    use limot::kitti::seqmap::read_seqmap;
    use limot_estimator::tracking::{AssociationMetric, Extrapolation, HeadingRule};
    let training = &args.training;
    let seqmap_path = args
        .seqmap
        .unwrap_or_else(|| training.join("evaluate_tracking.seqmap.val"));
    let mut entries = read_seqmap(&seqmap_path)?;
    // The directory whose NNNN.txt must exist: the results to score or the detections.
    let input_dir = args
        .score_only
        .clone()
        .or_else(|| args.detections.clone())
        .ok_or("--detections or --score-only is required")?;
    if args.skip_missing {
        entries.retain(|e| {
            let present = limot::kitti::sequence_file(&input_dir, e.sequence).is_file();
            if !present {
                eprintln!(
                    "skipping sequence {:04}: no file in {}",
                    e.sequence,
                    input_dir.display()
                );
            }
            present
        });
    }
    if let Some(results_dir) = args.score_only {
        let results = read_results_dir(&results_dir, &entries)?;
        print!("{}", score_results(training, &entries, &results)?.to_text());
        return Ok(());
    }
    let out = args.out.ok_or("--out is required when tracking")?;
    let mut options =
        kitti_tracking_options(&args.config, limot::kitti::detections::ScoreMap::Sigmoid)?;
    let tracker = &mut options.tracker;
    if let Some(v) = args.min_score {
        tracker.min_score = v;
    }
    if let Some(v) = args.max_misses {
        tracker.max_misses = v;
    }
    if let Some(v) = args.d_thres {
        tracker.d_thres_m = v;
    }
    if let Some(v) = args.init_frames {
        tracker.init_frames = v;
    }
    if let Some(v) = args.birth_min_score {
        tracker.birth_min_score = v;
    }
    if args.total_hits {
        tracker.confirm_on_total_hits = true;
    }
    if let Some(text) = &args.association {
        tracker.association = match text.split_once(':') {
            None if text == "distance" => AssociationMetric::CentreDistance,
            Some(("giou", min)) => AssociationMetric::Giou3d {
                min_giou: min
                    .parse()
                    .map_err(|e| format!("--association `{text}`: MIN: {e}"))?,
                distance_gate: true,
            },
            _ => {
                return Err(
                    format!("--association `{text}`: expected distance or giou:MIN").into(),
                );
            }
        };
    }
    if let Some(text) = &args.extrapolation {
        tracker.extrapolation = match text.as_str() {
            "fit" => Extrapolation::Fit,
            "constant-velocity" => Extrapolation::ConstantVelocity,
            _ => {
                return Err(
                    format!("--extrapolation `{text}`: expected fit or constant-velocity").into(),
                );
            }
        };
    }
    if let Some(n) = args.revive_frames {
        tracker.revive_frames = n;
    }
    if let Some(text) = &args.heading_rule {
        tracker.heading_rule = match text.as_str() {
            "first" => HeadingRule::FirstDetection,
            "motion-or-majority" => HeadingRule::MotionOrMajority,
            _ => {
                return Err(format!(
                    "--heading-rule `{text}`: expected first or motion-or-majority"
                )
                .into());
            }
        };
    }
    // A bad override is reported here, before any sequence is read.
    limot_estimator::tracking::Tracker::new(options.tracker.clone())?;
    let result = &mut options.result;
    if args.with_predicted {
        result.output = OutputPolicy::AllConfirmed;
    }
    if let Some(n) = args.coast {
        result.output = OutputPolicy::CoastingUpTo(n);
    }
    if let Some(n) = args.startup_frames {
        result.startup_frames = n;
    }
    if let Some(v) = args.min_track_score {
        result.min_track_score = v;
    }
    if let Some(v) = args.offline_track_score {
        result.offline_track_score = v;
    }
    if let Some(n) = args.coast_min_hits {
        result.coast_min_hits = n;
    }
    if args.detection_boxes {
        options.box_source = limot::experiments::BoxSource::Detection;
    }
    std::fs::create_dir_all(&out)?;
    let (tracks, evaluation) = evaluate_sequences(training, &input_dir, &entries, &options)?;
    for t in &tracks {
        write_results_file(&out, t.sequence, &t.labels)?;
    }
    print!("{}", evaluation.to_text());
    Ok(())
}
