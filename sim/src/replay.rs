//! Digital twins of recorded drives: a format-free replay input (the ego's
//! poses at a fixed frame period, object tracks as boxes at frames) and the
//! builder that turns it into a [`Scene`].
//!
//! - the ego follows a C2 [`Trajectory`] smoothed through its poses
//!   (`fit`: a penalised least-squares fit whose residual is reported), so
//!   the simulated IMU is that of a physically smooth motion;
//! - every track becomes an [`Agent`](crate::scene::Agent) present while it was labelled
//!   (`tracks`: interpolated between labelled frames, parked when its own
//!   motion stays within a few decimetres); parked ones stay for the whole
//!   drive where that overlaps nothing (labels end with the camera's view,
//!   the car does not);
//! - the ground follows the road height under the ego and a seeded static
//!   scene lines the driven corridor (`corridor`).
//!
//! Reading a recording's files (KITTI's OXTS, labels, calibration) is the
//! caller's job: the `limot` CLI converts them into a [`ReplayInput`].

mod corridor;
mod fit;
mod tracks;

pub use corridor::{Corridor, GroundFit};
pub use fit::{FitResidual, SmoothingConfig, fit_trajectory};
pub use tracks::{MAX_GAP_FRAMES, PARKED_SPREAD_M, TrackSummary};

use crate::scenario::{ScenarioError, ScenarioSpec, common};
use crate::scene::{Ego, Scene, Trajectory};
use limot_estimator::input::{Detection, ObjectClass};
use nalgebra::{Isometry3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// A recorded drive, as the builder needs it. Frame `k` is at
/// `k * frame_period_s`; the world frame is gravity-aligned (z up).
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayInput {
    /// Time between frames, s.
    pub frame_period_s: f64,
    /// `t_world_lidar` at each frame (at least 2).
    pub t_world_lidar: Vec<Isometry3<f64>>,
    /// 1-sigma uncertainty of each frame's position, m (weights the fit;
    /// same length as `t_world_lidar`).
    pub position_sigma_m: Vec<f64>,
    /// Maps IMU-frame points into the LiDAR frame.
    pub t_lidar_imu: Isometry3<f64>,
    /// The labelled objects.
    pub tracks: Vec<ReplayTrack>,
    /// Recorded detections per frame (LiDAR frame) to put into the dataset
    /// instead of the detector model's; `None` = the detector model.
    pub detections: Option<Vec<Vec<Detection>>>,
}

/// One labelled object: its boxes at the frames where it was labelled.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayTrack {
    /// Agent id, >= 1 and unique in the input.
    pub id: u32,
    /// Object class.
    pub class: ObjectClass,
    /// Box length, width, height, m.
    pub size_lwh_m: Vector3<f64>,
    /// The labelled boxes (any order; a repeated frame keeps its first box).
    pub boxes: Vec<TrackBox>,
}

/// A labelled box at one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackBox {
    /// Frame index into [`ReplayInput::t_world_lidar`].
    pub frame: usize,
    /// Box centre pose in the world (x along the heading).
    pub t_world_box: Isometry3<f64>,
}

/// What the builder did with a replay input: fit residuals, the corridor,
/// how the tracks became agents.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayReport {
    /// Residual of the ego trajectory fit at the input frames.
    pub ego_fit: FitResidual,
    /// The ground's residual under the ego.
    pub ground: GroundFit,
    /// The corridor's static scene type.
    pub corridor: Corridor,
    /// Static objects generated.
    pub statics: usize,
    /// How the tracks became agents.
    pub tracks: TrackSummary,
}

impl std::fmt::Display for ReplayReport {
    /// One line: fit residuals, ground under the ego, corridor and agents.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (e, g, t) = (&self.ego_fit, &self.ground, &self.tracks);
        write!(
            f,
            "ego fit residual rms {:.3} m / max {:.3} m, {:.4} / {:.4} rad, peak accel {:.2} m/s^2; \
             ground under the ego rms {:.3} m / max {:.3} m; corridor {}, {} statics; \
             agents {} moving, {} parked ({} of them for the whole drive; {} splits, {} bridged frames, \
             {} duplicate boxes)",
            e.position_rms_m,
            e.position_max_m,
            e.rotation_rms_rad,
            e.rotation_max_rad,
            e.accel_max_mps2,
            g.rms_m,
            g.max_m,
            self.corridor.name(),
            self.statics,
            t.moving,
            t.parked,
            t.parked_for_the_drive,
            t.splits,
            t.bridged_frames,
            t.duplicates,
        )
    }
}

fn build_error(message: impl Into<String>) -> ScenarioError {
    ScenarioError::Build {
        scenario: "replay".into(),
        message: message.into(),
    }
}

impl ReplayInput {
    /// Checks the invariants the builder relies on.
    ///
    /// # Errors
    /// [`ScenarioError::Build`] naming the first violated invariant.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        let n = self.t_world_lidar.len();
        if !(self.frame_period_s.is_finite() && self.frame_period_s > 0.0) {
            return Err(build_error(format!(
                "frame period {} s is not positive",
                self.frame_period_s
            )));
        }
        if n < 2 {
            return Err(build_error(format!("{n} ego poses: at least 2 needed")));
        }
        if self.position_sigma_m.len() != n {
            return Err(build_error(format!(
                "{} position sigmas for {n} poses",
                self.position_sigma_m.len()
            )));
        }
        for (k, (pose, sigma)) in self
            .t_world_lidar
            .iter()
            .zip(&self.position_sigma_m)
            .enumerate()
        {
            let finite = pose.translation.vector.iter().all(|v| v.is_finite())
                && pose.rotation.coords.iter().all(|v| v.is_finite());
            if !(finite && sigma.is_finite() && *sigma > 0.0) {
                return Err(build_error(format!(
                    "frame {k}: pose or position sigma {sigma} m is not finite and positive"
                )));
            }
        }
        let mut ids = std::collections::BTreeSet::new();
        for t in &self.tracks {
            if t.id == 0 || !ids.insert(t.id) {
                return Err(build_error(format!("track id {} is 0 or repeated", t.id)));
            }
            if !t.size_lwh_m.iter().all(|v| v.is_finite() && *v > 0.0) {
                return Err(build_error(format!("track {}: size is not positive", t.id)));
            }
            if let Some(b) = t.boxes.iter().find(|b| {
                b.frame >= n
                    || !b
                        .t_world_box
                        .translation
                        .vector
                        .iter()
                        .all(|v| v.is_finite())
                    || !b.t_world_box.rotation.coords.iter().all(|v| v.is_finite())
            }) {
                return Err(build_error(format!(
                    "track {}: box at frame {} is outside the {n} frames or not finite",
                    t.id, b.frame
                )));
            }
        }
        if let Some(d) = &self.detections
            && d.len() < n
        {
            return Err(build_error(format!(
                "detections for {} frames, {n} replayed",
                d.len()
            )));
        }
        Ok(())
    }

    /// Duration of the replay: frame `n - 1` plus one sweep, s.
    pub fn duration_s(&self) -> f64 {
        self.t_world_lidar.len() as f64 * self.frame_period_s
    }
}

/// Builds the twin's scene: the ego trajectory fitted through the poses,
/// the tracks as agents, the ground and the corridor's statics (seeded by
/// `spec.seed`; same spec and input, same scene). `spec.duration_s` caps the
/// replay; `spec.kitti.corridor` (unset: [`Corridor::choose`]) picks the
/// static scene; `spec.ego` gives the body size, the LiDAR height and the
/// ground's roughness comes from `spec.ground`.
///
/// # Errors
/// [`ScenarioError::Build`] for an input that breaks [`ReplayInput::validate`].
pub fn build_scene(
    spec: &ScenarioSpec,
    input: &ReplayInput,
) -> Result<(Scene, ReplayReport), ScenarioError> {
    input.validate()?;
    let dt = input.frame_period_s;
    let (ego_trajectory, ego_fit) = fit_trajectory(
        &input.t_world_lidar,
        &input.position_sigma_m,
        dt,
        &SmoothingConfig::EGO,
    );
    let duration_s = input.duration_s().min(spec.duration_s);
    let ego = ego_of(spec, ego_trajectory, input.t_lidar_imu);
    let (mut agents, mut track_summary) = tracks::agents(&input.tracks, dt);
    track_summary.parked_for_the_drive = tracks::park_for_the_drive(
        &mut agents,
        |t| (ego.t_world_box_at(t), ego.size_lwh_m),
        duration_s,
    );
    let corridor_choice = spec
        .kitti
        .as_ref()
        .and_then(|k| k.corridor)
        .unwrap_or_else(|| Corridor::choose(input));
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let lidar_height_m = spec.ego.lidar_height_m;
    let (ground, ground_fit) = corridor::fit_ground(
        &ego.trajectory,
        lidar_height_m,
        duration_s,
        common::road_roughness(&spec.ground, spec.seed),
    );
    let statics = corridor::statics(
        corridor_choice,
        &ego.trajectory,
        duration_s,
        &ground,
        &agents,
        &mut rng,
    );
    let report = ReplayReport {
        ego_fit,
        ground: ground_fit,
        corridor: corridor_choice,
        statics: statics.len(),
        tracks: track_summary,
    };
    Ok((
        Scene {
            duration_s,
            ground,
            statics,
            agents,
            ego,
        },
        report,
    ))
}

fn ego_of(spec: &ScenarioSpec, trajectory: Trajectory, t_lidar_imu: Isometry3<f64>) -> Ego {
    Ego {
        trajectory,
        size_lwh_m: Vector3::from(spec.ego.size_lwh_m),
        box_center_lidar_m: common::box_center_lidar_m(&spec.ego),
        t_lidar_imu,
    }
}
