//! The simulator's sweeps without the writing: frames of a built-in scenario
//! through `Simulation::frame` (rolling LiDAR, IMU, detections, truth), three
//! runs, with the best run's sweeps/s and a hash of every point (x, y, z,
//! intensity, label), to tell whether a change keeps the sweeps bit-identical:
//! `cargo bench -p limot-sim --bench sweep [-- SCENARIO [SEED [FRAMES]]]`
//! (default: urban, seed 2, 20 frames).
//!
//! `limot simulate` end to end, writing included, is `cargo bench -p limot
//! --bench simulate`; the LiDAR alone, `cargo bench -p limot-sim --bench lidar`.

use limot_sim::{ScenarioSpec, Simulation};
use limot_test_support::bench::{self, Fnv1a};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = bench::args();
    let name = args.first().map_or("urban", String::as_str);
    let seed: u64 = args.get(1).map_or(Ok(2), |s| s.parse())?;
    let frames: usize = args.get(2).map_or(Ok(20), |s| s.parse())?;
    let mut spec = ScenarioSpec::builtin(name).ok_or("no such built-in scenario")?;
    spec.seed = seed;
    // frames at 10 Hz, and a little more so that the last frame's sweep ends
    // inside the drive
    spec.duration_s = frames as f64 * 0.1 + 0.05;
    let start = Instant::now();
    let sim = Simulation::new(&spec)?;
    let build_s = start.elapsed().as_secs_f64();
    let mut best_s = f64::INFINITY;
    let mut hashes = Vec::new();
    let mut points = 0;
    for _ in 0..3 {
        let start = Instant::now();
        let mut hash = Fnv1a::new();
        points = 0;
        for index in 0..sim.frame_count() {
            let frame = sim.frame(index)?;
            let recorded = &frame.recorded;
            for (p, label) in recorded.scan.points.iter().zip(&recorded.labels) {
                let fields = [p.x, p.y, p.z, p.intensity].map(f32::to_bits);
                hash.write(fields.into_iter().chain([*label]).map(u64::from));
            }
            points += recorded.scan.points.len();
        }
        best_s = best_s.min(start.elapsed().as_secs_f64());
        hashes.push(hash.finish());
    }
    if hashes.iter().any(|&h| h != hashes[0]) {
        return Err(format!("the runs' sweeps differ: {hashes:016x?}").into());
    }
    println!(
        "{name} seed {seed}: {} frames, {points} points, hash {:016x}; scene {build_s:.3} s, \
         best of 3: {best_s:.3} s, {:.1} sweeps/s",
        sim.frame_count(),
        hashes[0],
        sim.frame_count() as f64 / best_s
    );
    Ok(())
}
