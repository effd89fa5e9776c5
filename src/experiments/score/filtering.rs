//! The dynamic-feature filter of a run against the per-point instance
//! labels of a limot dataset: of the LiDAR features (edge and planar points)
//! the estimator extracted, which it dropped as dynamic, which lie on moving
//! objects, which on static ones (parked, or stopped at a light), and for
//! the trajectory-based filters why a moving object's features were kept.

use crate::metrics::{FilterScore, filter_precision_recall, pose_at};
use crate::run::RunOutput;
use limot_estimator::Variant;
use limot_estimator::pipeline::FrameEstimate;
use limot_estimator::tracking::{Lifecycle, Motion, TrackOutput};
use limot_sim::record::{BoxTruth, Dataset, EgoTruth, RecordError};
use nalgebra::{Isometry3, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};

/// A moving object is faster than this at the frame (the paper's v_thres):
/// stopped cars count as static objects, like parked ones.
pub const FILTER_MOVING_SPEED_MPS: f64 = 1.0;

/// A track stands for a ground-truth object when its centre is within this
/// horizontal distance of the object's, both in the LiDAR frame (m): half a
/// car length, well below the spacing of cars in a queue.
pub const TRACK_OBJECT_GATE_M: f64 = 2.0;

/// Why features on moving objects survived a trajectory-based filter
/// (`dynafilt`, `limot`), judged by the tracks that filter had: those of the
/// previous estimated frame, predicted to each point's time. Each kept
/// feature on a moving object counts once, under the state of the track
/// nearest its object (within [`TRACK_OBJECT_GATE_M`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct KeptMovingCauses {
    /// No track near the object: not detected yet, missed by the detector,
    /// or lost.
    pub untracked: usize,
    /// A tentative track near it, not (yet) judged dynamic.
    pub tentative_static: usize,
    /// A confirmed track near it, judged static.
    pub confirmed_static: usize,
    /// A dynamic track near it: the point lay outside the box predicted for
    /// its time (box too small, or predicted at the wrong place).
    pub dynamic_outside_box: usize,
}

impl KeptMovingCauses {
    /// All kept features on moving objects.
    pub fn total(&self) -> usize {
        self.untracked + self.tentative_static + self.confirmed_static + self.dynamic_outside_box
    }

    fn count(&mut self, track: Option<&TrackOutput>) {
        match track.map(|t| (t.motion, t.lifecycle)) {
            None => self.untracked += 1,
            Some((Motion::Dynamic, _)) => self.dynamic_outside_box += 1,
            Some((Motion::Static, Lifecycle::Tentative)) => self.tentative_static += 1,
            Some((Motion::Static, Lifecycle::Confirmed)) => self.confirmed_static += 1,
        }
    }
}

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
    /// Features on parked objects (standing for the whole run, a subset of
    /// the standing ones; absent from results written before it existed).
    #[serde(default)]
    pub parked_features: usize,
    /// Of those, removed.
    #[serde(default)]
    pub removed_parked: usize,
    /// The parked objects' edge features (a subset of `parked_features`;
    /// absent from results written before it existed).
    #[serde(default)]
    pub parked_edge_features: usize,
    /// Of those, removed.
    #[serde(default)]
    pub removed_parked_edges: usize,
    /// Why the kept features on moving objects were kept (trajectory-based
    /// filters only; absent from results written before it existed).
    #[serde(default)]
    pub kept_moving_causes: Option<KeptMovingCauses>,
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

    /// `features removed … % of …; on moving objects … % of …; on standing
    /// objects … % of …` (no precision: for labels that cover part of the
    /// sweep, `super::kitti_filter`).
    pub fn labelled_summary_line(&self) -> String {
        let pct = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{:.1} %", 100.0 * x));
        format!(
            "features removed {} of {}; on labelled moving objects {} of {}; \
             on labelled standing objects {} of {}",
            pct(self.removed_fraction()),
            self.features,
            pct(self.score().recall),
            self.moving_features,
            pct(self.static_object_removed_fraction()),
            self.static_object_features
        )
    }

    /// Share of all features removed.
    pub fn removed_fraction(&self) -> Option<f64> {
        (self.features > 0).then(|| self.removed as f64 / self.features as f64)
    }

    /// Share of the static objects' features removed (what `allfilt` loses).
    pub fn static_object_removed_fraction(&self) -> Option<f64> {
        (self.static_object_features > 0)
            .then(|| self.removed_static_object as f64 / self.static_object_features as f64)
    }

    /// Share of the parked objects' features removed (structure no filter
    /// needs to drop).
    pub fn parked_removed_fraction(&self) -> Option<f64> {
        (self.parked_features > 0).then(|| self.removed_parked as f64 / self.parked_features as f64)
    }

    /// Share of the parked objects' edge features removed
    /// (`EstimatorConfig::filter_static_edges` drops them).
    pub fn parked_edge_removed_fraction(&self) -> Option<f64> {
        (self.parked_edge_features > 0)
            .then(|| self.removed_parked_edges as f64 / self.parked_edge_features as f64)
    }

    /// Share of the parked objects' planar features removed.
    pub fn parked_planar_removed_fraction(&self) -> Option<f64> {
        let features = self.parked_features - self.parked_edge_features;
        let removed = self.removed_parked - self.removed_parked_edges;
        (features > 0).then(|| removed as f64 / features as f64)
    }
}

/// What a filter is judged against at one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameObjects {
    /// The object under each point of the sweep (0: none), by point index.
    pub point_labels: Vec<u32>,
    /// Objects moving faster than [`FILTER_MOVING_SPEED_MPS`].
    pub moving: BTreeSet<u32>,
    /// Standing objects (parked, or stopped).
    pub standing: BTreeSet<u32>,
    /// Of those, the parked ones (they never move).
    pub parked: BTreeSet<u32>,
}

impl FilterEvaluation {
    /// No frame yet.
    pub fn empty() -> FilterEvaluation {
        FilterEvaluation {
            features: 0,
            removed: 0,
            moving_features: 0,
            removed_moving: 0,
            static_object_features: 0,
            removed_static_object: 0,
            parked_features: 0,
            removed_parked: 0,
            parked_edge_features: 0,
            removed_parked_edges: 0,
            kept_moving_causes: None,
        }
    }

    /// Counts the features of estimate `e` against `objects`; returns each
    /// feature's object label and whether the filter removed it.
    pub fn add_frame(&mut self, e: &FrameEstimate, objects: &FrameObjects) -> Vec<(u32, bool)> {
        let removed: BTreeSet<u32> = e.removed_feature_indices.iter().copied().collect();
        let labels: Vec<u32> = e
            .feature_indices
            .iter()
            .map(|&i| objects.point_labels.get(i as usize).copied().unwrap_or(0))
            .collect();
        let removed_mask: Vec<bool> = e
            .feature_indices
            .iter()
            .map(|i| removed.contains(i))
            .collect();
        let s = filter_precision_recall(&removed_mask, &labels, &objects.moving)
            .expect("one label per feature");
        self.features += labels.len();
        self.removed += s.true_positives + s.false_positives;
        self.moving_features += s.true_positives + s.false_negatives;
        self.removed_moving += s.true_positives;
        for ((&label, &r), i) in labels.iter().zip(&removed_mask).zip(&e.feature_indices) {
            if objects.standing.contains(&label) {
                self.static_object_features += 1;
                self.removed_static_object += usize::from(r);
            }
            if objects.parked.contains(&label) {
                self.parked_features += 1;
                self.removed_parked += usize::from(r);
                if e.edge_feature_indices.binary_search(i).is_ok() {
                    self.parked_edge_features += 1;
                    self.removed_parked_edges += usize::from(r);
                }
            }
        }
        labels.into_iter().zip(removed_mask).collect()
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
    let mut total = FilterEvaluation::empty();
    let trajectory_based = matches!(output.variant, Variant::Dynafilt | Variant::Limot);
    let mut causes = KeptMovingCauses::default();
    let mut ego = dataset.ego_truth()?;
    ego.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    let mut any = false;
    for (k, e) in output.estimates.iter().enumerate() {
        if e.feature_indices.is_empty() {
            continue;
        }
        any = true;
        let frame = e.frame_index as usize;
        let frame_boxes = boxes.get(frame).map_or(&[][..], |b| &b[..]);
        let moving: BTreeSet<u32> = frame_boxes
            .iter()
            .filter(|b| !b.parked && b.velocity_world_mps.norm() > FILTER_MOVING_SPEED_MPS)
            .map(|b| b.id)
            .collect();
        let objects = FrameObjects {
            point_labels: dataset.frame_labels(frame)?,
            standing: frame_boxes
                .iter()
                .filter(|b| !moving.contains(&b.id))
                .map(|b| b.id)
                .collect(),
            parked: frame_boxes
                .iter()
                .filter(|b| b.parked)
                .map(|b| b.id)
                .collect(),
            moving,
        };
        let features = total.add_frame(e, &objects);
        if trajectory_based {
            // The filter of frame `e` used the tracks after the estimate
            // before it (none for the first estimate).
            let previous = k
                .checked_sub(1)
                .map(|p| &output.estimates[p])
                .filter(|p| p.frame_index + 1 == e.frame_index);
            let nearest = previous.map(|p| {
                nearest_tracks(
                    p.frame_index as usize,
                    &p.t_world_lidar,
                    &p.tracks,
                    &boxes,
                    &ego,
                    &objects.moving,
                )
            });
            for &(label, r) in &features {
                if !r && objects.moving.contains(&label) {
                    let track = nearest.as_ref().and_then(|n| n.get(&label).copied());
                    causes.count(track);
                }
            }
        }
    }
    total.kept_moving_causes = trajectory_based.then_some(causes);
    Ok(any.then_some(total))
}

/// For each of `objects` labelled at `frame`, the track of `tracks` (the
/// estimate of that frame, LiDAR pose `t_world_lidar` in the estimator's
/// world) nearest to it in the LiDAR frame within [`TRACK_OBJECT_GATE_M`];
/// objects without one are absent.
fn nearest_tracks<'a>(
    frame: usize,
    t_world_lidar: &Isometry3<f64>,
    tracks: &'a [TrackOutput],
    boxes: &[Vec<BoxTruth>],
    ego: &[EgoTruth],
    objects: &BTreeSet<u32>,
) -> BTreeMap<u32, &'a TrackOutput> {
    let t_lidar_world = t_world_lidar.inverse();
    let tracks_lidar: Vec<Vector3<f64>> = tracks
        .iter()
        .map(|t| t_lidar_world * nalgebra::Point3::from(t.center_world))
        .map(|p| p.coords)
        .collect();
    let mut out = BTreeMap::new();
    for b in boxes.get(frame).into_iter().flatten() {
        if !objects.contains(&b.id) {
            continue;
        }
        let Some(t_world_lidar_truth) = pose_at(ego, b.t_s, |g| (g.t_s, g.t_world_lidar)) else {
            continue;
        };
        let center = (t_world_lidar_truth.inverse() * b.t_world_box)
            .translation
            .vector;
        let track = tracks
            .iter()
            .zip(&tracks_lidar)
            .map(|(t, c)| (t, (c - center).xy().norm()))
            .filter(|(_, d)| *d < TRACK_OBJECT_GATE_M)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((track, _)) = track {
            out.insert(b.id, track);
        }
    }
    out
}
