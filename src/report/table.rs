//! Markdown tables shaped like the paper's: a plain `Table` of typed cells
//! rendered as GitHub markdown with aligned columns, fixed decimals per column,
//! the best value in bold, and missing cells as "–"; plus builders for the
//! ego-ATE, tracking (MOTA/MOTP), per-object and timing tables.

use super::ReportError;

use crate::metrics::{ClearMotResult, ObjectScore, TimingAccumulator};
use limot_estimator::Variant;
use std::collections::BTreeMap;

/// What a missing cell renders as (an en dash, like the paper's "--").
pub const MISSING: &str = "–";

/// Decimals used for a numeric column unless the table says otherwise.
pub const DEFAULT_DECIMALS: usize = 3;

/// One table cell.
#[derive(Debug, Clone, PartialEq)]
pub enum Cell {
    /// Text, rendered as is.
    Text(String),
    /// Rendered with the column's fixed decimals.
    Num(f64),
    /// Rendered as is (counts such as IDSW, FP, FN).
    Int(i64),
    /// No value, rendered as "–".
    Missing,
}

impl From<&str> for Cell {
    fn from(s: &str) -> Cell {
        Cell::Text(s.to_string())
    }
}

impl From<String> for Cell {
    fn from(s: String) -> Cell {
        Cell::Text(s)
    }
}

impl From<f64> for Cell {
    fn from(v: f64) -> Cell {
        Cell::Num(v)
    }
}

impl From<Option<f64>> for Cell {
    fn from(v: Option<f64>) -> Cell {
        v.map_or(Cell::Missing, Cell::Num)
    }
}

impl From<usize> for Cell {
    fn from(v: usize) -> Cell {
        // Counts beyond i64 do not occur in evaluation; saturate rather than wrap.
        Cell::Int(i64::try_from(v).unwrap_or(i64::MAX))
    }
}

/// Which direction of a metric is better.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Better {
    /// Lower is better.
    Lower,
    /// Higher is better.
    Higher,
}

/// Which cells are printed in bold as the best of their comparison set. Values
/// are compared as rounded to their column's decimals, so values that print the
/// same tie (the paper bolds all of them). A set needs two or more finite
/// values, not all equal, to have a best.
#[derive(Debug, Clone, PartialEq)]
pub enum BoldRule {
    /// In every row, the best among `columns` (e.g. ATE_T of each variant).
    BestInRow {
        /// The compared columns.
        columns: Vec<usize>,
        /// Which direction wins.
        better: Better,
    },
    /// In `column`, the best over the rows that agree in the text of every
    /// `group_by` column (e.g. the best variant per sequence); no grouping
    /// compares the whole column.
    BestInColumn {
        /// The column.
        column: usize,
        /// Which direction wins.
        better: Better,
        /// Columns whose text defines a group.
        group_by: Vec<usize>,
    },
}

/// A table of typed cells; every row has one cell per header entry.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// Title, rendered as a heading.
    pub title: String,
    /// Column names.
    pub header: Vec<String>,
    /// Rows of cells.
    pub rows: Vec<Vec<Cell>>,
    /// Fixed decimals of `Cell::Num` per column; columns past its end use
    /// `DEFAULT_DECIMALS`.
    pub decimals: Vec<usize>,
    /// Which cells are bold.
    pub bold: Vec<BoldRule>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Align {
    Left,
    Right,
}

impl Table {
    /// An empty table with the given title and header.
    pub fn new(title: impl Into<String>, header: Vec<String>) -> Table {
        let decimals = vec![DEFAULT_DECIMALS; header.len()];
        Table {
            title: title.into(),
            header,
            rows: Vec::new(),
            decimals,
            bold: Vec::new(),
        }
    }

    /// Sets the fixed decimals of one column (ignored past the last column).
    pub fn set_decimals(&mut self, column: usize, decimals: usize) {
        if column < self.decimals.len() {
            self.decimals[column] = decimals;
        }
    }

    /// Appends a row after checking it has one cell per column.
    ///
    /// # Errors
    ///
    /// [`ReportError::TableShape`] when the row's length differs from the header's.
    pub fn push_row(&mut self, row: Vec<Cell>) -> Result<(), ReportError> {
        self.check_row(self.rows.len(), &row)?;
        self.rows.push(row);
        Ok(())
    }

    /// Appends a row `label` (in `label_column`) holding the mean of every other
    /// column over the current rows. A column's mean is only given when every
    /// row has a finite number there (a mean over a subset would not compare
    /// across variants); otherwise the cell is missing.
    ///
    /// # Errors
    ///
    /// [`ReportError::TableShape`] when the row's length differs from the header's.
    pub fn push_mean_row(&mut self, label: &str, label_column: usize) -> Result<(), ReportError> {
        if self.rows.is_empty() {
            return Ok(());
        }
        let mut row = Vec::with_capacity(self.header.len());
        for col in 0..self.header.len() {
            if col == label_column {
                row.push(Cell::Text(label.to_string()));
                continue;
            }
            let values: Option<Vec<f64>> = self
                .rows
                .iter()
                .map(|r| r.get(col).and_then(cell_value).filter(|v| v.is_finite()))
                .collect();
            row.push(match values {
                Some(v) => Cell::Num(v.iter().sum::<f64>() / v.len() as f64),
                None => Cell::Missing,
            });
        }
        self.push_row(row)
    }

    fn decimals_of(&self, column: usize) -> usize {
        self.decimals
            .get(column)
            .copied()
            .unwrap_or(DEFAULT_DECIMALS)
    }

    fn check_row(&self, index: usize, row: &[Cell]) -> Result<(), ReportError> {
        if row.len() != self.header.len() {
            return Err(ReportError::TableShape {
                table: self.title.clone(),
                row: index,
                expected: self.header.len(),
                found: row.len(),
            });
        }
        Ok(())
    }

    fn check_column(&self, column: usize) -> Result<(), ReportError> {
        if column >= self.header.len() {
            return Err(ReportError::TableColumn {
                table: self.title.clone(),
                column,
                columns: self.header.len(),
            });
        }
        Ok(())
    }

    /// The text a cell prints (before bold and escaping).
    fn cell_text(&self, column: usize, cell: &Cell) -> String {
        match cell {
            Cell::Text(s) => s.clone(),
            Cell::Num(v) => format_fixed(*v, self.decimals_of(column)),
            Cell::Int(v) => v.to_string(),
            Cell::Missing => MISSING.to_string(),
        }
    }

    /// The value a cell is compared by: its number rounded as printed.
    fn rank_value(&self, column: usize, cell: &Cell) -> Option<f64> {
        match cell {
            Cell::Num(v) if v.is_finite() => format_fixed(*v, self.decimals_of(column))
                .parse::<f64>()
                .ok(),
            Cell::Int(v) => Some(*v as f64),
            _ => None,
        }
    }

    /// Marks the best cells of `candidates` (row, column) in `bold`.
    fn mark_best(&self, candidates: &[(usize, usize)], better: Better, bold: &mut [Vec<bool>]) {
        let ranked: Vec<((usize, usize), f64)> = candidates
            .iter()
            .filter_map(|&(r, c)| self.rank_value(c, &self.rows[r][c]).map(|v| ((r, c), v)))
            .collect();
        if ranked.len() < 2 {
            return;
        }
        let best = ranked
            .iter()
            .map(|&(_, v)| v)
            .reduce(|a, b| match better {
                Better::Lower => a.min(b),
                Better::Higher => a.max(b),
            })
            .unwrap_or(f64::NAN);
        // When every value ties there is no best to point out.
        if ranked.iter().all(|&(_, v)| v == best) {
            return;
        }
        for &((r, c), v) in &ranked {
            if v == best {
                bold[r][c] = true;
            }
        }
    }

    fn bold_mask(&self) -> Result<Vec<Vec<bool>>, ReportError> {
        let mut bold = vec![vec![false; self.header.len()]; self.rows.len()];
        for rule in &self.bold {
            match rule {
                BoldRule::BestInRow { columns, better } => {
                    for &c in columns {
                        self.check_column(c)?;
                    }
                    for r in 0..self.rows.len() {
                        let cands: Vec<(usize, usize)> = columns.iter().map(|&c| (r, c)).collect();
                        self.mark_best(&cands, *better, &mut bold);
                    }
                }
                BoldRule::BestInColumn {
                    column,
                    better,
                    group_by,
                } => {
                    self.check_column(*column)?;
                    for &g in group_by {
                        self.check_column(g)?;
                    }
                    let mut groups: BTreeMap<Vec<String>, Vec<(usize, usize)>> = BTreeMap::new();
                    for (r, row) in self.rows.iter().enumerate() {
                        let key = group_by
                            .iter()
                            .map(|&g| self.cell_text(g, &row[g]))
                            .collect();
                        groups.entry(key).or_default().push((r, *column));
                    }
                    for cands in groups.values() {
                        self.mark_best(cands, *better, &mut bold);
                    }
                }
            }
        }
        Ok(bold)
    }

    /// GitHub markdown: the title in bold, a blank line, then the table with
    /// columns padded to a common width. Text columns are left-aligned, columns
    /// holding numbers right-aligned.
    ///
    /// # Errors
    ///
    /// [`ReportError`] when a row's shape or a bold rule's column is invalid.
    pub fn to_markdown(&self) -> Result<String, ReportError> {
        for (i, row) in self.rows.iter().enumerate() {
            self.check_row(i, row)?;
        }
        let bold = self.bold_mask()?;
        let ncol = self.header.len();
        let align: Vec<Align> = (0..ncol)
            .map(|c| {
                let numeric = self
                    .rows
                    .iter()
                    .any(|r| matches!(r[c], Cell::Num(_) | Cell::Int(_)));
                if numeric { Align::Right } else { Align::Left }
            })
            .collect();
        let body: Vec<Vec<String>> = self
            .rows
            .iter()
            .enumerate()
            .map(|(r, row)| {
                row.iter()
                    .enumerate()
                    .map(|(c, cell)| {
                        let text = escape_cell(&self.cell_text(c, cell));
                        if bold[r][c] {
                            format!("**{text}**")
                        } else {
                            text
                        }
                    })
                    .collect()
            })
            .collect();
        let header: Vec<String> = self.header.iter().map(|h| escape_cell(h)).collect();
        // Width in characters (not bytes: "–" is one column but three bytes);
        // at least 3 so the separator row is valid markdown.
        let width: Vec<usize> = (0..ncol)
            .map(|c| {
                body.iter()
                    .map(|r| r[c].chars().count())
                    .chain(std::iter::once(header[c].chars().count()))
                    .max()
                    .unwrap_or(0)
                    .max(3)
            })
            .collect();
        let pad = |text: &str, c: usize| {
            let fill = " ".repeat(width[c] - text.chars().count());
            match align[c] {
                Align::Left => format!("{text}{fill}"),
                Align::Right => format!("{fill}{text}"),
            }
        };
        let line = |cells: Vec<String>| format!("| {} |\n", cells.join(" | "));

        let mut out = String::new();
        if !self.title.is_empty() {
            out.push_str(&format!("**{}**\n\n", self.title));
        }
        out.push_str(&line(
            header.iter().enumerate().map(|(c, h)| pad(h, c)).collect(),
        ));
        out.push_str(&line(
            (0..ncol)
                .map(|c| match align[c] {
                    Align::Left => format!(":{}", "-".repeat(width[c] - 1)),
                    Align::Right => format!("{}:", "-".repeat(width[c] - 1)),
                })
                .collect(),
        ));
        for row in &body {
            out.push_str(&line(
                row.iter().enumerate().map(|(c, t)| pad(t, c)).collect(),
            ));
        }
        Ok(out)
    }
}

/// The numeric value of a cell, if it has one.
fn cell_value(cell: &Cell) -> Option<f64> {
    match cell {
        Cell::Num(v) => Some(*v),
        Cell::Int(v) => Some(*v as f64),
        _ => None,
    }
}

/// Fixed decimals; "-0.000" prints as "0.000" and non-finite values spell
/// themselves out (a NaN metric must stay visible, not look missing).
pub fn format_fixed(v: f64, decimals: usize) -> String {
    if v.is_nan() {
        return "NaN".to_string();
    }
    if v.is_infinite() {
        return if v > 0.0 { "inf" } else { "-inf" }.to_string();
    }
    let s = format!("{v:.decimals$}");
    match s.strip_prefix('-') {
        Some(rest) if rest.chars().all(|ch| ch == '0' || ch == '.') => rest.to_string(),
        _ => s,
    }
}

/// A pipe would end the cell early and a line break the row.
fn escape_cell(text: &str) -> String {
    text.replace('|', "\\|").replace(['\r', '\n'], " ")
}

// ---------------------------------------------------------------- builders

/// Ego-pose ATE of one variant on one sequence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EgoAte {
    /// ATE_T, m.
    pub ate_t_m: f64,
    /// ATE_R, rad.
    pub ate_r_rad: f64,
}

/// One sequence of the ego ATE table (paper Table "tab_ego_track").
#[derive(Debug, Clone, PartialEq)]
pub struct EgoAteRow {
    /// Sequence name.
    pub sequence: String,
    /// ATE per variant.
    pub per_variant: BTreeMap<Variant, EgoAte>,
}

/// Variants present in any row, in `Variant` order.
fn variants_of(maps: impl Iterator<Item = Vec<Variant>>) -> Vec<Variant> {
    let mut all: Vec<Variant> = maps.flatten().collect();
    all.sort();
    all.dedup();
    all
}

/// Seq | per variant: ATE_T \[m\], ATE_R \[rad\]; a final "mean" row; the best
/// variant per row and metric in bold.
///
/// # Errors
///
/// [`ReportError`] when the table cannot be built.
pub fn ego_ate_table(title: &str, rows: &[EgoAteRow]) -> Result<Table, ReportError> {
    let variants = variants_of(rows.iter().map(|r| r.per_variant.keys().copied().collect()));
    let mut header = vec!["Seq".to_string()];
    for v in &variants {
        header.push(format!("{} ATE_T [m]", v.label()));
        header.push(format!("{} ATE_R [rad]", v.label()));
    }
    let mut table = Table::new(title, header);
    for row in rows {
        let mut cells = vec![Cell::Text(row.sequence.clone())];
        for v in &variants {
            match row.per_variant.get(v) {
                Some(a) => cells.extend([Cell::Num(a.ate_t_m), Cell::Num(a.ate_r_rad)]),
                None => cells.extend([Cell::Missing, Cell::Missing]),
            }
        }
        table.push_row(cells)?;
    }
    table.push_mean_row("mean", 0)?;
    let n = variants.len();
    table.bold = vec![
        BoldRule::BestInRow {
            columns: (0..n).map(|i| 1 + 2 * i).collect(),
            better: Better::Lower,
        },
        BoldRule::BestInRow {
            columns: (0..n).map(|i| 2 + 2 * i).collect(),
            better: Better::Lower,
        },
    ];
    Ok(table)
}

/// CLEAR-MOT result of one variant on one sequence at one IoU threshold
/// (paper Table "tab_ab3dmot_compare" reports MOTP at 0.25 and 0.5).
#[derive(Debug, Clone, PartialEq)]
pub struct TrackingRow {
    /// Sequence name.
    pub sequence: String,
    /// The variant.
    pub variant: Variant,
    /// The 3D IoU threshold.
    pub iou_threshold: f64,
    /// MOTA, %.
    pub mota_percent: Option<f64>,
    /// MOTP, %.
    pub motp_percent: Option<f64>,
    /// ID switches.
    pub idsw: usize,
    /// False positives.
    pub fp: usize,
    /// False negatives.
    pub fn_: usize,
}

impl TrackingRow {
    /// Converts the fractions of `eval::clear_mot` to percent.
    pub fn from_clear_mot(
        sequence: &str,
        variant: Variant,
        iou_threshold: f64,
        result: &ClearMotResult,
    ) -> TrackingRow {
        TrackingRow {
            sequence: sequence.to_string(),
            variant,
            iou_threshold,
            mota_percent: result.mota.map(|m| 100.0 * m),
            motp_percent: result.motp.map(|m| 100.0 * m),
            idsw: result.id_switches,
            fp: result.false_positives,
            fn_: result.false_negatives,
        }
    }
}

/// Seq | Variant | IoU thr | MOTA [%] | MOTP [%] | IDSW | FP | FN; the best
/// variant per sequence and threshold in bold for every metric.
///
/// # Errors
///
/// [`ReportError`] when the table cannot be built.
pub fn tracking_table(title: &str, rows: &[TrackingRow]) -> Result<Table, ReportError> {
    let header = [
        "Seq", "Variant", "IoU thr", "MOTA [%]", "MOTP [%]", "IDSW", "FP", "FN",
    ]
    .map(String::from)
    .to_vec();
    let mut table = Table::new(title, header);
    table.set_decimals(2, 2);
    table.set_decimals(3, 2);
    table.set_decimals(4, 2);
    for row in rows {
        table.push_row(vec![
            Cell::Text(row.sequence.clone()),
            Cell::Text(row.variant.label().to_string()),
            Cell::Num(row.iou_threshold),
            row.mota_percent.into(),
            row.motp_percent.into(),
            row.idsw.into(),
            row.fp.into(),
            row.fn_.into(),
        ])?;
    }
    let group_by = vec![0, 2];
    table.bold = [
        (3, Better::Higher),
        (4, Better::Higher),
        (5, Better::Lower),
        (6, Better::Lower),
        (7, Better::Lower),
    ]
    .map(|(column, better)| BoldRule::BestInColumn {
        column,
        better,
        group_by: group_by.clone(),
    })
    .to_vec();
    Ok(table)
}

/// Pose accuracy of one tracked object under one variant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectMetrics {
    /// Tracked frames over ground-truth frames, in percent.
    pub tp_percent: f64,
    /// `None` when the object was never matched.
    pub ate_t_m: Option<f64>,
    /// ATE_R of the object's track, rad.
    pub ate_r_rad: Option<f64>,
}

impl From<&ObjectScore> for ObjectMetrics {
    fn from(s: &ObjectScore) -> ObjectMetrics {
        ObjectMetrics {
            tp_percent: s.tp_percent,
            ate_t_m: s.ate_t_rmse_m,
            ate_r_rad: s.ate_r_rmse_rad,
        }
    }
}

/// One object of the per-object table (paper Table "tab_obj_track").
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectRow {
    /// Sequence name.
    pub sequence: String,
    /// Ground-truth object id.
    pub object_id: u64,
    /// Scores per variant.
    pub per_variant: BTreeMap<Variant, ObjectMetrics>,
}

/// Seq / Obj | per variant: TP [%], ATE_T \[m\], ATE_R \[rad\]; a final "mean"
/// row; the best variant per row and metric in bold.
///
/// # Errors
///
/// [`ReportError`] when the table cannot be built.
pub fn object_table(title: &str, rows: &[ObjectRow]) -> Result<Table, ReportError> {
    let variants = variants_of(rows.iter().map(|r| r.per_variant.keys().copied().collect()));
    let mut header = vec!["Seq / Obj".to_string()];
    for v in &variants {
        header.push(format!("{} TP [%]", v.label()));
        header.push(format!("{} ATE_T [m]", v.label()));
        header.push(format!("{} ATE_R [rad]", v.label()));
    }
    let mut table = Table::new(title, header);
    for i in 0..variants.len() {
        table.set_decimals(1 + 3 * i, 2);
    }
    for row in rows {
        let mut cells = vec![Cell::Text(format!("{} / {}", row.sequence, row.object_id))];
        for v in &variants {
            match row.per_variant.get(v) {
                Some(m) => cells.extend([
                    Cell::Num(m.tp_percent),
                    m.ate_t_m.into(),
                    m.ate_r_rad.into(),
                ]),
                None => cells.extend([Cell::Missing, Cell::Missing, Cell::Missing]),
            }
        }
        table.push_row(cells)?;
    }
    table.push_mean_row("mean", 0)?;
    let n = variants.len();
    table.bold = [(1, Better::Higher), (2, Better::Lower), (3, Better::Lower)]
        .map(|(offset, better)| BoldRule::BestInRow {
            columns: (0..n).map(|i| offset + 3 * i).collect(),
            better,
        })
        .to_vec();
    Ok(table)
}

/// Runtime of one module (paper Table "tab_time_consume").
#[derive(Debug, Clone, PartialEq)]
pub struct TimingRow {
    /// Pipeline stage.
    pub module: String,
    /// Mean wall time, ms.
    pub mean_ms: f64,
    /// 95th-percentile wall time, ms.
    pub p95_ms: f64,
    /// Scans per second this module alone allows (1000 / mean_ms).
    pub fps: f64,
}

impl TimingRow {
    /// The row of `module` in an accumulator; `None` when it has no samples.
    pub fn from_accumulator(acc: &TimingAccumulator, module: &str) -> Option<TimingRow> {
        let stats = acc.stats(module)?;
        let p95_s = acc.percentile_s(module, 95.0)?;
        Some(TimingRow {
            module: module.to_string(),
            mean_ms: 1e3 * stats.mean_s,
            p95_ms: 1e3 * p95_s,
            fps: stats.fps,
        })
    }
}

/// A stage faster than this did no work in the variant (the object filter
/// of `lio`): its FPS is no figure worth printing.
const NO_WORK_MS: f64 = 1e-3;

/// Module | mean \[ms\] | p95 \[ms\] | FPS, one decimal each; FPS is missing
/// for stages that did no work.
///
/// # Errors
///
/// [`ReportError`] when the table cannot be built.
pub fn timing_table(title: &str, rows: &[TimingRow]) -> Result<Table, ReportError> {
    let header = ["Module", "mean [ms]", "p95 [ms]", "FPS"]
        .map(String::from)
        .to_vec();
    let mut table = Table::new(title, header);
    for c in 1..4 {
        table.set_decimals(c, 1);
    }
    for row in rows {
        table.push_row(vec![
            Cell::Text(row.module.clone()),
            Cell::Num(row.mean_ms),
            Cell::Num(row.p95_ms),
            if row.mean_ms < NO_WORK_MS {
                Cell::Missing
            } else {
                Cell::Num(row.fps)
            },
        ])?;
    }
    Ok(table)
}

#[cfg(test)]
mod tests;
