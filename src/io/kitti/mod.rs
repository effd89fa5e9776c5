//! KITTI readers and writers: one module per file format of the tracking
//! benchmark (calib, labels, object_labels, detections, oxts, poses, results,
//! seqmap, velodyne), [`raw`] for raw drives and the tracking-sequence
//! opener, [`export`] for the KITTI-style copy of a simulated dataset and
//! [`twin`] for a sequence as the simulator's replay input (digital twins).
//!
//! Frames used throughout:
//! - `cam` / `rect`: the rectified camera-0 frame of KITTI (x right, y down,
//!   z forward); label and detection boxes live here (bottom centre of the box).
//! - `velo` / `lidar`: the Velodyne frame (x forward, y left, z up) = our ego
//!   LiDAR frame.
//! - `imu`: the OXTS frame (x forward, y left, z up).
//!
//! Every parser takes the text (or bytes) and the path it came from, so that
//! every [`KittiError`] names the file, the 1-based line and the field.

pub mod calib;
pub mod detections;
pub mod export;
pub mod labels;
pub mod object_labels;
pub mod oxts;
pub mod poses;
pub mod raw;
pub mod results;
pub mod seqmap;
pub mod twin;
pub mod velodyne;

use std::path::{Path, PathBuf};

/// KITTI's frame period (10 Hz): the time step of frame-indexed files that carry no times.
pub const KITTI_FRAME_PERIOD_S: f64 = 0.1;

/// Why a KITTI file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum KittiError {
    /// The file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A field of a line is malformed.
    #[error("{}:{line}: column {column} (`{field}`): {why}", path.display())]
    Field {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column (whitespace- or comma-separated token).
        column: usize,
        /// Name of the field.
        field: &'static str,
        /// What is wrong with it.
        why: String,
    },
    /// A line has the wrong number of columns.
    #[error("{}:{line}: expected {expected} columns, found {found}", path.display())]
    ColumnCount {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// The column counts accepted (e.g. `17 or 18`).
        expected: String,
        /// The columns found.
        found: usize,
    },
    /// A line is malformed as a whole.
    #[error("{}:{line}: {why}", path.display())]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong with it.
        why: String,
    },
    /// A key-value file lacks a required key.
    #[error("{}: missing key `{key}`", path.display())]
    MissingKey {
        /// The file.
        path: PathBuf,
        /// The key.
        key: &'static str,
    },
    /// A binary file is malformed.
    #[error("{}: byte offset {byte_offset}: {why}", path.display())]
    Binary {
        /// The file.
        path: PathBuf,
        /// Offset of the problem.
        byte_offset: u64,
        /// What is wrong.
        why: String,
    },
    /// The file is well-formed but its content is inconsistent.
    #[error("{}: {why}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        why: String,
    },
}

/// Result of the KITTI readers and writers.
pub type Result<T> = std::result::Result<T, KittiError>;

/// Reads a whole text file, mapping I/O errors to [`KittiError::Io`].
///
/// # Errors
/// The file cannot be read ([`KittiError::Io`]).
pub fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|source| KittiError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes a whole text file, mapping I/O errors to [`KittiError::Io`].
///
/// # Errors
/// The file cannot be written ([`KittiError::Io`]).
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|source| KittiError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Where a token came from, for error messages.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LineCtx<'a> {
    pub path: &'a Path,
    /// 1-based line number.
    pub line: usize,
}

impl<'a> LineCtx<'a> {
    pub fn new(path: &'a Path, line: usize) -> Self {
        LineCtx { path, line }
    }

    pub fn field_error(&self, column: usize, field: &'static str, why: String) -> KittiError {
        KittiError::Field {
            path: self.path.to_path_buf(),
            line: self.line,
            column,
            field,
            why,
        }
    }

    pub fn line_error(&self, why: String) -> KittiError {
        KittiError::Line {
            path: self.path.to_path_buf(),
            line: self.line,
            why,
        }
    }

    pub fn column_count(&self, expected: &str, found: usize) -> KittiError {
        KittiError::ColumnCount {
            path: self.path.to_path_buf(),
            line: self.line,
            expected: expected.to_string(),
            found,
        }
    }

    /// Parses a finite f64 (NaN and infinities are errors).
    pub fn f64(&self, token: &str, column: usize, field: &'static str) -> Result<f64> {
        let value: f64 = token
            .parse()
            .map_err(|_| self.field_error(column, field, format!("`{token}` is not a number")))?;
        if !value.is_finite() {
            return Err(self.field_error(column, field, format!("`{token}` is not finite")));
        }
        Ok(value)
    }

    /// Parses an integer; also accepts a float with an integral value ("4.0").
    pub fn i64(&self, token: &str, column: usize, field: &'static str) -> Result<i64> {
        if let Ok(v) = token.parse::<i64>() {
            return Ok(v);
        }
        match token.parse::<f64>() {
            Ok(v) if v.is_finite() && v.fract() == 0.0 && v.abs() < 9.0e15 => Ok(v as i64),
            _ => Err(self.field_error(column, field, format!("`{token}` is not an integer"))),
        }
    }

    /// Parses a non-negative integer that fits in u32.
    pub fn u32(&self, token: &str, column: usize, field: &'static str) -> Result<u32> {
        let v = self.i64(token, column, field)?;
        u32::try_from(v).map_err(|_| {
            self.field_error(column, field, format!("`{token}` is not in 0..=4294967295"))
        })
    }
}

/// Non-empty lines of a text file with their 1-based line numbers
/// (blank lines and trailing `\r` are skipped).
pub(crate) fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_end_matches('\r')))
        .filter(|(_, l)| !l.trim().is_empty())
}

/// Path of a per-sequence file, e.g. `root/training/calib/0001.txt`.
pub fn sequence_file(dir: &Path, sequence: u32) -> PathBuf {
    dir.join(format!("{sequence:04}.txt"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn number_parsing_rejects_nan_and_names_the_field() {
        let path = Path::new("x.txt");
        let ctx = LineCtx::new(path, 7);
        let err = ctx.f64("nan", 3, "ry").unwrap_err().to_string();
        assert!(err.contains("x.txt:7") && err.contains("column 3") && err.contains("ry"));
        assert!(ctx.f64("inf", 1, "a").is_err());
        assert_eq!(ctx.i64("4.0", 1, "n").unwrap(), 4);
        assert!(ctx.i64("4.5", 1, "n").is_err());
        assert!(ctx.u32("-1", 1, "n").is_err());
    }
}
