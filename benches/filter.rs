//! Time of the dynamic feature filter (`dynamic_feature_mask`) on whole
//! simulated urban sweeps (64 beams, ~120k points), one thread:
//! `cargo bench -p limot --bench filter [-- FRAMES]`.
//!
//! Every point of a sweep is tested (the estimator tests only the feature
//! points), against each detection of the sweep as a box moving at 10 m/s
//! along its heading, with the ego moving at 10 m/s along x; the mask is
//! computed several times per sweep and the median is kept.

use limot::simulate::resolve_scenario;
use limot_estimator::object_removal::{
    BoxAtTime, ConstantVelocityBox, FilterConfig, dynamic_feature_mask,
};
use limot_sim::Simulation;
use nalgebra::{Isometry3, Vector3};
use std::time::{Duration, Instant};

fn main() {
    let frames: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(10);
    let mut spec = resolve_scenario("urban").expect("built-in scenario");
    spec.duration_s = 0.1 * (frames as f64 + 1.0);
    let sim = Simulation::new(&spec).expect("scenario builds");
    let config = FilterConfig::default();
    let reps = 20;
    let mut medians = Vec::new();
    let (mut points_total, mut boxes_total, mut removed_total) = (0, 0, 0);
    for i in 0..frames.min(sim.frame_count()) {
        let frame = sim.frame(i).expect("frame");
        let scan = &frame.recorded.scan;
        let points: Vec<Vector3<f64>> = scan.points.iter().map(|p| p.position()).collect();
        let times: Vec<f64> = scan
            .points
            .iter()
            .map(|p| scan.t_s + f64::from(p.time_offset_s))
            .collect();
        let t0_s = scan.t_s;
        let ego = move |t_s: f64| Isometry3::translation(10.0 * (t_s - t0_s), 0.0, 0.0);
        let moving: Vec<ConstantVelocityBox> = frame
            .recorded
            .detections
            .iter()
            .map(|d| {
                let b = d.detection.box_lidar.transformed(&ego(t0_s));
                ConstantVelocityBox {
                    box_ref: b,
                    t_ref_s: t0_s,
                    velocity_world_mps: 10.0 * Vector3::new(b.yaw_rad.cos(), b.yaw_rad.sin(), 0.0),
                    yaw_rate_radps: 0.0,
                }
            })
            .collect();
        let boxes: Vec<&dyn BoxAtTime> = moving.iter().map(|b| b as &dyn BoxAtTime).collect();
        let mut runs: Vec<Duration> = (0..reps)
            .map(|_| {
                let clock = Instant::now();
                let mask = dynamic_feature_mask(&points, &times, &ego, &boxes, &config);
                let elapsed = clock.elapsed();
                std::hint::black_box(mask.expect("valid input"));
                elapsed
            })
            .collect();
        runs.sort();
        medians.push(runs[reps / 2]);
        let mask = dynamic_feature_mask(&points, &times, &ego, &boxes, &config).expect("mask");
        points_total += points.len();
        boxes_total += boxes.len();
        removed_total += mask.iter().filter(|&&m| m).count();
    }
    let n = medians.len();
    let mean = medians.iter().sum::<Duration>() / n as u32;
    println!(
        "{n} sweeps, {:.0} points and {:.1} boxes per sweep, {:.0} points removed per sweep",
        points_total as f64 / n as f64,
        boxes_total as f64 / n as f64,
        removed_total as f64 / n as f64
    );
    println!(
        "dynamic_feature_mask: {:.3} ms per sweep (mean over sweeps of the median of {reps} runs)",
        mean.as_secs_f64() * 1e3
    );
}
