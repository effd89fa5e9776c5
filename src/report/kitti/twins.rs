//! The KITTI twins of a suite (`limot eval suite --families kitti`) in the
//! shapes of the paper's Tables I-III, beside the paper's rows for the same
//! sequences ([`super::paper`]): ego ATE per variant, the variants ranked per
//! sequence by ATE_T in the twin and in the paper and how often the two
//! orderings agree, class-Car tracking, and the paper's objects in the twins.
//!
//! Rankings compare ATE_T to the millimetre (the paper's precision), so
//! values equal to the millimetre tie in both orderings.

use super::paper::{
    PAPER_OBJECT_METHODS, PAPER_TABLE_III, paper_ego, paper_name, paper_table_ii_rows,
};
use crate::experiments::{SequenceResult, SuiteResults, format_sequences, twin_sequence};
use crate::io::kitti::twin::twin_agent_id;
use crate::metrics::{MotSummary, best_items, kendall_tau_b};
use crate::report::table::{Better, BoldRule, Cell, Table, format_fixed};
use crate::report::{ReportError, Section};
use limot_estimator::Variant;
use std::fmt::Write as _;

/// Decimals ATE_T is ranked at (the paper prints millimetres).
const RANK_DECIMALS: usize = 3;

/// A twin whose true ego path is shorter than this has a static ego: its
/// ATE_R is an alignment artefact of a path of no length.
pub const STATIC_EGO_PATH_M: f64 = 1.0;

/// A variant whose ATE_T exceeds this share of the path has diverged (every
/// row of the paper's Table I stays below 1.3 %).
pub const DIVERGED_ATE_PER_PATH: f64 = 0.02;

/// One twin of the suite with what the tables need.
struct Twin<'a> {
    sequence: u32,
    label: String,
    result: &'a SequenceResult,
}

impl Twin<'_> {
    /// ATE_T and ATE_R of `v` in the twin.
    fn ours(&self, v: Variant) -> Option<(f64, f64)> {
        self.result
            .metrics(v)
            .map(|m| (m.ego.ate_t_m, m.ego.ate_r_rad))
    }

    fn is_static(&self) -> bool {
        self.result
            .path_length_m
            .is_some_and(|p| p < STATIC_EGO_PATH_M)
    }

    /// The variants whose ATE_T exceeds [`DIVERGED_ATE_PER_PATH`] of the
    /// path, with that share.
    fn diverged(&self, variants: &[Variant]) -> Vec<(Variant, f64)> {
        let Some(path) = self
            .result
            .path_length_m
            .filter(|&p| p >= STATIC_EGO_PATH_M)
        else {
            return Vec::new();
        };
        variants
            .iter()
            .filter_map(|&v| Some((v, self.ours(v)?.0 / path)))
            .filter(|&(_, share)| share > DIVERGED_ATE_PER_PATH)
            .collect()
    }
}

/// The twins of `results`, in the suite's order.
fn twins(results: &SuiteResults) -> Vec<Twin<'_>> {
    let several_seeds = results.seeds.len() > 1;
    results
        .sequences
        .iter()
        .filter_map(|s| {
            let sequence = twin_sequence(&s.family)?;
            let label = if several_seeds {
                format!("{sequence:04} s{}", s.seed)
            } else {
                format!("{sequence:04}")
            };
            Some(Twin {
                sequence,
                label,
                result: s,
            })
        })
        .collect()
}

fn rank_value(ate_t_m: f64) -> f64 {
    format_fixed(ate_t_m, RANK_DECIMALS)
        .parse()
        .unwrap_or(f64::NAN)
}

/// `limot < dynafilt < lio = allfilt`: the variants best first, ties `=`.
fn ordering_text(scored: &[(Variant, f64)]) -> String {
    if scored.len() < 2 {
        return "–".to_string();
    }
    let mut sorted = scored.to_vec();
    sorted.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    let mut text = sorted[0].0.name().to_string();
    for w in sorted.windows(2) {
        text.push_str(if w[1].1 == w[0].1 { " = " } else { " < " });
        text.push_str(w[1].0.name());
    }
    text
}

/// The compared variants' ranked ATE_T in the twin and in the paper, when
/// every variant has both.
fn paired_scores(twin: &Twin, variants: &[Variant]) -> Option<(Vec<f64>, Vec<f64>)> {
    variants
        .iter()
        .map(|&v| {
            let ours = rank_value(twin.ours(v)?.0);
            let paper = paper_ego(twin.sequence, v)?.0;
            Some((ours, paper))
        })
        .collect::<Option<Vec<_>>>()
        .map(|pairs| pairs.into_iter().unzip())
}

/// How one twin's ordering compares with the paper's.
struct Agreement {
    tau_b: Option<f64>,
    best_same: bool,
}

fn agreement(ours: &[f64], paper: &[f64]) -> Agreement {
    let (best_ours, best_paper) = (best_items(ours), best_items(paper));
    Agreement {
        tau_b: kendall_tau_b(ours, paper),
        best_same: best_ours.iter().any(|i| best_paper.contains(i)),
    }
}

/// Table I's shape: per twin, the paper's row and ours, each with its ordering.
fn ego_table(twins: &[Twin], variants: &[Variant]) -> Result<Table, ReportError> {
    let mut header = vec!["Seq".to_string(), "Source".to_string()];
    for v in variants {
        header.push(format!("{} ATE_T [m]", v.label()));
        header.push(format!("{} ATE_R [rad]", v.label()));
    }
    header.push("path [m]".into());
    header.push("ordering by ATE_T".into());
    let path_column = header.len() - 2;
    let mut table = Table::new(
        "Ego ATE (SE(3)-aligned RMSE) on the KITTI twins beside the paper's Table I",
        header,
    );
    for i in 0..variants.len() {
        table.set_decimals(3 + 2 * i, 4);
    }
    table.set_decimals(path_column, 0);
    for twin in twins {
        let paper: Vec<Option<(f64, f64)>> = variants
            .iter()
            .map(|&v| paper_ego(twin.sequence, v))
            .collect();
        if paper.iter().any(Option::is_some) {
            let mut cells = vec![
                Cell::from(twin.label.as_str()),
                Cell::from("paper, Table I (real KITTI)"),
            ];
            for p in &paper {
                // ATE_R as the paper prints it (three decimals), not padded
                // to the twin's four
                let r = p.map_or(Cell::Missing, |x| Cell::from(format_fixed(x.1, 3)));
                cells.extend([p.map(|x| x.0).into(), r]);
            }
            cells.push(Cell::Missing);
            let scored: Vec<(Variant, f64)> = variants
                .iter()
                .zip(&paper)
                .filter_map(|(&v, p)| Some((v, (*p)?.0)))
                .collect();
            cells.push(Cell::from(ordering_text(&scored)));
            table.push_row(cells)?;
        }
        let mut cells = vec![Cell::from(twin.label.as_str()), Cell::from("ours, twin")];
        for &v in variants {
            let ours = twin.ours(v);
            cells.extend([ours.map(|x| x.0).into(), ours.map(|x| x.1).into()]);
        }
        cells.push(twin.result.path_length_m.into());
        let scored: Vec<(Variant, f64)> = variants
            .iter()
            .filter_map(|&v| Some((v, rank_value(twin.ours(v)?.0))))
            .collect();
        cells.push(Cell::from(if twin.result.error.is_some() {
            "not available".to_string()
        } else {
            ordering_text(&scored)
        }));
        table.push_row(cells)?;
    }
    table.bold.push(BoldRule::BestInRow {
        columns: (0..variants.len()).map(|i| 2 + 2 * i).collect(),
        better: Better::Lower,
    });
    Ok(table)
}

/// What is special about a twin, for the agreement table.
fn notes(twin: &Twin, variants: &[Variant]) -> String {
    let mut notes: Vec<String> = Vec::new();
    if twin.result.error.is_some() {
        notes.push("not available (see Failures)".into());
    }
    if variants
        .iter()
        .all(|&v| paper_ego(twin.sequence, v).is_none())
    {
        notes.push("no paper row".into());
    }
    if twin.is_static() {
        notes.push(format!(
            "static ego (path {:.1} m): ATE_R meaningless",
            twin.result.path_length_m.unwrap_or(0.0)
        ));
    }
    for (v, share) in twin.diverged(variants) {
        notes.push(format!(
            "{} diverged (ATE_T {:.1} % of the path)",
            v.name(),
            100.0 * share
        ));
    }
    if twin.result.error.is_none() {
        for &v in variants {
            if twin.result.metrics(v).is_none() {
                notes.push(format!("{}: not available", v.name()));
            }
        }
    }
    notes.join("; ")
}

/// Per twin: best variant in the paper and in the twin, whether they agree,
/// Kendall's τ_b of the two orderings, and notes.
fn agreement_table(twins: &[Twin], variants: &[Variant]) -> Result<Table, ReportError> {
    let mut table = Table::new(
        "Ordering of the variants by ATE_T: twin against the paper",
        [
            "Seq",
            "best (paper)",
            "best (twin)",
            "same best",
            "Kendall τ_b",
            "notes",
        ]
        .map(String::from)
        .to_vec(),
    );
    table.set_decimals(4, 2);
    let names = |scores: &[f64]| {
        best_items(scores)
            .iter()
            .map(|&i| variants[i].name())
            .collect::<Vec<_>>()
            .join(" = ")
    };
    for twin in twins {
        let mut cells = vec![Cell::from(twin.label.as_str())];
        match paired_scores(twin, variants) {
            Some((ours, paper)) => {
                let a = agreement(&ours, &paper);
                cells.extend([
                    Cell::from(names(&paper)),
                    Cell::from(names(&ours)),
                    Cell::from(if a.best_same { "yes" } else { "no" }),
                    a.tau_b.into(),
                ]);
            }
            None => cells.extend(vec![Cell::Missing; 4]),
        }
        cells.push(Cell::from(notes(twin, variants)));
        table.push_row(cells)?;
    }
    Ok(table)
}

/// The agreement summed over `twins`: (compared, best same, identical, mean τ_b).
fn agreement_counts(twins: &[&Twin], variants: &[Variant]) -> (usize, usize, usize, Option<f64>) {
    let (mut compared, mut best_same, mut identical) = (0, 0, 0);
    let mut taus = Vec::new();
    for twin in twins {
        let Some((ours, paper)) = paired_scores(twin, variants) else {
            continue;
        };
        let a = agreement(&ours, &paper);
        compared += 1;
        best_same += usize::from(a.best_same);
        if let Some(t) = a.tau_b {
            identical += usize::from(t == 1.0);
            taus.push(t);
        }
    }
    let mean = (!taus.is_empty()).then(|| taus.iter().sum::<f64>() / taus.len() as f64);
    (compared, best_same, identical, mean)
}

/// One line of agreement counts over `twins`, described by `what`.
fn agreement_line(what: &str, twins: &[&Twin], variants: &[Variant]) -> String {
    let (compared, best_same, identical, mean) = agreement_counts(twins, variants);
    if compared == 0 {
        return format!("{what}: no twin has a paper row and every variant scored.");
    }
    format!(
        "{what}: {compared} twin(s) compared; best variant the same on {best_same}, \
         ordering identical on {identical}, mean Kendall τ_b {}.",
        mean.map_or("–".to_string(), |t| format!("{t:.2}"))
    )
}

/// Per pair of variants: on how many twins with a paper row the first has
/// the lower ATE_T in the paper, in the twin, and in both or neither.
fn pairwise_table(twins: &[Twin], variants: &[Variant]) -> Result<Table, ReportError> {
    let mut table = Table::new(
        "Pairs of variants: on how many of the compared twins the first has the lower ATE_T",
        ["Pair", "compared", "paper", "twin", "same verdict"]
            .map(String::from)
            .to_vec(),
    );
    let paired: Vec<(Vec<f64>, Vec<f64>)> = twins
        .iter()
        .filter_map(|t| paired_scores(t, variants))
        .collect();
    let sign = |x: f64, y: f64| i8::from(x > y) - i8::from(x < y);
    for i in (0..variants.len()).rev() {
        for j in (0..i).rev() {
            let (mut paper, mut ours, mut same) = (0usize, 0usize, 0usize);
            for (o, p) in &paired {
                paper += usize::from(p[i] < p[j]);
                ours += usize::from(o[i] < o[j]);
                same += usize::from(sign(o[i], o[j]) == sign(p[i], p[j]));
            }
            table.push_row(vec![
                Cell::from(format!(
                    "{} vs {}",
                    variants[i].label(),
                    variants[j].label()
                )),
                paired.len().into(),
                paper.into(),
                ours.into(),
                same.into(),
            ])?;
        }
    }
    Ok(table)
}

/// Table II's shape: the paper's MOTP rows, then ours: class Car, 3D IoU,
/// combined over the twins where every tracking variant was scored.
fn tracking_table(twins: &[Twin], variants: &[Variant]) -> Result<Table, ReportError> {
    let mut table = Table::new(
        "Tracking, class Car, 3D IoU: MOTA / MOTP at 0.25 and 0.5 [%] as in the paper's Table II; IDSW / FP / FN at 0.25",
        [
            "Method",
            "Source",
            "twins",
            "MOTA@0.25",
            "MOTP@0.25",
            "MOTA@0.5",
            "MOTP@0.5",
            "IDSW",
            "FP",
            "FN",
            "GT",
        ]
        .map(String::from)
        .to_vec(),
    );
    for c in 3..7 {
        table.set_decimals(c, 2);
    }
    for cells in paper_table_ii_rows("paper, Table II (real KITTI, CenterPoint)", false) {
        table.push_row(cells)?;
    }
    let trackers: Vec<Variant> = variants
        .iter()
        .copied()
        .filter(|v| v.tracks_objects())
        .collect();
    let car = |twin: &Twin, v: Variant, threshold: f64| {
        twin.result
            .metrics(v)
            .and_then(|m| m.car_mot("3D", threshold))
            .map(|m| m.counts.clone())
    };
    let scored: Vec<&Twin> = twins
        .iter()
        .filter(|t| {
            trackers
                .iter()
                .all(|&v| car(t, v, 0.25).is_some() && car(t, v, 0.5).is_some())
        })
        .collect();
    if scored.is_empty() {
        return Ok(table);
    }
    for &v in &trackers {
        let combined = |threshold: f64| {
            let parts: Vec<MotSummary> =
                scored.iter().filter_map(|t| car(t, v, threshold)).collect();
            MotSummary::combine(&parts)
        };
        let (at25, at50) = (combined(0.25), combined(0.5));
        let pct = |x: Option<f64>| Cell::from(x.map(|v| 100.0 * v));
        table.push_row(vec![
            Cell::from(v.label()),
            Cell::from("ours, twins"),
            scored.len().into(),
            pct(at25.mota),
            pct(at25.motp),
            pct(at50.mota),
            pct(at50.motp),
            at25.id_switches.into(),
            at25.false_positives.into(),
            at25.false_negatives.into(),
            at25.gt_count.into(),
        ])?;
    }
    Ok(table)
}

/// Table III's shape: the paper's objects, its rows and ours in the twin of
/// the same sequence (the object's twin id, [`twin_agent_id`]).
fn object_table(twins: &[Twin], variants: &[Variant]) -> Result<Table, ReportError> {
    let mut table = Table::new(
        "The paper's objects (Table III): TP [%] at 3D IoU 0.25, ATE_T [m], ATE_R [rad] of the associated track",
        [
            "Seq / Obj",
            "Method",
            "Source",
            "TP [%]",
            "ATE_T [m]",
            "ATE_R [rad]",
        ]
        .map(String::from)
        .to_vec(),
    );
    table.set_decimals(3, 2);
    for (sequence, id, rows) in PAPER_TABLE_III {
        for twin in twins.iter().filter(|t| t.sequence == sequence) {
            let key = if twins.iter().filter(|t| t.sequence == sequence).count() > 1 {
                format!("{} / {id}", twin.label)
            } else {
                format!("{sequence:02} / {id}")
            };
            for (name, (tp, t, r)) in PAPER_OBJECT_METHODS.iter().zip(rows) {
                table.push_row(vec![
                    Cell::from(key.as_str()),
                    Cell::from(*name),
                    Cell::from("paper, Table III (real KITTI)"),
                    tp.into(),
                    t.into(),
                    r.into(),
                ])?;
            }
            let twin_id = u64::from(twin_agent_id(i64::try_from(id).unwrap_or(i64::MAX)));
            for &v in variants.iter().filter(|v| v.tracks_objects()) {
                let object = twin
                    .result
                    .metrics(v)
                    .and_then(|m| m.objects.iter().find(|o| o.gt_id == twin_id));
                let mut cells = vec![
                    Cell::from(key.as_str()),
                    Cell::from(v.label()),
                    Cell::from(if object.is_some() {
                        "ours, twin"
                    } else {
                        "ours, twin: not in the scored truth"
                    }),
                ];
                match object {
                    Some(o) => {
                        cells.extend([o.tp_percent.into(), o.ate_t_m.into(), o.ate_r_rad.into()])
                    }
                    None => cells.extend(vec![Cell::Missing; 3]),
                }
                table.push_row(cells)?;
            }
        }
    }
    table.bold.push(BoldRule::BestInColumn {
        column: 4,
        better: Better::Lower,
        group_by: vec![0],
    });
    Ok(table)
}

/// The section of the KITTI twins of `results`, `None` when it has none.
///
/// # Errors
///
/// [`ReportError`] when a table cannot be built.
pub fn twins_section(results: &SuiteResults) -> Result<Option<Section>, ReportError> {
    let Some(source) = &results.twins else {
        return Ok(None);
    };
    let twins = twins(results);
    let mut variants = results.variants.clone();
    variants.sort();
    let missing: Vec<String> = twins
        .iter()
        .filter(|t| t.result.error.is_some())
        .map(|t| t.label.clone())
        .collect();
    let mut text = format!(
        "Digital twins (`limot simulate kitti`) of KITTI tracking sequences {} in `{}`; \
         not available: {}. Detections: {}. The suite's estimator and tracker settings \
         (the same as for the generated families), scored against each twin's exact \
         ground truth. The paper's rows are its figures on the real sequences with \
         CenterPoint detections; its {} correspond to our {}.",
        format_sequences(&source.sequences),
        source.training.display(),
        if missing.is_empty() {
            "none".to_string()
        } else {
            missing.join(", ")
        },
        match &source.detections {
            Some(d) => format!(
                "the real detections of `{}` (AB3DMOT format, logit scores through the \
                 logistic function), recorded in the twins instead of the detector model's",
                d.display()
            ),
            None => "the simulator's detector model".to_string(),
        },
        variants
            .iter()
            .map(|&v| paper_name(v))
            .collect::<Vec<_>>()
            .join(", "),
        variants
            .iter()
            .map(|v| v.label())
            .collect::<Vec<_>>()
            .join(", "),
    );
    let _ = write!(
        text,
        "\n\nA twin is not the real sequence: its ego is a smooth fit of OXTS, so \
         OXTS error, part of the paper's figures, is absent; its traffic is the \
         labelled tracks (camera view only); its static scene is generated along the \
         corridor. Orderings compare ATE_T to the millimetre (the paper's precision; \
         `=` ties). Flags: static ego (path < {STATIC_EGO_PATH_M} m); diverged \
         (ATE_T > {:.0} % of the path; every paper row is below 1.3 %).",
        100.0 * DIVERGED_ATE_PER_PATH
    );
    let all: Vec<&Twin> = twins.iter().collect();
    let clean: Vec<&Twin> = twins
        .iter()
        .filter(|t| !t.is_static() && t.diverged(&variants).is_empty())
        .collect();
    let _ = write!(
        text,
        "\n\n{}\n\n{}\n\nChance level with four variants and no ties: the same best on \
         1 in 4, mean τ_b 0.",
        agreement_line("Every twin with a paper row", &all, &variants),
        agreement_line(
            "Without the static-ego and diverged twins",
            &clean,
            &variants
        ),
    );
    let _ = write!(
        text,
        "\n\nTracking is scored as in the rest of this report, restricted to class Car \
         (the twin's Car includes KITTI's Van) against the camera-visible truth \
         (KITTI's labels within {} m with a box in the KITTI-like camera's image, whether \
         or not the twin's scene hides them from its LiDAR, as KITTI's annotators judged \
         visibility on the real scans): the shape of KITTI's Car benchmark, not its devkit. Object ATE is in the true world frame (the track's \
         error alone). Object ids: a KITTI track id k is object k + 1 in its twin.",
        crate::io::kitti::export::LABEL_RANGE_M
    );
    Ok(Some(Section {
        heading: "KITTI twins beside the paper (Tables I-III)".into(),
        text,
        tables: vec![
            ego_table(&twins, &variants)?,
            agreement_table(&twins, &variants)?,
            pairwise_table(&twins, &variants)?,
            tracking_table(&twins, &variants)?,
            object_table(&twins, &variants)?,
        ],
        plots: Vec::new(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orderings_read_best_first_with_ties() {
        let scored = [
            (Variant::Lio, 0.856),
            (Variant::Allfilt, 0.854),
            (Variant::Dynafilt, 0.856),
            (Variant::Limot, 0.846),
        ];
        assert_eq!(ordering_text(&scored), "limot < allfilt < lio = dynafilt");
        assert_eq!(ordering_text(&scored[..1]), "–");
        assert_eq!(rank_value(0.85649), 0.856);
    }

    #[test]
    fn agreement_counts_a_shared_best_under_ties() {
        let a = agreement(&[0.3, 0.2, 0.2, 0.1], &[0.3, 0.2, 0.2, 0.1]);
        assert!(a.best_same && a.tau_b == Some(1.0));
        let a = agreement(&[0.1, 0.2, 0.3, 0.4], &[0.4, 0.3, 0.2, 0.1]);
        assert!(!a.best_same && a.tau_b == Some(-1.0));
        let a = agreement(&[0.1, 0.1, 0.3, 0.4], &[0.2, 0.1, 0.3, 0.4]);
        assert!(a.best_same);
    }
}
