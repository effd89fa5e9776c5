//! `limot simulate`: resolve a scenario (file or built-in name), simulate it
//! into a limot dataset and write a KITTI-style copy beside it.
use crate::cli::frame_progress_bar;
use crate::io::kitti::KittiError;
use crate::io::kitti::export::{ExportError, KittiCopyWriter, stored_box};
use crate::io::kitti::twin::{self, TwinNotes};
use limot_sim::record::WriteMode;
use limot_sim::replay::{Corridor, ReplayReport};
use limot_sim::scenario::{Family, KittiParams, ScenarioError, ScenarioSpec};
use limot_sim::{Simulation, SimulationError};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Why a scenario could not be simulated into a dataset.
#[derive(Debug, thiserror::Error)]
pub enum SimulateError {
    #[error(
        "scenario `{0}` is neither a file nor a built-in scenario (built-in: {names})",
        names = ScenarioSpec::builtin_names().join(", ")
    )]
    /// The argument is neither a file nor a built-in scenario.
    UnknownScenario(String),
    /// The scenario is malformed or invalid.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The simulation or its dataset writer failed.
    #[error(transparent)]
    Simulation(#[from] SimulationError),
    /// The KITTI-style copy could not be written.
    #[error(transparent)]
    Export(#[from] ExportError),
    /// A KITTI file of a twin could not be read.
    #[error(transparent)]
    Kitti(#[from] KittiError),
    /// A twin's argument is invalid.
    #[error("{0}")]
    Argument(String),
    #[error(
        "{}: output directory is not empty{}",
        path.display(),
        if *is_dataset { " (a limot dataset: pass --force to replace it)" } else { " and is not a limot dataset; choose another directory" }
    )]
    /// The output directory is not empty.
    OutputNotEmpty {
        /// The directory.
        path: PathBuf,
        /// Whether it holds a limot dataset (which `--force` may replace).
        is_dataset: bool,
    },
    /// The output directory could not be read or removed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The directory.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
}

/// Makes `out` ready for a new dataset. A missing or empty directory is
/// fine; an existing limot dataset (it has `meta.toml` or `scenario.toml`)
/// is removed when `replace` is set, so no stale sweeps of a longer earlier
/// run survive; anything else is refused rather than mixed or deleted.
///
/// # Errors
/// A directory that cannot be read or removed, or one that is not empty and not a limot dataset (or
/// `replace` is unset).
pub fn prepare_output_dir(out: &Path, replace: bool) -> Result<(), SimulateError> {
    let io = |source| SimulateError::Io {
        path: out.to_path_buf(),
        source,
    };
    if !out.exists() {
        return Ok(());
    }
    if out.read_dir().map_err(io)?.next().is_none() {
        return Ok(());
    }
    let is_dataset = out.join("meta.toml").is_file() || out.join("scenario.toml").is_file();
    if is_dataset && replace {
        return std::fs::remove_dir_all(out).map_err(io);
    }
    Err(SimulateError::OutputNotEmpty {
        path: out.to_path_buf(),
        is_dataset,
    })
}

/// A scenario given on the command line: a TOML file path, or the name of a
/// built-in scenario when no such file exists.
///
/// # Errors
/// A malformed scenario file, or a name that is neither a file nor a built-in scenario.
pub fn resolve_scenario(arg: &str) -> Result<ScenarioSpec, SimulateError> {
    let path = Path::new(arg);
    if path.exists() {
        return Ok(ScenarioSpec::load(path)?);
    }
    ScenarioSpec::builtin(arg).ok_or_else(|| SimulateError::UnknownScenario(arg.to_string()))
}

/// The scenario of a KITTI tracking sequence's digital twin: the default
/// sensors, ego and ground, seed 1, the whole sequence (up to the 3600 s
/// limit), the given frames, corridor (`residential`, `city`, `highway`;
/// unset = chosen from the sequence) and recorded detections.
///
/// # Errors
/// An unknown corridor name, or a table the spec's validation refuses.
pub fn kitti_scenario(
    training: &Path,
    sequence: u32,
    first_frame: usize,
    frames: Option<usize>,
    corridor: Option<&str>,
    detections: Option<&Path>,
) -> Result<ScenarioSpec, SimulateError> {
    let corridor = corridor
        .map(|name| match name {
            "residential" => Ok(Corridor::Residential),
            "city" => Ok(Corridor::City),
            "highway" => Ok(Corridor::Highway),
            other => Err(SimulateError::Argument(format!(
                "corridor `{other}`: expected residential, city or highway"
            ))),
        })
        .transpose()?;
    let spec = ScenarioSpec::kitti(KittiParams {
        training: training.display().to_string(),
        sequence,
        first_frame,
        frames,
        corridor,
        detections: detections.map(|d| d.display().to_string()),
    });
    spec.validate()?;
    Ok(spec)
}

/// The simulation of `spec`: a generated scene, or for a `kitti` spec the
/// twin of its sequence (read with [`twin::replay_input`]) with what the
/// conversion left out.
///
/// # Errors
/// An invalid spec, unreadable or malformed KITTI files, a scene the
/// simulator refuses.
pub fn simulation_of(
    spec: &ScenarioSpec,
) -> Result<(Simulation, Option<TwinNotes>), SimulateError> {
    spec.validate()?;
    match (&spec.family, &spec.kitti) {
        (Family::Kitti, Some(params)) => {
            let period = crate::io::kitti::KITTI_FRAME_PERIOD_S;
            let max_frames = (spec.duration_s / period + 1e-9).floor() as usize;
            let (input, notes) = twin::replay_input(params, max_frames)?;
            Ok((Simulation::from_replay(spec, &input)?, Some(notes)))
        }
        _ => Ok((Simulation::new(spec)?, None)),
    }
}

/// Overrides applied to a resolved scenario before simulating.
#[derive(Debug, Clone, Default)]
pub struct Overrides {
    /// Seed to use instead of the scenario's.
    pub seed: Option<u64>,
    /// Duration to use instead of the scenario's (s).
    pub duration_s: Option<f64>,
}

impl Overrides {
    /// # Errors
    /// A scenario that is invalid after the overrides.
    pub fn apply(&self, spec: &mut ScenarioSpec) -> Result<(), SimulateError> {
        if let Some(seed) = self.seed {
            spec.seed = seed;
        }
        if let Some(d) = self.duration_s {
            spec.duration_s = d;
        }
        spec.validate()?;
        Ok(())
    }
}

/// What a simulation run produced.
#[derive(Debug, Clone)]
pub struct SimulateSummary {
    /// The limot dataset.
    pub dataset_dir: PathBuf,
    /// Its KITTI-style copy, when written.
    pub kitti_dir: Option<PathBuf>,
    /// Sweeps simulated.
    pub frames: usize,
    /// LiDAR points recorded.
    pub points: usize,
    /// Detections recorded.
    pub detections: usize,
    /// Agents in the scene.
    pub agents: usize,
    /// Wall time of the simulation and export (s).
    pub wall_time_s: f64,
    /// What the replay builder did (twins only).
    pub replay: Option<ReplayReport>,
    /// What the KITTI conversion left out (twins only).
    pub twin: Option<TwinNotes>,
}

/// Simulates `spec` into `out` (limot format) and, unless `kitti` is false,
/// `out/kitti` (KITTI tracking layout), both written frame by frame while the
/// next frame is simulated. Shows a progress bar when `progress`.
/// `out` must be missing or empty (see [`prepare_output_dir`]).
///
/// # Errors
/// An output directory that is not empty, a scenario the simulator refuses, or a file that cannot
/// be written.
pub fn simulate(
    spec: &ScenarioSpec,
    out: &Path,
    kitti: bool,
    progress: bool,
) -> Result<SimulateSummary, SimulateError> {
    prepare_output_dir(out, false)?;
    let started = Instant::now();
    let (sim, twin) = simulation_of(spec)?;
    let total = sim.frame_count();
    let mode = WriteMode::default();
    let bar = frame_progress_bar(total, progress, "simulate");
    let (mut points, mut detections) = (0, 0);
    let mut copy = if kitti {
        let t_lidar_imu = sim.meta().t_lidar_imu();
        Some(KittiCopyWriter::begin(
            &out.join("kitti"),
            &t_lidar_imu,
            mode,
        )?)
    } else {
        None
    };
    let scene = sim.scene();
    let written = sim.write_dataset_with(
        out,
        mode,
        |frame| match &mut copy {
            Some(copy) => {
                let boxes: Vec<_> = frame.boxes.iter().map(stored_box).collect();
                copy.write_frame(&frame.recorded, &boxes, scene)
            }
            None => Ok(()),
        },
        |frame, _| {
            points += frame.recorded.scan.points.len();
            detections += frame.recorded.detections.len();
            bar.inc(1);
        },
    );
    bar.finish_and_clear();
    let dataset_dir = written.map_err(|e| match e {
        // the KITTI copy's own error, typed again
        SimulationError::Output(e) => match e.downcast::<ExportError>() {
            Ok(e) => SimulateError::Export(*e),
            Err(e) => SimulateError::Simulation(SimulationError::Output(e)),
        },
        e => SimulateError::Simulation(e),
    })?;
    let kitti_dir = copy.map(|c| c.finish(sim.spec(), scene)).transpose()?;
    Ok(SimulateSummary {
        dataset_dir,
        kitti_dir,
        frames: total,
        points,
        detections,
        agents: scene.agents.len(),
        wall_time_s: started.elapsed().as_secs_f64(),
        replay: sim.replay_report().cloned(),
        twin,
    })
}

/// Records the dataset in `dataset_dir` alone (no run) for Foxglove as the
/// MCAP file of `request`: every sweep de-skewed and placed with the true ego
/// poses, the detections and the ground-truth boxes and path
/// ([`crate::io::mcap::record_dataset`]).
///
/// # Errors
/// A dataset that cannot be read or a file that cannot be written (named).
pub fn record_dataset_mcap(
    dataset_dir: &Path,
    request: &crate::io::mcap::McapRequest,
) -> Result<crate::io::mcap::McapStats, crate::io::mcap::McapError> {
    let path = &request.path;
    let source =
        crate::io::Source::open(dataset_dir).map_err(|e| crate::io::mcap::McapError::Input {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    crate::io::mcap::record_dataset(request, &source, source.frame_range(0, None))
}

/// Writes the dataset in `dataset_dir` as the ROS 2 bag `path`: its raw
/// sweeps, IMU samples, extrinsic and detections
/// ([`crate::io::rosbag::write_bag`]), which `limot run` reads back to the
/// same frames.
///
/// # Errors
/// A dataset that cannot be read or a file that cannot be written (named).
pub fn write_dataset_bag(
    dataset_dir: &Path,
    path: &Path,
) -> Result<crate::io::mcap::McapStats, crate::io::mcap::McapError> {
    let source =
        crate::io::Source::open(dataset_dir).map_err(|e| crate::io::mcap::McapError::Input {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    crate::io::rosbag::write_bag(path, &source)
}
