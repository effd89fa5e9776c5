//! What a suite run saves: the figures of every sequence and variant
//! (`results.json`, [`SuiteResults`]), and the join of a sharded run's files.

use super::{
    Ablation, KittiTwins, RESULTS_FILE, RESULTS_FORMAT_VERSION, Result, Shard, SuiteError,
    sequence_name,
};
use crate::experiments::FilterEvaluation;
use crate::metrics::{MotSummary, TimingAccumulator};
use limot_estimator::Variant;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Serde helpers storing a [`Variant`] by its machine name.
pub(crate) mod variant_name {
    use limot_estimator::Variant;
    use serde::{Deserialize, Deserializer, Serializer, de::Error};

    pub fn serialize<S: Serializer>(v: &Variant, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(v.name())
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Variant, D::Error> {
        let name = String::deserialize(d)?;
        name.parse::<Variant>().map_err(D::Error::custom)
    }

    pub mod list {
        use super::*;
        use serde::ser::SerializeSeq;

        pub fn serialize<S: Serializer>(vs: &[Variant], s: S) -> Result<S::Ok, S::Error> {
            let mut seq = s.serialize_seq(Some(vs.len()))?;
            for v in vs {
                seq.serialize_element(v.name())?;
            }
            seq.end()
        }

        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Variant>, D::Error> {
            Vec::<String>::deserialize(d)?
                .iter()
                .map(|n| n.parse::<Variant>().map_err(D::Error::custom))
                .collect()
        }
    }
}

/// Ego trajectory accuracy (SE(3)-aligned ATE, RPE over one frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EgoMetrics {
    /// SE(3)-aligned ATE_T (RMSE), m.
    pub ate_t_m: f64,
    /// SE(3)-aligned ATE_R (RMSE), rad.
    pub ate_r_rad: f64,
    /// Largest translation error, m.
    pub ate_max_m: f64,
    /// Associated pose pairs.
    pub pairs: usize,
    /// RPE translation RMSE over one frame, m.
    pub rpe_t_m: Option<f64>,
    /// RPE rotation RMSE over one frame, rad.
    pub rpe_r_rad: Option<f64>,
    /// RMSE of the translation error along the true direction of travel, m
    /// ([`crate::metrics::AteResult::along_rmse_m`]; absent from results
    /// written before it was measured).
    #[serde(default)]
    pub ate_along_m: Option<f64>,
    /// Share of the scan matches that left a direction to the IMU's
    /// prediction (a degenerate match, e.g. along a road whose sides look the
    /// same everywhere), of the frames that were matched; absent for results
    /// written before it was measured.
    #[serde(default)]
    pub degenerate_match_share: Option<f64>,
}

/// Class-agnostic CLEAR-MOT at one IoU kind and threshold (MOTA, MOTP as fractions).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotMetrics {
    /// "3D" or "BEV".
    pub iou_kind: String,
    /// The IoU threshold.
    pub iou_threshold: f64,
    #[serde(flatten)]
    /// Counts and scores.
    pub counts: MotSummary,
}

/// One ground-truth object as the tracker followed it (3D IoU ≥ 0.25).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectMetricsRecord {
    /// Ground-truth id.
    pub gt_id: u64,
    /// Ground-truth class.
    pub class: String,
    /// Frames the object is in the ground truth.
    pub gt_frames: usize,
    /// Frames it was tracked in.
    pub tracked_frames: usize,
    /// `tracked_frames / gt_frames`, %.
    pub tp_percent: f64,
    /// The tracker id matched most often (the id in `tracks.csv`).
    pub track_id: Option<u64>,
    /// ATE_T of its track, m.
    pub ate_t_m: Option<f64>,
    /// ATE_R of its track, rad.
    pub ate_r_rad: Option<f64>,
}

/// Per-frame wall time of one pipeline stage, ms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageSamples {
    /// Stage name.
    pub stage: String,
    /// One wall time per frame, ms.
    pub ms: Vec<f64>,
}

/// Everything measured for one variant on one sequence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VariantMetrics {
    /// Frames with an estimate.
    pub frames_estimated: usize,
    /// Frames before the estimator initialised.
    pub frames_before_init: usize,
    /// Wall time of the run, s.
    pub wall_time_s: f64,
    /// Frames estimated per second of wall time.
    pub fps: f64,
    /// Ego trajectory accuracy.
    pub ego: EgoMetrics,
    /// Class-agnostic CLEAR-MOT per IoU kind and threshold.
    pub clear_mot: Vec<MotMetrics>,
    /// CLEAR-MOT of class Car alone (the class of KITTI's car benchmark),
    /// per IoU kind and threshold (absent from results written before it was measured).
    #[serde(default)]
    pub clear_mot_car: Vec<MotMetrics>,
    /// Per-object TP % and ATE.
    pub objects: Vec<ObjectMetricsRecord>,
    /// Pipeline stages in order, then "total".
    pub timings: Vec<StageSamples>,
    /// The dynamic-feature filter against the per-point labels (variants
    /// that filter; absent from results written before it was measured).
    #[serde(default)]
    pub filtering: Option<FilterEvaluation>,
}

impl VariantMetrics {
    /// CLEAR-MOT at `kind` ("3D"/"BEV") and `threshold`.
    pub fn mot(&self, kind: &str, threshold: f64) -> Option<&MotMetrics> {
        self.clear_mot
            .iter()
            .find(|m| m.iou_kind == kind && m.iou_threshold == threshold)
    }

    /// CLEAR-MOT of class Car at `kind` ("3D"/"BEV") and `threshold`.
    pub fn car_mot(&self, kind: &str, threshold: f64) -> Option<&MotMetrics> {
        self.clear_mot_car
            .iter()
            .find(|m| m.iou_kind == kind && m.iou_threshold == threshold)
    }

    /// Pipeline stage samples as a timing accumulator.
    pub fn timing_accumulator(&self) -> TimingAccumulator {
        let mut acc = TimingAccumulator::new();
        for stage in &self.timings {
            for &ms in &stage.ms {
                acc.record(&stage.stage, Duration::from_secs_f64(ms.max(0.0) / 1e3));
            }
        }
        acc
    }
}

/// One variant on one sequence: its figures, or why there are none.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VariantResult {
    #[serde(with = "variant_name")]
    /// The variant.
    pub variant: Variant,
    /// Output directory, relative to the suite directory.
    pub run_dir: PathBuf,
    /// Its figures; `None` when the run or its scoring failed.
    pub metrics: Option<VariantMetrics>,
    /// Set when the run or its scoring failed.
    pub error: Option<String>,
}

/// One ablation run on one sequence ([`Ablation`]): its figures, or why there are none.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AblationResult {
    /// The ablation.
    pub ablation: Ablation,
    /// Output directory, relative to the suite directory (`runs/<seq>/limot-joint`).
    pub run_dir: PathBuf,
    /// Its figures; `None` when the run or its scoring failed.
    pub metrics: Option<VariantMetrics>,
    /// Set when the run or its scoring failed.
    pub error: Option<String>,
}

/// One simulated sequence and every variant run on it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SequenceResult {
    /// `<family>_s<seed>`.
    pub name: String,
    /// Scenario family.
    pub family: String,
    /// Seed.
    pub seed: u64,
    /// Frames (sweeps) of the dataset.
    pub frames: usize,
    /// Dataset directory, relative to the suite directory.
    pub dataset_dir: PathBuf,
    /// Length of the true ego path, m (absent when the dataset could not be
    /// read, and from results written before it was measured).
    #[serde(default)]
    pub path_length_m: Option<f64>,
    /// Ground-truth ids of the moving objects (see [`MOVING_SPEED_MPS`](crate::experiments::MOVING_SPEED_MPS)).
    pub moving_objects: Vec<u64>,
    /// Set when the sequence could not be simulated or read.
    pub error: Option<String>,
    /// One entry per variant.
    pub variants: Vec<VariantResult>,
    /// One entry per ablation (absent when none ran, as in results written
    /// before ablations existed).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ablations: Vec<AblationResult>,
}

impl SequenceResult {
    /// The result of variant `v`, if it ran.
    pub fn variant(&self, v: Variant) -> Option<&VariantResult> {
        self.variants.iter().find(|r| r.variant == v)
    }

    /// The figures of variant `v`, if it ran and was scored.
    pub fn metrics(&self, v: Variant) -> Option<&VariantMetrics> {
        self.variant(v).and_then(|r| r.metrics.as_ref())
    }

    /// The figures of ablation `a`, if it ran and was scored.
    pub fn ablation_metrics(&self, a: Ablation) -> Option<&VariantMetrics> {
        self.ablations
            .iter()
            .find(|r| r.ablation == a)
            .and_then(|r| r.metrics.as_ref())
    }
}

/// What `results.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SuiteResults {
    /// Version of this layout ([`RESULTS_FORMAT_VERSION`]).
    pub format_version: u32,
    /// Scenario families, the `kitti` family as its twin families (`kitti-SSSS`).
    pub families: Vec<String>,
    /// Where the twins of the `kitti` family came from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub twins: Option<KittiTwins>,
    /// Seeds.
    pub seeds: Vec<u64>,
    /// Duration of each sequence, s.
    pub duration_s: f64,
    #[serde(with = "variant_name::list")]
    /// Variants run.
    pub variants: Vec<Variant>,
    /// Ablations run beside their variants (absent when none ran).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ablations: Vec<Ablation>,
    /// Set when only this shard's sequences are here.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<Shard>,
    /// One entry per sequence, family-major.
    pub sequences: Vec<SequenceResult>,
}

impl SuiteResults {
    /// The families as given to the suite: the twin families as one `kitti`.
    pub fn given_families(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for family in &self.families {
            let given = match (&self.twins, super::twin_sequence(family)) {
                (Some(_), Some(_)) => super::TWIN_FAMILY.to_string(),
                _ => family.clone(),
            };
            if !out.contains(&given) {
                out.push(given);
            }
        }
        out
    }

    /// Writes `dir/results.json` (a shard's: `dir/results-shard-K-of-N.json`).
    ///
    /// # Errors
    ///
    /// [`SuiteError::Io`] or [`SuiteError::Json`] when the file cannot be written.
    pub fn save(&self, dir: &Path) -> Result<PathBuf> {
        let path = dir.join(
            self.shard
                .map_or_else(|| RESULTS_FILE.to_string(), Shard::results_file_name),
        );
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

    /// Reads `results.json` (or `DIR/results.json` when given a directory);
    /// returns the results and the suite directory their paths are relative to.
    ///
    /// # Errors
    ///
    /// [`SuiteError`] when the file cannot be read or parsed or has another format version.
    pub fn load(path: &Path) -> Result<(SuiteResults, PathBuf)> {
        let file = if path.is_dir() {
            path.join(RESULTS_FILE)
        } else {
            path.to_path_buf()
        };
        let text = fs::read_to_string(&file).map_err(|source| SuiteError::Io {
            path: file.clone(),
            source,
        })?;
        let results: SuiteResults =
            serde_json::from_str(&text).map_err(|source| SuiteError::Json {
                path: file.clone(),
                source,
            })?;
        if results.format_version != RESULTS_FORMAT_VERSION {
            return Err(SuiteError::Version {
                path: file,
                found: results.format_version,
                expected: RESULTS_FORMAT_VERSION,
            });
        }
        let dir = file
            .parent()
            .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
        Ok((results, dir))
    }
}

/// Joins the results files of every shard of one suite (all `N` of them,
/// each once, same families, seeds, duration, variants and ablations, in one
/// directory, which the run paths inside are relative to) into the results
/// of the whole suite, sequences in the order a whole run gives them.
///
/// # Errors
///
/// [`SuiteError`] when a file cannot be read or the shards do not make one suite.
pub fn merge_shards(files: &[PathBuf]) -> Result<(SuiteResults, PathBuf)> {
    let spec_err = |text: String| SuiteError::Spec(text);
    let mut loaded = Vec::with_capacity(files.len());
    for file in files {
        loaded.push((file, SuiteResults::load(file)?));
    }
    let Some((first_file, (first, dir))) = loaded.first() else {
        return Err(spec_err("no shard results files given".into()));
    };
    let count = first
        .shard
        .ok_or_else(|| spec_err(format!("{}: not a shard's results", first_file.display())))?
        .count;
    let mut seen = vec![false; count];
    for (file, (r, r_dir)) in &loaded {
        let shard = r
            .shard
            .ok_or_else(|| spec_err(format!("{}: not a shard's results", file.display())))?;
        if shard.count != count {
            return Err(spec_err(format!(
                "{}: shard {}/{} of a suite split {} ways, {} of {count}",
                file.display(),
                shard.index,
                shard.count,
                shard.count,
                first_file.display()
            )));
        }
        if std::mem::replace(&mut seen[shard.index - 1], true) {
            return Err(spec_err(format!(
                "{}: shard {}/{count} given twice",
                file.display(),
                shard.index
            )));
        }
        if (
            &r.families,
            &r.twins,
            &r.seeds,
            r.duration_s,
            &r.variants,
            &r.ablations,
        ) != (
            &first.families,
            &first.twins,
            &first.seeds,
            first.duration_s,
            &first.variants,
            &first.ablations,
        ) {
            return Err(spec_err(format!(
                "{}: families, twins, seeds, duration, variants or ablations differ from {}",
                file.display(),
                first_file.display()
            )));
        }
        if r_dir != dir {
            return Err(spec_err(format!(
                "{}: not in {} with the other shards (the run paths are relative to it)",
                file.display(),
                dir.display()
            )));
        }
    }
    if let Some(missing) = seen.iter().position(|s| !s) {
        return Err(spec_err(format!(
            "shard {}/{count} is missing",
            missing + 1
        )));
    }
    let mut by_name: BTreeMap<String, SequenceResult> = loaded
        .iter()
        .flat_map(|(_, (r, _))| r.sequences.iter().cloned())
        .map(|s| (s.name.clone(), s))
        .collect();
    let mut sequences = Vec::with_capacity(by_name.len());
    for family in &first.families {
        for &seed in &first.seeds {
            let name = sequence_name(family, seed);
            sequences.push(
                by_name
                    .remove(&name)
                    .ok_or_else(|| spec_err(format!("no shard holds sequence {name}")))?,
            );
        }
    }
    let merged = SuiteResults {
        shard: None,
        sequences,
        ..first.clone()
    };
    Ok((merged, dir.clone()))
}
