//! CLEAR-MOT tracking metrics (Bernardin & Stiefelhagen 2008) on 3D boxes, as
//! the KITTI tracking devkit / AB3DMOT 3D evaluation and TrackEval compute them.
//!
//! Per frame:
//! 1. A ground-truth object keeps the tracker id it was matched to in the
//!    previous frame if that track is present and still overlaps with
//!    IoU ≥ threshold (the CLEAR-MOT rule; TrackEval implements it with a
//!    +1000 score bonus, which is equivalent).
//! 2. The remaining objects and tracks are matched by the Hungarian algorithm
//!    on cost 1 − IoU, pairs with IoU < threshold forbidden (maximum number of
//!    matches, then maximum summed IoU).
//! 3. Unmatched tracks are false positives, except those whose bird's-eye
//!    footprint lies more than `dont_care_min_fraction` inside a DontCare
//!    region (KITTI's rule for DontCare areas, applied to BEV boxes here);
//!    those are ignored. Unmatched ground-truth objects are false negatives.
//! 4. An ID switch is counted when a matched object's tracker id differs from
//!    a previous one (see [`IdSwitchRule`]).
//!
//! MOTA = 1 − (FN + FP + IDSW) / GT. MOTP = mean IoU of the matches (KITTI's
//! devkit reports MOTP as the mean overlap of true positives, which for 3D
//! evaluation is the mean 3D IoU; higher is better). Fragmentations count how
//! often a ground-truth trajectory resumes being tracked after an interruption
//! (tracked segments − 1, counted over the frames in which the object appears,
//! as the KITTI devkit walks each trajectory; a frame in which the object is
//! absent from the ground truth does not interrupt it, unlike TrackEval). MT/PT/ML: objects tracked in > 80 %, 20–80 %,
//! < 20 % of the frames they appear in.

use super::EvalError;
use super::assignment::min_cost_assignment;
use super::iou::{Box3, IouKind, bev_fraction_inside, iou};
use limot_estimator::input::ObjectClass;
use limot_sim::record::BoxTruth;
use std::collections::{BTreeMap, BTreeSet, HashMap};

/// The IoU thresholds of the paper's tracking tables.
pub const PAPER_IOU_THRESHOLDS: [f64; 2] = [0.25, 0.5];

/// A box with an identity: a ground-truth object or a tracker output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackedBox {
    pub id: u64,
    pub class: ObjectClass,
    pub bbox: Box3,
}

impl TrackedBox {
    /// A simulator ground-truth box (world frame; roll and pitch dropped).
    pub fn from_box_truth(truth: &BoxTruth) -> TrackedBox {
        TrackedBox {
            id: u64::from(truth.id),
            class: truth.class,
            bbox: Box3::from_pose(&truth.t_world_box, truth.size_lwh_m),
        }
    }
}

/// Everything compared in one frame (boxes in one common frame, e.g. world or LiDAR).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MotFrame {
    pub gt: Vec<TrackedBox>,
    pub tracks: Vec<TrackedBox>,
    /// Regions in which unmatched tracker boxes are not counted as false positives.
    pub dont_care: Vec<Box3>,
}

/// When a change of tracker id counts as an identity switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum IdSwitchRule {
    /// Against the last tracker id the object was ever matched to, even across
    /// frames where it was missed (CLEAR-MOT, TrackEval, MOTChallenge).
    #[default]
    LastMatched,
    /// Only when the object was also matched at its previous appearance
    /// (KITTI devkit: a switch across a gap of misses is not counted).
    Consecutive,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClearMotConfig {
    /// A pair matches when IoU ≥ this (paper: 0.25 and 0.5).
    pub iou_threshold: f64,
    pub iou_kind: IouKind,
    pub id_switch_rule: IdSwitchRule,
    /// Unmatched tracks more than this fraction inside a DontCare region are ignored.
    pub dont_care_min_fraction: f64,
}

impl Default for ClearMotConfig {
    fn default() -> Self {
        ClearMotConfig {
            iou_threshold: 0.5,
            iou_kind: IouKind::ThreeD,
            id_switch_rule: IdSwitchRule::LastMatched,
            dont_care_min_fraction: 0.5,
        }
    }
}

impl ClearMotConfig {
    pub fn with_threshold(iou_threshold: f64) -> ClearMotConfig {
        ClearMotConfig {
            iou_threshold,
            ..ClearMotConfig::default()
        }
    }
}

/// One ground-truth ↔ track correspondence in a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameMatch {
    /// Index into the frame's `gt` list.
    pub gt_index: usize,
    /// Index into the frame's `tracks` list.
    pub track_index: usize,
    pub gt_id: u64,
    pub track_id: u64,
    pub iou: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ClearMotResult {
    /// `None` when there is no ground truth.
    pub mota: Option<f64>,
    /// Mean IoU of the matches; `None` without matches.
    pub motp: Option<f64>,
    pub matches: usize,
    pub false_positives: usize,
    pub false_negatives: usize,
    pub id_switches: usize,
    pub fragmentations: usize,
    /// Ground-truth boxes over all frames.
    pub gt_count: usize,
    /// Tracker boxes over all frames (including ignored ones).
    pub track_count: usize,
    /// Unmatched tracker boxes ignored because they lie in a DontCare region.
    pub ignored_tracks: usize,
    pub gt_objects: usize,
    pub mostly_tracked: usize,
    pub partially_tracked: usize,
    pub mostly_lost: usize,
    pub iou_sum: f64,
    /// The matches of every frame, in frame order.
    pub per_frame: Vec<Vec<FrameMatch>>,
}

fn validate_frame(index: usize, frame: &MotFrame) -> Result<(), EvalError> {
    for (what, boxes) in [
        ("frame gt box", &frame.gt),
        ("frame track box", &frame.tracks),
    ] {
        let mut seen = BTreeSet::new();
        for b in boxes.iter() {
            if let Err((field, why)) = b.bbox.validate() {
                return Err(EvalError::Invalid {
                    what,
                    index,
                    field,
                    why: format!("id {}: {why}", b.id),
                });
            }
            if !seen.insert(b.id) {
                return Err(EvalError::Invalid {
                    what,
                    index,
                    field: "id",
                    why: format!("id {} appears twice in the frame", b.id),
                });
            }
        }
    }
    for region in &frame.dont_care {
        if let Err((field, why)) = region.validate() {
            return Err(EvalError::Invalid {
                what: "frame dont_care region",
                index,
                field,
                why,
            });
        }
    }
    Ok(())
}

fn validate_config(cfg: &ClearMotConfig) -> Result<(), EvalError> {
    let in_unit = |x: f64| (0.0..=1.0).contains(&x);
    if !in_unit(cfg.iou_threshold) || cfg.iou_threshold == 0.0 {
        return Err(EvalError::BadParameter {
            what: "ClearMotConfig.iou_threshold",
            why: format!("must be in (0, 1], got {}", cfg.iou_threshold),
        });
    }
    if !in_unit(cfg.dont_care_min_fraction) {
        return Err(EvalError::BadParameter {
            what: "ClearMotConfig.dont_care_min_fraction",
            why: format!("must be in [0, 1], got {}", cfg.dont_care_min_fraction),
        });
    }
    Ok(())
}

/// Matches one frame: previous correspondences first, Hungarian for the rest.
fn match_frame(
    frame: &MotFrame,
    cfg: &ClearMotConfig,
    prev_frame_match: &HashMap<u64, u64>,
) -> Result<Vec<FrameMatch>, EvalError> {
    let (n_gt, n_tr) = (frame.gt.len(), frame.tracks.len());
    let mut ious = vec![0.0; n_gt * n_tr];
    for (i, g) in frame.gt.iter().enumerate() {
        for (j, t) in frame.tracks.iter().enumerate() {
            ious[i * n_tr + j] = iou(&g.bbox, &t.bbox, cfg.iou_kind);
        }
    }
    let track_index: HashMap<u64, usize> = frame
        .tracks
        .iter()
        .enumerate()
        .map(|(j, t)| (t.id, j))
        .collect();
    let mut matches = Vec::new();
    let mut gt_taken = vec![false; n_gt];
    let mut track_taken = vec![false; n_tr];
    for (i, g) in frame.gt.iter().enumerate() {
        let kept = prev_frame_match
            .get(&g.id)
            .and_then(|tid| track_index.get(tid).copied());
        if let Some(j) = kept
            && ious[i * n_tr + j] >= cfg.iou_threshold
        {
            gt_taken[i] = true;
            track_taken[j] = true;
            matches.push((i, j));
        }
    }
    let free_gt: Vec<usize> = (0..n_gt).filter(|&i| !gt_taken[i]).collect();
    let free_tr: Vec<usize> = (0..n_tr).filter(|&j| !track_taken[j]).collect();
    let mut cost = Vec::with_capacity(free_gt.len() * free_tr.len());
    for &i in &free_gt {
        for &j in &free_tr {
            let o = ious[i * n_tr + j];
            cost.push(if o >= cfg.iou_threshold {
                1.0 - o
            } else {
                f64::INFINITY
            });
        }
    }
    let assignment = min_cost_assignment(free_gt.len(), free_tr.len(), &cost)?;
    for (r, c) in assignment.pairs {
        matches.push((free_gt[r], free_tr[c]));
    }
    matches.sort_unstable();
    Ok(matches
        .into_iter()
        .map(|(i, j)| FrameMatch {
            gt_index: i,
            track_index: j,
            gt_id: frame.gt[i].id,
            track_id: frame.tracks[j].id,
            iou: ious[i * n_tr + j],
        })
        .collect())
}

/// Per-object bookkeeping across frames.
#[derive(Default)]
struct GtHistory {
    present: usize,
    matched: usize,
    /// Last tracker id ever matched.
    last_matched: Option<u64>,
    /// Tracker id at the previous appearance (None = missed then).
    previous_appearance: Option<u64>,
    /// Number of tracked segments.
    segments: usize,
}

/// Class-agnostic CLEAR-MOT over a sequence of frames (classes are ignored;
/// use [`clear_mot_per_class`] for the per-class figures).
pub fn clear_mot(frames: &[MotFrame], cfg: &ClearMotConfig) -> Result<ClearMotResult, EvalError> {
    validate_config(cfg)?;
    for (i, f) in frames.iter().enumerate() {
        validate_frame(i, f)?;
    }
    let mut history: BTreeMap<u64, GtHistory> = BTreeMap::new();
    let mut prev_frame_match: HashMap<u64, u64> = HashMap::new();
    let mut r = ClearMotResult {
        mota: None,
        motp: None,
        matches: 0,
        false_positives: 0,
        false_negatives: 0,
        id_switches: 0,
        fragmentations: 0,
        gt_count: 0,
        track_count: 0,
        ignored_tracks: 0,
        gt_objects: 0,
        mostly_tracked: 0,
        partially_tracked: 0,
        mostly_lost: 0,
        iou_sum: 0.0,
        per_frame: Vec::with_capacity(frames.len()),
    };
    for frame in frames {
        let matches = match_frame(frame, cfg, &prev_frame_match)?;
        r.gt_count += frame.gt.len();
        r.track_count += frame.tracks.len();
        r.matches += matches.len();
        r.false_negatives += frame.gt.len() - matches.len();
        let mut track_matched = vec![false; frame.tracks.len()];
        for m in &matches {
            track_matched[m.track_index] = true;
            r.iou_sum += m.iou;
        }
        for (j, t) in frame.tracks.iter().enumerate() {
            if track_matched[j] {
                continue;
            }
            let in_dont_care = frame
                .dont_care
                .iter()
                .any(|d| bev_fraction_inside(&t.bbox, d) > cfg.dont_care_min_fraction);
            if in_dont_care {
                r.ignored_tracks += 1;
            } else {
                r.false_positives += 1;
            }
        }
        let matched_track: HashMap<u64, u64> =
            matches.iter().map(|m| (m.gt_id, m.track_id)).collect();
        for g in &frame.gt {
            let h = history.entry(g.id).or_default();
            h.present += 1;
            let now = matched_track.get(&g.id).copied();
            if let Some(tid) = now {
                h.matched += 1;
                let reference = match cfg.id_switch_rule {
                    IdSwitchRule::LastMatched => h.last_matched,
                    IdSwitchRule::Consecutive => h.previous_appearance,
                };
                if reference.is_some_and(|prev| prev != tid) {
                    r.id_switches += 1;
                }
                // A new tracked segment starts unless matched at the previous appearance.
                if h.previous_appearance.is_none() {
                    h.segments += 1;
                }
                h.last_matched = Some(tid);
            }
            h.previous_appearance = now;
        }
        prev_frame_match = matched_track;
        r.per_frame.push(matches);
    }
    r.gt_objects = history.len();
    for h in history.values() {
        r.fragmentations += h.segments.saturating_sub(1);
        let ratio = h.matched as f64 / h.present as f64;
        if ratio > 0.8 {
            r.mostly_tracked += 1;
        } else if ratio < 0.2 {
            r.mostly_lost += 1;
        } else {
            r.partially_tracked += 1;
        }
    }
    if r.gt_count > 0 {
        let errors = (r.false_negatives + r.false_positives + r.id_switches) as f64;
        r.mota = Some(1.0 - errors / r.gt_count as f64);
    }
    if r.matches > 0 {
        r.motp = Some(r.iou_sum / r.matches as f64);
    }
    Ok(r)
}

/// CLEAR-MOT for every class that occurs in the ground truth or the tracks:
/// boxes of other classes are dropped, DontCare regions apply to all classes.
pub fn clear_mot_per_class(
    frames: &[MotFrame],
    cfg: &ClearMotConfig,
) -> Result<BTreeMap<ObjectClass, ClearMotResult>, EvalError> {
    let classes: BTreeSet<ObjectClass> = frames
        .iter()
        .flat_map(|f| f.gt.iter().chain(&f.tracks).map(|b| b.class))
        .collect();
    let mut out = BTreeMap::new();
    for class in classes {
        let filtered: Vec<MotFrame> = frames
            .iter()
            .map(|f| MotFrame {
                gt: f.gt.iter().filter(|b| b.class == class).copied().collect(),
                tracks: f
                    .tracks
                    .iter()
                    .filter(|b| b.class == class)
                    .copied()
                    .collect(),
                dont_care: f.dont_care.clone(),
            })
            .collect();
        out.insert(class, clear_mot(&filtered, cfg)?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn car(id: u64, x: f64) -> TrackedBox {
        TrackedBox {
            id,
            class: ObjectClass::Car,
            bbox: Box3::new(Vector3::new(x, 0.0, 1.0), Vector3::new(4.0, 2.0, 2.0), 0.0),
        }
    }

    fn frame(gt: Vec<TrackedBox>, tracks: Vec<TrackedBox>) -> MotFrame {
        MotFrame {
            gt,
            tracks,
            dont_care: Vec::new(),
        }
    }

    /// Two objects, three frames: one FP, one FN, one ID switch, one imperfect match.
    fn hand_sequence() -> Vec<MotFrame> {
        vec![
            frame(
                vec![car(1, 0.0), car(2, 10.0)],
                vec![car(10, 0.0), car(11, 10.0)],
            ),
            frame(
                vec![car(1, 0.0), car(2, 10.0)],
                vec![car(10, 0.0), car(12, 10.0), car(13, 50.0)],
            ),
            // Track 10 is 1 m off along its length: IoU = 3/5.
            frame(vec![car(1, 0.0), car(2, 10.0)], vec![car(10, 1.0)]),
        ]
    }

    #[test]
    fn hand_counts_and_mota() {
        let r = clear_mot(&hand_sequence(), &ClearMotConfig::default()).unwrap();
        assert_eq!(r.gt_count, 6);
        assert_eq!(r.matches, 5);
        assert_eq!(r.false_positives, 1);
        assert_eq!(r.false_negatives, 1);
        assert_eq!(r.id_switches, 1);
        assert_eq!(r.fragmentations, 0);
        assert_eq!(r.mota, Some(1.0 - 3.0 / 6.0));
        assert!((r.motp.unwrap() - (4.0 + 0.6) / 5.0).abs() < 1e-12);
        assert_eq!(
            (r.mostly_tracked, r.partially_tracked, r.mostly_lost),
            (1, 1, 0)
        );
        assert_eq!(r.track_count, 6);
        // At threshold 0.65 the shifted match in frame 2 fails: one more FN and FP.
        let strict = clear_mot(&hand_sequence(), &ClearMotConfig::with_threshold(0.65)).unwrap();
        assert_eq!(
            (
                strict.matches,
                strict.false_negatives,
                strict.false_positives
            ),
            (4, 2, 2)
        );
    }

    #[test]
    fn previous_correspondence_is_kept() {
        // Frame 1: track 11 overlaps object 1 better, but 10 still passes the threshold.
        let frames = vec![
            frame(vec![car(1, 0.0)], vec![car(10, 0.0)]),
            frame(vec![car(1, 0.0)], vec![car(10, 1.0), car(11, 0.0)]),
        ];
        let r = clear_mot(&frames, &ClearMotConfig::default()).unwrap();
        assert_eq!(r.per_frame[1][0].track_id, 10);
        assert_eq!(r.id_switches, 0);
        assert_eq!(r.false_positives, 1);
        // Below the threshold the correspondence is dropped and 11 takes over.
        let r = clear_mot(&frames, &ClearMotConfig::with_threshold(0.7)).unwrap();
        assert_eq!(r.per_frame[1][0].track_id, 11);
        assert_eq!(r.id_switches, 1);
    }

    #[test]
    fn switch_across_a_gap_depends_on_rule() {
        let frames = vec![
            frame(vec![car(1, 0.0)], vec![car(10, 0.0)]),
            frame(vec![car(1, 0.0)], vec![]),
            frame(vec![car(1, 0.0)], vec![car(11, 0.0)]),
        ];
        let clear = clear_mot(&frames, &ClearMotConfig::default()).unwrap();
        assert_eq!(clear.id_switches, 1);
        assert_eq!(clear.fragmentations, 1);
        let kitti = ClearMotConfig {
            id_switch_rule: IdSwitchRule::Consecutive,
            ..ClearMotConfig::default()
        };
        let k = clear_mot(&frames, &kitti).unwrap();
        assert_eq!(k.id_switches, 0);
        assert_eq!(k.mota, Some(1.0 - 1.0 / 3.0));
    }

    #[test]
    fn absence_from_ground_truth_is_not_a_fragmentation() {
        let frames = vec![
            frame(vec![car(1, 0.0)], vec![car(10, 0.0)]),
            frame(vec![], vec![]),
            frame(vec![car(1, 0.0)], vec![car(10, 0.0)]),
        ];
        let r = clear_mot(&frames, &ClearMotConfig::default()).unwrap();
        assert_eq!((r.fragmentations, r.id_switches, r.mota), (0, 0, Some(1.0)));
        assert_eq!(r.mostly_tracked, 1);
    }

    #[test]
    fn dont_care_region_hides_false_positive() {
        let mut f = frame(vec![car(1, 0.0)], vec![car(10, 0.0), car(11, 30.0)]);
        let r = clear_mot(std::slice::from_ref(&f), &ClearMotConfig::default()).unwrap();
        assert_eq!((r.false_positives, r.ignored_tracks), (1, 0));
        f.dont_care.push(Box3::new(
            Vector3::new(31.0, 0.0, 0.0),
            Vector3::new(6.0, 6.0, 3.0),
            0.0,
        ));
        let r = clear_mot(&[f], &ClearMotConfig::default()).unwrap();
        assert_eq!((r.false_positives, r.ignored_tracks), (0, 1));
        assert_eq!(r.mota, Some(1.0));
    }

    #[test]
    fn per_class_separates_classes() {
        let mut ped_track = car(20, 0.0);
        ped_track.class = ObjectClass::Pedestrian;
        let frames = vec![frame(vec![car(1, 0.0)], vec![ped_track])];
        let agnostic = clear_mot(&frames, &ClearMotConfig::default()).unwrap();
        assert_eq!(agnostic.mota, Some(1.0));
        let per = clear_mot_per_class(&frames, &ClearMotConfig::default()).unwrap();
        let c = &per[&ObjectClass::Car];
        assert_eq!(
            (c.false_negatives, c.false_positives, c.mota),
            (1, 0, Some(0.0))
        );
        let p = &per[&ObjectClass::Pedestrian];
        assert_eq!((p.false_positives, p.gt_count, p.mota), (1, 0, None));
    }

    #[test]
    fn from_box_truth_keeps_id_class_and_yaw() {
        let truth = BoxTruth {
            frame: 3,
            t_s: 0.3,
            id: 7,
            class: ObjectClass::Truck,
            t_world_box: nalgebra::Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::z() * 0.4),
            size_lwh_m: Vector3::new(8.0, 2.5, 3.0),
            velocity_world_mps: Vector3::zeros(),
            parked: false,
        };
        let b = TrackedBox::from_box_truth(&truth);
        assert_eq!((b.id, b.class), (7, ObjectClass::Truck));
        assert!((b.bbox.yaw_rad - 0.4).abs() < 1e-12);
        assert_eq!(b.bbox.size_lwh, truth.size_lwh_m);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let twice = frame(vec![car(1, 0.0), car(1, 5.0)], vec![]);
        assert!(matches!(
            clear_mot(&[twice], &ClearMotConfig::default()),
            Err(EvalError::Invalid { field: "id", .. })
        ));
        let mut nan = car(1, 0.0);
        nan.bbox.yaw_rad = f64::NAN;
        assert!(clear_mot(&[frame(vec![], vec![nan])], &ClearMotConfig::default()).is_err());
        assert!(clear_mot(&[], &ClearMotConfig::with_threshold(0.0)).is_err());
        let empty = clear_mot(&[], &ClearMotConfig::default()).unwrap();
        assert_eq!((empty.mota, empty.motp), (None, None));
    }
}
