//! `limot run`: the estimator on a dataset, its outputs and scores.

use super::options::{kitti_tracking_options, parse_score_map};
use crate::experiments::{EgoEvalOptions, evaluate_ego};
use crate::experiments::{TrackEvalOptions, evaluate_tracks};
use std::path::PathBuf;

/// `limot run --sequence N [--detections P] [--score-map M]`: a KITTI
/// tracking sequence.
pub(super) struct KittiTracking {
    pub(super) sequence: Option<u32>,
    pub(super) detections: Option<PathBuf>,
    pub(super) score_map: String,
}

/// `limot run BAG --lidar-topic T --imu-topic T [--detections-topic T]
/// [--extrinsic F]`: a ROS 2 bag.
pub(super) struct BagTopics {
    pub(super) lidar: Option<String>,
    pub(super) imu: Option<String>,
    pub(super) detections: Option<String>,
    pub(super) extrinsic: Option<PathBuf>,
}

impl BagTopics {
    fn any(&self) -> bool {
        self.lidar.is_some()
            || self.imu.is_some()
            || self.detections.is_some()
            || self.extrinsic.is_some()
    }
}

#[allow(clippy::too_many_arguments)]
pub(super) fn run_estimator(
    dataset: &std::path::Path,
    out: Option<PathBuf>,
    variant: &str,
    lidar_only: bool,
    first_frame: usize,
    max_frames: Option<usize>,
    kitti_tracking: KittiTracking,
    bag: BagTopics,
    tracker: &str,
    mcap: Option<&crate::io::mcap::McapRequest>,
) -> Result<(), Box<dyn std::error::Error>> {
    use crate::io::Source;
    use crate::run::{RunOptions, run, run_recorded, write_output};
    use limot_estimator::Variant;
    let variant = Variant::ALL
        .into_iter()
        .find(|v| v.name() == variant)
        .ok_or_else(|| format!("unknown variant `{variant}` (lio, allfilt, dynafilt, limot)"))?;
    let is_bag = dataset.is_file();
    let out = out.unwrap_or_else(|| match is_bag {
        true => {
            let stem = dataset.file_stem().unwrap_or_default().to_string_lossy();
            dataset.with_file_name(format!("{stem}-{}", variant.name()))
        }
        false => dataset.join(variant.name()),
    });
    if bag.any() && !is_bag {
        let mcap_inside = std::fs::read_dir(dataset)
            .into_iter()
            .flatten()
            .filter_map(|e| e.ok().map(|e| e.path()))
            .find(|p| p.extension().is_some_and(|x| x == "mcap"));
        if let Some(file) = mcap_inside {
            return Err(format!(
                "{} is a rosbag2 directory: give one of its MCAP files, e.g. {}",
                dataset.display(),
                file.display()
            )
            .into());
        }
        return Err(format!(
            "--lidar-topic, --imu-topic, --detections-topic and --extrinsic are for a ROS 2 bag file, and {} is none",
            dataset.display()
        )
        .into());
    }
    let source = match (kitti_tracking.sequence, &kitti_tracking.detections) {
        _ if is_bag => {
            let (Some(lidar_topic), Some(imu_topic)) = (bag.lidar, bag.imu) else {
                return Err(format!(
                    "{}: a ROS 2 bag needs --lidar-topic TOPIC and --imu-topic TOPIC; its topics: {}",
                    dataset.display(),
                    crate::io::rosbag::topic_listing(dataset)?
                )
                .into());
            };
            Source::open_bag(
                dataset,
                &crate::io::rosbag::BagOptions {
                    lidar_topic,
                    imu_topic,
                    detections_topic: bag.detections,
                    extrinsic: bag.extrinsic,
                },
            )?
        }
        (Some(sequence), detections) => Source::open_kitti_tracking(
            dataset,
            sequence,
            detections.as_deref(),
            parse_score_map(&kitti_tracking.score_map)?,
        )?,
        (None, Some(_)) => {
            return Err("--detections needs --sequence (a KITTI tracking directory)".into());
        }
        (None, None) => Source::open(dataset)?,
    };
    let options = RunOptions {
        variant,
        lidar_only,
        first_frame,
        max_frames,
        progress: true,
    };
    let tracking = kitti_tracking_options(tracker, parse_score_map(&kitti_tracking.score_map)?)?;
    let config = if kitti_tracking.sequence.is_some() {
        crate::run::kitti_tracking_config(tracking.tracker.clone(), variant)
    } else {
        limot_estimator::pipeline::EstimatorConfig {
            tracker: tracking.tracker.clone(),
            ..Default::default()
        }
    };
    let output = match mcap {
        Some(request) => {
            let (output, stats) = run_recorded(&source, dataset, &options, Some(config), request)?;
            super::print_mcap(&stats);
            output
        }
        None => run(&source, dataset, &options, Some(config))?,
    };
    write_output(&out, &output)?;
    let n = output.estimates.len();
    println!(
        "{}: {} frames estimated ({} of them LiDAR-only before the inertial initialisation), {:?} mode, {:.1} s wall ({:.1} FPS)",
        variant.name(),
        n,
        output.frames_before_init,
        output.mode,
        output.wall_time.as_secs_f64(),
        n as f64 / output.wall_time.as_secs_f64().max(1e-9)
    );
    let timings: Vec<String> = output
        .mean_timings()
        .iter()
        .map(|(name, d)| format!("{name} {:.2}", d.as_secs_f64() * 1e3))
        .collect();
    println!("mean ms per frame: {}", timings.join(", "));
    if output.invalid_detections > 0 {
        eprintln!(
            "warning: {} detections skipped (non-finite or non-positive fields, score outside [0, 1], or seen outside their sweep)",
            output.invalid_detections
        );
    }
    if dataset.join("gt").join("ego.csv").is_file() {
        let opts = EgoEvalOptions::default();
        let e = evaluate_ego(dataset, &out.join("poses_tum.txt"), &opts)?;
        println!(
            "ego vs truth: ATE_T {:.3} m, ATE_R {:.4} rad over {} poses",
            e.ate.ate_t_rmse_m, e.ate.ate_r_rmse_rad, e.ate.n
        );
    }
    if let Some(sequence) = kitti_tracking.sequence {
        use crate::experiments::{KittiScoreOptions, score_run};
        let (scores, results) = score_run(
            dataset,
            sequence,
            &output,
            &out.join("kitti_results"),
            &KittiScoreOptions {
                result: tracking.result.clone(),
                score_map: tracking.score_map,
                ..KittiScoreOptions::default()
            },
        )?;
        println!("ego vs OXTS: {}", scores.ego.summary_line());
        match &scores.tracks {
            Some(tracks) => {
                for line in tracks.summary_lines(KittiScoreOptions::default().longest_objects) {
                    println!("tracks vs label_02: {line}");
                }
            }
            None if !variant.tracks_objects() => {}
            None => println!(
                "tracks: no {} here, so no MOT score",
                crate::io::kitti::sequence_file(&dataset.join("label_02"), sequence).display()
            ),
        }
        if let Some(f) = &scores.filter {
            println!("filter vs label_02: {}", f.labelled_summary_line());
        }
        let scores_path = out.join("scores.json");
        std::fs::write(&scores_path, serde_json::to_string_pretty(&scores)? + "\n")
            .map_err(|e| format!("{}: {e}", scores_path.display()))?;
        println!("KITTI tracking results: {}", results.display());
        println!("scores: {}", scores_path.display());
    }
    if let Source::Dataset(dataset) = &source {
        let (calib, _) = crate::experiments::dataset_calib(dataset, 0)?;
        let results =
            crate::run::write_dataset_kitti_tracks(&out.join("kitti_results"), &output, &calib)?;
        let e = evaluate_tracks(
            dataset_dir_of(dataset),
            &results,
            &TrackEvalOptions::default(),
        )?;
        for score in &e.scores {
            println!(
                "tracks vs truth ({:?} IoU {}): MOTA {:.1} %, MOTP {:.1} %, IDSW {}, FP {}, FN {}",
                score.iou_kind,
                score.iou_threshold,
                score.all.mota.unwrap_or(f64::NAN) * 100.0,
                score.all.motp.unwrap_or(f64::NAN) * 100.0,
                score.all.id_switches,
                score.all.false_positives,
                score.all.false_negatives
            );
        }
        println!("KITTI tracking results: {}", results.display());
    }
    println!("trajectory: {}", out.join("poses_tum.txt").display());
    Ok(())
}

pub(super) fn dataset_dir_of(dataset: &limot_sim::record::Dataset) -> &std::path::Path {
    &dataset.dir
}
