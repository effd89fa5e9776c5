//! Per-frame time of reading the input as `limot run` does (file read,
//! decoding, validation, detections), one thread:
//! `cargo bench -p limot --bench read -- DIR [--sequence N] [--runs R]`.
//!
//! DIR is a limot dataset or a KITTI tracking `training` directory (with
//! `--sequence`). Every frame is read `R` times (default 5) and the fastest
//! kept (the page cache holds the files after the first pass); the mean and
//! p95 over frames are printed, with a hash of every point's bits (to check
//! that a change decodes the same points).

use limot::io::Source;
use limot::io::kitti::detections::ScoreMap;
use limot_test_support::bench::{self, Fnv1a, mean_p95};
use std::path::PathBuf;
use std::time::Instant;

/// The allocator of the `limot` binary, so the figures are its figures.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    limot::allocator::keep_freed_pages();
    let args = bench::args();
    let dir = PathBuf::from(
        args.first()
            .expect("usage: read DIR [--sequence N] [--runs R]"),
    );
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .map(|i| args[i + 1].parse::<u32>().expect("a number after the flag"))
    };
    let runs = value("--runs").unwrap_or(5).max(1);
    let source = match value("--sequence") {
        Some(s) => Source::open_kitti_tracking(&dir, s, None, ScoreMap::Sigmoid),
        None => Source::open(&dir),
    }
    .expect("open the data");
    let frames = source.frame_count();
    let mut best_ms = vec![f64::INFINITY; frames];
    let mut hash = Fnv1a::new();
    let mut points = 0usize;
    for run in 0..runs {
        for (i, best) in best_ms.iter_mut().enumerate() {
            let clock = Instant::now();
            let frame = source.frame(i).expect("frame");
            let ms = clock.elapsed().as_secs_f64() * 1e3;
            *best = best.min(ms);
            if run == 0 {
                points += frame.scan.points.len();
                hash.write(frame.scan.points.iter().flat_map(|p| {
                    [p.x, p.y, p.z, p.intensity, p.time_offset_s]
                        .map(|v| u64::from(v.to_bits()))
                        .into_iter()
                        .chain([u64::from(p.ring)])
                }));
            }
            std::hint::black_box(frame);
        }
    }
    let (mean, p95) = mean_p95(best_ms);
    println!(
        "{frames} frames, {} points each, hash {:016x}",
        points / frames.max(1),
        hash.finish()
    );
    println!("read per frame (fastest of {runs}): mean {mean:.3} ms, p95 {p95:.3} ms");
}
