//! CLEAR-MOT tracking metrics (Bernardin & Stiefelhagen 2008) on 3D boxes
//! ([`OrientedBox`], BEV or 3D IoU) or image boxes ([`Box2`](super::iou::Box2)), as
//! the KITTI tracking devkit / AB3DMOT 3D evaluation and TrackEval compute
//! them. One matching core serves both geometries through [`MotBox`].
//!
//! Per frame:
//! 1. A ground-truth object keeps the tracker id it was matched to in the
//!    previous frame if that track is present and still overlaps with
//!    IoU ≥ threshold (the CLEAR-MOT rule; TrackEval implements it with a
//!    +1000 score bonus, which is equivalent: these pairs are disjoint, so
//!    all of them are kept). "Previous frame" depends on [`MatchingRule`].
//! 2. The remaining objects and tracks are matched by the Hungarian algorithm,
//!    pairs with IoU < threshold forbidden: maximum number of matches, then
//!    maximum summed IoU (KITTI devkit), or maximum summed IoU only
//!    (TrackEval), see [`MatchingRule`].
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
//! (tracked segments − 1). With [`MatchingRule::MaxMatches`] segments are
//! counted over the frames in which the object appears, as the KITTI devkit
//! walks each trajectory (a frame in which the object is absent from the
//! ground truth does not interrupt it); with [`MatchingRule::TrackEval`] as
//! TrackEval does (absence interrupts, frames without any ground truth or
//! without any track are skipped). MT/PT/ML: objects tracked in > 80 %,
//! 20–80 %, < 20 % of the frames they appear in.
//!
//! The IoU threshold test is `IoU ≥ threshold − ε` (ε = machine epsilon) as in
//! TrackEval, so that a pair computed a rounding error below 0.5 still matches.

use super::EvalError;
use super::assignment::min_cost_assignment;
use super::iou::{AREA_EPS, IouKind, MotBox};
use limot_estimator::geometry::OrientedBox;
use limot_estimator::input::ObjectClass;
use limot_sim::record::BoxTruth;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet, HashMap};

/// The IoU thresholds of the paper's tracking tables.
pub const PAPER_IOU_THRESHOLDS: [f64; 2] = [0.25, 0.5];

/// A box with an identity: a ground-truth object or a tracker output.
/// `B` is [`OrientedBox`] (3D evaluation) or [`Box2`](super::iou::Box2) (image).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackedBox<B = OrientedBox> {
    /// Track or ground-truth id, unique within a frame.
    pub id: u64,
    /// Object class.
    pub class: ObjectClass,
    /// The box.
    pub bbox: B,
}

impl TrackedBox<OrientedBox> {
    /// A simulator ground-truth box (world frame; roll and pitch dropped).
    pub fn from_box_truth(truth: &BoxTruth) -> TrackedBox {
        TrackedBox {
            id: u64::from(truth.id),
            class: truth.class,
            bbox: OrientedBox::from_pose(&truth.t_world_box, truth.size_lwh_m),
        }
    }
}

/// Everything compared in one frame (boxes in one common frame, e.g. world,
/// LiDAR or the image).
#[derive(Debug, Clone, PartialEq)]
pub struct MotFrame<B = OrientedBox> {
    /// Ground-truth boxes of the frame.
    pub gt: Vec<TrackedBox<B>>,
    /// Tracker boxes of the frame.
    pub tracks: Vec<TrackedBox<B>>,
    /// Regions in which unmatched tracker boxes are not counted as false positives.
    pub dont_care: Vec<B>,
}

impl<B> Default for MotFrame<B> {
    fn default() -> Self {
        MotFrame {
            gt: Vec::new(),
            tracks: Vec::new(),
            dont_care: Vec::new(),
        }
    }
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

/// How the per-frame matching treats competing pairs and empty frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MatchingRule {
    /// The largest number of matches, then the largest summed IoU (as the
    /// KITTI devkit's Munkres with a huge cost for forbidden pairs; unlike
    /// the devkit, which matches every frame independently, previous-frame
    /// correspondences are kept first, as CLEAR-MOT prescribes). The previous
    /// frame is the frame just before, whatever it contains.
    #[default]
    MaxMatches,
    /// TrackEval's `CLEAR.eval_sequence`: the largest summed IoU (fewer but
    /// tighter matches can win); frames without any ground truth or without
    /// any track neither break the previous-frame correspondences nor count
    /// for fragmentation, and an object absent from a frame loses them.
    TrackEval,
}

#[derive(Debug, Clone, Copy, PartialEq)]
/// Settings of a CLEAR-MOT evaluation.
pub struct ClearMotConfig {
    /// A pair matches when IoU ≥ this (paper: 0.25 and 0.5).
    pub iou_threshold: f64,
    /// BEV or 3D IoU for [`OrientedBox`]; image boxes ignore it.
    pub iou_kind: IouKind,
    /// When a match counts as an ID switch.
    pub id_switch_rule: IdSwitchRule,
    /// How ground truth and tracks are matched per frame.
    pub matching: MatchingRule,
    /// Unmatched tracks more than this fraction inside a DontCare region are ignored.
    pub dont_care_min_fraction: f64,
}

impl Default for ClearMotConfig {
    fn default() -> Self {
        ClearMotConfig {
            iou_threshold: 0.5,
            iou_kind: IouKind::ThreeD,
            id_switch_rule: IdSwitchRule::LastMatched,
            matching: MatchingRule::MaxMatches,
            dont_care_min_fraction: 0.5,
        }
    }
}

impl ClearMotConfig {
    /// The default settings with another IoU threshold.
    pub fn with_threshold(iou_threshold: f64) -> ClearMotConfig {
        ClearMotConfig {
            iou_threshold,
            ..ClearMotConfig::default()
        }
    }

    /// TrackEval's `CLEAR` metric as its KITTI 2D box benchmark runs it:
    /// image IoU ≥ 0.5, ID switches against the last matched id, TrackEval's
    /// matching. DontCare handling is part of its preprocessing (see
    /// `eval::kitti_mot`), so frames fed with this config carry no regions.
    pub fn trackeval() -> ClearMotConfig {
        ClearMotConfig {
            iou_threshold: 0.5,
            iou_kind: IouKind::ThreeD,
            id_switch_rule: IdSwitchRule::LastMatched,
            matching: MatchingRule::TrackEval,
            dont_care_min_fraction: 0.5,
        }
    }

    /// The matching threshold test (TrackEval's `sim ≥ threshold − eps`).
    fn passes(&self, overlap: f64) -> bool {
        overlap >= self.iou_threshold - AREA_EPS
    }
}

/// One ground-truth ↔ track correspondence in a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameMatch {
    /// Index into the frame's `gt` list.
    pub gt_index: usize,
    /// Index into the frame's `tracks` list.
    pub track_index: usize,
    /// Ground-truth id.
    pub gt_id: u64,
    /// Track id.
    pub track_id: u64,
    /// IoU of the pair.
    pub iou: f64,
}

#[derive(Debug, Clone, PartialEq)]
/// CLEAR-MOT counts and scores of a sequence (or of combined sequences).
pub struct ClearMotResult {
    /// `None` when there is no ground truth.
    pub mota: Option<f64>,
    /// Mean IoU of the matches; `None` without matches.
    pub motp: Option<f64>,
    /// Matched ground-truth boxes (true positives).
    pub matches: usize,
    /// Unmatched tracker boxes.
    pub false_positives: usize,
    /// Unmatched ground-truth boxes.
    pub false_negatives: usize,
    /// Matches whose track differs from the ground truth's previous one.
    pub id_switches: usize,
    /// Times a ground-truth trajectory's tracking was interrupted.
    pub fragmentations: usize,
    /// Ground-truth boxes over all frames.
    pub gt_count: usize,
    /// Tracker boxes over all frames (including ignored ones).
    pub track_count: usize,
    /// Unmatched tracker boxes ignored because they lie in a DontCare region.
    pub ignored_tracks: usize,
    /// Distinct ground-truth objects.
    pub gt_objects: usize,
    /// Objects tracked in at least 80 % of their frames.
    pub mostly_tracked: usize,
    /// Objects that are neither mostly tracked nor mostly lost.
    pub partially_tracked: usize,
    /// Objects tracked in less than 20 % of their frames.
    pub mostly_lost: usize,
    /// Sum of the matches' IoU.
    pub iou_sum: f64,
    /// The matches of every frame, in frame order.
    pub per_frame: Vec<Vec<FrameMatch>>,
}

/// The headline figures of a [`ClearMotResult`], as results files store them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotSummary {
    /// MOTA as a fraction; `None` without ground truth.
    pub mota: Option<f64>,
    /// MOTP (mean IoU of the matches); `None` without matches.
    pub motp: Option<f64>,
    /// ID switches.
    pub id_switches: usize,
    /// False positives.
    pub false_positives: usize,
    /// False negatives.
    pub false_negatives: usize,
    /// Matches.
    pub matches: usize,
    /// Ground-truth boxes evaluated.
    pub gt_count: usize,
}

impl From<&ClearMotResult> for MotSummary {
    fn from(r: &ClearMotResult) -> Self {
        MotSummary {
            mota: r.mota,
            motp: r.motp,
            id_switches: r.id_switches,
            false_positives: r.false_positives,
            false_negatives: r.false_negatives,
            matches: r.matches,
            gt_count: r.gt_count,
        }
    }
}

impl MotSummary {
    /// Counts summed over sequences, MOTA and MOTP recomputed from them (as
    /// the devkit and TrackEval combine sequences).
    pub fn combine<'a>(parts: impl IntoIterator<Item = &'a MotSummary>) -> MotSummary {
        let mut total = MotSummary {
            mota: None,
            motp: None,
            id_switches: 0,
            false_positives: 0,
            false_negatives: 0,
            matches: 0,
            gt_count: 0,
        };
        let mut iou_sum = 0.0;
        for p in parts {
            total.id_switches += p.id_switches;
            total.false_positives += p.false_positives;
            total.false_negatives += p.false_negatives;
            total.matches += p.matches;
            total.gt_count += p.gt_count;
            iou_sum += p.motp.unwrap_or(0.0) * p.matches as f64;
        }
        let errors = total.false_negatives + total.false_positives + total.id_switches;
        total.mota = (total.gt_count > 0).then(|| 1.0 - errors as f64 / total.gt_count as f64);
        total.motp = (total.matches > 0).then(|| iou_sum / total.matches as f64);
        total
    }
}

fn validate_frame<B: MotBox>(index: usize, frame: &MotFrame<B>) -> Result<(), EvalError> {
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
fn match_frame<B: MotBox>(
    frame: &MotFrame<B>,
    cfg: &ClearMotConfig,
    prev_frame_match: &HashMap<u64, u64>,
) -> Result<Vec<FrameMatch>, EvalError> {
    let (n_gt, n_tr) = (frame.gt.len(), frame.tracks.len());
    let mut ious = vec![0.0; n_gt * n_tr];
    for (i, g) in frame.gt.iter().enumerate() {
        for (j, t) in frame.tracks.iter().enumerate() {
            ious[i * n_tr + j] = g.bbox.overlap(&t.bbox, cfg.iou_kind);
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
            && cfg.passes(ious[i * n_tr + j])
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
            cost.push(match (cfg.matching, cfg.passes(o)) {
                // Forbidden pairs: the assignment maximises their complement first.
                (MatchingRule::MaxMatches, true) => 1.0 - o,
                (MatchingRule::MaxMatches, false) => f64::INFINITY,
                // Pure maximum IoU sum (scipy's linear_sum_assignment on −score
                // with failing pairs zeroed); zero pairs are dropped below.
                (MatchingRule::TrackEval, true) => -o,
                (MatchingRule::TrackEval, false) => 0.0,
            });
        }
    }
    let assignment = min_cost_assignment(free_gt.len(), free_tr.len(), &cost)?;
    for (r, c) in assignment.pairs {
        let (i, j) = (free_gt[r], free_tr[c]);
        if cfg.passes(ious[i * n_tr + j]) {
            matches.push((i, j));
        }
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
///
/// # Errors
///
/// [`EvalError`] for an invalid configuration or non-finite boxes.
///
/// # Examples
///
/// One car, tracked exactly in frame 0 and missed in frame 1, where the
/// tracker reports a box far away instead: 1 match, 1 miss, 1 false positive,
/// so MOTA = 1 − (1 + 1) / 2 = 0 and MOTP = 1.
///
/// ```
/// use limot::metrics::{ClearMotConfig, MotFrame, TrackedBox, clear_mot};
/// use limot_estimator::geometry::OrientedBox;
/// use limot_estimator::input::ObjectClass;
/// use nalgebra::Vector3;
///
/// let car = |x: f64, id: u64| TrackedBox {
///     id,
///     class: ObjectClass::Car,
///     bbox: OrientedBox::new(Vector3::new(x, 0.0, 0.0), Vector3::new(4.0, 2.0, 1.5), 0.0),
/// };
/// let frames = [
///     MotFrame { gt: vec![car(10.0, 1)], tracks: vec![car(10.0, 7)], dont_care: vec![] },
///     MotFrame { gt: vec![car(11.0, 1)], tracks: vec![car(40.0, 8)], dont_care: vec![] },
/// ];
/// let r = clear_mot(&frames, &ClearMotConfig::default())?;
/// assert_eq!((r.matches, r.false_negatives, r.false_positives), (1, 1, 1));
/// assert_eq!(r.mota, Some(0.0));
/// assert_eq!(r.motp, Some(1.0));
/// # Ok::<(), limot::metrics::EvalError>(())
/// ```
pub fn clear_mot<B: MotBox>(
    frames: &[MotFrame<B>],
    cfg: &ClearMotConfig,
) -> Result<ClearMotResult, EvalError> {
    validate_config(cfg)?;
    for (i, f) in frames.iter().enumerate() {
        validate_frame(i, f)?;
    }
    let mut history: BTreeMap<u64, GtHistory> = BTreeMap::new();
    let mut prev_frame_match: HashMap<u64, u64> = HashMap::new();
    let mut r = combine_sequences(&[]);
    r.per_frame.reserve(frames.len());
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
                .any(|d| t.bbox.fraction_inside(d) > cfg.dont_care_min_fraction);
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
                // A new tracked segment starts unless tracked just before.
                let tracked_before = match cfg.matching {
                    MatchingRule::MaxMatches => h.previous_appearance.is_some(),
                    MatchingRule::TrackEval => prev_frame_match.contains_key(&g.id),
                };
                if !tracked_before {
                    h.segments += 1;
                }
                h.last_matched = Some(tid);
            }
            h.previous_appearance = now;
        }
        // TrackEval skips frames without ground truth or without tracks when
        // it carries correspondences forward.
        let skip = cfg.matching == MatchingRule::TrackEval
            && (frame.gt.is_empty() || frame.tracks.is_empty());
        if !skip {
            prev_frame_match = matched_track;
        }
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
    r.finish_ratios();
    Ok(r)
}

impl ClearMotResult {
    /// Sets MOTA and MOTP from the counts.
    fn finish_ratios(&mut self) {
        self.mota = (self.gt_count > 0).then(|| {
            let errors = (self.false_negatives + self.false_positives + self.id_switches) as f64;
            1.0 - errors / self.gt_count as f64
        });
        self.motp = (self.matches > 0).then(|| self.iou_sum / self.matches as f64);
    }
}

/// Combines the results of independent sequences as the KITTI devkit and
/// TrackEval do: counts (and the IoU sum) add up, MOTA and MOTP are
/// recomputed from the sums; `per_frame` is the concatenation.
pub fn combine_sequences(results: &[ClearMotResult]) -> ClearMotResult {
    let mut total = ClearMotResult {
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
        per_frame: Vec::new(),
    };
    for r in results {
        total.matches += r.matches;
        total.false_positives += r.false_positives;
        total.false_negatives += r.false_negatives;
        total.id_switches += r.id_switches;
        total.fragmentations += r.fragmentations;
        total.gt_count += r.gt_count;
        total.track_count += r.track_count;
        total.ignored_tracks += r.ignored_tracks;
        total.gt_objects += r.gt_objects;
        total.mostly_tracked += r.mostly_tracked;
        total.partially_tracked += r.partially_tracked;
        total.mostly_lost += r.mostly_lost;
        total.iou_sum += r.iou_sum;
        total.per_frame.extend(r.per_frame.iter().cloned());
    }
    total.finish_ratios();
    total
}

/// CLEAR-MOT for every class that occurs in the ground truth or the tracks:
/// boxes of other classes are dropped, DontCare regions apply to all classes.
///
/// # Errors
///
/// As [`clear_mot`].
pub fn clear_mot_per_class<B: MotBox>(
    frames: &[MotFrame<B>],
    cfg: &ClearMotConfig,
) -> Result<BTreeMap<ObjectClass, ClearMotResult>, EvalError> {
    let classes: BTreeSet<ObjectClass> = frames
        .iter()
        .flat_map(|f| f.gt.iter().chain(&f.tracks).map(|b| b.class))
        .collect();
    let mut out = BTreeMap::new();
    for class in classes {
        let filtered: Vec<MotFrame<B>> = frames
            .iter()
            .map(|f| MotFrame::<B> {
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
            bbox: OrientedBox::new(Vector3::new(x, 0.0, 1.0), Vector3::new(4.0, 2.0, 2.0), 0.0),
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
        f.dont_care.push(OrientedBox::new(
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
            labelled: true,
            annotated: false,
        };
        let b = TrackedBox::from_box_truth(&truth);
        assert_eq!((b.id, b.class), (7, ObjectClass::Truck));
        assert!((b.bbox.yaw_rad - 0.4).abs() < 1e-12);
        assert_eq!(b.bbox.size_lwh, truth.size_lwh_m);
    }

    fn img(id: u64, left: f64) -> TrackedBox<crate::metrics::iou::Box2> {
        TrackedBox {
            id,
            class: ObjectClass::Car,
            bbox: crate::metrics::iou::Box2::from_ltrb([left, 0.0, left + 10.0, 10.0]),
        }
    }

    #[test]
    fn trackeval_rule_maximises_iou_sum_not_match_count() {
        // Boxes 10 px wide; a 3 px shift gives IoU 7/13 ≥ 0.5, 6 px fails.
        // Three matches of 7/13 are possible (g3-t1, g1-t2, g2-t3), but two
        // exact matches (g1-t1, g2-t2) sum to more.
        let f = MotFrame {
            gt: vec![img(3, 0.0), img(1, 3.0), img(2, 6.0)],
            tracks: vec![img(11, 3.0), img(12, 6.0), img(13, 9.0)],
            dont_care: vec![],
        };
        let frames = std::slice::from_ref(&f);
        let devkit = clear_mot(frames, &ClearMotConfig::default()).unwrap();
        assert_eq!(devkit.matches, 3);
        assert!((devkit.motp.unwrap() - 7.0 / 13.0).abs() < 1e-12);
        let te = clear_mot(frames, &ClearMotConfig::trackeval()).unwrap();
        assert_eq!(
            (te.matches, te.false_negatives, te.false_positives),
            (2, 1, 1)
        );
        assert_eq!(te.motp, Some(1.0));
    }

    #[test]
    fn trackeval_rule_carries_correspondence_over_empty_frames() {
        // Frame 1 has no tracks. In frame 2, track 10 still overlaps (IoU 7/13)
        // but 11 fits exactly.
        let frames = vec![
            frame(vec![car(1, 0.0)], vec![car(10, 0.0)]),
            frame(vec![car(1, 0.0)], vec![]),
            frame(vec![car(1, 0.0)], vec![car(10, 1.0), car(11, 0.0)]),
        ];
        let te = clear_mot(&frames, &ClearMotConfig::trackeval()).unwrap();
        assert_eq!(te.per_frame[2][0].track_id, 10);
        assert_eq!((te.id_switches, te.fragmentations), (0, 0));
        let devkit = clear_mot(&frames, &ClearMotConfig::default()).unwrap();
        assert_eq!(devkit.per_frame[2][0].track_id, 11);
        assert_eq!((devkit.id_switches, devkit.fragmentations), (1, 1));
        // Absence from the ground truth interrupts a TrackEval segment only.
        let gap = vec![
            frame(
                vec![car(1, 0.0), car(2, 20.0)],
                vec![car(10, 0.0), car(20, 20.0)],
            ),
            frame(vec![car(2, 20.0)], vec![car(20, 20.0)]),
            frame(
                vec![car(1, 0.0), car(2, 20.0)],
                vec![car(10, 0.0), car(20, 20.0)],
            ),
        ];
        let te = clear_mot(&gap, &ClearMotConfig::trackeval()).unwrap();
        assert_eq!((te.fragmentations, te.id_switches), (1, 0));
        let devkit = clear_mot(&gap, &ClearMotConfig::default()).unwrap();
        assert_eq!(devkit.fragmentations, 0);
    }

    #[test]
    fn combine_sequences_sums_counts() {
        let a = clear_mot(&hand_sequence(), &ClearMotConfig::default()).unwrap();
        let both = combine_sequences(&[a.clone(), a.clone()]);
        assert_eq!(both.gt_count, 2 * a.gt_count);
        assert_eq!(both.id_switches, 2 * a.id_switches);
        assert_eq!(both.mota, a.mota);
        assert!((both.motp.unwrap() - a.motp.unwrap()).abs() < 1e-15);
        assert_eq!(both.per_frame.len(), 6);
        assert_eq!(combine_sequences(&[]).mota, None);
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
        assert!(clear_mot::<OrientedBox>(&[], &ClearMotConfig::with_threshold(0.0)).is_err());
        let empty = clear_mot::<OrientedBox>(&[], &ClearMotConfig::default()).unwrap();
        assert_eq!((empty.mota, empty.motp), (None, None));
    }
}
