//! KITTI 2D box tracking evaluation, replicating TrackEval's `Kitti2DBox`
//! dataset (TrackEval 1.3.0, `datasets/kitti_2d_box.py`) in front of our
//! CLEAR-MOT core ([`clear_mot`] on [`Box2`] image boxes).
//!
//! Replicated, per frame and evaluated class (Car or Pedestrian):
//! - Ground truth: rows of the class and of its distractor class (`Van` for
//!   Car, `Person`/`Person_sitting` for Pedestrian) with track id ≥ 0; `DontCare`
//!   rows are ignore regions. Tracker rows: the class only, track id ≥ 0.
//! - A preprocessing match of all these ground-truth and tracker boxes
//!   (Hungarian, maximum summed image IoU, pairs below 0.5 zeroed); a tracker
//!   box matched to a distractor (distractor class, occlusion > 2 or
//!   truncation > 0) is removed.
//! - An unmatched tracker box is removed when its height is ≤ 25 px or more
//!   than 50 % of its area lies inside one DontCare region.
//! - Only ground truth of the class with occlusion ≤ 2 and truncation 0
//!   (truncation read as an integer, as TrackEval does) is evaluated.
//! - CLEAR-MOT with [`ClearMotConfig::trackeval`]: image IoU ≥ 0.5, ID switch
//!   against the last matched id, TrackEval's matching rule.
//!
//! Not replicated: TrackEval's ID relabelling (irrelevant to the metrics),
//! its tracker-file class filter (it loads every row, then masks by class,
//! which we do directly), its crash on `Person_sitting` (we treat it as the
//! pedestrian distractor), and tie-breaking between equally good
//! assignments (scipy and our Hungarian may pick different optima when IoUs
//! tie exactly). The original KITTI devkit differs in more ways (see
//! docs/metrics.md): it also ignores ground truth below 25 px, counts
//! ID switches only between consecutive matches and maximises the match count.

use super::EvalError;
use super::assignment::min_cost_assignment;
use super::clear_mot::{
    ClearMotConfig, ClearMotResult, IdSwitchRule, MatchingRule, MotFrame, TrackedBox, clear_mot,
};
use super::iou::{AREA_EPS, Box2, IouKind, image_fraction_inside, iou_image};
use crate::io::kitti::calib::Calib;
use crate::io::kitti::detections::camera_box_to_lidar;
use crate::io::kitti::labels::TrackingLabel;
use limot_estimator::geometry::OrientedBox;
use limot_estimator::input::ObjectClass;
use std::collections::BTreeMap;

/// The classes TrackEval's KITTI 2D box benchmark evaluates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum KittiEvalClass {
    /// Class Car (distractor: Van).
    Car,
    /// Class Pedestrian (distractors: Person, Person_sitting).
    Pedestrian,
}

impl KittiEvalClass {
    /// Both classes.
    pub const ALL: [KittiEvalClass; 2] = [KittiEvalClass::Car, KittiEvalClass::Pedestrian];

    /// The class in our own types.
    pub fn object_class(self) -> ObjectClass {
        match self {
            KittiEvalClass::Car => ObjectClass::Car,
            KittiEvalClass::Pedestrian => ObjectClass::Pedestrian,
        }
    }

    /// Whether a KITTI type name is this class (case-insensitive).
    pub fn is_class(self, type_name: &str) -> bool {
        let lower = type_name.to_ascii_lowercase();
        match self {
            KittiEvalClass::Car => lower == "car",
            KittiEvalClass::Pedestrian => lower == "pedestrian",
        }
    }

    /// Whether a KITTI type name is this class's distractor (matched tracker
    /// boxes are ignored, the ground truth is not evaluated).
    pub fn is_distractor(self, type_name: &str) -> bool {
        let lower = type_name.to_ascii_lowercase();
        match self {
            KittiEvalClass::Car => lower == "van",
            KittiEvalClass::Pedestrian => lower == "person" || lower == "person_sitting",
        }
    }
}

/// TrackEval's `Kitti2DBox` preprocessing parameters (its hard-coded values
/// are the [`Default`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KittiPreprocessConfig {
    /// The evaluated class.
    pub class: KittiEvalClass,
    /// Ground truth more occluded than this is a distractor (2).
    pub max_occlusion: i64,
    /// Ground truth more truncated than this is a distractor (0).
    pub max_truncation: i64,
    /// Unmatched tracker boxes at most this tall are removed (25 px).
    pub min_height_px: f64,
    /// IoU threshold of the preprocessing match (0.5).
    pub match_iou_threshold: f64,
    /// Unmatched tracker boxes more than this fraction inside a DontCare region are removed (0.5).
    pub dont_care_min_fraction: f64,
}

impl Default for KittiPreprocessConfig {
    fn default() -> Self {
        KittiPreprocessConfig::for_class(KittiEvalClass::Car)
    }
}

impl KittiPreprocessConfig {
    /// TrackEval's settings for `class`.
    pub fn for_class(class: KittiEvalClass) -> KittiPreprocessConfig {
        KittiPreprocessConfig {
            class,
            max_occlusion: 2,
            max_truncation: 0,
            min_height_px: 25.0,
            match_iou_threshold: 0.5,
            dont_care_min_fraction: 0.5,
        }
    }
}

/// What the preprocessing removed, summed over the frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct KittiPreprocessStats {
    /// Ground-truth boxes of the class or its distractor (before filtering).
    pub gt_candidates: usize,
    /// Of those, the ones not evaluated (distractor class, occluded, truncated).
    pub gt_distractors: usize,
    /// Tracker boxes of the class (before filtering).
    pub tracker_candidates: usize,
    /// Tracker boxes removed because they matched a distractor.
    pub removed_matched_distractor: usize,
    /// Unmatched tracker boxes removed for their height.
    pub removed_too_small: usize,
    /// Unmatched tracker boxes removed inside a DontCare region (and tall enough).
    pub removed_dont_care: usize,
}

/// Frames ready for [`clear_mot`] plus what preprocessing removed.
#[derive(Debug, Clone, PartialEq)]
pub struct KittiMotFrames {
    /// The frames to evaluate, image boxes.
    pub frames: Vec<MotFrame<Box2>>,
    /// What the preprocessing removed.
    pub stats: KittiPreprocessStats,
}

fn check_params(cfg: &KittiPreprocessConfig) -> Result<(), EvalError> {
    let unit = |x: f64| (0.0..=1.0).contains(&x);
    if !unit(cfg.match_iou_threshold) || cfg.match_iou_threshold == 0.0 {
        return Err(EvalError::BadParameter {
            what: "KittiPreprocessConfig.match_iou_threshold",
            why: format!("must be in (0, 1], got {}", cfg.match_iou_threshold),
        });
    }
    if !unit(cfg.dont_care_min_fraction) {
        return Err(EvalError::BadParameter {
            what: "KittiPreprocessConfig.dont_care_min_fraction",
            why: format!("must be in [0, 1], got {}", cfg.dont_care_min_fraction),
        });
    }
    if !cfg.min_height_px.is_finite() {
        return Err(EvalError::BadParameter {
            what: "KittiPreprocessConfig.min_height_px",
            why: format!("must be finite, got {}", cfg.min_height_px),
        });
    }
    Ok(())
}

/// Validated image box of a label; `index` is the label's position in its list.
fn label_box(what: &'static str, index: usize, label: &TrackingLabel) -> Result<Box2, EvalError> {
    let b = Box2::from_ltrb(label.bbox_2d);
    b.validate().map_err(|(field, why)| EvalError::Invalid {
        what,
        index,
        field,
        why: format!("frame {} track {}: {why}", label.frame, label.track_id),
    })?;
    Ok(b)
}

/// Groups labels by frame, checking that every frame is below `num_frames`.
fn by_frame<'a>(
    what: &'static str,
    labels: &'a [TrackingLabel],
    num_frames: u32,
) -> Result<Vec<Vec<(usize, &'a TrackingLabel)>>, EvalError> {
    let mut out: Vec<Vec<(usize, &TrackingLabel)>> = vec![Vec::new(); num_frames as usize];
    for (index, label) in labels.iter().enumerate() {
        let Some(slot) = out.get_mut(label.frame as usize) else {
            return Err(EvalError::Invalid {
                what,
                index,
                field: "frame",
                why: format!(
                    "frame {} is outside the sequence of {num_frames} frames",
                    label.frame
                ),
            });
        };
        slot.push((index, label));
    }
    Ok(out)
}

/// TrackEval's preprocessing of one KITTI sequence for one class: ground-truth
/// labels (`label_02` with DontCare rows) and tracker results, both in the
/// KITTI tracking label format, frames `0..num_frames` (the seqmap length).
///
/// # Errors
///
/// [`EvalError`] for invalid labels or preprocessing settings.
pub fn kitti_2d_frames(
    gt: &[TrackingLabel],
    results: &[TrackingLabel],
    num_frames: u32,
    cfg: &KittiPreprocessConfig,
) -> Result<KittiMotFrames, EvalError> {
    check_params(cfg)?;
    let gt_frames = by_frame("kitti ground-truth label", gt, num_frames)?;
    let result_frames = by_frame("kitti result label", results, num_frames)?;
    let class = cfg.class;
    let mut stats = KittiPreprocessStats::default();
    let mut frames = Vec::with_capacity(num_frames as usize);
    for (gt_rows, result_rows) in gt_frames.iter().zip(&result_frames) {
        let mut regions = Vec::new();
        // (id, box, evaluated?) of the class and its distractors.
        let mut gt_c: Vec<(u64, Box2, bool)> = Vec::new();
        for &(index, label) in gt_rows {
            let what = "kitti ground-truth label";
            if label.is_dont_care() {
                regions.push(label_box(what, index, label)?);
                continue;
            }
            let of_class = class.is_class(&label.type_name);
            if label.track_id < 0 || !(of_class || class.is_distractor(&label.type_name)) {
                continue;
            }
            // TrackEval reads truncation with `astype(int)` (toward zero).
            let truncation = label.truncated as i64;
            let evaluated =
                of_class && label.occluded <= cfg.max_occlusion && truncation <= cfg.max_truncation;
            gt_c.push((
                label.track_id as u64,
                label_box(what, index, label)?,
                evaluated,
            ));
        }
        let mut tr_c: Vec<(u64, Box2)> = Vec::new();
        for &(index, label) in result_rows {
            if label.track_id >= 0 && class.is_class(&label.type_name) {
                let b = label_box("kitti result label", index, label)?;
                tr_c.push((label.track_id as u64, b));
            }
        }
        stats.gt_candidates += gt_c.len();
        stats.gt_distractors += gt_c.iter().filter(|g| !g.2).count();
        stats.tracker_candidates += tr_c.len();

        // Preprocessing match: maximum summed IoU, scores below the threshold zeroed.
        let (n_gt, n_tr) = (gt_c.len(), tr_c.len());
        let mut cost = Vec::with_capacity(n_gt * n_tr);
        for g in &gt_c {
            for t in &tr_c {
                let s = iou_image(&g.1, &t.1);
                cost.push(if s < cfg.match_iou_threshold - AREA_EPS {
                    0.0
                } else {
                    -s
                });
            }
        }
        let mut keep_track = vec![true; n_tr];
        let mut matched_track = vec![false; n_tr];
        for (i, j) in min_cost_assignment(n_gt, n_tr, &cost)?.pairs {
            if -cost[i * n_tr + j] > AREA_EPS {
                matched_track[j] = true;
                if !gt_c[i].2 {
                    keep_track[j] = false;
                    stats.removed_matched_distractor += 1;
                }
            }
        }
        for (j, t) in tr_c.iter().enumerate() {
            if matched_track[j] {
                continue;
            }
            if t.1.height_px() <= cfg.min_height_px + AREA_EPS {
                keep_track[j] = false;
                stats.removed_too_small += 1;
            } else if regions
                .iter()
                .any(|r| image_fraction_inside(&t.1, r) > cfg.dont_care_min_fraction + AREA_EPS)
            {
                keep_track[j] = false;
                stats.removed_dont_care += 1;
            }
        }
        let object_class = class.object_class();
        frames.push(MotFrame {
            gt: gt_c
                .iter()
                .filter(|g| g.2)
                .map(|&(id, bbox, _)| TrackedBox {
                    id,
                    class: object_class,
                    bbox,
                })
                .collect(),
            tracks: tr_c
                .iter()
                .zip(&keep_track)
                .filter(|(_, keep)| **keep)
                .map(|(&(id, bbox), _)| TrackedBox {
                    id,
                    class: object_class,
                    bbox,
                })
                .collect(),
            // Already applied above, relative to the preprocessing match.
            dont_care: Vec::new(),
        });
    }
    Ok(KittiMotFrames { frames, stats })
}

/// CLEAR-MOT of one KITTI sequence and class as TrackEval's `Kitti2DBox`
/// with its `CLEAR` metric computes it.
///
/// # Errors
///
/// As [`kitti_2d_frames`] and [`clear_mot`].
pub fn kitti_2d_clear_mot(
    gt: &[TrackingLabel],
    results: &[TrackingLabel],
    num_frames: u32,
    class: KittiEvalClass,
) -> Result<ClearMotResult, EvalError> {
    let prepared = kitti_2d_frames(
        gt,
        results,
        num_frames,
        &KittiPreprocessConfig::for_class(class),
    )?;
    clear_mot(&prepared.frames, &ClearMotConfig::trackeval())
}

/// AB3DMOT-style 3D CLEAR-MOT of one sequence: TrackEval's KITTI preprocessing
/// (distractors, DontCare, small boxes; decided on the image boxes as the 2D
/// benchmark does), then CLEAR-MOT on the 3D IoU of the kept boxes (LiDAR frame
/// via `calib`) at `iou_threshold`, TrackEval's matching and ID-switch rules.
///
/// # Errors
///
/// As [`kitti_2d_frames`] and [`clear_mot`].
pub fn kitti_3d_clear_mot(
    gt: &[TrackingLabel],
    results: &[TrackingLabel],
    num_frames: u32,
    class: KittiEvalClass,
    calib: &Calib,
    iou_threshold: f64,
) -> Result<ClearMotResult, EvalError> {
    let prepared = kitti_2d_frames(
        gt,
        results,
        num_frames,
        &KittiPreprocessConfig::for_class(class),
    )?;
    // (frame, id) → 3D box, for the ground truth and for the results.
    let boxes_of = |labels: &[TrackingLabel]| -> BTreeMap<(u32, u64), OrientedBox> {
        labels
            .iter()
            .filter(|l| l.track_id >= 0 && !l.is_dont_care())
            .map(|l| {
                let b = camera_box_to_lidar(&l.cam_box, calib);
                (
                    (l.frame, l.track_id as u64),
                    OrientedBox::new(b.center, b.size_lwh, b.yaw_rad),
                )
            })
            .collect()
    };
    let gt_boxes = boxes_of(gt);
    let result_boxes = boxes_of(results);
    let lift = |frame: u32,
                boxes: &BTreeMap<(u32, u64), OrientedBox>,
                items: &[TrackedBox<Box2>]|
     -> Vec<TrackedBox<OrientedBox>> {
        items
            .iter()
            .filter_map(|t| {
                boxes.get(&(frame, t.id)).map(|b| TrackedBox {
                    id: t.id,
                    class: t.class,
                    bbox: *b,
                })
            })
            .collect()
    };
    let frames: Vec<MotFrame<OrientedBox>> = prepared
        .frames
        .iter()
        .enumerate()
        .map(|(k, f)| MotFrame {
            gt: lift(k as u32, &gt_boxes, &f.gt),
            tracks: lift(k as u32, &result_boxes, &f.tracks),
            dont_care: Vec::new(),
        })
        .collect();
    let cfg = ClearMotConfig {
        iou_threshold,
        iou_kind: IouKind::ThreeD,
        id_switch_rule: IdSwitchRule::LastMatched,
        matching: MatchingRule::TrackEval,
        dont_care_min_fraction: 0.5,
    };
    clear_mot(&frames, &cfg)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::kitti::labels::parse_labels;
    use std::path::Path;

    fn labels(text: &str) -> Vec<TrackingLabel> {
        parse_labels(text, Path::new("t.txt")).unwrap()
    }

    // Frame 0: car 0 (evaluated), van 1, car 2 truncated, a DontCare region.
    const GT: &str = "\
0 0 Car 0 0 0 100 100 200 200 1.5 1.6 3.9 0 1.7 20 0
0 1 Van 0 0 0 300 100 400 200 2 1.8 4.4 3 1.8 20 0
0 2 Car 1 0 0 500 100 600 200 1.5 1.6 3.9 6 1.7 20 0
0 -1 DontCare -1 -1 -10 700 100 800 200 -1 -1 -1 -1000 -1000 -1000 -10
1 0 Car 0 3 0 100 100 200 200 1.5 1.6 3.9 0 1.7 20 0
";

    fn result(frame: u32, id: i64, ltrb: [f64; 4]) -> String {
        format!(
            "{frame} {id} Car -1 -1 0 {} {} {} {} 1.5 1.6 3.9 0 1.7 20 0 0.9\n",
            ltrb[0], ltrb[1], ltrb[2], ltrb[3]
        )
    }

    #[test]
    fn preprocessing_removes_what_trackeval_removes() {
        let gt = labels(GT);
        let mut text = String::new();
        text += &result(0, 5, [102.0, 100.0, 202.0, 200.0]); // TP on car 0
        text += &result(0, 6, [300.0, 100.0, 400.0, 200.0]); // on the van: removed
        text += &result(0, 7, [500.0, 100.0, 600.0, 200.0]); // on truncated car 2: removed
        text += &result(0, 8, [710.0, 110.0, 790.0, 190.0]); // in DontCare: removed
        text += &result(0, 9, [900.0, 100.0, 950.0, 120.0]); // 20 px tall: removed
        text += &result(0, 10, [900.0, 200.0, 950.0, 260.0]); // FP
        text += &result(1, 5, [100.0, 100.0, 200.0, 200.0]); // on occluded car: removed
        let res = labels(&text);
        let p = kitti_2d_frames(&gt, &res, 3, &KittiPreprocessConfig::default()).unwrap();
        assert_eq!(p.frames.len(), 3);
        assert_eq!(
            p.stats,
            KittiPreprocessStats {
                gt_candidates: 4,
                gt_distractors: 3,
                tracker_candidates: 7,
                removed_matched_distractor: 3,
                removed_too_small: 1,
                removed_dont_care: 1,
            }
        );
        let ids: Vec<u64> = p.frames[0].tracks.iter().map(|t| t.id).collect();
        assert_eq!(ids, vec![5, 10]);
        assert_eq!(p.frames[0].gt.len(), 1);
        assert!(p.frames[1].gt.is_empty() && p.frames[1].tracks.is_empty());
        let r = kitti_2d_clear_mot(&gt, &res, 3, KittiEvalClass::Car).unwrap();
        assert_eq!((r.matches, r.false_positives, r.false_negatives), (1, 1, 0));
        assert!((r.motp.unwrap() - 98.0 * 100.0 / (102.0 * 100.0)).abs() < 1e-12);
        assert_eq!(r.mota, Some(0.0));
        // Pedestrians: no ground truth, tracker rows are cars: nothing at all.
        let ped = kitti_2d_clear_mot(&gt, &res, 3, KittiEvalClass::Pedestrian).unwrap();
        assert_eq!((ped.gt_count, ped.track_count, ped.mota), (0, 0, None));
    }

    #[test]
    fn unmatched_dont_care_only_counts_when_unmatched() {
        // A tracker box matched to an evaluated car inside a DontCare region stays a TP.
        let gt = labels(
            "0 0 Car 0 0 0 100 100 200 200 1.5 1.6 3.9 0 1.7 20 0\n\
             0 -1 DontCare -1 -1 -10 90 90 210 210 -1 -1 -1 -1000 -1000 -1000 -10\n",
        );
        let res = labels(&result(0, 3, [100.0, 100.0, 200.0, 200.0]));
        let r = kitti_2d_clear_mot(&gt, &res, 1, KittiEvalClass::Car).unwrap();
        assert_eq!((r.matches, r.false_positives), (1, 0));
    }

    #[test]
    fn bad_inputs_are_errors() {
        let gt = labels(GT);
        let outside = labels(&result(7, 1, [0.0, 0.0, 50.0, 50.0]));
        let err = kitti_2d_frames(&gt, &outside, 3, &KittiPreprocessConfig::default())
            .unwrap_err()
            .to_string();
        assert!(err.contains("frame 7") && err.contains("3 frames"), "{err}");
        let inverted = labels(&result(0, 1, [50.0, 0.0, 10.0, 50.0]));
        let err = kitti_2d_frames(&gt, &inverted, 3, &KittiPreprocessConfig::default())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("right_px") && err.contains("result label"),
            "{err}"
        );
        let bad = KittiPreprocessConfig {
            match_iou_threshold: 0.0,
            ..KittiPreprocessConfig::default()
        };
        assert!(kitti_2d_frames(&gt, &[], 3, &bad).is_err());
    }

    #[test]
    fn three_d_evaluation_uses_3d_iou_after_kitti_preprocessing() {
        use crate::io::kitti::detections::camera_box_to_lidar;
        use crate::io::kitti::labels::parse_labels;
        use crate::metrics::iou::iou_3d;
        use std::path::Path;
        let calib = crate::io::kitti::calib::tests::sample();
        let parse = |text: &str| parse_labels(text, Path::new("t.txt")).unwrap();
        // Frame 0: a car 20 m ahead and a van; frame 1: the car only.
        let gt = parse(
            "0 0 Car 0 0 0 500 150 600 250 1.5 1.6 4.0 1.0 1.7 20.0 -1.57\n\
             0 1 Van 0 0 0 100 150 200 250 2.0 1.8 4.5 -6.0 1.8 20.0 -1.57\n\
             1 0 Car 0 0 0 500 150 600 250 1.5 1.6 4.0 1.0 1.7 20.0 -1.57\n",
        );
        // Frame 0: the car shifted 1 m along its length (3D IoU 0.6), a box
        // on the van (removed), frame 1: the car shifted 3 m (IoU 1/7 < 0.25).
        let results = parse(
            "0 3 Car 0 0 0 500 150 600 250 1.5 1.6 4.0 1.0 1.7 21.0 -1.57 0.9\n\
             0 4 Car 0 0 0 100 150 200 250 2.0 1.8 4.5 -6.0 1.8 20.0 -1.57 0.9\n\
             1 3 Car 0 0 0 500 150 600 250 1.5 1.6 4.0 1.0 1.7 23.0 -1.57 0.9\n",
        );
        let r = kitti_3d_clear_mot(&gt, &results, 2, KittiEvalClass::Car, &calib, 0.25).unwrap();
        assert_eq!(r.gt_count, 2);
        assert_eq!(r.track_count, 2, "the box on the van is removed");
        assert_eq!((r.matches, r.false_positives, r.false_negatives), (1, 1, 1));
        let to_box3 = |l: &TrackingLabel| {
            let b = camera_box_to_lidar(&l.cam_box, &calib);
            OrientedBox::new(b.center, b.size_lwh, b.yaw_rad)
        };
        let expected = iou_3d(&to_box3(&gt[0]), &to_box3(&results[0]));
        assert!((expected - 0.6).abs() < 0.01, "{expected}");
        assert!((r.motp.unwrap() - expected).abs() < 1e-12);
        assert!((r.mota.unwrap() - (1.0 - 2.0 / 2.0)).abs() < 1e-12);
        // The same results pass the image benchmark (identical 2D boxes).
        let r2 = kitti_2d_clear_mot(&gt, &results, 2, KittiEvalClass::Car).unwrap();
        assert_eq!((r2.matches, r2.false_positives), (2, 0));
    }
}
