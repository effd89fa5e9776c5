//! The dynamic-feature filter of a run against the per-point instance
//! labels of a limot dataset: of the LiDAR features (edge and planar points)
//! the estimator extracted, which it dropped as dynamic, which lie on moving
//! objects, which on static ones (parked, or stopped at a light).

use crate::metrics::{FilterScore, filter_precision_recall};
use crate::run::RunOutput;
use limot_sim::record::{Dataset, RecordError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;

/// A moving object is faster than this at the frame (the paper's v_thres):
/// stopped cars count as static objects, like parked ones.
pub const FILTER_MOVING_SPEED_MPS: f64 = 1.0;

/// The filter of one run over every estimated frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FilterEvaluation {
    /// Features removed / kept against "on a moving object" (positives).
    pub features: usize,
    /// Features removed by the filter.
    pub removed: usize,
    /// Features on moving objects.
    pub moving_features: usize,
    /// Of those, removed.
    pub removed_moving: usize,
    /// Features on standing objects.
    pub static_object_features: usize,
    /// Of those, removed.
    pub removed_static_object: usize,
}

impl FilterEvaluation {
    /// Precision and recall of the removal against the moving objects.
    pub fn score(&self) -> FilterScore {
        let tp = self.removed_moving;
        let fp = self.removed - self.removed_moving;
        let fn_ = self.moving_features - self.removed_moving;
        let tn = self.features - self.removed - fn_;
        FilterScore::from_counts(tp, fp, fn_, tn)
    }

    /// Share of the static objects' features removed (what `allfilt` loses).
    pub fn static_object_removed_fraction(&self) -> Option<f64> {
        (self.static_object_features > 0)
            .then(|| self.removed_static_object as f64 / self.static_object_features as f64)
    }
}

/// Scores `output` (run with `EstimatorConfig::record_feature_indices`)
/// against `dataset`'s labels. `None` when the run recorded no features.
///
/// # Errors
///
/// [`RecordError`] when the dataset's labels or the run's filter output cannot be read.
pub fn evaluate_filtering(
    dataset: &Dataset,
    output: &RunOutput,
) -> Result<Option<FilterEvaluation>, RecordError> {
    let boxes = dataset.box_truth()?;
    let mut total = FilterEvaluation {
        features: 0,
        removed: 0,
        moving_features: 0,
        removed_moving: 0,
        static_object_features: 0,
        removed_static_object: 0,
    };
    let mut any = false;
    for e in &output.estimates {
        if e.feature_indices.is_empty() {
            continue;
        }
        any = true;
        let frame = e.frame_index as usize;
        let labels = dataset.frame(frame)?.labels;
        let frame_boxes = boxes.get(frame).map_or(&[][..], |b| &b[..]);
        let moving: BTreeSet<u32> = frame_boxes
            .iter()
            .filter(|b| !b.parked && b.velocity_world_mps.norm() > FILTER_MOVING_SPEED_MPS)
            .map(|b| b.id)
            .collect();
        let static_objects: BTreeSet<u32> = frame_boxes
            .iter()
            .filter(|b| !moving.contains(&b.id))
            .map(|b| b.id)
            .collect();
        let removed: BTreeSet<u32> = e.removed_feature_indices.iter().copied().collect();
        let feature_labels: Vec<u32> = e
            .feature_indices
            .iter()
            .map(|&i| labels.get(i as usize).copied().unwrap_or(0))
            .collect();
        let removed_mask: Vec<bool> = e
            .feature_indices
            .iter()
            .map(|i| removed.contains(i))
            .collect();
        let s = filter_precision_recall(&removed_mask, &feature_labels, &moving)
            .expect("one label per feature");
        total.features += feature_labels.len();
        total.removed += s.true_positives + s.false_positives;
        total.moving_features += s.true_positives + s.false_negatives;
        total.removed_moving += s.true_positives;
        for (&label, &r) in feature_labels.iter().zip(&removed_mask) {
            if static_objects.contains(&label) {
                total.static_object_features += 1;
                total.removed_static_object += usize::from(r);
            }
        }
    }
    Ok(any.then_some(total))
}
