//! Unit tests of `table`.

use super::*;

#[test]
fn markdown_aligns_rounds_bolds_and_marks_missing() {
    let header = ["Seq", "A [m]", "B [m]", "n"].map(String::from).to_vec();
    let mut t = Table::new("ATE", header);
    t.set_decimals(2, 1);
    t.push_row(vec![
        "00".into(),
        Cell::Num(0.8456),
        Cell::Num(0.91),
        Cell::Int(12),
    ])
    .unwrap();
    t.push_row(vec![
        "01|x".into(),
        Cell::Missing,
        Cell::Num(-0.04),
        Cell::Int(3),
    ])
    .unwrap();
    t.push_row(vec![
        "02".into(),
        Cell::Num(1.2),
        Cell::Num(1.24),
        Cell::Int(3),
    ])
    .unwrap();
    t.bold = vec![
        BoldRule::BestInRow {
            columns: vec![1, 2],
            better: Better::Lower,
        },
        BoldRule::BestInColumn {
            column: 3,
            better: Better::Higher,
            group_by: vec![],
        },
    ];
    // Row 00: 0.846 < 0.9 → A bold. Row 01: one value only → no bold, and
    // -0.04 at one decimal prints "0.0" not "-0.0". Row 02: 1.200 and 1.2
    // print equal at their precision → an all-way tie, no bold. Column n:
    // 12 is best. Widths follow the widest cell including "**".
    let expected = "**ATE**\n\
                    \n\
                    | Seq   |     A [m] | B [m] |      n |\n\
                    | :---- | --------: | ----: | -----: |\n\
                    | 00    | **0.846** |   0.9 | **12** |\n\
                    | 01\\|x |         – |   0.0 |      3 |\n\
                    | 02    |     1.200 |   1.2 |      3 |\n";
    assert_eq!(t.to_markdown().unwrap(), expected);
}

#[test]
fn grouped_column_best_and_shape_errors() {
    let header = ["Seq", "Variant", "MOTA"].map(String::from).to_vec();
    let mut t = Table::new("", header);
    t.set_decimals(2, 1);
    for (seq, var, mota) in [
        ("a", "x", 50.0),
        ("a", "y", 60.0),
        ("b", "x", 70.0),
        ("b", "y", 65.0),
        ("b", "z", 70.04),
    ] {
        t.push_row(vec![seq.into(), var.into(), Cell::Num(mota)])
            .unwrap();
    }
    t.bold = vec![BoldRule::BestInColumn {
        column: 2,
        better: Better::Higher,
        group_by: vec![0],
    }];
    let md = t.to_markdown().unwrap();
    // No title line when the title is empty; best per sequence, not
    // overall; 70.04 prints as 70.0 and ties with 70.0 (both bold).
    assert!(md.starts_with("| Seq |"), "{md}");
    assert!(md.contains("| a   | y       | **60.0** |"), "{md}");
    assert!(md.contains("| b   | x       | **70.0** |"), "{md}");
    assert!(md.contains("| b   | z       | **70.0** |"), "{md}");
    assert_eq!(md.matches("**").count(), 6, "{md}");

    let err = t.push_row(vec!["c".into()]).unwrap_err();
    assert!(
        matches!(
            err,
            ReportError::TableShape {
                row: 5,
                expected: 3,
                found: 1,
                ..
            }
        ),
        "{err:?}"
    );
    t.rows.push(vec![Cell::Missing]);
    assert!(matches!(
        t.to_markdown(),
        Err(ReportError::TableShape { row: 5, .. })
    ));
    t.rows.pop();
    t.bold.push(BoldRule::BestInRow {
        columns: vec![2, 7],
        better: Better::Lower,
    });
    assert!(matches!(
        t.to_markdown(),
        Err(ReportError::TableColumn { column: 7, .. })
    ));
}

#[test]
fn non_finite_numbers_stay_visible_and_never_bold() {
    assert_eq!(format_fixed(f64::NAN, 3), "NaN");
    assert_eq!(format_fixed(f64::NEG_INFINITY, 1), "-inf");
    assert_eq!(format_fixed(-0.0004, 3), "0.000");
    assert_eq!(format_fixed(-0.0006, 3), "-0.001");
    let mut t = Table::new("", vec!["a".into(), "b".into()]);
    t.push_row(vec![Cell::Num(f64::NAN), Cell::Num(1.0)])
        .unwrap();
    t.bold = vec![BoldRule::BestInRow {
        columns: vec![0, 1],
        better: Better::Lower,
    }];
    let md = t.to_markdown().unwrap();
    assert!(md.contains("| NaN | 1.000 |"), "{md}");
}

fn ego(t: f64, r: f64) -> EgoAte {
    EgoAte {
        ate_t_m: t,
        ate_r_rad: r,
    }
}

#[test]
fn ego_ate_table_has_paper_shape_and_mean_row() {
    let rows = vec![
        EgoAteRow {
            sequence: "00".into(),
            per_variant: [
                (Variant::Limot, ego(0.846, 0.024)),
                (Variant::Lio, ego(0.856, 0.020)),
            ]
            .into(),
        },
        EgoAteRow {
            sequence: "01".into(),
            per_variant: [
                (Variant::Limot, ego(1.681, 0.045)),
                (Variant::Lio, ego(1.683, 0.044)),
            ]
            .into(),
        },
        EgoAteRow {
            sequence: "02".into(),
            per_variant: [
                (Variant::Dynafilt, ego(0.25, 0.011)),
                (Variant::Lio, ego(0.3, 0.010)),
                (Variant::Limot, ego(0.2, 0.012)),
            ]
            .into(),
        },
    ];
    let t = ego_ate_table("Ego ATE", &rows).unwrap();
    // Variants in enum order regardless of insertion order.
    assert_eq!(
        t.header,
        [
            "Seq",
            "LIO ATE_T [m]",
            "LIO ATE_R [rad]",
            "LIO-Dynafilt ATE_T [m]",
            "LIO-Dynafilt ATE_R [rad]",
            "LIMOT ATE_T [m]",
            "LIMOT ATE_R [rad]"
        ]
    );
    assert_eq!(t.rows.len(), 4);
    let mean = &t.rows[3];
    assert_eq!(mean[0], Cell::Text("mean".into()));
    // LIO-Dynafilt misses two sequences: its mean is missing, not partial.
    assert_eq!(mean[3], Cell::Missing);
    let Cell::Num(lio_mean_t) = mean[1] else {
        panic!("{:?}", mean[1])
    };
    assert!((lio_mean_t - (0.856 + 1.683 + 0.3) / 3.0).abs() < 1e-12);
    let md = t.to_markdown().unwrap();
    let cells_of = |prefix: &str| -> Vec<String> {
        let line = md.lines().find(|l| l.starts_with(prefix)).unwrap();
        line.split('|').map(|c| c.trim().to_string()).collect()
    };
    // Seq 00: LIMOT has the lower ATE_T, LIO the lower ATE_R; Dynafilt missing.
    assert_eq!(
        cells_of("| 00")[2..8],
        ["0.856", "**0.020**", "–", "–", "**0.846**", "0.024"]
    );
    // Mean row: LIO ATE_R 0.074/3 → 0.025, LIMOT ATE_T 2.727/3 → 0.909.
    assert_eq!(
        cells_of("| mean")[2..8],
        ["0.946", "**0.025**", "–", "–", "**0.909**", "0.027"]
    );
}

#[test]
fn tracking_object_and_timing_tables() {
    let tr = |variant, mota, idsw| TrackingRow {
        sequence: "0001".into(),
        variant,
        iou_threshold: 0.25,
        mota_percent: Some(mota),
        motp_percent: None,
        idsw,
        fp: 3,
        fn_: 4,
    };
    let t = tracking_table(
        "MOT",
        &[tr(Variant::Lio, 70.0, 5), tr(Variant::Limot, 80.0, 2)],
    )
    .unwrap();
    let md = t.to_markdown().unwrap();
    assert!(
        md.contains("| LIMOT   |    0.25 | **80.00** | –        | **2** |   3 |   4 |"),
        "{md}"
    );
    assert!(
        md.contains("| LIO     |    0.25 |     70.00 | –        |     5 |   3 |   4 |"),
        "{md}"
    );

    let m = |tp, t| ObjectMetrics {
        tp_percent: tp,
        ate_t_m: t,
        ate_r_rad: Some(0.1),
    };
    let rows = vec![ObjectRow {
        sequence: "04".into(),
        object_id: 2,
        per_variant: [
            (Variant::Lio, m(27.07, Some(0.7))),
            (Variant::Limot, m(27.07, None)),
            (Variant::Dynafilt, m(25.0, Some(0.8))),
        ]
        .into(),
    }];
    let t = object_table("Objects", &rows).unwrap();
    assert_eq!(t.header.len(), 10);
    let md = t.to_markdown().unwrap();
    let line = md.lines().find(|l| l.starts_with("| 04 / 2")).unwrap();
    // Equal best TP ties (both bold, Dynafilt's 25.00 not); a
    // never-matched object has no ATE, the best of the others is bold.
    assert_eq!(line.matches("**27.07**").count(), 2, "{line}");
    assert!(
        line.contains(" **0.700** ") && line.contains(" – "),
        "{line}"
    );
    // Every ATE_R is 0.1: an all-way tie has no best.
    assert!(!line.contains("**0.100**"), "{line}");

    let mut acc = TimingAccumulator::new();
    for ms in [10u64, 20, 30, 40] {
        acc.record("odometry", std::time::Duration::from_millis(ms));
    }
    let row = TimingRow::from_accumulator(&acc, "odometry").unwrap();
    assert!((row.mean_ms - 25.0).abs() < 1e-9 && (row.fps - 40.0).abs() < 1e-9);
    assert!((row.p95_ms - 38.5).abs() < 1e-9, "{}", row.p95_ms);
    assert!(TimingRow::from_accumulator(&acc, "nope").is_none());
    let md = timing_table("Timing", &[row])
        .unwrap()
        .to_markdown()
        .unwrap();
    assert!(
        md.contains("| odometry |      25.0 |     38.5 | 40.0 |"),
        "{md}"
    );
    // A stage that did no work has no FPS.
    acc.record("filter", std::time::Duration::from_nanos(40));
    let idle = TimingRow::from_accumulator(&acc, "filter").unwrap();
    let md = timing_table("Timing", &[idle])
        .unwrap()
        .to_markdown()
        .unwrap();
    assert!(
        md.contains("| filter |       0.0 |      0.0 | –   |"),
        "{md}"
    );
}
