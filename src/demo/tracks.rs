//! A run's tracks scored against the scored truth, with the cause of every
//! error ([`mot_loss`]): the written tracks as `limot eval tracks` reads
//! them, and every live track of the estimator (tentative, coasting) placed
//! in the truth's world frame the same way.

use super::detector::DetectorFrame;
use crate::experiments::{ScoredTruth, world_box_to_lidar};
use crate::metrics::{ClearMotConfig, EvalError, LiveTrack, MotLoss, TookDetection, mot_loss};
use crate::run::RunOutput;
use limot_estimator::tracking::Lifecycle;
use std::collections::BTreeSet;
use std::path::Path;

/// Every live track of every frame of `output`, in the truth's world frame:
/// moved into the frame's LiDAR frame with the run's own pose (as the
/// written boxes are), then out with the true one. The detection a track
/// took is named by the detector frame's truth ids (the estimator indexes
/// the frame's detections in dataset order: `output` must have skipped none).
pub fn live_tracks(
    output: &RunOutput,
    detector: &[DetectorFrame],
    truth: &ScoredTruth,
) -> Vec<Vec<LiveTrack>> {
    let mut live = vec![Vec::new(); truth.gt.len()];
    for e in &output.estimates {
        let k = e.frame_index as usize;
        let Some(frame_live) = live.get_mut(k) else {
            continue;
        };
        for t in &e.tracks {
            let took = match t.detection_index.filter(|_| !t.predicted) {
                None => TookDetection::None,
                Some(d) => match detector.get(k).and_then(|f| f.truth_ids.get(d)) {
                    Some(Some(id)) => TookDetection::Object(*id),
                    Some(None) => TookDetection::FalsePositive,
                    None => TookDetection::None,
                },
            };
            let lidar_box =
                world_box_to_lidar(&t.center_world, &t.size_lwh, t.yaw_rad, &e.t_world_lidar);
            frame_live.push(LiveTrack {
                id: t.id,
                confirmed: t.lifecycle == Lifecycle::Confirmed,
                took,
                bbox: truth.lidar_box_to_world(k, &lidar_box),
            });
        }
    }
    live
}

/// The written tracks of `results` against `truth` at `cfg`, errors by cause;
/// `detected[k]` = the truth ids the detector found in frame `k` at `cfg`.
///
/// # Errors
///
/// The result file cannot be read, or a metric fails.
pub fn track_loss(
    results: &Path,
    truth: &ScoredTruth,
    live: &[Vec<LiveTrack>],
    detected: &[BTreeSet<u64>],
    cfg: &ClearMotConfig,
) -> Result<MotLoss, super::DemoError> {
    let input = truth.tracking_input(results)?;
    mot_loss(&input.frames, detected, live, cfg).map_err(|e: EvalError| e.into())
}
