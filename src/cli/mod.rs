//! The `limot` command line: argument types (clap) and one module per
//! subcommand. `main.rs` parses [`Cli`] and calls [`Cli::run`].
mod demo;
mod eval;
mod options;
mod progress;
mod realism;
mod report;
mod run;
mod simulate;
mod track_kitti;

pub(crate) use progress::frame_progress_bar;

use crate::simulate::Overrides;
use clap::{Parser, Subcommand};
use run::KittiTracking;
use std::path::PathBuf;

/// The `limot` command line.
#[derive(Parser)]
#[command(
    name = "limot",
    version,
    about = "LiDAR-inertial odometry and multi-object tracking, with a simulation testbed"
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a scenario into a dataset (limot format plus a KITTI-style copy in OUT/kitti).
    Simulate {
        /// Scenario TOML file, a built-in scenario name (highway, highway-dense, highway-jam,
        /// highway-exit, urban, urban-parked, urban-left, urban-uturn, urban-give-way, parking-lot), or `kitti` with --training and
        /// --sequence: the digital twin of a KITTI tracking sequence.
        scenario: String,
        /// With `kitti`: the KITTI tracking `training` dir (calib/, oxts/, label_02/).
        #[arg(long)]
        training: Option<PathBuf>,
        /// With `kitti`: the sequence number.
        #[arg(long)]
        sequence: Option<u32>,
        /// With `kitti`: the first KITTI frame replayed.
        #[arg(long, default_value_t = 0)]
        first_frame: usize,
        /// With `kitti`: frames replayed (default: to the end of the sequence).
        #[arg(long)]
        frames: Option<usize>,
        /// With `kitti`: residential, city or highway (default: chosen from the sequence).
        #[arg(long)]
        corridor: Option<String>,
        /// With `kitti`: AB3DMOT-format detections of the sequence (logit scores, e.g.
        /// PointRCNN's) put into the dataset instead of the detector model's.
        #[arg(long)]
        detections: Option<PathBuf>,
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
        /// Also record the dataset for Foxglove as this MCAP file (cloud, truth, detections).
        #[arg(long, value_name = "FILE")]
        mcap: Option<PathBuf>,
        /// Also write the raw sensor streams as this ROS 2 bag (MCAP: /points_raw,
        /// /imu, /tf_static, /detections3d), which `limot run FILE --lidar-topic
        /// /points_raw --imu-topic /imu` reads.
        #[arg(long, value_name = "FILE")]
        bag: Option<PathBuf>,
        #[command(flatten)]
        mcap_points: options::McapPoints,
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
        /// The Foxglove recording of the `limot` run (default: OUT/limot.mcap).
        #[arg(long, value_name = "FILE")]
        mcap: Option<PathBuf>,
        /// Write no MCAP recording.
        #[arg(long, conflicts_with = "mcap")]
        no_mcap: bool,
        #[command(flatten)]
        mcap_points: options::McapPoints,
    },
    /// Run the estimator on a dataset and write its trajectory (OUT/poses_tum.txt, ...).
    Run {
        /// A limot dataset, a KITTI raw drive dir (velodyne_points/, oxts/), a dir of KITTI
        /// .bin scans, or a ROS 2 bag file (.mcap) with --lidar-topic and --imu-topic.
        dataset: PathBuf,
        /// Output directory (default: DATASET/<variant>; for a bag FILE.mcap,
        /// FILE-<variant> beside it).
        #[arg(long)]
        out: Option<PathBuf>,
        /// The bag's sensor_msgs/PointCloud2 topic.
        #[arg(long, value_name = "TOPIC")]
        lidar_topic: Option<String>,
        /// The bag's sensor_msgs/Imu topic.
        #[arg(long, value_name = "TOPIC")]
        imu_topic: Option<String>,
        /// The bag's vision_msgs/Detection3DArray topic (boxes in the LiDAR frame).
        #[arg(long, value_name = "TOPIC")]
        detections_topic: Option<String>,
        /// The bag's LiDAR-IMU extrinsic: TOML `t_lidar_imu = [x, y, z, qx, qy, qz, qw]`
        /// (default: from /tf_static).
        #[arg(long, value_name = "FILE")]
        extrinsic: Option<PathBuf>,
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
        /// Also record the run for Foxglove as this MCAP file (cloud, poses, tracks, ...).
        #[arg(long, value_name = "FILE")]
        mcap: Option<PathBuf>,
        #[command(flatten)]
        mcap_points: options::McapPoints,
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
        /// A baseline suite (its results.json or directory): the report gains
        /// baseline.md, ATE_T and 3D MOTA@0.25 per sequence and variant before
        /// and after, and the regressions (ATE_T up > 5 % and > 1 cm, MOTA
        /// down > 2 points, a run no longer scored).
        #[arg(long)]
        baseline: Option<PathBuf>,
        /// With --baseline: exit with an error when there is any regression
        /// (a gate for CI or a merge request).
        #[arg(long, requires = "baseline")]
        fail_on_regression: bool,
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
    /// sequence, score it and write OUT/results.json and OUT/report/README.md;
    /// `--families kitti --training DIR --sequences 0-20`: the KITTI twins,
    /// reported beside the paper's Tables I-III.
    Suite(SuiteArgs),
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

/// Options of `limot eval suite`.
#[derive(clap::Args, Debug)]
struct SuiteArgs {
    /// Scenario families: built-in names (highway, highway-dense, highway-jam, highway-exit,
    /// urban, urban-parked, urban-left, urban-uturn, urban-give-way, parking-lot), TOML files, or `kitti` (the
    /// digital twins of --sequences in --training), comma-separated (default: every
    /// built-in scenario).
    #[arg(long)]
    families: Option<String>,
    /// Seeds, comma-separated (default: 1,2; a suite of KITTI twins only: 1).
    #[arg(long)]
    seeds: Option<String>,
    /// Duration of each sequence, s (default: 30; a suite of KITTI twins
    /// only: the whole sequence). A twin is cut to this.
    #[arg(long)]
    duration: Option<f64>,
    /// Variants, comma-separated: lio, allfilt, dynafilt, limot.
    #[arg(long, default_value = "lio,allfilt,dynafilt,limot")]
    variants: String,
    /// Ablations, comma-separated, each one more run per sequence reported
    /// beside its variant: `joint` = limot with dynamic objects informing the
    /// ego (the fully joint form; run `limot-joint`), against limot's default
    /// where they are conditioned on the optimised ego. Needs limot in --variants.
    #[arg(long, value_name = "LIST")]
    ablation: Option<String>,
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
    /// With `kitti`: the KITTI tracking `training` dir (oxts/, calib/, label_02/).
    #[arg(long)]
    training: Option<PathBuf>,
    /// With `kitti`: the sequences, numbers and ranges (`0-20`, `0,3,5-7`;
    /// default: every sequence with OXTS). Those not in --training are
    /// reported as not available.
    #[arg(long)]
    sequences: Option<String>,
    /// With `kitti`: AB3DMOT-format detections (DIR/SSSS.txt, logit scores,
    /// e.g. detections/pointrcnn_Car_val) recorded in the twins instead of
    /// the simulator's detector model.
    #[arg(long)]
    detections: Option<PathBuf>,
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

impl Cli {
    /// Runs the parsed command.
    ///
    /// # Errors
    /// Whatever the command reports: unreadable or malformed inputs (named),
    /// bad argument values, failed runs or unwritable outputs.
    pub fn run(self) -> Result<(), Box<dyn std::error::Error>> {
        match self.command {
            Command::Simulate {
                scenario,
                training,
                sequence,
                first_frame,
                frames,
                corridor,
                detections,
                out,
                seed,
                duration,
                no_kitti,
                print,
                force,
                mcap,
                mcap_points,
                bag,
            } => simulate::run_simulate(
                &scenario,
                simulate::TwinArgs {
                    training,
                    sequence,
                    first_frame,
                    frames,
                    corridor,
                    detections,
                },
                Overrides {
                    seed,
                    duration_s: duration,
                },
                print,
                simulate::SimulateOutputs {
                    out: &out,
                    kitti: !no_kitti,
                    force,
                    mcap: mcap.map(|path| mcap_points.request(path)).as_ref(),
                    bag: bag.as_deref(),
                },
            ),
            Command::Demo {
                out,
                scenario,
                duration,
                mcap,
                no_mcap,
                mcap_points,
            } => {
                let mcap = (!no_mcap)
                    .then(|| mcap_points.request(mcap.unwrap_or_else(|| out.join("limot.mcap"))));
                demo::run_demo(&scenario, &out, duration, mcap.as_ref())
            }
            Command::Run {
                dataset,
                out,
                lidar_topic,
                imu_topic,
                detections_topic,
                extrinsic,
                variant,
                lidar_only,
                first_frame,
                max_frames,
                sequence,
                detections,
                score_map,
                tracker,
                mcap,
                mcap_points,
            } => run::run_estimator(
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
                run::BagTopics {
                    lidar: lidar_topic,
                    imu: imu_topic,
                    detections: detections_topic,
                    extrinsic,
                },
                &tracker,
                mcap.map(|path| mcap_points.request(path)).as_ref(),
            ),
            Command::Eval { what } => eval::run_eval(what),
            Command::TrackKitti(args) => track_kitti::run_track_kitti(args),
            Command::Report {
                results,
                merge,
                out,
                baseline,
                fail_on_regression,
            } => report::run_report(
                &results,
                merge,
                out,
                baseline.map(|path| report::Baseline {
                    path,
                    fail_on_regression,
                }),
            ),
            Command::Realism {
                path,
                sequence,
                out,
                reference,
                reference_sequence,
            } => realism::run_realism(path, sequence, out, reference, reference_sequence),
            Command::Version => {
                println!("limot {}", env!("CARGO_PKG_VERSION"));
                Ok(())
            }
        }
    }
}

/// Says where a Foxglove recording went and what it holds.
fn print_mcap(stats: &crate::io::mcap::McapStats) {
    let span_s = stats
        .time_range_ns
        .map_or(0.0, |(first, last)| (last - first) as f64 * 1e-9);
    println!(
        "Foxglove recording: {} ({:.1} MB, {} messages over {:.1} s; layout docs/foxglove-layout.json)",
        stats.path.display(),
        stats.bytes as f64 / 1e6,
        stats.messages,
        span_s
    );
}
