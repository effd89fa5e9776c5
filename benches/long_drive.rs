//! Memory over a long drive: streams a simulated drive frame by frame (no
//! frame is kept) through the estimator and prints, once per simulated
//! minute, the estimator's [`Footprint`] and the process's resident memory,
//! then the peak: `cargo bench -p limot --bench long_drive [-- SECONDS
//! [VARIANT [FAMILY]]]` (default 600 s of `limot` on `urban`).
//!
//! Every footprint count should level off once the window and the map
//! radius are full; the resident memory should stop growing with them.

use limot::simulate::resolve_scenario;
use limot_estimator::input::Frame;
use limot_estimator::pipeline::{Estimator, EstimatorConfig, Footprint, Variant};
use limot_sim::Simulation;
use limot_test_support::bench;
use std::time::Instant;

/// `VmRSS` / `VmHWM` of this process in MiB (Linux), or NaN elsewhere.
fn memory_mib(field: &str) -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with(field))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kib| kib.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

fn row(t_s: f64, f: &Footprint) -> String {
    format!(
        "| {t_s:.0} | {} | {} | {} | {} | {} | {} | {} | {} | {:.0} |",
        f.imu_samples,
        f.map_keyframes,
        f.map_points,
        f.window_frames,
        f.tracks,
        f.lost_tracks,
        f.objects,
        f.bootstrap_frames,
        memory_mib("VmRSS:")
    )
}

fn main() {
    let args = bench::args();
    let seconds: f64 = args.first().and_then(|a| a.parse().ok()).unwrap_or(600.0);
    let variant = match args.get(1).map_or("limot", String::as_str) {
        "lio" => Variant::Lio,
        "allfilt" => Variant::Allfilt,
        "dynafilt" => Variant::Dynafilt,
        _ => Variant::Limot,
    };
    let family = args.get(2).map_or("urban", String::as_str);
    let mut spec = resolve_scenario(family).expect("built-in scenario");
    spec.duration_s = seconds;
    let sim = Simulation::new(&spec).expect("scenario builds");
    let imu = sim.imu_stream().expect("imu").samples;
    let extrinsics = limot_estimator::input::Extrinsics {
        t_lidar_imu: sim.meta().t_lidar_imu(),
    };
    let config = EstimatorConfig {
        variant,
        ..EstimatorConfig::default()
    };
    let mut estimator = Estimator::new(config, extrinsics).expect("config");
    println!(
        "{family}, {seconds} s, {variant:?}: {} frames streamed\n",
        sim.frame_count()
    );
    println!(
        "| t [s] | IMU samples | map keyframes | map points | window | tracks | lost tracks | objects | bootstrap | RSS [MiB] |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let clock = Instant::now();
    let (mut next, mut estimates, mut next_report_s) = (0, 0usize, 60.0);
    let mut peak = Footprint::default();
    for i in 0..sim.frame_count() {
        let f = sim.frame(i).expect("frame");
        let frame = Frame {
            scan: f.recorded.scan,
            detections: f.recorded.detections.iter().map(|d| d.detection).collect(),
        };
        let end = frame.scan.t_s + frame.scan.sweep_duration_s;
        while next < imu.len() && imu[next].t_s <= end + 1e-9 {
            estimator.push_imu(imu[next]).expect("imu");
            next += 1;
        }
        estimates += estimator.push_frame(&frame).expect("frame").len();
        let now = estimator.footprint();
        peak = Footprint {
            imu_samples: peak.imu_samples.max(now.imu_samples),
            map_keyframes: peak.map_keyframes.max(now.map_keyframes),
            map_points: peak.map_points.max(now.map_points),
            window_frames: peak.window_frames.max(now.window_frames),
            tracks: peak.tracks.max(now.tracks),
            lost_tracks: peak.lost_tracks.max(now.lost_tracks),
            objects: peak.objects.max(now.objects),
            bootstrap_frames: peak.bootstrap_frames.max(now.bootstrap_frames),
        };
        if frame.scan.t_s >= next_report_s {
            println!("{}", row(frame.scan.t_s, &now));
            next_report_s += 60.0;
        }
    }
    println!(
        "| peak | {} | {} | {} | {} | {} | {} | {} | {} | {:.0} (VmHWM) |",
        peak.imu_samples,
        peak.map_keyframes,
        peak.map_points,
        peak.window_frames,
        peak.tracks,
        peak.lost_tracks,
        peak.objects,
        peak.bootstrap_frames,
        memory_mib("VmHWM:")
    );
    println!(
        "\n{estimates} estimates in {:.0?} (simulation included)",
        clock.elapsed()
    );
}
