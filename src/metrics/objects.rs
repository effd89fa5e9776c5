//! Per-object tracking quality, as the paper's object table (after
//! DynaSLAM II): for every ground-truth object,
//!
//! - TP % = frames in which the object is matched to a track with
//!   IoU ≥ threshold (paper: 0.25) / frames in which the object appears;
//!   matching is the CLEAR-MOT matching of [`super::clear_mot`];
//! - the object's ATE against the track matched to it most often (its
//!   "associated track", ties to the smaller track id), over the frames in
//!   which that track is matched to it: translation RMSE of the box centres
//!   [m] and RMSE of the wrapped yaw difference [rad].
//!
//! No trajectory alignment is done here: boxes must already be in the same
//! frame (e.g. estimated world boxes mapped with the ego ATE alignment).

use super::EvalError;
use super::clear_mot::{ClearMotConfig, MotFrame, clear_mot};
use limot_estimator::geometry::wrap_angle_rad;
use std::collections::BTreeMap;

#[derive(Debug, Clone, PartialEq)]
/// TP % and ATE of one ground-truth object.
pub struct ObjectScore {
    /// Ground-truth id.
    pub gt_id: u64,
    /// Frames in which the object appears in the ground truth.
    pub gt_frames: usize,
    /// Frames in which it is matched to any track.
    pub tracked_frames: usize,
    /// 100 · tracked_frames / gt_frames.
    pub tp_percent: f64,
    /// The track matched most often; `None` if never matched.
    pub track_id: Option<u64>,
    /// Frames in which `track_id` is the match (the ATE sample count).
    pub ate_frames: usize,
    /// Centre-distance RMSE over `ate_frames`; `None` if never matched.
    pub ate_t_rmse_m: Option<f64>,
    /// Yaw-difference RMSE over `ate_frames`; `None` if never matched.
    pub ate_r_rmse_rad: Option<f64>,
}

/// Scores every ground-truth object (sorted by id). `cfg.iou_threshold` is the
/// TP threshold (0.25 in the paper).
///
/// # Errors
///
/// [`EvalError`] for invalid frames or boxes or a threshold outside (0, 1].
pub fn object_scores(
    frames: &[MotFrame],
    cfg: &ClearMotConfig,
) -> Result<Vec<ObjectScore>, EvalError> {
    let mot = clear_mot(frames, cfg)?;
    #[derive(Default)]
    struct Acc {
        gt_frames: usize,
        tracked_frames: usize,
        per_track: BTreeMap<u64, (usize, f64, f64)>, // frames, Σ dt², Σ dyaw²
    }
    let mut acc: BTreeMap<u64, Acc> = BTreeMap::new();
    for (frame, matches) in frames.iter().zip(&mot.per_frame) {
        for g in &frame.gt {
            acc.entry(g.id).or_default().gt_frames += 1;
        }
        for m in matches {
            let g = &frame.gt[m.gt_index].bbox;
            let t = &frame.tracks[m.track_index].bbox;
            let a = acc.entry(m.gt_id).or_default();
            a.tracked_frames += 1;
            let e = a.per_track.entry(m.track_id).or_insert((0, 0.0, 0.0));
            e.0 += 1;
            e.1 += (g.center - t.center).norm_squared();
            e.2 += wrap_angle_rad(t.yaw_rad - g.yaw_rad).powi(2);
        }
    }
    Ok(acc
        .into_iter()
        .map(|(gt_id, a)| {
            // Most frequent track; BTreeMap order makes ties go to the smaller id.
            let best =
                a.per_track
                    .iter()
                    .fold(
                        None::<(u64, (usize, f64, f64))>,
                        |best, (&id, &v)| match best {
                            Some((_, b)) if b.0 >= v.0 => best,
                            _ => Some((id, v)),
                        },
                    );
            let (track_id, ate_frames, ate_t, ate_r) = match best {
                Some((id, (n, st, sr))) => (
                    Some(id),
                    n,
                    Some((st / n as f64).sqrt()),
                    Some((sr / n as f64).sqrt()),
                ),
                None => (None, 0, None, None),
            };
            ObjectScore {
                gt_id,
                gt_frames: a.gt_frames,
                tracked_frames: a.tracked_frames,
                tp_percent: 100.0 * a.tracked_frames as f64 / a.gt_frames as f64,
                track_id,
                ate_frames,
                ate_t_rmse_m: ate_t,
                ate_r_rmse_rad: ate_r,
            }
        })
        .collect())
}

#[cfg(test)]
mod hand_tests {
    use super::*;
    use crate::metrics::clear_mot::TrackedBox;
    use limot_estimator::geometry::OrientedBox;
    use limot_estimator::input::ObjectClass;
    use nalgebra::Vector3;

    fn car(id: u64, x: f64, yaw: f64) -> TrackedBox {
        TrackedBox {
            id,
            class: ObjectClass::Car,
            bbox: OrientedBox::new(Vector3::new(x, 0.0, 1.0), Vector3::new(4.0, 2.0, 2.0), yaw),
        }
    }

    #[test]
    fn tp_percent_and_object_ate() {
        let f = |gt: Vec<TrackedBox>, tracks: Vec<TrackedBox>| MotFrame {
            gt,
            tracks,
            dont_care: vec![],
        };
        // Object 1 in 4 frames: track 10 (0.5 m off, ±0.1 rad) twice, missed once
        // (track 12 is 3 m off: IoU = 1/7 < 0.25), then track 11 once.
        // Object 2 is never tracked.
        let frames = vec![
            f(
                vec![car(1, 0.0, 0.0), car(2, 20.0, 0.0)],
                vec![car(10, 0.5, 0.1)],
            ),
            f(vec![car(1, 0.0, 0.0)], vec![car(10, 0.5, -0.1)]),
            f(vec![car(1, 0.0, 0.0)], vec![car(12, 3.0, 0.0)]),
            f(vec![car(1, 0.0, 0.0)], vec![car(11, 0.0, 0.0)]),
        ];
        let scores = object_scores(&frames, &ClearMotConfig::with_threshold(0.25)).unwrap();
        assert_eq!(scores.len(), 2);
        let a = &scores[0];
        assert_eq!((a.gt_id, a.gt_frames, a.tracked_frames), (1, 4, 3));
        assert!((a.tp_percent - 75.0).abs() < 1e-12);
        assert_eq!((a.track_id, a.ate_frames), (Some(10), 2));
        assert!((a.ate_t_rmse_m.unwrap() - 0.5).abs() < 1e-12);
        assert!((a.ate_r_rmse_rad.unwrap() - 0.1).abs() < 1e-12);
        let b = &scores[1];
        assert_eq!((b.gt_frames, b.tracked_frames, b.tp_percent), (1, 0, 0.0));
        assert_eq!((b.track_id, b.ate_t_rmse_m), (None, None));
    }
}
