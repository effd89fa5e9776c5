//! `limot realism`: the realism statistics ([`crate::metrics::realism`]) of one
//! sequence read through the KITTI tracking layout (a KITTI `training`
//! directory, a limot dataset's `kitti/` copy, or the dataset itself), and
//! the report files `realism.json` and `realism.md`, optionally beside a
//! reference sequence (real KITTI) with each statistic's ratio to it.
//!
//! Scans are read as the estimator reads them
//! ([`RawDrive::open_tracking_sequence`]: rings from KITTI's point order or
//! the laser elevations, KITTI's elevation correction on KITTI's own scans);
//! the attitudes are the OXTS truth: `t_world_lidar` from
//! [`lidar_poses`], turned into the gravity-aligned frame of the first OXTS
//! record; the vehicle frame is the IMU (OXTS) frame of `calib/SSSS.txt`.

use crate::cli::frame_progress_bar;
use crate::experiments::lidar_poses;
use crate::io::kitti::KittiError;
use crate::io::kitti::calib::Calib;
use crate::io::kitti::raw::RawDrive;
use crate::io::kitti::sequence_file;
use crate::metrics::EvalError;
use crate::metrics::{
    RealismAccumulator, RealismConfig, RealismStats, StatComparison, compare_realism,
};
use nalgebra::{Rotation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Why the realism statistics could not be computed or written.
#[derive(Debug, thiserror::Error)]
pub enum RealismError {
    #[error(transparent)]
    /// A KITTI file could not be read.
    Kitti(#[from] KittiError),
    #[error("{}: {source}", path.display())]
    /// A statistic could not be computed.
    Eval {
        /// The sequence directory.
        path: PathBuf,
        #[source]
        /// The cause.
        source: EvalError,
    },
    #[error("{}: {why}", path.display())]
    /// An input is missing or malformed.
    Input {
        /// The input.
        path: PathBuf,
        /// What is wrong with it.
        why: String,
    },
    #[error("{}: {source}", path.display())]
    /// A file could not be read or written.
    Io {
        /// The file.
        path: PathBuf,
        #[source]
        /// The cause.
        source: std::io::Error,
    },
}

/// One analysed sequence: where it came from and its statistics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SequenceRealism {
    /// The KITTI-layout directory that was read.
    pub kitti_dir: PathBuf,
    /// Sequence number.
    pub sequence: u32,
    /// Its statistics.
    pub stats: RealismStats,
}

/// The contents of `realism.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RealismReport {
    /// The analysed dataset.
    pub dataset: SequenceRealism,
    /// The reference (e.g. a real KITTI sequence), when given.
    pub reference: Option<SequenceRealism>,
    /// Each scalar statistic beside the reference's (empty without one).
    pub comparison: Vec<StatComparison>,
}

/// The KITTI-layout directory of `path`: `path` itself when it has
/// `velodyne/`, else a limot dataset's `path/kitti`.
///
/// # Errors
///
/// [`RealismError::Input`] when the path is neither a limot dataset nor a KITTI-layout directory.
pub fn kitti_dir_of(path: &Path) -> Result<PathBuf, RealismError> {
    if !path.is_dir() {
        return Err(RealismError::Input {
            path: path.to_path_buf(),
            why: "not a directory".to_string(),
        });
    }
    if path.join("velodyne").is_dir() {
        return Ok(path.to_path_buf());
    }
    if path.join("kitti").join("velodyne").is_dir() {
        return Ok(path.join("kitti"));
    }
    Err(RealismError::Input {
        path: path.to_path_buf(),
        why: "neither a KITTI tracking directory (velodyne/, oxts/, calib/) nor a limot \
              dataset with its KITTI copy (kitti/)"
            .to_string(),
    })
}

/// The statistics of sequence `sequence` of `path` (see the module docs);
/// a per-frame progress bar when `progress`. Every error names the file.
///
/// # Errors
///
/// [`RealismError`] when a file cannot be read or a statistic computed.
pub fn analyze_sequence(
    path: &Path,
    sequence: u32,
    config: &RealismConfig,
    progress: bool,
) -> Result<SequenceRealism, RealismError> {
    let dir = kitti_dir_of(path)?;
    let drive = RawDrive::open_tracking_sequence(&dir, sequence)?;
    let calib_path = sequence_file(&dir.join("calib"), sequence);
    let calib = Calib::read(&calib_path)?;
    let oxts_path = sequence_file(&dir.join("oxts"), sequence);
    let Some(first) = drive.oxts.first() else {
        return Err(RealismError::Input {
            path: oxts_path,
            why: "no OXTS records: the sequence has no ground truth".to_string(),
        });
    };
    // oxts_to_poses is relative to the first record: its attitude makes it level
    let r_level_world = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(
        &first.record.rotation_enu_imu(),
    ));
    let poses = lidar_poses(&drive.poses(), &calib);
    let r_vehicle_lidar = calib.t_velo_imu.rotation.inverse();
    let mut acc = RealismAccumulator::new(config.clone()).map_err(|source| RealismError::Eval {
        path: dir.clone(),
        source,
    })?;
    let bar = frame_progress_bar(drive.num_scans(), progress, "realism");
    for (i, (frame, t_world_lidar)) in drive.velodyne.iter().zip(&poses).enumerate() {
        let scan = drive.scan(i)?;
        let r_level_lidar = r_level_world * t_world_lidar.rotation;
        acc.add_sweep(
            &scan.points,
            &r_level_lidar,
            &t_world_lidar.translation.vector,
            &r_vehicle_lidar,
        )
        .map_err(|source| RealismError::Eval {
            path: frame.path.clone(),
            source,
        })?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let stats = acc.finish().map_err(|source| RealismError::Eval {
        path: dir.join("velodyne").join(format!("{sequence:04}")),
        source,
    })?;
    Ok(SequenceRealism {
        kitti_dir: dir,
        sequence,
        stats,
    })
}

impl RealismReport {
    /// The report of `dataset`, beside `reference` when given.
    pub fn new(dataset: SequenceRealism, reference: Option<SequenceRealism>) -> RealismReport {
        let comparison = reference
            .as_ref()
            .map(|r| compare_realism(&dataset.stats, &r.stats))
            .unwrap_or_default();
        RealismReport {
            dataset,
            reference,
            comparison,
        }
    }

    /// The markdown table(s) of `realism.md`.
    pub fn to_markdown(&self) -> String {
        let mut md = String::from("# Realism statistics\n\n");
        let describe = |s: &SequenceRealism| {
            format!(
                "`{}` sequence {:04} ({} sweeps)",
                s.kitti_dir.display(),
                s.sequence,
                s.stats.sweeps
            )
        };
        let _ = writeln!(md, "Dataset: {}.", describe(&self.dataset));
        if let Some(r) = &self.reference {
            let _ = writeln!(md, "Reference: {}.", describe(r));
        }
        let _ = writeln!(
            md,
            "\nDefinitions: docs/realism.md. Changes are between consecutive sweeps.\n"
        );
        let stats = &self.dataset.stats;
        match &self.reference {
            Some(_) => {
                md.push_str("| statistic | unit | dataset | reference | ratio | within x2 |\n");
                md.push_str("|---|---|---|---|---|---|\n");
                for c in &self.comparison {
                    let _ = writeln!(
                        md,
                        "| {} | {} | {} | {} | {:.2} | {} |",
                        c.statistic,
                        c.unit,
                        fmt_value(c.value),
                        fmt_value(c.reference),
                        c.ratio,
                        if c.within_factor_2 { "yes" } else { "**no**" }
                    );
                }
                let within = self.comparison.iter().filter(|c| c.within_factor_2).count();
                let _ = writeln!(
                    md,
                    "\n{within} of {} statistics within a factor of 2 of the reference.",
                    self.comparison.len()
                );
            }
            None => {
                md.push_str("| statistic | unit | value |\n|---|---|---|\n");
                for (name, unit, value) in stats.scalars() {
                    let _ = writeln!(md, "| {name} | {unit} | {} |", fmt_value(value));
                }
            }
        }
        let [x, y, z] = stats.information_share_pct;
        let _ = writeln!(
            md,
            "\nInformation share x / y / z (vehicle frame): {x:.1} / {y:.1} / {z:.1} % \
             ({} points with a normal); ground pairs skipped: {}; sweep pairs standing \
             (not in the attitude and ground-ring figures): {}.",
            stats.information_points, stats.ground_pairs_skipped, stats.standing_pairs
        );
        if let Some(r) = &self.reference {
            let [x, y, z] = r.stats.information_share_pct;
            let _ = writeln!(
                md,
                "Reference: {x:.1} / {y:.1} / {z:.1} %; ground pairs skipped: {}; standing: {}.",
                r.stats.ground_pairs_skipped, r.stats.standing_pairs
            );
        }
        let reference = self.reference.as_ref().map(|r| &r.stats);
        histogram_table(
            &mut md,
            "range [m]",
            &stats.range_histogram,
            reference.map(|r| &r.range_histogram),
            1,
        );
        histogram_table(
            &mut md,
            "intensity",
            &stats.intensity_histogram,
            reference.map(|r| &r.intensity_histogram),
            2,
        );
        md
    }

    /// Writes `realism.json` and `realism.md` into `out` (created); returns their paths.
    ///
    /// # Errors
    ///
    /// [`RealismError::Io`] when a file cannot be written.
    pub fn write(&self, out: &Path) -> Result<(PathBuf, PathBuf), RealismError> {
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| RealismError::Io { path, source }
        };
        std::fs::create_dir_all(out).map_err(io(out))?;
        let json_path = out.join("realism.json");
        let json = serde_json::to_string_pretty(self).map_err(|e| RealismError::Input {
            path: json_path.clone(),
            why: e.to_string(),
        })?;
        std::fs::write(&json_path, json + "\n").map_err(io(&json_path))?;
        let md_path = out.join("realism.md");
        std::fs::write(&md_path, self.to_markdown()).map_err(io(&md_path))?;
        Ok((json_path, md_path))
    }
}

fn fmt_value(v: f64) -> String {
    if v.abs() >= 1000.0 {
        format!("{v:.0}")
    } else if v.abs() >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.4}")
    }
}

fn histogram_table(
    md: &mut String,
    label: &str,
    h: &crate::metrics::Histogram,
    reference: Option<&crate::metrics::Histogram>,
    decimals: usize,
) {
    let _ = writeln!(
        md,
        "\n| {label} | dataset % |{}",
        if reference.is_some() {
            " reference % |"
        } else {
            ""
        }
    );
    let _ = writeln!(
        md,
        "|---|---|{}",
        if reference.is_some() { "---|" } else { "" }
    );
    let last = h.fractions.len().saturating_sub(1);
    for (i, f) in h.fractions.iter().enumerate() {
        let lo = h.start + i as f64 * h.bin_width;
        let bin = if i == last {
            format!(">= {lo:.decimals$}")
        } else {
            format!("{lo:.decimals$}-{:.decimals$}", lo + h.bin_width)
        };
        let _ = write!(md, "| {bin} | {:.2} |", 100.0 * f);
        if let Some(r) = reference {
            let _ = write!(
                md,
                " {:.2} |",
                100.0 * r.fractions.get(i).copied().unwrap_or(0.0)
            );
        }
        md.push('\n');
    }
}

/// Options of `limot realism`.
#[derive(Debug, Clone)]
pub struct RealismOptions {
    /// A limot dataset or a KITTI-layout directory.
    pub path: PathBuf,
    /// Sequence number inside `path`.
    pub sequence: u32,
    /// Default: `PATH/realism` for a limot dataset, else `reports/realism`.
    pub out: Option<PathBuf>,
    /// Reference KITTI-layout directory, when given.
    pub reference: Option<PathBuf>,
    /// Sequence number inside `reference`.
    pub reference_sequence: u32,
    /// Show a progress bar.
    pub progress: bool,
}

/// `limot realism`: analyses the dataset (and the reference), writes the
/// report and prints its table.
///
/// # Errors
///
/// [`RealismError`] when an input cannot be read or analysed or the report written.
pub fn run_realism(opts: &RealismOptions) -> Result<RealismReport, RealismError> {
    let config = RealismConfig::default();
    if opts.progress {
        eprintln!("realism: {}", opts.path.display());
    }
    let dataset = analyze_sequence(&opts.path, opts.sequence, &config, opts.progress)?;
    let reference = match &opts.reference {
        Some(path) => {
            if opts.progress {
                eprintln!("reference: {}", path.display());
            }
            Some(analyze_sequence(
                path,
                opts.reference_sequence,
                &config,
                opts.progress,
            )?)
        }
        None => None,
    };
    let report = RealismReport::new(dataset, reference);
    let out = opts.out.clone().unwrap_or_else(|| {
        if opts.path.join("kitti").is_dir() {
            opts.path.join("realism")
        } else {
            PathBuf::from("reports/realism")
        }
    });
    let (json, md) = report.write(&out)?;
    print!("{}", report.to_markdown());
    println!("\nwrote {} and {}", json.display(), md.display());
    Ok(report)
}
