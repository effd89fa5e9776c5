//! `limot simulate`: simulate a scenario into a dataset.

use crate::simulate::{Overrides, prepare_output_dir, resolve_scenario, simulate};

pub(super) fn run_simulate(
    scenario: &str,
    out: &std::path::Path,
    overrides: Overrides,
    kitti: bool,
    print: bool,
    force: bool,
    mcap: Option<&std::path::Path>,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut spec = resolve_scenario(scenario)?;
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
