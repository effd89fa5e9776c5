//! `limot realism` end to end: the statistics of a short simulated dataset
//! (read as a dataset and as its KITTI copy, through the library and the
//! CLI), errors on broken input that name the file, and the statistics of
//! the real KITTI tracking sequence 0000 when `../shared/data` is present
//! (unpacked under the target directory; a failed unpack fails the test).

mod common;

use limot::experiments::{RealismReport, analyze_sequence};
use limot::metrics::{RealismConfig, RealismStats};
use limot::simulate::{resolve_scenario, simulate};
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

const SIM_FRAMES: usize = 30;

/// A 3 s urban dataset with its KITTI copy, simulated once per test process.
fn sim_dataset() -> PathBuf {
    static DIR: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let mut spec = resolve_scenario("urban").unwrap();
        spec.duration_s = SIM_FRAMES as f64 * 0.1;
        spec.seed = 2;
        let dir = common::process_dir().join("realism-urban-3s");
        let _ = fs::remove_dir_all(&dir);
        simulate(&spec, &dir, true, false).unwrap();
        dir
    })
    .clone()
}

fn assert_finite(stats: &RealismStats) {
    for (name, unit, value) in stats.scalars() {
        assert!(value.is_finite(), "{name} [{unit}] = {value}");
    }
    for h in [&stats.range_histogram, &stats.intensity_histogram] {
        let sum: f64 = h.fractions.iter().sum();
        assert!((sum - 1.0).abs() < 1e-9, "{h:?}");
    }
    let share: f64 = stats.information_share_pct.iter().sum();
    assert!(
        (share - 100.0).abs() < 1e-6,
        "{:?}",
        stats.information_share_pct
    );
}

#[test]
fn simulated_dataset_gives_finite_plausible_figures() {
    let dir = sim_dataset();
    let config = RealismConfig::default();
    let s = analyze_sequence(&dir, 0, &config, false).unwrap();
    assert_eq!(s.kitti_dir, dir.join("kitti"));
    let stats = &s.stats;
    assert_eq!(stats.sweeps, SIM_FRAMES);
    assert_finite(stats);
    // the ego departs at 1 s: the pairs before are standing
    assert_eq!(
        stats.roll_change_deg.n + stats.standing_pairs,
        SIM_FRAMES - 1
    );
    assert!(stats.roll_change_deg.n >= 10, "{stats:?}");
    assert!(
        stats.roll_change_deg.p95 < 1.0 && stats.pitch_change_deg.p95 < 1.0,
        "{stats:?}"
    );
    let ground = &stats.ground_ring_displacement_m;
    assert!(
        ground.n + stats.ground_pairs_skipped + stats.standing_pairs == SIM_FRAMES - 1,
        "{stats:?}"
    );
    assert!(stats.ground_pairs_skipped <= 2, "{stats:?}");
    assert!(ground.median >= 0.0 && ground.p95 < 0.5, "{ground:?}");
    let along = stats.information_share_pct[0];
    assert!(
        (1.0..99.0).contains(&along),
        "{:?}",
        stats.information_share_pct
    );
    assert!(stats.information_points > 10_000, "{stats:?}");
    assert!((3.0..40.0).contains(&stats.range_median_m), "{stats:?}");
    assert!((0.0..0.5).contains(&stats.range_beyond_far_fraction));
    assert!((50_000.0..200_000.0).contains(&stats.points_per_sweep_mean));

    // the KITTI copy itself is the same input
    let copy = analyze_sequence(&dir.join("kitti"), 0, &config, false).unwrap();
    assert_eq!(copy.stats, s.stats);
}

#[test]
fn cli_writes_json_and_markdown_beside_a_reference() {
    let dir = sim_dataset();
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("realism-cli-out");
    let _ = fs::remove_dir_all(&out);
    let run = Command::new(env!("CARGO_BIN_EXE_limot"))
        .arg("realism")
        .arg(&dir)
        .arg("--out")
        .arg(&out)
        .arg("--reference")
        .arg(dir.join("kitti"))
        .arg("--reference-sequence")
        .arg("0")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let report: RealismReport =
        serde_json::from_str(&fs::read_to_string(out.join("realism.json")).unwrap()).unwrap();
    assert_eq!(
        report.comparison.len(),
        report.dataset.stats.scalars().len()
    );
    assert!(
        report
            .comparison
            .iter()
            .all(|c| c.within_factor_2 && (c.ratio - 1.0).abs() < 1e-12),
        "{:?}",
        report.comparison
    );
    let md = fs::read_to_string(out.join("realism.md")).unwrap();
    assert!(md.contains("| along-track information share | % |"), "{md}");
    assert!(
        md.contains("11 of 11 statistics within a factor of 2"),
        "{md}"
    );
    assert!(stdout.contains("realism.json"), "{stdout}");
}

/// A 3-frame copy of the simulated KITTI copy, for breaking.
fn small_copy(name: &str) -> PathBuf {
    let src = sim_dataset().join("kitti");
    let dst = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("realism-broken-{name}"));
    let _ = fs::remove_dir_all(&dst);
    fs::create_dir_all(dst.join("velodyne/0000")).unwrap();
    fs::create_dir_all(dst.join("oxts")).unwrap();
    fs::create_dir_all(dst.join("calib")).unwrap();
    // the last three sweeps: the ego is driving (the motion statistics
    // leave standing pairs out)
    let first = SIM_FRAMES - 3;
    let lines_of = |p: &str| {
        let text = fs::read_to_string(src.join(p)).unwrap();
        let lines: Vec<&str> = text.lines().skip(first).take(3).collect();
        fs::write(dst.join(p), lines.join("\n") + "\n").unwrap();
    };
    lines_of("oxts/0000.txt");
    lines_of("times.txt");
    fs::copy(src.join("calib/0000.txt"), dst.join("calib/0000.txt")).unwrap();
    let f = "velodyne_elevation_correction_deg.txt";
    fs::copy(src.join(f), dst.join(f)).unwrap();
    for i in 0..3 {
        let from = format!("velodyne/0000/{:06}.bin", first + i);
        let to = format!("velodyne/0000/{i:06}.bin");
        fs::copy(src.join(&from), dst.join(&to)).unwrap();
    }
    dst
}

fn error_of(dir: &Path) -> String {
    let err = analyze_sequence(dir, 0, &RealismConfig::default(), false).unwrap_err();
    let mut text = err.to_string();
    let mut source = std::error::Error::source(&err);
    while let Some(s) = source {
        text += &format!(": {s}");
        source = s.source();
    }
    text
}

#[test]
fn broken_input_is_an_error_naming_the_file() {
    // the intact copy works
    let ok = small_copy("intact");
    let stats = analyze_sequence(&ok, 0, &RealismConfig::default(), false).unwrap();
    assert_eq!(stats.stats.sweeps, 3);

    let missing = ok.join("no-such-dir");
    assert!(error_of(&missing).contains("no-such-dir"));
    let not_kitti = ok.join("calib");
    assert!(error_of(&not_kitti).contains("neither a KITTI tracking directory"));

    let short = small_copy("short");
    let bin = short.join("velodyne/0000/000001.bin");
    let bytes = fs::read(&bin).unwrap();
    fs::write(&bin, &bytes[..100]).unwrap();
    let e = error_of(&short);
    assert!(e.contains("000001.bin") && e.contains("truncated"), "{e}");

    let nan = small_copy("nan");
    let bin = nan.join("velodyne/0000/000002.bin");
    let mut bytes = fs::read(&bin).unwrap();
    bytes[16 * 5 + 4..16 * 5 + 8].copy_from_slice(&f32::NAN.to_le_bytes());
    fs::write(&bin, bytes).unwrap();
    let e = error_of(&nan);
    assert!(e.contains("000002.bin") && e.contains("not finite"), "{e}");

    let empty = small_copy("empty");
    fs::write(empty.join("velodyne/0000/000000.bin"), b"").unwrap();
    let e = error_of(&empty);
    assert!(e.contains("000000.bin") && e.contains("no points"), "{e}");

    let no_truth = small_copy("no-truth");
    fs::remove_file(no_truth.join("oxts/0000.txt")).unwrap();
    let e = error_of(&no_truth);
    assert!(e.contains("oxts/0000.txt"), "{e}");

    let garbled_truth = small_copy("garbled-truth");
    fs::write(garbled_truth.join("oxts/0000.txt"), "1 2 three\n").unwrap();
    let e = error_of(&garbled_truth);
    assert!(e.contains("oxts/0000.txt:1"), "{e}");

    // the CLI fails with the file named
    let run = Command::new(env!("CARGO_BIN_EXE_limot"))
        .arg("realism")
        .arg(&nan)
        .arg("--out")
        .arg(nan.join("out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && stderr.contains("000002.bin"),
        "{stderr}"
    );
}

#[test]
fn real_kitti_0000_figures() {
    let Some(data) = common::data_root("real KITTI scans (realism of sequence 0000)") else {
        return;
    };
    let training = common::kitti_training(&data);
    let s = analyze_sequence(&training, 0, &RealismConfig::default(), false).unwrap();
    let stats = &s.stats;
    eprintln!("{stats:#?}");
    assert_eq!(stats.sweeps, 154);
    assert_finite(stats);
    // measured (docs/realism.md), with margin: a real car's attitude moves
    // ~0.1 deg per frame and its ground rings centimetres
    assert!(
        (0.02..0.5).contains(&stats.roll_change_deg.mean),
        "{stats:?}"
    );
    assert!(
        (0.02..0.5).contains(&stats.pitch_change_deg.mean),
        "{stats:?}"
    );
    let ground = &stats.ground_ring_displacement_m;
    assert!((0.01..0.3).contains(&ground.median), "{ground:?}");
    assert!(stats.ground_pairs_skipped <= 2, "{stats:?}");
    let along = stats.information_share_pct[0];
    assert!(
        (25.0..60.0).contains(&along),
        "{:?}",
        stats.information_share_pct
    );
    assert!((100_000.0..140_000.0).contains(&stats.points_per_sweep_mean));
    assert!((4.0..30.0).contains(&stats.range_median_m), "{stats:?}");
}
