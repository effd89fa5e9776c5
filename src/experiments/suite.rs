//! `limot eval suite`: simulates a set of scenarios (families × seeds), runs
//! every requested system variant on each, scores the runs against ground
//! truth and saves the figures as `OUT/results.json`, from which
//! `crate::report::suite` renders the tables and plots (also later, without
//! re-running, via `limot report`).
//!
//! The family `kitti` stands for the digital twins of the KITTI tracking
//! sequences of [`SuiteSpec::twins`] (one family `kitti-SSSS` per sequence,
//! see [`KittiTwins`]); a sequence whose files are not in the data is kept in the
//! results as not available.
//!
//! Layout of OUT:
//!
//! ```text
//! data/<family>_s<seed>/            the simulated dataset (reused when its scenario.toml and the
//!                                    simulator's code fingerprint match)
//! runs/<family>_s<seed>/<variant>/  poses_tum.txt, tracks.csv, ... and kitti_results/0000.txt
//! runs/<family>_s<seed>/limot-joint/ the same for an ablation (`--ablation joint`)
//! results.json                      SuiteResults (paths inside are relative to OUT)
//! results-shard-K-of-N.json         instead, when only shard K of N ran (`--shard K/N`)
//! ```
//!
//! Sequences run in parallel (`SuiteSpec::jobs` threads; the figures are
//! those of a serial run, the per-stage times those of a busy machine: use
//! one job for timing). A suite also splits into `N` independent shards
//! (sequence `i` of the family-major list belongs to shard `i mod N + 1`),
//! for array jobs on a cluster; [`merge_shards`] joins their results files
//! into the one a whole run writes.
//!
//! An [`Ablation`] runs its variant once more on every sequence with one
//! setting changed (the fully joint `limot`: `limot-joint`), saved beside the
//! variants and reported next to the variant it changes.
//!
//! A variant whose run or scoring fails is recorded with its error text and
//! the suite goes on; so does a sequence whose simulation fails. Only a bad
//! suite specification (unknown family, empty lists, bad duration) or an
//! unwritable OUT stops the suite.

use crate::experiments::evaluate_filtering;
use crate::experiments::{EgoEvalOptions, evaluate_ego};
use crate::experiments::{TrackEvalOptions, TracksEvaluation, dataset_calib, evaluate_tracks};
use crate::io::Source;
use crate::metrics::IouKind;
use crate::metrics::MotSummary;
use crate::run::{RunOptions, RunOutput, run, write_dataset_kitti_tracks, write_output};
use crate::simulate::{Overrides, prepare_output_dir, resolve_scenario, simulate};
use indicatif::{ProgressBar, ProgressStyle};
use limot_estimator::Variant;
use limot_estimator::input::ObjectClass;
use limot_estimator::pipeline::{EstimatorConfig, FrameEstimate};
use limot_sim::record::Dataset;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

mod ablation;
mod results;
mod twins;

pub use ablation::Ablation;
pub(crate) use results::variant_name;
pub use results::{
    AblationResult, EgoMetrics, MotMetrics, ObjectMetricsRecord, SequenceResult, StageSamples,
    SuiteResults, VariantMetrics, VariantResult, merge_shards,
};
pub use twins::{
    KittiTwins, TWIN_FAMILY, format_sequences, parse_sequences, twin_family, twin_sequence,
};

/// Version of the `results.json` layout; bumped when fields change meaning.
pub const RESULTS_FORMAT_VERSION: u32 = 1;

/// File name of the saved results inside the suite directory.
pub const RESULTS_FILE: &str = "results.json";

/// A ground-truth object counts as moving when it is not parked and its
/// horizontal speed reaches this at some frame (slower ones are waiting or
/// creeping: their points do not disturb the odometry).
pub const MOVING_SPEED_MPS: f64 = 0.5;

#[derive(Debug, thiserror::Error)]
/// Why a suite could not be run, saved, read or reported.
pub enum SuiteError {
    #[error("suite specification: {0}")]
    /// The suite's specification is invalid.
    Spec(String),
    #[error("family `{family}`: {source}")]
    /// A scenario family could not be resolved or simulated.
    Scenario {
        /// The family.
        family: String,
        #[source]
        /// The cause.
        source: Box<crate::simulate::SimulateError>,
    },
    #[error("{path}: {source}")]
    /// A file could not be read or written.
    Io {
        /// The file.
        path: PathBuf,
        #[source]
        /// The cause.
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    /// A results file is not valid JSON of its layout.
    Json {
        /// The file.
        path: PathBuf,
        #[source]
        /// The cause.
        source: serde_json::Error,
    },
    #[error("{path}: results format version {found}, this limot reads version {expected}")]
    /// A results file has another format version.
    Version {
        /// The file.
        path: PathBuf,
        /// Its version.
        found: u32,
        /// The version this build reads.
        expected: u32,
    },
    #[error("{path}: line {line}: field `{field}`: {why}")]
    /// A run output file is malformed.
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// The field.
        field: String,
        /// What is wrong with it.
        why: String,
    },
    #[error(transparent)]
    /// A report could not be written.
    Report(#[from] crate::report::ReportError),
    #[error("{0}")]
    /// Run outputs or results are inconsistent.
    Data(String),
}

pub type Result<T, E = SuiteError> = std::result::Result<T, E>;

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct SuiteSpec {
    /// Scenario files or built-in names (highway, highway-dense, highway-jam,
    /// highway-exit, urban, urban-parked, urban-left, urban-uturn, urban-give-way, parking-lot), or [`TWIN_FAMILY`] for the
    /// twins of `twins`.
    pub families: Vec<String>,
    /// Seeds, each simulated per family.
    pub seeds: Vec<u64>,
    /// Duration of each sequence, s.
    pub duration_s: f64,
    /// Variants run on each sequence.
    pub variants: Vec<Variant>,
    /// Ablations run on each sequence after the variants (each needs its
    /// variant among `variants`, the run it is compared with).
    pub ablations: Vec<Ablation>,
    /// Output directory (OUT).
    pub out_dir: PathBuf,
    /// Run only this shard's sequences (and save them as its own results file).
    pub shard: Option<Shard>,
    /// Sequences run at once; `None`: one per core.
    pub jobs: Option<usize>,
    /// The KITTI sequences the `kitti` family stands for (required with it).
    pub twins: Option<KittiTwins>,
}

/// Shard `index` (1-based) of `count`: the sequences at positions
/// `index - 1, index - 1 + count, ...` of the family-major sequence list.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// 1-based shard index.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl Shard {
    /// Parses `K/N` with 1 <= K <= N.
    ///
    /// # Errors
    ///
    /// [`SuiteError::Spec`] unless the text is `K/N` with `1 <= K <= N`.
    pub fn parse(text: &str) -> Result<Shard> {
        let bad = || {
            SuiteError::Spec(format!(
                "shard `{text}`: expected K/N with 1 <= K <= N (e.g. 2/4)"
            ))
        };
        let (k, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            k.trim().parse::<usize>().map_err(|_| bad())?,
            n.trim().parse::<usize>().map_err(|_| bad())?,
        );
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// Whether the sequence at `position` of the whole list is this shard's.
    pub fn holds(self, position: usize) -> bool {
        position % self.count == self.index - 1
    }

    /// `results-shard-K-of-N.json`.
    pub fn results_file_name(self) -> String {
        format!("results-shard-{}-of-{}.json", self.index, self.count)
    }
}

impl SuiteSpec {
    /// Runs per sequence: one per variant and one per ablation.
    pub fn runs_per_sequence(&self) -> usize {
        self.variants.len() + self.ablations.len()
    }

    /// The families one sequence per seed is simulated of: `families` with
    /// `kitti` replaced by one twin family per sequence of `twins`.
    ///
    /// # Errors
    ///
    /// [`SuiteError::Spec`] for `kitti` without `twins` or `twins` without `kitti`.
    pub fn sequence_families(&self) -> Result<Vec<String>> {
        let has_twins = self.families.iter().any(|f| f == TWIN_FAMILY);
        match (&self.twins, has_twins) {
            (None, true) => Err(SuiteError::Spec(
                "the kitti family needs a KITTI tracking training dir (--training DIR)".into(),
            )),
            (Some(_), false) => Err(SuiteError::Spec(
                "--training, --sequences and --detections are for the kitti family (--families kitti)"
                    .into(),
            )),
            (twins, _) => Ok(self
                .families
                .iter()
                .flat_map(|f| match twins {
                    Some(t) if f == TWIN_FAMILY => {
                        t.sequences.iter().map(|&n| twin_family(n)).collect()
                    }
                    _ => vec![f.clone()],
                })
                .collect()),
        }
    }

    /// Non-empty lists without repeats and a positive, finite duration.
    ///
    /// # Errors
    ///
    /// [`SuiteError::Spec`] for an empty or repeated family, seed or variant list, a
    /// repeated ablation or one whose variant does not run, a non-positive duration, an invalid shard or zero jobs, `kitti` without
    /// twins or twins without `kitti`.
    pub fn validate(&self) -> Result<()> {
        fn no_repeats<T: Ord + std::fmt::Debug>(what: &str, items: &[T]) -> Result<()> {
            if items.is_empty() {
                return Err(SuiteError::Spec(format!("no {what} given")));
            }
            let mut seen = BTreeSet::new();
            for item in items {
                if !seen.insert(item) {
                    return Err(SuiteError::Spec(format!("{what}: {item:?} given twice")));
                }
            }
            Ok(())
        }
        no_repeats("families", &self.families)?;
        no_repeats("seeds", &self.seeds)?;
        no_repeats("variants", &self.variants)?;
        if !self.ablations.is_empty() {
            no_repeats("ablations", &self.ablations)?;
        }
        if let Some(a) = self
            .ablations
            .iter()
            .find(|a| !self.variants.contains(&a.variant()))
        {
            return Err(SuiteError::Spec(format!(
                "ablation {a} is compared with {}: add it to the variants",
                a.variant()
            )));
        }
        let families = self.sequence_families()?;
        no_repeats("families (with the kitti twins)", &families)?;
        // two scenario files with one stem would share a data directory
        let names: Vec<String> = families.iter().map(|f| sequence_name(f, 0)).collect();
        no_repeats("family names (file stems)", &names)?;
        if !(self.duration_s.is_finite() && self.duration_s > 0.0) {
            return Err(SuiteError::Spec(format!(
                "duration must be a positive number of seconds, got {}",
                self.duration_s
            )));
        }
        if let Some(shard) = self.shard {
            Shard::parse(&format!("{}/{}", shard.index, shard.count))?;
        }
        if self.jobs == Some(0) {
            return Err(SuiteError::Spec("jobs must be at least 1".into()));
        }
        Ok(())
    }
}

/// Parses a comma-separated list (`"lio,dynafilt"`), naming the option in errors.
///
/// # Errors
///
/// [`SuiteError::Spec`] for an empty list or an entry that does not parse.
pub fn parse_list<T>(
    option: &str,
    text: &str,
    parse: impl Fn(&str) -> std::result::Result<T, String>,
) -> Result<Vec<T>> {
    text.split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| parse(s).map_err(|why| SuiteError::Spec(format!("--{option} `{s}`: {why}"))))
        .collect()
}

/// `<family>_s<seed>`, with a scenario file's stem as the family name.
pub fn sequence_name(family: &str, seed: u64) -> String {
    let stem = Path::new(family)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or(family);
    format!("{stem}_s{seed}")
}

/// An error and its sources on one line.
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let s_text = s.to_string();
        // transparent wrappers repeat their source's message
        if !text.ends_with(&s_text) {
            text.push_str(": ");
            text.push_str(&s_text);
        }
        source = s.source();
    }
    text
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> SuiteError + '_ {
    move |source| SuiteError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The overall bar (runs done / total), hidden when `visible` is false.
fn overall_bar(total: usize, visible: bool) -> ProgressBar {
    if !visible {
        return ProgressBar::hidden();
    }
    ProgressBar::new(total as u64).with_style(
        ProgressStyle::with_template("{prefix:>10} [{bar:40}] {pos}/{len} runs  {msg}  {elapsed}")
            .expect("static template")
            .progress_chars("#>-"),
    )
}

/// Simulates `spec` into `dir` unless a complete dataset of the same resolved
/// scenario is already there.
fn ensure_dataset(
    spec: &limot_sim::scenario::ScenarioSpec,
    dir: &Path,
    progress: bool,
) -> std::result::Result<bool, Box<dyn std::error::Error>> {
    let wanted = spec.to_toml();
    let existing = fs::read_to_string(dir.join("scenario.toml")).ok();
    let written_by = fs::read_to_string(dir.join(DATASET_CODE_FILE)).ok();
    if dir.join("meta.toml").is_file()
        && existing.as_deref() == Some(wanted.as_str())
        && written_by.as_deref() == Some(DATASET_CODE)
    {
        return Ok(false);
    }
    prepare_output_dir(dir, true)?;
    simulate(spec, dir, false, progress)?;
    fs::write(dir.join(DATASET_CODE_FILE), DATASET_CODE)
        .map_err(|e| format!("{}: {e}", dir.join(DATASET_CODE_FILE).display()))?;
    Ok(true)
}

/// A fingerprint of the code that writes datasets (build.rs): a dataset is
/// reused only when both its scenario and this match, so a simulator change
/// re-simulates it.
const DATASET_CODE: &str = env!("LIMOT_DATASET_CODE");
/// Where the suite records which code wrote a dataset it simulated.
const DATASET_CODE_FILE: &str = ".limot-dataset-code";

/// Length of the dataset's true ego path, m.
fn path_length_m(dataset: &Dataset) -> std::result::Result<f64, Box<dyn std::error::Error>> {
    let ego = dataset.ego_truth()?;
    Ok(ego
        .windows(2)
        .map(|w| {
            (w[1].t_world_lidar.translation.vector - w[0].t_world_lidar.translation.vector).norm()
        })
        .sum())
}

/// Ids of the moving ground-truth objects of a dataset.
fn moving_objects(dataset: &Dataset) -> std::result::Result<Vec<u64>, Box<dyn std::error::Error>> {
    let mut moving = BTreeSet::new();
    for frame in dataset.box_truth()? {
        for b in frame {
            if !b.parked && b.velocity_world_mps.xy().norm() >= MOVING_SPEED_MPS {
                moving.insert(u64::from(b.id));
            }
        }
    }
    Ok(moving.into_iter().collect())
}

fn iou_kind_name(kind: IouKind) -> &'static str {
    match kind {
        IouKind::ThreeD => "3D",
        IouKind::Bev => "BEV",
    }
}

/// Per-stage samples (ms) of a run, stages in pipeline order, then "total".
fn stage_samples(output: &RunOutput) -> Vec<StageSamples> {
    let mut stages: Vec<StageSamples> = Vec::new();
    for e in &output.estimates {
        let timings = e.timings.stages();
        let total = ("total", e.timings.total());
        for (i, (name, d)) in timings.into_iter().chain([total]).enumerate() {
            if stages.len() <= i {
                stages.push(StageSamples {
                    stage: name.to_string(),
                    ms: Vec::with_capacity(output.estimates.len()),
                });
            }
            // whole microseconds: finer is clock noise, and it keeps results.json small
            stages[i].ms.push((d.as_secs_f64() * 1e6).round() / 1e3);
        }
    }
    stages
}

/// CLEAR-MOT per IoU kind and threshold, of every class (`class` `None`)
/// or of one class (left out where that class has neither truth nor tracks).
fn mot_metrics(tracks: &TracksEvaluation, class: Option<ObjectClass>) -> Vec<MotMetrics> {
    tracks
        .scores
        .iter()
        .filter_map(|s| {
            let result = match class {
                None => &s.all,
                Some(c) => s.per_class.get(&c)?,
            };
            Some(MotMetrics {
                iou_kind: iou_kind_name(s.iou_kind).to_string(),
                iou_threshold: s.iou_threshold,
                counts: MotSummary::from(result),
            })
        })
        .collect()
}

fn object_metrics(tracks: &TracksEvaluation) -> Vec<ObjectMetricsRecord> {
    tracks
        .objects
        .iter()
        .map(|o| ObjectMetricsRecord {
            gt_id: o.gt_id,
            class: tracks
                .object_classes
                .get(&o.gt_id)
                .map_or_else(|| "?".to_string(), |c| c.to_string()),
            gt_frames: o.gt_frames,
            tracked_frames: o.tracked_frames,
            tp_percent: o.tp_percent,
            track_id: o.track_id,
            ate_t_m: o.ate_t_rmse_m,
            ate_r_rad: o.ate_r_rmse_rad,
        })
        .collect()
}

/// Share of the matched frames whose scan match was degenerate (see
/// [`EgoMetrics::degenerate_match_share`]); `None` without a match.
fn degenerate_match_share(estimates: &[FrameEstimate]) -> Option<f64> {
    let matches: Vec<_> = estimates.iter().filter_map(|e| e.scan_match).collect();
    let degenerate = matches
        .iter()
        .filter(|m| m.degenerate_directions > 0)
        .count();
    (!matches.is_empty()).then(|| degenerate as f64 / matches.len() as f64)
}

/// Runs one variant (with `ablation`'s override, if any) into `run_dir` and scores it.
fn run_variant(
    source: &Source,
    dataset: &Dataset,
    variant: Variant,
    ablation: Option<Ablation>,
    run_dir: &Path,
    progress: bool,
) -> std::result::Result<VariantMetrics, Box<dyn std::error::Error>> {
    // A stale output of an earlier suite must not pass for this run's.
    if run_dir.exists() {
        fs::remove_dir_all(run_dir).map_err(io_err(run_dir))?;
    }
    let options = RunOptions {
        variant,
        progress,
        ..RunOptions::default()
    };
    // Feature indices are recorded for the filter's precision and recall.
    let mut config = EstimatorConfig {
        record_feature_indices: variant != Variant::Lio,
        ..EstimatorConfig::default()
    };
    if let Some(a) = ablation {
        a.apply(&mut config);
    }
    let output = run(source, &dataset.dir, &options, Some(config))?;
    write_output(run_dir, &output)?;
    let filtering = evaluate_filtering(dataset, &output)?;
    let (calib, _) = dataset_calib(dataset, 0)?;
    let results = write_dataset_kitti_tracks(&run_dir.join("kitti_results"), &output, &calib)?;
    let ego = evaluate_ego(
        &dataset.dir,
        &run_dir.join("poses_tum.txt"),
        &EgoEvalOptions::default(),
    )?;
    // JSON has no NaN: a non-finite score would not survive results.json
    if !(ego.ate.ate_t_rmse_m.is_finite() && ego.ate.ate_r_rmse_rad.is_finite()) {
        return Err(format!(
            "ego ATE is not finite (ATE_T {}, ATE_R {})",
            ego.ate.ate_t_rmse_m, ego.ate.ate_r_rmse_rad
        )
        .into());
    }
    let tracks = evaluate_tracks(&dataset.dir, &results, &TrackEvalOptions::default())?;
    let wall_time_s = output.wall_time.as_secs_f64();
    Ok(VariantMetrics {
        frames_estimated: output.estimates.len(),
        frames_before_init: output.frames_before_init,
        wall_time_s,
        fps: output.estimates.len() as f64 / wall_time_s.max(1e-9),
        ego: EgoMetrics {
            ate_t_m: ego.ate.ate_t_rmse_m,
            ate_r_rad: ego.ate.ate_r_rmse_rad,
            ate_max_m: ego.ate.max_m,
            pairs: ego.ate.n,
            rpe_t_m: ego.rpe.as_ref().map(|r| r.trans_rmse_m),
            rpe_r_rad: ego.rpe.as_ref().map(|r| r.rot_rmse_rad),
            ate_along_m: ego.ate.along_rmse_m,
            degenerate_match_share: degenerate_match_share(&output.estimates),
        },
        clear_mot: mot_metrics(&tracks, None),
        clear_mot_car: mot_metrics(&tracks, Some(ObjectClass::Car)),
        objects: object_metrics(&tracks),
        timings: stage_samples(&output),
        filtering,
    })
}

/// Simulates (or reuses) one sequence and runs every variant on it; a
/// sequence without a scenario (`Err`: why) is recorded as not available.
fn run_sequence(
    spec: &SuiteSpec,
    scenario: std::result::Result<&limot_sim::scenario::ScenarioSpec, &str>,
    family: &str,
    seed: u64,
    bar: &ProgressBar,
    progress: bool,
) -> SequenceResult {
    let name = sequence_name(family, seed);
    let dataset_rel = Path::new("data").join(&name);
    let dataset_dir = spec.out_dir.join(&dataset_rel);
    let mut result = SequenceResult {
        name: name.clone(),
        family: family.to_string(),
        seed,
        frames: 0,
        dataset_dir: dataset_rel,
        path_length_m: None,
        moving_objects: Vec::new(),
        error: None,
        variants: Vec::new(),
        ablations: Vec::new(),
    };
    let scenario = match scenario {
        Ok(scenario) => scenario,
        Err(why) => {
            result.error = Some(why.to_string());
            bar.inc(spec.runs_per_sequence() as u64);
            return result;
        }
    };
    bar.set_message(format!("{name}: simulate"));
    // Inner progress bars (serial runs only) draw while the overall bar waits.
    let simulated = if progress {
        bar.suspend(|| ensure_dataset(scenario, &dataset_dir, progress))
    } else {
        ensure_dataset(scenario, &dataset_dir, progress)
    };
    let opened = simulated
        .and_then(|_| Ok(Dataset::open(&dataset_dir)?))
        .and_then(|d| {
            let moving = moving_objects(&d)?;
            let path_length_m = path_length_m(&d)?;
            Ok((d, moving, path_length_m))
        })
        .and_then(|(d, moving, path_length_m)| {
            let source = Source::open(&dataset_dir)?;
            Ok((d, moving, path_length_m, source))
        });
    let (dataset, moving, path_length_m, source) = match opened {
        Ok(x) => x,
        Err(e) => {
            result.error = Some(error_chain(e.as_ref()));
            // the variants of this sequence count as done
            bar.inc(spec.runs_per_sequence() as u64);
            return result;
        }
    };
    result.frames = dataset.frame_count();
    result.path_length_m = Some(path_length_m);
    result.moving_objects = moving;
    let runs = spec
        .variants
        .iter()
        .map(|&v| (v, None))
        .chain(spec.ablations.iter().map(|&a| (a.variant(), Some(a))));
    for (variant, ablation) in runs {
        let run_name = ablation.map_or_else(|| variant.name().to_string(), Ablation::run_name);
        bar.set_message(format!("{name}: {run_name}"));
        let run_rel = Path::new("runs").join(&name).join(&run_name);
        let run_dir = spec.out_dir.join(&run_rel);
        let outcome = if progress {
            bar.suspend(|| run_variant(&source, &dataset, variant, ablation, &run_dir, progress))
        } else {
            run_variant(&source, &dataset, variant, ablation, &run_dir, progress)
        };
        let (metrics, error) = match outcome {
            Ok(m) => (Some(m), None),
            Err(e) => (None, Some(error_chain(e.as_ref()))),
        };
        if bar.is_hidden() {
            // no overall bar: no per-run line either
        } else {
            let what = match (&metrics, &error) {
                (Some(m), _) => format!(
                    "ATE_T {:.3} m, ATE_R {:.4} rad, {:.1} FPS",
                    m.ego.ate_t_m, m.ego.ate_r_rad, m.fps
                ),
                (_, Some(e)) => format!("not available: {e}"),
                _ => String::new(),
            };
            bar.println(format!("{name} {run_name}: {what}"));
        }
        match ablation {
            None => result.variants.push(VariantResult {
                variant,
                run_dir: run_rel,
                metrics,
                error,
            }),
            Some(ablation) => result.ablations.push(AblationResult {
                ablation,
                run_dir: run_rel,
                metrics,
                error,
            }),
        }
        bar.inc(1);
    }
    result
}

/// Runs the whole suite and saves `OUT/results.json`.
///
/// # Errors
///
/// [`SuiteError`] when the specification is invalid or the results cannot be written; failures of single sequences or runs are recorded in the results instead.
pub fn run_suite(spec: &SuiteSpec, progress: bool) -> Result<SuiteResults> {
    spec.validate()?;
    let families = spec.sequence_families()?;
    if let Some(twins) = &spec.twins {
        twins.check()?;
    }
    // Resolve every scenario first: a typo fails before hours of simulation.
    // A twin whose files are missing has the reason instead.
    let mut scenarios = BTreeMap::new();
    for family in &families {
        for &seed in &spec.seeds {
            let wrap = |source| SuiteError::Scenario {
                family: family.clone(),
                source: Box::new(source),
            };
            let twin = twin_sequence(family).zip(spec.twins.as_ref());
            let mut scenario = match twin {
                Some((n, twins)) => match twins.missing_files(n) {
                    Some(why) => {
                        scenarios.insert((family.clone(), seed), Err(why));
                        continue;
                    }
                    None => twins.scenario(n)?,
                },
                None => resolve_scenario(family).map_err(wrap)?,
            };
            Overrides {
                seed: Some(seed),
                duration_s: Some(spec.duration_s),
            }
            .apply(&mut scenario)
            .map_err(wrap)?;
            scenarios.insert((family.clone(), seed), Ok(scenario));
        }
    }
    fs::create_dir_all(&spec.out_dir).map_err(io_err(&spec.out_dir))?;
    // families in the given order, then seeds in the given order
    let mine: Vec<(&String, u64)> = families
        .iter()
        .flat_map(|family| spec.seeds.iter().map(move |&seed| (family, seed)))
        .enumerate()
        .filter(|(position, _)| spec.shard.is_none_or(|s| s.holds(*position)))
        .map(|(_, sequence)| sequence)
        .collect();
    let total = mine.len() * spec.runs_per_sequence();
    let bar = overall_bar(total, progress);
    bar.set_prefix(match spec.shard {
        Some(s) => format!("shard {}/{}", s.index, s.count),
        None => "suite".to_string(),
    });
    let jobs = spec
        .jobs
        .unwrap_or_else(rayon::current_num_threads)
        .min(mine.len())
        .max(1);
    // Inner progress bars only when one sequence runs at a time.
    let inner_progress = progress && jobs == 1;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .map_err(|e| SuiteError::Spec(format!("cannot start {jobs} threads: {e}")))?;
    let sequences: Vec<SequenceResult> = pool.install(|| {
        use rayon::prelude::*;
        mine.par_iter()
            .map(|(family, seed)| {
                let scenario = scenarios[&((*family).clone(), *seed)]
                    .as_ref()
                    .map_err(String::as_str);
                run_sequence(spec, scenario, family, *seed, &bar, inner_progress)
            })
            .collect()
    });
    bar.finish_and_clear();
    let results = SuiteResults {
        format_version: RESULTS_FORMAT_VERSION,
        families,
        twins: spec.twins.clone(),
        seeds: spec.seeds.clone(),
        duration_s: spec.duration_s,
        variants: spec.variants.clone(),
        ablations: spec.ablations.clone(),
        shard: spec.shard,
        sequences,
    };
    results.save(&spec.out_dir)?;
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> SuiteSpec {
        SuiteSpec {
            families: vec!["urban".into()],
            seeds: vec![1, 2],
            duration_s: 4.0,
            variants: vec![Variant::Lio],
            ablations: Vec::new(),
            out_dir: PathBuf::from("unused"),
            shard: None,
            jobs: None,
            twins: None,
        }
    }

    #[test]
    fn spec_validation_names_the_problem() {
        assert!(spec().validate().is_ok());
        let mut s = spec();
        s.seeds = vec![1, 1];
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains("seeds") && e.contains("twice"), "{e}");
        let mut s = spec();
        s.variants.clear();
        assert!(s.validate().unwrap_err().to_string().contains("variants"));
        let mut s = spec();
        s.duration_s = f64::NAN;
        assert!(s.validate().unwrap_err().to_string().contains("duration"));
        // an ablation is compared with its variant, which must run
        let mut s = spec();
        s.ablations = vec![Ablation::Joint];
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains("joint") && e.contains("limot"), "{e}");
        s.variants.push(Variant::Limot);
        assert!(s.validate().is_ok());
        assert_eq!(s.runs_per_sequence(), 3);
        s.ablations.push(Ablation::Joint);
        assert!(s.validate().unwrap_err().to_string().contains("ablations"));
    }

    #[test]
    fn unknown_family_fails_before_any_work() {
        let dir = std::env::temp_dir().join(format!("limot-suite-unknown-{}", std::process::id()));
        let s = SuiteSpec {
            families: vec!["no-such-family".into()],
            out_dir: dir.clone(),
            ..spec()
        };
        let e = run_suite(&s, false).unwrap_err().to_string();
        assert!(e.contains("no-such-family"), "{e}");
        assert!(!dir.exists(), "nothing may be written for a bad spec");
    }

    #[test]
    fn list_parsing_trims_and_reports_the_option() {
        let v = parse_list("variants", " lio, dynafilt ,", |s| {
            s.parse::<Variant>().map_err(|e| e.to_string())
        })
        .unwrap();
        assert_eq!(v, vec![Variant::Lio, Variant::Dynafilt]);
        let e = parse_list("seeds", "1,x", |s| {
            s.parse::<u64>().map_err(|e| e.to_string())
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("--seeds `x`"), "{e}");
    }

    #[test]
    fn sequence_names_use_the_file_stem() {
        assert_eq!(sequence_name("urban", 3), "urban_s3");
        assert_eq!(sequence_name("scenarios/my_city.toml", 1), "my_city_s1");
    }

    #[test]
    fn error_chain_skips_repeated_messages() {
        let inner = std::io::Error::other("disk full");
        let outer = SuiteError::Io {
            path: PathBuf::from("a/b"),
            source: inner,
        };
        assert_eq!(error_chain(&outer), "a/b: disk full");
    }
}
