//! Experiments: the glue that runs the system's variants on datasets and
//! scores them with [`crate::metrics`], for the report layer ([`crate::report`]).
//!
//! - Scoring result files against ground truth (`limot eval ego|tracks|filtering`,
//!   a run on a KITTI sequence): [`evaluate_ego`], [`evaluate_tracks`],
//!   [`evaluate_filtering`], [`score_run`].
//! - The simulated suite (families × seeds × variants → `results.json`),
//!   with the KITTI twins as the family `kitti`: [`run_suite`],
//!   [`merge_shards`], [`SuiteResults`], [`KittiTwins`].
//! - The KITTI suite (variants and the tracker alone on KITTI tracking
//!   sequences): [`run_kitti_suite`], [`KittiSuiteResults`].
//! - The tracker alone on KITTI tracking data and its scores:
//!   [`track_sequence`], [`evaluate_sequences`], [`score_results`].
//! - Realism statistics of a simulated dataset against a KITTI sequence:
//!   [`run_realism`].
mod kitti_suite;
mod realism;
mod score;
mod suite;
mod track_kitti;

pub use kitti_suite::{
    Ab3dmotSummary, EgoPeerResult, KITTI_RESULTS_FORMAT_VERSION, KITTI_RESULTS_KIND,
    KittiSequenceResult, KittiSuiteResults, KittiSuiteSpec, KittiVariantResult, TRACKER_ALONE,
    TrackerResult, has_scans, is_kitti_results, oxts_sequences, run_kitti_suite,
};
pub use realism::{
    RealismError, RealismOptions, RealismReport, SequenceRealism, analyze_sequence, kitti_dir_of,
    run_realism,
};
pub use score::ego::{
    EgoEvalOptions, EgoEvaluation, PoseFormat, Trajectory, detect_pose_format, evaluate_ego,
    evaluate_trajectories, load_estimate, load_truth, parse_rpe_delta,
};
pub use score::filtering::{
    FILTER_MOVING_SPEED_MPS, FilterEvaluation, FrameObjects, KeptMovingCauses, TRACK_OBJECT_GATE_M,
    evaluate_filtering,
};
pub use score::kitti_filter::{
    LABEL_BOX_GROUND_CLEARANCE_M, LABEL_BOX_MARGIN_M, SPEED_WINDOW_FRAMES, score_filter_on_labels,
};
pub use score::kitti_sequence::{
    EgoScores, KittiEgoTruth, KittiRunScores, KittiScoreOptions, ObjectSummary, RPE_PATH_DELTA_M,
    TrackScores, read_ego_truth, read_sequence_labels, score_ego, score_run, score_tracks,
};
pub use score::tracks::{
    GtFilter, MotScore, ResultBoxes, ScoredTruth, TrackEvalOptions, TrackingInput,
    TracksEvaluation, dataset_calib, ego_pose_at, evaluate_tracks, read_results, tracking_input,
};
pub use score::{EvaluateError, dataset_frame_times, is_limot_dataset};
pub(crate) use suite::variant_name;
pub use suite::{
    Ablation, AblationResult, EgoMetrics, KittiTwins, MOVING_SPEED_MPS, MotMetrics,
    ObjectMetricsRecord, RESULTS_FILE, RESULTS_FORMAT_VERSION, SequenceResult, Shard, StageSamples,
    SuiteError, SuiteResults, SuiteSpec, TWIN_FAMILY, VariantMetrics, VariantResult, error_chain,
    format_sequences, merge_shards, parse_list, parse_sequences, run_suite, sequence_name,
    twin_family, twin_sequence,
};
pub use track_kitti::{
    BoxSource, OutputPolicy, ResultPolicy, ResultWriter, SequenceResults, SequenceScores,
    SequenceTracks, TrackKittiError, TrackKittiOptions, TrackingEvaluation, detection_to_world,
    evaluate_sequences, kitti_val_offline_options, kitti_val_tuned_config, kitti_val_tuned_options,
    lidar_poses, read_results_dir, score_results, track_sequence, track_sequence_with,
    world_box_to_lidar,
};
