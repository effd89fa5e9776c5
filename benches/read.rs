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
use std::path::PathBuf;
use std::time::Instant;

/// The allocator of the `limot` binary, so the figures are its figures.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// FNV-1a step over 64-bit words.
fn hash_words(hash: &mut u64, words: impl IntoIterator<Item = u64>) {
    for word in words {
        *hash = (*hash ^ word).wrapping_mul(0x0100_0000_01b3);
    }
}

fn main() {
    limot::allocator::keep_freed_pages();
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
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
    let mut hash = 0xcbf2_9ce4_8422_2325_u64;
    let mut points = 0usize;
    for run in 0..runs {
        for (i, best) in best_ms.iter_mut().enumerate() {
            let clock = Instant::now();
            let frame = source.frame(i).expect("frame");
            let ms = clock.elapsed().as_secs_f64() * 1e3;
            *best = best.min(ms);
            if run == 0 {
                points += frame.scan.points.len();
                hash_words(
                    &mut hash,
                    frame.scan.points.iter().flat_map(|p| {
                        [p.x, p.y, p.z, p.intensity, p.time_offset_s]
                            .map(|v| u64::from(v.to_bits()))
                            .into_iter()
                            .chain([u64::from(p.ring)])
                    }),
                );
            }
            std::hint::black_box(frame);
        }
    }
    let mut sorted = best_ms.clone();
    sorted.sort_by(f64::total_cmp);
    let mean = sorted.iter().sum::<f64>() / frames.max(1) as f64;
    let p95 = sorted[((frames.max(1) - 1) as f64 * 0.95).round() as usize];
    println!(
        "{frames} frames, {} points each, hash {hash:016x}",
        points / frames.max(1)
    );
    println!("read per frame (fastest of {runs}): mean {mean:.3} ms, p95 {p95:.3} ms");
}
