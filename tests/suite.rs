//! `limot eval suite` / `limot report` on one short urban sequence (seed 1,
//! 4 s) with lio, dynafilt and limot; a variant that fails is recorded as
//! not available without aborting the suite. The `joint` ablation on a short
//! highway sequence.

use limot::experiments::{
    Ablation, RESULTS_FILE, Shard, SuiteResults, SuiteSpec, merge_shards, run_suite,
};
use limot::report::write_suite_report;
use limot_estimator::Variant;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

mod common;

use common::without_timings;

fn scratch(name: &str) -> PathBuf {
    let dir = common::process_dir().join("suite").join(name);
    let _ = fs::remove_dir_all(&dir);
    dir
}

fn spec(out_dir: PathBuf, duration_s: f64, variants: Vec<Variant>) -> SuiteSpec {
    SuiteSpec {
        families: vec!["urban".into()],
        seeds: vec![1],
        duration_s,
        variants,
        ablations: Vec::new(),
        out_dir,
        shard: None,
        jobs: None,
        twins: None,
    }
}

/// The suite run once per test binary, with its report in OUT/report.
fn suite() -> &'static (SuiteResults, PathBuf) {
    static SUITE: OnceLock<(SuiteResults, PathBuf)> = OnceLock::new();
    SUITE.get_or_init(|| {
        let out = scratch("main");
        let variants = vec![Variant::Lio, Variant::Dynafilt, Variant::Limot];
        let results = run_suite(&spec(out.clone(), 4.0, variants), false).unwrap();
        write_suite_report(&out.join("report"), &results, &out).unwrap();
        (results, out)
    })
}

#[test]
fn results_json_round_trips() {
    let (results, out) = suite();
    let (loaded, dir) = SuiteResults::load(&out.join(RESULTS_FILE)).unwrap();
    assert_eq!(&loaded, results);
    assert_eq!(&dir, out);
    // a directory works as well
    let (loaded, _) = SuiteResults::load(out).unwrap();
    assert_eq!(&loaded, results);
    // without ablations the file keeps the layout written before they existed
    let text = fs::read_to_string(out.join(RESULTS_FILE)).unwrap();
    assert!(!text.contains("ablation"), "{text}");
}

#[test]
fn every_run_tracks_the_ego_to_half_a_metre_and_is_scored() {
    let (results, _) = suite();
    assert_eq!(results.sequences.len(), 1);
    let s = &results.sequences[0];
    assert_eq!((s.name.as_str(), s.frames), ("urban_s1", 40));
    assert!(s.error.is_none(), "{:?}", s.error);
    assert!(!s.moving_objects.is_empty());
    for v in [Variant::Lio, Variant::Dynafilt] {
        let r = s.variant(v).unwrap();
        let m = r
            .metrics
            .as_ref()
            .unwrap_or_else(|| panic!("{v}: {:?}", r.error));
        assert!(
            m.ego.ate_t_m.is_finite() && m.ego.ate_t_m < 0.5,
            "{v}: ATE_T {} m",
            m.ego.ate_t_m
        );
        assert!(m.ego.ate_r_rad.is_finite() && m.ego.ate_r_rad < 0.1);
        // the urban street constrains every direction of the scan match
        let along = m.ego.ate_along_m.expect("the ego drives");
        assert!(along <= m.ego.ate_t_m, "{v}: along {along} m");
        assert_eq!(m.ego.degenerate_match_share, Some(0.0), "{v}");
        assert_eq!(m.frames_estimated, s.frames, "{v}: one estimate per frame");
        for (kind, thr) in [("3D", 0.25), ("3D", 0.5), ("BEV", 0.25), ("BEV", 0.5)] {
            let mot = m
                .mot(kind, thr)
                .unwrap_or_else(|| panic!("{v}: no {kind} {thr}"));
            assert!(
                mot.counts.gt_count > 0 && mot.counts.matches > 0,
                "{v} {kind} {thr}: {mot:?}"
            );
            assert!(mot.counts.motp.is_some_and(|p| p >= thr && p <= 1.0));
        }
        assert!(m.objects.iter().any(|o| o.tp_percent > 0.0));
        let total = m.timings.iter().find(|t| t.stage == "total").unwrap();
        assert_eq!(total.ms.len(), m.frames_estimated);
        assert!(total.ms.iter().all(|ms| ms.is_finite() && *ms > 0.0));
        assert!(m.fps > 0.0);
        // The filter is scored against the per-point labels where it runs.
        match (v, m.filtering) {
            (Variant::Lio, f) => assert!(f.is_none(), "{f:?}"),
            (_, Some(f)) => {
                assert!(f.features > 10_000 && f.moving_features > 0, "{f:?}");
                let score = f.score();
                assert!(score.recall.is_some_and(|r| r > 0.5), "{v}: {score:?}");
                // what it removes lies on objects: moving ones, and the
                // parked cars' edges it drops by design
                // (`EstimatorConfig::filter_static_edges`)
                let on_objects = (f.removed_moving + f.removed_static_object) as f64;
                let object_precision = on_objects / f.removed.max(1) as f64;
                eprintln!("{v}: filter {score:?}, object precision {object_precision:.3}");
                assert!(object_precision > 0.8, "{v}: {object_precision} {f:?}");
            }
            (_, None) => panic!("{v}: no filter figures"),
        }
    }
}

#[test]
fn limot_runs_in_the_suite_and_is_scored() {
    let (results, _) = suite();
    let limot = results.sequences[0].variant(Variant::Limot).unwrap();
    assert!(limot.error.is_none(), "{:?}", limot.error);
    let m = limot.metrics.as_ref().unwrap();
    assert!(m.ego.ate_t_m < 0.5, "limot ATE_T {}", m.ego.ate_t_m);
}

/// Links `](file.svg)` of a README.
fn svg_links(readme: &str) -> Vec<String> {
    readme
        .split("](")
        .skip(1)
        .filter_map(|rest| rest.split(')').next())
        .filter(|target| target.ends_with(".svg"))
        .map(String::from)
        .collect()
}

#[test]
fn report_has_variant_columns_and_existing_plots() {
    let (_, out) = suite();
    let report = out.join("report");
    let readme = fs::read_to_string(report.join("README.md")).unwrap();
    for column in [
        "LIO ATE_T [m]",
        "LIO-Dynafilt ATE_T [m]",
        "LIO-Dynafilt TP [%]",
        "MOTP [%] (IoU 0.25)",
        "**LIO-Dynafilt: time per scan by module**",
        "**Dynamic-feature filtering vs per-point labels (LiDAR features)**",
        "static-object features removed [%]",
    ] {
        assert!(
            readme.contains(column),
            "README lacks {column:?}:\n{readme}"
        );
    }
    let links = svg_links(&readme);
    assert!(
        links.contains(&"urban_s1_ego_xy.svg".to_string()),
        "{links:?}"
    );
    assert!(
        links.contains(&"urban_s1_ego_error.svg".to_string()),
        "{links:?}"
    );
    assert!(
        links.iter().any(|l| l.ends_with("_speed.svg")),
        "no object speed plot: {links:?}"
    );
    for link in &links {
        let svg = fs::read_to_string(report.join(link)).unwrap();
        assert!(svg.contains("<svg") && svg.contains("<polyline"), "{link}");
    }
}

#[test]
fn limot_report_re_renders_the_same_readme() {
    let (_, out) = suite();
    let again = scratch("rerender");
    let status = Command::new(env!("CARGO_BIN_EXE_limot"))
        .arg("report")
        .arg(out.join(RESULTS_FILE))
        .arg("--out")
        .arg(&again)
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let stdout = String::from_utf8_lossy(&status.stdout);
    assert!(
        stdout.contains("| urban_s1 |"),
        "ego table printed:\n{stdout}"
    );
    let first = fs::read_to_string(out.join("report").join("README.md")).unwrap();
    let second = fs::read_to_string(again.join("README.md")).unwrap();
    assert_eq!(first, second);
    for link in svg_links(&second) {
        assert!(fs::metadata(again.join(&link)).unwrap().len() > 0, "{link}");
    }
}

/// `limot report --baseline`: a suite against itself has no regression and
/// passes the gate; against a baseline whose lio run was 20 % better, the
/// gate fails naming that run, and baseline.md lists it.
#[test]
fn the_baseline_gate_passes_the_same_results_and_fails_a_worse_ate() {
    let (results, out) = suite();
    let report = |baseline: &Path, to: &Path| {
        Command::new(env!("CARGO_BIN_EXE_limot"))
            .arg("report")
            .arg(out.join(RESULTS_FILE))
            .arg("--out")
            .arg(to)
            .arg("--baseline")
            .arg(baseline)
            .arg("--fail-on-regression")
            .output()
            .unwrap()
    };
    let same = scratch("baseline-same");
    let run = report(&out.join(RESULTS_FILE), &same);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let page = fs::read_to_string(same.join("baseline.md")).unwrap();
    assert!(page.contains("No regressions."), "{page}");

    let better = scratch("baseline-better");
    fs::create_dir_all(&better).unwrap();
    let mut doctored = results.clone();
    let lio = doctored.sequences[0]
        .variants
        .iter_mut()
        .find(|r| r.variant == Variant::Lio)
        .and_then(|r| r.metrics.as_mut())
        .unwrap();
    let ate = lio.ego.ate_t_m;
    lio.ego.ate_t_m = (ate / 1.2).min(ate - 0.02);
    doctored.save(&better).unwrap();
    let to = scratch("baseline-worse");
    let run = report(&better.join(RESULTS_FILE), &to);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("1 regression(s)"), "{stderr}");
    let name = &doctored.sequences[0].name;
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        stdout.contains(&format!(
            "regression: {name} / {}: ATE_T",
            Variant::Lio.label()
        )),
        "{stdout}"
    );
    let page = fs::read_to_string(to.join("baseline.md")).unwrap();
    assert!(page.contains("1 regression(s)"), "{page}");
}

#[test]
fn a_corrupt_dataset_fails_its_runs_without_aborting_the_suite() {
    let (_, main_out) = suite();
    let out = scratch("corrupt");
    // the same scenario, so the suite reuses the copied dataset
    let data = out.join("data").join("urban_s1");
    copy_dir(&main_out.join("data").join("urban_s1"), &data);
    let scan = data.join("scans").join("000020.bin");
    let bytes = fs::read(&scan).unwrap();
    fs::write(&scan, &bytes[..bytes.len() / 2]).unwrap();
    let results = run_suite(&spec(out.clone(), 4.0, vec![Variant::Lio]), false).unwrap();
    let r = results.sequences[0].variant(Variant::Lio).unwrap();
    assert!(r.metrics.is_none());
    let error = r.error.as_deref().unwrap();
    assert!(error.contains("000020.bin"), "{error}");
    // saved, and rendered with the failure spelled out
    let (loaded, _) = SuiteResults::load(&out).unwrap();
    assert_eq!(loaded, results);
    let readme = write_suite_report(&out.join("report"), &results, &out).unwrap();
    let text = fs::read_to_string(readme).unwrap();
    assert!(text.contains("urban_s1 / LIO: not available"), "{text}");
}

#[test]
fn datasets_are_reused_only_for_the_same_scenario_and_simulator() {
    let out = scratch("reuse");
    let meta = out.join("data").join("urban_s1").join("meta.toml");
    let short = spec(out.clone(), 1.0, vec![Variant::Lio]);
    let first = run_suite(&short, false).unwrap();
    assert_eq!(first.sequences[0].frames, 10);
    let written = fs::metadata(&meta).unwrap().modified().unwrap();
    run_suite(&short, false).unwrap();
    assert_eq!(fs::metadata(&meta).unwrap().modified().unwrap(), written);
    // the same scenario written by other simulator code: re-simulated
    let code = out
        .join("data")
        .join("urban_s1")
        .join(".limot-dataset-code");
    let current = fs::read_to_string(&code).unwrap();
    assert!(!current.trim().is_empty());
    fs::write(&code, "an older simulator").unwrap();
    run_suite(&short, false).unwrap();
    assert_eq!(fs::read_to_string(&code).unwrap(), current);
    assert_ne!(fs::metadata(&meta).unwrap().modified().unwrap(), written);
    let longer = run_suite(&spec(out.clone(), 1.5, vec![Variant::Lio]), false).unwrap();
    assert_eq!(longer.sequences[0].frames, 15, "re-simulated for 1.5 s");
}

fn copy_dir(from: &Path, to: &Path) {
    fs::create_dir_all(to).unwrap();
    for entry in fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            fs::copy(entry.path(), &target).unwrap();
        }
    }
}

#[test]
fn shards_merged_give_the_whole_suite_run_in_parallel() {
    let whole_out = scratch("whole");
    let shards_out = scratch("shards");
    let two_sequences = |out: PathBuf, shard: Option<&str>, jobs: usize| SuiteSpec {
        families: vec!["urban".into(), "highway".into()],
        seeds: vec![3],
        duration_s: 2.0,
        variants: vec![Variant::Lio, Variant::Limot],
        ablations: vec![Ablation::Joint],
        out_dir: out,
        shard: shard.map(|s| Shard::parse(s).unwrap()),
        jobs: Some(jobs),
        twins: None,
    };
    // both sequences at once, against one at a time in two shards
    let whole = run_suite(&two_sequences(whole_out.clone(), None, 2), false).unwrap();
    let names: Vec<&str> = whole.sequences.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["urban_s3", "highway_s3"]);
    assert!(whole.sequences.iter().all(|s| s.error.is_none()));
    assert!(
        whole
            .sequences
            .iter()
            .all(|s| s.ablation_metrics(Ablation::Joint).is_some()),
        "the ablation ran on every sequence"
    );
    for shard in ["2/2", "1/2"] {
        let part = run_suite(&two_sequences(shards_out.clone(), Some(shard), 1), false).unwrap();
        assert_eq!(part.sequences.len(), 1);
    }
    let file = |k| shards_out.join(format!("results-shard-{k}-of-2.json"));
    let status = Command::new(env!("CARGO_BIN_EXE_limot"))
        .arg("report")
        .arg("--merge")
        .args([file(2), file(1)])
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let (merged, dir) = SuiteResults::load(&shards_out).unwrap();
    assert_eq!(dir, shards_out);
    assert!(merged.shard.is_none());
    assert_eq!(without_timings(merged), without_timings(whole));
    let readme = fs::read_to_string(shards_out.join("report").join("README.md")).unwrap();
    assert!(
        readme.contains("| highway_s3 | LIMOT (joint) |"),
        "{readme}"
    );

    // A shard run without the ablation is not part of the same suite.
    let mut other = SuiteResults::load(&file(2)).unwrap().0;
    other.ablations.clear();
    for s in &mut other.sequences {
        s.ablations.clear();
    }
    fs::write(
        file(2),
        serde_json::to_string_pretty(&other).unwrap() + "\n",
    )
    .unwrap();
    let err = merge_shards(&[file(1), file(2)]).unwrap_err().to_string();
    assert!(err.contains("ablations differ"), "{err}");

    // An incomplete, repeated or whole-suite file list is refused by name.
    for (files, expected) in [
        (vec![file(1)], "shard 2/2 is missing".to_string()),
        (vec![file(1), file(1)], "given twice".to_string()),
        (
            vec![file(1), whole_out.join(RESULTS_FILE)],
            format!("{}: not a shard", whole_out.join(RESULTS_FILE).display()),
        ),
    ] {
        let err = merge_shards(&files).unwrap_err().to_string();
        assert!(err.contains(&expected), "{err}");
    }
    assert!(Shard::parse("0/2").is_err() && Shard::parse("3/2").is_err());
    assert!(Shard::parse("2").is_err() && Shard::parse("a/b").is_err());
}

/// Ego positions of a TUM trajectory file.
fn tum_positions(path: &Path) -> Vec<[f64; 3]> {
    fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            [v[1], v[2], v[3]]
        })
        .collect()
}

#[test]
fn the_joint_ablation_runs_beside_limot_and_moves_the_ego() {
    // Highway traffic: limot confirms dynamic objects within 6 s, so letting
    // them inform the ego changes its trajectory (without any the two forms
    // would be the same graph and the same poses).
    let out = scratch("ablation");
    let spec = SuiteSpec {
        families: vec!["highway".into()],
        ablations: vec![Ablation::Joint],
        ..spec(out.clone(), 6.0, vec![Variant::Limot])
    };
    let results = run_suite(&spec, false).unwrap();
    assert_eq!(results.ablations, [Ablation::Joint]);
    let s = &results.sequences[0];
    assert!(s.error.is_none(), "{:?}", s.error);
    assert_eq!(s.variants.len(), 1, "the ablation is not a variant");
    let joint = &s.ablations[0];
    assert_eq!(joint.ablation, Ablation::Joint);
    assert_eq!(joint.run_dir, Path::new("runs/highway_s1/limot-joint"));
    let (conditioned, joint_m) = (
        s.metrics(Variant::Limot).unwrap(),
        joint
            .metrics
            .as_ref()
            .unwrap_or_else(|| panic!("{:?}", joint.error)),
    );
    assert!(
        joint_m.ego.ate_t_m < 0.5,
        "joint ATE_T {}",
        joint_m.ego.ate_t_m
    );
    assert_eq!(joint_m.frames_estimated, conditioned.frames_estimated);
    let a = tum_positions(&out.join(&s.variants[0].run_dir).join("poses_tum.txt"));
    let b = tum_positions(&out.join(&joint.run_dir).join("poses_tum.txt"));
    assert_eq!(a.len(), b.len());
    let largest_m = a
        .iter()
        .zip(&b)
        .map(|(p, q)| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    assert!(largest_m > 1e-6, "the joint form did not move the ego");
    // in results.json and the report, beside limot
    let (loaded, _) = SuiteResults::load(&out).unwrap();
    assert_eq!(loaded, results);
    let readme = write_suite_report(&out.join("report"), &results, &out).unwrap();
    let text = fs::read_to_string(readme).unwrap();
    assert!(text.contains("| highway_s1 | LIMOT         |"), "{text}");
    assert!(text.contains("| highway_s1 | LIMOT (joint) |"), "{text}");
    assert!(text.contains("--ablation joint"), "{text}");
}

#[test]
fn an_ablation_without_its_variant_is_refused_before_any_work() {
    let out = scratch("ablation-refused");
    let status = Command::new(env!("CARGO_BIN_EXE_limot"))
        .args(["eval", "suite", "--families", "urban", "--seeds", "1"])
        .args([
            "--duration",
            "1",
            "--variants",
            "lio",
            "--ablation",
            "joint",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(!status.status.success());
    let stderr = String::from_utf8_lossy(&status.stderr);
    assert!(
        stderr.contains("ablation joint is compared with limot"),
        "{stderr}"
    );
    assert!(!out.exists(), "nothing may be written for a bad spec");
}
