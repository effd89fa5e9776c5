//! AB3DMOT's 3D multi-object tracking evaluation (Weng et al., "AB3DMOT: A
//! Baseline for 3D Multi-Object Tracking and New Evaluation Metrics", 2020;
//! `scripts/KITTI/evaluate.py` of xinshuoweng/AB3DMOT): CLEAR-MOT on 3D IoU
//! at one track-score threshold, and its averages over recall, sAMOTA, AMOTA
//! and AMOTP.
//!
//! Replicated from evaluate.py, for one class (Car with its neighbour Van, or
//! Pedestrian with Person_sitting) over all sequences together:
//! - Loading: ground-truth and result rows of the class or its neighbour with
//!   track id ≥ 0; ground-truth `DontCare` rows are ignore regions. A result
//!   without a score scores −1.
//! - Track score: every result row of a track carries the track's mean score
//!   over the sequence; a threshold drops whole tracks whose mean is below it.
//! - Per frame: Hungarian assignment of ground truth to results on `1 − IoU3D`
//!   with pairs above `1 − iou_threshold` forbidden (the most pairs, then the
//!   least cost). A result box that was never matched is ignored when it is a
//!   neighbour-class box, at most 25 px high in the image, or more than half
//!   inside one DontCare region. Ground truth of the neighbour class, with
//!   occlusion > 2 or (integer) truncation > 0 is ignored, matched or not;
//!   a matched one still counts as a true positive for MOTP, recall and the
//!   recall samples, as in evaluate.py.
//! - ID switches along each ground-truth trajectory: a match whose track id
//!   differs from the last matched one while the previous frame of the
//!   trajectory was matched; ignored frames reset the last id.
//! - Recall sampling (`getThresholds`): the true positives' track scores of
//!   the unthresholded evaluation, sorted, give one threshold per recall step
//!   of 1/40; sMOTA(r) = clamp(1 − (FN + FP + IDS − (1 − r)·n_gt)/(r·n_gt), 0, 1).
//!   sAMOTA, AMOTA and AMOTP are the sums over the sampled thresholds divided
//!   by 40 (missing high-recall samples count 0). The reported MOTA/MOTP are
//!   those at the threshold with the best MOTA.
//!
//! evaluate.py keeps two pieces of state across its threshold runs, which we
//! reproduce for identical figures: a result box once matched is never
//! ignored again, and the mean scores are re-averaged from the previous run's
//! means. Boxes are compared in the rectified camera frame (x right, z
//! forward, up = −y), as AB3DMOT does; the IoU is [`iou_3d`].

use super::EvalError;
use super::assignment::min_cost_assignment;
use super::iou::{Box2, image_fraction_inside, iou_3d, validate_box};
use super::kitti_mot::KittiEvalClass;
use crate::io::kitti::labels::{CameraBox, TrackingLabel};
use limot_estimator::geometry::OrientedBox;
use nalgebra::Vector3;
use std::collections::{BTreeMap, HashMap};

/// Parameters of the evaluation (evaluate.py's values are the [`Default`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ab3dmotEvalConfig {
    /// Minimum 3D IoU of a match (0.25 for AB3DMOT's 3D evaluation).
    pub iou_threshold: f64,
    /// Ground truth above this truncation level (read as an integer) is ignored.
    pub max_truncation: i64,
    /// Ground truth above this occlusion level is ignored.
    pub max_occlusion: i64,
    /// Unmatched result boxes at most this high in the image are ignored.
    pub min_height_px: f64,
    /// Recall samples: 1/(n − 1) apart, the first one (recall 0) dropped.
    pub num_sample_points: usize,
}

impl Default for Ab3dmotEvalConfig {
    fn default() -> Self {
        Ab3dmotEvalConfig {
            iou_threshold: 0.25,
            max_truncation: 0,
            max_occlusion: 2,
            min_height_px: 25.0,
            num_sample_points: 41,
        }
    }
}

/// One sequence's ground truth and results (KITTI tracking rows, camera frame).
#[derive(Debug, Clone, Copy)]
pub struct Ab3dmotSequence<'a> {
    /// Ground-truth rows.
    pub gt: &'a [TrackingLabel],
    /// Result rows (their score column gates tracks).
    pub results: &'a [TrackingLabel],
    /// Frames evaluated: `0..num_frames` (extended to the last ground-truth frame).
    pub num_frames: u32,
}

/// CLEAR-MOT counts at one score threshold, as evaluate.py counts them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ab3dmotCounts {
    /// Tracks whose mean score is below this were dropped.
    pub score_threshold: f64,
    /// The recall this threshold samples (1 for a plain evaluation).
    pub recall_sample: f64,
    /// Matches, including those to ignored ground truth.
    pub true_positives: u64,
    /// Tracker boxes not matched.
    pub false_positives: u64,
    /// Evaluated ground truth not matched.
    pub false_negatives: u64,
    /// ID switches.
    pub id_switches: u64,
    /// Ground truth evaluated (ignored boxes excluded).
    pub gt_count: u64,
    /// Sum of the matches' 3D IoU.
    pub iou_sum: f64,
    /// `None` without evaluated ground truth.
    pub mota: Option<f64>,
    /// sMOTA at `recall_sample`.
    pub smota: Option<f64>,
    /// Mean 3D IoU of the matches; 0 without matches (evaluate.py's value).
    pub motp: f64,
    /// TP / (TP + FN).
    pub recall: f64,
    /// TP / (TP + FP).
    pub precision: f64,
}

/// The full evaluation: the recall curve, its averages and the best-MOTA row.
#[derive(Debug, Clone, PartialEq)]
pub struct Ab3dmotResult {
    /// The evaluation without a threshold (every track kept).
    pub all_tracks: Ab3dmotCounts,
    /// One row per sampled recall, in increasing recall.
    pub curve: Vec<Ab3dmotCounts>,
    /// The row at the threshold with the highest MOTA (evaluated with recall 1).
    pub best: Ab3dmotCounts,
    /// Scaled AMOTA: mean sMOTA over the sampled recalls.
    pub samota: f64,
    /// Mean MOTA over the sampled recalls.
    pub amota: f64,
    /// Mean MOTP over the sampled recalls.
    pub amotp: f64,
}

/// An AB3DMOT camera-frame box as a z-up [`OrientedBox`]: x right, y forward (camera
/// z), z up (camera −y); yaw = −rotation_y.
pub fn camera_box3(cam: &CameraBox) -> OrientedBox {
    let [h, w, l] = [cam.dims_hwl.x, cam.dims_hwl.y, cam.dims_hwl.z];
    let c = cam.bottom_center_rect;
    OrientedBox::new(
        Vector3::new(c.x, c.z, -c.y + 0.5 * h),
        Vector3::new(l, w, h),
        -cam.rotation_y_rad,
    )
}

struct GtBox {
    track_id: i64,
    box3: OrientedBox,
    /// Neighbour class, too occluded or truncated.
    hard: bool,
}

struct ResultBox {
    frame: usize,
    track_id: i64,
    neighbour: bool,
    box2: Box2,
    box3: OrientedBox,
    score: f64,
    /// Matched in any evaluation so far (evaluate.py's `valid` flag).
    valid: bool,
}

struct SequenceData {
    gt: Vec<Vec<GtBox>>,
    dont_care: Vec<Vec<Box2>>,
    /// In frame order, file order within a frame.
    results: Vec<ResultBox>,
    results_by_frame: Vec<Vec<usize>>,
}

/// What one evaluation run returns besides its counts.
struct Run {
    counts: Ab3dmotCounts,
    /// Track scores of the matches, in match order.
    tp_scores: Vec<f64>,
}

/// Evaluates results of several sequences together, exactly as AB3DMOT's
/// evaluate.py does (see the module docs). Errors on a non-finite box or a
/// track id used twice in one frame of the results.
///
/// # Errors
///
/// [`EvalError`] for invalid labels, boxes or configuration.
///
/// # Examples
///
/// One car tracked exactly over two frames: MOTA and MOTP at the best
/// threshold are 1; with a single object only the recall-1 sample of the 40
/// is reached, so sAMOTA, AMOTA and AMOTP are 1/40.
///
/// ```
/// use limot::io::kitti::labels::parse_labels;
/// use limot::metrics::{Ab3dmotEvalConfig, Ab3dmotSequence, KittiEvalClass, ab3dmot_evaluate};
/// use std::path::Path;
///
/// let car = "Car 0 0 0 500 150 600 250 1.5 1.6 4.0 1.0 1.7 20.0 -1.57";
/// let gt = parse_labels(&format!("0 0 {car}\n1 0 {car}\n"), Path::new("gt.txt"))?;
/// let results = parse_labels(&format!("0 7 {car} 0.9\n1 7 {car} 0.9\n"), Path::new("r.txt"))?;
/// let sequence = Ab3dmotSequence { gt: &gt, results: &results, num_frames: 2 };
/// let r = ab3dmot_evaluate(&[sequence], KittiEvalClass::Car, &Ab3dmotEvalConfig::default())?;
/// assert_eq!(r.best.mota, Some(1.0));
/// assert_eq!(r.best.motp, 1.0);
/// assert!((r.samota - 1.0 / 40.0).abs() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn ab3dmot_evaluate(
    sequences: &[Ab3dmotSequence<'_>],
    class: KittiEvalClass,
    cfg: &Ab3dmotEvalConfig,
) -> Result<Ab3dmotResult, EvalError> {
    if !(cfg.iou_threshold > 0.0 && cfg.iou_threshold <= 1.0) {
        return Err(EvalError::BadParameter {
            what: "ab3dmot evaluation",
            why: format!("iou_threshold {} not in (0, 1]", cfg.iou_threshold),
        });
    }
    if cfg.num_sample_points < 2 {
        return Err(EvalError::BadParameter {
            what: "ab3dmot evaluation",
            why: "num_sample_points must be at least 2".into(),
        });
    }
    let mut data = sequences
        .iter()
        .map(|s| load_sequence(s, class, cfg))
        .collect::<Result<Vec<_>, _>>()?;

    let first = run(&mut data, cfg, f64::NEG_INFINITY, 1.0)?;
    let num_gt = first.counts.true_positives + first.counts.false_negatives;
    let samples = recall_samples(&first.tp_scores, num_gt, cfg.num_sample_points);
    let mut curve = Vec::with_capacity(samples.len());
    let (mut best_mota, mut best_threshold) = (0.0, f64::NEG_INFINITY);
    for (threshold, recall) in samples {
        let counts = run(&mut data, cfg, threshold, recall)?.counts;
        if let Some(mota) = counts.mota
            && mota > best_mota
        {
            best_mota = mota;
            best_threshold = threshold;
        }
        curve.push(counts);
    }
    let best = run(&mut data, cfg, best_threshold, 1.0)?.counts;
    let steps = (cfg.num_sample_points - 1) as f64;
    let sum = |f: fn(&Ab3dmotCounts) -> f64| curve.iter().map(f).sum::<f64>() / steps;
    Ok(Ab3dmotResult {
        all_tracks: first.counts,
        samota: sum(|c| c.smota.unwrap_or(0.0)),
        amota: sum(|c| c.mota.unwrap_or(0.0)),
        amotp: sum(|c| c.motp),
        curve,
        best,
    })
}

fn load_sequence(
    seq: &Ab3dmotSequence<'_>,
    class: KittiEvalClass,
    cfg: &Ab3dmotEvalConfig,
) -> Result<SequenceData, EvalError> {
    let wanted = |l: &TrackingLabel| class.is_class(&l.type_name) || neighbour(class, l);
    let last_gt = seq.gt.iter().map(|l| l.frame + 1).max().unwrap_or(0);
    let frames = seq.num_frames.max(last_gt) as usize;
    let mut gt: Vec<Vec<GtBox>> = (0..frames).map(|_| Vec::new()).collect();
    let mut dont_care: Vec<Vec<Box2>> = (0..frames).map(|_| Vec::new()).collect();
    for (index, l) in seq.gt.iter().enumerate() {
        let f = l.frame as usize;
        if l.is_dont_care() {
            dont_care[f].push(Box2::from_ltrb(l.bbox_2d));
        } else if wanted(l) && l.track_id >= 0 {
            let box3 = checked_box3("kitti ground-truth label", index, &l.cam_box)?;
            gt[f].push(GtBox {
                track_id: l.track_id,
                box3,
                hard: neighbour(class, l)
                    || l.occluded > cfg.max_occlusion
                    || (l.truncated as i64) > cfg.max_truncation,
            });
        }
    }
    let mut results = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for (index, l) in seq.results.iter().enumerate() {
        if !wanted(l) || l.track_id < 0 {
            continue;
        }
        let what = "kitti result label";
        if !seen.insert((l.frame, l.track_id)) {
            return Err(EvalError::Invalid {
                what,
                index,
                field: "track_id",
                why: format!("track {} twice in frame {}", l.track_id, l.frame),
            });
        }
        let box2 = Box2::from_ltrb(l.bbox_2d);
        box2.validate().map_err(|(field, why)| EvalError::Invalid {
            what,
            index,
            field,
            why,
        })?;
        results.push(ResultBox {
            frame: l.frame as usize,
            track_id: l.track_id,
            neighbour: neighbour(class, l),
            box2,
            box3: checked_box3(what, index, &l.cam_box)?,
            score: l.score.unwrap_or(-1.0),
            valid: false,
        });
    }
    results.sort_by_key(|r| r.frame);
    let mut results_by_frame: Vec<Vec<usize>> = (0..frames).map(|_| Vec::new()).collect();
    for (i, r) in results.iter().enumerate() {
        if r.frame < frames {
            results_by_frame[r.frame].push(i);
        }
    }
    Ok(SequenceData {
        gt,
        dont_care,
        results,
        results_by_frame,
    })
}

fn neighbour(class: KittiEvalClass, l: &TrackingLabel) -> bool {
    let lower = l.type_name.to_ascii_lowercase();
    match class {
        KittiEvalClass::Car => lower == "van",
        KittiEvalClass::Pedestrian => lower == "person_sitting",
    }
}

fn checked_box3(
    what: &'static str,
    index: usize,
    cam: &CameraBox,
) -> Result<OrientedBox, EvalError> {
    let b = camera_box3(cam);
    validate_box(&b).map_err(|(field, why)| EvalError::Invalid {
        what,
        index,
        field,
        why,
    })?;
    Ok(b)
}

/// evaluate.py's `getThresholds`: (threshold, recall) per recall step, the
/// recall-0 sample dropped.
fn recall_samples(tp_scores: &[f64], num_gt: u64, num_sample_points: usize) -> Vec<(f64, f64)> {
    let mut scores = tp_scores.to_vec();
    scores.sort_by(|a, b| b.total_cmp(a));
    let n = scores.len();
    let step = 1.0 / (num_sample_points as f64 - 1.0);
    let mut current = 0.0;
    let mut out = Vec::new();
    for (i, &score) in scores.iter().enumerate() {
        let left = (i + 1) as f64 / num_gt as f64;
        let right = if i + 1 < n {
            (i + 2) as f64 / num_gt as f64
        } else {
            left
        };
        if (right - current) < (current - left) && i + 1 < n {
            continue;
        }
        out.push((score, current));
        current += step;
    }
    out.into_iter().skip(1).collect()
}

/// One evaluate.py `compute3rdPartyMetrics(threshold, recall)` call.
fn run(
    data: &mut [SequenceData],
    cfg: &Ab3dmotEvalConfig,
    threshold: f64,
    recall_sample: f64,
) -> Result<Run, EvalError> {
    let (mut tp, mut fp, mut fn_, mut n_gt) = (0u64, 0u64, 0u64, 0i64);
    let mut iou_sum = 0.0;
    let mut tp_scores = Vec::new();
    let mut id_switches = 0u64;
    let max_cost = 1.0 - cfg.iou_threshold;
    for seq in data.iter_mut() {
        // Every box carries its track's mean score (re-averaged each run).
        let mut per_track: BTreeMap<i64, (f64, usize)> = BTreeMap::new();
        for r in &seq.results {
            let e = per_track.entry(r.track_id).or_insert((0.0, 0));
            e.0 += r.score;
            e.1 += 1;
        }
        let mean: HashMap<i64, f64> = per_track
            .iter()
            .map(|(&id, &(sum, n))| (id, sum / n as f64))
            .collect();
        for r in seq.results.iter_mut() {
            r.score = mean[&r.track_id];
        }
        // Per ground-truth id: matched track id (-1 none) and ignored, per frame present.
        let mut trajectories: BTreeMap<i64, Vec<(i64, bool)>> = BTreeMap::new();
        for (f, gts) in seq.gt.iter().enumerate() {
            let kept: Vec<usize> = seq.results_by_frame[f]
                .iter()
                .copied()
                .filter(|&i| seq.results[i].score >= threshold)
                .collect();
            n_gt += gts.len() as i64;
            let mut cost = Vec::with_capacity(gts.len() * kept.len());
            for g in gts {
                for &i in &kept {
                    let c = 1.0 - iou_3d(&g.box3, &seq.results[i].box3);
                    cost.push(if c <= max_cost { c } else { f64::INFINITY });
                }
            }
            let assignment = min_cost_assignment(gts.len(), kept.len(), &cost)?;
            let mut matched_to: Vec<Option<usize>> = vec![None; gts.len()];
            for &(row, col) in &assignment.pairs {
                let c = cost[row * kept.len() + col];
                let r = &mut seq.results[kept[col]];
                r.valid = true;
                matched_to[row] = Some(kept[col]);
                tp += 1;
                iou_sum += 1.0 - c;
                tp_scores.push(r.score);
            }
            // Unmatched result boxes that are ignored.
            let mut ignored_results = 0i64;
            let mut ignored_ids = std::collections::HashSet::new();
            for &i in &kept {
                let r = &seq.results[i];
                if r.valid {
                    continue;
                }
                let ignored = r.neighbour
                    || r.box2.height_px().abs() <= cfg.min_height_px
                    || seq.dont_care[f]
                        .iter()
                        .any(|d| image_fraction_inside(&r.box2, d) > 0.5);
                if ignored {
                    ignored_results += 1;
                    ignored_ids.insert(r.track_id);
                }
            }
            let (mut ignored_fn, mut ignored_tp, mut ignored_pairs) = (0i64, 0i64, 0i64);
            for (g, m) in gts.iter().zip(&matched_to) {
                let track = m.map_or(-1, |i| seq.results[i].track_id);
                trajectories
                    .entry(g.track_id)
                    .or_default()
                    .push((track, g.hard));
                if !g.hard {
                    continue;
                }
                match m {
                    None => ignored_fn += 1,
                    Some(_) => {
                        ignored_tp += 1;
                        if ignored_ids.contains(&track) {
                            ignored_pairs += 1;
                        }
                    }
                }
            }
            let matched = assignment.pairs.len() as i64;
            let frame_tp = matched - ignored_tp;
            n_gt -= ignored_fn + ignored_tp;
            fn_ += (gts.len() as i64 - matched - ignored_fn) as u64;
            fp += (kept.len() as i64 - frame_tp - ignored_results - ignored_tp + ignored_pairs)
                as u64;
        }
        id_switches += trajectories
            .values()
            .map(|t| trajectory_id_switches(t))
            .sum::<u64>();
    }
    let n_gt = n_gt.max(0) as u64;
    let errors = (fn_ + fp + id_switches) as f64;
    let (mota, smota) = if n_gt == 0 {
        (None, None)
    } else {
        let n = n_gt as f64;
        let smota = 1.0 - (errors - (1.0 - recall_sample) * n) / (recall_sample * n);
        (Some(1.0 - errors / n), Some(smota.clamp(0.0, 1.0)))
    };
    let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    let (recall, precision) = if tp + fp == 0 || tp + fn_ == 0 {
        (0.0, 0.0)
    } else {
        (ratio(tp, tp + fn_), ratio(tp, tp + fp))
    };
    Ok(Run {
        counts: Ab3dmotCounts {
            score_threshold: threshold,
            recall_sample,
            true_positives: tp,
            false_positives: fp,
            false_negatives: fn_,
            id_switches,
            gt_count: n_gt,
            iou_sum,
            mota,
            smota,
            motp: if tp == 0 { 0.0 } else { iou_sum / tp as f64 },
            recall,
            precision,
        },
        tp_scores,
    })
}

/// ID switches of one ground-truth trajectory (matched track id or −1, and
/// whether the frame is ignored), evaluate.py's rule.
fn trajectory_id_switches(trajectory: &[(i64, bool)]) -> u64 {
    if trajectory.iter().all(|&(_, ignored)| ignored) || trajectory.iter().all(|&(id, _)| id == -1)
    {
        return 0;
    }
    let mut switches = 0;
    let mut last_id = trajectory[0].0;
    for f in 1..trajectory.len() {
        let (id, ignored) = trajectory[f];
        if ignored {
            last_id = -1;
            continue;
        }
        if last_id != id && last_id != -1 && id != -1 && trajectory[f - 1].0 != -1 {
            switches += 1;
        }
        if id != -1 {
            last_id = id;
        }
    }
    switches
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::kitti::labels::parse_labels;
    use std::path::Path;

    fn parse(text: &str) -> Vec<TrackingLabel> {
        parse_labels(text, Path::new("t.txt")).unwrap()
    }

    /// A car row: frame, id, x offset (m), z (m), optional score.
    fn car(frame: u32, id: i64, x: f64, z: f64, score: Option<f64>) -> String {
        let s = score.map_or(String::new(), |s| format!(" {s}"));
        format!("{frame} {id} Car 0 0 0 500 150 600 250 1.5 1.6 4.0 {x} 1.7 {z} -1.57{s}\n")
    }

    #[test]
    fn camera_box_matches_the_camera_geometry() {
        let cam = parse(&car(0, 0, 1.0, 20.0, None))[0].cam_box;
        let b = camera_box3(&cam);
        // Bottom at camera y = 1.7 (z_up = −1.7), 1.5 m high.
        assert!((b.center - Vector3::new(1.0, 20.0, -1.7 + 0.75)).norm() < 1e-12);
        // ry = −90°: the car's length along the camera z axis (forward).
        let corners = b.bev_corners();
        let span_y = corners.iter().map(|c| c.y).fold(f64::MIN, f64::max)
            - corners.iter().map(|c| c.y).fold(f64::MAX, f64::min);
        assert!((span_y - 4.0).abs() < 1e-2, "{span_y}");
    }

    #[test]
    fn thresholds_follow_get_thresholds() {
        // 4 matches of 8 ground truth: recalls 1/8 .. 4/8, samples every 1/4.
        let s = recall_samples(&[0.9, 0.8, 0.7, 0.6], 8, 5);
        // Recall 0 is dropped; 3/8 is skipped for 1/2, the last score always taken.
        assert_eq!(s, vec![(0.8, 0.25), (0.6, 0.5)]);
        let all = recall_samples(&[1.0, 0.5], 2, 3);
        assert_eq!(all, vec![(0.5, 0.5)]);
    }

    #[test]
    fn counts_and_id_switches_on_a_hand_case() {
        // One car for 4 frames; track 1 then track 2 (a switch); a van gt
        // matched by track 3 (ignored TP); a false track 4 far away.
        let mut gt = String::new();
        let mut res = String::new();
        for f in 0..4 {
            gt += &car(f, 0, 1.0, 20.0, None);
            gt += &format!("{f} 1 Van 0 0 0 100 150 200 250 2.0 1.8 4.5 -6.0 1.8 20.0 -1.57\n");
            res += &car(f, if f < 2 { 1 } else { 2 }, 1.0, 20.3, Some(0.9));
            res +=
                &format!("{f} 3 Car 0 0 0 100 150 200 250 2.0 1.8 4.5 -6.0 1.8 20.0 -1.57 0.5\n");
        }
        res += &car(0, 4, 10.0, 40.0, Some(0.2));
        let (gt, res) = (parse(&gt), parse(&res));
        let seq = Ab3dmotSequence {
            gt: &gt,
            results: &res,
            num_frames: 4,
        };
        let r =
            ab3dmot_evaluate(&[seq], KittiEvalClass::Car, &Ab3dmotEvalConfig::default()).unwrap();
        let a = r.all_tracks;
        assert_eq!(a.true_positives, 8, "car and van matches");
        assert_eq!(a.gt_count, 4, "the van is ignored");
        assert_eq!(
            (a.false_positives, a.false_negatives, a.id_switches),
            (1, 0, 1)
        );
        assert!((a.mota.unwrap() - (1.0 - 2.0 / 4.0)).abs() < 1e-12);
        // IoU of a 0.3 m shift along a 4 m box: 3.7 / 4.3.
        let expected_motp = (4.0 * 3.7 / 4.3 + 4.0) / 8.0;
        assert!((a.motp - expected_motp).abs() < 1e-3, "{}", a.motp);
        // The best threshold drops the false track 4 (mean score 0.2).
        assert_eq!(r.best.false_positives, 0);
        assert!(r.best.score_threshold > 0.2);
        assert!((r.best.mota.unwrap() - 0.75).abs() < 1e-12);
        assert!(r.samota > 0.0 && r.samota <= 1.0);
    }

    #[test]
    fn ignored_frames_reset_the_last_id() {
        let t = [(1, false), (-1, true), (2, false)];
        assert_eq!(trajectory_id_switches(&t), 0);
        let t = [(1, false), (2, false), (-1, false), (3, false)];
        assert_eq!(trajectory_id_switches(&t), 1);
    }

    #[test]
    fn duplicate_track_in_a_frame_is_an_error() {
        let gt = parse(&car(0, 0, 1.0, 20.0, None));
        let res = parse(&(car(0, 5, 1.0, 20.0, Some(1.0)) + &car(0, 5, 3.0, 20.0, Some(1.0))));
        let seq = Ab3dmotSequence {
            gt: &gt,
            results: &res,
            num_frames: 1,
        };
        assert!(
            ab3dmot_evaluate(&[seq], KittiEvalClass::Car, &Ab3dmotEvalConfig::default()).is_err()
        );
    }
}
