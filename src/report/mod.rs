//! Evaluation reports: markdown tables shaped like the paper's, SVG plots, and
//! the two report directories built from them: the simulated suite's
//! ([`write_suite_report`]) and the KITTI suite's ([`write_kitti_report`]).
//! [`write_report`] gathers sections of tables and plots into a directory with a
//! `README.md`. Everything works on plain data, so the runners in
//! [`crate::experiments`] only fill the row structs and series.
mod baseline;
mod ego_error;
mod kitti;
mod plot;
mod suite;
mod table;

pub use baseline::{
    Regression, Tolerance, baseline_markdown, baseline_summary_table, baseline_table, regressions,
};
pub use ego_error::{EgoErrorSeries, ego_error_series};
pub use kitti::{
    DIVERGED_ATE_PER_PATH, STATIC_EGO_PATH_M, ab3dmot_table, ego_table as kitti_ego_table,
    kitti_report, object_table as kitti_object_table, tracking_table as kitti_tracking_table,
    twins_section, write_kitti_report,
};
pub use plot::{
    ColourScale, ColouredPath, LineKind, Series2D, Style, plot_coloured_path, plot_error_over_time,
    plot_object_tracks, plot_speed, plot_trajectories_xy,
};
pub use suite::{
    ablation_table as suite_ablation_table, build_report, ego_table as suite_ego_table,
    write_suite_report,
};
pub use table::{
    Better, BoldRule, Cell, EgoAte, EgoAteRow, ObjectMetrics, ObjectRow, Table, TimingRow,
    TrackingRow, ego_ate_table, object_table, timing_table, tracking_table,
};

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Why a report, table or plot could not be produced.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("table {table:?}: row {row} has {found} cells, the header has {expected}")]
    /// A row has another number of cells than the header.
    TableShape {
        /// The table's title.
        table: String,
        /// Row index.
        row: usize,
        /// Header length.
        expected: usize,
        /// Cells in the row.
        found: usize,
    },
    #[error("table {table:?}: bold rule names column {column}, the table has {columns}")]
    /// A bold rule names a column the table does not have.
    TableColumn {
        /// The table's title.
        table: String,
        /// The column named.
        column: usize,
        /// Columns of the table.
        columns: usize,
    },
    #[error("{path}: no series to plot")]
    /// A plot has no series.
    NoSeries {
        /// The plot file.
        path: PathBuf,
    },
    #[error("{path}: series {label:?} has no points")]
    /// A series has no points.
    EmptySeries {
        /// The plot file.
        path: PathBuf,
        /// The series' label.
        label: String,
    },
    #[error("{path}: series {label:?} point {index} is not finite ({x}, {y})")]
    /// A point of a series is not finite.
    NonFinite {
        /// The plot file.
        path: PathBuf,
        /// The series' label.
        label: String,
        /// Index of the point.
        index: usize,
        /// Its x.
        x: f64,
        /// Its y.
        y: f64,
    },
    #[error("{path}: plotting failed: {message}")]
    /// The plotting library failed.
    Plot {
        /// The plot file.
        path: PathBuf,
        /// Its message.
        message: String,
    },
    #[error("{path}: plot file name {name:?} must be a plain `*.svg` file name")]
    /// A plot's file name is not a plain `*.svg` name.
    BadPlotName {
        /// The report directory.
        path: PathBuf,
        /// The name.
        name: String,
    },
    #[error("{path}: plot file {name:?} appears twice in the report")]
    /// Two plots of a report have the same file name.
    DuplicatePlot {
        /// The report directory.
        path: PathBuf,
        /// The name.
        name: String,
    },
    #[error("{path}: {source}")]
    /// A file could not be written.
    Io {
        /// The file.
        path: PathBuf,
        #[source]
        /// The cause.
        source: std::io::Error,
    },
}

/// What a plot shows; each maps to one function of `plot`.
#[derive(Debug, Clone, PartialEq)]
pub enum PlotKind {
    /// Ego trajectories, top view (`plot_trajectories_xy`).
    TrajectoriesXy {
        /// One series per trajectory.
        series: Vec<Series2D>,
    },
    /// Object tracks vs truth, top view (`plot_object_tracks`).
    ObjectTracks {
        /// True object trajectories.
        truth: Vec<Series2D>,
        /// Estimated object trajectories.
        est: Vec<Series2D>,
    },
    /// Speed over time (`plot_speed`).
    Speed {
        /// One series per object or variant.
        series: Vec<Series2D>,
    },
    /// An error over time (`plot_error_over_time`); `y_desc` names it and its unit.
    ErrorOverTime {
        /// Axis label: the error and its unit.
        y_desc: String,
        /// One series per variant.
        series: Vec<Series2D>,
    },
    /// A path coloured by a value, top view (`plot_coloured_path`).
    ColouredPath {
        /// Drawn first, e.g. the truth.
        background: Vec<Series2D>,
        /// The coloured path.
        path: ColouredPath,
        /// Value to colour.
        scale: ColourScale,
    },
}

/// One plot of a section, written as `file_name` inside the report directory.
#[derive(Debug, Clone, PartialEq)]
pub struct Plot {
    /// A plain file name ending in `.svg` (no directories).
    pub file_name: String,
    /// Title drawn above the plot.
    pub title: String,
    /// What it shows.
    pub kind: PlotKind,
}

impl Plot {
    /// Draws the plot to `path`.
    ///
    /// # Errors
    ///
    /// As the plot functions ([`plot_trajectories_xy`] and its siblings).
    pub fn draw(&self, path: &Path) -> Result<(), ReportError> {
        match &self.kind {
            PlotKind::TrajectoriesXy { series } => plot_trajectories_xy(path, &self.title, series),
            PlotKind::ObjectTracks { truth, est } => {
                plot_object_tracks(path, &self.title, truth, est)
            }
            PlotKind::Speed { series } => plot_speed(path, &self.title, series),
            PlotKind::ErrorOverTime { y_desc, series } => {
                plot_error_over_time(path, &self.title, y_desc, series)
            }
            PlotKind::ColouredPath {
                background,
                path: coloured,
                scale,
            } => plot_coloured_path(path, &self.title, background, coloured, scale),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Default)]
/// A titled part of a report: text, tables and plots, in that order.
pub struct Section {
    /// Heading.
    pub heading: String,
    /// Markdown paragraph(s) placed under the heading; may be empty.
    pub text: String,
    /// Tables.
    pub tables: Vec<Table>,
    /// Plots.
    pub plots: Vec<Plot>,
}

#[derive(Debug, Clone, PartialEq, Default)]
/// A report: its title and sections, written by [`write_report`].
pub struct Report {
    /// Title.
    pub title: String,
    /// Sections, in order.
    pub sections: Vec<Section>,
}

/// A plot file name must stay inside the report directory and be an SVG.
fn check_plot_name(dir: &Path, name: &str) -> Result<(), ReportError> {
    let plain = !name.is_empty()
        && name.ends_with(".svg")
        && name.len() > ".svg".len()
        && !name.contains(['/', '\\'])
        && name != ".."
        && !name.starts_with('.');
    if plain {
        Ok(())
    } else {
        Err(ReportError::BadPlotName {
            path: dir.join(name),
            name: name.to_string(),
        })
    }
}

/// Spaces and parentheses would break a markdown link target.
fn link_target(name: &str) -> String {
    name.replace(' ', "%20")
        .replace('(', "%28")
        .replace(')', "%29")
}

/// The README text; plots are linked by file name, relative to the README.
///
/// # Errors
///
/// [`ReportError`] when a table does not render or plot names are invalid or repeated.
pub fn render_readme(report: &Report) -> Result<String, ReportError> {
    let mut out = format!("# {}\n", report.title);
    for section in &report.sections {
        out.push_str(&format!("\n## {}\n", section.heading));
        if !section.text.trim().is_empty() {
            out.push_str(&format!("\n{}\n", section.text.trim_end()));
        }
        for table in &section.tables {
            out.push('\n');
            out.push_str(&table.to_markdown()?);
        }
        for plot in &section.plots {
            out.push_str(&format!(
                "\n![{}]({})\n",
                plot.title.replace(['[', ']'], ""),
                link_target(&plot.file_name)
            ));
        }
    }
    Ok(out)
}

/// Writes every plot of `report` as an SVG into `dir` (created if needed) and
/// then `dir/README.md` with the tables and links to the plots. Names and
/// tables are checked before anything is written, so a bad report leaves no
/// half-written README. Returns the README path.
///
/// # Errors
///
/// [`ReportError`] for invalid tables or plots or a failed write.
pub fn write_report(dir: &Path, report: &Report) -> Result<PathBuf, ReportError> {
    let mut seen = BTreeSet::new();
    for plot in report.sections.iter().flat_map(|s| &s.plots) {
        check_plot_name(dir, &plot.file_name)?;
        if !seen.insert(plot.file_name.as_str()) {
            return Err(ReportError::DuplicatePlot {
                path: dir.join(&plot.file_name),
                name: plot.file_name.clone(),
            });
        }
    }
    let readme = render_readme(report)?;
    std::fs::create_dir_all(dir).map_err(|source| ReportError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    for plot in report.sections.iter().flat_map(|s| &s.plots) {
        plot.draw(&dir.join(&plot.file_name))?;
    }
    let readme_path = dir.join("README.md");
    std::fs::write(&readme_path, readme).map_err(|source| ReportError::Io {
        path: readme_path.clone(),
        source,
    })?;
    Ok(readme_path)
}
