//! Unit tests of `suite`.

use super::plots::{read_tracks_csv, thin};
use super::*;
use crate::experiments::{
    EgoMetrics, MotMetrics, ObjectMetricsRecord, RESULTS_FORMAT_VERSION, StageSamples,
    VariantResult,
};
use crate::experiments::{FilterEvaluation, KeptMovingCauses};

fn object(gt_id: u64, gt_frames: usize, tp_percent: f64, ate: Option<f64>) -> ObjectMetricsRecord {
    ObjectMetricsRecord {
        gt_id,
        class: "Car".into(),
        gt_frames,
        tracked_frames: (tp_percent / 100.0 * gt_frames as f64).round() as usize,
        tp_percent,
        track_id: ate.map(|_| gt_id + 100),
        ate_t_m: ate,
        ate_r_rad: ate.map(|a| a / 10.0),
    }
}

fn metrics(ate_t_m: f64, motp: f64, total_ms: &[f64]) -> VariantMetrics {
    VariantMetrics {
        frames_estimated: total_ms.len(),
        frames_before_init: 2,
        wall_time_s: 1.0,
        fps: total_ms.len() as f64,
        ego: EgoMetrics {
            ate_t_m,
            ate_r_rad: ate_t_m / 100.0,
            ate_max_m: 2.0 * ate_t_m,
            pairs: total_ms.len(),
            rpe_t_m: Some(0.01),
            rpe_r_rad: None,
            ate_along_m: None,
            degenerate_match_share: None,
        },
        clear_mot: ["3D", "BEV"]
            .into_iter()
            .flat_map(|kind| {
                [0.25, 0.5].map(|thr| MotMetrics {
                    iou_kind: kind.into(),
                    iou_threshold: thr,
                    counts: crate::metrics::MotSummary {
                        mota: Some(0.5),
                        motp: Some(motp + thr / 10.0),
                        id_switches: 1,
                        false_positives: 2,
                        false_negatives: 3,
                        matches: 10,
                        gt_count: 13,
                    },
                })
            })
            .collect(),
        clear_mot_car: Vec::new(),
        objects: vec![
            object(1, 30, 50.0, Some(0.3)),
            object(2, 40, 0.0, None),
            object(3, 10, 90.0, Some(0.2)),
            object(4, 50, 80.0, Some(0.1)), // parked: not in moving_objects
        ],
        timings: vec![
            StageSamples {
                stage: "features".into(),
                ms: total_ms.iter().map(|t| t / 2.0).collect(),
            },
            StageSamples {
                stage: "total".into(),
                ms: total_ms.to_vec(),
            },
        ],
        filtering: None,
    }
}

fn ok(variant: Variant, m: VariantMetrics) -> VariantResult {
    VariantResult {
        variant,
        run_dir: PathBuf::from("runs/x").join(variant.name()),
        metrics: Some(m),
        error: None,
    }
}

fn failed(variant: Variant) -> VariantResult {
    VariantResult {
        variant,
        run_dir: PathBuf::from("runs/x").join(variant.name()),
        metrics: None,
        error: Some("variant `limot` is not implemented yet".into()),
    }
}

fn sequence(name: &str, variants: Vec<VariantResult>) -> SequenceResult {
    SequenceResult {
        name: name.into(),
        family: "urban".into(),
        seed: 1,
        frames: 40,
        dataset_dir: PathBuf::from("data").join(name),
        path_length_m: Some(50.0),
        moving_objects: vec![1, 2, 3],
        error: None,
        variants,
        ablations: Vec::new(),
    }
}

fn results() -> SuiteResults {
    SuiteResults {
        format_version: RESULTS_FORMAT_VERSION,
        families: vec!["urban".into()],
        twins: None,
        seeds: vec![1, 2],
        duration_s: 4.0,
        variants: vec![Variant::Lio, Variant::Dynafilt, Variant::Limot],
        ablations: Vec::new(),
        shard: None,
        sequences: vec![
            sequence(
                "urban_s1",
                vec![
                    ok(Variant::Lio, metrics(0.2, 0.6, &[10.0, 20.0])),
                    ok(Variant::Dynafilt, metrics(0.1, 0.7, &[30.0])),
                    failed(Variant::Limot),
                ],
            ),
            sequence(
                "urban_s2",
                vec![
                    ok(Variant::Lio, metrics(0.4, 0.8, &[30.0])),
                    ok(Variant::Dynafilt, metrics(0.5, 0.7, &[40.0])),
                    failed(Variant::Limot),
                ],
            ),
        ],
    }
}

fn cell(t: &Table, row: usize, header: &str) -> Cell {
    let col = t.header.iter().position(|h| h == header).unwrap();
    t.rows[row][col].clone()
}

#[test]
fn ego_table_has_a_column_pair_per_variant_with_figures_and_a_mean() {
    let t = ego_table(&results()).unwrap();
    assert_eq!(
        t.header,
        [
            "Seq",
            "LIO ATE_T [m]",
            "LIO ATE_R [rad]",
            "LIO-Dynafilt ATE_T [m]",
            "LIO-Dynafilt ATE_R [rad]"
        ]
    );
    assert_eq!(t.rows.len(), 3);
    assert_eq!(cell(&t, 2, "Seq"), Cell::Text("mean".into()));
    for (header, mean) in [("LIO ATE_T [m]", 0.3), ("LIO-Dynafilt ATE_T [m]", 0.3)] {
        let Cell::Num(v) = cell(&t, 2, header) else {
            panic!("{header}: no mean")
        };
        assert!((v - mean).abs() < 1e-12, "{header}: {v}");
    }
    let md = t.to_markdown().unwrap();
    // best per row in bold: dynafilt on s1, lio on s2; ATE_R at 4 decimals
    assert!(md.contains("**0.100**") && md.contains("**0.400**"), "{md}");
    assert!(md.contains("**0.0010**"), "{md}");
}

#[test]
fn ego_error_split_table_splits_along_and_across_and_counts_degenerate_matches() {
    let mut r = results();
    let ego = &mut r.sequences[0].variants[1].metrics.as_mut().unwrap().ego;
    // ATE_T 0.1 m: 0.08 along, so 0.06 across
    ego.ate_along_m = Some(0.08);
    ego.degenerate_match_share = Some(0.25);
    let t = ego_error_split_table(&r).unwrap();
    assert_eq!(
        t.rows.len(),
        4,
        "a row per sequence and variant with figures"
    );
    assert_eq!(cell(&t, 1, "Variant"), Cell::Text("LIO-Dynafilt".into()));
    let Cell::Num(across) = cell(&t, 1, "across [m]") else {
        panic!("no across")
    };
    assert!((across - 0.06).abs() < 1e-12, "{across}");
    assert_eq!(cell(&t, 1, "along the path [m]"), Cell::Num(0.08));
    assert_eq!(cell(&t, 1, "degenerate matches [%]"), Cell::Num(25.0));
    // results scored before the split was measured leave the cells empty
    assert_eq!(cell(&t, 0, "along the path [m]"), Cell::Missing);
    assert_eq!(cell(&t, 0, "across [m]"), Cell::Missing);
    assert_eq!(cell(&t, 0, "degenerate matches [%]"), Cell::Missing);
}

#[test]
fn motp_table_means_over_sequences_per_variant() {
    let t = motp_table(&results()).unwrap();
    assert_eq!(t.rows.len(), 2, "limot has no figures");
    // lio: (0.6 + 0.8) / 2 + 0.025 → 72.5 %; dynafilt 72.5 % too at 0.25
    let Cell::Num(lio) = cell(&t, 0, "MOTP [%] (IoU 0.25)") else {
        panic!()
    };
    assert!((lio - 72.5).abs() < 1e-9, "{lio}");
    let Cell::Num(dyn_05) = cell(&t, 1, "MOTP [%] (IoU 0.5)") else {
        panic!()
    };
    assert!((dyn_05 - 75.0).abs() < 1e-9, "{dyn_05}");
}

#[test]
fn filtering_table_scores_the_variants_that_filter() {
    let mut r = results();
    let m = r.sequences[0].variants[1].metrics.as_mut().unwrap();
    // 100 features: 20 on moving objects (15 removed), 30 on static
    // objects (3 removed), 2 removed on the static scene.
    m.filtering = Some(FilterEvaluation {
        features: 100,
        removed: 20,
        moving_features: 20,
        removed_moving: 15,
        static_object_features: 30,
        removed_static_object: 3,
        parked_features: 20,
        removed_parked: 1,
        parked_edge_features: 2,
        removed_parked_edges: 1,
        kept_moving_causes: Some(KeptMovingCauses {
            untracked: 2,
            tentative_static: 1,
            confirmed_static: 0,
            dynamic_outside_box: 2,
        }),
    });
    let t = filtering_table(&r).unwrap();
    assert_eq!(t.rows.len(), 1, "only dynafilt on urban_s1 has figures");
    let num = |h| match cell(&t, 0, h) {
        Cell::Num(x) => x,
        c => panic!("{c:?}"),
    };
    assert!((num("precision [%]") - 75.0).abs() < 1e-9);
    assert!((num("recall [%]") - 75.0).abs() < 1e-9);
    assert!((num("static-object features removed [%]") - 10.0).abs() < 1e-9);
    // the 5 kept moving features by cause, as shares of the 20
    assert!((num("kept moving: untracked [%]") - 10.0).abs() < 1e-9);
    assert!((num("tentative static [%]") - 5.0).abs() < 1e-9);
    assert!((num("confirmed static [%]") - 0.0).abs() < 1e-9);
    assert!((num("dynamic, outside box [%]") - 10.0).abs() < 1e-9);
    let md = t.to_markdown().unwrap();
    assert!(md.contains("urban_s1"), "{md}");
}

#[test]
fn object_table_lists_the_longest_seen_moving_objects() {
    let t = objects_table(&results()).unwrap();
    let labels: Vec<Cell> = t.rows.iter().map(|r| r[0].clone()).collect();
    // object 4 is parked; the others by gt_frames (40, 30, 10)
    let expected: Vec<Cell> = [
        "urban_s1 / 2",
        "urban_s1 / 1",
        "urban_s1 / 3",
        "urban_s2 / 2",
        "urban_s2 / 1",
        "urban_s2 / 3",
        "mean",
    ]
    .map(|s| Cell::Text(s.into()))
    .to_vec();
    assert_eq!(labels, expected);
    assert_eq!(cell(&t, 0, "LIO ATE_T [m]"), Cell::Missing);
    assert_eq!(cell(&t, 1, "LIO TP [%]"), Cell::Num(50.0));
}

#[test]
fn timing_pools_every_frame_of_every_sequence() {
    let r = results();
    let t = timing_table_of(&r, Variant::Lio).unwrap().unwrap();
    assert_eq!(t.rows.len(), 2);
    assert_eq!(t.rows[1][0], Cell::Text("total".into()));
    // (10 + 20 + 30) / 3 = 20 ms → 50 FPS
    let Cell::Num(mean) = t.rows[1][1] else {
        panic!()
    };
    let Cell::Num(fps) = t.rows[1][3] else {
        panic!()
    };
    assert!(
        (mean - 20.0).abs() < 1e-6 && (fps - 50.0).abs() < 1e-3,
        "{mean} {fps}"
    );
    assert!(timing_table_of(&r, Variant::Limot).unwrap().is_none());
}

#[test]
fn failed_runs_show_as_not_available() {
    let r = results();
    let t = runs_table(&r).unwrap();
    assert_eq!(t.rows.len(), 6);
    assert_eq!(cell(&t, 2, "status"), Cell::Text("not available".into()));
    assert_eq!(cell(&t, 2, "RPE_T [m]"), Cell::Missing);
    assert_eq!(cell(&t, 0, "status"), Cell::Text("ok".into()));
    let f = failures(&r);
    assert_eq!(f.len(), 2);
    assert!(f[0].contains("urban_s1 / LIMOT: not available: variant `limot`"));
}

#[test]
fn report_without_run_files_notes_the_missing_plots() {
    let dir = Path::new("/nonexistent/limot-suite");
    let report = build_report(&results(), dir).unwrap();
    let seq = report
        .sections
        .iter()
        .find(|s| s.heading == "Sequence urban_s1")
        .unwrap();
    assert!(seq.plots.is_empty());
    assert!(seq.text.contains("ego plots left out"), "{}", seq.text);
    assert!(report.sections.iter().any(|s| s.heading == "Failures"));
}

#[test]
fn tracks_csv_is_read_by_header_and_errors_name_line_and_field() {
    let dir = std::env::temp_dir().join(format!("limot-suite-report-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("tracks.csv");
    std::fs::write(
        &path,
        "frame,t_s,id,class,x,y,z,yaw_rad,l,w,h,vx,vy,vz,lifecycle,motion,predicted\n\
         3,0.3,7,Car,1,2,3,0.1,4,2,1.5,5,0,0,Confirmed,Dynamic,false\n",
    )
    .unwrap();
    let rows = read_tracks_csv(&path).unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!((rows[0].frame, rows[0].id), (3, 7));
    assert_eq!(rows[0].center_world, Vector3::new(1.0, 2.0, 3.0));
    assert_eq!(rows[0].velocity_world_mps.x, 5.0);
    std::fs::write(
        &path,
        "frame,t_s,id,x,y,z,vx,vy,vz\n1,0.1,2,1,2,3,0,0,0\n1,0.1,2,1,nan,3,0,0,0\n",
    )
    .unwrap();
    let e = read_tracks_csv(&path).unwrap_err().to_string();
    assert!(e.contains("line 3") && e.contains("`y`"), "{e}");
    std::fs::write(&path, "frame,t_s,x\n").unwrap();
    let e = read_tracks_csv(&path).unwrap_err().to_string();
    assert!(e.contains("line 1") && e.contains("`id`"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn thinning_keeps_first_and_last_and_bounds_the_count() {
    let pts: Vec<usize> = (0..1001).collect();
    let t = thin(&pts, 100);
    assert!(t.len() <= 100, "{}", t.len());
    assert_eq!((t[0], *t.last().unwrap()), (0, 1000));
    assert_eq!(thin(&pts[..5], 100), pts[..5].to_vec());
}

/// `results()` with limot scored and the `joint` ablation beside it (failed on s2).
fn results_with_ablation() -> SuiteResults {
    let mut r = results();
    r.ablations = vec![Ablation::Joint];
    for (i, s) in r.sequences.iter_mut().enumerate() {
        s.variants[2] = ok(Variant::Limot, metrics(0.2 + 0.1 * i as f64, 0.8, &[10.0]));
        s.ablations.push(crate::experiments::AblationResult {
            ablation: Ablation::Joint,
            run_dir: PathBuf::from("runs/x/limot-joint"),
            metrics: (i == 0).then(|| metrics(0.25, 0.8, &[10.0])),
            error: (i == 1).then(|| "diverged".to_string()),
        });
    }
    r
}

#[test]
fn ablation_rows_sit_beside_their_variant() {
    assert!(ablation_table(&results()).unwrap().is_none(), "no ablation");
    let r = results_with_ablation();
    let t = ablation_table(&r).unwrap().unwrap();
    let runs: Vec<Cell> = t.rows.iter().map(|row| row[1].clone()).collect();
    let (limot, joint) = (Cell::from("LIMOT"), Cell::from("LIMOT (joint)"));
    assert_eq!(
        runs,
        [&limot, &joint, &limot, &joint, &limot, &joint].map(Clone::clone)
    );
    assert_eq!(cell(&t, 0, "ATE_T [m]"), Cell::Num(0.2));
    assert_eq!(cell(&t, 1, "ATE_T [m]"), Cell::Num(0.25));
    assert_eq!(cell(&t, 3, "ATE_T [m]"), Cell::Missing, "failed on s2");
    // means: limot over both sequences, joint has none (one failed)
    assert_eq!(cell(&t, 4, "Seq"), Cell::from("mean"));
    let Cell::Num(mean) = cell(&t, 4, "ATE_T [m]") else {
        panic!("no mean")
    };
    assert!((mean - 0.25).abs() < 1e-12, "{mean}");
    assert_eq!(cell(&t, 5, "ATE_T [m]"), Cell::Missing);
    // moving objects 1..3 of the table: TP (50 + 0 + 90) / 3, ATE (0.3 + 0.2) / 2
    let Cell::Num(tp) = cell(&t, 0, "moving objects TP [%]") else {
        panic!()
    };
    assert!((tp - 140.0 / 3.0).abs() < 1e-9, "{tp}");
    assert_eq!(cell(&t, 0, "moving objects ATE_T [m]"), Cell::Num(0.25));
    let md = t.to_markdown().unwrap();
    assert!(md.contains("**0.200**"), "limot better on s1:\n{md}");

    let report = build_report(&r, Path::new("/nonexistent/limot-suite")).unwrap();
    let section = report
        .sections
        .iter()
        .find(|s| s.heading.starts_with("Ablation"))
        .unwrap();
    assert!(section.text.contains("dynamic_objects_inform_ego = true"));
    assert!(report.sections[0].text.contains("--ablation joint"));
    let runs = runs_table(&r).unwrap();
    assert_eq!(runs.rows.len(), 8, "3 variants + 1 ablation per sequence");
    assert!(
        failures(&r)
            .iter()
            .any(|f| f == "- urban_s2 / LIMOT (joint): not available: diverged")
    );
}
