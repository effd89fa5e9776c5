//! `limot eval`: scores result FILES against ground truth, so external tools
//! (e.g. KISS-ICP run on the KITTI-style copy of a simulated dataset) and,
//! later, the variant runner are evaluated the same way.
//!
//! - [`ego`]: an estimated ego trajectory (TUM or KITTI pose file) against a
//!   limot dataset, a KITTI-style directory (OXTS + calib) or a pose file →
//!   ATE_T / ATE_R after alignment and RPE.
//! - [`kitti_sequence`]: a run on a KITTI tracking sequence against its OXTS
//!   poses and label_02 (ego ATE/RPE, Car CLEAR-MOT in 2D and 3D, object ATE;
//!   the filter judged by the labelled boxes, [`kitti_filter`]).
//! - [`tracks`]: KITTI-format tracking results (label_02 lines + score) against
//!   the ground-truth boxes of a limot dataset → CLEAR-MOT at 3D and BEV IoU,
//!   TP % and per-object ATE.
//!
//! This module is glue between the file readers ([`crate::io::kitti`],
//! [`limot_sim::record`]), the metrics ([`crate::metrics`]) and the tables
//! ([`crate::report::table`]); it holds no metric of its own.

pub(crate) mod ego;
pub(crate) mod filtering;
pub(crate) mod json;
pub(crate) mod kitti_filter;
pub(crate) mod kitti_sequence;
pub(crate) mod tracks;

use crate::io::kitti::KittiError;
use crate::metrics::EvalError;
use crate::report::ReportError;
use limot_sim::record::RecordError;
use std::path::{Path, PathBuf};

/// Why an evaluation could not be done.
#[derive(Debug, thiserror::Error)]
pub enum EvaluateError {
    #[error(transparent)]
    /// A KITTI file could not be read.
    Kitti(#[from] KittiError),
    #[error(transparent)]
    /// A limot dataset could not be read.
    Record(#[from] RecordError),
    #[error(transparent)]
    /// A metric could not be computed.
    Eval(#[from] EvalError),
    #[error(transparent)]
    /// A table could not be built.
    Report(#[from] ReportError),
    #[error(transparent)]
    /// The estimator run failed.
    Run(#[from] Box<crate::run::RunError>),
    #[error("{}: {source}", path.display())]
    /// A file could not be read or written.
    Io {
        /// The file.
        path: PathBuf,
        #[source]
        /// The cause.
        source: std::io::Error,
    },
    #[error("{}: {why}", path.display())]
    /// An input is missing or malformed.
    Input {
        /// The input.
        path: PathBuf,
        /// What is wrong with it.
        why: String,
    },
    #[error(
        "timestamps do not overlap: estimate {} covers [{est_first_s}, {est_last_s}] s ({est_n} poses), \
         truth {} covers [{truth_first_s}, {truth_last_s}] s ({truth_n} poses); only {pairs} pose pairs \
         are within max_dt = {max_dt_s} s of each other, need at least {need} \
         (check the time base, or pass --times / --max-dt)",
        estimate.display(),
        truth.display()
    )]
    /// Too few estimate poses lie within `max_dt_s` of a truth pose.
    NoOverlap {
        /// The estimate file.
        estimate: PathBuf,
        /// The truth.
        truth: PathBuf,
        /// First estimate time, s.
        est_first_s: f64,
        /// Last estimate time, s.
        est_last_s: f64,
        /// Estimate poses.
        est_n: usize,
        /// First truth time, s.
        truth_first_s: f64,
        /// Last truth time, s.
        truth_last_s: f64,
        /// Truth poses.
        truth_n: usize,
        /// Pairs associated.
        pairs: usize,
        /// Pairs needed.
        need: usize,
        /// Association tolerance, s.
        max_dt_s: f64,
    },
    #[error(
        "{} has {poses} poses but the times {} has {times} entries",
        poses_path.display(),
        times_path.display()
    )]
    /// A times file does not have one entry per pose.
    TimesLength {
        /// The pose file.
        poses_path: PathBuf,
        /// Its pose count.
        poses: usize,
        /// The times file.
        times_path: PathBuf,
        /// Its entry count.
        times: usize,
    },
    #[error("invalid argument: {0}")]
    /// A command-line argument is invalid.
    Argument(String),
}

pub type Result<T> = std::result::Result<T, EvaluateError>;

pub use crate::io::kitti::poses::read_times;

/// Whether `dir` is a limot dataset (it holds `meta.toml`).
pub fn is_limot_dataset(dir: &Path) -> bool {
    dir.is_dir() && dir.join("meta.toml").is_file()
}

/// Start time of every sweep of a limot dataset: `kitti/times.txt` when the
/// KITTI-style copy exists, else `index · sweep_duration_s` (the simulator
/// starts sweep `i` at that time).
///
/// # Errors
///
/// [`EvaluateError`] when the dataset cannot be read.
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
