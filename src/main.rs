//! `limot`: command-line interface.

use clap::{Parser, Subcommand};
use limot::demo::run_demo as demo;
use limot::simulate::{Overrides, resolve_scenario, simulate};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "limot",
    version,
    about = "LiDAR-inertial odometry and multi-object tracking, with a simulation testbed"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a scenario into a dataset (limot format plus a KITTI-style copy in OUT/kitti).
    Simulate {
        /// Scenario TOML file, or a built-in scenario name (highway, urban).
        scenario: String,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Override the scenario's seed.
        #[arg(long)]
        seed: Option<u64>,
        /// Override the scenario's duration, s.
        #[arg(long)]
        duration: Option<f64>,
        /// Skip the KITTI-style copy.
        #[arg(long)]
        no_kitti: bool,
        /// Print the resolved scenario as TOML and exit.
        #[arg(long)]
        print: bool,
    },
    /// Simulate the default urban scenario, score it and write a small report (OUT/report).
    Demo {
        /// Output directory.
        #[arg(long, default_value = "out/demo")]
        out: PathBuf,
        /// Scenario TOML file or built-in name.
        #[arg(long, default_value = "urban")]
        scenario: String,
        /// Override the scenario's duration, s.
        #[arg(long)]
        duration: Option<f64>,
    },
    /// Print the version of every component.
    Version,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Simulate {
            scenario,
            out,
            seed,
            duration,
            no_kitti,
            print,
        } => run_simulate(
            &scenario,
            &out,
            Overrides {
                seed,
                duration_s: duration,
            },
            !no_kitti,
            print,
        ),
        Command::Demo {
            out,
            scenario,
            duration,
        } => run_demo(&scenario, &out, duration),
        Command::Version => {
            println!("limot {}", env!("CARGO_PKG_VERSION"));
            Ok(())
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            let mut source = e.source();
            while let Some(s) = source {
                eprintln!("  caused by: {s}");
                source = s.source();
            }
            ExitCode::FAILURE
        }
    }
}

fn run_simulate(
    scenario: &str,
    out: &std::path::Path,
    overrides: Overrides,
    kitti: bool,
    print: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut spec = resolve_scenario(scenario)?;
    overrides.apply(&mut spec)?;
    if print {
        print!("{}", spec.to_toml());
        return Ok(());
    }
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
    Ok(())
}

fn run_demo(
    scenario: &str,
    out: &std::path::Path,
    duration_s: Option<f64>,
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
    let s = demo(&spec, out, true)?;
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
    println!("estimator variants: not implemented yet (issues 3-5)");
    println!("report: {}", s.report_readme.display());
    Ok(())
}
