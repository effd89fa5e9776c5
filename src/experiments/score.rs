//! `limot eval`: scores result FILES against ground truth, so external tools
//! (e.g. KISS-ICP run on the KITTI-style copy of a simulated dataset) and,
//! later, the variant runner are evaluated the same way.
//!
//! - [`ego`]: an estimated ego trajectory (TUM or KITTI pose file) against a
//!   limot dataset, a KITTI-style directory (OXTS + calib) or a pose file →
//!   ATE_T / ATE_R after alignment and RPE.
//! - [`kitti_sequence`]: a run on a KITTI tracking sequence against its OXTS
//!   poses and label_02 (ego ATE/RPE, Car CLEAR-MOT in 2D and 3D, object ATE).
//! - [`tracks`]: KITTI-format tracking results (label_02 lines + score) against
//!   the ground-truth boxes of a limot dataset → CLEAR-MOT at 3D and BEV IoU,
//!   TP % and per-object ATE.
//!
//! This module is glue between the file readers ([`crate::kitti`],
//! [`limot_sim::record`]), the metrics ([`crate::metrics`]) and the tables
//! ([`crate::report::table`]); it holds no metric of its own.

pub(crate) mod ego;
pub(crate) mod filtering;
pub(crate) mod json;
pub(crate) mod kitti_sequence;
pub(crate) mod tracks;

use crate::metrics::EvalError;
use crate::kitti::KittiError;
use crate::report::ReportError;
use limot_sim::record::RecordError;
use std::path::{Path, PathBuf};

/// Why an evaluation could not be done.
#[derive(Debug, thiserror::Error)]
pub enum EvaluateError {
    #[error(transparent)]
    Kitti(#[from] KittiError),
    #[error(transparent)]
    Record(#[from] RecordError),
    #[error(transparent)]
    Eval(#[from] EvalError),
    #[error(transparent)]
    Report(#[from] ReportError),
    #[error(transparent)]
    Run(#[from] Box<crate::run::RunError>),
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: {why}", path.display())]
    Input { path: PathBuf, why: String },
    #[error(
        "timestamps do not overlap: estimate {} covers [{est_first_s}, {est_last_s}] s ({est_n} poses), \
         truth {} covers [{truth_first_s}, {truth_last_s}] s ({truth_n} poses); only {pairs} pose pairs \
         are within max_dt = {max_dt_s} s of each other, need at least {need} \
         (check the time base, or pass --times / --max-dt)",
        estimate.display(),
        truth.display()
    )]
    NoOverlap {
        estimate: PathBuf,
        truth: PathBuf,
        est_first_s: f64,
        est_last_s: f64,
        est_n: usize,
        truth_first_s: f64,
        truth_last_s: f64,
        truth_n: usize,
        pairs: usize,
        need: usize,
        max_dt_s: f64,
    },
    #[error(
        "{} has {poses} poses but the times {} has {times} entries",
        poses_path.display(),
        times_path.display()
    )]
    TimesLength {
        poses_path: PathBuf,
        poses: usize,
        times_path: PathBuf,
        times: usize,
    },
    #[error("invalid argument: {0}")]
    Argument(String),
}

pub type Result<T> = std::result::Result<T, EvaluateError>;

pub use crate::kitti::poses::read_times;

/// Whether `dir` is a limot dataset (it holds `meta.toml`).
pub fn is_limot_dataset(dir: &Path) -> bool {
    dir.is_dir() && dir.join("meta.toml").is_file()
}

/// Start time of every sweep of a limot dataset: `kitti/times.txt` when the
/// KITTI-style copy exists, else `index · sweep_duration_s` (the simulator
/// starts sweep `i` at that time).
pub fn dataset_frame_times(dataset: &limot_sim::record::Dataset) -> Result<Vec<f64>> {
    let times_path = dataset.dir.join("kitti").join("times.txt");
    if times_path.is_file() {
        let times = read_times(&times_path)?;
        if times.len() != dataset.frame_count() {
            return Err(EvaluateError::Input {
                path: times_path,
                why: format!(
                    "{} times but the dataset has {} frames",
                    times.len(),
                    dataset.frame_count()
                ),
            });
        }
        return Ok(times);
    }
    let dt = dataset.meta.sweep_duration_s;
    Ok((0..dataset.frame_count()).map(|i| i as f64 * dt).collect())
}
