//! Where a tracker loses against its detector: every false negative and
//! false positive of the tracks' CLEAR-MOT score, put in exactly one cause.
//!
//! Both are scored against the same truth boxes (same ids per frame). The
//! detector's matches at the same threshold say which truth boxes the
//! detector found; the tracker's live tracks (tentative, confirmed and
//! coasting ones, with the truth id of the detection each took this frame)
//! say what became of a found box. A false negative of the tracks is
//!
//! - [`FnCauses::detector_miss`]: the detector did not find it (its own FN);
//!   of those, [`FnCauses::coasting_would_match`] had a confirmed track
//!   coasting on its prediction that overlaps it at the threshold (a box
//!   an output policy that writes coasting tracks would have scored);
//! - [`FnCauses::detection_unused`]: found, but no track took the detection
//!   (below the tracker's score gates, or invalid);
//! - [`FnCauses::unconfirmed_first`]: found and taken by a tentative track
//!   of an object the tracks had never matched before (the confirmation
//!   delay of a new object);
//! - [`FnCauses::unconfirmed_again`]: the same after the tracks had matched
//!   the object before (a track lost or split off by association, restarted);
//! - [`FnCauses::tracked_box_off`]: taken by a confirmed track whose written
//!   box misses the truth at the threshold (fit lag, size, or not written).
//!
//! The tracks can also match a box the detector missed (a smoothed box
//! within the IoU where the noisy detection was not):
//! [`MotLoss::recovered_misses`], so the tracks' FN exceed the detector's by
//! the FN causes after `detector_miss`, less those.
//!
//! A false positive (a written box matching no truth) is
//! [`FpCauses::false_detection`] (its track took a detector false positive),
//! [`FpCauses::outside_truth`] (a real object that is not in this frame's
//! truth set), [`FpCauses::box_off`] (an object of the truth set, box below
//! the threshold: the other half of a `tracked_box_off`),
//! [`FpCauses::coasting`] (a written box without a detection this frame) or
//! [`FpCauses::unknown`] (no live track carries its id).

use super::EvalError;
use super::clear_mot::{ClearMotConfig, ClearMotResult, MotFrame, clear_mot};
use super::iou::iou;
use limot_estimator::geometry::OrientedBox;
use std::collections::BTreeSet;

/// What detection a live track took in a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TookDetection {
    /// None: the track coasted on its prediction.
    None,
    /// A detection of the truth object with this id.
    Object(u64),
    /// A detector false positive.
    FalsePositive,
}

/// One of the tracker's live tracks in a frame, in the truth's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveTrack {
    /// Track id (the id of its written boxes).
    pub id: u64,
    /// Confirmed (else tentative).
    pub confirmed: bool,
    /// The detection it took this frame.
    pub took: TookDetection,
    /// Its box this frame (the prediction when coasting).
    pub bbox: OrientedBox,
}

/// The causes of the tracks' false negatives (they sum to its FN).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FnCauses {
    /// The detector did not find the truth box.
    pub detector_miss: usize,
    /// Of `detector_miss`: a coasting confirmed track overlapped it.
    pub coasting_would_match: usize,
    /// Found, but no track took the detection.
    pub detection_unused: usize,
    /// Found, taken by a tentative track of an object never matched before.
    pub unconfirmed_first: usize,
    /// Found, taken by a tentative track of an object matched before.
    pub unconfirmed_again: usize,
    /// Found, taken by a confirmed track whose written box misses it.
    pub tracked_box_off: usize,
}

impl FnCauses {
    /// Every false negative (`coasting_would_match` is inside `detector_miss`).
    pub fn total(&self) -> usize {
        self.detector_miss
            + self.detection_unused
            + self.unconfirmed_first
            + self.unconfirmed_again
            + self.tracked_box_off
    }
}

/// The causes of the tracks' false positives (they sum to its FP).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FpCauses {
    /// The track took a detector false positive.
    pub false_detection: usize,
    /// A real object outside this frame's truth set.
    pub outside_truth: usize,
    /// An object of the truth set, its box below the threshold.
    pub box_off: usize,
    /// A written box without a detection this frame.
    pub coasting: usize,
    /// No live track carries the box's id.
    pub unknown: usize,
}

impl FpCauses {
    /// Every false positive.
    pub fn total(&self) -> usize {
        self.false_detection + self.outside_truth + self.box_off + self.coasting + self.unknown
    }
}

/// The tracks' CLEAR-MOT score and the causes of its errors.
#[derive(Debug, Clone, PartialEq)]
pub struct MotLoss {
    /// The tracks' score (as [`clear_mot`] of the same frames).
    pub tracks: ClearMotResult,
    /// Causes of `tracks.false_negatives`.
    pub fn_causes: FnCauses,
    /// Causes of `tracks.false_positives`.
    pub fp_causes: FpCauses,
    /// Truth boxes the detector missed that the tracks matched.
    pub recovered_misses: usize,
}

/// Scores `frames` (truth and written track boxes) and puts each error in a
/// cause (see the module docs). `detected[k]` holds the truth ids the
/// detector matched in frame `k` (at the same threshold, against the same
/// truth ids); `live[k]` the tracker's live tracks after frame `k`.
///
/// # Errors
///
/// [`EvalError::LengthMismatch`] when the three inputs differ in length,
/// [`EvalError::BadParameter`] for frames with DontCare regions (their
/// ignored boxes have no cause), and the errors of [`clear_mot`].
pub fn mot_loss(
    frames: &[MotFrame],
    detected: &[BTreeSet<u64>],
    live: &[Vec<LiveTrack>],
    cfg: &ClearMotConfig,
) -> Result<MotLoss, EvalError> {
    for (what, n) in [
        ("mot_loss: frames vs detected", detected.len()),
        ("mot_loss: frames vs live tracks", live.len()),
    ] {
        if n != frames.len() {
            return Err(EvalError::LengthMismatch {
                what,
                left: frames.len(),
                right: n,
            });
        }
    }
    if frames.iter().any(|f| !f.dont_care.is_empty()) {
        return Err(EvalError::BadParameter {
            what: "mot_loss",
            why: "frames with DontCare regions are not supported".into(),
        });
    }
    let tracks = clear_mot(frames, cfg)?;
    let mut fn_causes = FnCauses::default();
    let mut fp_causes = FpCauses::default();
    let mut recovered_misses = 0;
    // objects the tracks matched in an earlier frame
    let mut matched_before: BTreeSet<u64> = BTreeSet::new();
    for (k, frame) in frames.iter().enumerate() {
        let matches = &tracks.per_frame[k];
        let matched_gt: BTreeSet<usize> = matches.iter().map(|m| m.gt_index).collect();
        let matched_tracks: BTreeSet<usize> = matches.iter().map(|m| m.track_index).collect();
        for (i, g) in frame.gt.iter().enumerate() {
            if matched_gt.contains(&i) {
                recovered_misses += usize::from(!detected[k].contains(&g.id));
                continue;
            }
            if !detected[k].contains(&g.id) {
                fn_causes.detector_miss += 1;
                let coasting_match = live[k].iter().any(|t| {
                    t.confirmed
                        && t.took == TookDetection::None
                        && cfg_passes(cfg, iou(&g.bbox, &t.bbox, cfg.iou_kind))
                });
                fn_causes.coasting_would_match += usize::from(coasting_match);
                continue;
            }
            let takers: Vec<&LiveTrack> = live[k]
                .iter()
                .filter(|t| t.took == TookDetection::Object(g.id))
                .collect();
            if takers.is_empty() {
                fn_causes.detection_unused += 1;
            } else if takers.iter().any(|t| t.confirmed) {
                fn_causes.tracked_box_off += 1;
            } else if matched_before.contains(&g.id) {
                fn_causes.unconfirmed_again += 1;
            } else {
                fn_causes.unconfirmed_first += 1;
            }
        }
        let truth_ids: BTreeSet<u64> = frame.gt.iter().map(|g| g.id).collect();
        for (j, w) in frame.tracks.iter().enumerate() {
            if matched_tracks.contains(&j) {
                continue;
            }
            match live[k].iter().find(|t| t.id == w.id).map(|t| t.took) {
                None => fp_causes.unknown += 1,
                Some(TookDetection::None) => fp_causes.coasting += 1,
                Some(TookDetection::FalsePositive) => fp_causes.false_detection += 1,
                Some(TookDetection::Object(id)) if truth_ids.contains(&id) => {
                    fp_causes.box_off += 1;
                }
                Some(TookDetection::Object(_)) => fp_causes.outside_truth += 1,
            }
        }
        matched_before.extend(matches.iter().map(|m| m.gt_id));
    }
    Ok(MotLoss {
        tracks,
        fn_causes,
        fp_causes,
        recovered_misses,
    })
}

/// The threshold test of [`clear_mot`] (its machine-epsilon slack).
fn cfg_passes(cfg: &ClearMotConfig, overlap: f64) -> bool {
    overlap >= cfg.iou_threshold - super::iou::AREA_EPS
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::TrackedBox;
    use limot_estimator::input::ObjectClass;
    use nalgebra::Vector3;

    fn car(x: f64) -> OrientedBox {
        OrientedBox {
            center: Vector3::new(x, 0.0, 0.8),
            size_lwh: Vector3::new(4.0, 1.8, 1.6),
            yaw_rad: 0.0,
        }
    }

    fn tb(id: u64, x: f64) -> TrackedBox {
        TrackedBox {
            id,
            class: ObjectClass::Car,
            bbox: car(x),
        }
    }

    fn live(id: u64, confirmed: bool, took: TookDetection, x: f64) -> LiveTrack {
        LiveTrack {
            id,
            confirmed,
            took,
            bbox: car(x),
        }
    }

    fn frame(gt: Vec<TrackedBox>, tracks: Vec<TrackedBox>) -> MotFrame {
        MotFrame {
            gt,
            tracks,
            dont_care: Vec::new(),
        }
    }

    /// Object 1 (at x = 0) through the stages of a track's life, object 2
    /// (at x = 50) never found, object 3 (at x = 100) outside the truth set.
    #[test]
    fn every_error_gets_its_cause_and_the_causes_sum_to_the_score() {
        use TookDetection::{FalsePositive, None as Coast, Object};
        let frames = vec![
            // 0: found, tentative track 10 (new object); 2 missed, nothing coasts
            frame(vec![tb(1, 0.0), tb(2, 50.0)], vec![]),
            // 1: found, confirmed 10 written and matched; a false detection
            //    confirmed as track 20 and written far from everything
            frame(vec![tb(1, 0.0)], vec![tb(10, 0.0), tb(20, 200.0)]),
            // 2: found, confirmed 10 written 3 m off (FN + FP box_off);
            //    object 3 written, not in the truth set
            frame(vec![tb(1, 0.0)], vec![tb(10, 3.0), tb(30, 100.0)]),
            // 3: not found, 10 coasts on it; 2 found but no track took it
            frame(vec![tb(1, 0.0), tb(2, 50.0)], vec![]),
            // 4: found again, taken by a new tentative track 11
            frame(vec![tb(1, 0.0)], vec![]),
            // 5: the detector's box missed, track 11's box matches
            frame(vec![tb(1, 0.0)], vec![tb(11, 0.1)]),
        ];
        let detected: Vec<BTreeSet<u64>> = vec![
            [1].into(),
            [1].into(),
            [1].into(),
            [2].into(),
            [1].into(),
            [].into(),
        ];
        let live = vec![
            vec![live(10, false, Object(1), 0.0)],
            vec![
                live(10, true, Object(1), 0.0),
                live(20, true, FalsePositive, 200.0),
            ],
            vec![
                live(10, true, Object(1), 3.0),
                live(30, true, Object(3), 100.0),
            ],
            vec![live(10, true, Coast, 0.2)],
            vec![live(11, false, Object(1), 0.0)],
            vec![live(11, true, Object(1), 0.1)],
        ];
        let cfg = ClearMotConfig::with_threshold(0.25);
        let loss = mot_loss(&frames, &detected, &live, &cfg).unwrap();
        assert_eq!(
            loss.fn_causes,
            FnCauses {
                detector_miss: 2,
                coasting_would_match: 1,
                detection_unused: 1,
                unconfirmed_first: 1,
                unconfirmed_again: 1,
                tracked_box_off: 1,
            }
        );
        assert_eq!(
            loss.fp_causes,
            FpCauses {
                false_detection: 1,
                outside_truth: 1,
                box_off: 1,
                coasting: 0,
                unknown: 0,
            }
        );
        assert_eq!(loss.recovered_misses, 1);
        assert_eq!(loss.fn_causes.total(), loss.tracks.false_negatives);
        assert_eq!(loss.fp_causes.total(), loss.tracks.false_positives);
        assert_eq!(loss.tracks, clear_mot(&frames, &cfg).unwrap());
    }

    #[test]
    fn a_written_box_without_a_live_track_or_detection_is_named() {
        let frames = vec![frame(vec![], vec![tb(5, 0.0), tb(6, 20.0)])];
        let live = vec![vec![live(6, true, TookDetection::None, 20.0)]];
        let cfg = ClearMotConfig::with_threshold(0.25);
        let loss = mot_loss(&frames, &[BTreeSet::new()], &live, &cfg).unwrap();
        assert_eq!((loss.fp_causes.unknown, loss.fp_causes.coasting), (1, 1));
    }

    #[test]
    fn mismatched_inputs_are_rejected() {
        let cfg = ClearMotConfig::with_threshold(0.25);
        let frames = vec![frame(vec![tb(1, 0.0)], vec![])];
        let e = mot_loss(&frames, &[], &[vec![]], &cfg).unwrap_err();
        assert!(matches!(e, EvalError::LengthMismatch { .. }), "{e}");
        let mut with_region = frames.clone();
        with_region[0].dont_care.push(car(0.0));
        let e = mot_loss(&with_region, &[BTreeSet::new()], &[vec![]], &cfg).unwrap_err();
        assert!(matches!(e, EvalError::BadParameter { .. }), "{e}");
    }
}
