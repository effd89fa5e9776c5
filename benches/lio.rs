//! Per-scan time of the `lio` path split by module, one thread, on the
//! default urban scenario (64-beam sweeps of ~120k points):
//! `cargo bench -p limot --bench lio [-- SECONDS]`.
//!
//! A plain timing main: the scenario is simulated first (not timed), then
//! the estimator runs over every frame on the calling thread.

use limot::simulate::resolve_scenario;
use limot_estimator::input::Frame;
use limot_estimator::pipeline::{Estimator, EstimatorConfig, FrameEstimate};
use limot_sim::Simulation;
use std::time::{Duration, Instant};

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn main() {
    let seconds: f64 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(20.0);
    let mut spec = resolve_scenario("urban").expect("built-in scenario");
    spec.duration_s = seconds;
    let sim = Simulation::new(&spec).expect("scenario builds");
    let clock = Instant::now();
    let frames: Vec<Frame> = (0..sim.frame_count())
        .map(|i| {
            let f = sim.frame(i).expect("frame");
            Frame {
                scan: f.recorded.scan,
                detections: f.recorded.detections.iter().map(|d| d.detection).collect(),
            }
        })
        .collect();
    let imu = sim.imu_stream().expect("imu").samples;
    let extrinsics = limot_estimator::input::Extrinsics {
        t_lidar_imu: sim.meta().t_lidar_imu(),
    };
    let points: usize = frames.iter().map(|f| f.scan.points.len()).sum();
    println!(
        "simulated {} frames ({:.0} points/scan) in {:.1?}",
        frames.len(),
        points as f64 / frames.len() as f64,
        clock.elapsed()
    );

    let mut estimator = Estimator::new(EstimatorConfig::default(), extrinsics).expect("config");
    let mut estimates: Vec<FrameEstimate> = Vec::new();
    let mut next = 0;
    let clock = Instant::now();
    for frame in &frames {
        let end = frame.scan.t_s + frame.scan.sweep_duration_s;
        while next < imu.len() && imu[next].t_s <= end + 1e-9 {
            estimator.push_imu(imu[next]).expect("imu");
            next += 1;
        }
        estimates.extend(estimator.push_frame(frame).expect("frame"));
    }
    let wall = clock.elapsed();
    let stages = estimates[0].timings.stages().map(|(n, _)| n);
    println!("\n| stage | mean ms | median ms | p95 ms |\n|---|---|---|---|");
    for (i, name) in stages.iter().enumerate() {
        let mut d: Vec<Duration> = estimates.iter().map(|e| e.timings.stages()[i].1).collect();
        d.sort();
        let mean = d.iter().sum::<Duration>() / d.len() as u32;
        println!(
            "| {name} | {:.2} | {:.2} | {:.2} |",
            mean.as_secs_f64() * 1e3,
            percentile(&d, 0.5).as_secs_f64() * 1e3,
            percentile(&d, 0.95).as_secs_f64() * 1e3
        );
    }
    let mut totals: Vec<Duration> = estimates.iter().map(|e| e.timings.total()).collect();
    totals.sort();
    let mean = totals.iter().sum::<Duration>() / totals.len() as u32;
    println!(
        "| total | {:.2} | {:.2} | {:.2} |",
        mean.as_secs_f64() * 1e3,
        percentile(&totals, 0.5).as_secs_f64() * 1e3,
        percentile(&totals, 0.95).as_secs_f64() * 1e3
    );
    println!(
        "\n{} frames estimated in {:.2?} wall: {:.1} FPS on one thread",
        estimates.len(),
        wall,
        estimates.len() as f64 / wall.as_secs_f64()
    );
}
