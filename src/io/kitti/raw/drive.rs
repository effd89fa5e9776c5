//! Raw drives: OXTS stream, Velodyne frame list and scans.

use super::time::{parse_timestamp_lines, read_timestamps};
use crate::io::kitti::oxts::{OxtsRecord, oxts_to_imu, oxts_to_poses, parse_oxts};
use crate::io::kitti::velodyne::{
    KITTI_HDL64_ELEVATION_CORRECTION_DEG, SWEEP_DURATION_S, VelodyneScan, encode_bin, parse_bin,
    raise_scan_elevation, read_bin,
};
use crate::io::kitti::{KittiError, LineCtx, Result, content_lines, read_text};
use limot_estimator::input::{ImuSample, LidarPoint, LidarScan};
use nalgebra::Isometry3;
use std::fmt;
use std::path::{Path, PathBuf};

/// An OXTS step longer than this many nominal periods is reported as a gap.
pub const GAP_FACTOR: f64 = 3.0;

// ---------------------------------------------------------------------------
// Drive
// ---------------------------------------------------------------------------

/// One OXTS record with its own timestamp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimedOxts {
    /// Time (s since the Unix epoch, or since the first frame for tracking sequences).
    pub t_s: f64,
    /// The record.
    pub record: OxtsRecord,
}

/// Storage format of a Velodyne sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScanFormat {
    /// `.bin`: little-endian f32 x, y, z, reflectance.
    Bin,
    /// `.txt` (`_extract` drives): `x y z reflectance` per line.
    Txt,
}

/// Where [`VelodyneFrame::t_start_s`] came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SweepStart {
    /// `timestamps_start.txt`.
    Measured,
    /// `timestamps.txt` (camera trigger, laser facing forward) − 0.05 s.
    FromTrigger,
    /// `timestamps_end.txt` − 0.1 s.
    FromEnd,
    /// No timestamps at all ([`RawDrive::open_bare_scans`]): frame `i` starts
    /// at `0.1·i` s (10 Hz from 0).
    Synthetic10Hz,
}

/// One Velodyne sweep of a drive (the points are loaded on demand).
#[derive(Debug, Clone, PartialEq)]
pub struct VelodyneFrame {
    /// The scan file.
    pub path: PathBuf,
    /// Its storage format.
    pub format: ScanFormat,
    /// Sweep start (laser facing backwards); the scan's `t_s`.
    pub t_start_s: f64,
    /// Camera trigger (laser facing forward), when `timestamps.txt` exists.
    pub t_trigger_s: Option<f64>,
    /// Sweep end, when `timestamps_end.txt` exists.
    pub t_end_s: Option<f64>,
    /// Where `t_start_s` came from.
    pub start_source: SweepStart,
}

/// A step in the OXTS stream longer than [`GAP_FACTOR`] nominal periods.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuGap {
    /// Index of the last record before the gap (the next one is `index + 1`).
    pub index: usize,
    /// Time of the record before the gap (s).
    pub t_before_s: f64,
    /// Time of the record after the gap (s).
    pub t_after_s: f64,
    /// Nominal period of the stream (median step).
    pub period_s: f64,
}

impl ImuGap {
    /// Length of the gap (s).
    pub fn duration_s(&self) -> f64 {
        self.t_after_s - self.t_before_s
    }

    /// Records missing in the gap, rounded.
    pub fn missing_samples(&self) -> usize {
        ((self.duration_s() / self.period_s).round() as usize).saturating_sub(1)
    }
}

impl fmt::Display for ImuGap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "OXTS gap after record {}: {:.3} s without data ({:.1} periods of {:.4} s, ~{} samples missing)",
            self.index,
            self.duration_s(),
            self.duration_s() / self.period_s,
            self.period_s,
            self.missing_samples()
        )
    }
}

/// A KITTI raw drive directory, its OXTS records and Velodyne frame list.
#[derive(Debug, Clone)]
pub struct RawDrive {
    /// The drive directory.
    pub drive_dir: PathBuf,
    /// Every OXTS record at its own timestamp (100 Hz in `_extract`, 10 Hz in `_sync`).
    pub oxts: Vec<TimedOxts>,
    /// Velodyne sweeps (empty when the drive has no `velodyne_points`).
    pub velodyne: Vec<VelodyneFrame>,
    /// Nominal OXTS period: the median positive step (`None` for < 2 distinct times).
    pub oxts_period_s: Option<f64>,
    /// Elevation added to every loaded point (rad, see
    /// [`raise_elevation`](crate::io::kitti::velodyne::raise_elevation)): KITTI's
    /// [`KITTI_HDL64_ELEVATION_CORRECTION_DEG`] for KITTI's own recordings,
    /// 0 for scans of other origin; set it to 0 to read the points as stored.
    pub elevation_correction_rad: f64,
    gaps: Vec<ImuGap>,
}

/// Numbered data files `dir/NNNNNNNNNN.<ext>` sorted; their numbers must be
/// 0, 1, 2, … (a hole would silently misalign the timestamps).
fn numbered_files(dir: &Path, extensions: &[&str]) -> Result<Vec<PathBuf>> {
    let io = |source| KittiError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        let matches = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| extensions.contains(&e));
        if matches && path.is_file() {
            files.push(path);
        }
    }
    files.sort();
    for (i, path) in files.iter().enumerate() {
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        let number: Option<usize> = stem
            .bytes()
            .all(|b| b.is_ascii_digit())
            .then(|| stem.parse().ok())
            .flatten();
        match number {
            Some(n) if n == i => {}
            Some(n) => {
                return Err(KittiError::Invalid {
                    path: path.clone(),
                    why: format!(
                        "expected frame {i:010} here, found {n:010}: a data file is missing"
                    ),
                });
            }
            None => {
                return Err(KittiError::Invalid {
                    path: path.clone(),
                    why: "data file name is not a frame number".to_string(),
                });
            }
        }
    }
    Ok(files)
}

pub(super) fn count_mismatch(
    timestamps: &Path,
    times: usize,
    data_dir: &Path,
    files: usize,
) -> KittiError {
    KittiError::Invalid {
        path: timestamps.to_path_buf(),
        why: format!(
            "{times} timestamps but {files} data files in {}",
            data_dir.display()
        ),
    }
}

/// Median of the positive steps between consecutive times.
pub fn nominal_period_s(times_s: &[f64]) -> Option<f64> {
    let mut steps: Vec<f64> = times_s
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    if steps.is_empty() {
        return None;
    }
    steps.sort_by(f64::total_cmp);
    Some(steps[steps.len() / 2])
}

/// Steps longer than [`GAP_FACTOR`] · `period_s`.
fn find_gaps(times_s: &[f64], period_s: f64) -> Vec<ImuGap> {
    times_s
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[1] - w[0] > GAP_FACTOR * period_s)
        .map(|(index, w)| ImuGap {
            index,
            t_before_s: w[0],
            t_after_s: w[1],
            period_s,
        })
        .collect()
}

/// Reads a timestamp file (with line numbers) if it exists.
fn optional_timestamps(path: &Path) -> Result<Option<Vec<(usize, f64)>>> {
    if path.is_file() {
        parse_timestamp_lines(&read_text(path)?, path).map(Some)
    } else {
        Ok(None)
    }
}

impl RawDrive {
    /// Opens a drive directory: reads every OXTS record with its timestamp,
    /// lists the Velodyne sweeps (if `velodyne_points/data` exists) with
    /// their times, and checks numbering, counts and time order (module docs).
    /// Its scans get KITTI's elevation correction.
    ///
    /// # Errors
    /// Missing or malformed OXTS or Velodyne files, holes in their numbering, timestamp files of
    /// the wrong length, or time going backwards (named).
    pub fn open(drive_dir: &Path) -> Result<RawDrive> {
        let oxts = read_oxts_stream(&drive_dir.join("oxts"))?;
        let velodyne_dir = drive_dir.join("velodyne_points");
        let velodyne = if velodyne_dir.join("data").is_dir() {
            read_velodyne_frames(&velodyne_dir)?
        } else {
            Vec::new()
        };
        Ok(RawDrive::from_streams(
            drive_dir,
            oxts,
            velodyne,
            KITTI_HDL64_ELEVATION_CORRECTION_DEG.to_radians(),
        ))
    }

    /// A drive of these streams; the OXTS period and gaps follow from its times.
    pub(super) fn from_streams(
        dir: &Path,
        oxts: Vec<TimedOxts>,
        velodyne: Vec<VelodyneFrame>,
        elevation_correction_rad: f64,
    ) -> RawDrive {
        let times: Vec<f64> = oxts.iter().map(|o| o.t_s).collect();
        let oxts_period_s = nominal_period_s(&times);
        let gaps = oxts_period_s
            .map(|p| find_gaps(&times, p))
            .unwrap_or_default();
        RawDrive {
            drive_dir: dir.to_path_buf(),
            oxts,
            velodyne,
            oxts_period_s,
            elevation_correction_rad,
            gaps,
        }
    }

    /// Opens a directory of bare numbered `.bin`/`.txt` scans with no
    /// timestamps and no OXTS (e.g. `shared/data/kitti_raw_scans`). The
    /// timing is SYNTHETIC: frame `i` starts at `0.1·i` s (10 Hz from 0),
    /// marked [`SweepStart::Synthetic10Hz`]. The points are read as stored
    /// (no elevation correction: a directory of `.bin` files says nothing of
    /// the sensor that recorded them).
    ///
    /// # Errors
    /// An unreadable directory, mixed `.bin`/`.txt` scans or holes in their numbering.
    pub fn open_bare_scans(dir: &Path) -> Result<RawDrive> {
        let (files, format) = scan_files(dir)?;
        let velodyne = files
            .into_iter()
            .enumerate()
            .map(|(i, path)| VelodyneFrame {
                path,
                format,
                t_start_s: i as f64 * SWEEP_DURATION_S,
                t_trigger_s: None,
                t_end_s: None,
                start_source: SweepStart::Synthetic10Hz,
            })
            .collect();
        Ok(RawDrive {
            drive_dir: dir.to_path_buf(),
            oxts: Vec::new(),
            velodyne,
            oxts_period_s: None,
            elevation_correction_rad: 0.0,
            gaps: Vec::new(),
        })
    }

    /// OXTS timestamps (s since the Unix epoch).
    pub fn oxts_times_s(&self) -> Vec<f64> {
        self.oxts.iter().map(|o| o.t_s).collect()
    }

    /// OXTS records without times.
    pub fn oxts_records(&self) -> Vec<OxtsRecord> {
        self.oxts.iter().map(|o| o.record).collect()
    }

    /// Holes in the OXTS stream (see [`GAP_FACTOR`]); empty when regular.
    pub fn gaps(&self) -> &[ImuGap] {
        &self.gaps
    }

    /// One IMU sample per OXTS record at its own timestamp: specific force
    /// (ax, ay, az) and rate (wx, wy, wz) in the IMU body frame, exactly as
    /// [`oxts_to_imu`] maps the fields.
    pub fn imu_samples(&self) -> Vec<ImuSample> {
        let mut samples = oxts_to_imu(&self.oxts_records(), 0.0, 0.0);
        for (sample, timed) in samples.iter_mut().zip(&self.oxts) {
            sample.t_s = timed.t_s;
        }
        samples
    }

    /// IMU poses `T_w_imu` per OXTS record ([`oxts_to_poses`]: world = first IMU frame).
    pub fn poses(&self) -> Vec<Isometry3<f64>> {
        oxts_to_poses(&self.oxts_records())
    }

    /// Number of Velodyne sweeps.
    pub fn num_scans(&self) -> usize {
        self.velodyne.len()
    }

    /// Loads sweep `i` with its rings; `t_s` = sweep start; points raised by
    /// [`RawDrive::elevation_correction_rad`].
    ///
    /// # Errors
    /// An unreadable or malformed scan file (named), or `i` beyond the drive's scans.
    pub fn velodyne_scan(&self, i: usize) -> Result<VelodyneScan> {
        let Some(frame) = self.velodyne.get(i) else {
            return Err(KittiError::Invalid {
                path: self.drive_dir.clone(),
                why: format!(
                    "scan {i} requested but the drive has {} scans",
                    self.velodyne.len()
                ),
            });
        };
        let mut scan = match frame.format {
            ScanFormat::Bin => read_bin(&frame.path, frame.t_start_s),
            ScanFormat::Txt => read_velodyne_txt(&frame.path, frame.t_start_s),
        }?;
        raise_scan_elevation(&mut scan.scan, self.elevation_correction_rad);
        Ok(scan)
    }

    /// Loads sweep `i` as the estimator's [`LidarScan`] (`t_s` = sweep start).
    ///
    /// # Errors
    /// An unreadable or malformed scan file (named), or `i` beyond the drive's scans.
    pub fn scan(&self, i: usize) -> Result<LidarScan> {
        self.velodyne_scan(i).map(|s| s.scan)
    }
}

/// `oxts/timestamps.txt` + `oxts/data/*.txt` → timed records.
fn read_oxts_stream(oxts_dir: &Path) -> Result<Vec<TimedOxts>> {
    let timestamps_path = oxts_dir.join("timestamps.txt");
    let data_dir = oxts_dir.join("data");
    let times = read_timestamps(&timestamps_path)?;
    let files = numbered_files(&data_dir, &["txt"])?;
    if files.len() != times.len() {
        return Err(count_mismatch(
            &timestamps_path,
            times.len(),
            &data_dir,
            files.len(),
        ));
    }
    files
        .iter()
        .zip(&times)
        .map(|(path, t_s)| {
            let records = parse_oxts(&read_text(path)?, path)?;
            match records[..] {
                [record] => Ok(TimedOxts { t_s: *t_s, record }),
                _ => Err(KittiError::Invalid {
                    path: path.clone(),
                    why: format!("expected one OXTS record, found {}", records.len()),
                }),
            }
        })
        .collect()
}

/// Numbered scans of a directory: all `.bin` or all `.txt` (mixing is an error).
pub(super) fn scan_files(data_dir: &Path) -> Result<(Vec<PathBuf>, ScanFormat)> {
    let bins = numbered_files(data_dir, &["bin"]);
    let txts = numbered_files(data_dir, &["txt"]);
    match (bins, txts) {
        (Ok(b), Ok(t)) if !b.is_empty() && !t.is_empty() => Err(KittiError::Invalid {
            path: data_dir.to_path_buf(),
            why: format!(
                "both .bin ({}) and .txt ({}) scans: cannot tell which to use",
                b.len(),
                t.len()
            ),
        }),
        (Ok(b), Ok(t)) if b.is_empty() => Ok((t, ScanFormat::Txt)),
        (Ok(b), _) if !b.is_empty() => Ok((b, ScanFormat::Bin)),
        (Err(e), _) | (_, Err(e)) => Err(e),
        (Ok(b), Ok(_)) => Ok((b, ScanFormat::Bin)),
    }
}

/// `velodyne_points/` → frames with start/trigger/end times.
fn read_velodyne_frames(velodyne_dir: &Path) -> Result<Vec<VelodyneFrame>> {
    let data_dir = velodyne_dir.join("data");
    let (files, format) = scan_files(&data_dir)?;
    let trigger_path = velodyne_dir.join("timestamps.txt");
    let start_path = velodyne_dir.join("timestamps_start.txt");
    let end_path = velodyne_dir.join("timestamps_end.txt");
    let trigger = optional_timestamps(&trigger_path)?;
    let start = optional_timestamps(&start_path)?;
    let end = optional_timestamps(&end_path)?;
    for (path, times) in [
        (&trigger_path, &trigger),
        (&start_path, &start),
        (&end_path, &end),
    ] {
        if let Some(times) = times
            && times.len() != files.len()
        {
            return Err(count_mismatch(path, times.len(), &data_dir, files.len()));
        }
    }
    let no_times = || KittiError::Invalid {
        path: velodyne_dir.to_path_buf(),
        why: "no timestamps.txt, timestamps_start.txt or timestamps_end.txt \
              (use RawDrive::open_bare_scans for scans without times)"
            .to_string(),
    };
    if trigger.is_none() && start.is_none() && end.is_none() {
        return Err(no_times());
    }
    let mut frames = Vec::with_capacity(files.len());
    for (i, path) in files.into_iter().enumerate() {
        let trigger_i = trigger.as_ref().map(|t| t[i]);
        let end_i = end.as_ref().map(|t| t[i]);
        let t_trigger_s = trigger_i.map(|(_, t)| t);
        let t_end_s = end_i.map(|(_, t)| t);
        let (t_start_s, start_source) = match (start.as_ref().map(|s| s[i]), t_trigger_s, t_end_s) {
            (Some((_, s)), _, _) => (s, SweepStart::Measured),
            (None, Some(t), _) => (t - 0.5 * SWEEP_DURATION_S, SweepStart::FromTrigger),
            (None, None, Some(e)) => (e - SWEEP_DURATION_S, SweepStart::FromEnd),
            (None, None, None) => return Err(no_times()),
        };
        if let (Some((line, t)), SweepStart::Measured) = (trigger_i, start_source)
            && t < t_start_s
        {
            return Err(KittiError::Line {
                path: trigger_path.clone(),
                line,
                why: format!("trigger {t:.9} s is before the sweep start {t_start_s:.9} s"),
            });
        }
        let reference_s = t_trigger_s.unwrap_or(t_start_s);
        if let Some((line, e)) = end_i
            && e < reference_s
        {
            return Err(KittiError::Line {
                path: end_path.clone(),
                line,
                why: format!("sweep end {e:.9} s is before its start/trigger {reference_s:.9} s"),
            });
        }
        frames.push(VelodyneFrame {
            path,
            format,
            t_start_s,
            t_trigger_s,
            t_end_s,
            start_source,
        });
    }
    Ok(frames)
}

/// Parses a text scan (`x y z reflectance` per line, `_extract` drives) with
/// the same ring and per-point time logic as `.bin` scans.
///
/// # Errors
/// A line without 4 columns or a malformed field (file, line and column).
pub fn parse_velodyne_txt(text: &str, path: &Path, t_s: f64) -> Result<VelodyneScan> {
    const NAMES: [&str; 4] = ["x", "y", "z", "reflectance"];
    let mut points = Vec::new();
    for (line_no, line) in content_lines(text) {
        let ctx = LineCtx::new(path, line_no);
        let tokens: Vec<&str> = line.split_whitespace().collect();
        if tokens.len() != 4 {
            return Err(ctx.column_count("4", tokens.len()));
        }
        let mut v = [0f32; 4];
        for (k, value) in v.iter_mut().enumerate() {
            // Validate as f64 (clear errors), then parse the token as f32
            // directly: one rounding, so shortest-form f32 text is exact.
            let x = ctx.f64(tokens[k], k + 1, NAMES[k])?;
            *value = tokens[k].parse::<f32>().unwrap_or(f32::NAN);
            if !value.is_finite() {
                return Err(ctx.field_error(k + 1, NAMES[k], format!("`{x}` overflows f32")));
            }
        }
        points.push(LidarPoint {
            x: v[0],
            y: v[1],
            z: v[2],
            intensity: v[3],
            ring: 0,
            time_offset_s: 0.0,
        });
    }
    // Through the binary decoder so rings and point times follow exactly the
    // `.bin` rules (finite values cannot fail there).
    parse_bin(&encode_bin(&points), path, t_s)
}

/// Reads a text scan (see [`parse_velodyne_txt`]).
///
/// # Errors
/// An unreadable file, or a malformed line (see [`parse_velodyne_txt`]).
pub fn read_velodyne_txt(path: &Path, t_s: f64) -> Result<VelodyneScan> {
    parse_velodyne_txt(&read_text(path)?, path, t_s)
}
