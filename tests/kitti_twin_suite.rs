//! `limot eval suite --families kitti`: the KITTI twins of 0000 and 0020
//! (3 s each, the real PointRCNN boxes) and 0019, which is not in
//! `../shared/data`, with the four variants: the report sets Tables I-III
//! beside the paper's rows with both rankings; two jobs, one job and two
//! merged shards give the same figures; bad input is named. When the data is
//! absent the data tests print a loud note and return; when it is present
//! they always run.

use limot::experiments::{SuiteResults, twin_family};
use limot_estimator::Variant;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

mod common;

use common::without_timings;

const SEQUENCES: &str = "0,19-20";
const DURATION_S: &str = "3";

struct Data {
    training: PathBuf,
    detections: PathBuf,
}

fn data() -> Option<Data> {
    common::data_root("KITTI twin suite").map(|root| Data {
        training: root.join("kitti_tracking/training"),
        detections: root.join("kitti_tracking/detections/pointrcnn_Car_val"),
    })
}

fn scratch(name: &str) -> PathBuf {
    let dir = common::process_dir().join("kitti_twin_suite").join(name);
    let _ = fs::remove_dir_all(&dir);
    dir
}

fn limot(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_limot"))
        .args(args)
        .output()
        .unwrap()
}

fn succeeds(args: &[&str]) -> String {
    let out = limot(args);
    assert!(
        out.status.success(),
        "limot {args:?}:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn fails(args: &[&str]) -> String {
    let out = limot(args);
    assert!(!out.status.success(), "limot {args:?} succeeded");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// `eval suite --families kitti ...` into `out` with extra arguments.
fn twin_suite(data: &Data, out: &Path, extra: &[&str]) -> String {
    let mut args = vec![
        "eval",
        "suite",
        "--families",
        "kitti",
        "--training",
        data.training.to_str().unwrap(),
        "--sequences",
        SEQUENCES,
        "--detections",
        data.detections.to_str().unwrap(),
        "--duration",
        DURATION_S,
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    succeeds(&args)
}

/// The whole suite in two jobs, once per test binary: its results and directory.
fn whole(data: &Data) -> &'static (SuiteResults, PathBuf) {
    static WHOLE: OnceLock<(SuiteResults, PathBuf)> = OnceLock::new();
    WHOLE.get_or_init(|| {
        let out = scratch("whole");
        let stdout = twin_suite(data, &out, &["--jobs", "2"]);
        assert!(
            stdout.contains("not available: KITTI sequence 0019 is not in the data"),
            "{stdout}"
        );
        (SuiteResults::load(&out).unwrap().0, out)
    })
}

#[test]
fn the_twin_suite_reports_tables_i_to_iii_beside_the_papers_with_rankings() {
    let Some(data) = data() else { return };
    let (results, out) = whole(&data);
    let names: Vec<&str> = results.sequences.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["kitti-0000_s1", "kitti-0019_s1", "kitti-0020_s1"]);
    assert_eq!(results.families, [0, 19, 20].map(twin_family));
    assert_eq!(results.seeds, [1], "one seed by default for twins");
    let twins = results.twins.as_ref().unwrap();
    assert_eq!(twins.sequences, [0, 19, 20]);
    assert_eq!(twins.detections.as_deref(), Some(data.detections.as_path()));
    let missing = &results.sequences[1];
    let why = missing.error.as_deref().unwrap();
    assert!(
        why.contains("0019 is not in the data") && why.contains("oxts/0019.txt"),
        "{why}"
    );
    for s in [&results.sequences[0], &results.sequences[2]] {
        assert!(s.error.is_none(), "{}: {:?}", s.name, s.error);
        assert_eq!(s.frames, 30, "{}", s.name);
        assert!(s.path_length_m.is_some_and(|p| p > 5.0), "{}", s.name);
        // the twin recorded the real boxes of its sequence
        let scenario = fs::read_to_string(out.join(&s.dataset_dir).join("scenario.toml")).unwrap();
        assert!(scenario.contains("pointrcnn_Car_val"), "{scenario}");
        for v in Variant::ALL {
            let m = s
                .metrics(v)
                .unwrap_or_else(|| panic!("{} {v}: {:?}", s.name, s.variant(v)));
            assert!(m.ego.ate_t_m < 1.0, "{} {v}: {}", s.name, m.ego.ate_t_m);
            let car = m.car_mot("3D", 0.25).unwrap();
            assert!(car.counts.gt_count > 0, "{} {v}: {car:?}", s.name);
        }
    }
    let readme = fs::read_to_string(out.join("report/README.md")).unwrap();
    for expected in [
        "## KITTI twins beside the paper (Tables I-III)",
        "not available: 0019",
        "pointrcnn_Car_val",
        "its LIO-SAM, LIO-Allfilt, LIO-Dynafilt, LIMOT correspond to our LIO, LIO-Allfilt, LIO-Dynafilt, LIMOT",
        // Table I: the paper's rows beside ours, each with its ordering
        "| 0020 | paper, Table I (real KITTI) |         9.488 |",
        "| limot < dynafilt < allfilt < lio |",
        "| 0019 | ours, twin ",
        "| not available ",
        "ordering by ATE_T",
        "Kendall τ_b",
        "Every twin with a paper row: 2 twin(s) compared; best variant the same on ",
        "LIMOT vs LIO ",
        // Table II: the paper's MOTP rows and ours, class Car
        "| LIMOT        | paper, Table II (real KITTI, CenterPoint) |",
        "| LIMOT        | ours, twins ",
        // Table III: the paper's objects of 0020
        "| 20 / 12 ",
        "--families kitti --training ",
    ] {
        assert!(
            readme.contains(expected),
            "README lacks {expected:?}:\n{readme}"
        );
    }
}

#[test]
fn one_job_and_merged_shards_give_the_figures_of_two_jobs() {
    let Some(data) = data() else { return };
    let (whole, _) = whole(&data);
    let out = scratch("shards");
    // shard 1/2 holds 0000 and 0020 (positions 0 and 2), run one at a time;
    // shard 2/2 holds only 0019, which is not in the data
    for shard in ["2/2", "1/2"] {
        twin_suite(&data, &out, &["--shard", shard, "--jobs", "1"]);
    }
    let file = |k: usize| {
        out.join(format!("results-shard-{k}-of-2.json"))
            .display()
            .to_string()
    };
    succeeds(&["report", "--merge", &file(1), &file(2)]);
    let (merged, _) = SuiteResults::load(&out).unwrap();
    assert_eq!(without_timings(merged), without_timings(whole.clone()));
    let readme = fs::read_to_string(out.join("report/README.md")).unwrap();
    assert!(readme.contains("## KITTI twins beside the paper (Tables I-III)"));
}

#[test]
fn bad_twin_input_is_named() {
    let missing = scratch("no-such-training");
    let missing = missing.to_str().unwrap();
    let suite = |extra: &[&str]| {
        let mut args = vec!["eval", "suite", "--out", "unused-never-written"];
        args.extend_from_slice(extra);
        fails(&args)
    };
    for (args, expected) in [
        (
            vec![
                "--families",
                "kitti",
                "--training",
                missing,
                "--sequences",
                "0",
            ],
            format!("--training {missing}: not a directory"),
        ),
        (
            vec!["--families", "kitti", "--training", missing],
            format!("--training {missing}: not a directory"),
        ),
        (
            vec![
                "--families",
                "kitti",
                "--training",
                missing,
                "--sequences",
                "5-2",
            ],
            "--sequences `5-2`: a range runs from the lower number".to_string(),
        ),
        (
            vec!["--families", "kitti"],
            "the kitti family needs a KITTI tracking training dir".to_string(),
        ),
        (
            vec!["--families", "urban", "--training", ".", "--sequences", "0"],
            "are for the kitti family".to_string(),
        ),
    ] {
        let stderr = suite(&args);
        assert!(stderr.contains(&expected), "{args:?}: {stderr}");
    }
    assert!(!Path::new("unused-never-written").exists());
    let Some(data) = data() else { return };
    let training = data.training.to_str().unwrap();
    let stderr = suite(&[
        "--families",
        "kitti",
        "--training",
        training,
        "--sequences",
        "99",
    ]);
    assert!(
        stderr.contains("0099") && stderr.contains(training),
        "{stderr}"
    );
    let stderr = suite(&[
        "--families",
        "kitti",
        "--training",
        training,
        "--sequences",
        "0",
        "--detections",
        missing,
    ]);
    assert!(
        stderr.contains(&format!("--detections {missing}: not a directory")),
        "{stderr}"
    );
}
