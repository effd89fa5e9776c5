//! `limot eval`: scores result FILES against ground truth, so external tools
//! (e.g. KISS-ICP run on the KITTI-style copy of a simulated dataset) and,
//! later, the variant runner are evaluated the same way.
//!
//! - [`ego`]: an estimated ego trajectory (TUM or KITTI pose file) against a
//!   limot dataset, a KITTI-style directory (OXTS + calib) or a pose file →
//!   ATE_T / ATE_R after alignment and RPE.
//! - [`tracks`]: KITTI-format tracking results (label_02 lines + score) against
//!   the ground-truth boxes of a limot dataset → CLEAR-MOT at 3D and BEV IoU,
//!   TP % and per-object ATE.
//!
//! This module is glue between the file readers ([`crate::kitti`],
//! [`limot_sim::record`]), the metrics ([`crate::eval`]) and the tables
//! ([`crate::report::table`]); it holds no metric of its own.

pub mod ego;
pub mod filtering;
pub mod json;
pub mod tracks;

use crate::eval::EvalError;
use crate::kitti::{KittiError, LineCtx, content_lines, read_text};
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

/// Parses a times file (KITTI `times.txt`: one time in seconds per line, the
/// first column is used). Times must be finite and non-decreasing.
pub fn parse_times(text: &str, path: &Path) -> std::result::Result<Vec<f64>, KittiError> {
    let mut times: Vec<f64> = Vec::new();
    for (line_no, line) in content_lines(text) {
        let ctx = LineCtx::new(path, line_no);
        let token = line.split_whitespace().next().unwrap_or_default();
        let t_s = ctx.f64(token, 1, "t")?;
        if let Some(&prev) = times.last()
            && t_s < prev
        {
            return Err(ctx.field_error(
                1,
                "t",
                format!("{t_s} is before the previous time {prev}"),
            ));
        }
        times.push(t_s);
    }
    Ok(times)
}

/// Reads a times file (see [`parse_times`]).
pub fn read_times(path: &Path) -> std::result::Result<Vec<f64>, KittiError> {
    parse_times(&read_text(path)?, path)
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_parse_and_errors_name_the_line() {
        let path = Path::new("times.txt");
        let t = parse_times("0.000000e+00\n1.000000e-01\n\n2.0e-01 extra\n", path).unwrap();
        assert_eq!(t, vec![0.0, 0.1, 0.2]);
        let err = parse_times("0\n0.1\nabc\n", path).unwrap_err().to_string();
        assert!(err.contains("times.txt:3"), "{err}");
        let err = parse_times("0\n0.2\n0.1\n", path).unwrap_err().to_string();
        assert!(
            err.contains("times.txt:3") && err.contains("before"),
            "{err}"
        );
    }
}
