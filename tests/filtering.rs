//! Dynamic feature filtering on a generated urban drive, scored against the
//! simulator's per-point instance labels: `dynafilt` removes the features on
//! moving objects (faster than 1 m/s) and keeps the parked cars' planar
//! features (their edges go: `EstimatorConfig::filter_static_edges`);
//! `allfilt` removes both, and is no more accurate for it.

mod common;

use limot::experiments::evaluate_filtering;
use limot::io::Source;
use limot::run::{RunOptions, run};
use limot::simulate::resolve_scenario;
use limot_estimator::Variant;
use limot_estimator::pipeline::EstimatorConfig;
use limot_sim::Simulation;
use limot_sim::record::Dataset;
use limot_sim::scenario::EgoRoute;
use std::path::Path;

#[test]
fn dynafilt_removes_moving_features_and_keeps_parked_cars() {
    // the straight main-street route (inner lane) the figures below were
    // measured on
    let mut spec = resolve_scenario("urban").unwrap();
    spec.duration_s = 30.0;
    spec.urban.as_mut().unwrap().ego_route = EgoRoute::Straight;
    spec.ego.lane = 1;
    let dir = std::env::temp_dir().join(format!("limot-filtering-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    Simulation::new(&spec)
        .unwrap()
        .write_dataset(&dir, |_, _| {})
        .unwrap();
    let dataset = Dataset::open(&dir).unwrap();
    let source = Source::open(&dir).unwrap();
    let config = EstimatorConfig {
        record_feature_indices: true,
        ..EstimatorConfig::default()
    };
    let mut results = Vec::new();
    for variant in [Variant::Dynafilt, Variant::Allfilt] {
        let options = RunOptions {
            variant,
            ..RunOptions::default()
        };
        let output = run(&source, Path::new(&dir), &options, Some(config.clone())).unwrap();
        let (ate_t, _) = common::ate(&dir, &output);
        let c = evaluate_filtering(&dataset, &output)
            .unwrap()
            .expect("features recorded");
        if variant == Variant::Dynafilt {
            // The tracks, as KITTI tracking results, scored against the truth.
            let (calib, _) = limot::experiments::dataset_calib(&dataset, 0).unwrap();
            let results =
                limot::run::write_dataset_kitti_tracks(&dir.join("kitti_results"), &output, &calib)
                    .unwrap();
            // Each result line carries its frame's detection score.
            let lines = limot::io::kitti::labels::read_labels(&results).unwrap();
            assert!(lines.len() > 1000, "{}", lines.len());
            let scores: Vec<f64> = lines.iter().map(|l| l.score.unwrap()).collect();
            assert!(scores.iter().all(|s| (0.0..=1.0).contains(s)));
            assert!(
                scores.iter().any(|&s| s < 0.99),
                "scores all 1: not the detections'"
            );
            let e = limot::experiments::evaluate_tracks(
                &dir,
                &results,
                &limot::experiments::TrackEvalOptions::default(),
            )
            .unwrap();
            let s = &e.scores[0];
            let (mota, motp) = (s.all.mota.unwrap(), s.all.motp.unwrap());
            eprintln!(
                "tracks ({:?} IoU {}): MOTA {mota:.3}, MOTP {motp:.3}, IDSW {}, FP {}, FN {}",
                s.iou_kind,
                s.iou_threshold,
                s.all.id_switches,
                s.all.false_positives,
                s.all.false_negatives
            );
            // Measured (30 s): MOTA 0.55, MOTP 0.79 at 3D IoU 0.25 (confirmed, matched
            // tracks only; the misses are mostly objects the detector misses).
            assert!(mota > 0.45 && motp > 0.75, "MOTA {mota} MOTP {motp}");
        }
        // The kept moving features, each counted under exactly one cause
        // (trajectory-based filters only).
        match (variant, c.kept_moving_causes) {
            (Variant::Dynafilt, Some(causes)) => {
                assert_eq!(causes.total(), c.moving_features - c.removed_moving);
                eprintln!("dynafilt kept moving features by cause: {causes:?}");
            }
            (Variant::Allfilt, None) => {}
            (v, causes) => panic!("{v:?}: causes {causes:?}"),
        }
        let score = c.score();
        let object_precision =
            (c.removed_moving + c.removed_static_object) as f64 / c.removed.max(1) as f64;
        let moving_precision = score.precision.unwrap();
        let recall = score.recall.unwrap();
        let standing_removed = c.static_object_removed_fraction().unwrap();
        let parked_removed = c.parked_removed_fraction().unwrap();
        let parked_edges = c.parked_edge_removed_fraction().unwrap();
        let parked_planar = c.parked_planar_removed_fraction().unwrap();
        eprintln!(
            "{}: ATE_T {ate_t:.4} m; {c:?}; moving precision {moving_precision:.3} (object precision {object_precision:.3}), recall {recall:.3}, standing features removed {standing_removed:.3}, parked {parked_removed:.3} (edges {parked_edges:.3}, planar {parked_planar:.3})",
            variant.name()
        );
        results.push((
            ate_t,
            object_precision,
            recall,
            parked_removed,
            parked_edges,
            parked_planar,
        ));
    }
    // Measured (seed 2, 30 s, 2026-12-08): dynafilt recall 0.996, 0.947 of
    // what it removes lies on objects; of the parked cars' features it
    // removes 3.2 % of the planar ones and 94 % of the edges (3.6 % of their
    // features). The cars standing at the lights after driving are filtered
    // as moving (`EstimatorConfig::filter_stopped_movers`), so against
    // "moving faster than 1 m/s at that frame" its precision is 0.53 and 56 %
    // of the standing objects' features go; allfilt recall 0.94, 94 % of the
    // standing objects' features removed.
    let (dynafilt_ate, object_precision, recall, _, parked_edges, parked_planar) = results[0];
    assert!(recall >= 0.9, "dynafilt recall {recall}");
    assert!(
        object_precision >= 0.9,
        "dynafilt removed {object_precision} on objects"
    );
    // The parked cars' edge features go (`EstimatorConfig::filter_static_edges`:
    // once a car's track is confirmed static), their planar ones stay.
    assert!(
        parked_edges > 0.8,
        "dynafilt removed {parked_edges} of the parked cars' edge features"
    );
    assert!(
        parked_planar < 0.05,
        "dynafilt removed {parked_planar} of the parked cars' planar features"
    );
    let (allfilt_ate, _, allfilt_recall, allfilt_parked, _, _) = results[1];
    // Keeping the parked cars' planar features costs no accuracy where
    // traffic moves (issue 17: dynafilt at least as good as allfilt).
    // Measured: dynafilt 0.0127 m, allfilt 0.0129 m.
    assert!(
        dynafilt_ate <= allfilt_ate + 0.001,
        "dynafilt ATE_T {dynafilt_ate} m, allfilt {allfilt_ate} m"
    );
    // This sweep's detections that no settled static track explains are
    // filtered too, so the trajectory-based filter misses no more moving
    // features than dropping every box does.
    assert!(
        recall >= allfilt_recall,
        "dynafilt recall {recall} below allfilt's {allfilt_recall}"
    );
    assert!(
        allfilt_parked > 0.8,
        "allfilt removed only {allfilt_parked} of the parked cars' features"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
