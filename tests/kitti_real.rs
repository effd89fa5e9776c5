//! Every variant on the 154 real HDL-64E scans of KITTI tracking sequence 0000
//! (`../shared/data/kitti_tracking/velodyne_0000.tar.xz`, unpacked with
//! `../shared/data/unpack-kitti.sh` under the target directory), through
//! `limot eval kitti`: scored against the OXTS poses and label_02, with the
//! measured figures as bounds. Skips with a loud note only when
//! `../shared/data` is absent; a failed unpack or run fails the test.

use limot::experiments::TrackScores;
use limot::experiments::kitti_val_tuned_options;
use limot::experiments::{KittiSuiteResults, KittiSuiteSpec, run_kitti_suite};
use limot::io::kitti::detections::ScoreMap;
use limot::report::write_kitti_report;
use limot_estimator::Variant;
use std::path::{Path, PathBuf};

mod common;

/// Frames of sequence 0000.
const FRAMES: usize = 154;

/// Unpacks the real scans into a KITTI `training` directory under the target
/// dir, once per test process (the tests run in parallel).
fn training_dir(data: &Path) -> PathBuf {
    static UNPACKED: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    UNPACKED
        .get_or_init(|| common::kitti_training(data))
        .clone()
}

fn run_all_variants() -> Option<KittiSuiteResults> {
    let data = common::data_root("real KITTI scans (sequence 0000)")?;
    let training = training_dir(&data);
    let out = common::process_dir().join("kitti_real_0000");
    let _ = std::fs::remove_dir_all(&out);
    let spec = KittiSuiteSpec {
        training,
        detections: Some(data.join("kitti_tracking/detections/pointrcnn_Car_val")),
        tracking: kitti_val_tuned_options(),
        variants: Variant::ALL.to_vec(),
        sequences: Some(vec![0]),
        tracking_peer: None,
        ego_peers: Vec::new(),
        out_dir: out.clone(),
    };
    let results = run_kitti_suite(&spec, false).unwrap();
    let readme = write_kitti_report(&out.join("report"), &results).unwrap();
    let text = std::fs::read_to_string(readme).unwrap();
    assert!(text.contains("| 00  | LIMOT (limot)"), "{text}");
    assert!(text.contains("paper, Table I"), "{text}");
    // the filter table: one row per filtering variant
    assert!(
        text.contains("Dynamic-feature filter against label_02"),
        "{text}"
    );
    assert!(text.contains("| 00  | LIO-Allfilt  |"), "{text}");
    assert!(
        !text.contains("| 00  | LIO          |"),
        "lio filters nothing: {text}"
    );
    Some(results)
}

#[test]
fn every_variant_runs_and_scores_on_real_sequence_0000() {
    let Some(results) = run_all_variants() else {
        return;
    };
    assert_eq!(results.sequences.len(), 1);
    let s = &results.sequences[0];
    assert!(s.has_scans);
    assert_eq!(s.frames, FRAMES);
    let lio = s
        .run(Variant::Lio)
        .unwrap()
        .scores
        .as_ref()
        .unwrap()
        .ego
        .clone();
    for variant in Variant::ALL {
        let run = s.run(variant).unwrap();
        assert_eq!(run.error, None, "{variant:?}");
        // No frame lost: every frame has an estimate, the moving start's ten
        // LiDAR-only sweeps before the inertial initialisation included.
        assert_eq!(run.frames_before_init, 10, "{variant:?}");
        assert_eq!(run.frames_estimated, FRAMES, "{variant:?}");
        let scores = run.scores.as_ref().unwrap();
        let e = &scores.ego;
        eprintln!("{variant:?}: {}", e.summary_line());
        // Frame 0's sweep starts before the first OXTS record.
        assert_eq!(e.poses, FRAMES - 1);
        assert_eq!(e.truth_frames_gated, 0);
        // Measured over frames 0-153 (SE(3) ATE_T / ATE_R, Sim(3) ATE_T and
        // scale, RPE): 0.919-0.921 m / 0.0191-0.0192 rad, 0.346-0.347 m at
        // 0.955, 1 frame 0.0311 m / 0.00078 rad, 10 m 0.593 m (the 10 Hz
        // OXTS's densities widened, io::imu_noise_for_rate; before:
        // 0.916-0.926 m, Sim(3) 0.322-0.323 m, 10 m 0.587 m, against the
        // velocity-integrated truth of docs/kitti-real-data.md lio 0.277 ->
        // 0.284 m and 10 m RPE 0.317 -> 0.304 m: within that truth's error,
        // while the twins gain 2-3x). The scale (the
        // OXTS positions are ~3 % short of the OXTS's own velocity) is most
        // of the SE(3) ATE: see docs/kitti-real-data.md.
        assert!(e.ate_t_m < 0.93, "{variant:?}: {}", e.ate_t_m);
        assert!(e.ate_r_rad < 0.021, "{variant:?}: {}", e.ate_r_rad);
        assert!(e.sim3_ate_t_m < 0.36, "{variant:?}: {}", e.sim3_ate_t_m);
        assert!(
            (0.94..0.97).contains(&e.sim3_scale),
            "{variant:?}: {}",
            e.sim3_scale
        );
        assert!(e.rpe_frame_t_m.unwrap() < 0.032, "{variant:?}");
        assert!(e.rpe_frame_r_rad.unwrap() < 0.0009, "{variant:?}");
        assert!(e.rpe_10m_t_m.unwrap() < 0.60, "{variant:?}");
        // The object variants are not worse than lio (within 2 %: the run
        // is this sensitive to its first sweeps; 0.03 m/s more speed at the
        // second sweep moved dynafilt from 0.917 to 0.926 m).
        assert!(
            e.ate_t_m <= 1.02 * lio.ate_t_m,
            "{variant:?}: {} vs lio {}",
            e.ate_t_m,
            lio.ate_t_m
        );
        match variant {
            Variant::Lio => assert!(scores.tracks.is_none() && scores.filter.is_none()),
            _ => {
                check_tracks(variant, scores.tracks.as_ref().unwrap());
                check_filter(variant, scores.filter.as_ref().unwrap());
            }
        }
    }
    // limot's jointly optimised tracks are at least as good as dynafilt's
    // (the same tracker without the joint graph) and as the tracker alone
    // on the OXTS poses, both written by the same result rules: MOTA and
    // 3D MOTP.
    let tracks_of = |v: Variant| {
        let t = s.run(v).unwrap().scores.as_ref().unwrap();
        t.tracks.clone().unwrap()
    };
    let alone = s.tracker.as_ref().unwrap().scores.clone().unwrap();
    let (limot, dynafilt) = (tracks_of(Variant::Limot), tracks_of(Variant::Dynafilt));
    for other in [&dynafilt.image_iou_50, &alone.image_iou_50] {
        assert!(limot.image_iou_50.mota.unwrap() >= other.mota.unwrap());
    }
    for other in [&dynafilt.iou3d_25, &alone.iou3d_25] {
        assert!(limot.iou3d_25.mota.unwrap() >= other.mota.unwrap());
        assert!(limot.iou3d_25.motp.unwrap() >= other.motp.unwrap());
    }
    // The tracker alone on the same sequence, OXTS ego poses: MOTA 85.1 %,
    // 3D MOTP 83.9 %; AB3DMOT's evaluate.py: sAMOTA 92.8 %, best MOTA 87.4 %.
    let tracker = s.tracker.as_ref().unwrap().scores.as_ref().unwrap();
    assert!(tracker.image_iou_50.mota.unwrap() > 0.84);
    assert!(tracker.iou3d_25.motp.unwrap() > 0.83);
    assert_eq!(results.ab3dmot_eval.len(), 1);
    let ab3dmot = &results.ab3dmot_eval[0];
    assert_eq!(ab3dmot.sequences, [0]);
    assert!(ab3dmot.samota > 0.92, "{ab3dmot:?}");
    assert!(ab3dmot.best_mota.unwrap() > 0.87, "{ab3dmot:?}");
}

/// The filter judged by label_02's boxes (`experiments::score::kitti_filter`).
/// Measured on 0000: of the labelled moving objects' features (the van ahead
/// and the cyclist, whom a car detector does not report) every filter removes
/// about half; of the standing objects' (the parked cars) allfilt removes
/// about half, the trajectory-based filters 2.4 % of their planar features
/// and 83 % of their edges (`EstimatorConfig::filter_static_edges`; 6.4 % of
/// all their features); all removals together are 0.4-1.5 % of the
/// features.
fn check_filter(variant: Variant, f: &limot::experiments::FilterEvaluation) {
    eprintln!(
        "{variant:?} filter vs label_02: {}",
        f.labelled_summary_line()
    );
    let share = |a: usize, b: usize| a as f64 / b as f64;
    assert!(f.features > 10_000_000, "{variant:?}: {}", f.features);
    assert!(f.moving_features > 30_000 && f.static_object_features > 150_000);
    let moving = share(f.removed_moving, f.moving_features);
    let standing = share(f.removed_static_object, f.static_object_features);
    assert!((0.45..0.65).contains(&moving), "{variant:?}: {moving}");
    let parked_planar = f.parked_planar_removed_fraction().unwrap();
    let parked_edges = f.parked_edge_removed_fraction().unwrap();
    eprintln!(
        "{variant:?}: parked planar features removed {parked_planar:.3}, edges {parked_edges:.3}"
    );
    match variant {
        Variant::Allfilt => assert!(standing > 0.4, "{standing}"),
        _ => {
            assert!(parked_planar < 0.05, "{variant:?}: {parked_planar}");
            assert!(parked_edges > 0.5, "{variant:?}: {parked_edges}");
        }
    }
    assert!(share(f.removed, f.features) < 0.02, "{variant:?}");
}

/// Measured on 0000 (PointRCNN cars, the tracker settings chosen on the val
/// split, which 0000 is not in; limot's static-node setting chosen on 0000):
/// 2D / 3D@0.25 MOTA 85.1 % (allfilt, dynafilt) and 85.6 % (limot), 3D MOTP
/// 83.6 % and 84.1 %, FP 21-22, FN 9, one ID switch; the three
/// longest-labelled cars tracked in 94-100 % of their frames within
/// 0.08-0.09 m.
fn check_tracks(variant: Variant, t: &TrackScores) {
    for m in [&t.image_iou_50, &t.iou3d_25] {
        assert_eq!(m.gt_count, 215, "{variant:?}");
        assert!(m.mota.unwrap() > 0.84, "{variant:?}: {:?}", m.mota);
        assert!(m.id_switches <= 1, "{variant:?}");
    }
    // Measured: 3D MOTP 83.6 % (allfilt, dynafilt), 84.1 % (limot).
    assert!(
        t.iou3d_25.motp.unwrap() > 0.83,
        "{variant:?}: {:?}",
        t.iou3d_25.motp
    );
    for o in t.objects.iter().take(3) {
        assert!(o.tp_percent > 90.0, "{variant:?}: {o:?}");
        assert!(o.ate_t_m.unwrap() < 0.11, "{variant:?}: {o:?}");
    }
}

/// A copy of sequence 0000 with its first `scans` scans, for damaging.
fn partial_copy(training: &Path, name: &str, scans: usize) -> PathBuf {
    let dir = common::process_dir().join(name);
    let _ = std::fs::remove_dir_all(&dir);
    for sub in ["calib", "oxts", "label_02"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
        std::fs::copy(
            training.join(sub).join("0000.txt"),
            dir.join(sub).join("0000.txt"),
        )
        .unwrap();
    }
    let velodyne = dir.join("velodyne/0000");
    std::fs::create_dir_all(&velodyne).unwrap();
    for i in 0..scans {
        let name = format!("{i:06}.bin");
        std::fs::copy(
            training.join("velodyne/0000").join(&name),
            velodyne.join(&name),
        )
        .unwrap();
    }
    dir
}

fn open_error(dir: &Path) -> String {
    match limot::io::Source::open_kitti_tracking(dir, 0, None, ScoreMap::Sigmoid) {
        Ok(_) => panic!("{} opened", dir.display()),
        Err(e) => limot::experiments::error_chain(&e),
    }
}

#[test]
fn damaged_sequences_name_the_file_and_missing_labels_give_no_mot_score() {
    let Some(data) = common::data_root("real KITTI scans (sequence 0000)") else {
        return;
    };
    let training = training_dir(&data);
    // Fewer scans than OXTS records.
    let short = partial_copy(&training, "kitti_short", 5);
    let e = open_error(&short);
    assert!(
        e.contains("oxts/0000.txt") && e.contains("154") && e.contains("5"),
        "{e}"
    );
    // No velodyne directory.
    std::fs::remove_dir_all(short.join("velodyne/0000")).unwrap();
    let e = open_error(&short);
    assert!(e.contains("velodyne/0000"), "{e}");

    let dir = partial_copy(&training, "kitti_damaged", FRAMES);
    // A garbled OXTS line and calibration line name file and line.
    let oxts = dir.join("oxts/0000.txt");
    let good_oxts = std::fs::read_to_string(&oxts).unwrap();
    let mut lines: Vec<&str> = good_oxts.lines().collect();
    lines[4] = "garbage line";
    std::fs::write(&oxts, lines.join("\n")).unwrap();
    let e = open_error(&dir);
    assert!(e.contains("oxts/0000.txt:5"), "{e}");
    std::fs::write(&oxts, &good_oxts).unwrap();
    let calib = dir.join("calib/0000.txt");
    let good_calib = std::fs::read_to_string(&calib).unwrap();
    let garbled: String = good_calib
        .lines()
        .map(|l| {
            if l.starts_with("Tr_imu_velo") {
                "Tr_imu_velo 1 2 3"
            } else {
                l
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(&calib, garbled).unwrap();
    let e = open_error(&dir);
    assert!(
        e.contains("calib/0000.txt:") && e.contains("Tr_imu_velo"),
        "{e}"
    );
    std::fs::write(&calib, &good_calib).unwrap();
    // A truncated scan names the file when it is read.
    let scan = dir.join("velodyne/0000/000003.bin");
    let bytes = std::fs::read(&scan).unwrap();
    std::fs::write(&scan, &bytes[..1000]).unwrap();
    let source = limot::io::Source::open_kitti_tracking(&dir, 0, None, ScoreMap::Sigmoid).unwrap();
    let e = limot::experiments::error_chain(&source.frame(3).unwrap_err());
    assert!(e.contains("000003.bin") && e.contains("byte offset"), "{e}");
    std::fs::write(&scan, &bytes).unwrap();

    // No labels: the ego is scored, the tracks are not.
    std::fs::remove_file(dir.join("label_02/0000.txt")).unwrap();
    let detections = data.join("kitti_tracking/detections/pointrcnn_Car_val");
    let source =
        limot::io::Source::open_kitti_tracking(&dir, 0, Some(&detections), ScoreMap::Sigmoid)
            .unwrap();
    let options = limot::run::RunOptions {
        variant: Variant::Dynafilt,
        max_frames: Some(30),
        ..limot::run::RunOptions::default()
    };
    let output = limot::run::run(&source, &dir, &options, None).unwrap();
    let (scores, results) = limot::experiments::score_run(
        &dir,
        0,
        &output,
        &dir.join("kitti_results"),
        &Default::default(),
    )
    .unwrap();
    assert!(scores.tracks.is_none());
    // 30 frames, all estimated; frame 0's sweep starts before the first OXTS record.
    assert_eq!(scores.ego.poses, 29);
    assert!(results.is_file());
}
