//! The demo report's tracking tables and the text that reads them: the
//! detector's ceiling and the tracks against the same truth, and where the
//! tracks lose against the ceiling ([`crate::metrics::mot_loss`]).

use super::EstimatorSummary;
use crate::metrics::ClearMotResult;
use crate::report::{Cell, ReportError, Table};

fn pct(v: Option<f64>) -> Cell {
    v.map(|x| 100.0 * x).into()
}

/// One row per IoU threshold and source: the detector (oracle ids), then
/// each variant's tracks; MOTA, MOTP, FP, FN, IDSW, matches, truth boxes.
///
/// # Errors
///
/// [`ReportError`] when a row does not fit the header.
pub fn same_truth_table(
    detector: &[(f64, ClearMotResult); 2],
    estimators: &[EstimatorSummary],
) -> Result<Table, ReportError> {
    let mut table = Table::new(
        "Detector ceiling and tracks vs the same truth (camera-visible boxes, 3D IoU, all classes)",
        [
            "IoU thr.",
            "source",
            "MOTA %",
            "MOTP %",
            "FP",
            "FN",
            "IDSW",
            "matches",
            "truth boxes",
        ]
        .map(String::from)
        .to_vec(),
    );
    for (k, (threshold, det)) in detector.iter().enumerate() {
        let rows = std::iter::once(("detector (oracle ids)".to_string(), det)).chain(
            estimators
                .iter()
                .map(|e| (format!("{} tracks", e.variant), &e.tracks[k])),
        );
        for (source, r) in rows {
            table.push_row(vec![
                Cell::Num(*threshold),
                Cell::from(source.as_str()),
                pct(r.mota),
                pct(r.motp),
                Cell::from(r.false_positives),
                Cell::from(r.false_negatives),
                Cell::from(r.id_switches),
                Cell::from(r.matches),
                Cell::from(r.gt_count),
            ])?;
        }
    }
    table.set_decimals(0, 2);
    table.set_decimals(2, 1);
    table.set_decimals(3, 1);
    Ok(table)
}

/// The tracks' FN, FP and IDSW at 3D IoU 0.25 by cause, one column per variant.
///
/// # Errors
///
/// [`ReportError`] when a row does not fit the header.
pub fn loss_table(estimators: &[EstimatorSummary]) -> Result<Table, ReportError> {
    let mut header = vec!["error: cause".to_string()];
    header.extend(estimators.iter().map(|e| e.variant.to_string()));
    let mut table = Table::new(
        "Where the tracks lose against the detector (3D IoU 0.25)",
        header,
    );
    type Get = fn(&EstimatorSummary) -> usize;
    let rows: [(&str, Get); 13] = [
        ("FN: detector miss (the ceiling's own FN)", |e| {
            e.loss.fn_causes.detector_miss
        }),
        ("  of which a coasting track overlapped", |e| {
            e.loss.fn_causes.coasting_would_match
        }),
        ("FN: detection taken by no track", |e| {
            e.loss.fn_causes.detection_unused
        }),
        ("FN: confirmation delay, new object", |e| {
            e.loss.fn_causes.unconfirmed_first
        }),
        ("FN: confirmation delay, object tracked before", |e| {
            e.loss.fn_causes.unconfirmed_again
        }),
        ("FN: confirmed track, box below IoU", |e| {
            e.loss.fn_causes.tracked_box_off
        }),
        ("FP: detector false positive confirmed", |e| {
            e.loss.fp_causes.false_detection
        }),
        ("FP: object outside the truth set", |e| {
            e.loss.fp_causes.outside_truth
        }),
        ("FP: box below IoU (the FN's other half)", |e| {
            e.loss.fp_causes.box_off
        }),
        ("FP: coasting box", |e| e.loss.fp_causes.coasting),
        ("FP: no live track", |e| e.loss.fp_causes.unknown),
        ("IDSW", |e| e.loss.tracks.id_switches),
        ("(gain) detector miss, matched by the tracks", |e| {
            e.loss.recovered_misses
        }),
    ];
    for (name, get) in rows {
        let mut row = vec![Cell::from(name)];
        row.extend(estimators.iter().map(|e| Cell::from(get(e))));
        table.push_row(row)?;
    }
    Ok(table)
}

/// How one variant's MOTA falls from the detector's, in signed MOTA points
/// per cause (they sum to the difference), as a markdown paragraph.
pub fn loss_sentence(detector: &ClearMotResult, e: &EstimatorSummary) -> String {
    let l = &e.loss;
    let f = &l.fn_causes;
    let gt = l.tracks.gt_count.max(1) as f64;
    let points = |n: f64| 100.0 * n / gt;
    let fp_gain = detector.false_positives as f64 - l.tracks.false_positives as f64;
    format!(
        "`{}`: MOTA {:.1} % against the ceiling's {:.1} %, in MOTA points: confirmation \
         delay {:+.1} ({} boxes of new objects, {} of objects tracked before), detections \
         no track took {:+.1}, confirmed tracks' boxes below the IoU {:+.1}, boxes the \
         tracks matched where the detection missed {:+.1} ({}), false positives {:+.1} \
         ({} against the detector's {}: {} detector false positives confirmed, {} objects \
         outside the truth set, {} boxes below the IoU), ID switches {:+.1}. Of the {} \
         detector misses, {} had a confirmed track coasting over it (IoU at the threshold) \
         that is not written: `limot run` writes only the tracks matched in the frame.",
        e.variant,
        100.0 * l.tracks.mota.unwrap_or(f64::NAN),
        100.0 * detector.mota.unwrap_or(f64::NAN),
        -points((f.unconfirmed_first + f.unconfirmed_again) as f64),
        f.unconfirmed_first,
        f.unconfirmed_again,
        -points(f.detection_unused as f64),
        -points(f.tracked_box_off as f64),
        points(l.recovered_misses as f64),
        l.recovered_misses,
        points(fp_gain),
        l.tracks.false_positives,
        detector.false_positives,
        l.fp_causes.false_detection,
        l.fp_causes.outside_truth,
        l.fp_causes.box_off,
        -points(l.tracks.id_switches as f64),
        f.detector_miss,
        f.coasting_would_match,
    )
}
