//! `limot track-kitti`: the tracker alone on KITTI tracking sequences, or scoring of result files.

use super::TrackKittiArgs;
use super::options::kitti_tracking_options;

/// `limot track-kitti`: tracks, writes result files and prints the scores.
pub(super) fn run_track_kitti(args: TrackKittiArgs) -> Result<(), Box<dyn std::error::Error>> {
    use crate::experiments::{OutputPolicy, evaluate_sequences, read_results_dir, score_results};
    use crate::io::kitti::results::write_results_file;
    use crate::io::kitti::seqmap::read_seqmap;
    use limot_estimator::tracking::{AssociationMetric, Extrapolation, HeadingRule};
    let training = &args.training;
    let seqmap_path = args
        .seqmap
        .unwrap_or_else(|| training.join("evaluate_tracking.seqmap.val"));
    let mut entries = read_seqmap(&seqmap_path)?;
    // The directory whose NNNN.txt must exist: the results to score or the detections.
    let input_dir = args
        .score_only
        .clone()
        .or_else(|| args.detections.clone())
        .ok_or("--detections or --score-only is required")?;
    if args.skip_missing {
        entries.retain(|e| {
            let present = crate::io::kitti::sequence_file(&input_dir, e.sequence).is_file();
            if !present {
                eprintln!(
                    "skipping sequence {:04}: no file in {}",
                    e.sequence,
                    input_dir.display()
                );
            }
            present
        });
    }
    if let Some(results_dir) = args.score_only {
        let results = read_results_dir(&results_dir, &entries)?;
        print!("{}", score_results(training, &entries, &results)?.to_text());
        return Ok(());
    }
    let out = args.out.ok_or("--out is required when tracking")?;
    let mut options = kitti_tracking_options(
        &args.config,
        crate::io::kitti::detections::ScoreMap::Sigmoid,
    )?;
    let tracker = &mut options.tracker;
    if let Some(v) = args.min_score {
        tracker.min_score = v;
    }
    if let Some(v) = args.max_misses {
        tracker.max_misses = v;
    }
    if let Some(v) = args.d_thres {
        tracker.d_thres_m = v;
    }
    if let Some(v) = args.init_frames {
        tracker.init_frames = v;
    }
    if let Some(v) = args.birth_min_score {
        tracker.birth_min_score = v;
    }
    if args.total_hits {
        tracker.confirm_on_total_hits = true;
    }
    if let Some(text) = &args.association {
        tracker.association = match text.split_once(':') {
            None if text == "distance" => AssociationMetric::CentreDistance,
            Some(("giou", min)) => AssociationMetric::Giou3d {
                min_giou: min
                    .parse()
                    .map_err(|e| format!("--association `{text}`: MIN: {e}"))?,
                distance_gate: true,
            },
            _ => {
                return Err(
                    format!("--association `{text}`: expected distance or giou:MIN").into(),
                );
            }
        };
    }
    if let Some(text) = &args.extrapolation {
        tracker.extrapolation = match text.as_str() {
            "fit" => Extrapolation::Fit,
            "constant-velocity" => Extrapolation::ConstantVelocity,
            _ => {
                return Err(
                    format!("--extrapolation `{text}`: expected fit or constant-velocity").into(),
                );
            }
        };
    }
    if let Some(n) = args.revive_frames {
        tracker.revive_frames = n;
    }
    if let Some(text) = &args.heading_rule {
        tracker.heading_rule = match text.as_str() {
            "first" => HeadingRule::FirstDetection,
            "motion-or-majority" => HeadingRule::MotionOrMajority,
            _ => {
                return Err(format!(
                    "--heading-rule `{text}`: expected first or motion-or-majority"
                )
                .into());
            }
        };
    }
    // A bad override is reported here, before any sequence is read.
    limot_estimator::tracking::Tracker::new(options.tracker.clone())?;
    let result = &mut options.result;
    if args.with_predicted {
        result.output = OutputPolicy::AllConfirmed;
    }
    if let Some(n) = args.coast {
        result.output = OutputPolicy::CoastingUpTo(n);
    }
    if let Some(n) = args.startup_frames {
        result.startup_frames = n;
    }
    if let Some(v) = args.min_track_score {
        result.min_track_score = v;
    }
    if let Some(v) = args.offline_track_score {
        result.offline_track_score = v;
    }
    if let Some(n) = args.coast_min_hits {
        result.coast_min_hits = n;
    }
    if args.detection_boxes {
        options.box_source = crate::experiments::BoxSource::Detection;
    }
    std::fs::create_dir_all(&out)?;
    let (tracks, evaluation) = evaluate_sequences(training, &input_dir, &entries, &options)?;
    for t in &tracks {
        write_results_file(&out, t.sequence, &t.labels)?;
    }
    print!("{}", evaluation.to_text());
    Ok(())
}
