//! The tracker alone on the real KITTI tracking validation sequences
//! (`../shared/data/kitti_tracking`: PointRCNN car detections of AB3DMOT,
//! OXTS ego poses, label_02 ground truth). Skips with a loud note only when
//! `../shared/data` is absent; any unreadable file fails the test.

use limot::experiments::{
    BoxSource, OutputPolicy, TrackKittiError, TrackKittiOptions, TrackingEvaluation,
    evaluate_sequences, kitti_val_offline_options, kitti_val_tuned_config, kitti_val_tuned_options,
    lidar_poses, read_results_dir, score_results, track_sequence, track_sequence_with,
};
use limot::io::kitti::calib::Calib;
use limot::io::kitti::detections::{
    ScoreMap, camera_box_to_lidar, parse_ab3dmot_csv, read_ab3dmot_csv,
};
use limot::io::kitti::labels::read_labels;
use limot::io::kitti::oxts::{oxts_to_poses, read_oxts};
use limot::io::kitti::seqmap::read_seqmap;
use limot::io::kitti::sequence_file;
use limot_estimator::tracking::{AssociationMetric, Extrapolation, HeadingRule, TrackerConfig};
use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

mod common;

fn data_root() -> Option<PathBuf> {
    common::data_root("KITTI tracking")
}

/// The validation sequence not shipped in ../shared/data.
const ABSENT_SEQUENCE: u32 = 19;

struct Dirs {
    training: PathBuf,
    detections: PathBuf,
}

fn dirs(root: &Path) -> Dirs {
    let base = root.join("kitti_tracking");
    Dirs {
        training: base.join("training"),
        detections: base.join("detections/pointrcnn_Car_val"),
    }
}

fn evaluate(root: &Path, options: &TrackKittiOptions) -> TrackingEvaluation {
    let d = dirs(root);
    let seqmap = read_seqmap(&d.training.join("evaluate_tracking.seqmap.val")).unwrap();
    assert_eq!(seqmap.len(), 11, "the validation split has 11 sequences");
    // ../shared/data ships sequences 0000-0018 only: 0019 (1059 frames) of
    // the split is absent. Any other missing file fails below.
    let present: Vec<_> = seqmap
        .into_iter()
        .filter(|e| e.sequence != ABSENT_SEQUENCE)
        .collect();
    let numbers: Vec<u32> = present.iter().map(|e| e.sequence).collect();
    assert_eq!(numbers, [1, 6, 8, 10, 12, 13, 14, 15, 16, 18]);
    let (tracks, eval) = evaluate_sequences(&d.training, &d.detections, &present, options).unwrap();
    assert_eq!(tracks.len(), present.len());
    for t in &tracks {
        assert_eq!(t.garbage_detections, 0, "sequence {}", t.sequence);
    }
    eval
}

/// AB3DMOT's published Car figures: KITTI 2D MOTA and 3D (IoU 0.25) MOTA / MOTP.
const AB3DMOT_MOTA_2D: f64 = 0.838;
const AB3DMOT_MOTA_3D: f64 = 0.8647;
const AB3DMOT_MOTP_3D: f64 = 0.7940;

#[test]
fn validation_sequences_reach_ab3dmot_level() {
    let Some(root) = data_root() else { return };
    // Measured on the 10 available val sequences (7560 evaluated car boxes):
    //              2D MOTA / MOTP   3D@0.25 MOTA / MOTP   IDSW  FP   FN   evaluate.py best MOTA, sAMOTA
    // paper cfg:   80.42 / 87.14    80.45 / 80.02          10   425  1045  82.13, 86.20
    // tuned cfg:   83.65 / 87.08    83.61 / 79.97          20   349   867  85.33, 89.80
    // AB3DMOT:     84.75 / 86.81    84.70 / 79.60          14   381   758  85.49, 86.97
    // Bounds: about one point below the measurement.
    let paper = evaluate(&root, &TrackKittiOptions::default());
    println!("paper config:\n{}", paper.to_text());
    let tuned = evaluate(&root, &kitti_val_tuned_options());
    println!("tuned config:\n{}", tuned.to_text());
    assert!(
        tuned.ab3dmot_3d.samota > 0.89,
        "{}",
        tuned.ab3dmot_3d.samota
    );
    assert!(tuned.ab3dmot_3d.best.mota.unwrap() > 0.845);
    assert!(
        paper.ab3dmot_3d.samota > 0.855,
        "{}",
        paper.ab3dmot_3d.samota
    );
    for (name, eval, min_mota) in [("paper", &paper, 0.79), ("tuned", &tuned, 0.825)] {
        let (two_d, three_d) = (&eval.total_image_iou_50, &eval.total_iou3d_25);
        assert_eq!(two_d.gt_count, 7560, "{name}");
        assert_eq!(three_d.gt_count, 7560, "{name}");
        let mota_2d = two_d.mota.unwrap();
        let mota_3d = three_d.mota.unwrap();
        let motp_2d = two_d.motp.unwrap();
        let motp_3d = three_d.motp.unwrap();
        assert!(mota_2d > min_mota, "{name}: 2D MOTA {mota_2d}");
        assert!(mota_3d > min_mota, "{name}: 3D MOTA {mota_3d}");
        assert!(motp_2d > 0.86, "{name}: 2D MOTP {motp_2d}");
        assert!(motp_3d > 0.79, "{name}: 3D MOTP {motp_3d}");
        assert!(
            two_d.id_switches <= 25,
            "{name}: IDSW {}",
            two_d.id_switches
        );
        // Within a few points of AB3DMOT (which also has sequence 0019).
        assert!(
            (mota_2d - AB3DMOT_MOTA_2D).abs() < 0.05,
            "{name}: {mota_2d}"
        );
        assert!(
            (mota_3d - AB3DMOT_MOTA_3D).abs() < 0.07,
            "{name}: {mota_3d}"
        );
        assert!(
            (motp_3d - AB3DMOT_MOTP_3D).abs() < 0.02,
            "{name}: {motp_3d}"
        );
    }
    // Tuning pays on both evaluations.
    assert!(tuned.total_image_iou_50.mota > paper.total_image_iou_50.mota);
    assert!(tuned.total_iou3d_25.mota > paper.total_iou3d_25.mota);
}

#[test]
fn offline_settings_are_ahead_of_ab3dmot_in_sample() {
    let Some(root) = data_root() else { return };
    // Measured (whole split, in-sample; the two-fold held-out figures are in
    // docs/tracking-kitti.md):
    //              2D MOTA  FP / FN    3D best MOTA / MOTP   sAMOTA
    // offline:     88.16    319 / 564  88.47 / 79.21          89.86
    // AB3DMOT:     84.75    381 / 758  85.49 / 79.54          86.97
    let e = evaluate(&root, &kitti_val_offline_options());
    println!("offline settings:\n{}", e.to_text());
    let t = &e.total_image_iou_50;
    let a = &e.ab3dmot_3d;
    let pct = |x: f64| (100.0 * x * 100.0).round() / 100.0;
    assert_eq!(pct(t.mota.unwrap()), 88.16);
    assert_eq!((t.false_positives, t.false_negatives), (319, 564));
    assert_eq!(pct(a.best.mota.unwrap()), 88.47);
    assert_eq!(pct(a.samota), 89.86);
    // Ahead of AB3DMOT's output on the same evaluators.
    assert!(t.mota.unwrap() > 0.8475 && a.best.mota.unwrap() > 0.8549 && a.samota > 0.8697);
}

/// The 10 val sequences present in ../shared/data.
fn present_val_seqmap(training: &Path) -> Vec<limot::io::kitti::seqmap::SeqmapEntry> {
    read_seqmap(&training.join("evaluate_tracking.seqmap.val"))
        .unwrap()
        .into_iter()
        .filter(|e| e.sequence != ABSENT_SEQUENCE)
        .collect()
}

#[test]
fn ab3dmot_peer_output_scores() {
    let Some(root) = data_root() else { return };
    let d = dirs(&root);
    let peer_dir = root.join("kitti_tracking/peers/ab3dmot_pointrcnn_Car_val_thres");
    let seqmap = present_val_seqmap(&d.training);
    assert_eq!(seqmap.len(), 10);
    let results = read_results_dir(&peer_dir, &seqmap).unwrap();
    let eval = score_results(&d.training, &seqmap, &results).unwrap();
    println!("{}", eval.to_text());
    // AB3DMOT's output on these labels; the real evaluate.py gives the same
    // 3D figures (85.49 / 79.54 / 86.97, AMOTA 41.76; docs/tracking-kitti.md).
    // The peer README's 86.55 / 79.38 / 88.92 and 2D 85.82 (FP 394, FN 779)
    // imply ~8380 ground-truth boxes instead of the 7560 here (full val with
    // 0019, like AB3DMOT's published rows), not these label files.
    let a = &eval.ab3dmot_3d;
    let pct = |x: f64| (100.0 * x * 100.0).round() / 100.0;
    assert_eq!(pct(a.best.mota.unwrap()), 85.49, "{:?}", a.best);
    assert_eq!(pct(a.best.motp), 79.54, "{:?}", a.best);
    assert_eq!(pct(a.samota), 86.97);
    assert_eq!(pct(a.amota), 41.76);
    assert_eq!(a.best.gt_count, 7560);
    // Recall samples stop where the output's recall does.
    assert!(
        a.curve.len() < 40 && a.curve.len() > 30,
        "{}",
        a.curve.len()
    );
    let t = &eval.total_image_iou_50;
    assert_eq!(pct(t.mota.unwrap()), 84.75);
    assert_eq!(
        (t.false_positives, t.false_negatives, t.id_switches),
        (381, 758, 14)
    );
}

#[test]
fn nan_in_a_detection_csv_names_file_and_line() {
    let Some(root) = data_root() else { return };
    let d = dirs(&root);
    // A copy of the real sequence 0012 detections with one field made NaN.
    let original = std::fs::read_to_string(d.detections.join("0012.txt")).unwrap();
    let lines: Vec<&str> = original.lines().collect();
    assert!(lines.len() > 5);
    let mut fields: Vec<String> = lines[4].split(',').map(str::to_string).collect();
    fields[11] = "nan".to_string();
    let mut corrupted: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    corrupted[4] = fields.join(",");
    let tmp = std::env::temp_dir().join(format!("limot_kitti_tracking_{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    std::fs::write(tmp.join("0012.txt"), corrupted.join("\n") + "\n").unwrap();
    let err = track_sequence(&d.training, &tmp, 12, &TrackerConfig::default()).unwrap_err();
    std::fs::remove_dir_all(&tmp).unwrap();
    assert!(matches!(err, TrackKittiError::Kitti(_)), "{err:?}");
    let msg = err.to_string();
    assert!(
        msg.contains("0012.txt:5") && msg.contains("`y`") && msg.contains("not finite"),
        "{msg}"
    );
    // The parser alone says the same.
    let perr = parse_ab3dmot_csv("0,2,1,2,3,4,5,1.5,1.6,4,1,NaN,10,0,0\n", Path::new("d.csv"))
        .unwrap_err()
        .to_string();
    assert!(perr.contains("d.csv:1") && perr.contains("`y`"), "{perr}");
}

#[test]
#[ignore = "parameter sweep for the report; prints a table"]
fn sweep_tracker_knobs() {
    let Some(root) = data_root() else { return };
    let base = TrackKittiOptions::default();
    let mut variants: Vec<(String, TrackKittiOptions)> = vec![("default".into(), base.clone())];
    variants.push((
        "box=detection".into(),
        TrackKittiOptions {
            box_source: BoxSource::Detection,
            ..base.clone()
        },
    ));
    variants.push(("output=all-confirmed".into(), {
        let mut o = base.clone();
        o.result.output = OutputPolicy::AllConfirmed;
        o
    }));
    for init in [1, 2, 3] {
        let mut o = base.clone();
        o.tracker.init_frames = init;
        variants.push((format!("init_frames={init}"), o));
    }
    for ms in [0.5, 0.8, 0.95] {
        let mut o = base.clone();
        o.tracker.min_score = ms;
        variants.push((format!("min_score={ms}"), o));
    }
    for mm in [1, 2, 5] {
        let mut o = base.clone();
        o.tracker.max_misses = mm;
        variants.push((format!("max_misses={mm}"), o));
    }
    for dt in [1.0, 3.0, 4.0] {
        let mut o = base.clone();
        o.tracker.d_thres_m = dt;
        variants.push((format!("d_thres={dt}"), o));
    }
    for ms in [0.3, 0.5, 0.6, 0.7] {
        for mm in [1, 2, 3] {
            for init in [3, 4, 5] {
                let mut o = base.clone();
                o.tracker.min_score = ms;
                o.tracker.max_misses = mm;
                o.tracker.init_frames = init;
                variants.push((format!("ms={ms},mm={mm},init={init}"), o));
            }
        }
    }
    for (name, o) in &variants {
        let e = evaluate(&root, o);
        let (a, b) = (&e.total_image_iou_50, &e.total_iou3d_25);
        println!(
            "{name:>22}  2D: MOTA {:.2} MOTP {:.2} IDSW {} FP {} FN {}  |  3D@0.25: MOTA {:.2} MOTP {:.2} IDSW {} FP {} FN {}",
            100.0 * a.mota.unwrap(),
            100.0 * a.motp.unwrap(),
            a.id_switches,
            a.false_positives,
            a.false_negatives,
            100.0 * b.mota.unwrap(),
            100.0 * b.motp.unwrap(),
            b.id_switches,
            b.false_positives,
            b.false_negatives
        );
    }
}

#[test]
fn parked_cars_stand_still_in_the_world_frame() {
    // Checks the pose convention (T_world_lidar = T_world_imu · T_velo_imu⁻¹)
    // independently of the tracker: in the val sequences where the ego drives
    // at 7-14 m/s, labelled cars that sweep > 10 m through the LiDAR frame
    // but stay within half a metre in the world frame are parked ones passed
    // by; with a wrong pose they would smear over metres.
    let Some(root) = data_root() else { return };
    let d = dirs(&root);
    let mut world_spreads = Vec::new();
    for seq in [1, 8, 10, 18] {
        let calib = Calib::read(&sequence_file(&d.training.join("calib"), seq)).unwrap();
        let oxts = read_oxts(&sequence_file(&d.training.join("oxts"), seq)).unwrap();
        let poses = lidar_poses(&oxts_to_poses(&oxts), &calib);
        let labels = read_labels(&sequence_file(&d.training.join("label_02"), seq)).unwrap();
        let mut per_track: BTreeMap<i64, Vec<LidarAndWorld>> = BTreeMap::new();
        for l in labels
            .iter()
            .filter(|l| l.type_name == "Car" && l.track_id >= 0)
        {
            let b = camera_box_to_lidar(&l.cam_box, &calib);
            let world = poses[l.frame as usize]
                .transform_point(&b.center.into())
                .coords;
            per_track
                .entry(l.track_id)
                .or_default()
                .push((b.center, world));
        }
        for boxes in per_track.values().filter(|b| b.len() >= 20) {
            let travel_lidar = (boxes[0].0 - boxes[boxes.len() - 1].0).norm();
            if travel_lidar > 10.0 {
                let world: Vec<Vector3<f64>> = boxes.iter().map(|b| b.1).collect();
                world_spreads.push(horizontal_spread_m(&world));
            }
        }
    }
    world_spreads.sort_by(f64::total_cmp);
    println!("world-frame spread of cars sweeping > 10 m past the ego: {world_spreads:.2?}");
    let parked = world_spreads.iter().filter(|s| **s < 0.5).count();
    assert!(parked >= 40, "{world_spreads:?}");
}

/// A box centre in the LiDAR frame and in the world frame.
type LidarAndWorld = (Vector3<f64>, Vector3<f64>);

/// Largest horizontal distance of a point from the points' mean.
fn horizontal_spread_m(points: &[Vector3<f64>]) -> f64 {
    let mean = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    points
        .iter()
        .map(|p| (p - mean).xy().norm())
        .fold(0.0, f64::max)
}

#[test]
fn matched_tracks_carry_their_detection_score() {
    let Some(root) = data_root() else { return };
    let d = dirs(&root);
    let seq = 1;
    let raw = read_ab3dmot_csv(&sequence_file(&d.detections, seq)).unwrap();
    let options = TrackKittiOptions {
        tracker: kitti_val_tuned_config(),
        ..TrackKittiOptions::default()
    };
    let matched = track_sequence_with(&d.training, &d.detections, seq, &options).unwrap();
    let mut written = 0;
    for (frame, boxes) in matched.per_frame.iter().enumerate() {
        for b in boxes {
            written += 1;
            // The raw score, through the tracker's [0, 1] score and back.
            let found = raw.iter().any(|r| {
                r.frame as usize == frame
                    && (ScoreMap::Sigmoid.apply(r.score_raw) - ScoreMap::Sigmoid.apply(b.score))
                        .abs()
                        < 1e-12
            });
            assert!(
                found,
                "frame {frame} track {}: score {}",
                b.track_id, b.score
            );
            assert!(ScoreMap::Sigmoid.apply(b.score) >= options.tracker.min_score - 1e-12);
        }
    }
    assert!(written > 2000, "{written}");
    // Writing coasting tracks too adds boxes (with their last detection's score).
    let all = track_sequence_with(&d.training, &d.detections, seq, &{
        let mut o = options;
        o.result.output = OutputPolicy::AllConfirmed;
        o
    })
    .unwrap();
    let written_all: usize = all.per_frame.iter().map(Vec::len).sum();
    assert!(written_all > written, "{written_all} vs {written}");
    assert_eq!(matched.labels.len() + matched.outside_image, written);
}

/// The two folds of the 10 val sequences for cross-validation.
const FOLDS: [[u32; 5]; 2] = [[1, 6, 8, 10, 12], [13, 14, 15, 16, 18]];

/// Model-selection objective, the tracker's aim (ahead of AB3DMOT in 2D MOTA,
/// 3D MOTA at the best threshold and sAMOTA): the smallest of the three
/// margins over AB3DMOT's own output scored on the same sequences.
fn objective(e: &TrackingEvaluation, peer: &TrackingEvaluation) -> f64 {
    let figures = |e: &TrackingEvaluation| {
        [
            e.total_image_iou_50.mota.unwrap(),
            e.ab3dmot_3d.best.mota.unwrap(),
            e.ab3dmot_3d.samota,
        ]
    };
    let (ours, theirs) = (figures(e), figures(peer));
    (0..3)
        .map(|k| ours[k] - theirs[k])
        .fold(f64::INFINITY, f64::min)
}

/// How written tracks are gated on their mean raw detection score.
#[derive(Debug, Clone, Copy)]
enum TrackGate {
    None,
    /// Online: the mean so far (`min_track_score`).
    Online(f64),
    /// Offline: the mean over the whole sequence (`offline_track_score`).
    Offline(f64),
}

/// The candidate KITTI settings of the cross-validation. Start-up 3 frames
/// and a 3 m centre gate are fixed: the earlier 128-setting grid picked them
/// on each fold separately.
fn candidate_options() -> Vec<(String, TrackKittiOptions)> {
    let mut out = Vec::new();
    let gates = [
        TrackGate::None,
        TrackGate::Online(1.0),
        TrackGate::Online(1.5),
        TrackGate::Online(2.0),
        TrackGate::Offline(2.0),
        TrackGate::Offline(3.0),
        TrackGate::Offline(4.0),
    ];
    for gate in gates {
        for min_score in [0.0, 0.3, 0.45, 0.6] {
            for giou in [false, true] {
                for coast in [0, 1] {
                    for init in [2, 3] {
                        for cv in [false, true] {
                            for revive in [0, 2] {
                                let mut o = kitti_val_tuned_options();
                                o.result.startup_frames = 3;
                                o.tracker.d_thres_m = 3.0;
                                o.tracker.min_score = min_score;
                                (o.result.min_track_score, o.result.offline_track_score) =
                                    match gate {
                                        TrackGate::None => (f64::NEG_INFINITY, f64::NEG_INFINITY),
                                        TrackGate::Online(v) => (v, f64::NEG_INFINITY),
                                        TrackGate::Offline(v) => (f64::NEG_INFINITY, v),
                                    };
                                o.tracker.association = if giou {
                                    AssociationMetric::Giou3d {
                                        min_giou: -0.2,
                                        distance_gate: false,
                                    }
                                } else {
                                    AssociationMetric::CentreDistance
                                };
                                o.result.output = match coast {
                                    0 => OutputPolicy::MatchedConfirmed,
                                    n => OutputPolicy::CoastingUpTo(n),
                                };
                                o.tracker.init_frames = init;
                                o.tracker.extrapolation = if cv {
                                    Extrapolation::ConstantVelocity
                                } else {
                                    Extrapolation::Fit
                                };
                                o.tracker.revive_frames = revive;
                                let name = format!(
                                    "gate {gate:?} min_score {min_score} giou {giou} coast {coast} \
                                     init {init} cv {cv} revive {revive}"
                                );
                                out.push((name, o));
                            }
                        }
                    }
                }
            }
        }
    }
    out
}

fn summary(e: &TrackingEvaluation) -> String {
    let (t, a) = (&e.total_image_iou_50, &e.ab3dmot_3d);
    format!(
        "2D MOTA {:.2} FP {} FN {} IDSW {} | 3D MOTA {:.2} MOTP {:.2} | sAMOTA {:.2} AMOTA {:.2}",
        100.0 * t.mota.unwrap(),
        t.false_positives,
        t.false_negatives,
        t.id_switches,
        100.0 * a.best.mota.unwrap(),
        100.0 * a.best.motp,
        100.0 * a.samota,
        100.0 * a.amota
    )
}

/// Tracks every present val sequence with `options` and scores fold A, fold B
/// and the whole split from the same tracks.
fn score_folds(root: &Path, options: &TrackKittiOptions) -> [TrackingEvaluation; 3] {
    let d = dirs(root);
    let all = present_val_seqmap(&d.training);
    let results: Vec<limot::experiments::SequenceResults> = all
        .iter()
        .map(|e| {
            let t = track_sequence_with(&d.training, &d.detections, e.sequence, options).unwrap();
            limot::experiments::SequenceResults {
                sequence: e.sequence,
                labels: t.labels,
            }
        })
        .collect();
    let subset = |keep: &dyn Fn(u32) -> bool| {
        let seqmap: Vec<_> = all.iter().filter(|e| keep(e.sequence)).cloned().collect();
        let rows: Vec<_> = results
            .iter()
            .filter(|r| keep(r.sequence))
            .cloned()
            .collect();
        score_results(&d.training, &seqmap, &rows).unwrap()
    };
    [
        subset(&|s| FOLDS[0].contains(&s)),
        subset(&|s| FOLDS[1].contains(&s)),
        subset(&|_| true),
    ]
}

#[test]
#[ignore = "the new tracker options one at a time on the shipped settings; prints a table"]
fn ablate_tracker_options() {
    let Some(root) = data_root() else { return };
    let base = kitti_val_tuned_options();
    let mut variants: Vec<(String, TrackKittiOptions)> = vec![("shipped".into(), base.clone())];
    let with = |f: &dyn Fn(&mut TrackKittiOptions)| {
        let mut o = base.clone();
        f(&mut o);
        o
    };
    for min_giou in [-0.5, -0.2, 0.0] {
        for gate in [false, true] {
            variants.push((
                format!("giou {min_giou} gate {gate}"),
                with(&|o| {
                    o.tracker.association = AssociationMetric::Giou3d {
                        min_giou,
                        distance_gate: gate,
                    }
                }),
            ));
        }
    }
    variants.push((
        "constant velocity".into(),
        with(&|o| o.tracker.extrapolation = Extrapolation::ConstantVelocity),
    ));
    for revive in [1, 2, 4] {
        variants.push((
            format!("revive {revive}"),
            with(&|o| o.tracker.revive_frames = revive),
        ));
    }
    variants.push((
        "heading motion/majority".into(),
        with(&|o| o.tracker.heading_rule = HeadingRule::MotionOrMajority),
    ));
    // Combinations: the new prediction/association with coasting boxes written.
    for coast in [0, 1, 2] {
        for giou in [false, true] {
            for revive in [0, 2] {
                variants.push((
                    format!("combo coast {coast} giou {giou} cv revive {revive}"),
                    with(&|o| {
                        o.result.output = match coast {
                            0 => OutputPolicy::MatchedConfirmed,
                            n => OutputPolicy::CoastingUpTo(n),
                        };
                        o.tracker.extrapolation = Extrapolation::ConstantVelocity;
                        o.tracker.revive_frames = revive;
                        if giou {
                            o.tracker.association = AssociationMetric::Giou3d {
                                min_giou: -0.2,
                                distance_gate: false,
                            };
                        }
                    }),
                ));
            }
        }
    }
    // AB3DMOT's offline whole-track gate instead of the online one.
    for min_score in [0.3, 0.45, 0.6] {
        for offline in [1.0, 2.0, 3.0] {
            for coast in [0, 1] {
                for init in [2, 3] {
                    variants.push((
                        format!(
                            "offline {offline} min_score {min_score} coast {coast} init {init}"
                        ),
                        with(&|o| {
                            o.tracker.min_score = min_score;
                            o.result.min_track_score = f64::NEG_INFINITY;
                            o.result.offline_track_score = offline;
                            o.tracker.init_frames = init;
                            o.tracker.extrapolation = Extrapolation::ConstantVelocity;
                            o.result.output = match coast {
                                0 => OutputPolicy::MatchedConfirmed,
                                n => OutputPolicy::CoastingUpTo(n),
                            };
                        }),
                    ));
                }
            }
        }
    }
    let filter = std::env::var("LIMOT_ABLATE").unwrap_or_default();
    for (name, o) in variants.iter().filter(|(n, _)| n.contains(&filter)) {
        let [a, b, all] = score_folds(&root, o);
        println!(
            "{name}\n  A: {}\n  B: {}\n  all: {}",
            summary(&a),
            summary(&b),
            summary(&all)
        );
    }
}

#[test]
#[ignore = "two-fold cross-validation of the KITTI settings (~12 min); prints a table"]
fn cross_validate_kitti_settings() {
    let Some(root) = data_root() else { return };
    let d = dirs(&root);
    let all = present_val_seqmap(&d.training);
    let fold_map = |k: usize| -> Vec<_> {
        all.iter()
            .filter(|e| FOLDS[k].contains(&e.sequence))
            .cloned()
            .collect()
    };
    let candidates = candidate_options();
    let peer_dir = root.join("kitti_tracking/peers/ab3dmot_pointrcnn_Car_val_thres");
    let peer = |seqmap: &[limot::io::kitti::seqmap::SeqmapEntry]| {
        score_results(
            &d.training,
            seqmap,
            &read_results_dir(&peer_dir, seqmap).unwrap(),
        )
        .unwrap()
    };
    let peers = [peer(&fold_map(0)), peer(&fold_map(1)), peer(&all)];
    // Objective of every candidate on fold A, fold B and the whole split
    // (each candidate tracked once; the folds scored from the same tracks).
    let objectives: Vec<[f64; 3]> = candidates
        .iter()
        .map(|(_, o)| {
            let e = score_folds(&root, o);
            [0, 1, 2].map(|k| objective(&e[k], &peers[k]))
        })
        .collect();
    // Two selections: among the online settings only, and among all (with
    // AB3DMOT's offline whole-track gate).
    let mut shipped = Vec::new();
    for online_only in [true, false] {
        let allowed = |i: usize| {
            !online_only || candidates[i].1.result.offline_track_score == f64::NEG_INFINITY
        };
        let select = |k: usize| {
            (0..candidates.len())
                .filter(|&i| allowed(i))
                .max_by(|&i, &j| {
                    objectives[i][k]
                        .total_cmp(&objectives[j][k])
                        .then(j.cmp(&i))
                })
                .unwrap()
        };
        println!(
            "=== {} settings",
            if online_only {
                "online"
            } else {
                "online or offline"
            }
        );
        let mut held_out: BTreeMap<u32, Vec<limot::io::kitti::labels::TrackingLabel>> =
            BTreeMap::new();
        for (train, test) in [(0, 1), (1, 0)] {
            let i = select(train);
            let (name, options) = &candidates[i];
            let (tracks, e) =
                evaluate_sequences(&d.training, &d.detections, &fold_map(test), options).unwrap();
            println!(
                "tuned on fold {train} (objective {:.2}): {name}\n  held-out fold {test}: {}\n  AB3DMOT on fold {test}: {}",
                100.0 * objectives[i][train],
                summary(&e),
                summary(&peers[test])
            );
            for t in tracks {
                held_out.insert(t.sequence, t.labels);
            }
        }
        let results: Vec<_> = all
            .iter()
            .map(|e| limot::experiments::SequenceResults {
                sequence: e.sequence,
                labels: held_out[&e.sequence].clone(),
            })
            .collect();
        let e = score_results(&d.training, &all, &results).unwrap();
        println!("held-out, whole split: {}", summary(&e));
        println!("AB3DMOT, whole split: {}", summary(&peers[2]));
        // The same selection on the whole split gives the shipped settings.
        let i = select(2);
        let (name, options) = &candidates[i];
        let (_, e) = evaluate_sequences(&d.training, &d.detections, &all, options).unwrap();
        println!(
            "selected on the whole split (objective {:.2}): {name}\n  {}",
            100.0 * objectives[i][2],
            summary(&e)
        );
        shipped.push(options.clone());
    }
    assert_eq!(
        shipped[0],
        kitti_val_tuned_options(),
        "kitti_val_tuned_options() is the whole-split selection among online settings"
    );
    assert_eq!(
        shipped[1],
        kitti_val_offline_options(),
        "kitti_val_offline_options() is the whole-split selection among all settings"
    );
}

#[test]
fn startup_rule_and_track_score_gate_change_what_is_written() {
    let Some(root) = data_root() else { return };
    let d = dirs(&root);
    let seq = 1;
    let base = TrackKittiOptions {
        tracker: kitti_val_tuned_config(),
        ..TrackKittiOptions::default()
    };
    let plain = track_sequence_with(&d.training, &d.detections, seq, &base).unwrap();
    // Confirmation takes 3 frames: nothing is written in frames 0 and 1.
    assert!(plain.per_frame[0].is_empty() && plain.per_frame[1].is_empty());
    let mut startup = base.clone();
    startup.result.startup_frames = 3;
    let started = track_sequence_with(&d.training, &d.detections, seq, &startup).unwrap();
    assert!(
        started.per_frame[0].len() >= 3,
        "{}",
        started.per_frame[0].len()
    );
    assert_eq!(started.per_frame[5..], plain.per_frame[5..]);
    // A mean-logit gate writes a subset, and only tracks whose written
    // scores (raw, in the result lines) are high on average.
    let mut gated = base;
    gated.result.min_track_score = 5.0;
    let strict = track_sequence_with(&d.training, &d.detections, seq, &gated).unwrap();
    let count =
        |t: &limot::experiments::SequenceTracks| t.per_frame.iter().map(Vec::len).sum::<usize>();
    assert!(count(&strict) < count(&plain) && count(&strict) > 0);
    let mut per_track: BTreeMap<i64, Vec<f64>> = BTreeMap::new();
    for l in &strict.labels {
        per_track
            .entry(l.track_id)
            .or_default()
            .push(l.score.unwrap());
    }
    let low = per_track
        .values()
        .filter(|s| s.iter().sum::<f64>() / (s.len() as f64) < 3.0)
        .count();
    assert!(low * 10 < per_track.len(), "{low} of {}", per_track.len());
}

/// `limot track-kitti`'s flags set every tracker option, and a bad value is
/// refused naming the flag before any sequence is read.
#[test]
fn track_kitti_flags_set_the_tracker_options() {
    let Some(root) = data_root() else { return };
    let d = dirs(&root);
    let scratch = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("track_kitti_flags");
    let _ = std::fs::remove_dir_all(&scratch);
    std::fs::create_dir_all(&scratch).unwrap();
    let seqmap = scratch.join("seqmap");
    let line = std::fs::read_to_string(d.training.join("evaluate_tracking.seqmap.val"))
        .unwrap()
        .lines()
        .find(|l| l.starts_with("0001"))
        .unwrap()
        .to_string();
    std::fs::write(&seqmap, line + "\n").unwrap();
    let run = |extra: &[&str], out: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_limot"))
            .arg("track-kitti")
            .arg("--training")
            .arg(&d.training)
            .arg("--detections")
            .arg(&d.detections)
            .arg("--seqmap")
            .arg(&seqmap)
            .arg("--out")
            .arg(scratch.join(out))
            .args(extra)
            .output()
            .unwrap()
    };
    let plain = run(&[], "plain");
    let flagged = run(
        &[
            "--association",
            "giou:-0.5",
            "--extrapolation",
            "constant-velocity",
            "--revive-frames",
            "2",
            "--heading-rule",
            "first",
            "--offline-track-score",
            "3",
        ],
        "flagged",
    );
    for out in [&plain, &flagged] {
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(String::from_utf8_lossy(&out.stdout).contains("MOTA"));
    }
    let file = |out: &str| std::fs::read_to_string(scratch.join(out).join("0001.txt")).unwrap();
    assert_ne!(file("plain"), file("flagged"), "the flags changed nothing");
    for (flag, value) in [
        ("--association", "giou:x"),
        ("--association", "nearest"),
        ("--extrapolation", "wobble"),
        ("--heading-rule", "last"),
    ] {
        let out = run(&[flag, value], "bad");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{flag} {value}");
        assert!(stderr.contains(flag), "{flag} {value}: {stderr}");
    }
    // A value the tracker's own validation refuses (a GIoU threshold is
    // at least -1).
    let out = run(&["--association", "giou:-3"], "bad");
    assert!(!out.status.success());
    assert!(!String::from_utf8_lossy(&out.stderr).is_empty());
}
