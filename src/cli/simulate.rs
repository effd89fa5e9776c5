//! `limot simulate`: simulate a scenario into a dataset.

use crate::simulate::{Overrides, kitti_scenario, prepare_output_dir, resolve_scenario, simulate};
use std::path::PathBuf;

/// The `kitti` scenario's arguments.
pub(super) struct TwinArgs {
    pub training: Option<PathBuf>,
    pub sequence: Option<u32>,
    pub first_frame: usize,
    pub frames: Option<usize>,
    pub corridor: Option<String>,
    pub detections: Option<PathBuf>,
}

pub(super) fn run_simulate(
    scenario: &str,
    twin: TwinArgs,
    out: &std::path::Path,
    overrides: Overrides,
    kitti: bool,
    print: bool,
    force: bool,
    mcap: Option<&std::path::Path>,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut spec = if scenario == "kitti" && !std::path::Path::new(scenario).exists() {
        let (Some(training), Some(sequence)) = (twin.training, twin.sequence) else {
            return Err("`simulate kitti` needs --training DIR and --sequence N".into());
        };
        kitti_scenario(
            &training,
            sequence,
            twin.first_frame,
            twin.frames,
            twin.corridor.as_deref(),
            twin.detections.as_deref(),
        )?
    } else {
        if twin.training.is_some() || twin.sequence.is_some() || twin.detections.is_some() {
            return Err(format!(
                "--training, --sequence and --detections are for `simulate kitti`, not `{scenario}`"
            )
            .into());
        }
        resolve_scenario(scenario)?
    };
    overrides.apply(&mut spec)?;
    if print {
        print!("{}", spec.to_toml());
        return Ok(());
    }
    prepare_output_dir(out, force)?;
    let s = simulate(&spec, out, kitti, true)?;
    println!(
        "simulated `{}` (seed {}): {} frames, {} agents, {} points, {} detections in {:.1} s ({:.1} frames/s)",
        spec.name,
        spec.seed,
        s.frames,
        s.agents,
        s.points,
        s.detections,
        s.wall_time_s,
        s.frames as f64 / s.wall_time_s.max(1e-9)
    );
    if let Some(r) = &s.replay {
        println!(
            "twin: ego fit residual rms {:.3} m / max {:.3} m, {:.4} / {:.4} rad, peak accel {:.2} m/s^2; \
             ground under the ego rms {:.3} m / max {:.3} m; corridor {}, {} statics; \
             agents {} moving, {} parked ({} splits, {} bridged frames, {} duplicate boxes)",
            r.ego_fit.position_rms_m,
            r.ego_fit.position_max_m,
            r.ego_fit.rotation_rms_rad,
            r.ego_fit.rotation_max_rad,
            r.ego_fit.accel_max_mps2,
            r.ground.rms_m,
            r.ground.max_m,
            r.corridor.name(),
            r.statics,
            r.tracks.moving,
            r.tracks.parked,
            r.tracks.splits,
            r.tracks.bridged_frames,
            r.tracks.duplicates,
        );
    }
    if let Some(n) = &s.twin {
        println!(
            "KITTI frames {}..{} ({} m driven), {} with degraded GPS, labels left out: {:?}, reused ids: {}{}",
            n.first_frame,
            n.first_frame + n.frames,
            n.path_length_m.round(),
            n.degraded_gps_frames,
            n.skipped_labels,
            n.reused_ids,
            if n.no_labels { " (no label file)" } else { "" }
        );
    }
    println!("dataset: {}", s.dataset_dir.display());
    if let Some(k) = &s.kitti_dir {
        println!("KITTI-style copy: {}", k.display());
    }
    if let Some(path) = mcap {
        let stats = crate::simulate::record_dataset_mcap(&s.dataset_dir, path)?;
        super::print_mcap(&stats);
    }
    Ok(())
}
