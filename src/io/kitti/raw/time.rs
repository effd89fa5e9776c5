//! KITTI timestamps: the calendar parser and timestamp files.

use crate::io::kitti::{LineCtx, Result, content_lines, read_text};
use std::fmt;
use std::path::Path;

// ---------------------------------------------------------------------------
// Timestamps
// ---------------------------------------------------------------------------

/// Seconds since 1970-01-01 of a proleptic Gregorian date (Howard Hinnant's
/// `days_from_civil`; exact integer arithmetic).
pub(super) fn days_from_civil(year: i64, month: u32, day: u32) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let yoe = y - era * 400; // [0, 399]
    let m = month as i64;
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + day as i64 - 1; // [0, 365]
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy; // [0, 146096]
    era * 146_097 + doe - 719_468
}

/// Inverse of [`days_from_civil`]: (year, month, day).
pub(super) fn civil_from_days(days: i64) -> (i64, u32, u32) {
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

pub(super) fn is_leap_year(year: i64) -> bool {
    (year % 4 == 0 && year % 100 != 0) || year % 400 == 0
}

pub(super) fn days_in_month(year: i64, month: u32) -> u32 {
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
    /// Whole seconds since the Unix epoch.
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
///
/// ```
/// use limot::io::kitti::raw::{UnixTime, parse_unix_time};
/// let t = parse_unix_time("2011-09-26 13:02:25.964389445").unwrap();
/// assert_eq!(t, UnixTime { secs: 1_317_042_145, nanos: 964_389_445 });
/// assert!(parse_unix_time("2011-02-30 00:00:00").is_err());
/// ```
///
/// # Errors
/// A malformed date or time, or one out of range (e.g. February 30th).
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
///
/// ```
/// use limot::io::kitti::raw::parse_timestamp;
/// let t_s = parse_timestamp("2011-09-26 13:02:25.964389445").unwrap();
/// assert!((t_s - 1_317_042_145.964_389_445).abs() < 1e-6);
/// ```
///
/// # Errors
/// A malformed timestamp (see [`parse_unix_time`]).
pub fn parse_timestamp(s: &str) -> std::result::Result<f64, String> {
    parse_unix_time(s).map(|t| t.as_secs_f64())
}

/// Parses a timestamp file (one stamp per non-blank line) and rejects time
/// going backwards; errors name the file and line.
///
/// # Errors
/// A malformed timestamp, or time going backwards (file and line).
pub fn parse_timestamps(text: &str, path: &Path) -> Result<Vec<f64>> {
    Ok(parse_timestamp_lines(text, path)?
        .into_iter()
        .map(|(_, t)| t)
        .collect())
}

/// [`parse_timestamps`] keeping each stamp's 1-based line number.
pub(super) fn parse_timestamp_lines(text: &str, path: &Path) -> Result<Vec<(usize, f64)>> {
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
///
/// # Errors
/// An unreadable file, or a malformed one (see [`parse_timestamps`]).
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
