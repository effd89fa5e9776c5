//! A suite's results beside a baseline's (`limot report NEW --baseline OLD`):
//! per sequence and variant the ego ATE_T and the 3D CLEAR-MOT at IoU 0.25
//! before and after, the truth count with them (a changed ground truth moves
//! MOTA without any change of the tracker), per-variant summaries, and the
//! changes that count as regressions under a [`Tolerance`].
//!
//! Sequences are matched by name and variants by variant; a sequence or
//! variant on one side only is listed with its missing side empty, never
//! silently dropped.

use super::{Cell, ReportError, Table};
use crate::experiments::{MotMetrics, SuiteResults, VariantMetrics};
use limot_estimator::Variant;

/// What counts as a regression against the baseline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// ATE_T may grow by this fraction of the baseline's...
    pub ate_fraction: f64,
    /// ...or by this much, whichever is larger, m.
    pub ate_m: f64,
    /// 3D MOTA@0.25 may fall by this much (fraction, 0.02 = 2 points).
    pub mota_drop: f64,
}

impl Default for Tolerance {
    /// 5 % or 1 cm of ATE_T (the larger), 2 points of MOTA.
    fn default() -> Tolerance {
        Tolerance {
            ate_fraction: 0.05,
            ate_m: 0.01,
            mota_drop: 0.02,
        }
    }
}

/// One figure of one run that got worse than the tolerance allows.
#[derive(Debug, Clone, PartialEq)]
pub struct Regression {
    /// Sequence name.
    pub sequence: String,
    /// The variant.
    pub variant: Variant,
    /// `ATE_T [m]` or `MOTA 3D@0.25`.
    pub figure: &'static str,
    /// The baseline's value.
    pub before: f64,
    /// This suite's value.
    pub after: f64,
}

impl std::fmt::Display for Regression {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} / {}: {} {:.4} -> {:.4}",
            self.sequence,
            self.variant.label(),
            self.figure,
            self.before,
            self.after
        )
    }
}

/// The compared figures of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Figures {
    ate_t_m: f64,
    mot: Option<Counts>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Counts {
    mota: Option<f64>,
    errors: usize,
    gt_count: usize,
}

impl Figures {
    fn of(m: &VariantMetrics) -> Figures {
        Figures {
            ate_t_m: m.ego.ate_t_m,
            mot: m.mot("3D", 0.25).map(Counts::of),
        }
    }
}

impl Counts {
    fn of(m: &MotMetrics) -> Counts {
        let c = &m.counts;
        Counts {
            mota: c.mota,
            errors: c.false_positives + c.false_negatives + c.id_switches,
            gt_count: c.gt_count,
        }
    }
}

/// One (sequence, variant) on both sides.
struct Pair {
    sequence: String,
    variant: Variant,
    before: Option<Figures>,
    after: Option<Figures>,
}

/// Every (sequence, variant) of either side: this suite's order, then what
/// only the baseline has.
fn pairs(results: &SuiteResults, baseline: &SuiteResults) -> Vec<Pair> {
    let figures = |r: &SuiteResults, name: &str, v: Variant| {
        r.sequences
            .iter()
            .find(|s| s.name == name)
            .and_then(|s| s.metrics(v))
            .map(Figures::of)
    };
    let mut keys: Vec<(String, Variant)> = Vec::new();
    for side in [results, baseline] {
        for s in &side.sequences {
            for v in side.variants.iter().copied() {
                let key = (s.name.clone(), v);
                if !keys.contains(&key) {
                    keys.push(key);
                }
            }
        }
    }
    keys.into_iter()
        .map(|(sequence, variant)| Pair {
            before: figures(baseline, &sequence, variant),
            after: figures(results, &sequence, variant),
            sequence,
            variant,
        })
        .collect()
}

fn mota_percent(f: Option<Figures>) -> Cell {
    f.and_then(|f| f.mot)
        .and_then(|m| m.mota)
        .map_or(Cell::Missing, |m| Cell::Num(100.0 * m))
}

fn gt_count(f: Option<Figures>) -> Cell {
    f.and_then(|f| f.mot)
        .map_or(Cell::Missing, |m| m.gt_count.into())
}

/// Per sequence and variant: ATE_T and 3D MOTA@0.25 (with its truth count)
/// in the baseline and here.
///
/// # Errors
/// [`ReportError`] when the table cannot be built.
pub fn baseline_table(
    results: &SuiteResults,
    baseline: &SuiteResults,
) -> Result<Table, ReportError> {
    let mut table = Table::new(
        "Against the baseline: ego ATE_T and 3D MOTA@0.25 per sequence and variant",
        [
            "Sequence",
            "Variant",
            "ATE_T base [m]",
            "ATE_T [m]",
            "ratio",
            "MOTA base [%]",
            "MOTA [%]",
            "GT base",
            "GT",
        ]
        .map(String::from)
        .to_vec(),
    );
    for column in [5, 6] {
        table.set_decimals(column, 1);
    }
    for p in pairs(results, baseline) {
        let (b, a) = (p.before.map(|f| f.ate_t_m), p.after.map(|f| f.ate_t_m));
        let ratio = match (b, a) {
            (Some(b), Some(a)) if b > 0.0 => Cell::Num(a / b),
            _ => Cell::Missing,
        };
        table.push_row(vec![
            p.sequence.into(),
            p.variant.label().into(),
            b.into(),
            a.into(),
            ratio,
            mota_percent(p.before),
            mota_percent(p.after),
            gt_count(p.before),
            gt_count(p.after),
        ])?;
    }
    Ok(table)
}

/// Per variant over the sequences both sides scored: mean ATE_T, pooled 3D
/// MOTA@0.25 (1 - errors / truth summed over sequences) and the number of
/// regressions among `found` ([`regressions`]).
///
/// # Errors
/// [`ReportError`] when the table cannot be built.
pub fn baseline_summary_table(
    results: &SuiteResults,
    baseline: &SuiteResults,
    found: &[Regression],
) -> Result<Table, ReportError> {
    let mut table = Table::new(
        "Against the baseline, per variant (sequences scored on both sides)",
        [
            "Variant",
            "sequences",
            "mean ATE_T base [m]",
            "mean ATE_T [m]",
            "pooled MOTA base [%]",
            "pooled MOTA [%]",
            "regressions",
        ]
        .map(String::from)
        .to_vec(),
    );
    for column in [4, 5] {
        table.set_decimals(column, 1);
    }
    let all = pairs(results, baseline);
    for v in results.variants.iter().copied() {
        let both: Vec<(Figures, Figures)> = all
            .iter()
            .filter(|p| p.variant == v)
            .filter_map(|p| Some((p.before?, p.after?)))
            .collect();
        if both.is_empty() {
            continue;
        }
        let n = both.len() as f64;
        let mean = |side: fn(&(Figures, Figures)) -> Figures| {
            both.iter().map(|f| side(f).ate_t_m).sum::<f64>() / n
        };
        let pooled = |side: fn(&(Figures, Figures)) -> Figures| {
            let counts: Option<Vec<Counts>> = both.iter().map(|f| side(f).mot).collect();
            let counts = counts?;
            let gt: usize = counts.iter().map(|c| c.gt_count).sum();
            let errors: usize = counts.iter().map(|c| c.errors).sum();
            (gt > 0).then(|| 100.0 * (1.0 - errors as f64 / gt as f64))
        };
        table.push_row(vec![
            v.label().into(),
            both.len().into(),
            mean(|f| f.0).into(),
            mean(|f| f.1).into(),
            pooled(|f| f.0).into(),
            pooled(|f| f.1).into(),
            found.iter().filter(|r| r.variant == v).count().into(),
        ])?;
    }
    Ok(table)
}

/// The figures that got worse than `tolerance` allows, over the runs both
/// sides scored, plus every run the baseline scored and this suite did not
/// (reported with `after` NaN: a run that stopped working is a regression).
pub fn regressions(
    results: &SuiteResults,
    baseline: &SuiteResults,
    tolerance: &Tolerance,
) -> Vec<Regression> {
    let mut out = Vec::new();
    for p in pairs(results, baseline) {
        let Some(before) = p.before else { continue };
        let regression = |figure, before, after| Regression {
            sequence: p.sequence.clone(),
            variant: p.variant,
            figure,
            before,
            after,
        };
        let in_results = results.sequences.iter().any(|s| s.name == p.sequence)
            && results.variants.contains(&p.variant);
        let Some(after) = p.after else {
            if in_results {
                out.push(regression("ATE_T [m]", before.ate_t_m, f64::NAN));
            }
            continue;
        };
        let allowed_m = (tolerance.ate_fraction * before.ate_t_m).max(tolerance.ate_m);
        if after.ate_t_m > before.ate_t_m + allowed_m || !after.ate_t_m.is_finite() {
            out.push(regression("ATE_T [m]", before.ate_t_m, after.ate_t_m));
        }
        let mota = |f: Figures| f.mot.and_then(|m| m.mota);
        if let (Some(b), Some(a)) = (mota(before), mota(after))
            && a < b - tolerance.mota_drop
        {
            out.push(regression("MOTA 3D@0.25", b, a));
        }
    }
    out
}

/// The baseline comparison as a markdown page: `tolerance` stated, both
/// tables and the regressions `found` under it ([`regressions`]).
///
/// # Errors
/// [`ReportError`] when a table cannot be built.
pub fn baseline_markdown(
    results: &SuiteResults,
    baseline: &SuiteResults,
    baseline_name: &str,
    tolerance: &Tolerance,
    found: &[Regression],
) -> Result<String, ReportError> {
    let mut out = format!(
        "# Against the baseline {baseline_name}\n\nRegression: ATE_T up by more than \
         {:.0} % or {:.3} m (the larger), or 3D MOTA@0.25 down by more than {:.1} points; \
         a run the baseline scored and this suite did not. MOTA moves with its truth \
         (GT columns) as well as with the tracker.\n\n",
        100.0 * tolerance.ate_fraction,
        tolerance.ate_m,
        100.0 * tolerance.mota_drop
    );
    out += &baseline_summary_table(results, baseline, found)?.to_markdown()?;
    out += "\n";
    if found.is_empty() {
        out += "No regressions.\n\n";
    } else {
        out += &format!("{} regression(s):\n\n", found.len());
        for r in found {
            out += &format!("- {r}\n");
        }
        out += "\n";
    }
    out += &baseline_table(results, baseline)?.to_markdown()?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiments::{EgoMetrics, RESULTS_FORMAT_VERSION, SequenceResult, VariantResult};
    use crate::metrics::MotSummary;
    use std::path::PathBuf;

    /// A scored run: ATE_T, and 3D@0.25 counts (fp + fn errors over gt).
    fn scored(variant: Variant, ate_t_m: f64, errors: usize, gt_count: usize) -> VariantResult {
        let mot = MotMetrics {
            iou_kind: "3D".into(),
            iou_threshold: 0.25,
            counts: MotSummary {
                mota: Some(1.0 - errors as f64 / gt_count as f64),
                motp: Some(0.7),
                id_switches: 0,
                false_positives: errors / 2,
                false_negatives: errors - errors / 2,
                matches: gt_count - (errors - errors / 2),
                gt_count,
            },
        };
        VariantResult {
            variant,
            run_dir: PathBuf::from("runs"),
            metrics: Some(VariantMetrics {
                frames_estimated: 10,
                frames_before_init: 1,
                wall_time_s: 1.0,
                fps: 10.0,
                ego: EgoMetrics {
                    ate_t_m,
                    ate_r_rad: 0.001,
                    ate_max_m: 2.0 * ate_t_m,
                    pairs: 10,
                    rpe_t_m: None,
                    rpe_r_rad: None,
                    ate_along_m: None,
                    degenerate_match_share: None,
                },
                clear_mot: vec![mot],
                clear_mot_car: Vec::new(),
                objects: Vec::new(),
                timings: Vec::new(),
                filtering: None,
            }),
            error: None,
        }
    }

    fn failed(variant: Variant) -> VariantResult {
        VariantResult {
            variant,
            run_dir: PathBuf::from("runs"),
            metrics: None,
            error: Some("diverged".into()),
        }
    }

    fn suite(sequences: Vec<(&str, Vec<VariantResult>)>) -> SuiteResults {
        SuiteResults {
            format_version: RESULTS_FORMAT_VERSION,
            families: vec!["urban".into()],
            twins: None,
            seeds: vec![1],
            duration_s: 1.0,
            variants: vec![Variant::Lio, Variant::Limot],
            ablations: Vec::new(),
            shard: None,
            sequences: sequences
                .into_iter()
                .map(|(name, variants)| SequenceResult {
                    name: name.into(),
                    family: "urban".into(),
                    seed: 1,
                    frames: 10,
                    dataset_dir: PathBuf::from(name),
                    path_length_m: None,
                    moving_objects: Vec::new(),
                    error: None,
                    variants,
                    ablations: Vec::new(),
                })
                .collect(),
        }
    }

    fn baseline() -> SuiteResults {
        suite(vec![
            (
                "a",
                vec![
                    scored(Variant::Lio, 1.0, 10, 100),
                    scored(Variant::Limot, 0.009, 20, 100),
                ],
            ),
            (
                "b",
                vec![
                    scored(Variant::Lio, 0.5, 0, 50),
                    scored(Variant::Limot, 0.2, 5, 50),
                ],
            ),
            ("only-in-baseline", vec![scored(Variant::Lio, 0.1, 0, 10)]),
        ])
    }

    #[test]
    fn the_same_results_have_no_regressions() {
        let b = baseline();
        assert!(regressions(&b, &b, &Tolerance::default()).is_empty());
        let table = baseline_table(&b, &b).unwrap();
        assert_eq!(table.rows.len(), 6);
        for row in &table.rows {
            assert!(matches!(row[4], Cell::Num(r) if r == 1.0) || row[4] == Cell::Missing);
        }
    }

    #[test]
    fn regressions_are_beyond_both_ate_allowances_or_a_mota_drop() {
        let after = suite(vec![
            (
                "a",
                vec![
                    // +4 %: within 5 %
                    scored(Variant::Lio, 1.04, 10, 100),
                    // +50 % but 4.5 mm, under 1 cm; MOTA 80 -> 77 %
                    scored(Variant::Limot, 0.0135, 23, 100),
                ],
            ),
            (
                "b",
                vec![
                    // +6 % and 3 cm; MOTA 100 -> 98.5 % on a grown truth
                    scored(Variant::Lio, 0.53, 1, 70),
                    failed(Variant::Limot),
                ],
            ),
        ]);
        let found = regressions(&after, &baseline(), &Tolerance::default());
        let names: Vec<String> = found.iter().map(ToString::to_string).collect();
        assert_eq!(found.len(), 3, "{names:?}");
        assert_eq!(
            (found[0].sequence.as_str(), found[0].variant),
            ("a", Variant::Limot)
        );
        assert_eq!(found[0].figure, "MOTA 3D@0.25");
        assert!((found[0].before - 0.8).abs() < 1e-12 && (found[0].after - 0.77).abs() < 1e-12);
        assert_eq!(
            (found[1].sequence.as_str(), found[1].figure),
            ("b", "ATE_T [m]")
        );
        // a run that stopped being scored
        assert_eq!(
            (found[2].sequence.as_str(), found[2].variant),
            ("b", Variant::Limot)
        );
        assert!(found[2].after.is_nan());
        // the sequence this suite did not run is listed, not a regression
        let table = baseline_table(&after, &baseline()).unwrap();
        let only = table
            .rows
            .iter()
            .find(|r| {
                r[0] == Cell::Text("only-in-baseline".into()) && r[1] == Variant::Lio.label().into()
            })
            .unwrap();
        assert_eq!(
            (only[2].clone(), only[3].clone()),
            (Cell::Num(0.1), Cell::Missing)
        );
        let grown = table
            .rows
            .iter()
            .find(|r| r[0] == "b".into() && r[1] == Variant::Lio.label().into())
            .unwrap();
        assert_eq!(
            (grown[7].clone(), grown[8].clone()),
            (Cell::Int(50), Cell::Int(70))
        );
    }

    #[test]
    fn the_summary_pools_errors_over_the_truth_of_sequences_scored_twice() {
        let after = suite(vec![
            (
                "a",
                vec![scored(Variant::Lio, 2.0, 30, 100), failed(Variant::Limot)],
            ),
            (
                "b",
                vec![
                    scored(Variant::Lio, 1.0, 0, 50),
                    scored(Variant::Limot, 0.2, 5, 50),
                ],
            ),
        ]);
        let found = regressions(&after, &baseline(), &Tolerance::default());
        let table = baseline_summary_table(&after, &baseline(), &found).unwrap();
        let lio = &table.rows[0];
        assert_eq!(lio[0], Variant::Lio.label().into());
        assert_eq!(lio[1], Cell::Int(2));
        assert_eq!(
            (lio[2].clone(), lio[3].clone()),
            (Cell::Num(0.75), Cell::Num(1.5))
        );
        // (10 + 0) / 150 errors before, (30 + 0) / 150 after
        let pooled = |c: &Cell| match c {
            Cell::Num(v) => *v,
            other => panic!("{other:?}"),
        };
        assert!((pooled(&lio[4]) - 100.0 * (1.0 - 10.0 / 150.0)).abs() < 1e-9);
        assert!((pooled(&lio[5]) - 80.0).abs() < 1e-9);
        assert_eq!(lio[6], Cell::Int(3)); // ATE on a and b, MOTA on a
        // limot: only b is scored on both sides
        assert_eq!(table.rows[1][1], Cell::Int(1));
    }
}
