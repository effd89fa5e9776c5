//! `limot eval ego`: an estimated ego trajectory file against ground truth.
//!
//! Ground truth (`--truth`) is one of
//! - a limot dataset directory (`meta.toml`): `gt/ego.csv`, `t_world_lidar` at
//!   the IMU rate; its frames are the sweep starts;
//! - a KITTI-style directory (`oxts/NNNN.txt` + `calib/NNNN.txt`, e.g. the
//!   `kitti/` copy of a limot dataset or KITTI tracking `training/`): IMU poses
//!   from OXTS with the devkit's `oxts_to_poses`, turned into LiDAR poses with
//!   `Tr_imu_velo`: `t_world_lidar = t_world_imu · t_velo_imu⁻¹`; times from
//!   `times.txt` beside `oxts/` when present, else 0.1 s steps (KITTI's 10 Hz);
//! - a pose file (TUM, or KITTI with `--truth-times` or 0.1 s steps).
//!
//! The estimate (`--estimate`) is a TUM file (its own timestamps) or a KITTI
//! pose file (one pose per frame): its times come from `--times`, else from the
//! truth's frames (sweep starts of a limot dataset, the KITTI directory's times,
//! a KITTI truth pose file's times), which must then have as many entries.
//!
//! Poses are associated by timestamp within `max_dt_s`, aligned with Umeyama
//! (SE(3) by default; the estimate may start in any frame, e.g. KISS-ICP's
//! first-scan frame) and scored with [`crate::metrics::ate`] and
//! [`crate::metrics::rpe`].
//!
//! Straight and static paths: the alignment's rotation is completed from the
//! orientations where positions leave it free ([`crate::metrics::complete_alignment`]).

use super::json::{Json, obj};
use super::{EvaluateError, Result, dataset_frame_times, is_limot_dataset, read_times};
use crate::io::kitti::calib::Calib;
use crate::io::kitti::oxts::{oxts_to_poses, read_oxts};
use crate::io::kitti::poses::{parse_kitti_poses, parse_tum};
use crate::io::kitti::{KITTI_FRAME_PERIOD_S, LineCtx, content_lines, read_text, sequence_file};
use crate::metrics::{
    AlignMode, AteResult, EvalError, RpeDelta, RpeResult, associate, ate_with, rpe,
};
use crate::metrics::{AlignmentFix, complete_alignment};
use crate::report::{Cell, Table};
use limot_sim::record::Dataset;
use nalgebra::Isometry3;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// Pose file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PoseFormat {
    /// `t x y z qx qy qz qw` per line.
    Tum,
    /// 12 numbers per line (top 3x4 of the pose, row-major), no times.
    Kitti,
}

impl FromStr for PoseFormat {
    type Err = EvaluateError;
    fn from_str(s: &str) -> Result<PoseFormat> {
        match s.to_ascii_lowercase().as_str() {
            "tum" => Ok(PoseFormat::Tum),
            "kitti" => Ok(PoseFormat::Kitti),
            _ => Err(EvaluateError::Argument(format!(
                "pose format `{s}`: expected tum or kitti"
            ))),
        }
    }
}

/// Parses `--rpe-delta`: `N` frames (`1`, `10`) or `Xm` metres (`10m`, `2.5m`).
/// A metre delta gets a path tolerance of 10 % of it (evo's default relative
/// tolerance), used only with all pairs.
///
/// # Errors
///
/// [`EvaluateError::Argument`] unless the text is `N` (frames, N >= 1) or `Xm`
/// (metres, X > 0).
pub fn parse_rpe_delta(s: &str) -> Result<RpeDelta> {
    let bad = |why: &str| EvaluateError::Argument(format!("--rpe-delta `{s}`: {why}"));
    let s_trim = s.trim();
    if let Some(m) = s_trim.strip_suffix('m') {
        let delta_m: f64 = m
            .trim()
            .parse()
            .map_err(|_| bad("not a number of metres"))?;
        if !(delta_m > 0.0 && delta_m.is_finite()) {
            return Err(bad("must be > 0"));
        }
        return Ok(RpeDelta::Meters {
            delta_m,
            path_tolerance_m: 0.1 * delta_m,
        });
    }
    let frames: usize = s_trim
        .parse()
        .map_err(|_| bad("expected a frame count (1) or metres (10m)"))?;
    if frames == 0 {
        return Err(bad("frame delta must be >= 1"));
    }
    Ok(RpeDelta::Frames(frames))
}

/// How `limot eval ego` reads and scores its inputs.
#[derive(Debug, Clone, PartialEq)]
pub struct EgoEvalOptions {
    /// Estimate format; `None` detects it from the column count (8 or 12).
    pub estimate_format: Option<PoseFormat>,
    /// Times of a KITTI estimate, one per pose.
    pub estimate_times: Option<PathBuf>,
    /// Truth pose file format; `None` detects it.
    pub truth_format: Option<PoseFormat>,
    /// Times of a KITTI truth pose file.
    pub truth_times: Option<PathBuf>,
    /// KITTI sequence number in a KITTI-style truth directory.
    pub sequence: u32,
    /// How the estimate is aligned to the truth.
    pub align: AlignMode,
    /// Largest time difference of an associated pose pair, s.
    pub max_dt_s: f64,
    /// The RPE's pose-pair spacing.
    pub rpe_delta: RpeDelta,
    /// RPE over every pair at the spacing rather than consecutive ones.
    pub rpe_all_pairs: bool,
}

impl Default for EgoEvalOptions {
    fn default() -> Self {
        EgoEvalOptions {
            estimate_format: None,
            estimate_times: None,
            truth_format: None,
            truth_times: None,
            sequence: 0,
            align: AlignMode::Se3,
            max_dt_s: 0.01,
            rpe_delta: RpeDelta::Frames(1),
            rpe_all_pairs: false,
        }
    }
}

/// A timestamped trajectory read from disk.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// The file or directory it came from.
    pub path: PathBuf,
    /// What was read, for reports ("limot dataset gt/ego.csv", ...).
    pub kind: String,
    /// Timestamped poses (`t_world_lidar`), by time.
    pub poses: Vec<(f64, Isometry3<f64>)>,
    /// Times of the source's frames (sweeps) when it has frames; a KITTI
    /// estimate without its own times takes these.
    pub frame_times: Option<Vec<f64>>,
}

/// Detects the format of a pose file from its first data line (8 columns TUM,
/// 12 KITTI; `#` comments skipped).
///
/// # Errors
///
/// [`EvaluateError::Input`] when the text is neither TUM nor KITTI poses.
pub fn detect_pose_format(text: &str, path: &Path) -> Result<PoseFormat> {
    let first = content_lines(text).find(|(_, l)| !l.trim_start().starts_with('#'));
    let Some((line_no, line)) = first else {
        return Err(EvaluateError::Input {
            path: path.to_path_buf(),
            why: "no poses in the file".into(),
        });
    };
    match line.split_whitespace().count() {
        8 => Ok(PoseFormat::Tum),
        12 => Ok(PoseFormat::Kitti),
        n => Err(LineCtx::new(path, line_no)
            .column_count("8 (TUM) or 12 (KITTI)", n)
            .into()),
    }
}

/// Reads a pose file. KITTI poses get `times` (one per pose), which must be given.
fn read_pose_file(
    path: &Path,
    format: Option<PoseFormat>,
    times: impl FnOnce(usize) -> Result<Vec<f64>>,
) -> Result<Trajectory> {
    let text = read_text(path)?;
    let format = match format {
        Some(f) => f,
        None => detect_pose_format(&text, path)?,
    };
    match format {
        PoseFormat::Tum => {
            let poses = parse_tum(&text, path)?;
            Ok(Trajectory {
                path: path.to_path_buf(),
                kind: "TUM pose file".into(),
                poses: poses.iter().map(|p| (p.t_s, p.pose)).collect(),
                frame_times: None,
            })
        }
        PoseFormat::Kitti => {
            let poses = parse_kitti_poses(&text, path)?;
            let times = times(poses.len())?;
            Ok(Trajectory {
                path: path.to_path_buf(),
                kind: "KITTI pose file".into(),
                poses: times.iter().copied().zip(poses).collect(),
                frame_times: Some(times),
            })
        }
    }
}

/// Reads a times file and checks it has one entry per pose.
fn times_for(times_path: &Path, poses_path: &Path, n_poses: usize) -> Result<Vec<f64>> {
    let times = read_times(times_path)?;
    if times.len() != n_poses {
        return Err(EvaluateError::TimesLength {
            poses_path: poses_path.to_path_buf(),
            poses: n_poses,
            times_path: times_path.to_path_buf(),
            times: times.len(),
        });
    }
    Ok(times)
}

fn kitti_steps(n: usize) -> Vec<f64> {
    (0..n).map(|i| i as f64 * KITTI_FRAME_PERIOD_S).collect()
}

/// LiDAR poses of a KITTI-style directory (see the module docs).
fn read_kitti_dir(dir: &Path, sequence: u32) -> Result<Trajectory> {
    let oxts_path = sequence_file(&dir.join("oxts"), sequence);
    let calib_path = sequence_file(&dir.join("calib"), sequence);
    let records = read_oxts(&oxts_path)?;
    if records.is_empty() {
        return Err(EvaluateError::Input {
            path: oxts_path,
            why: "no OXTS records".into(),
        });
    }
    let calib = Calib::read(&calib_path)?;
    let t_imu_velo = calib.t_velo_imu.inverse();
    let poses: Vec<Isometry3<f64>> = oxts_to_poses(&records)
        .iter()
        .map(|t_world_imu| t_world_imu * t_imu_velo)
        .collect();
    let times_path = dir.join("times.txt");
    let (times, kind) = if times_path.is_file() {
        (
            times_for(&times_path, &oxts_path, poses.len())?,
            "KITTI OXTS (times.txt)",
        )
    } else {
        (kitti_steps(poses.len()), "KITTI OXTS (0.1 s steps)")
    };
    Ok(Trajectory {
        path: oxts_path,
        kind: kind.into(),
        poses: times.iter().copied().zip(poses).collect(),
        frame_times: Some(times),
    })
}

/// Reads the ground-truth trajectory (see the module docs for the sources).
///
/// # Errors
///
/// [`EvaluateError`] when the truth cannot be read or has no poses.
pub fn load_truth(path: &Path, opts: &EgoEvalOptions) -> Result<Trajectory> {
    if is_limot_dataset(path) {
        let dataset = Dataset::open(path)?;
        let truth = dataset.ego_truth()?;
        return Ok(Trajectory {
            path: path.join("gt").join("ego.csv"),
            kind: "limot dataset ground truth (t_world_lidar)".into(),
            poses: truth.iter().map(|e| (e.t_s, e.t_world_lidar)).collect(),
            frame_times: Some(dataset_frame_times(&dataset)?),
        });
    }
    if path.is_dir() {
        if path.join("oxts").is_dir() {
            return read_kitti_dir(path, opts.sequence);
        }
        return Err(EvaluateError::Input {
            path: path.to_path_buf(),
            why: "neither a limot dataset (meta.toml) nor a KITTI-style directory (oxts/)".into(),
        });
    }
    read_pose_file(path, opts.truth_format, |n| match &opts.truth_times {
        Some(t) => times_for(t, path, n),
        None => Ok(kitti_steps(n)),
    })
}

/// Reads the estimated trajectory; a KITTI estimate takes `--times`, else the
/// truth's frame times.
///
/// # Errors
///
/// [`EvaluateError`] when the estimate cannot be read or its times do not match.
pub fn load_estimate(path: &Path, truth: &Trajectory, opts: &EgoEvalOptions) -> Result<Trajectory> {
    read_pose_file(path, opts.estimate_format, |n| {
        if let Some(t) = &opts.estimate_times {
            return times_for(t, path, n);
        }
        match &truth.frame_times {
            Some(times) if times.len() == n => Ok(times.clone()),
            Some(times) => Err(EvaluateError::Input {
                path: path.to_path_buf(),
                why: format!(
                    "KITTI pose file with {n} poses, but the truth {} has {} frames to take \
                     times from; pass --times",
                    truth.path.display(),
                    times.len()
                ),
            }),
            None => Err(EvaluateError::Input {
                path: path.to_path_buf(),
                why:
                    "a KITTI pose file has no timestamps and the truth has no frames; pass --times"
                        .into(),
            }),
        }
    })
}

/// ATE and RPE of one estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct EgoEvaluation {
    /// The truth's path.
    pub truth: PathBuf,
    /// What the truth is (dataset, KITTI directory, pose file).
    pub truth_kind: String,
    /// The estimate's path.
    pub estimate: PathBuf,
    /// The estimate's format.
    pub estimate_kind: String,
    /// The alignment used.
    pub align: AlignMode,
    /// Association tolerance, s.
    pub max_dt_s: f64,
    /// ATE after alignment.
    pub ate: AteResult,
    /// The RPE's spacing.
    pub rpe_delta: RpeDelta,
    /// `None` when the trajectory is too short for the delta.
    pub rpe: Option<RpeResult>,
    /// How the alignment's rotation was fixed where positions do not determine it.
    pub alignment_fix: AlignmentFix,
}

fn time_range(traj: &[(f64, Isometry3<f64>)]) -> (f64, f64) {
    traj.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (t, _)| {
            (lo.min(*t), hi.max(*t))
        })
}

/// Scores an estimate against the truth (both already read).
///
/// # Errors
///
/// [`EvaluateError::NoOverlap`] when too few poses associate; [`EvaluateError::Eval`] when a metric fails.
pub fn evaluate_trajectories(
    truth: &Trajectory,
    estimate: &Trajectory,
    opts: &EgoEvalOptions,
) -> Result<EgoEvaluation> {
    let pairs = associate(&estimate.poses, &truth.poses, opts.max_dt_s)?;
    let need = if opts.align == AlignMode::None { 1 } else { 2 };
    if pairs.len() < need {
        let (est_first_s, est_last_s) = time_range(&estimate.poses);
        let (truth_first_s, truth_last_s) = time_range(&truth.poses);
        return Err(EvaluateError::NoOverlap {
            estimate: estimate.path.clone(),
            truth: truth.path.clone(),
            est_first_s,
            est_last_s,
            est_n: estimate.poses.len(),
            truth_first_s,
            truth_last_s,
            truth_n: truth.poses.len(),
            pairs: pairs.len(),
            need,
            max_dt_s: opts.max_dt_s,
        });
    }
    let mut ate = ate_with(&estimate.poses, &truth.poses, opts.max_dt_s, opts.align)?;
    let mut alignment_fix = AlignmentFix::None;
    if opts.align != AlignMode::None
        && let Some((alignment, fix)) =
            complete_alignment(&estimate.poses, &truth.poses, &pairs, &ate.alignment)
    {
        // Score the estimate moved by the completed alignment without re-aligning.
        let moved: Vec<(f64, Isometry3<f64>)> = estimate
            .poses
            .iter()
            .map(|(t, p)| (*t, alignment.transform_pose(p)))
            .collect();
        ate = ate_with(&moved, &truth.poses, opts.max_dt_s, AlignMode::None)?;
        ate.alignment = alignment;
        alignment_fix = fix;
    }
    let rpe = match rpe(
        &estimate.poses,
        &truth.poses,
        opts.max_dt_s,
        opts.rpe_delta,
        opts.rpe_all_pairs,
    ) {
        Ok(r) => Some(r),
        Err(EvalError::TooFew { .. }) => None,
        Err(e) => return Err(e.into()),
    };
    Ok(EgoEvaluation {
        truth: truth.path.clone(),
        truth_kind: truth.kind.clone(),
        estimate: estimate.path.clone(),
        estimate_kind: estimate.kind.clone(),
        align: opts.align,
        max_dt_s: opts.max_dt_s,
        ate,
        rpe_delta: opts.rpe_delta,
        rpe,
        alignment_fix,
    })
}

/// Reads both trajectories and scores the estimate.
///
/// # Errors
///
/// As [`load_truth`], [`load_estimate`] and [`evaluate_trajectories`].
pub fn evaluate_ego(truth: &Path, estimate: &Path, opts: &EgoEvalOptions) -> Result<EgoEvaluation> {
    let truth = load_truth(truth, opts)?;
    let estimate = load_estimate(estimate, &truth, opts)?;
    evaluate_trajectories(&truth, &estimate, opts)
}

fn align_name(mode: AlignMode) -> &'static str {
    match mode {
        AlignMode::None => "none",
        AlignMode::Se3 => "SE(3)",
        AlignMode::Sim3 => "Sim(3)",
    }
}

fn delta_name(delta: RpeDelta) -> String {
    match delta {
        RpeDelta::Frames(1) => "1 frame".into(),
        RpeDelta::Frames(n) => format!("{n} frames"),
        RpeDelta::Meters { delta_m, .. } => format!("{delta_m} m"),
    }
}

impl EgoEvaluation {
    /// The headline: `ATE_T RMSE … m, ATE_R RMSE … rad (…)`.
    pub fn summary_line(&self) -> String {
        format!(
            "ATE_T RMSE {:.6} m, ATE_R RMSE {:.6} rad ({} pose pairs, alignment: {})",
            self.ate.ate_t_rmse_m,
            self.ate.ate_r_rmse_rad,
            self.ate.n,
            align_name(self.align)
        )
    }

    /// Why the alignment's rotation was completed from orientations, if it was.
    pub fn alignment_note(&self) -> Option<&'static str> {
        match self.alignment_fix {
            AlignmentFix::None => None,
            AlignmentFix::RollFromOrientations => Some(
                "the path is straight, so the alignment's rotation about it was taken from the \
                 orientations (Umeyama leaves it undetermined)",
            ),
            AlignmentFix::RotationFromOrientations => Some(
                "the positions do not move, so the alignment's rotation was taken from the \
                 orientations",
            ),
        }
    }

    /// Metric | RMSE | mean | median | max | n.
    ///
    /// # Errors
    ///
    /// [`EvaluateError::Report`] when the table cannot be built.
    pub fn table(&self) -> Result<Table> {
        let header = ["Metric", "RMSE", "mean", "median", "max", "n"]
            .map(String::from)
            .to_vec();
        let mut table = Table::new(
            format!("Ego trajectory (alignment: {})", align_name(self.align)),
            header,
        );
        for c in 1..5 {
            table.set_decimals(c, 6);
        }
        let a = &self.ate;
        table.push_row(vec![
            Cell::from("ATE_T [m]"),
            a.ate_t_rmse_m.into(),
            a.mean_m.into(),
            a.median_m.into(),
            a.max_m.into(),
            a.n.into(),
        ])?;
        table.push_row(vec![
            Cell::from("ATE_T along the path [m]"),
            a.along_rmse_m.into(),
            Cell::Missing,
            Cell::Missing,
            Cell::Missing,
            a.n.into(),
        ])?;
        table.push_row(vec![
            Cell::from("ATE_R [rad]"),
            a.ate_r_rmse_rad.into(),
            Cell::Missing,
            Cell::Missing,
            Cell::Missing,
            a.n.into(),
        ])?;
        let delta = delta_name(self.rpe_delta);
        match &self.rpe {
            Some(r) => {
                table.push_row(vec![
                    Cell::from(format!("RPE_t [m] per {delta}")),
                    r.trans_rmse_m.into(),
                    r.trans_mean_m.into(),
                    r.trans_median_m.into(),
                    r.trans_max_m.into(),
                    r.n_pairs.into(),
                ])?;
                table.push_row(vec![
                    Cell::from(format!("RPE_R [rad] per {delta}")),
                    r.rot_rmse_rad.into(),
                    r.rot_mean_rad.into(),
                    r.rot_median_rad.into(),
                    r.rot_max_rad.into(),
                    r.n_pairs.into(),
                ])?;
            }
            None => {
                let mut row = vec![Cell::from(format!("RPE per {delta} (too short)"))];
                row.extend(std::iter::repeat_n(Cell::Missing, 4));
                row.push(0usize.into());
                table.push_row(row)?;
            }
        }
        Ok(table)
    }

    /// Markdown: sources, the headline and the table.
    ///
    /// # Errors
    ///
    /// [`EvaluateError::Report`] when a table cannot be built.
    pub fn to_markdown(&self) -> Result<String> {
        let mut out = format!(
            "# limot eval ego\n\n- truth: `{}` ({})\n- estimate: `{}` ({})\n- association: max_dt = {} s\n",
            self.truth.display(),
            self.truth_kind,
            self.estimate.display(),
            self.estimate_kind,
            self.max_dt_s
        );
        if let Some(note) = self.alignment_note() {
            out.push_str(&format!("- note: {note}\n"));
        }
        out.push_str(&format!("\n{}\n\n", self.summary_line()));
        out.push_str(&self.table()?.to_markdown()?);
        Ok(out)
    }

    /// The evaluation as a JSON summary.
    pub fn to_json(&self) -> Json {
        let a = &self.ate;
        let rpe = match &self.rpe {
            Some(r) => obj([
                ("trans_rmse_m", r.trans_rmse_m.into()),
                ("trans_mean_m", r.trans_mean_m.into()),
                ("trans_median_m", r.trans_median_m.into()),
                ("trans_max_m", r.trans_max_m.into()),
                ("rot_rmse_rad", r.rot_rmse_rad.into()),
                ("rot_mean_rad", r.rot_mean_rad.into()),
                ("rot_median_rad", r.rot_median_rad.into()),
                ("rot_max_rad", r.rot_max_rad.into()),
                ("n_pairs", r.n_pairs.into()),
            ]),
            None => Json::Null,
        };
        let (delta_frames, delta_m) = match self.rpe_delta {
            RpeDelta::Frames(n) => (Json::from(n), Json::Null),
            RpeDelta::Meters { delta_m, .. } => (Json::Null, Json::from(delta_m)),
        };
        obj([
            ("truth", self.truth.display().to_string().into()),
            ("truth_kind", self.truth_kind.clone().into()),
            ("estimate", self.estimate.display().to_string().into()),
            ("estimate_kind", self.estimate_kind.clone().into()),
            ("alignment", align_name(self.align).into()),
            ("alignment_degenerate", a.alignment.degenerate.into()),
            (
                "alignment_fix",
                match self.alignment_fix {
                    AlignmentFix::None => "none",
                    AlignmentFix::RollFromOrientations => "roll_from_orientations",
                    AlignmentFix::RotationFromOrientations => "rotation_from_orientations",
                }
                .into(),
            ),
            ("alignment_scale", a.alignment.scale.into()),
            ("max_dt_s", self.max_dt_s.into()),
            (
                "ate",
                obj([
                    ("t_rmse_m", a.ate_t_rmse_m.into()),
                    ("r_rmse_rad", a.ate_r_rmse_rad.into()),
                    ("t_mean_m", a.mean_m.into()),
                    ("t_median_m", a.median_m.into()),
                    ("t_max_m", a.max_m.into()),
                    (
                        "t_along_rmse_m",
                        a.along_rmse_m.map_or(Json::Null, Json::from),
                    ),
                    ("n", a.n.into()),
                ]),
            ),
            (
                "rpe_delta",
                obj([("frames", delta_frames), ("meters", delta_m)]),
            ),
            ("rpe", rpe),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, Vector3};

    fn traj(path: &str, poses: Vec<(f64, Isometry3<f64>)>) -> Trajectory {
        Trajectory {
            path: PathBuf::from(path),
            kind: "test".into(),
            poses,
            frame_times: None,
        }
    }

    /// Along x, with a tiny lateral wiggle (λ₂/λ₁ ≈ 1e-10) and changing attitude.
    fn straight_truth(wiggle_m: f64) -> Vec<(f64, Isometry3<f64>)> {
        (0..50)
            .map(|i| {
                let f = i as f64;
                let pose = Isometry3::new(
                    Vector3::new(2.0 * f, wiggle_m * (0.7 * f).sin(), 0.0),
                    Vector3::new(
                        0.02 * (0.3 * f).sin(),
                        0.01 * f.cos(),
                        0.05 * (0.2 * f).sin(),
                    ),
                );
                (0.1 * f, pose)
            })
            .collect()
    }

    #[test]
    fn straight_and_static_paths_take_the_rotation_from_orientations() {
        let offset = Isometry3::new(Vector3::new(5.0, -3.0, 1.0), Vector3::new(0.3, -0.2, 1.0));
        let opts = EgoEvalOptions::default();
        for (truth, fix) in [
            (straight_truth(1e-4), AlignmentFix::RollFromOrientations),
            (straight_truth(3.0), AlignmentFix::None),
        ] {
            let est: Vec<_> = truth.iter().map(|(t, p)| (*t, offset * p)).collect();
            let r = evaluate_trajectories(&traj("t", truth), &traj("e", est), &opts).unwrap();
            assert_eq!(r.alignment_fix, fix);
            assert!(r.ate.ate_t_rmse_m < 1e-9, "{}", r.ate.ate_t_rmse_m);
            assert!(r.ate.ate_r_rmse_rad < 1e-9, "{}", r.ate.ate_r_rmse_rad);
        }
        // Standing still: positions say nothing about the rotation.
        let still: Vec<_> = straight_truth(0.0)
            .into_iter()
            .map(|(t, p)| {
                (
                    t,
                    Isometry3::from_parts(Translation3::new(1.0, 2.0, 3.0), p.rotation),
                )
            })
            .collect();
        let est: Vec<_> = still.iter().map(|(t, p)| (*t, offset * p)).collect();
        let r = evaluate_trajectories(&traj("t", still.clone()), &traj("e", est.clone()), &opts)
            .unwrap();
        assert_eq!(r.alignment_fix, AlignmentFix::RotationFromOrientations);
        assert!(r.ate.ate_t_rmse_m < 1e-9 && r.ate.ate_r_rmse_rad < 1e-9);
        // Standing still with an estimate that jitters by millimetres: the
        // positions' rotation would be noise (Umeyama gave ATE_R ~3 rad on a
        // standing KITTI twin); the orientations give the exact one.
        let jittered: Vec<_> = est
            .iter()
            .enumerate()
            .map(|(i, (t, p))| {
                let f = i as f64;
                let jitter = Vector3::new(
                    0.003 * (1.7 * f).sin(),
                    0.002 * (2.3 * f).cos(),
                    0.001 * (0.9 * f).sin(),
                );
                (
                    *t,
                    Isometry3::from_parts(
                        Translation3::from(p.translation.vector + jitter),
                        p.rotation,
                    ),
                )
            })
            .collect();
        let r =
            evaluate_trajectories(&traj("t", still.clone()), &traj("e", jittered), &opts).unwrap();
        assert_eq!(r.alignment_fix, AlignmentFix::RotationFromOrientations);
        assert!(r.ate.ate_r_rmse_rad < 1e-9, "{}", r.ate.ate_r_rmse_rad);
        assert!(r.ate.ate_t_rmse_m < 0.005, "{}", r.ate.ate_t_rmse_m);
        // A yaw error that the roll fix must not absorb (it is about z, not x).
        let truth = straight_truth(1e-4);
        let est: Vec<_> = truth
            .iter()
            .map(|(t, p)| {
                (
                    *t,
                    p * Isometry3::new(Vector3::zeros(), Vector3::new(0.0, 0.0, 0.01)),
                )
            })
            .collect();
        let r = evaluate_trajectories(&traj("t", truth), &traj("e", est), &opts).unwrap();
        assert!(
            (r.ate.ate_r_rmse_rad - 0.01).abs() < 1e-3,
            "{}",
            r.ate.ate_r_rmse_rad
        );
    }

    #[test]
    fn rpe_delta_parses_frames_and_metres() {
        assert_eq!(parse_rpe_delta("1").unwrap(), RpeDelta::Frames(1));
        assert_eq!(
            parse_rpe_delta("10m").unwrap(),
            RpeDelta::Meters {
                delta_m: 10.0,
                path_tolerance_m: 1.0
            }
        );
        for bad in ["0", "-1m", "abc", "m", "nanm"] {
            assert!(parse_rpe_delta(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn format_detection_names_file_and_line() {
        let p = Path::new("e.txt");
        assert_eq!(
            detect_pose_format("# c\n\n0 1 2 3 0 0 0 1\n", p).unwrap(),
            PoseFormat::Tum
        );
        assert_eq!(
            detect_pose_format("1 0 0 0 0 1 0 0 0 0 1 0\n", p).unwrap(),
            PoseFormat::Kitti
        );
        let err = detect_pose_format("\n1 2 3\n", p).unwrap_err().to_string();
        assert!(err.contains("e.txt:2"), "{err}");
        assert!(detect_pose_format("# only\n", p).is_err());
    }
}
