//! Quality of dynamic-feature filtering: the removed points are the
//! classifier's positives, a point is truly positive when its ground-truth
//! instance label belongs to a moving object.
//!
//! precision = TP / (TP + FP) (removed points that were on moving objects),
//! recall = TP / (TP + FN) (moving-object points that were removed).

use super::EvalError;
use std::collections::BTreeSet;

#[derive(Debug, Clone, Copy, PartialEq)]
/// Confusion counts and scores of a dynamic-point classification.
pub struct FilterScore {
    /// Dynamic points removed.
    pub true_positives: usize,
    /// Static points removed.
    pub false_positives: usize,
    /// Dynamic points kept.
    pub false_negatives: usize,
    /// Static points kept.
    pub true_negatives: usize,
    /// `None` when nothing was removed.
    pub precision: Option<f64>,
    /// `None` when no point lies on a moving object.
    pub recall: Option<f64>,
}

impl FilterScore {
    /// F1 score; `None` when precision or recall is undefined or both are 0.
    pub fn f1(&self) -> Option<f64> {
        let (p, r) = (self.precision?, self.recall?);
        (p + r > 0.0).then(|| 2.0 * p * r / (p + r))
    }

    /// Sums the counts of several scans (micro average).
    pub fn merge(&self, other: &FilterScore) -> FilterScore {
        FilterScore::from_counts(
            self.true_positives + other.true_positives,
            self.false_positives + other.false_positives,
            self.false_negatives + other.false_negatives,
            self.true_negatives + other.true_negatives,
        )
    }

    /// The score of the given confusion counts.
    pub fn from_counts(tp: usize, fp: usize, fn_: usize, tn: usize) -> FilterScore {
        let ratio = |num: usize, den: usize| (den > 0).then(|| num as f64 / den as f64);
        FilterScore {
            true_positives: tp,
            false_positives: fp,
            false_negatives: fn_,
            true_negatives: tn,
            precision: ratio(tp, tp + fp),
            recall: ratio(tp, tp + fn_),
        }
    }
}

/// Scores one scan. `removed[i]`: point `i` was filtered out; `labels[i]`: its
/// ground-truth instance id (0 = static scene); `moving_ids`: the instances
/// that move in this scan.
///
/// # Errors
///
/// [`EvalError::LengthMismatch`] when the masks differ in length.
pub fn filter_precision_recall(
    removed: &[bool],
    labels: &[u32],
    moving_ids: &BTreeSet<u32>,
) -> Result<FilterScore, EvalError> {
    if removed.len() != labels.len() {
        return Err(EvalError::LengthMismatch {
            what: "filter: removed mask vs labels",
            left: removed.len(),
            right: labels.len(),
        });
    }
    let (mut tp, mut fp, mut fn_, mut tn) = (0, 0, 0, 0);
    for (&r, label) in removed.iter().zip(labels) {
        match (r, moving_ids.contains(label)) {
            (true, true) => tp += 1,
            (true, false) => fp += 1,
            (false, true) => fn_ += 1,
            (false, false) => tn += 1,
        }
    }
    Ok(FilterScore::from_counts(tp, fp, fn_, tn))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_case() {
        // labels: 0 static, 5 moving car, 7 parked car.
        let labels = [0, 0, 5, 5, 5, 7, 7, 0];
        let removed = [false, true, true, true, false, true, false, false];
        let moving = BTreeSet::from([5]);
        let s = filter_precision_recall(&removed, &labels, &moving).unwrap();
        assert_eq!(
            (
                s.true_positives,
                s.false_positives,
                s.false_negatives,
                s.true_negatives
            ),
            (2, 2, 1, 3)
        );
        assert_eq!(s.precision, Some(0.5));
        assert_eq!(s.recall, Some(2.0 / 3.0));
        assert!((s.f1().unwrap() - 4.0 / 7.0).abs() < 1e-15);
        let twice = s.merge(&s);
        assert_eq!(twice.precision, Some(0.5));
        assert_eq!(twice.true_negatives, 6);
    }

    #[test]
    fn undefined_ratios_and_errors() {
        let s = filter_precision_recall(&[false, false], &[0, 3], &BTreeSet::new()).unwrap();
        assert_eq!(s.precision, None);
        assert_eq!(s.recall, None);
        assert_eq!(s.f1(), None);
        assert!(matches!(
            filter_precision_recall(&[true], &[1, 2], &BTreeSet::new()),
            Err(EvalError::LengthMismatch { .. })
        ));
    }
}
