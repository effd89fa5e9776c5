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

/// Where and what `limot simulate` writes.
pub(super) struct SimulateOutputs<'a> {
    /// The dataset directory.
    pub out: &'a std::path::Path,
    /// Also write the KITTI-style copy.
    pub kitti: bool,
    /// Replace an existing dataset directory.
    pub force: bool,
    /// Also record the dataset as this MCAP recording.
    pub mcap: Option<&'a crate::io::mcap::McapRequest>,
    /// Also write the raw streams as this ROS 2 bag.
    pub bag: Option<&'a std::path::Path>,
}

pub(super) fn run_simulate(
    scenario: &str,
    twin: TwinArgs,
    overrides: Overrides,
    print: bool,
    outputs: SimulateOutputs<'_>,
) -> Result<(), Box<dyn std::error::Error>> {
    let SimulateOutputs {
        out,
        kitti,
        force,
        mcap,
        bag,
    } = outputs;
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
        println!("twin: {r}");
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
    if let Some(request) = mcap {
        let stats = crate::simulate::record_dataset_mcap(&s.dataset_dir, request)?;
        super::print_mcap(&stats);
    }
    if let Some(path) = bag {
        let stats = crate::simulate::write_dataset_bag(&s.dataset_dir, path)?;
        println!(
            "ROS 2 bag: {} ({:.1} MB, {} messages; limot run {} --lidar-topic {} --imu-topic {} --detections-topic {})",
            stats.path.display(),
            stats.bytes as f64 / 1e6,
            stats.messages,
            stats.path.display(),
            crate::io::rosbag::TOPIC_POINTS,
            crate::io::rosbag::TOPIC_IMU,
            crate::io::rosbag::TOPIC_DETECTIONS,
        );
    }
    Ok(())
}
