//! Report layer end to end: SVG plots on disk and the report directory.

use limot::report::{
    Cell, LineKind, Plot, PlotKind, Report, ReportError, Section, Series2D, Table,
    plot_error_over_time, plot_object_tracks, plot_speed, plot_trajectories_xy, write_report,
};
use limot_estimator::Variant;
use std::path::{Path, PathBuf};

/// A fresh directory per test under cargo's integration-test scratch dir.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("report_{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The `points` of every data polyline (stroke width 2 is reserved for series).
fn series_polylines(svg: &str) -> Vec<Vec<(f64, f64)>> {
    svg.split("<polyline")
        .skip(1)
        .filter(|el| {
            let end = el.find("/>").unwrap_or(el.len());
            el[..end].contains("stroke-width=\"2\"")
        })
        .map(|el| {
            let start = el.find("points=\"").unwrap() + "points=\"".len();
            let end = start + el[start..].find('"').unwrap();
            el[start..end]
                .split_whitespace()
                .map(|xy| {
                    let (x, y) = xy.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect()
        })
        .collect()
}

/// The text content of every `<text>` element, trimmed.
fn texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|el| {
            let start = el.find('>')? + 1;
            let end = el.find("</text>")?;
            Some(el[start..end].trim().to_string())
        })
        .collect()
}

fn has_text(svg: &str, label: &str) -> bool {
    texts(svg).iter().any(|t| t == label)
}

fn circle(radius_m: f64, n: usize, cx: f64, cy: f64) -> Vec<(f64, f64)> {
    (0..=n)
        .map(|i| {
            let a = i as f64 / n as f64 * std::f64::consts::TAU;
            (cx + radius_m * a.cos(), cy + radius_m * a.sin())
        })
        .collect()
}

#[test]
fn trajectory_plot_has_one_polyline_per_series_labels_and_equal_scale() {
    let dir = scratch("traj");
    let path = dir.join("ego.svg");
    let series = vec![
        Series2D::truth("truth", circle(50.0, 200, 0.0, 0.0)),
        Series2D::line("lio", circle(50.5, 200, 0.3, 0.0)),
        Series2D::line("limot", circle(50.1, 200, 0.1, 0.0)),
    ];
    plot_trajectories_xy(&path, "Ego trajectory seq 0007", &series).unwrap();
    let svg = std::fs::read_to_string(&path).unwrap();
    assert!(svg.starts_with("<svg"), "{}", &svg[..80.min(svg.len())]);
    assert!(svg.trim_end().ends_with("</svg>"));
    for label in [
        "truth",
        "lio",
        "limot",
        "Ego trajectory seq 0007",
        "x [m]",
        "y [m]",
    ] {
        assert!(has_text(&svg, label), "label {label:?} missing");
    }
    let lines = series_polylines(&svg);
    assert_eq!(lines.len(), 3, "one data polyline per series");
    assert!(svg.contains("stroke=\"#000000\""), "truth is black");
    // A circle must look round: equal pixel extent in x and y (top view with
    // equal metres per pixel, although the canvas is not square).
    let truth = &lines[0];
    let ext = |f: fn(&(f64, f64)) -> f64| {
        let v: Vec<f64> = truth.iter().map(f).collect();
        v.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - v.iter().cloned().fold(f64::INFINITY, f64::min)
    };
    let (w_px, h_px) = (ext(|p| p.0), ext(|p| p.1));
    assert!(w_px > 200.0, "circle should fill the plot, got {w_px} px");
    assert!(
        (w_px - h_px).abs() <= 2.0,
        "x extent {w_px} px vs y extent {h_px} px"
    );
}

#[test]
fn object_speed_and_error_plots_are_written() {
    let dir = scratch("objects");
    let truth = vec![
        Series2D::line("obj 2 truth", vec![(0.0, 0.0), (10.0, 1.0), (20.0, 3.0)]),
        Series2D::line("obj 5 truth", vec![(5.0, -4.0), (5.0, -4.0)]),
    ];
    let est = vec![
        Series2D::line("obj 2 limot", vec![(0.2, 0.1), (10.1, 1.2), (19.8, 3.1)]),
        Series2D::line("obj 5 limot", vec![(5.1, -3.9)]).with_kind(LineKind::Markers),
    ];
    let tracks = dir.join("tracks.svg");
    plot_object_tracks(&tracks, "Objects", &truth, &est).unwrap();
    let svg = std::fs::read_to_string(&tracks).unwrap();
    // Three line series; the marker series draws circles instead.
    assert_eq!(series_polylines(&svg).len(), 3);
    assert!(svg.contains("<circle"));
    // Truth without a colour is drawn black, both truth tracks.
    assert_eq!(
        svg.matches("stroke=\"#000000\" stroke-width=\"2\"").count(),
        2
    );
    for label in ["obj 2 truth", "obj 5 truth", "obj 2 limot", "obj 5 limot"] {
        assert!(has_text(&svg, label), "label {label:?} missing");
    }

    let speed = dir.join("speed.svg");
    let t_speed: Vec<(f64, f64)> = (0..50).map(|i| (0.1 * i as f64, 10.0)).collect();
    plot_speed(
        &speed,
        "Speed",
        &[Series2D::truth("truth", t_speed.clone())],
    )
    .unwrap();
    let svg = std::fs::read_to_string(&speed).unwrap();
    assert!(svg.starts_with("<svg") && has_text(&svg, "speed [m/s]") && has_text(&svg, "t [s]"));
    assert_eq!(series_polylines(&svg).len(), 1);

    let err = dir.join("err.svg");
    let e: Vec<(f64, f64)> = t_speed.iter().map(|&(t, _)| (t, 0.01 * t)).collect();
    plot_error_over_time(
        &err,
        "Error",
        "translation error [m]",
        &[Series2D::line("lio", e)],
    )
    .unwrap();
    let svg = std::fs::read_to_string(&err).unwrap();
    assert!(has_text(&svg, "translation error [m]"));
}

#[test]
fn nan_or_empty_input_is_an_error_naming_the_path() {
    let dir = scratch("bad");
    let path = dir.join("nan.svg");
    let series = [Series2D::line("lio", vec![(0.0, 0.0), (f64::NAN, 1.0)])];
    let err = plot_trajectories_xy(&path, "t", &series).unwrap_err();
    assert!(
        matches!(err, ReportError::NonFinite { index: 1, .. }),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(
        msg.contains(&path.display().to_string()) && msg.contains("lio"),
        "{msg}"
    );
    assert!(!path.exists(), "no file for a failed plot");

    let err = plot_speed(&path, "t", &[]).unwrap_err();
    assert!(matches!(err, ReportError::NoSeries { .. }));
    assert!(err.to_string().contains("nan.svg"));
    let err = plot_speed(&path, "t", &[Series2D::line("x", vec![])]).unwrap_err();
    assert!(matches!(err, ReportError::EmptySeries { .. }));

    // An unwritable target names the path too.
    let missing = dir.join("no_such_dir").join("p.svg");
    let err = plot_speed(&missing, "t", &[Series2D::line("x", vec![(0.0, 1.0)])]).unwrap_err();
    assert!(matches!(err, ReportError::Io { .. }), "{err:?}");
    assert!(err.to_string().contains("no_such_dir"));
}

fn sample_report() -> Report {
    let mut table = Table::new("Ego ATE", vec!["Seq".into(), "LIO ATE_T [m]".into()]);
    table.push_row(vec!["0001".into(), Cell::Num(0.5)]).unwrap();
    let traj = Plot {
        file_name: "ego_0001.svg".into(),
        title: "Ego 0001".into(),
        kind: PlotKind::TrajectoriesXy {
            series: vec![
                Series2D::truth("truth", circle(20.0, 50, 0.0, 0.0)),
                Series2D::line(Variant::Lio.label(), circle(20.2, 50, 0.0, 0.0)),
            ],
        },
    };
    let speed = Plot {
        file_name: "speed_0001.svg".into(),
        title: "Object speed".into(),
        kind: PlotKind::Speed {
            series: vec![Series2D::truth("truth", vec![(0.0, 1.0), (1.0, 2.0)])],
        },
    };
    let tracks = Plot {
        file_name: "objects_0001.svg".into(),
        title: "Objects".into(),
        kind: PlotKind::ObjectTracks {
            truth: vec![Series2D::line("gt 1", vec![(0.0, 0.0), (3.0, 1.0)])],
            est: vec![Series2D::line("est 1", vec![(0.1, 0.0), (3.0, 1.1)])],
        },
    };
    let err = Plot {
        file_name: "err_0001.svg".into(),
        title: "Error".into(),
        kind: PlotKind::ErrorOverTime {
            y_desc: "error [m]".into(),
            series: vec![Series2D::line("lio", vec![(0.0, 0.0), (1.0, 0.2)])],
        },
    };
    Report {
        title: "limot evaluation".into(),
        sections: vec![
            Section {
                heading: "Ego pose".into(),
                text: "Highway family, seed 1.".into(),
                tables: vec![table],
                plots: vec![traj, err],
            },
            Section {
                heading: "Objects".into(),
                text: String::new(),
                tables: vec![],
                plots: vec![tracks, speed],
            },
        ],
    }
}

#[test]
fn write_report_links_every_plot_it_writes() {
    let dir = scratch("report").join("out");
    let report = sample_report();
    let readme_path = write_report(&dir, &report).unwrap();
    assert_eq!(readme_path, dir.join("README.md"));
    let readme = std::fs::read_to_string(&readme_path).unwrap();
    assert!(readme.starts_with("# limot evaluation\n"));
    assert!(readme.contains("\n## Ego pose\n") && readme.contains("\n## Objects\n"));
    assert!(readme.contains("Highway family, seed 1."));
    assert!(readme.contains("| 0001 |         0.500 |"), "{readme}");

    let svgs: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".svg"))
        .collect();
    assert_eq!(svgs.len(), 4, "{svgs:?}");
    for name in &svgs {
        assert!(
            readme.contains(&format!("]({name})")),
            "README misses {name}"
        );
        let svg = std::fs::read_to_string(dir.join(name)).unwrap();
        assert!(svg.starts_with("<svg"));
    }
    // Every link in the README points at a file that exists.
    for link in readme.split("](").skip(1) {
        let target = &link[..link.find(')').unwrap()];
        assert!(dir.join(target).is_file(), "dangling link {target}");
    }
}

#[test]
fn write_report_rejects_bad_names_before_writing() {
    let dir = scratch("report_bad").join("out");
    let mut report = sample_report();
    report.sections[1].plots[0].file_name = "../escape.svg".into();
    let err = write_report(&dir, &report).unwrap_err();
    assert!(matches!(err, ReportError::BadPlotName { .. }), "{err:?}");
    assert!(err.to_string().contains("escape.svg"));
    assert!(!dir.exists(), "nothing written for a rejected report");

    let mut report = sample_report();
    report.sections[1].plots[0].file_name = "ego_0001.svg".into();
    let err = write_report(&dir, &report).unwrap_err();
    assert!(matches!(err, ReportError::DuplicatePlot { .. }), "{err:?}");

    // A NaN in a plot fails the report with the plot's path and no README.
    let mut report = sample_report();
    if let PlotKind::Speed { series } = &mut report.sections[1].plots[1].kind {
        series[0].points[1].1 = f64::NAN;
    }
    let err = write_report(&dir, &report).unwrap_err();
    assert!(err.to_string().contains("speed_0001.svg"), "{err}");
    assert!(!dir.join("README.md").exists());
}

mod table_props {
    use limot::report::{Better, BoldRule, Cell, Table};
    use proptest::prelude::*;

    fn cell() -> impl Strategy<Value = Cell> {
        prop_oneof![
            (-1e4f64..1e4).prop_map(Cell::Num),
            (-1000i64..1000).prop_map(Cell::Int),
            Just(Cell::Missing),
            "[a-z|– \n]{0,8}".prop_map(Cell::Text),
        ]
    }

    proptest! {
        /// Whatever the cells, every line of the table has the same width
        /// and the same number of cell separators (unescaped pipes).
        #[test]
        fn markdown_rows_stay_aligned(
            ncol in 1usize..5,
            rows in proptest::collection::vec(proptest::collection::vec(cell(), 4), 0..6),
            decimals in 0usize..5,
        ) {
            let header: Vec<String> = (0..ncol).map(|c| format!("col {c}")).collect();
            let mut t = Table::new("", header);
            for c in 0..ncol {
                t.set_decimals(c, decimals);
            }
            for row in rows {
                t.push_row(row[..ncol].to_vec()).unwrap();
            }
            t.bold = vec![BoldRule::BestInRow { columns: (0..ncol).collect(), better: Better::Lower }];
            let md = t.to_markdown().unwrap();
            let lines: Vec<&str> = md.lines().collect();
            prop_assert_eq!(lines.len(), 2 + t.rows.len());
            let width = lines[0].chars().count();
            for line in &lines {
                prop_assert_eq!(line.chars().count(), width, "{}", md);
                let seps = line.len() - line.replace("|", "").len() - line.matches("\\|").count();
                prop_assert_eq!(seps, ncol + 1, "{}", md);
            }
        }
    }
}
