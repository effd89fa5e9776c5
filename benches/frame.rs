//! Per-frame time of `limot run`, stage by stage, one core, steady on a
//! loaded machine:
//! `cargo bench -p limot --bench frame -- DIR [--sequence N --detections D]
//! [--variant V] [--runs R] [--grid-cell M] [--no-cell-planes]`.
//!
//! DIR is any source `limot run` reads (a limot dataset, or a KITTI tracking
//! `training` directory with `--sequence`; then the settings are those of
//! `limot run --sequence N --tracker tuned --score-map sigmoid`). The whole
//! run is repeated R times (default 5); a run is deterministic, so every
//! repetition does the same work, and each frame's stage takes the fastest of
//! its R times: what another process on the core added is dropped. Printed:
//! the mean and p95 over frames of each stage and of the frame's total (the
//! sum of its stages' best times), and the fastest whole run's mean total
//! for comparison. `--grid-cell M` overrides the local map's grid cell
//! (`local_map.grid_cell_m`), to measure the map's layout against its cost;
//! `--no-cell-planes` matches every planar point by k-NN
//! (`local_map.cell_planes = None`).

use limot::io::Source;
use limot::io::kitti::detections::ScoreMap;
use limot::run::{RunOptions, kitti_tracking_config, run};
use limot_estimator::pipeline::{EstimatorConfig, Variant};
use limot_test_support::bench::{self, mean_p95};
use std::path::PathBuf;
use std::time::Duration;

/// The allocator of the `limot` binary, so the figures are its figures.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn value_of<'a>(args: &'a [String], flag: &str) -> Option<&'a str> {
    args.iter()
        .position(|a| a == flag)
        .and_then(|i| args.get(i + 1))
        .map(String::as_str)
}

fn main() {
    limot::allocator::keep_freed_pages();
    let args = bench::args();
    let usage = "usage: frame DIR [--sequence N --detections D] [--variant V] [--runs R] [--grid-cell M] [--no-cell-planes]";
    let dir = PathBuf::from(args.first().expect(usage));
    let variant: Variant = value_of(&args, "--variant")
        .unwrap_or("limot")
        .parse()
        .expect("--variant: lio, allfilt, dynafilt or limot");
    let runs: usize = value_of(&args, "--runs")
        .map(|r| r.parse().expect("--runs is a number"))
        .unwrap_or(5)
        .max(1);
    let sequence = value_of(&args, "--sequence").map(|s| s.parse::<u32>().expect("sequence"));
    let detections = value_of(&args, "--detections").map(PathBuf::from);
    let (source, config) = match sequence {
        Some(s) => (
            Source::open_kitti_tracking(&dir, s, detections.as_deref(), ScoreMap::Sigmoid),
            EstimatorConfig {
                // the filter's score is not timed
                record_feature_indices: false,
                ..kitti_tracking_config(
                    limot::experiments::kitti_val_tuned_options().tracker,
                    variant,
                )
            },
        ),
        None => (Source::open(&dir), EstimatorConfig::default()),
    };
    let source = source.expect("open the data");
    let mut config = config;
    if let Some(cell) = value_of(&args, "--grid-cell") {
        config.local_map.grid_cell_m = cell.parse().expect("--grid-cell is a number");
    }
    if args.iter().any(|a| a == "--no-cell-planes") {
        config.local_map.cell_planes = None;
    }
    let options = RunOptions {
        variant,
        ..RunOptions::default()
    };

    // best[frame][stage]
    let mut best: Vec<Vec<(&'static str, Duration)>> = Vec::new();
    let mut best_run_mean = f64::INFINITY;
    for _ in 0..runs {
        let output = run(&source, &dir, &options, Some(config.clone())).expect("run");
        let mut run_total = Duration::ZERO;
        for (i, e) in output.estimates.iter().enumerate() {
            let stages = e.timings.stages();
            run_total += e.timings.total();
            if best.len() <= i {
                best.push(stages.to_vec());
            } else {
                for (b, (_, d)) in best[i].iter_mut().zip(stages) {
                    b.1 = b.1.min(d);
                }
            }
        }
        let mean_ms = run_total.as_secs_f64() * 1e3 / output.estimates.len().max(1) as f64;
        best_run_mean = best_run_mean.min(mean_ms);
    }
    let Some(first) = best.first() else {
        println!("no frames estimated");
        return;
    };
    println!(
        "{} frames, {variant}, best of {runs} runs per frame and stage (ms, mean / p95)",
        best.len()
    );
    for (s, (name, _)) in first.iter().enumerate() {
        let (mean, p95) = mean_p95(best.iter().map(|f| f[s].1.as_secs_f64() * 1e3).collect());
        println!("{name:>15} {mean:7.3} / {p95:7.3}");
    }
    let (mean, p95) = mean_p95(
        best.iter()
            .map(|f| f.iter().map(|(_, d)| d.as_secs_f64()).sum::<f64>() * 1e3)
            .collect(),
    );
    println!("{:>15} {mean:7.3} / {p95:7.3}", "total");
    println!("fastest whole run: mean total {best_run_mean:.3} ms per frame");
}
