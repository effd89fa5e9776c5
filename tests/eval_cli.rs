//! `limot eval` on a short simulated dataset: ego trajectories written as
//! TUM / KITTI pose files and the KITTI copy's labels used as tracker results.

use limot::experiments::EvaluateError;
use limot::experiments::{EgoEvalOptions, evaluate_ego, load_truth};
use limot::experiments::{GtFilter, TrackEvalOptions, ego_pose_at, evaluate_tracks};
use limot::io::kitti::poses::{StampedPose, write_kitti_poses, write_tum};
use limot::metrics::AlignMode;
use limot::metrics::IouKind;
use limot::simulate::{resolve_scenario, simulate};
use limot_sim::record::Dataset;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

mod common;

/// A 3 s urban dataset (with its KITTI copy), simulated once per test binary.
fn dataset() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let mut spec = resolve_scenario("urban").unwrap();
        spec.duration_s = 3.0;
        // under target/ (replaced by the next run) rather than leaked into /tmp
        let dir = common::process_dir().join("eval-cli-urban-3s");
        let _ = fs::remove_dir_all(&dir);
        let summary = simulate(&spec, &dir, true, false).unwrap();
        assert_eq!(summary.frames, 30);
        dir
    })
}

fn scratch(name: &str) -> PathBuf {
    dataset().join("scratch").join(name)
}

fn write(path: &Path, text: &str) -> PathBuf {
    fs::create_dir_all(path.parent().unwrap()).unwrap();
    fs::write(path, text).unwrap();
    path.to_path_buf()
}

fn ego_truth() -> Vec<(f64, Isometry3<f64>)> {
    Dataset::open(dataset())
        .unwrap()
        .ego_truth()
        .unwrap()
        .iter()
        .map(|e| (e.t_s, e.t_world_lidar))
        .collect()
}

fn tum(poses: &[(f64, Isometry3<f64>)]) -> String {
    let stamped: Vec<StampedPose> = poses
        .iter()
        .map(|&(t_s, pose)| StampedPose { t_s, pose })
        .collect();
    write_tum(&stamped)
}

#[test]
fn ground_truth_as_estimate_has_zero_ate() {
    let dir = dataset();
    let truth = ego_truth();
    let opts = EgoEvalOptions::default();

    // TUM at the IMU rate: every sample associates with itself.
    let tum_path = write(&scratch("truth_tum.txt"), &tum(&truth));
    let r = evaluate_ego(dir, &tum_path, &opts).unwrap();
    assert_eq!(r.ate.n, truth.len());
    assert!(r.ate.ate_t_rmse_m < 1e-9, "{}", r.ate.ate_t_rmse_m);
    assert!(r.ate.ate_r_rmse_rad < 1e-9, "{}", r.ate.ate_r_rmse_rad);
    let rpe = r.rpe.unwrap();
    assert!(rpe.trans_rmse_m < 1e-9 && rpe.rot_rmse_rad < 1e-9);

    // KITTI poses at the sweep starts, times taken from the dataset's frames.
    let ds = Dataset::open(dir).unwrap();
    let ego = ds.ego_truth().unwrap();
    let ego_path = dir.join("gt/ego.csv");
    let sweep_poses: Vec<Isometry3<f64>> = (0..ds.frame_count())
        .map(|i| ego_pose_at(&ego, i as f64 * ds.meta.sweep_duration_s, &ego_path).unwrap())
        .collect();
    let kitti_path = write(
        &scratch("truth_kitti.txt"),
        &write_kitti_poses(&sweep_poses),
    );
    let r = evaluate_ego(dir, &kitti_path, &opts).unwrap();
    assert_eq!(r.ate.n, 30);
    assert!(r.ate.ate_t_rmse_m < 1e-9, "{}", r.ate.ate_t_rmse_m);
    assert!(r.ate.ate_r_rmse_rad < 1e-9, "{}", r.ate.ate_r_rmse_rad);

    // The KITTI copy as truth (OXTS → IMU poses, Tr_imu_velo → LiDAR poses)
    // agrees with the copy's own ground-truth poses/0000.txt.
    let kitti_dir = dir.join("kitti");
    let r = evaluate_ego(&kitti_dir, &kitti_dir.join("poses/0000.txt"), &opts).unwrap();
    assert_eq!(r.ate.n, 30);
    assert!(r.ate.ate_t_rmse_m < 1e-6, "{}", r.ate.ate_t_rmse_m);
    assert!(r.ate.ate_r_rmse_rad < 1e-9, "{}", r.ate.ate_r_rmse_rad);
    let t = load_truth(&kitti_dir, &opts).unwrap();
    assert_eq!(t.poses.len(), 30);
    assert_eq!(t.poses[0].1, Isometry3::identity() * t.poses[0].1);
}

#[test]
fn rigid_offset_is_removed_by_alignment() {
    let truth = ego_truth();
    let offset = Isometry3::from_parts(
        Translation3::new(120.0, -35.0, 4.0),
        UnitQuaternion::from_euler_angles(0.02, -0.03, 1.1),
    );
    let est: Vec<_> = truth.iter().map(|(t, p)| (*t, offset * p)).collect();
    let path = write(&scratch("offset_tum.txt"), &tum(&est));
    let r = evaluate_ego(dataset(), &path, &EgoEvalOptions::default()).unwrap();
    assert!(r.ate.ate_t_rmse_m < 1e-9, "{}", r.ate.ate_t_rmse_m);
    assert!(r.ate.ate_r_rmse_rad < 1e-9, "{}", r.ate.ate_r_rmse_rad);
    let raw = EgoEvalOptions {
        align: AlignMode::None,
        ..EgoEvalOptions::default()
    };
    let r = evaluate_ego(dataset(), &path, &raw).unwrap();
    assert!(r.ate.ate_t_rmse_m > 100.0, "{}", r.ate.ate_t_rmse_m);
}

#[test]
fn known_drift_gives_the_expected_errors() {
    let truth = ego_truth();
    let n = truth.len() as f64;
    let raw = EgoEvalOptions {
        align: AlignMode::None,
        ..EgoEvalOptions::default()
    };
    // est_i = Trans(v·t_i) · T_i · Rz(ω·t_i): position drift v, heading drift ω
    // (the right factor leaves the positions alone).
    let v = Vector3::new(0.03, -0.04, 0.0); // 0.05 m/s
    let omega = 0.01; // rad/s
    let drifted = |with_turn: bool| -> Vec<(f64, Isometry3<f64>)> {
        truth
            .iter()
            .map(|(t, p)| {
                let shift =
                    Isometry3::from_parts(Translation3::from(v * *t), UnitQuaternion::identity());
                let yaw = if with_turn { omega * t } else { 0.0 };
                let turn = Isometry3::from_parts(
                    Translation3::identity(),
                    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
                );
                (*t, shift * p * turn)
            })
            .collect()
    };
    let path = write(&scratch("drift_tum.txt"), &tum(&drifted(true)));
    let r = evaluate_ego(dataset(), &path, &raw).unwrap();
    let expected_t = (truth
        .iter()
        .map(|(t, _)| (v * *t).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    let expected_r = (truth.iter().map(|(t, _)| (omega * t).powi(2)).sum::<f64>() / n).sqrt();
    assert!(
        (r.ate.ate_t_rmse_m - expected_t).abs() < 1e-9,
        "{} vs {expected_t}",
        r.ate.ate_t_rmse_m
    );
    assert!(
        (r.ate.ate_r_rmse_rad - expected_r).abs() < 1e-9,
        "{} vs {expected_r}",
        r.ate.ate_r_rmse_rad
    );
    // SE(3) alignment can only reduce the translation error, not remove a drift.
    let aligned = evaluate_ego(dataset(), &path, &EgoEvalOptions::default()).unwrap();
    assert!(aligned.ate.ate_t_rmse_m <= expected_t + 1e-12);
    assert!(
        aligned.ate.ate_t_rmse_m > 0.1 * expected_t,
        "{}",
        aligned.ate.ate_t_rmse_m
    );

    // One-frame RPE of the position drift alone: E_ij = T_j⁻¹·Trans(v·Δt)·T_j,
    // so every pair's translation error is |v|·Δt and its rotation error 0.
    let path = write(&scratch("shift_tum.txt"), &tum(&drifted(false)));
    let r = evaluate_ego(dataset(), &path, &raw).unwrap();
    let steps: Vec<f64> = truth.windows(2).map(|w| w[1].0 - w[0].0).collect();
    let m = steps.len() as f64;
    let rpe_t = (steps.iter().map(|dt| (v.norm() * dt).powi(2)).sum::<f64>() / m).sqrt();
    let rpe = r.rpe.unwrap();
    assert_eq!(rpe.n_pairs, steps.len());
    assert!(
        (rpe.trans_rmse_m - rpe_t).abs() < 1e-9,
        "{} vs {rpe_t}",
        rpe.trans_rmse_m
    );
    assert!(rpe.rot_rmse_rad < 1e-9, "{}", rpe.rot_rmse_rad);
}

#[test]
fn bad_inputs_name_file_and_line_or_the_time_ranges() {
    let dir = dataset();
    let truth = ego_truth();
    let mut text = tum(&truth[..5]);
    text.push_str("0.5 1 2 x 0 0 0 1\n");
    let bad = write(&scratch("bad_tum.txt"), &text);
    let err = evaluate_ego(dir, &bad, &EgoEvalOptions::default()).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("bad_tum.txt:6") && msg.contains("`z`"),
        "{msg}"
    );

    let late: Vec<_> = truth.iter().map(|(t, p)| (t + 1000.0, *p)).collect();
    let late_path = write(&scratch("late_tum.txt"), &tum(&late));
    let err = evaluate_ego(dir, &late_path, &EgoEvalOptions::default()).unwrap_err();
    assert!(
        matches!(err, EvaluateError::NoOverlap { pairs: 0, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("do not overlap"), "{err}");

    // A KITTI estimate whose length matches no frame list needs --times.
    let few = write(
        &scratch("few_kitti.txt"),
        &write_kitti_poses(&[Isometry3::identity(); 3]),
    );
    let msg = evaluate_ego(dir, &few, &EgoEvalOptions::default())
        .unwrap_err()
        .to_string();
    assert!(msg.contains("--times"), "{msg}");

    // Tracking results: a frame beyond the dataset names the line.
    let labels = fs::read_to_string(dir.join("kitti/label_02/0000.txt")).unwrap();
    let first = labels.lines().next().unwrap();
    let mut tokens: Vec<&str> = first.split_whitespace().collect();
    tokens[0] = "30";
    let bad_results = write(
        &scratch("bad_results.txt"),
        &format!("{first}\n{}\n", tokens.join(" ")),
    );
    let msg = evaluate_tracks(dir, &bad_results, &TrackEvalOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("bad_results.txt:2") && msg.contains("frame"),
        "{msg}"
    );
}

#[test]
fn kitti_labels_as_results_track_perfectly() {
    let dir = dataset();
    let labels_path = dir.join("kitti/label_02/0000.txt");
    let r = evaluate_tracks(dir, &labels_path, &TrackEvalOptions::default()).unwrap();
    assert_eq!(r.frames, 30);
    assert_eq!(r.scores.len(), 4);
    for s in &r.scores {
        let m = &s.all;
        assert!(m.gt_count > 0);
        assert_eq!(
            (m.false_positives, m.false_negatives, m.id_switches),
            (0, 0, 0),
            "{:?} {}",
            s.iou_kind,
            s.iou_threshold
        );
        assert_eq!(m.mota, Some(1.0));
        // boxes pitch and roll on their suspensions and KITTI labels carry
        // the heading only: the round trip keeps all but ~1e-4 of the overlap
        assert!(m.motp.unwrap() > 0.999, "{:?}", m.motp);
    }
    assert!(!r.objects.is_empty());
    for o in &r.objects {
        assert_eq!(o.tp_percent, 100.0, "object {}", o.gt_id);
        // Centres survive the camera-frame round trip exactly; the heading
        // keeps a ~1e-4 rad error because the copy drops the box's roll and
        // pitch (its suspension's, in the tilted LiDAR frame).
        assert!(o.ate_t_rmse_m.unwrap() < 1e-9, "{:?}", o.ate_t_rmse_m);
        assert!(o.ate_r_rmse_rad.unwrap() < 5e-4, "{:?}", o.ate_r_rmse_rad);
    }
    let markdown = r.to_markdown().unwrap();
    assert!(markdown.contains("MOTA [%]") && markdown.contains("ATE_T [m]"));

    // Against every ground-truth box, the objects outside the camera view are misses.
    let all = TrackEvalOptions {
        gt_filter: GtFilter::All,
        ..TrackEvalOptions::default()
    };
    let r_all = evaluate_tracks(dir, &labels_path, &all).unwrap();
    let m_all = r_all.score(IouKind::ThreeD, 0.5).unwrap();
    let m = r.score(IouKind::ThreeD, 0.5).unwrap();
    assert_eq!(m_all.false_positives, 0);
    assert_eq!(m_all.matches, m.matches);
    assert_eq!(m_all.false_negatives, m_all.gt_count - m.gt_count);
    assert!(m_all.false_negatives > 0, "every box is camera-visible?");

    // Dropping one object's lines from the results: exactly its boxes are missed.
    let text = fs::read_to_string(&labels_path).unwrap();
    let dropped_id = text
        .lines()
        .next()
        .unwrap()
        .split_whitespace()
        .nth(1)
        .unwrap();
    let kept: Vec<&str> = text
        .lines()
        .filter(|l| l.split_whitespace().nth(1) != Some(dropped_id))
        .collect();
    let dropped = text.lines().count() - kept.len();
    let partial = write(&scratch("partial_results.txt"), &(kept.join("\n") + "\n"));
    let r = evaluate_tracks(dir, &partial, &TrackEvalOptions::default()).unwrap();
    let m = r.score(IouKind::ThreeD, 0.25).unwrap();
    assert_eq!(m.false_negatives, dropped);
    let expected_mota = 1.0 - dropped as f64 / m.gt_count as f64;
    assert!((m.mota.unwrap() - expected_mota).abs() < 1e-12);
    let id: u64 = dropped_id.parse().unwrap();
    let o = r.objects.iter().find(|o| o.gt_id == id).unwrap();
    assert_eq!((o.tp_percent, o.track_id), (0.0, None));
}

/// Output into a pipe whose reader has gone (`| head -1`) ends the process
/// quietly, as for any Unix tool, instead of a panic.
#[test]
fn cli_ends_quietly_when_its_reader_goes_away() {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let out = Command::new(env!("CARGO_BIN_EXE_limot"))
        .args(["simulate", "urban", "--print", "--out"])
        .arg(scratch("cli_pipe"))
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(out.status.signal(), Some(libc::SIGPIPE), "{:?}", out.status);
    }
}

#[test]
fn cli_prints_ate_and_fails_with_file_and_line() {
    let dir = dataset();
    let truth = ego_truth();
    let good = write(&scratch("cli_tum.txt"), &tum(&truth));
    let json = scratch("cli_ate.json");
    let out = Command::new(env!("CARGO_BIN_EXE_limot"))
        .args(["eval", "ego", "--truth"])
        .arg(dir)
        .arg("--estimate")
        .arg(&good)
        .arg("--json")
        .arg(&json)
        .args(["--rpe-delta", "1m"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line = stdout
        .lines()
        .find(|l| l.starts_with("ATE_T RMSE"))
        .unwrap();
    assert!(line.contains("0.000000 m"), "{line}");
    assert!(stdout.contains("RPE_t [m] per 1 m"), "{stdout}");
    let json_text = fs::read_to_string(&json).unwrap();
    assert!(json_text.contains("\"t_rmse_m\": 0"), "{json_text}");

    let mut text = tum(&truth[..2]);
    text.push_str("0.2 1 2 3 0 0 0\n");
    let bad = write(&scratch("cli_bad.txt"), &text);
    let out = Command::new(env!("CARGO_BIN_EXE_limot"))
        .args(["eval", "ego", "--truth"])
        .arg(dir)
        .arg("--estimate")
        .arg(&bad)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("cli_bad.txt:3"), "{stderr}");

    let out = Command::new(env!("CARGO_BIN_EXE_limot"))
        .args(["eval", "tracks", "--truth"])
        .arg(dir)
        .arg("--results")
        .arg(dir.join("kitti/label_02/0000.txt"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("3D IoU >= 0.5: MOTA 100.00 %"), "{stdout}");
}
