//! KITTI raw drives (`2011_09_26/2011_09_26_drive_0001_sync` and the
//! unsynchronised `_extract` variant): per-sample timestamps, 100 Hz OXTS
//! (10 Hz in `_sync`), Velodyne sweeps with start/trigger/end times, and the
//! three per-day calibration files.
//!
//! Layout read here:
//! ```text
//! <date>/calib_imu_to_velo.txt   R: (9) T: (3)            -> T_velo_imu
//! <date>/calib_velo_to_cam.txt   R: (9) T: (3) delta_f/c  -> T_cam_velo
//! <date>/calib_cam_to_cam.txt    R_rect_00: P_rect_00..03: (+ unused keys)
//! <drive>/oxts/timestamps.txt    "2011-09-26 13:02:25.964389445" per line
//! <drive>/oxts/data/NNNNNNNNNN.txt          one 30-field OXTS line each
//! <drive>/velodyne_points/timestamps{,_start,_end}.txt
//! <drive>/velodyne_points/data/NNNNNNNNNN.{bin,txt}
//! ```
//! Times are seconds since the Unix epoch (UTC, leap seconds ignored as Unix
//! time does), as f64: at ~1.3e9 s its resolution is ~2.4e-7 s, finer than
//! the microsecond jitter of the recorded clocks.
//!
//! Velodyne times: `timestamps_start` = the laser facing backwards (sweep
//! start, the [`LidarScan::t_s`] we use), `timestamps` = facing forwards
//! (camera trigger, mid sweep), `timestamps_end` = backwards again. When a
//! drive lacks `timestamps_start`, the start is derived as trigger − 0.05 s
//! or end − 0.1 s (see [`SweepStart`]).
//!
//! Checks: data files must be numbered 0, 1, 2, … without holes; every
//! timestamp file must have as many lines as there are data files; time must
//! not go backwards within a file (equal consecutive stamps are accepted);
//! per sweep start ≤ trigger ≤ end. Holes in the OXTS stream longer than
//! [`GAP_FACTOR`] nominal periods are not errors: they are listed by
//! [`RawDrive::gaps`] so callers can decide (e.g. stop IMU propagation).

use super::calib::{Calib, isometry_from_3x4};
use super::oxts::{OxtsRecord, oxts_to_imu, oxts_to_poses, parse_oxts};
use super::velodyne::{
    KITTI_HDL64_ELEVATION_CORRECTION_DEG, SWEEP_DURATION_S, VelodyneScan, encode_bin, parse_bin,
    raise_scan_elevation, read_bin,
};
use super::{KittiError, LineCtx, Result, content_lines, read_text};
use limot_estimator::input::{ImuSample, LidarPoint, LidarScan};
use nalgebra::{Isometry3, Matrix3, Matrix3x4};
use std::fmt;
use std::path::{Path, PathBuf};

/// An OXTS step longer than this many nominal periods is reported as a gap.
pub const GAP_FACTOR: f64 = 3.0;

// ---------------------------------------------------------------------------
// Timestamps
// ---------------------------------------------------------------------------

/// Seconds since 1970-01-01 of a proleptic Gregorian date (Howard Hinnant's
/// `days_from_civil`; exact integer arithmetic).
fn days_from_civil(year: i64, month: u32, day: u32) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let yoe = y - era * 400; // [0, 399]
    let m = month as i64;
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + day as i64 - 1; // [0, 365]
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy; // [0, 146096]
    era * 146_097 + doe - 719_468
}

/// Inverse of [`days_from_civil`]: (year, month, day).
fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

fn is_leap_year(year: i64) -> bool {
    (year % 4 == 0 && year % 100 != 0) || year % 400 == 0
}

fn days_in_month(year: i64, month: u32) -> u32 {
    match month {
        2 if is_leap_year(year) => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// A KITTI timestamp split into whole Unix seconds and nanoseconds, so that
/// no precision is lost before the caller picks a representation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct UnixTime {
    pub secs: i64,
    /// In 0..1_000_000_000.
    pub nanos: u32,
}

impl UnixTime {
    /// Seconds since the epoch as f64 (integer and fraction added last).
    pub fn as_secs_f64(&self) -> f64 {
        self.secs as f64 + self.nanos as f64 * 1e-9
    }

    /// Nearest nanosecond to `t_s` (for writing synthetic files).
    pub fn from_secs_f64(t_s: f64) -> UnixTime {
        let mut secs = t_s.floor();
        let mut nanos = ((t_s - secs) * 1e9).round();
        if nanos >= 1e9 {
            secs += 1.0;
            nanos -= 1e9;
        }
        UnixTime {
            secs: secs as i64,
            nanos: nanos as u32,
        }
    }
}

impl fmt::Display for UnixTime {
    /// KITTI spelling: `YYYY-MM-DD HH:MM:SS.nnnnnnnnn`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let days = self.secs.div_euclid(86_400);
        let sod = self.secs.rem_euclid(86_400);
        let (year, month, day) = civil_from_days(days);
        write!(
            f,
            "{year:04}-{month:02}-{day:02} {:02}:{:02}:{:02}.{:09}",
            sod / 3600,
            (sod / 60) % 60,
            sod % 60,
            self.nanos
        )
    }
}

/// Parses `YYYY-MM-DD HH:MM:SS[.f…]` (1 to 9 fraction digits, UTC) into whole
/// seconds and nanoseconds; `Err` carries a human-readable reason.
pub fn parse_unix_time(s: &str) -> std::result::Result<UnixTime, String> {
    let mut parts = s.split_whitespace();
    let (Some(date), Some(time), None) = (parts.next(), parts.next(), parts.next()) else {
        return Err(format!(
            "`{s}` is not `YYYY-MM-DD HH:MM:SS.fffffffff` (date and time separated by a space)"
        ));
    };
    fn number(token: &str, digits: usize, what: &str) -> std::result::Result<u32, String> {
        if token.len() != digits || !token.bytes().all(|b| b.is_ascii_digit()) {
            return Err(format!("{what} `{token}` is not {digits} digits"));
        }
        token.parse().map_err(|_| format!("{what} `{token}`"))
    }
    let date_fields: Vec<&str> = date.split('-').collect();
    let [y, mo, d] = date_fields[..] else {
        return Err(format!("date `{date}` is not YYYY-MM-DD"));
    };
    let year = number(y, 4, "year")? as i64;
    let month = number(mo, 2, "month")?;
    if !(1..=12).contains(&month) {
        return Err(format!("month {month} is not in 1..=12"));
    }
    let day = number(d, 2, "day")?;
    if day == 0 || day > days_in_month(year, month) {
        return Err(format!("day {day} does not exist in {year:04}-{month:02}"));
    }
    let (hms, fraction) = match time.split_once('.') {
        Some((hms, fraction)) => (hms, Some(fraction)),
        None => (time, None),
    };
    let time_fields: Vec<&str> = hms.split(':').collect();
    let [h, mi, se] = time_fields[..] else {
        return Err(format!("time `{time}` is not HH:MM:SS"));
    };
    let hour = number(h, 2, "hour")?;
    let minute = number(mi, 2, "minute")?;
    let second = number(se, 2, "second")?;
    if hour > 23 || minute > 59 || second > 59 {
        return Err(format!(
            "time {hour:02}:{minute:02}:{second:02} is out of range (leap seconds are not accepted)"
        ));
    }
    let nanos = match fraction {
        None => 0,
        Some(f) => {
            if f.is_empty() || f.len() > 9 || !f.bytes().all(|b| b.is_ascii_digit()) {
                return Err(format!("fraction `.{f}` is not 1 to 9 digits"));
            }
            let value: u32 = f.parse().map_err(|_| format!("fraction `.{f}`"))?;
            value * 10u32.pow(9 - f.len() as u32)
        }
    };
    let secs = days_from_civil(year, month, day) * 86_400
        + hour as i64 * 3600
        + minute as i64 * 60
        + second as i64;
    Ok(UnixTime { secs, nanos })
}

/// Parses one KITTI timestamp into seconds since the Unix epoch.
/// `"2011-09-26 13:02:25.964389445"` → 1317042145.964389445.
pub fn parse_timestamp(s: &str) -> std::result::Result<f64, String> {
    parse_unix_time(s).map(|t| t.as_secs_f64())
}

/// Parses a timestamp file (one stamp per non-blank line) and rejects time
/// going backwards; errors name the file and line.
pub fn parse_timestamps(text: &str, path: &Path) -> Result<Vec<f64>> {
    Ok(parse_timestamp_lines(text, path)?
        .into_iter()
        .map(|(_, t)| t)
        .collect())
}

/// [`parse_timestamps`] keeping each stamp's 1-based line number.
fn parse_timestamp_lines(text: &str, path: &Path) -> Result<Vec<(usize, f64)>> {
    let mut times = Vec::new();
    let mut previous: Option<UnixTime> = None;
    for (line_no, line) in content_lines(text) {
        let ctx = LineCtx::new(path, line_no);
        let t = parse_unix_time(line.trim()).map_err(|why| ctx.line_error(why))?;
        if let Some(prev) = previous
            && t < prev
        {
            return Err(ctx.line_error(format!("time goes backwards: {t} is before {prev}")));
        }
        previous = Some(t);
        times.push((line_no, t.as_secs_f64()));
    }
    Ok(times)
}

/// Reads a timestamp file (see [`parse_timestamps`]).
pub fn read_timestamps(path: &Path) -> Result<Vec<f64>> {
    parse_timestamps(&read_text(path)?, path)
}

/// Formats times as a KITTI timestamp file (nearest nanosecond).
pub fn write_timestamps(times_s: &[f64]) -> String {
    times_s
        .iter()
        .map(|t| format!("{}\n", UnixTime::from_secs_f64(*t)))
        .collect()
}

// ---------------------------------------------------------------------------
// Calibration
// ---------------------------------------------------------------------------

/// One `key: numbers` line of a raw calibration file.
struct CalibEntry {
    line: usize,
    values: Vec<String>,
}

/// Splits `key: v1 v2 …` lines at the first colon (values such as
/// `calib_time: 09-Jan-2012 13:57:47` contain colons themselves).
fn parse_key_values(text: &str, path: &Path) -> Result<Vec<(String, CalibEntry)>> {
    let mut entries: Vec<(String, CalibEntry)> = Vec::new();
    for (line_no, line) in content_lines(text) {
        let ctx = LineCtx::new(path, line_no);
        let Some((key, rest)) = line.split_once(':') else {
            return Err(ctx.line_error(format!("expected `key: values`, found `{}`", line.trim())));
        };
        let key = key.trim();
        if key.is_empty() || key.contains(char::is_whitespace) {
            return Err(ctx.line_error(format!("`{key}` is not a calibration key")));
        }
        if entries.iter().any(|(k, _)| k == key) {
            return Err(ctx.line_error(format!("duplicate key `{key}`")));
        }
        entries.push((
            key.to_string(),
            CalibEntry {
                line: line_no,
                values: rest.split_whitespace().map(str::to_string).collect(),
            },
        ));
    }
    Ok(entries)
}

/// The numbers of a required key, checked for count and finiteness.
fn numbers<const N: usize>(
    entries: &[(String, CalibEntry)],
    path: &Path,
    key: &'static str,
) -> Result<([f64; N], usize)> {
    let Some((_, entry)) = entries.iter().find(|(k, _)| k == key) else {
        return Err(KittiError::MissingKey {
            path: path.to_path_buf(),
            key,
        });
    };
    let ctx = LineCtx::new(path, entry.line);
    if entry.values.len() != N {
        return Err(ctx.column_count(&format!("{key}: + {N}"), entry.values.len() + 1));
    }
    let mut out = [0.0; N];
    for (i, (value, token)) in out.iter_mut().zip(&entry.values).enumerate() {
        *value = ctx.f64(token, i + 2, key)?;
    }
    Ok((out, entry.line))
}

/// `R:` and `T:` of a rigid-transform file → isometry (rotation checked and
/// re-orthonormalised as in the tracking calibration).
fn rigid_transform(text: &str, path: &Path) -> Result<Isometry3<f64>> {
    let entries = parse_key_values(text, path)?;
    let (r, r_line) = numbers::<9>(&entries, path, "R")?;
    let (t, _) = numbers::<3>(&entries, path, "T")?;
    let m = Matrix3x4::new(
        r[0], r[1], r[2], t[0], r[3], r[4], r[5], t[1], r[6], r[7], r[8], t[2],
    );
    isometry_from_3x4(&m).map_err(|why| LineCtx::new(path, r_line).line_error(format!("R: {why}")))
}

/// Calibration of one KITTI raw recording day (`<date>/calib_*.txt`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawCalib {
    /// `calib_imu_to_velo.txt`: maps IMU (OXTS) points into the Velodyne frame.
    pub t_velo_imu: Isometry3<f64>,
    /// `calib_velo_to_cam.txt`: maps Velodyne points into the unrectified camera-0 frame.
    pub t_cam_velo: Isometry3<f64>,
    /// `R_rect_00`: rectifying rotation of camera 0, as stored.
    pub r_rect_00: Matrix3<f64>,
    /// `P_rect_00` … `P_rect_03`: projections of the rectified cameras (02 = left colour).
    pub p_rect: [Matrix3x4<f64>; 4],
}

impl RawCalib {
    pub const IMU_TO_VELO: &'static str = "calib_imu_to_velo.txt";
    pub const VELO_TO_CAM: &'static str = "calib_velo_to_cam.txt";
    pub const CAM_TO_CAM: &'static str = "calib_cam_to_cam.txt";

    /// Reads the three calibration files of a date directory.
    pub fn read(date_dir: &Path) -> Result<RawCalib> {
        let imu_path = date_dir.join(Self::IMU_TO_VELO);
        let velo_path = date_dir.join(Self::VELO_TO_CAM);
        let cam_path = date_dir.join(Self::CAM_TO_CAM);
        RawCalib::parse(
            (&read_text(&imu_path)?, &imu_path),
            (&read_text(&velo_path)?, &velo_path),
            (&read_text(&cam_path)?, &cam_path),
        )
    }

    /// Parses the texts of `calib_imu_to_velo`, `calib_velo_to_cam` and
    /// `calib_cam_to_cam` (each with its path for error messages). Keys not
    /// needed here (`calib_time`, `S_xx`, `K_xx`, `D_xx`, `delta_f`, …) are
    /// ignored; needed ones are checked.
    pub fn parse(
        imu_to_velo: (&str, &Path),
        velo_to_cam: (&str, &Path),
        cam_to_cam: (&str, &Path),
    ) -> Result<RawCalib> {
        let t_velo_imu = rigid_transform(imu_to_velo.0, imu_to_velo.1)?;
        let t_cam_velo = rigid_transform(velo_to_cam.0, velo_to_cam.1)?;
        let (text, path) = cam_to_cam;
        let entries = parse_key_values(text, path)?;
        let (r, r_line) = numbers::<9>(&entries, path, "R_rect_00")?;
        let r_rect_00 = Matrix3::from_row_slice(&r);
        // Same orthonormality check as the tracking `R_rect` (via a 3x4 with t = 0).
        let mut as_3x4 = Matrix3x4::zeros();
        as_3x4.fixed_view_mut::<3, 3>(0, 0).copy_from(&r_rect_00);
        isometry_from_3x4(&as_3x4)
            .map_err(|why| LineCtx::new(path, r_line).line_error(format!("R_rect_00: {why}")))?;
        let keys = ["P_rect_00", "P_rect_01", "P_rect_02", "P_rect_03"];
        let mut p_rect = [Matrix3x4::zeros(); 4];
        for (p, key) in p_rect.iter_mut().zip(keys) {
            let (values, _) = numbers::<12>(&entries, path, key)?;
            *p = Matrix3x4::from_row_slice(&values);
        }
        Ok(RawCalib {
            t_velo_imu,
            t_cam_velo,
            r_rect_00,
            p_rect,
        })
    }

    /// The tracking-style calibration (P0..P3 = P_rect_00..03, R_rect =
    /// R_rect_00), so the tracking code path can be reused on raw drives.
    pub fn to_calib(&self) -> Calib {
        Calib {
            p0: self.p_rect[0],
            p1: self.p_rect[1],
            p2: self.p_rect[2],
            p3: self.p_rect[3],
            r_rect: self.r_rect_00,
            t_cam_velo: self.t_cam_velo,
            t_velo_imu: self.t_velo_imu,
        }
    }
}

// ---------------------------------------------------------------------------
// Drive
// ---------------------------------------------------------------------------

/// One OXTS record with its own timestamp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimedOxts {
    pub t_s: f64,
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

/// When the frames of a KITTI tracking directory were taken.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackingFrameTimes {
    /// Sweep start of each frame (the scan's [`LidarScan::t_s`]).
    pub sweep_starts_s: Vec<f64>,
    /// How long after its sweep start a frame's OXTS record, camera image
    /// and labels were taken.
    pub frame_delay_s: f64,
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
            sweep_starts_s: super::poses::read_times(&times_path)?,
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

/// One Velodyne sweep of a drive (the points are loaded on demand).
#[derive(Debug, Clone, PartialEq)]
pub struct VelodyneFrame {
    pub path: PathBuf,
    pub format: ScanFormat,
    /// Sweep start (laser facing backwards); the scan's `t_s`.
    pub t_start_s: f64,
    /// Camera trigger (laser facing forward), when `timestamps.txt` exists.
    pub t_trigger_s: Option<f64>,
    /// Sweep end, when `timestamps_end.txt` exists.
    pub t_end_s: Option<f64>,
    pub start_source: SweepStart,
}

/// A step in the OXTS stream longer than [`GAP_FACTOR`] nominal periods.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuGap {
    /// Index of the last record before the gap (the next one is `index + 1`).
    pub index: usize,
    pub t_before_s: f64,
    pub t_after_s: f64,
    /// Nominal period of the stream (median step).
    pub period_s: f64,
}

impl ImuGap {
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
    pub drive_dir: PathBuf,
    /// Every OXTS record at its own timestamp (100 Hz in `_extract`, 10 Hz in `_sync`).
    pub oxts: Vec<TimedOxts>,
    /// Velodyne sweeps (empty when the drive has no `velodyne_points`).
    pub velodyne: Vec<VelodyneFrame>,
    /// Nominal OXTS period: the median positive step (`None` for < 2 distinct times).
    pub oxts_period_s: Option<f64>,
    /// Elevation added to every loaded point (rad, see
    /// [`raise_elevation`](super::velodyne::raise_elevation)): KITTI's
    /// [`KITTI_HDL64_ELEVATION_CORRECTION_DEG`] for KITTI's own recordings,
    /// 0 for scans of other origin; set it to 0 to read the points as stored.
    pub elevation_correction_rad: f64,
    gaps: Vec<ImuGap>,
}

/// File of a KITTI-tracking-style directory declaring the elevation
/// correction its scans need, in degrees (one number): `limot simulate`
/// writes `0` into its copies; a user may write one to override the default.
pub const ELEVATION_CORRECTION_FILE: &str = "velodyne_elevation_correction_deg.txt";

/// The elevation correction (rad) of the scans of a tracking directory: the
/// number in [`ELEVATION_CORRECTION_FILE`] when present; else none for our
/// own copies (they have `times.txt`, KITTI has not) and KITTI's
/// [`KITTI_HDL64_ELEVATION_CORRECTION_DEG`] for KITTI's recordings.
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

fn count_mismatch(timestamps: &Path, times: usize, data_dir: &Path, files: usize) -> KittiError {
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
    fn from_streams(
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
    /// Sequence `sequence` of a KITTI *tracking* directory (`training/`,
    /// or the KITTI-style copy `limot simulate` writes):
    /// `velodyne/SSSS/NNNNNN.bin`, `oxts/SSSS.txt` (one record per frame).
    /// With `times.txt` (our copies) scans start at its times and each OXTS
    /// record is at its scan's start; without (KITTI), frame `i` starts at
    /// `0.1·i` s and its OXTS record is at the camera trigger, half a sweep
    /// later, as KITTI synchronises them. The scans' elevation correction is
    /// [`declared_elevation_correction_rad`].
    pub fn open_tracking_sequence(dir: &Path, sequence: u32) -> Result<RawDrive> {
        let name = format!("{sequence:04}");
        let (files, format) = scan_files(&dir.join("velodyne").join(&name))?;
        let oxts_path = dir.join("oxts").join(format!("{name}.txt"));
        let records = super::oxts::read_oxts(&oxts_path)?;
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
fn scan_files(data_dir: &Path) -> Result<(Vec<PathBuf>, ScanFormat)> {
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
pub fn read_velodyne_txt(path: &Path, t_s: f64) -> Result<VelodyneScan> {
    parse_velodyne_txt(&read_text(path)?, path, t_s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kitti::oxts::{EARTH_RADIUS_M, lat_lon_to_mercator, lat_to_scale};
    use crate::kitti::velodyne::{RingSource, write_bin};
    use crate::kitti::write_text;
    use nalgebra::Vector3;
    use proptest::prelude::*;
    use std::f64::consts::PI;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// A fresh directory under the system temp dir, removed on drop.
    struct TempDir(PathBuf);

    impl TempDir {
        fn new(tag: &str) -> TempDir {
            static COUNTER: AtomicUsize = AtomicUsize::new(0);
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let dir = std::env::temp_dir()
                .join(format!("limot_kitti_raw_{}_{n}_{tag}", std::process::id()));
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).unwrap();
            TempDir(dir)
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    /// 2011-09-26 13:02:25.964389445 UTC.
    const T0: UnixTime = UnixTime {
        secs: 1_317_042_145,
        nanos: 964_389_445,
    };

    fn add_nanos(t: UnixTime, nanos: i64) -> UnixTime {
        let total = t.nanos as i64 + nanos;
        UnixTime {
            secs: t.secs + total.div_euclid(1_000_000_000),
            nanos: total.rem_euclid(1_000_000_000) as u32,
        }
    }

    // Circular motion: radius 20 m, 10 m/s, counter-clockwise, starting due east.
    const RADIUS_M: f64 = 20.0;
    const SPEED_MPS: f64 = 10.0;
    const YAW_RATE_RADPS: f64 = SPEED_MPS / RADIUS_M;
    const LAT0_DEG: f64 = 49.0;
    const LON0_DEG: f64 = 8.4;

    /// Inverse of the devkit Mercator projection.
    fn mercator_to_lat_lon(mx: f64, my: f64, scale: f64) -> (f64, f64) {
        let lon = mx * 180.0 / (scale * PI * EARTH_RADIUS_M);
        let lat = 360.0 / PI * (my / (scale * EARTH_RADIUS_M)).exp().atan() - 90.0;
        (lat, lon)
    }

    /// Position (east, north) in m and yaw on the circle `tau_s` after the start.
    fn circle(tau_s: f64) -> (f64, f64, f64) {
        let a = YAW_RATE_RADPS * tau_s;
        (RADIUS_M * a.sin(), RADIUS_M * (1.0 - a.cos()), a)
    }

    /// The OXTS record `tau_s` into the circle; `i` varies the fields that
    /// do not affect the pose so that field-by-field checks mean something.
    fn circle_record(tau_s: f64, i: usize) -> OxtsRecord {
        let scale = lat_to_scale(LAT0_DEG);
        let (mx0, my0) = lat_lon_to_mercator(LAT0_DEG, LON0_DEG, scale);
        let (east, north, yaw) = circle(tau_s);
        let (lat, lon) = mercator_to_lat_lon(mx0 + east, my0 + north, scale);
        let k = i as f64;
        OxtsRecord {
            lat_deg: lat,
            lon_deg: lon,
            alt_m: 112.5,
            roll_rad: 0.0,
            pitch_rad: 0.0,
            yaw_rad: yaw,
            vn_mps: SPEED_MPS * yaw.sin(),
            ve_mps: SPEED_MPS * yaw.cos(),
            vf_mps: SPEED_MPS,
            vl_mps: 0.0,
            vu_mps: 0.0,
            ax_mps2: 0.05 * (0.37 * k).sin(),
            ay_mps2: SPEED_MPS * YAW_RATE_RADPS + 0.01 * (0.11 * k).cos(),
            az_mps2: 9.81 + 0.02 * (0.23 * k).sin(),
            af_mps2: 0.0,
            al_mps2: SPEED_MPS * YAW_RATE_RADPS,
            au_mps2: 9.81,
            wx_radps: 1e-3 * (0.5 * k).sin(),
            wy_radps: -1e-3 * (0.3 * k).cos(),
            wz_radps: YAW_RATE_RADPS,
            wf_radps: 0.0,
            wl_radps: 0.0,
            wu_radps: YAW_RATE_RADPS,
            pos_accuracy_m: 0.05,
            vel_accuracy_mps: 0.02,
            navstat: 4,
            numsats: 9,
            posmode: 5,
            velmode: 5,
            orimode: 6,
        }
    }

    /// What a synthetic drive was written with.
    struct Written {
        records: Vec<OxtsRecord>,
        scan_starts: Vec<UnixTime>,
        scans: Vec<Vec<LidarPoint>>,
    }

    fn oxts_offset_ns(i: usize) -> i64 {
        // 100 Hz with ±200 µs deterministic jitter, like the real logger.
        i as i64 * 10_000_000 + ((i * 7919) % 401) as i64 * 1000 - 200_000
    }

    /// A scan in KITTI order (64 lasers top first, azimuth increasing) so
    /// that rings come from scan lines; `k` varies range and intensity.
    fn scan_points(k: usize) -> Vec<LidarPoint> {
        let mut points = Vec::new();
        for line in 0..64u16 {
            let elevation = (2.0 - 0.4 * line as f64).to_radians();
            for j in 0..12 {
                let az = (j as f64 + 0.5) / 12.0 * 2.0 * PI;
                let r = 10.0 + k as f64 + 0.1 * j as f64;
                points.push(LidarPoint {
                    x: (r * elevation.cos() * az.cos()) as f32,
                    y: (r * elevation.cos() * az.sin()) as f32,
                    z: (r * elevation.sin()) as f32,
                    intensity: 0.01 * (j + k) as f32,
                    ring: 63 - line,
                    time_offset_s: 0.0,
                });
            }
        }
        points
    }

    /// Writes `<dir>/oxts` (`n_oxts` records at 100 Hz) and
    /// `<dir>/velodyne_points` (`n_scans` sweeps at 10 Hz, `.bin` or `.txt`).
    fn write_drive(dir: &Path, n_oxts: usize, n_scans: usize, txt_scans: bool) -> Written {
        let oxts_data = dir.join("oxts/data");
        std::fs::create_dir_all(&oxts_data).unwrap();
        let oxts_times: Vec<UnixTime> = (0..n_oxts)
            .map(|i| add_nanos(T0, oxts_offset_ns(i)))
            .collect();
        let tau0 = oxts_times[0];
        let records: Vec<OxtsRecord> = oxts_times
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let tau_s =
                    (t.secs - tau0.secs) as f64 + (t.nanos as f64 - tau0.nanos as f64) * 1e-9;
                circle_record(tau_s, i)
            })
            .collect();
        for (i, r) in records.iter().enumerate() {
            write_text(
                &oxts_data.join(format!("{i:010}.txt")),
                &(r.to_line() + "\n"),
            )
            .unwrap();
        }
        let stamps =
            |times: &[UnixTime]| -> String { times.iter().map(|t| format!("{t}\n")).collect() };
        write_text(&dir.join("oxts/timestamps.txt"), &stamps(&oxts_times)).unwrap();

        let velo_data = dir.join("velodyne_points/data");
        std::fs::create_dir_all(&velo_data).unwrap();
        let scan_starts: Vec<UnixTime> = (0..n_scans)
            .map(|k| add_nanos(T0, k as i64 * 100_000_000 + 3_141_592))
            .collect();
        let mut scans = Vec::new();
        for k in 0..n_scans {
            let points = scan_points(k);
            if txt_scans {
                let text: String = points
                    .iter()
                    .map(|p| format!("{} {} {} {}\n", p.x, p.y, p.z, p.intensity))
                    .collect();
                write_text(&velo_data.join(format!("{k:010}.txt")), &text).unwrap();
            } else {
                write_bin(&velo_data.join(format!("{k:010}.bin")), &points).unwrap();
            }
            scans.push(points);
        }
        let shifted =
            |ns: i64| -> Vec<UnixTime> { scan_starts.iter().map(|t| add_nanos(*t, ns)).collect() };
        let velo = dir.join("velodyne_points");
        write_text(&velo.join("timestamps_start.txt"), &stamps(&scan_starts)).unwrap();
        write_text(&velo.join("timestamps.txt"), &stamps(&shifted(50_000_000))).unwrap();
        write_text(
            &velo.join("timestamps_end.txt"),
            &stamps(&shifted(99_000_000)),
        )
        .unwrap();
        Written {
            records,
            scan_starts,
            scans,
        }
    }

    fn error_text(result: Result<RawDrive>) -> String {
        match result {
            Ok(_) => panic!("expected an error"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn timestamps_parse_known_values() {
        assert_eq!(parse_timestamp("1970-01-01 00:00:01.5").unwrap(), 1.5);
        assert_eq!(parse_timestamp("1970-01-01 00:00:00").unwrap(), 0.0);
        let t = parse_unix_time("2011-09-26 13:02:25.964389445").unwrap();
        assert_eq!(t, T0);
        let t_s = parse_timestamp("2011-09-26 13:02:25.964389445").unwrap();
        assert!(
            (t_s - 1_317_042_145.0 - 0.964_389_445).abs() < 1e-6,
            "{t_s}"
        );
        // Leap day and year ends (checked against `date -u -d … +%s`).
        assert_eq!(
            parse_unix_time("2012-02-29 00:00:00").unwrap().secs,
            1_330_473_600
        );
        assert_eq!(
            parse_unix_time("1999-12-31 23:59:59.000000001").unwrap(),
            UnixTime {
                secs: 946_684_799,
                nanos: 1
            }
        );
        assert_eq!(
            parse_unix_time("1969-12-31 23:59:59.25").unwrap(),
            UnixTime {
                secs: -1,
                nanos: 250_000_000
            }
        );
        assert_eq!(T0.to_string(), "2011-09-26 13:02:25.964389445");
        for bad in [
            "",
            "2011-09-26",
            "2011-09-26 13:02:25.964389445 x",
            "2011-13-26 13:02:25.1",
            "2011-02-29 13:02:25.1",
            "2011-09-26 24:00:00.0",
            "2011-09-26 13:60:00.0",
            "2011-09-26 13:02:60.0",
            "2011-09-26 13:02:25.",
            "2011-09-26 13:02:25.1234567890",
            "2011-09-26 13:02:2x.1",
            "2011-9-26 13:02:25.1",
            "2011-09-26 13:02:25.-1",
            "+011-09-26 13:02:25.1",
        ] {
            assert!(parse_timestamp(bad).is_err(), "accepted `{bad}`");
        }
    }

    #[test]
    fn malformed_timestamp_names_file_and_line() {
        let text = "2011-09-26 13:02:25.1\n2011-09-26 13:02:25.2\n2011-09-26 13:0:25.3\n";
        let err = parse_timestamps(text, Path::new("oxts/timestamps.txt"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("oxts/timestamps.txt:3") && err.contains("minute"),
            "{err}"
        );
        let back = "2011-09-26 13:02:25.2\n\n2011-09-26 13:02:25.1\n";
        let err = parse_timestamps(back, Path::new("t.txt"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("t.txt:3") && err.contains("backwards"),
            "{err}"
        );
        // Equal consecutive stamps are accepted (documented).
        let equal = "2011-09-26 13:02:25.2\n2011-09-26 13:02:25.2\n";
        assert_eq!(
            parse_timestamps(equal, Path::new("t.txt")).unwrap().len(),
            2
        );
    }

    #[test]
    fn synthetic_100hz_drive_reads_back() {
        let tmp = TempDir::new("drive");
        let written = write_drive(&tmp.0, 200, 3, false);
        let drive = RawDrive::open(&tmp.0).unwrap();
        assert_eq!(drive.oxts.len(), 200);
        assert!(drive.gaps().is_empty(), "{:?}", drive.gaps());
        let period = drive.oxts_period_s.unwrap();
        assert!((period - 0.01).abs() < 4e-4, "{period}");

        // Times exact to 1e-6 s: truth = the known start + the integer
        // nanosecond offsets the files were written with.
        let mut worst_time_err: f64 = 0.0;
        for (i, o) in drive.oxts.iter().enumerate() {
            let truth = 1_317_042_145.0 + (964_389_445 + oxts_offset_ns(i)) as f64 * 1e-9;
            worst_time_err = worst_time_err.max((o.t_s - truth).abs());
        }
        assert!(worst_time_err < 1e-6, "{worst_time_err}");
        let times = drive.oxts_times_s();
        let rewritten = parse_timestamps(&write_timestamps(&times), Path::new("w")).unwrap();
        assert!(
            times
                .iter()
                .zip(&rewritten)
                .all(|(a, b)| (a - b).abs() < 1e-6)
        );

        // IMU samples carry the written fields and their own times.
        let imu = drive.imu_samples();
        assert_eq!(imu.len(), 200);
        for ((s, o), r) in imu.iter().zip(&drive.oxts).zip(&written.records) {
            assert_eq!(o.record, *r);
            assert_eq!(s.t_s, o.t_s);
            assert_eq!(s.accel_mps2, Vector3::new(r.ax_mps2, r.ay_mps2, r.az_mps2));
            assert_eq!(
                s.gyro_radps,
                Vector3::new(r.wx_radps, r.wy_radps, r.wz_radps)
            );
            assert!(s.validate().is_ok());
        }
        assert!(imu.windows(2).all(|w| w[1].t_s > w[0].t_s));

        // Poses follow the circle (world = first IMU frame = ENU at the start).
        let poses = drive.poses();
        let mut worst_pos_m: f64 = 0.0;
        let mut worst_yaw_rad: f64 = 0.0;
        for (pose, o) in poses.iter().zip(&drive.oxts) {
            let (east, north, yaw) = circle(o.t_s - drive.oxts[0].t_s);
            let p = pose.translation.vector;
            worst_pos_m = worst_pos_m.max((p - Vector3::new(east, north, 0.0)).norm());
            let (_, _, pose_yaw) = pose.rotation.euler_angles();
            worst_yaw_rad = worst_yaw_rad.max(crate::kitti::wrap_angle_rad(pose_yaw - yaw).abs());
        }
        // 2 s at 0.5 rad/s: a full 1 rad of arc, 20 m of travel.
        let last = poses.last().unwrap().translation.vector;
        assert!(last.norm() > 15.0, "{last}");
        // τ is rebuilt from f64 times (~2.4e-7 s resolution) → ~2.4e-6 m at 10 m/s.
        println!(
            "synthetic 100 Hz drive: time err {worst_time_err:.2e} s, pose err {worst_pos_m:.2e} m / {worst_yaw_rad:.2e} rad over {:.1} m",
            last.norm()
        );
        assert!(worst_pos_m < 1e-5, "{worst_pos_m}");
        assert!(worst_yaw_rad < 1e-6, "{worst_yaw_rad}");

        // Scans load with t_s = sweep start and the written points, raised by
        // KITTI's elevation correction (a raw drive is KITTI's recording).
        let raised = drive.velodyne_scan(0).unwrap();
        let angle = KITTI_HDL64_ELEVATION_CORRECTION_DEG.to_radians();
        assert_eq!(drive.elevation_correction_rad, angle);
        for (a, b) in raised.scan.points.iter().zip(&written.scans[0]) {
            let p = Vector3::new(b.x as f64, b.y as f64, b.z as f64);
            let q = crate::kitti::velodyne::raise_elevation(&p, angle);
            assert_eq!((a.x, a.y, a.z), (q.x as f32, q.y as f32, q.z as f32));
        }
        let mut drive = drive;
        drive.elevation_correction_rad = 0.0;
        assert_eq!(drive.num_scans(), 3);
        for k in 0..3 {
            let frame = &drive.velodyne[k];
            assert_eq!(frame.start_source, SweepStart::Measured);
            assert_eq!(frame.format, ScanFormat::Bin);
            let start = written.scan_starts[k].as_secs_f64();
            assert!((frame.t_start_s - start).abs() < 1e-6);
            assert!((frame.t_trigger_s.unwrap() - (start + 0.05)).abs() < 1e-6);
            assert!((frame.t_end_s.unwrap() - (start + 0.099)).abs() < 1e-6);
            let scan = drive.velodyne_scan(k).unwrap();
            assert_eq!(scan.ring_source, RingSource::ScanLines);
            assert!((scan.scan.t_s - start).abs() < 1e-6);
            assert_eq!(scan.scan.points.len(), written.scans[k].len());
            for (a, b) in scan.scan.points.iter().zip(&written.scans[k]) {
                assert_eq!(
                    (a.x, a.y, a.z, a.intensity, a.ring),
                    (b.x, b.y, b.z, b.intensity, b.ring)
                );
            }
            assert_eq!(drive.scan(k).unwrap(), scan.scan);
        }
        let err = drive.scan(3).unwrap_err().to_string();
        assert!(err.contains("has 3 scans"), "{err}");
    }

    #[test]
    fn extract_style_text_scans_match_binary_scans() {
        let bin = TempDir::new("bin");
        let txt = TempDir::new("txt");
        write_drive(&bin.0, 12, 2, false);
        write_drive(&txt.0, 12, 2, true);
        let a = RawDrive::open(&bin.0).unwrap();
        let b = RawDrive::open(&txt.0).unwrap();
        assert_eq!(b.velodyne[0].format, ScanFormat::Txt);
        for k in 0..2 {
            assert_eq!(a.velodyne_scan(k).unwrap(), b.velodyne_scan(k).unwrap());
        }
        // Malformed text scan line → file:line and field.
        let path = b.velodyne[1].path.clone();
        let text = read_text(&path)
            .unwrap()
            .replacen('\n', "\n1 2 abc 0.5\n", 1);
        write_text(&path, &text).unwrap();
        let err = b.scan(1).unwrap_err().to_string();
        assert!(
            err.contains("0000000001.txt:2") && err.contains("`z`"),
            "{err}"
        );
        let err = parse_velodyne_txt("1 2 3\n", Path::new("s.txt"), 0.0)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("s.txt:1") && err.contains("expected 4"),
            "{err}"
        );
        let err = parse_velodyne_txt("1 2 1e39 0\n", Path::new("s.txt"), 0.0)
            .unwrap_err()
            .to_string();
        assert!(err.contains("overflows f32"), "{err}");
    }

    #[test]
    fn backwards_time_is_an_error_naming_the_line() {
        let tmp = TempDir::new("backwards");
        write_drive(&tmp.0, 20, 1, false);
        let path = tmp.0.join("oxts/timestamps.txt");
        let mut lines: Vec<String> = read_text(&path)
            .unwrap()
            .lines()
            .map(str::to_string)
            .collect();
        lines.swap(6, 7);
        write_text(&path, &(lines.join("\n") + "\n")).unwrap();
        let err = error_text(RawDrive::open(&tmp.0));
        assert!(
            err.contains("timestamps.txt:8") && err.contains("backwards"),
            "{err}"
        );
    }

    #[test]
    fn gaps_are_reported_not_fatal() {
        let tmp = TempDir::new("gap");
        write_drive(&tmp.0, 100, 1, false);
        // Drop records 40..52 (12 samples, 0.13 s hole) and renumber the files.
        let data = tmp.0.join("oxts/data");
        let stamps_path = tmp.0.join("oxts/timestamps.txt");
        let stamps: Vec<String> = read_text(&stamps_path)
            .unwrap()
            .lines()
            .map(str::to_string)
            .collect();
        let keep: Vec<usize> = (0..100).filter(|i| !(40..52).contains(i)).collect();
        let lines: Vec<String> = (0..100)
            .map(|i| read_text(&data.join(format!("{i:010}.txt"))).unwrap())
            .collect();
        std::fs::remove_dir_all(&data).unwrap();
        std::fs::create_dir_all(&data).unwrap();
        let mut new_stamps = String::new();
        for (j, i) in keep.iter().enumerate() {
            write_text(&data.join(format!("{j:010}.txt")), &lines[*i]).unwrap();
            new_stamps += &stamps[*i];
            new_stamps.push('\n');
        }
        write_text(&stamps_path, &new_stamps).unwrap();
        let drive = RawDrive::open(&tmp.0).unwrap();
        assert_eq!(drive.oxts.len(), 88);
        assert_eq!(drive.imu_samples().len(), 88);
        let gaps = drive.gaps();
        assert_eq!(gaps.len(), 1, "{gaps:?}");
        let gap = gaps[0];
        assert_eq!(gap.index, 39);
        let truth_s = (oxts_offset_ns(52) - oxts_offset_ns(39)) as f64 * 1e-9;
        assert!((gap.duration_s() - truth_s).abs() < 1e-6, "{gap}");
        assert_eq!(gap.missing_samples(), 12, "{gap}");
        assert!(gap.to_string().contains("after record 39"), "{gap}");
    }

    #[test]
    fn count_mismatches_and_holes_are_errors() {
        let tmp = TempDir::new("count");
        write_drive(&tmp.0, 20, 3, false);
        // One timestamp too many.
        let stamps = tmp.0.join("oxts/timestamps.txt");
        let original = read_text(&stamps).unwrap();
        write_text(&stamps, &format!("{original}2011-09-26 13:02:59.0\n")).unwrap();
        let err = error_text(RawDrive::open(&tmp.0));
        assert!(
            err.contains("oxts/timestamps.txt") && err.contains("21 timestamps but 20 data files"),
            "{err}"
        );
        write_text(&stamps, &original).unwrap();
        // A hole in the numbering.
        let f = tmp.0.join("oxts/data/0000000005.txt");
        let kept = read_text(&f).unwrap();
        std::fs::remove_file(&f).unwrap();
        let err = error_text(RawDrive::open(&tmp.0));
        assert!(
            err.contains("0000000006.txt") && err.contains("expected frame 0000000005"),
            "{err}"
        );
        write_text(&f, &kept).unwrap();
        // A missing last Velodyne scan.
        std::fs::remove_file(tmp.0.join("velodyne_points/data/0000000002.bin")).unwrap();
        let err = error_text(RawDrive::open(&tmp.0));
        assert!(
            err.contains("velodyne_points/timestamps")
                && err.contains("3 timestamps but 2 data files"),
            "{err}"
        );
        // Mixed .bin and .txt scans.
        write_text(
            &tmp.0.join("velodyne_points/data/0000000000.txt"),
            "1 2 3 4\n",
        )
        .unwrap();
        let err = error_text(RawDrive::open(&tmp.0));
        assert!(err.contains("both .bin"), "{err}");
    }

    #[test]
    fn malformed_oxts_and_sweep_times_are_errors() {
        let tmp = TempDir::new("malformed");
        let written = write_drive(&tmp.0, 10, 2, false);
        let f = tmp.0.join("oxts/data/0000000004.txt");
        let line = written.records[4].to_line().replacen(
            &written.records[4].az_mps2.to_string(),
            "nan",
            1,
        );
        write_text(&f, &(line + "\n")).unwrap();
        let err = error_text(RawDrive::open(&tmp.0));
        assert!(
            err.contains("0000000004.txt:1") && err.contains("`az`"),
            "{err}"
        );
        // Two records in one file.
        let two = written.records[4].to_line() + "\n" + &written.records[4].to_line() + "\n";
        write_text(&f, &two).unwrap();
        let err = error_text(RawDrive::open(&tmp.0));
        assert!(
            err.contains("0000000004.txt") && err.contains("found 2"),
            "{err}"
        );
        write_text(&f, &(written.records[4].to_line() + "\n")).unwrap();
        assert!(RawDrive::open(&tmp.0).is_ok());
        // Sweep end before its trigger.
        let end = tmp.0.join("velodyne_points/timestamps_end.txt");
        let mut lines: Vec<String> = read_text(&end)
            .unwrap()
            .lines()
            .map(str::to_string)
            .collect();
        lines[1] = add_nanos(written.scan_starts[1], 10_000_000).to_string();
        write_text(&end, &(lines.join("\n") + "\n")).unwrap();
        let err = error_text(RawDrive::open(&tmp.0));
        assert!(
            err.contains("timestamps_end.txt:2") && err.contains("before"),
            "{err}"
        );
        // Without timestamps_start the start is derived from the trigger.
        std::fs::remove_file(&end).unwrap();
        std::fs::remove_file(tmp.0.join("velodyne_points/timestamps_start.txt")).unwrap();
        let drive = RawDrive::open(&tmp.0).unwrap();
        let frame = &drive.velodyne[1];
        assert_eq!(frame.start_source, SweepStart::FromTrigger);
        assert!((frame.t_start_s - written.scan_starts[1].as_secs_f64()).abs() < 1e-6);
        // No timestamps at all: refused, pointing to the bare-scan reader.
        std::fs::remove_file(tmp.0.join("velodyne_points/timestamps.txt")).unwrap();
        let err = error_text(RawDrive::open(&tmp.0));
        assert!(err.contains("open_bare_scans"), "{err}");
    }

    #[test]
    fn tracking_scans_are_corrected_unless_declared_otherwise() {
        let tmp = TempDir::new("tracking_elev");
        let velo = tmp.0.join("velodyne/0000");
        std::fs::create_dir_all(&velo).unwrap();
        std::fs::create_dir_all(tmp.0.join("oxts")).unwrap();
        let points = scan_points(0);
        write_bin(&velo.join("000000.bin"), &points).unwrap();
        write_text(
            &tmp.0.join("oxts/0000.txt"),
            &format!("{}\n", circle_record(0.0, 0).to_line()),
        )
        .unwrap();
        let z_of = |drive: &RawDrive| drive.scan(0).unwrap().points[0].z;
        let stored = points[0].z;
        let p = Vector3::new(points[0].x as f64, points[0].y as f64, stored as f64);
        let raise =
            |deg: f64| crate::kitti::velodyne::raise_elevation(&p, f64::to_radians(deg)).z as f32;

        // KITTI's own layout (no times.txt): KITTI's correction.
        let drive = RawDrive::open_tracking_sequence(&tmp.0, 0).unwrap();
        let kitti = KITTI_HDL64_ELEVATION_CORRECTION_DEG.to_radians();
        assert_eq!(drive.elevation_correction_rad, kitti);
        assert_eq!(z_of(&drive), raise(KITTI_HDL64_ELEVATION_CORRECTION_DEG));
        assert_ne!(z_of(&drive), stored);

        // Our copies (times.txt): the points as stored.
        write_text(&tmp.0.join("times.txt"), "0.0\n").unwrap();
        let drive = RawDrive::open_tracking_sequence(&tmp.0, 0).unwrap();
        assert_eq!(drive.elevation_correction_rad, 0.0);
        assert_eq!(z_of(&drive), stored);

        // The declaration file wins either way.
        let declared = tmp.0.join(ELEVATION_CORRECTION_FILE);
        write_text(&declared, "0.1\n").unwrap();
        let drive = RawDrive::open_tracking_sequence(&tmp.0, 0).unwrap();
        assert!((drive.elevation_correction_rad - 0.1f64.to_radians()).abs() < 1e-15);
        assert_eq!(z_of(&drive), raise(0.1));
        std::fs::remove_file(tmp.0.join("times.txt")).unwrap();
        write_text(&declared, "0\n").unwrap();
        let drive = RawDrive::open_tracking_sequence(&tmp.0, 0).unwrap();
        assert_eq!(z_of(&drive), stored);

        // Garbled declarations name the file and line.
        for (text, why) in [
            ("abc\n", "not a number"),
            ("0.2 0.3\n", "one angle"),
            ("\n9\n", "plausible"),
            ("", "empty"),
        ] {
            write_text(&declared, text).unwrap();
            let err = RawDrive::open_tracking_sequence(&tmp.0, 0)
                .unwrap_err()
                .to_string();
            assert!(
                err.contains(ELEVATION_CORRECTION_FILE) && err.contains(why),
                "{err}"
            );
        }
        write_text(&declared, "\n\n0.3\n").unwrap();
        let err = declared_elevation_correction_rad(&tmp.0);
        assert!(err.is_ok());
        write_text(&declared, "9\n").unwrap();
        let err = declared_elevation_correction_rad(&tmp.0)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(&format!("{ELEVATION_CORRECTION_FILE}:1")),
            "{err}"
        );
    }

    #[test]
    fn bare_scans_get_synthetic_10hz_times() {
        let tmp = TempDir::new("bare");
        for k in 0..3 {
            write_bin(&tmp.0.join(format!("{k:010}.bin")), &scan_points(k)).unwrap();
        }
        let drive = RawDrive::open_bare_scans(&tmp.0).unwrap();
        assert!(drive.oxts.is_empty() && drive.imu_samples().is_empty() && drive.gaps().is_empty());
        assert_eq!(drive.num_scans(), 3);
        for k in 0..3 {
            assert_eq!(drive.velodyne[k].start_source, SweepStart::Synthetic10Hz);
            let scan = drive.scan(k).unwrap();
            assert_eq!(scan.t_s, k as f64 * 0.1);
            assert_eq!(scan.points.len(), scan_points(k).len());
            // Read as stored: no elevation correction for bare scans.
            assert_eq!(scan.points[7].z, scan_points(k)[7].z);
        }
        // The 20 real scans of shared/data, when present.
        let real = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kitti_raw_scans");
        if real.is_dir() {
            let drive = RawDrive::open_bare_scans(&real).unwrap();
            assert_eq!(drive.num_scans(), 20);
            let last = drive.velodyne_scan(19).unwrap();
            assert!((last.scan.t_s - 1.9).abs() < 1e-12);
            assert_eq!(last.ring_source, RingSource::ScanLines);
            assert!(last.scan.points.len() > 100_000);
        } else {
            eprintln!(
                "NOTE: {} absent: real bare-scan case not run",
                real.display()
            );
        }
    }

    // Raw calibration of 2011-09-26 (the day of tracking `calib::tests::SAMPLE`).
    const IMU_TO_VELO: &str = "\
calib_time: 25-May-2012 16:47:16
R: 9.999976e-01 7.553071e-04 -2.035826e-03 -7.854027e-04 9.998898e-01 -1.482298e-02 2.024406e-03 1.482454e-02 9.998881e-01
T: -8.086759e-01 3.195559e-01 -7.997231e-01
";
    const VELO_TO_CAM: &str = "\
calib_time: 15-Mar-2012 11:37:16
R: 7.533745e-03 -9.999714e-01 -6.166020e-04 1.480249e-02 7.280733e-04 -9.998902e-01 9.998621e-01 7.523790e-03 1.480755e-02
T: -4.069766e-03 -7.631618e-02 -2.717806e-01
delta_f: 0.000000e+00 0.000000e+00
delta_c: 0.000000e+00 0.000000e+00
";
    const CAM_TO_CAM: &str = "\
calib_time: 09-Jan-2012 13:57:47
corner_dist: 9.950000e-02
S_00: 1.392000e+03 5.120000e+02
K_00: 9.842439e+02 0.000000e+00 6.900000e+02 0.000000e+00 9.808141e+02 2.331966e+02 0.000000e+00 0.000000e+00 1.000000e+00
D_00: -3.728755e-01 2.037299e-01 2.219027e-03 1.383707e-03 -7.233722e-02
R_00: 1.000000e+00 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00
T_00: 2.573699e-16 -1.059758e-16 1.614870e-16
S_rect_00: 1.242000e+03 3.750000e+02
R_rect_00: 9.999239e-01 9.837760e-03 -7.445048e-03 -9.869795e-03 9.999421e-01 -4.278459e-03 7.402527e-03 4.351614e-03 9.999631e-01
P_rect_00: 7.215377e+02 0.000000e+00 6.095593e+02 0.000000e+00 0.000000e+00 7.215377e+02 1.728540e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00
S_rect_01: 1.242000e+03 3.750000e+02
R_rect_01: 9.996878e-01 -8.976826e-03 2.331651e-02 8.876121e-03 9.999508e-01 4.418952e-03 -2.335503e-02 -4.210612e-03 9.997184e-01
P_rect_01: 7.215377e+02 0.000000e+00 6.095593e+02 -3.875744e+02 0.000000e+00 7.215377e+02 1.728540e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00
P_rect_02: 7.215377e+02 0.000000e+00 6.095593e+02 4.485728e+01 0.000000e+00 7.215377e+02 1.728540e+02 2.163791e-01 0.000000e+00 0.000000e+00 1.000000e+00 2.745884e-03
P_rect_03: 7.215377e+02 0.000000e+00 6.095593e+02 -3.395242e+02 0.000000e+00 7.215377e+02 1.728540e+02 2.199936e+00 0.000000e+00 0.000000e+00 1.000000e+00 2.729905e-03
";

    fn write_calib_dir(dir: &Path, cam_to_cam: &str) {
        write_text(&dir.join(RawCalib::IMU_TO_VELO), IMU_TO_VELO).unwrap();
        write_text(&dir.join(RawCalib::VELO_TO_CAM), VELO_TO_CAM).unwrap();
        write_text(&dir.join(RawCalib::CAM_TO_CAM), cam_to_cam).unwrap();
    }

    #[test]
    fn raw_calib_matches_the_tracking_calibration_of_the_same_day() {
        let tmp = TempDir::new("calib");
        write_calib_dir(&tmp.0, CAM_TO_CAM);
        let raw = RawCalib::read(&tmp.0).unwrap();
        let calib = raw.to_calib();
        let tracking = crate::kitti::calib::tests::sample();
        assert_eq!(calib.p0, tracking.p0);
        assert_eq!(calib.p1, tracking.p1);
        assert_eq!(calib.p2, tracking.p2);
        assert_eq!(calib.p3, tracking.p3);
        assert_eq!(calib.r_rect, tracking.r_rect);
        for (a, b) in [
            (calib.t_cam_velo, tracking.t_cam_velo),
            (calib.t_velo_imu, tracking.t_velo_imu),
        ] {
            let d = a.inverse() * b;
            assert!(
                d.translation.vector.norm() < 1e-12 && d.rotation.angle() < 1e-12,
                "{d}"
            );
        }
        // The tracking code path works on it: a point ahead projects into the image.
        let px = calib
            .project_velo_to_image(&Vector3::new(15.0, 0.0, 0.0))
            .unwrap();
        assert!(
            (px.x - 609.0).abs() < 30.0 && px.y > 150.0 && px.y < 250.0,
            "{px}"
        );
    }

    #[test]
    fn raw_calib_errors_name_file_line_and_key() {
        let tmp = TempDir::new("calib_err");
        let missing: String = CAM_TO_CAM
            .lines()
            .filter(|l| !l.starts_with("P_rect_02"))
            .map(|l| format!("{l}\n"))
            .collect();
        write_calib_dir(&tmp.0, &missing);
        let err = RawCalib::read(&tmp.0).unwrap_err().to_string();
        assert!(
            err.contains("calib_cam_to_cam.txt") && err.contains("P_rect_02"),
            "{err}"
        );

        let skew = CAM_TO_CAM.replace("R_rect_00: 9.999239e-01", "R_rect_00: 1.5");
        write_calib_dir(&tmp.0, &skew);
        let err = RawCalib::read(&tmp.0).unwrap_err().to_string();
        assert!(
            err.contains("calib_cam_to_cam.txt:9") && err.contains("orthonormal"),
            "{err}"
        );

        let short = CAM_TO_CAM.replace(" 2.745884e-03", "");
        write_calib_dir(&tmp.0, &short);
        let err = RawCalib::read(&tmp.0).unwrap_err().to_string();
        assert!(
            err.contains("calib_cam_to_cam.txt:14") && err.contains("columns"),
            "{err}"
        );

        let p = |name: &str| PathBuf::from(name);
        let (ip, vp, cp) = (p("imu.txt"), p("velo.txt"), p("cam.txt"));
        let bad_t = IMU_TO_VELO.replace("3.195559e-01", "abc");
        let err = RawCalib::parse((&bad_t, &ip), (VELO_TO_CAM, &vp), (CAM_TO_CAM, &cp))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("imu.txt:3") && err.contains("column 3") && err.contains("`T`"),
            "{err}"
        );
        let no_colon = VELO_TO_CAM.replace("delta_f:", "delta_f");
        let err = RawCalib::parse((IMU_TO_VELO, &ip), (&no_colon, &vp), (CAM_TO_CAM, &cp))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("velo.txt:4") && err.contains("key: values"),
            "{err}"
        );
        let dup = format!("{VELO_TO_CAM}T: 0 0 0\n");
        let err = RawCalib::parse((IMU_TO_VELO, &ip), (&dup, &vp), (CAM_TO_CAM, &cp))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("velo.txt:6") && err.contains("duplicate"),
            "{err}"
        );
        let no_r: String = IMU_TO_VELO
            .lines()
            .filter(|l| !l.starts_with("R:"))
            .map(|l| format!("{l}\n"))
            .collect();
        let err = RawCalib::parse((&no_r, &ip), (VELO_TO_CAM, &vp), (CAM_TO_CAM, &cp))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("imu.txt") && err.contains("missing key `R`"),
            "{err}"
        );
    }

    /// Days since 1970-01-01 by counting, independent of the closed form.
    fn naive_days(year: i64, month: u32, day: u32) -> i64 {
        let mut days = 0i64;
        if year >= 1970 {
            for y in 1970..year {
                days += if is_leap_year(y) { 366 } else { 365 };
            }
        } else {
            for y in year..1970 {
                days -= if is_leap_year(y) { 366 } else { 365 };
            }
        }
        for m in 1..month {
            days += days_in_month(year, m) as i64;
        }
        days + day as i64 - 1
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        #[test]
        fn fuzz_timestamp_parser_never_panics(s in "\\PC{0,40}") {
            let _ = parse_timestamp(&s);
            let _ = parse_timestamps(&s, Path::new("f.txt"));
        }

        #[test]
        fn fuzz_near_valid_timestamps(s in "[0-9]{4}-[0-9]{2}-[0-9]{2} [0-9]{2}:[0-9]{2}:[0-9]{2}(\\.[0-9]{1,10})?") {
            if let Ok(t) = parse_unix_time(&s) {
                // Accepted ⇒ formatting gives the same instant back.
                prop_assert_eq!(parse_unix_time(&t.to_string()).unwrap(), t);
                prop_assert_eq!(&t.to_string()[..19], &s[..19]);
            }
        }

        #[test]
        fn fuzz_date_arithmetic_matches_counting(year in 1900i64..2100, month in 1u32..=12, day in 1u32..=31) {
            prop_assume!(day <= days_in_month(year, month));
            let days = days_from_civil(year, month, day);
            prop_assert_eq!(days, naive_days(year, month, day));
            prop_assert_eq!(civil_from_days(days), (year, month, day));
        }

        #[test]
        fn fuzz_format_parse_round_trip(
            secs in days_from_civil(0, 1, 1) * 86_400..days_from_civil(9999, 12, 31) * 86_400 + 86_400,
            nanos in 0u32..1_000_000_000,
        ) {
            let t = UnixTime { secs, nanos };
            prop_assert_eq!(parse_unix_time(&t.to_string()).unwrap(), t);
        }

        #[test]
        fn fuzz_f64_time_conversion(offset_ns in 0i64..10_000_000_000_000) {
            let t = add_nanos(T0, offset_ns);
            let back = UnixTime::from_secs_f64(t.as_secs_f64());
            let err_ns = (back.secs - t.secs) * 1_000_000_000 + back.nanos as i64 - t.nanos as i64;
            prop_assert!(err_ns.abs() <= 500, "{err_ns}");
        }

        #[test]
        fn fuzz_calib_text_never_panics(pos in 0usize..2000, c in any::<char>(), which in 0usize..3) {
            let mut texts = [IMU_TO_VELO.to_string(), VELO_TO_CAM.to_string(), CAM_TO_CAM.to_string()];
            let t = &mut texts[which];
            let mut chars: Vec<char> = t.chars().collect();
            let i = pos % chars.len();
            chars[i] = c;
            *t = chars.into_iter().collect();
            let (ip, vp, cp) = (PathBuf::from("i"), PathBuf::from("v"), PathBuf::from("c"));
            let _ = RawCalib::parse((&texts[0], &ip), (&texts[1], &vp), (&texts[2], &cp));
        }

        #[test]
        fn fuzz_text_scan_never_panics(s in "([-0-9.e ]{0,30}\n){0,5}") {
            if let Ok(scan) = parse_velodyne_txt(&s, Path::new("s.txt"), 0.0) {
                prop_assert!(scan.scan.points.iter().all(|p| p.position().iter().all(|v| v.is_finite())));
            }
        }
    }
}
