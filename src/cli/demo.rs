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
    // every row against the same truth: the camera-visible boxes the tracks are judged on
    let line = |what: &str, r: &crate::metrics::ClearMotResult| {
        format!(
            "{what}: MOTA {:.1} %, MOTP {:.1} %, FP {}, FN {}, IDSW {} ({} truth boxes)",
            r.mota.unwrap_or(f64::NAN) * 100.0,
            r.motp.unwrap_or(f64::NAN) * 100.0,
            r.false_positives,
            r.false_negatives,
            r.id_switches,
            r.gt_count
        )
    };
    for (k, (threshold, r)) in s.detector.iter().enumerate() {
        println!(
            "{}",
            line(&format!("3D IoU {threshold}: detector (oracle ids)"), r)
        );
        for e in &s.estimators {
            println!(
                "{}",
                line(
                    &format!("3D IoU {threshold}: {} tracks", e.variant),
                    &e.tracks[k]
                )
            );
        }
    }
    for e in &s.estimators {
        println!(
            "estimator {}: ego ATE_T {:.3} m, ATE_R {:.4} rad over {} frames ({} LiDAR-only before initialisation); \
             {:.1} ms/frame, {:.1} FPS; {}",
            e.variant,
            e.ate_t_m,
            e.ate_r_rad,
            e.frames_estimated,
            e.frames_before_init,
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
