//! `limot demo` end to end on a shortened default scenario.

use limot::demo::run_demo;
use limot::simulate::resolve_scenario;
use std::fs;

#[test]
fn demo_simulates_scores_and_writes_a_report() {
    let mut spec = resolve_scenario("urban").unwrap();
    spec.duration_s = 3.0;
    let out = std::env::temp_dir().join(format!("limot-demo-{}", std::process::id()));
    let _ = fs::remove_dir_all(&out);
    let mcap = out.join("limot.mcap");
    let request = limot::io::mcap::McapRequest {
        path: mcap.clone(),
        max_cloud_points: Some(25_000),
    };
    let s = run_demo(&spec, &out, false, Some(&request)).unwrap();
    // the `limot` run's Foxglove recording, whole (tests/mcap.rs reads one in detail)
    let stats = s.mcap.as_ref().unwrap();
    assert_eq!(stats.path, mcap);
    assert_eq!(std::fs::metadata(&mcap).unwrap().len(), stats.bytes);
    assert!(stats.messages >= 30 * 7, "{} messages", stats.messages);
    assert_eq!(s.frames, 30);
    assert!(
        s.mean_points_per_scan > 50_000.0,
        "{}",
        s.mean_points_per_scan
    );
    assert!(s.moving_agents > 0 && s.parked_agents > 0);
    // the ego waits ~1 s, then pulls away
    assert!(s.ego_path_length_m > 0.5 && s.ego_path_length_m < 40.0);
    for (threshold, r) in &s.detector {
        let mota = r.mota.unwrap();
        // the detector is good but imperfect: misses, false positives, box noise
        assert!(mota > 0.3 && mota < 1.0, "MOTA {mota} at {threshold}");
        assert!(r.false_negatives > 0);
        assert_eq!(r.id_switches, 0, "oracle ids cannot switch");
    }
    // lio and limot ran on the dataset and follow the truth
    let names: Vec<&str> = s.estimators.iter().map(|e| e.variant).collect();
    assert_eq!(names, ["lio", "limot"]);
    for e in &s.estimators {
        assert_eq!(e.frames_estimated, 30, "one estimate per frame");
        assert!(e.frames_before_init <= 10, "{}", e.frames_before_init);
        assert!(e.ate_t_m < 0.1, "{} ATE_T {} m", e.variant, e.ate_t_m);
        assert!(e.trajectory.is_file());
        assert!(e.tracks[0].mota.is_some(), "{}: tracks scored", e.variant);
        // per-pose errors for the plots: one per estimate, the ATE's RMSE
        let t = &e.errors.translation_m.points;
        assert_eq!(t.len(), 30);
        assert_eq!(e.errors.rotation_deg.points.len(), 30);
        assert_eq!(e.errors.path.points.len(), 30);
        let rmse = (t.iter().map(|p| p.1 * p.1).sum::<f64>() / t.len() as f64).sqrt();
        assert!((rmse - e.ate_t_m).abs() < 1e-9, "{rmse} vs {}", e.ate_t_m);
    }
    // like with like: the detector and every variant's tracks on the same truth boxes
    for (k, (threshold, det)) in s.detector.iter().enumerate() {
        assert!(det.gt_count > 0);
        for e in &s.estimators {
            assert_eq!(
                e.tracks[k].gt_count, det.gt_count,
                "{} at {threshold}",
                e.variant
            );
        }
    }
    // every error of the tracks has one cause; the ceiling's FN are the detector misses
    let ceiling = &s.detector[0].1;
    for e in &s.estimators {
        let l = &e.loss;
        assert_eq!(l.tracks, e.tracks[0]);
        assert_eq!(
            l.fn_causes.total(),
            l.tracks.false_negatives,
            "{}",
            e.variant
        );
        assert_eq!(
            l.fp_causes.total(),
            l.tracks.false_positives,
            "{}",
            e.variant
        );
        assert_eq!(
            l.fn_causes.detector_miss + l.recovered_misses,
            ceiling.false_negatives
        );
        assert_eq!(l.fp_causes.unknown, 0, "every written box is a live track");
        // a 3 s drive is inside the first tracks' confirmation delay
        assert!(l.fn_causes.unconfirmed_first > 0, "{:?}", l.fn_causes);
    }
    let readme = fs::read_to_string(&s.report_readme).unwrap();
    for needle in [
        "MOTA %",
        "truth boxes",
        "Where the tracks lose against the detector",
        "ego_translation_error.svg",
        "ego_rotation_error.svg",
        "ego_error_path_limot.svg",
        "ATE_T [m]",
        "| limot ",
        "ego_trajectory.svg",
        "ego_speed.svg",
        "objects.svg",
    ] {
        assert!(readme.contains(needle), "report lacks {needle}");
    }
    for svg in [
        "ego_trajectory.svg",
        "ego_speed.svg",
        "objects.svg",
        "ego_translation_error.svg",
        "ego_rotation_error.svg",
        "ego_error_path_lio.svg",
        "ego_error_path_limot.svg",
    ] {
        let text = fs::read_to_string(out.join("report").join(svg)).unwrap();
        assert!(text.starts_with("<svg"), "{svg}");
    }
    let _ = fs::remove_dir_all(&out);
}
