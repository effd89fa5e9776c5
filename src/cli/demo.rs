//! `limot demo`: simulate, score and report the default urban scenario.

use crate::demo::run_demo as demo;
use crate::simulate::{Overrides, resolve_scenario};

pub(super) fn run_demo(
    scenario: &str,
    out: &std::path::Path,
    duration_s: Option<f64>,
    mcap: Option<&crate::io::mcap::McapRequest>,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut spec = resolve_scenario(scenario)?;
    Overrides {
        seed: None,
        duration_s,
    }
    .apply(&mut spec)?;
    println!(
        "limot demo: simulating `{}` ({} s, seed {}) into {}",
        spec.name,
        spec.duration_s,
        spec.seed,
        out.display()
    );
    let s = demo(&spec, out, true, mcap)?;
    println!(
        "{} sweeps, {:.0} points per sweep, {} moving and {} parked agents, ego drove {:.0} m",
        s.frames, s.mean_points_per_scan, s.moving_agents, s.parked_agents, s.ego_path_length_m
    );
    for (threshold, r) in &s.detector {
        println!(
            "detector at 3D IoU {threshold}: MOTA {:.1} %, MOTP {:.1} % ({} matches, {} FP, {} FN; oracle ids)",
            r.mota.unwrap_or(f64::NAN) * 100.0,
            r.motp.unwrap_or(f64::NAN) * 100.0,
            r.matches,
            r.false_positives,
            r.false_negatives
        );
    }
    for e in &s.estimators {
        println!(
            "estimator {}: ego ATE_T {:.3} m, ATE_R {:.4} rad over {} frames ({} LiDAR-only before initialisation); \
             tracks MOTA {:.1} %, MOTP {:.1} % (3D IoU 0.25); {:.1} ms/frame, {:.1} FPS; {}",
            e.variant,
            e.ate_t_m,
            e.ate_r_rad,
            e.frames_estimated,
            e.frames_before_init,
            e.tracks.mota.unwrap_or(f64::NAN) * 100.0,
            e.tracks.motp.unwrap_or(f64::NAN) * 100.0,
            e.mean_frame_ms,
            e.fps,
            e.trajectory.display()
        );
    }
    if let Some(stats) = &s.mcap {
        super::print_mcap(stats);
    }
    println!("report: {}", s.report_readme.display());
    Ok(())
}
