//! The checked CSV reader behind the dataset's text streams: a header that
//! must match, numbered rows, and typed fields whose errors name file, line
//! and column.

use super::{RecordError, format_err, io_err, pose_from_array};
use limot_estimator::input::ObjectClass;
use nalgebra::{Isometry3, Vector3};
use std::fs;
use std::path::{Path, PathBuf};

/// A CSV file split into numbered rows with a checked header.
pub(super) struct Csv {
    path: PathBuf,
    text: String,
}

impl Csv {
    pub(super) fn open(path: PathBuf, header: &str) -> Result<Csv, RecordError> {
        let text = fs::read_to_string(&path).map_err(io_err(&path))?;
        let first = text.lines().next().unwrap_or("");
        if first.trim() != header {
            return Err(format_err(
                &path,
                1,
                "header",
                format!("expected `{header}`, found `{first}`"),
            ));
        }
        Ok(Csv { path, text })
    }

    /// Rows after the header as (1-based line, fields), each with exactly
    /// `columns` fields.
    pub(super) fn rows<'a>(&'a self, columns: &[&'a str]) -> Result<Vec<Row<'a>>, RecordError> {
        let mut rows = Vec::new();
        for (i, line) in self.text.lines().enumerate().skip(1) {
            if line.trim().is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            if fields.len() != columns.len() {
                return Err(format_err(
                    &self.path,
                    i + 1,
                    "columns",
                    format!(
                        "{} fields, expected {} ({})",
                        fields.len(),
                        columns.len(),
                        columns.join(",")
                    ),
                ));
            }
            rows.push(Row {
                path: &self.path,
                line: i + 1,
                fields,
                columns: columns.to_vec(),
            });
        }
        Ok(rows)
    }
}

pub(super) struct Row<'a> {
    path: &'a Path,
    line: usize,
    pub(super) fields: Vec<&'a str>,
    columns: Vec<&'a str>,
}

impl Row<'_> {
    pub(super) fn f64(&self, i: usize) -> Result<f64, RecordError> {
        let v: f64 = self.fields[i].parse().map_err(|_| {
            format_err(
                self.path,
                self.line,
                self.columns[i],
                format!("`{}` is not a number", self.fields[i]),
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
        self.fields[i].parse().map_err(|_| {
            format_err(
                self.path,
                self.line,
                self.columns[i],
                format!("`{}` is not a valid integer", self.fields[i]),
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
        ObjectClass::parse(self.fields[i]).ok_or_else(|| {
            format_err(
                self.path,
                self.line,
                self.columns[i],
                format!("unknown class `{}`", self.fields[i]),
            )
        })
    }

    pub(super) fn error(&self, i: usize, message: impl Into<String>) -> RecordError {
        format_err(self.path, self.line, self.columns[i], message)
    }
}
