//! The KITTI tracking-sequence opener: frame times, elevation correction and scans of `training/`-style directories.

use super::drive::{RawDrive, SweepStart, TimedOxts, VelodyneFrame, count_mismatch, scan_files};
use crate::io::kitti::velodyne::{KITTI_HDL64_ELEVATION_CORRECTION_DEG, SWEEP_DURATION_S};
use crate::io::kitti::{KittiError, LineCtx, Result, content_lines, read_text};
use std::path::Path;

/// When the frames of a KITTI tracking directory were taken.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackingFrameTimes {
    /// Sweep start of each frame (the scan's [`LidarScan::t_s`](limot_estimator::input::LidarScan::t_s)).
    pub sweep_starts_s: Vec<f64>,
    /// How long after its sweep start a frame's OXTS record, camera image
    /// and labels were taken.
    pub frame_delay_s: f64,
    /// Where the sweep starts came from.
    pub start_source: SweepStart,
}

/// Frame times of a KITTI tracking directory with `frames` frames: from its
/// `times.txt` (sweep starts, as limot's KITTI-style copies write them; the
/// frame is the sweep start), else KITTI's 10 Hz with the frame at the camera
/// trigger, which fires when the laser faces forward: half a sweep after the
/// sweep start.
///
/// # Errors
/// An unreadable or malformed `times.txt` (named).
pub fn tracking_frame_times(dir: &Path, frames: usize) -> Result<TrackingFrameTimes> {
    let times_path = dir.join("times.txt");
    Ok(if times_path.is_file() {
        TrackingFrameTimes {
            sweep_starts_s: crate::io::kitti::poses::read_times(&times_path)?,
            frame_delay_s: 0.0,
            start_source: SweepStart::Measured,
        }
    } else {
        TrackingFrameTimes {
            sweep_starts_s: (0..frames).map(|i| i as f64 * SWEEP_DURATION_S).collect(),
            frame_delay_s: 0.5 * SWEEP_DURATION_S,
            start_source: SweepStart::Synthetic10Hz,
        }
    })
}

/// File of a KITTI-tracking-style directory declaring the elevation
/// correction its scans need, in degrees (one number): `limot simulate`
/// writes `0` into its copies; a user may write one to override the default.
pub const ELEVATION_CORRECTION_FILE: &str = "velodyne_elevation_correction_deg.txt";

/// The elevation correction (rad) of the scans of a tracking directory: the
/// number in [`ELEVATION_CORRECTION_FILE`] when present; else none for our
/// own copies (they have `times.txt`, KITTI has not) and KITTI's
/// [`KITTI_HDL64_ELEVATION_CORRECTION_DEG`] for KITTI's recordings.
///
/// # Errors
/// An unreadable or malformed correction file, or an implausible angle (beyond 5°).
pub fn declared_elevation_correction_rad(dir: &Path) -> Result<f64> {
    let path = dir.join(ELEVATION_CORRECTION_FILE);
    if path.is_file() {
        let text = read_text(&path)?;
        let mut lines = content_lines(&text);
        let (line_no, line) = lines.next().ok_or_else(|| KittiError::Invalid {
            path: path.clone(),
            why: "empty: expected one angle in degrees".to_string(),
        })?;
        let ctx = LineCtx::new(&path, line_no);
        let tokens: Vec<&str> = line.split_whitespace().collect();
        if tokens.len() != 1 || lines.next().is_some() {
            return Err(ctx.line_error("expected one angle in degrees".to_string()));
        }
        let deg = ctx.f64(tokens[0], 1, "elevation_correction_deg")?;
        if deg.abs() > 5.0 {
            return Err(ctx.field_error(
                1,
                "elevation_correction_deg",
                format!("{deg}° is not a plausible correction (|angle| ≤ 5°)"),
            ));
        }
        return Ok(deg.to_radians());
    }
    Ok(if dir.join("times.txt").is_file() {
        0.0
    } else {
        KITTI_HDL64_ELEVATION_CORRECTION_DEG.to_radians()
    })
}

impl RawDrive {
    /// Sequence `sequence` of a KITTI *tracking* directory (`training/`,
    /// or the KITTI-style copy `limot simulate` writes):
    /// `velodyne/SSSS/NNNNNN.bin`, `oxts/SSSS.txt` (one record per frame).
    /// With `times.txt` (our copies) scans start at its times and each OXTS
    /// record is at its scan's start; without (KITTI), frame `i` starts at
    /// `0.1·i` s and its OXTS record is at the camera trigger, half a sweep
    /// later, as KITTI synchronises them. The scans' elevation correction is
    /// [`declared_elevation_correction_rad`].
    ///
    /// # Errors
    /// Missing or malformed scans, OXTS or `times.txt`, or counts that do not match the scans (named).
    pub fn open_tracking_sequence(dir: &Path, sequence: u32) -> Result<RawDrive> {
        let name = format!("{sequence:04}");
        let (files, format) = scan_files(&dir.join("velodyne").join(&name))?;
        let oxts_path = dir.join("oxts").join(format!("{name}.txt"));
        let records = crate::io::kitti::oxts::read_oxts(&oxts_path)?;
        let times_path = dir.join("times.txt");
        let TrackingFrameTimes {
            sweep_starts_s: starts_s,
            frame_delay_s: oxts_delay_s,
            start_source,
        } = tracking_frame_times(dir, files.len())?;
        if starts_s.len() != files.len() {
            return Err(count_mismatch(
                &times_path,
                starts_s.len(),
                &dir.join("velodyne").join(&name),
                files.len(),
            ));
        }
        if records.len() != files.len() {
            return Err(count_mismatch(
                &oxts_path,
                records.len(),
                &dir.join("velodyne").join(&name),
                files.len(),
            ));
        }
        let velodyne = files
            .into_iter()
            .zip(&starts_s)
            .map(|(path, &t_start_s)| VelodyneFrame {
                path,
                format,
                t_start_s,
                t_trigger_s: None,
                t_end_s: None,
                start_source,
            })
            .collect();
        let oxts: Vec<TimedOxts> = records
            .into_iter()
            .zip(&starts_s)
            .map(|(record, &t)| TimedOxts {
                t_s: t + oxts_delay_s,
                record,
            })
            .collect();
        let elevation_correction_rad = declared_elevation_correction_rad(dir)?;
        Ok(RawDrive::from_streams(
            dir,
            oxts,
            velodyne,
            elevation_correction_rad,
        ))
    }
}
