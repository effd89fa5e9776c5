//! `limot eval kitti`: every variant on every KITTI tracking sequence whose
//! scans are present, the tracker alone on every sequence with detections,
//! and optional peers' outputs (AB3DMOT's result files, another odometry's
//! poses), all scored by the same evaluators
//! ([`crate::experiments::kitti_sequence`]) and saved as `OUT/results.json`;
//! [`crate::report::kitti`] renders it in the shapes of the paper's Tables
//! I-III with the paper's published rows beside ours.
//!
//! Layout of OUT:
//!
//! ```text
//! runs/SSSS/<variant>/   poses_tum.txt, tracks.csv, ..., kitti_results/SSSS.txt
//! tracker/SSSS.txt       the tracker alone (KITTI results)
//! results.json           KittiSuiteResults
//! report/README.md       the tables
//! ```
//!
//! A run or sequence that fails is recorded with its error and the others go
//! on; only a bad specification or an unwritable OUT stops the command.

use crate::experiments::{
    KittiRunScores, KittiScoreOptions, TrackScores, read_sequence_labels, score_ego, score_run,
    score_tracks,
};
use crate::experiments::{SuiteError, error_chain, variant_name};
use crate::experiments::{TrackKittiOptions, track_sequence_with};
use crate::io::Source;
use crate::io::kitti::calib::Calib;
use crate::io::kitti::labels::read_labels;
use crate::io::kitti::oxts::read_oxts;
use crate::io::kitti::poses::parse_tum;
use crate::io::kitti::{read_text, sequence_file};
use crate::metrics::KittiEvalClass;
use crate::metrics::{Ab3dmotEvalConfig, Ab3dmotSequence, ab3dmot_evaluate};
use crate::run::{RunOptions, kitti_tracking_config, run, write_output};
use indicatif::{ProgressBar, ProgressStyle};
use limot_estimator::Variant;
use serde::{Deserialize, Serialize};
use std::fs;
use std::path::{Path, PathBuf};

/// Version of this `results.json` layout.
pub const KITTI_RESULTS_FORMAT_VERSION: u32 = 1;

/// The `kind` field that tells these results from a simulated suite's.
pub const KITTI_RESULTS_KIND: &str = "kitti";

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct KittiSuiteSpec {
    /// A KITTI tracking `training` directory (calib/, oxts/, label_02/, velodyne/).
    pub training: PathBuf,
    /// AB3DMOT-format detections (`SSSS.txt`), for the object variants and
    /// the tracker alone; without them only `lio` runs.
    pub detections: Option<PathBuf>,
    /// The tracker settings and result-file rules of the object variants and
    /// of the tracker alone (e.g. [`crate::experiments::kitti_val_tuned_options`]), with the
    /// detections' score map.
    pub tracking: TrackKittiOptions,
    /// Variants run on each sequence with scans.
    pub variants: Vec<Variant>,
    /// Sequences to consider; `None`: every sequence with an OXTS file.
    pub sequences: Option<Vec<u32>>,
    /// Peer tracking results (KITTI format, `SSSS.txt`) scored beside ours.
    pub tracking_peer: Option<(String, PathBuf)>,
    /// Peer ego trajectories (TUM, `SSSS.txt`, LiDAR poses), each scored beside ours.
    pub ego_peers: Vec<(String, PathBuf)>,
    /// Output directory (OUT).
    pub out_dir: PathBuf,
}

/// One variant on one sequence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KittiVariantResult {
    #[serde(with = "variant_name")]
    /// The variant.
    pub variant: Variant,
    /// Output directory, relative to OUT.
    pub run_dir: PathBuf,
    /// Frames with an estimate.
    pub frames_estimated: usize,
    /// Frames before the estimator initialised.
    pub frames_before_init: usize,
    /// Mean wall time per estimated frame, ms.
    pub mean_frame_ms: f64,
    /// Scores; `None` when the run or its scoring failed.
    pub scores: Option<KittiRunScores>,
    /// Why the run or its scoring failed.
    pub error: Option<String>,
}

/// Tracking scores of a tracker (ours alone, or a peer's result files) on one sequence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrackerResult {
    /// Scores; `None` on failure.
    pub scores: Option<TrackScores>,
    /// Why the tracking or its scoring failed.
    pub error: Option<String>,
}

/// A peer's ego trajectory on one sequence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EgoPeerResult {
    /// The peer's name.
    pub name: String,
    /// Scores; `None` on failure.
    pub scores: Option<crate::experiments::EgoScores>,
    /// Why the trajectory could not be scored.
    pub error: Option<String>,
}

/// One KITTI tracking sequence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KittiSequenceResult {
    /// Sequence number.
    pub sequence: u32,
    /// OXTS records (= frames).
    pub frames: usize,
    /// Whether the sequence has velodyne scans (the variants need them).
    pub has_scans: bool,
    /// One entry per variant run.
    pub runs: Vec<KittiVariantResult>,
    /// The tracker alone with the KITTI settings, OXTS ego poses.
    pub tracker: Option<TrackerResult>,
    /// The peer tracker's results, when given.
    pub tracking_peer: Option<TrackerResult>,
    /// The peer ego trajectories, when given.
    pub ego_peers: Vec<EgoPeerResult>,
}

impl KittiSequenceResult {
    /// The run of variant `v`, if any.
    pub fn run(&self, v: Variant) -> Option<&KittiVariantResult> {
        self.runs.iter().find(|r| r.variant == v)
    }
}

/// AB3DMOT's evaluate.py ([`ab3dmot_evaluate`], Car, 3D IoU 0.25) of one
/// tracker's result files over a set of sequences (its thresholds are shared
/// by the whole set, so it is computed per set, not per sequence).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ab3dmotSummary {
    /// The tracker's name.
    pub name: String,
    /// Sequences evaluated together.
    pub sequences: Vec<u32>,
    /// sAMOTA.
    pub samota: f64,
    /// AMOTA.
    pub amota: f64,
    /// AMOTP.
    pub amotp: f64,
    /// MOTA and MOTP at the score threshold with the best MOTA.
    pub best_mota: Option<f64>,
    /// MOTP at the score threshold with the best MOTA.
    pub best_motp: f64,
}

/// What `results.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KittiSuiteResults {
    /// Always [`KITTI_RESULTS_KIND`].
    pub kind: String,
    /// Version of this layout ([`KITTI_RESULTS_FORMAT_VERSION`]).
    pub format_version: u32,
    /// The KITTI tracking `training/` directory.
    pub training: PathBuf,
    /// Detection CSV directory, when the tracker ran.
    pub detections: Option<PathBuf>,
    #[serde(with = "variant_name::list")]
    /// Variants run.
    pub variants: Vec<Variant>,
    /// Name of the peer tracker, when given.
    pub tracking_peer: Option<String>,
    /// Names of the peer ego trajectories.
    pub ego_peers: Vec<String>,
    /// One entry per sequence.
    pub sequences: Vec<KittiSequenceResult>,
    /// evaluate.py of the tracker alone (and the tracking peer) over the
    /// sequences both have, and of the tracker alone over all it ran on.
    #[serde(default)]
    pub ab3dmot_eval: Vec<Ab3dmotSummary>,
}

impl KittiSuiteResults {
    /// Writes `dir/results.json`.
    ///
    /// # Errors
    /// An unwritable file.
    pub fn save(&self, dir: &Path) -> Result<PathBuf, SuiteError> {
        let path = dir.join(crate::experiments::RESULTS_FILE);
        let text = serde_json::to_string_pretty(self).map_err(|source| SuiteError::Json {
            path: path.clone(),
            source,
        })?;
        fs::write(&path, text + "\n").map_err(|source| SuiteError::Io {
            path: path.clone(),
            source,
        })?;
        Ok(path)
    }

    /// Reads KITTI suite results from JSON text of `path`.
    ///
    /// # Errors
    /// Malformed JSON or another format version (named with the file).
    pub fn parse(text: &str, path: &Path) -> Result<KittiSuiteResults, SuiteError> {
        let results: KittiSuiteResults =
            serde_json::from_str(text).map_err(|source| SuiteError::Json {
                path: path.to_path_buf(),
                source,
            })?;
        if results.format_version != KITTI_RESULTS_FORMAT_VERSION {
            return Err(SuiteError::Version {
                path: path.to_path_buf(),
                found: results.format_version,
                expected: KITTI_RESULTS_FORMAT_VERSION,
            });
        }
        Ok(results)
    }
}

/// Whether `text` (a results.json) holds KITTI suite results.
pub fn is_kitti_results(text: &str) -> bool {
    #[derive(Deserialize)]
    struct Kind {
        kind: Option<String>,
    }
    serde_json::from_str::<Kind>(text)
        .ok()
        .and_then(|k| k.kind)
        .is_some_and(|k| k == KITTI_RESULTS_KIND)
}

/// `training/velodyne/SSSS/` with at least one `.bin` scan.
pub fn has_scans(training: &Path, sequence: u32) -> bool {
    fs::read_dir(training.join("velodyne").join(format!("{sequence:04}")))
        .map(|entries| {
            entries
                .filter_map(|e| e.ok())
                .any(|e| e.path().extension().is_some_and(|x| x == "bin"))
        })
        .unwrap_or(false)
}

/// Sequences with an OXTS file (`oxts/SSSS.txt`), ascending.
///
/// # Errors
/// An unreadable `oxts/` directory.
pub fn oxts_sequences(training: &Path) -> Result<Vec<u32>, SuiteError> {
    let dir = training.join("oxts");
    let entries = fs::read_dir(&dir).map_err(|source| SuiteError::Io {
        path: dir.clone(),
        source,
    })?;
    let mut sequences: Vec<u32> = entries
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().into_string().ok()?;
            let stem = name.strip_suffix(".txt")?;
            (stem.len() == 4).then(|| stem.parse().ok())?
        })
        .collect();
    sequences.sort_unstable();
    Ok(sequences)
}

fn bar(total: usize, visible: bool) -> ProgressBar {
    if !visible {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(total as u64).with_style(
        ProgressStyle::with_template("{msg:>24} [{bar:40}] {pos}/{len} runs  eta {eta}")
            .expect("static template")
            .progress_chars("=> "),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(250));
    bar
}

/// Runs one variant on one sequence and scores it.
fn run_variant(
    spec: &KittiSuiteSpec,
    sequence: u32,
    variant: Variant,
    opts: &KittiScoreOptions,
) -> KittiVariantResult {
    let run_dir = PathBuf::from("runs")
        .join(format!("{sequence:04}"))
        .join(variant.name());
    let mut result = KittiVariantResult {
        variant,
        run_dir: run_dir.clone(),
        frames_estimated: 0,
        frames_before_init: 0,
        mean_frame_ms: 0.0,
        scores: None,
        error: None,
    };
    let out = spec.out_dir.join(&run_dir);
    let attempt = || -> Result<_, Box<dyn std::error::Error>> {
        let detections = spec
            .detections
            .as_deref()
            .filter(|_| variant.tracks_objects());
        let source = Source::open_kitti_tracking(
            &spec.training,
            sequence,
            detections,
            spec.tracking.score_map,
        )?;
        let options = RunOptions {
            variant,
            ..RunOptions::default()
        };
        let config = kitti_tracking_config(spec.tracking.tracker.clone(), variant);
        let output = run(&source, &spec.training, &options, Some(config))?;
        write_output(&out, &output)?;
        let (scores, _) = score_run(
            &spec.training,
            sequence,
            &output,
            &out.join("kitti_results"),
            opts,
        )?;
        Ok((output, scores))
    };
    match attempt() {
        Ok((output, scores)) => {
            result.frames_estimated = output.estimates.len();
            result.frames_before_init = output.frames_before_init;
            result.mean_frame_ms = output
                .mean_timings()
                .last()
                .map_or(0.0, |(_, d)| d.as_secs_f64() * 1e3);
            result.scores = Some(scores);
        }
        Err(e) => result.error = Some(error_chain(e.as_ref())),
    }
    result
}

/// The tracker alone (KITTI settings) on one sequence, or a peer's result file.
fn score_tracker(
    training: &Path,
    sequence: u32,
    frames: usize,
    results: impl FnOnce() -> Result<
        Vec<crate::io::kitti::labels::TrackingLabel>,
        Box<dyn std::error::Error>,
    >,
) -> TrackerResult {
    let attempt = || -> Result<Option<TrackScores>, Box<dyn std::error::Error>> {
        let Some(gt) = read_sequence_labels(training, sequence)? else {
            return Ok(None);
        };
        let calib = Calib::read(&sequence_file(&training.join("calib"), sequence))?;
        let labels = results()?;
        Ok(Some(score_tracks(&gt, &labels, frames as u32, &calib)?))
    };
    match attempt() {
        Ok(scores) => TrackerResult {
            scores,
            error: None,
        },
        Err(e) => TrackerResult {
            scores: None,
            error: Some(error_chain(e.as_ref())),
        },
    }
}

/// A peer's TUM trajectory `dir/SSSS.txt` (stamped like limot's poses: the
/// sweep of frame `i` starts at `0.1·i` s) scored like our runs, which
/// cover every frame.
fn score_ego_peer(
    training: &Path,
    sequence: u32,
    name: &str,
    dir: &Path,
    opts: &KittiScoreOptions,
) -> Option<EgoPeerResult> {
    let path = sequence_file(dir, sequence);
    if !path.is_file() {
        return None;
    }
    let attempt = || -> Result<_, Box<dyn std::error::Error>> {
        let poses = parse_tum(&read_text(&path)?, &path)?;
        let poses: Vec<_> = poses.iter().map(|p| (p.t_s, p.pose)).collect();
        Ok(score_ego(training, sequence, &poses, opts)?)
    };
    Some(match attempt() {
        Ok(scores) => EgoPeerResult {
            name: name.to_string(),
            scores: Some(scores),
            error: None,
        },
        Err(e) => EgoPeerResult {
            name: name.to_string(),
            scores: None,
            error: Some(error_chain(e.as_ref())),
        },
    })
}

/// evaluate.py of `name`'s result files `dir/SSSS.txt` over `sequences`.
fn ab3dmot_summary(
    training: &Path,
    name: &str,
    dir: &Path,
    sequences: &[&KittiSequenceResult],
) -> Result<Ab3dmotSummary, SuiteError> {
    let data = |e: &dyn std::error::Error| SuiteError::Data(error_chain(e));
    let mut labels = Vec::with_capacity(sequences.len());
    for s in sequences {
        let gt = read_sequence_labels(training, s.sequence)
            .map_err(|e| data(&e))?
            .unwrap_or_default();
        let results = read_labels(&sequence_file(dir, s.sequence)).map_err(|e| data(&e))?;
        labels.push((gt, results, s.frames as u32));
    }
    let input: Vec<Ab3dmotSequence<'_>> = labels
        .iter()
        .map(|(gt, results, num_frames)| Ab3dmotSequence {
            gt,
            results,
            num_frames: *num_frames,
        })
        .collect();
    let r = ab3dmot_evaluate(&input, KittiEvalClass::Car, &Ab3dmotEvalConfig::default())
        .map_err(|e| data(&e))?;
    Ok(Ab3dmotSummary {
        name: name.to_string(),
        sequences: sequences.iter().map(|s| s.sequence).collect(),
        samota: r.samota,
        amota: r.amota,
        amotp: r.amotp,
        best_mota: r.best.mota,
        best_motp: r.best.motp,
    })
}

/// evaluate.py of the tracker alone and the tracking peer on the sequences
/// both scored, and of the tracker alone on every sequence it scored.
fn ab3dmot_summaries(
    spec: &KittiSuiteSpec,
    results: &[KittiSequenceResult],
) -> Result<Vec<Ab3dmotSummary>, SuiteError> {
    let scored = |t: &Option<TrackerResult>| t.as_ref().is_some_and(|t| t.scores.is_some());
    let tracker_dir = spec.out_dir.join("tracker");
    let mut out = Vec::new();
    if let Some((name, dir)) = &spec.tracking_peer {
        let both: Vec<&KittiSequenceResult> = results
            .iter()
            .filter(|s| scored(&s.tracker) && scored(&s.tracking_peer))
            .collect();
        if !both.is_empty() {
            out.push(ab3dmot_summary(&spec.training, name, dir, &both)?);
            out.push(ab3dmot_summary(
                &spec.training,
                TRACKER_ALONE,
                &tracker_dir,
                &both,
            )?);
        }
    }
    let all: Vec<&KittiSequenceResult> = results.iter().filter(|s| scored(&s.tracker)).collect();
    if !all.is_empty() {
        out.push(ab3dmot_summary(
            &spec.training,
            TRACKER_ALONE,
            &tracker_dir,
            &all,
        )?);
    }
    Ok(out)
}

/// The name of the tracker-alone rows.
pub const TRACKER_ALONE: &str = "tracker alone (limot)";

/// Runs everything `spec` asks for, saves `results.json` and returns the results.
///
/// # Errors
/// An empty variant list, an unreadable `training/oxts/`, an unwritable OUT.
pub fn run_kitti_suite(
    spec: &KittiSuiteSpec,
    progress: bool,
) -> Result<KittiSuiteResults, SuiteError> {
    if spec.variants.is_empty() {
        return Err(SuiteError::Spec("no variants given".into()));
    }
    let sequences = match &spec.sequences {
        Some(s) => s.clone(),
        None => oxts_sequences(&spec.training)?,
    };
    fs::create_dir_all(&spec.out_dir).map_err(|source| SuiteError::Io {
        path: spec.out_dir.clone(),
        source,
    })?;
    let opts = KittiScoreOptions {
        result: spec.tracking.result.clone(),
        score_map: spec.tracking.score_map,
        ..KittiScoreOptions::default()
    };
    let detections_of = |sequence: u32| {
        spec.detections
            .as_ref()
            .map(|d| sequence_file(d, sequence))
            .filter(|p| p.is_file())
    };
    let scanned: Vec<u32> = sequences
        .iter()
        .copied()
        .filter(|&s| has_scans(&spec.training, s))
        .collect();
    let with_detections = sequences
        .iter()
        .filter(|&&s| detections_of(s).is_some())
        .count();
    let bar = bar(
        scanned.len() * spec.variants.len() + with_detections,
        progress,
    );
    let mut results = Vec::with_capacity(sequences.len());
    for &sequence in &sequences {
        let oxts_path = sequence_file(&spec.training.join("oxts"), sequence);
        let frames = match read_oxts(&oxts_path) {
            Ok(records) => records.len(),
            Err(e) => {
                return Err(SuiteError::Data(error_chain(&e)));
            }
        };
        let mut result = KittiSequenceResult {
            sequence,
            frames,
            has_scans: scanned.contains(&sequence),
            runs: Vec::new(),
            tracker: None,
            tracking_peer: None,
            ego_peers: Vec::new(),
        };
        if result.has_scans {
            for &variant in &spec.variants {
                bar.set_message(format!("{sequence:04} {}", variant.name()));
                result
                    .runs
                    .push(run_variant(spec, sequence, variant, &opts));
                bar.inc(1);
            }
        }
        if let Some(det_dir) = spec
            .detections
            .as_deref()
            .filter(|_| detections_of(sequence).is_some())
        {
            bar.set_message(format!("{sequence:04} tracker"));
            let options = &spec.tracking;
            let out_dir = spec.out_dir.join("tracker");
            result.tracker = Some(score_tracker(&spec.training, sequence, frames, || {
                let tracks = track_sequence_with(&spec.training, det_dir, sequence, options)?;
                fs::create_dir_all(&out_dir)?;
                crate::io::kitti::results::write_results_file(&out_dir, sequence, &tracks.labels)?;
                Ok(tracks.labels)
            }));
            bar.inc(1);
        }
        if let Some((_, dir)) = &spec.tracking_peer {
            let path = sequence_file(dir, sequence);
            if path.is_file() {
                result.tracking_peer =
                    Some(score_tracker(&spec.training, sequence, frames, || {
                        Ok(read_labels(&path)?)
                    }));
            }
        }
        for (name, dir) in &spec.ego_peers {
            if let Some(peer) = score_ego_peer(&spec.training, sequence, name, dir, &opts) {
                result.ego_peers.push(peer);
            }
        }
        results.push(result);
    }
    bar.finish_and_clear();
    let ab3dmot_eval = ab3dmot_summaries(spec, &results)?;
    let results = KittiSuiteResults {
        kind: KITTI_RESULTS_KIND.into(),
        format_version: KITTI_RESULTS_FORMAT_VERSION,
        training: spec.training.clone(),
        detections: spec.detections.clone(),
        variants: spec.variants.clone(),
        tracking_peer: spec.tracking_peer.as_ref().map(|(name, _)| name.clone()),
        ego_peers: spec
            .ego_peers
            .iter()
            .map(|(name, _)| name.clone())
            .collect(),
        sequences: results,
        ab3dmot_eval,
    };
    results.save(&spec.out_dir)?;
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_kind_is_recognised_and_a_suite_file_is_not() {
        assert!(is_kitti_results(
            r#"{"kind": "kitti", "format_version": 1}"#
        ));
        assert!(!is_kitti_results(
            r#"{"format_version": 1, "families": []}"#
        ));
        assert!(!is_kitti_results("not json"));
    }

    #[test]
    fn oxts_sequences_are_the_four_digit_txt_files_in_order() {
        let dir = std::env::temp_dir().join(format!("limot-kitti-suite-{}", std::process::id()));
        let oxts = dir.join("oxts");
        fs::create_dir_all(&oxts).unwrap();
        for name in ["0003.txt", "0000.txt", "notes.txt", "12.txt", "0020.txt"] {
            fs::write(oxts.join(name), "").unwrap();
        }
        assert_eq!(oxts_sequences(&dir).unwrap(), vec![0, 3, 20]);
        assert!(!has_scans(&dir, 0));
        let scans = dir.join("velodyne").join("0003");
        fs::create_dir_all(&scans).unwrap();
        fs::write(scans.join("000000.bin"), [0u8; 16]).unwrap();
        assert!(has_scans(&dir, 3));
        fs::remove_dir_all(&dir).unwrap();
    }
}
