//! Per-scan time of LOAM feature extraction and the voxel downsampling of
//! its edge and planar points, one thread, on real or simulated scans:
//! `cargo bench -p limot --bench features -- DIR [--sequence N] [FRAMES]`.
//!
//! DIR is a limot dataset or a KITTI tracking `training` directory (with
//! `--sequence`). The scans are read first (not timed) and used as they are
//! (no de-skew: its cost is not what this measures); each stage is timed per
//! scan, median over repetitions (or with `--best` the fastest repetition,
//! steadier on a loaded machine), and the mean and p95 over scans printed,
//! with a hash of every feature index and downsampled coordinate (to check
//! that a change leaves the outputs bit for bit as they were).

use limot::io::Source;
use limot::io::kitti::detections::ScoreMap;
use limot_estimator::lidar::{FeatureConfig, FeatureExtractor, VoxelDownsampler};
use limot_test_support::bench::{self, Fnv1a, mean_p95};
use nalgebra::Vector3;
use std::path::PathBuf;
use std::time::Instant;

/// Planar and edge voxel edges of the pipeline's defaults, m.
const EDGE_VOXEL_M: f64 = 0.2;
const PLANAR_VOXEL_M: f64 = 0.4;
const REPS: usize = 7;

fn main() {
    let args = bench::args();
    let dir = PathBuf::from(
        args.first()
            .expect("usage: features DIR [--sequence N] [FRAMES]"),
    );
    let best = args.iter().any(|a| a == "--best");
    let sequence = args
        .iter()
        .position(|a| a == "--sequence")
        .map(|i| args[i + 1].parse::<u32>().expect("sequence number"));
    // positional arguments: DIR, then FRAMES (the value after --sequence is not one)
    let positional: Vec<&String> = args
        .iter()
        .enumerate()
        .filter(|(i, a)| !a.starts_with("--") && (*i == 0 || args[i - 1] != "--sequence"))
        .map(|(_, a)| a)
        .collect();
    let frames: usize = positional
        .get(1)
        .map(|a| a.parse().expect("FRAMES is a number"))
        .unwrap_or(40);
    let source = match sequence {
        Some(s) => Source::open_kitti_tracking(&dir, s, None, ScoreMap::Sigmoid),
        None => Source::open(&dir),
    }
    .expect("open the data");
    let scans: Vec<_> = (0..source.frame_count().min(frames))
        .map(|i| source.frame(i).expect("frame").scan)
        .collect();
    let mut extractor = FeatureExtractor::new(FeatureConfig::default());
    let mut downsampler = VoxelDownsampler::default();
    let (mut features_ms, mut downsample_ms) = (Vec::new(), Vec::new());
    let (mut planar_in, mut planar_out) = (0usize, 0usize);
    let mut hash = Fnv1a::new();
    for scan in &scans {
        let positions: Vec<Vector3<f64>> = scan.points.iter().map(|p| p.position()).collect();
        let mut f_reps = Vec::new();
        let mut d_reps = Vec::new();
        for _ in 0..REPS {
            let clock = Instant::now();
            let features = extractor.extract(&positions, scan);
            f_reps.push(clock.elapsed().as_secs_f64() * 1e3);
            let clock = Instant::now();
            // gathered first, as the pipeline does
            let edges: Vec<_> = features
                .edge_indices
                .iter()
                .map(|&i| positions[i])
                .collect();
            let e = downsampler.downsample(&edges, EDGE_VOXEL_M);
            let planar: Vec<_> = features
                .planar_indices
                .iter()
                .map(|&i| positions[i])
                .collect();
            let p = downsampler.downsample(&planar, PLANAR_VOXEL_M);
            d_reps.push(clock.elapsed().as_secs_f64() * 1e3);
            planar_in = features.planar_indices.len();
            planar_out = p.len();
            if f_reps.len() == 1 {
                let indices = features.edge_indices.iter().chain(&features.planar_indices);
                hash.write(indices.map(|&i| i as u64));
                let coordinates = e.iter().chain(&p).flat_map(|v| v.iter().copied());
                hash.write(coordinates.map(f64::to_bits));
            }
            std::hint::black_box((e, &p));
        }
        f_reps.sort_by(f64::total_cmp);
        d_reps.sort_by(f64::total_cmp);
        let pick = if best { 0 } else { REPS / 2 };
        features_ms.push(f_reps[pick]);
        downsample_ms.push(d_reps[pick]);
    }
    let points = scans.iter().map(|s| s.points.len()).sum::<usize>() / scans.len().max(1);
    let (fm, fp) = mean_p95(features_ms);
    let (dm, dp) = mean_p95(downsample_ms);
    println!(
        "{} scans, {points} points each (last: {planar_in} planar -> {planar_out}), hash {:016x}",
        scans.len(),
        hash.finish()
    );
    println!("features   mean {fm:.3} ms  p95 {fp:.3} ms");
    println!("downsample mean {dm:.3} ms  p95 {dp:.3} ms");
    println!("together   mean {:.3} ms", fm + dm);
}
