//! The simulation driver: scenario spec -> scene -> sensor streams and ground
//! truth, frame by frame, and into a dataset directory.
//!
//! Every sensor draws from its own seed derived from the scenario seed, and
//! every frame is a pure function of (spec, frame index), so a dataset is
//! byte-identical whenever the spec is, whatever the thread count.

use crate::record::{
    BiasTruth, BoxTruth, DatasetWriter, EgoTruth, FORMAT_VERSION, Meta, RecordError, RecordedFrame,
    WriteMode, points_per_instance, pose_to_array,
};
use crate::replay::{ReplayInput, ReplayReport};
use crate::scenario::{ScenarioError, ScenarioSpec};
use crate::scene::Scene;
use crate::sensors::{DetectionWithTruth, Detector, DetectorError};
use crate::sensors::{ImuError, ImuSimulator, ImuStream};
use crate::sensors::{LidarError, LidarSimulator, SimulatedScan};
use crate::world::World;
use limot_estimator::input::{Detection, LidarScan};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Frames [`Simulation::write_dataset_with`] simulates at once.
const FRAMES_IN_FLIGHT: usize = 2;

#[derive(Debug, thiserror::Error)]
/// Why a scenario could not be simulated or written.
pub enum SimulationError {
    #[error(transparent)]
    /// The spec is invalid or its scene could not be built.
    Scenario(#[from] ScenarioError),
    #[error("lidar: {0}")]
    /// The `[lidar]` settings are invalid.
    Lidar(#[from] LidarError),
    #[error("imu: {0}")]
    /// The `[imu]` settings are invalid.
    Imu(#[from] ImuError),
    #[error("detector: {0}")]
    /// The `[detector]` settings are invalid, or it produced an invalid detection.
    Detector(#[from] DetectorError),
    #[error(transparent)]
    /// Writing the dataset failed.
    Record(#[from] RecordError),
    #[error(transparent)]
    /// The caller's own output of [`Simulation::write_dataset_with`] failed.
    Output(Box<dyn std::error::Error + Send + Sync>),
    #[error("frame {index} does not exist (the scenario has {count} frames)")]
    /// A frame index at or beyond [`Simulation::frame_count`].
    NoSuchFrame {
        /// The requested frame.
        index: usize,
        /// Frames in the scenario.
        count: usize,
    },
}

/// One simulated frame with the ground truth that goes with it.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedFrame {
    /// Frame index, 0-based.
    pub index: usize,
    /// Sweep start time, s.
    pub t_s: f64,
    /// The sweep, its per-point labels and the detections, as written to a dataset.
    pub recorded: RecordedFrame,
    /// World-frame boxes of all agents present at the sweep start.
    pub boxes: Vec<BoxTruth>,
}

/// A scenario ready to be simulated: its scene, the ray-cast world and the
/// seeded sensors. Frames are pure functions of (spec, frame index).
///
/// ```
/// use limot_sim::{ScenarioSpec, Simulation};
///
/// let mut spec = ScenarioSpec::builtin("highway").expect("a built-in scenario");
/// spec.duration_s = 0.2;
/// spec.ego.depart_s = 0.0;
/// let sim = Simulation::new(&spec)?;
/// assert_eq!(sim.frame_count(), 2); // 0.1 s sweeps
/// let frame = sim.frame(1)?;
/// assert_eq!(frame.t_s, sim.frame_start_s(1));
/// assert!(!frame.recorded.scan.points.is_empty());
/// assert_eq!(frame.recorded.labels.len(), frame.recorded.scan.points.len());
/// // ground truth: one box per agent at the sweep start
/// assert_eq!(frame.boxes.len(), sim.scene().agents.len());
/// # Ok::<(), limot_sim::SimulationError>(())
/// ```
pub struct Simulation {
    spec: ScenarioSpec,
    scene: Scene,
    /// What the replay builder did (replayed scenarios only).
    replay: Option<ReplayReport>,
    /// Recorded detections per frame, used instead of the detector's.
    replayed_detections: Option<Vec<Vec<Detection>>>,
    world: World,
    lidar: LidarSimulator,
    imu: ImuSimulator,
    detector: Detector,
}

/// Independent sub-seeds per sensor (SplitMix64 of the scenario seed), so
/// changing one sensor's settings never changes another's noise.
fn sub_seed(seed: u64, stream: u64) -> u64 {
    let mut z = seed
        .wrapping_add(stream.wrapping_mul(0x9E37_79B9_7F4A_7C15))
        .wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Simulation {
    /// Validates `spec`, builds its scene and ray-cast world, and sets up the
    /// sensors with seeds derived from `spec.seed`.
    ///
    /// # Errors
    /// [`SimulationError::Scenario`] for an invalid spec or a scene that cannot be
    /// built, and the sensor variants for invalid sensor settings.
    pub fn new(spec: &ScenarioSpec) -> Result<Simulation, SimulationError> {
        spec.validate()?;
        let scene = spec.build()?;
        Self::with_scene(spec, scene, None, None)
    }

    /// A replayed scenario (a `kitti` spec): its scene built from `input` by
    /// [`crate::replay::build_scene`], the recorded detections (if the input
    /// has them) in place of the detector model's.
    ///
    /// # Errors
    /// As [`Simulation::new`], and [`SimulationError::Scenario`] for an
    /// input the replay builder rejects.
    pub fn from_replay(
        spec: &ScenarioSpec,
        input: &ReplayInput,
    ) -> Result<Simulation, SimulationError> {
        spec.validate()?;
        let (scene, report) = crate::replay::build_scene(spec, input)?;
        Self::with_scene(spec, scene, Some(report), input.detections.clone())
    }

    fn with_scene(
        spec: &ScenarioSpec,
        scene: Scene,
        replay: Option<ReplayReport>,
        replayed_detections: Option<Vec<Vec<Detection>>>,
    ) -> Result<Simulation, SimulationError> {
        let world = World::new(&scene);
        Ok(Simulation {
            lidar: LidarSimulator::new(spec.lidar.clone(), sub_seed(spec.seed, 1))?,
            imu: ImuSimulator::new(spec.imu.clone(), sub_seed(spec.seed, 2))?,
            detector: Detector::new(spec.detector.clone(), sub_seed(spec.seed, 3))?,
            spec: spec.clone(),
            scene,
            replay,
            replayed_detections,
            world,
        })
    }

    /// What the replay builder did, for a replayed scenario.
    pub fn replay_report(&self) -> Option<&ReplayReport> {
        self.replay.as_ref()
    }

    /// The validated spec.
    pub fn spec(&self) -> &ScenarioSpec {
        &self.spec
    }

    /// The generated scene (ground, statics, agents, ego).
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The ray-cast world of the scene.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// Duration of one LiDAR sweep, s.
    pub fn sweep_duration_s(&self) -> f64 {
        self.spec.lidar.sweep_duration_s()
    }

    /// Number of complete sweeps inside the scenario duration.
    pub fn frame_count(&self) -> usize {
        // the epsilon keeps 60 s / 0.1 s at 600 despite rounding
        (self.scene.duration_s / self.sweep_duration_s() + 1e-9).floor() as usize
    }

    /// Start time of frame `index` (`index` sweeps after t = 0), s.
    pub fn frame_start_s(&self, index: usize) -> f64 {
        index as f64 * self.sweep_duration_s()
    }

    /// Simulates frame `index`: the rolling sweep, its labels, the detections
    /// and the ground-truth boxes at the sweep start.
    ///
    /// # Errors
    /// [`SimulationError::NoSuchFrame`] for `index >= frame_count()`;
    /// [`SimulationError::Detector`] if a generated detection is invalid.
    pub fn frame(&self, index: usize) -> Result<SimulatedFrame, SimulationError> {
        self.frame_reusing(index, None)
    }

    /// [`Simulation::frame`], reusing the point and label buffers of `spare`
    /// (a frame that is no longer needed).
    fn frame_reusing(
        &self,
        index: usize,
        spare: Option<SimulatedFrame>,
    ) -> Result<SimulatedFrame, SimulationError> {
        let count = self.frame_count();
        if index >= count {
            return Err(SimulationError::NoSuchFrame { index, count });
        }
        let t_s = self.frame_start_s(index);
        let mut sweep = match spare {
            Some(frame) => SimulatedScan {
                scan: frame.recorded.scan,
                labels: frame.recorded.labels,
            },
            None => SimulatedScan {
                scan: LidarScan::default(),
                labels: Vec::new(),
            },
        };
        self.lidar
            .scan_into(&self.scene, &self.world, index as u64, t_s, &mut sweep);
        let detections = match &self.replayed_detections {
            Some(recorded) => recorded
                .get(index)
                .into_iter()
                .flatten()
                .map(|&detection| DetectionWithTruth {
                    detection,
                    truth_id: None,
                })
                .collect(),
            None => self.detector.detect(
                index as u64,
                t_s,
                &self.scene,
                &points_per_instance(&sweep.labels),
                &self.spec.lidar,
            )?,
        };
        let boxes = self
            .scene
            .agents
            .iter()
            .filter(|agent| agent.is_present(t_s))
            .map(|agent| {
                let b = agent.box_at(t_s);
                BoxTruth {
                    frame: index,
                    t_s,
                    id: b.id,
                    class: b.class,
                    t_world_box: b.t_world_box,
                    size_lwh_m: b.size_lwh_m,
                    velocity_world_mps: b.velocity_world_mps,
                    parked: agent.parked,
                    labelled: agent.is_labelled(t_s),
                    annotated: agent.is_annotated(),
                }
            })
            .collect();
        Ok(SimulatedFrame {
            index,
            t_s,
            recorded: RecordedFrame {
                scan: sweep.scan,
                labels: sweep.labels,
                detections,
            },
            boxes,
        })
    }

    /// The IMU stream over the whole scenario (one call: the bias random walk
    /// is one continuous process).
    ///
    /// # Errors
    /// [`SimulationError::Imu`] if the scenario's time range is not finite.
    pub fn imu_stream(&self) -> Result<ImuStream, SimulationError> {
        Ok(self
            .imu
            .simulate(&self.scene.ego, 0.0, self.scene.duration_s)?)
    }

    /// Ground-truth ego states (t_world_lidar and LiDAR velocity) at the IMU sample times.
    pub fn ego_truth(&self, imu: &ImuStream) -> Vec<EgoTruth> {
        imu.samples
            .iter()
            .map(|s| {
                let state = self.scene.ego.trajectory.state_at(s.t_s);
                EgoTruth {
                    t_s: s.t_s,
                    t_world_lidar: state.t_world_body,
                    velocity_world_mps: state.velocity_world_mps,
                }
            })
            .collect()
    }

    /// Ground-truth IMU biases at the IMU sample times of `imu`.
    pub fn bias_truth(imu: &ImuStream) -> Vec<BiasTruth> {
        imu.samples
            .iter()
            .zip(imu.accel_bias.iter().zip(&imu.gyro_bias))
            .map(|(s, (a, g))| BiasTruth {
                t_s: s.t_s,
                accel_bias: *a,
                gyro_bias: *g,
            })
            .collect()
    }

    /// The dataset's `meta.toml` contents for this scenario.
    pub fn meta(&self) -> Meta {
        Meta {
            format_version: FORMAT_VERSION,
            name: self.spec.name.clone(),
            family: self.spec.family.name().to_string(),
            seed: self.spec.seed,
            duration_s: self.scene.duration_s,
            frame_count: self.frame_count(),
            imu_rate_hz: self.spec.imu.rate_hz,
            sweep_duration_s: self.sweep_duration_s(),
            num_rings: crate::sensors::hdl64::NUM_LASERS as u16,
            t_lidar_imu: pose_to_array(&self.scene.ego.t_lidar_imu),
        }
    }

    /// Simulates every frame into a dataset directory and returns it.
    /// `on_frame(frame, total)` is called after each frame is simulated
    /// (progress bars).
    ///
    /// # Errors
    /// The first [`SimulationError`] of any frame, and
    /// [`SimulationError::Record`] when a file cannot be written.
    pub fn write_dataset(
        &self,
        dir: &Path,
        on_frame: impl FnMut(&SimulatedFrame, usize),
    ) -> Result<PathBuf, SimulationError> {
        self.write_dataset_with(
            dir,
            WriteMode::default(),
            |_| Ok::<(), SimulationError>(()),
            on_frame,
        )
    }

    /// [`Simulation::write_dataset`] with the files written in `mode`, and
    /// `also(frame)` called for every frame after the frame's own files are
    /// written, on the writer's thread, in frame order: more output made
    /// from the frames (a copy in another format). Frames are simulated on
    /// the calling thread (the sweep's rays on rayon's pool) while the
    /// writer writes the frame before, so the files, their contents and
    /// their order are those of a serial run.
    ///
    /// # Errors
    /// The first [`SimulationError`] of any frame, [`SimulationError::Record`]
    /// when a file cannot be written and [`SimulationError::Output`] with the
    /// first error of `also`; the run stops at the first error.
    pub fn write_dataset_with<E>(
        &self,
        dir: &Path,
        mode: WriteMode,
        mut also: impl FnMut(&SimulatedFrame) -> Result<(), E> + Send,
        mut on_frame: impl FnMut(&SimulatedFrame, usize),
    ) -> Result<PathBuf, SimulationError>
    where
        E: Into<Box<dyn std::error::Error + Send + Sync>>,
    {
        let mut writer = DatasetWriter::begin_with_mode(dir, &self.spec.to_toml(), mode)?;
        let total = self.frame_count();
        // the writer thread writes frame k while the sensors simulate
        // frame k + 1; two more frames may wait in the channel
        let (to_writer, frames) = std::sync::mpsc::sync_channel::<SimulatedFrame>(2);
        // written frames come back, so their buffers are reused (fresh
        // memory for every sweep would be a page fault per 4 KiB)
        let (to_reuse, spares) = std::sync::mpsc::channel::<SimulatedFrame>();
        let written = std::thread::scope(|scope| {
            let writing = scope.spawn(move || -> Result<DatasetWriter, SimulationError> {
                for frame in frames {
                    writer.write_frame(&frame.recorded, &frame.boxes)?;
                    also(&frame).map_err(|e| SimulationError::Output(e.into()))?;
                    // the simulation may be over: then the frame is dropped
                    let _ = to_reuse.send(frame);
                }
                Ok(writer)
            });
            let mut simulated = Ok(());
            // frames are simulated FRAMES_IN_FLIGHT at a time, so one frame's
            // serial steps (culling, labels, detector) overlap another's rays
            'frames: for first in (0..total).step_by(FRAMES_IN_FLIGHT) {
                let group: Vec<_> = (first..(first + FRAMES_IN_FLIGHT).min(total))
                    .map(|index| (index, spares.try_recv().ok()))
                    .collect::<Vec<_>>()
                    .into_par_iter()
                    .map(|(index, spare)| self.frame_reusing(index, spare))
                    .collect();
                for frame in group {
                    match frame {
                        Ok(frame) => {
                            on_frame(&frame, total);
                            if to_writer.send(frame).is_err() {
                                // the writer stopped on an error: it reports it
                                break 'frames;
                            }
                        }
                        Err(e) => {
                            simulated = Err(e);
                            break 'frames;
                        }
                    }
                }
            }
            drop(to_writer);
            let writer = writing
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            simulated.and(writer)
        });
        let writer = written?;
        let imu = self.imu_stream()?;
        let ego = self.ego_truth(&imu);
        let biases = Self::bias_truth(&imu);
        Ok(writer.finish(self.meta(), &imu.samples, &biases, &ego)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sub_seeds_differ_per_stream_and_seed() {
        let seeds: Vec<u64> = (0..4)
            .flat_map(|seed| (0..4).map(move |s| sub_seed(seed, s)))
            .collect();
        let mut unique = seeds.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), seeds.len());
    }
}
