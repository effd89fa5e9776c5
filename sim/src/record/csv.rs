//! The checked CSV reader behind the dataset's text streams: a header that
//! must match, numbered rows, and typed fields whose errors name file, line
//! and column.

use super::{RecordError, format_err, io_err, pose_from_array};
use limot_estimator::input::ObjectClass;
use nalgebra::{Isometry3, Vector3};
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

/// A CSV file with a checked header, read row by row: a long drive's
/// ground truth is never held as text.
pub(super) struct Csv {
    path: PathBuf,
    reader: BufReader<File>,
}

impl Csv {
    pub(super) fn open(path: PathBuf, header: &str) -> Result<Csv, RecordError> {
        let file = File::open(&path).map_err(io_err(&path))?;
        let mut reader = BufReader::with_capacity(1 << 16, file);
        let mut first = String::new();
        reader.read_line(&mut first).map_err(io_err(&path))?;
        if first.trim() != header {
            return Err(format_err(
                &path,
                1,
                "header",
                format!("expected `{header}`, found `{}`", first.trim_end()),
            ));
        }
        Ok(Csv { path, reader })
    }

    /// The rows after the header, in order, as (1-based line, fields), each
    /// with exactly `columns` fields; blank lines are skipped.
    pub(super) fn rows<'a>(&'a mut self, columns: &'a [&'a str]) -> Rows<'a> {
        Rows {
            path: &self.path,
            reader: &mut self.reader,
            line: 1,
            columns,
        }
    }
}

/// The iterator of [`Csv::rows`].
pub(super) struct Rows<'a> {
    path: &'a Path,
    reader: &'a mut BufReader<File>,
    line: usize,
    columns: &'a [&'a str],
}

impl<'a> Iterator for Rows<'a> {
    type Item = Result<Row<'a>, RecordError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            let mut text = String::new();
            match self.reader.read_line(&mut text) {
                Ok(0) => return None,
                Ok(_) => {}
                Err(e) => return Some(Err(io_err(self.path)(e))),
            }
            self.line += 1;
            let body = text.trim_end_matches(['\n', '\r']);
            if body.trim().is_empty() {
                continue;
            }
            let mut spans = Vec::with_capacity(self.columns.len());
            let mut start = 0;
            for piece in body.split(',') {
                let lead = piece.len() - piece.trim_start().len();
                spans.push((start + lead, start + lead + piece.trim().len()));
                start += piece.len() + 1;
            }
            if spans.len() != self.columns.len() {
                return Some(Err(format_err(
                    self.path,
                    self.line,
                    "columns",
                    format!(
                        "{} fields, expected {} ({})",
                        spans.len(),
                        self.columns.len(),
                        self.columns.join(",")
                    ),
                )));
            }
            return Some(Ok(Row {
                path: self.path,
                line: self.line,
                text,
                spans,
                columns: self.columns,
            }));
        }
    }
}

pub(super) struct Row<'a> {
    path: &'a Path,
    line: usize,
    text: String,
    spans: Vec<(usize, usize)>,
    columns: &'a [&'a str],
}

impl Row<'_> {
    /// Field `i`, trimmed.
    pub(super) fn field(&self, i: usize) -> &str {
        let (from, to) = self.spans[i];
        &self.text[from..to]
    }

    pub(super) fn f64(&self, i: usize) -> Result<f64, RecordError> {
        let v: f64 = self.field(i).parse().map_err(|_| {
            format_err(
                self.path,
                self.line,
                self.columns[i],
                format!("`{}` is not a number", self.field(i)),
            )
        })?;
        if !v.is_finite() {
            return Err(format_err(
                self.path,
                self.line,
                self.columns[i],
                format!("{v} is not finite"),
            ));
        }
        Ok(v)
    }

    pub(super) fn int<T: std::str::FromStr>(&self, i: usize) -> Result<T, RecordError> {
        self.field(i).parse().map_err(|_| {
            format_err(
                self.path,
                self.line,
                self.columns[i],
                format!("`{}` is not a valid integer", self.field(i)),
            )
        })
    }

    pub(super) fn vec3(&self, i: usize) -> Result<Vector3<f64>, RecordError> {
        Ok(Vector3::new(
            self.f64(i)?,
            self.f64(i + 1)?,
            self.f64(i + 2)?,
        ))
    }

    pub(super) fn pose(&self, i: usize) -> Result<Isometry3<f64>, RecordError> {
        let mut a = [0.0; 7];
        for (k, v) in a.iter_mut().enumerate() {
            *v = self.f64(i + k)?;
        }
        let qn = (a[3] * a[3] + a[4] * a[4] + a[5] * a[5] + a[6] * a[6]).sqrt();
        if (qn - 1.0).abs() > 1e-3 {
            return Err(format_err(
                self.path,
                self.line,
                self.columns[i + 3],
                format!("quaternion norm {qn} is not 1"),
            ));
        }
        Ok(pose_from_array(&a))
    }

    /// A time stamp strictly after `previous` (streams never go backwards).
    pub(super) fn increasing_time(
        &self,
        i: usize,
        previous: Option<f64>,
    ) -> Result<f64, RecordError> {
        let t_s = self.f64(i)?;
        match previous {
            Some(prev) if t_s <= prev => {
                Err(self.error(i, format!("time {t_s} does not increase (previous {prev})")))
            }
            _ => Ok(t_s),
        }
    }

    /// Three finite, positive box dimensions.
    pub(super) fn size(&self, i: usize) -> Result<Vector3<f64>, RecordError> {
        let size = self.vec3(i)?;
        if let Some(k) = (0..3).find(|&k| size[k] <= 0.0) {
            return Err(self.error(i + k, format!("{} is not a positive size", size[k])));
        }
        Ok(size)
    }

    pub(super) fn class(&self, i: usize) -> Result<ObjectClass, RecordError> {
        ObjectClass::parse(self.field(i)).ok_or_else(|| {
            format_err(
                self.path,
                self.line,
                self.columns[i],
                format!("unknown class `{}`", self.field(i)),
            )
        })
    }

    pub(super) fn error(&self, i: usize, message: impl Into<String>) -> RecordError {
        format_err(self.path, self.line, self.columns[i], message)
    }
}
