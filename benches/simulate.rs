//! `limot simulate` end to end: the scene build, the rolling LiDAR, IMU,
//! detector and ground truth, and the writing of the dataset with its KITTI
//! copy, for urban (seed 2) and highway (seed 1) on 2 and 1 rayon threads,
//! three interleaved runs each, medians:
//! `cargo bench -p limot --bench simulate [-- SECONDS]` (default 20 s of drive).
//!
//! Frames/s is the command's own figure (frames over the wall time from the
//! scene build to the last file); MB/s the bytes it wrote per wall second.

use limot::simulate::{resolve_scenario, simulate};
use limot_test_support::bench;
use std::path::Path;

/// The allocator of the `limot` binary, so the figures are its figures.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Bytes of every file below `dir`.
fn tree_bytes(dir: &Path) -> u64 {
    let mut total = 0;
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).expect("readable output") {
            let entry = entry.expect("readable entry");
            let meta = entry.metadata().expect("metadata");
            if meta.is_dir() {
                stack.push(entry.path());
            } else {
                total += meta.len();
            }
        }
    }
    total
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    limot::allocator::keep_freed_pages();
    let seconds: f64 = bench::args()
        .iter()
        .find_map(|a| a.parse().ok())
        .unwrap_or(20.0);
    let cases = [("urban", 2), ("highway", 1)];
    let thread_counts = [2, 1];
    let pools = thread_counts
        .iter()
        .map(|&n| rayon::ThreadPoolBuilder::new().num_threads(n).build())
        .collect::<Result<Vec<_>, _>>()?;
    let mut results = vec![Vec::new(); cases.len() * thread_counts.len()];
    for _ in 0..3 {
        for (c, (name, seed)) in cases.iter().enumerate() {
            let mut spec = resolve_scenario(name)?;
            spec.duration_s = seconds;
            spec.seed = *seed;
            for (t, pool) in pools.iter().enumerate() {
                let dir = std::env::temp_dir()
                    .join(format!("limot-bench-simulate-{}", std::process::id()));
                let _ = std::fs::remove_dir_all(&dir);
                let summary = pool.install(|| simulate(&spec, &dir, true, false))?;
                let bytes = tree_bytes(&dir) as f64;
                std::fs::remove_dir_all(&dir)?;
                results[c * thread_counts.len() + t].push((
                    summary.frames as f64 / summary.wall_time_s,
                    summary.wall_time_s,
                    bytes / summary.wall_time_s / 1e6,
                    bytes / summary.frames as f64 / 1e6,
                ));
            }
        }
    }
    println!("simulate, {seconds} s drives, dataset + KITTI copy, median of 3 interleaved runs");
    println!("| scenario | threads | frames/s | wall [s] | written [MB/s] | per frame [MB] |");
    println!("|---|---|---|---|---|---|");
    for (c, (name, seed)) in cases.iter().enumerate() {
        for (t, threads) in thread_counts.iter().enumerate() {
            let runs = &results[c * thread_counts.len() + t];
            let pick = |f: fn(&(f64, f64, f64, f64)) -> f64| median(runs.iter().map(f).collect());
            println!(
                "| {name} s{seed} | {threads} | {:.1} | {:.2} | {:.0} | {:.2} |",
                pick(|r| r.0),
                pick(|r| r.1),
                pick(|r| r.2),
                pick(|r| r.3)
            );
        }
    }
    Ok(())
}
