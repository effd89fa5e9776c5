//! The rolling HDL-64E sweep: every column (64 lasers at one azimuth) fires
//! at its own time and is cast against the world as it is then, so ego and
//! object motion distort the sweep exactly as on a real spinning sensor.
//!
//! Points are delivered raw: in the LiDAR frame at their own firing time,
//! with `time_offset_s` = the column time and `ring` (0 = lowest beam, see
//! [`crate::sensors::hdl64`]). Each point carries the ground-truth instance id of what
//! it hit (0 = static scene).
//!
//! Intensity, in [0, 1], models the HDL-64E's calibrated reflectance as
//! KITTI stores it: surface reflectivity x (0.8 + 0.2 |cos(incidence)|)
//! (asphalt returns nearly as bright at grazing incidence as head-on) x a
//! range falloff `1 / (1 + (r / 45 m)^4)` (returns beyond ~50 m are faint)
//! x the laser's own gain (log-normal, sigma 0.25, fixed per sensor seed)
//! x a per-return speckle (log-normal, sigma 0.35). Reflectivities: road
//! 0.22, tree crown and trunk, shrub, earth, building and facade 0.3, wall, kerb
//! and bridge concrete 0.35, pole and fence 0.4, guard rail 0.5, sign 0.9
//! (retro-reflective), car 0.3, truck 0.35, cyclist and pedestrian 0.3.
//!
//! Determinism: column `c` of frame `f` draws its noise from a ChaCha8 stream
//! keyed by (seed, f) with stream number `c`, and columns are concatenated in
//! firing order, so a scan is byte-identical whatever the thread count.

use crate::scene::{Scene, StaticKind};
use crate::sensors::LidarConfig;
use crate::sensors::hdl64::{NUM_LASERS, elevation_table_rad, ring_of_beam};
use crate::world::{RayHit, Surface, World};
use limot_estimator::input::{LidarPoint, LidarScan, ObjectClass};
use nalgebra::{Point3, Unit, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;

/// Why a LiDAR configuration was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LidarError {
    #[error("lidar.{field} = {value} is not finite")]
    /// A field is NaN or infinite.
    NotFinite {
        /// Name of the field.
        field: &'static str,
        /// The rejected value.
        value: f64,
    },
    #[error("lidar.{field} = {value} must be > 0")]
    /// A field that must be positive is not.
    NotPositive {
        /// Name of the field.
        field: &'static str,
        /// The rejected value.
        value: f64,
    },
    #[error("lidar.{field} = {value} must be >= 0")]
    /// A field that must not be negative is.
    Negative {
        /// Name of the field.
        field: &'static str,
        /// The rejected value.
        value: f64,
    },
    #[error("lidar.dropout_probability = {0} must be in [0, 1)")]
    /// `dropout_probability` outside [0, 1).
    BadProbability(f64),
    #[error("lidar.min_range_m = {min_range_m} must be below lidar.max_range_m = {max_range_m}")]
    /// `min_range_m` is not below `max_range_m`.
    RangeOrder {
        /// The configured minimum range, m.
        min_range_m: f64,
        /// The configured maximum range, m.
        max_range_m: f64,
    },
    #[error("lidar.azimuth_steps = {0} must be in 1..=1000000")]
    /// `azimuth_steps` outside 1..=1000000.
    BadAzimuthSteps(usize),
}

/// One simulated sweep and the instance id of every point (same order).
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedScan {
    /// The sweep: points in the LiDAR frame at their own firing time.
    pub scan: LidarScan,
    /// Instance id of each point's surface ([`crate::scene::STATIC_INSTANCE_ID`] for the ground and statics).
    pub labels: Vec<u32>,
}

/// The rolling LiDAR: a validated configuration, the beam table and a seed.
#[derive(Debug, Clone)]
pub struct LidarSimulator {
    config: LidarConfig,
    seed: u64,
    /// Unit directions in the LiDAR frame for azimuth 0, per beam: (cos el, sin el).
    elevation_cos_sin: [(f64, f64); NUM_LASERS],
    /// tan(elevation) of each beam: its slope in a column's plane.
    elevation_tan: [f64; NUM_LASERS],
    /// Intensity gain of each beam's laser.
    laser_gain: [f64; NUM_LASERS],
}

/// ChaCha stream (of the LiDAR seed) of the per-laser intensity gains; the
/// columns' noise streams are keyed by frame and never use it.
const LASER_GAIN_STREAM: u64 = u64::MAX;
/// Log-normal sigma of a laser's intensity gain and of a return's speckle.
const LASER_GAIN_SIGMA: f64 = 0.25;
const SPECKLE_SIGMA: f64 = 0.35;

/// A slot no beam has filled (yet).
const NO_POINT: LidarPoint = LidarPoint {
    x: 0.0,
    y: 0.0,
    z: 0.0,
    intensity: 0.0,
    ring: 0,
    time_offset_s: 0.0,
};

/// Columns per rayon task: enough work to amortise scheduling.
const COLUMNS_PER_TASK: usize = 16;

impl LidarSimulator {
    /// A LiDAR with a validated `config`; `seed` draws the per-laser gains and every sweep's noise.
    ///
    /// # Errors
    /// [`LidarError`] naming the first invalid field of `config`.
    pub fn new(config: LidarConfig, seed: u64) -> Result<LidarSimulator, LidarError> {
        validate(&config)?;
        let table = elevation_table_rad();
        let elevation_cos_sin = table.map(|el| (el.cos(), el.sin()));
        debug_assert!(
            table.windows(2).all(|pair| pair[0] > pair[1]),
            "beams fall with the beam index (BeamCandidates)"
        );
        let mut gains = ChaCha8Rng::seed_from_u64(seed);
        gains.set_stream(LASER_GAIN_STREAM);
        let laser_gain = std::array::from_fn(|_| {
            let n: f64 = gains.sample(StandardNormal);
            (LASER_GAIN_SIGMA * n).exp()
        });
        Ok(LidarSimulator {
            config,
            seed,
            elevation_cos_sin,
            elevation_tan: elevation_cos_sin.map(|(cos, sin)| sin / cos),
            laser_gain,
        })
    }

    /// The configuration this LiDAR was built with.
    pub fn config(&self) -> &LidarConfig {
        &self.config
    }

    /// Time offset of column `column` after the sweep start.
    pub fn column_time_offset_s(&self, column: usize) -> f64 {
        column as f64 / (self.config.azimuth_steps as f64 * self.config.rotation_hz)
    }

    /// Simulates the sweep starting at `t_start_s` (frame `frame_index` only
    /// selects the noise stream).
    pub fn scan(
        &self,
        scene: &Scene,
        world: &World,
        frame_index: u64,
        t_start_s: f64,
    ) -> SimulatedScan {
        let mut out = SimulatedScan {
            scan: LidarScan {
                t_s: t_start_s,
                sweep_duration_s: self.config.sweep_duration_s(),
                num_rings: NUM_LASERS as u16,
                points: Vec::new(),
            },
            labels: Vec::new(),
        };
        self.scan_into(scene, world, frame_index, t_start_s, &mut out);
        out
    }

    /// [`LidarSimulator::scan`] into `out`, whose contents are replaced (its
    /// buffers are reused: a caller that recycles them allocates nothing per sweep).
    pub fn scan_into(
        &self,
        scene: &Scene,
        world: &World,
        frame_index: u64,
        t_start_s: f64,
        out: &mut SimulatedScan,
    ) {
        let columns = self.config.azimuth_steps;
        // where each agent can be during this sweep, for per-column culling
        let agent_spheres =
            world.agent_sweep_spheres(t_start_s, t_start_s + self.config.sweep_duration_s());
        let static_bins = StaticBins::new(scene, world, &self.config, t_start_s);
        let sweep = Sweep {
            scene,
            world,
            agent_spheres: &agent_spheres,
            static_bins: &static_bins,
            frame_index,
            t_start_s,
        };
        // every column fills its own 64 slots, then the returns are packed
        // in column order
        let (points, labels) = (&mut out.scan.points, &mut out.labels);
        points.clear();
        points.resize(columns * NUM_LASERS, NO_POINT);
        labels.clear();
        labels.resize(columns * NUM_LASERS, 0);
        let slots = COLUMNS_PER_TASK * NUM_LASERS;
        let counts: Vec<[u8; COLUMNS_PER_TASK]> = points
            .par_chunks_mut(slots)
            .zip(labels.par_chunks_mut(slots))
            .enumerate()
            .map(|(task, (points, labels))| {
                let mut counts = [0; COLUMNS_PER_TASK];
                // each beam's ground range in the column before, where the
                // next column's search starts (a task's first column has none,
                // so a task's points do not depend on the others')
                let mut ground_ranges_m = [f64::NAN; NUM_LASERS];
                let mut candidates = BeamCandidates::default();
                let columns = points
                    .chunks_mut(NUM_LASERS)
                    .zip(labels.chunks_mut(NUM_LASERS));
                for (k, (points, labels)) in columns.enumerate() {
                    counts[k] = self.fire_column(
                        &sweep,
                        task * COLUMNS_PER_TASK + k,
                        points,
                        labels,
                        &mut ground_ranges_m,
                        &mut candidates,
                    );
                }
                counts
            })
            .collect();
        let mut kept = 0;
        for (column, &count) in counts.iter().flatten().take(columns).enumerate() {
            let start = column * NUM_LASERS;
            let count = usize::from(count);
            points.copy_within(start..start + count, kept);
            labels.copy_within(start..start + count, kept);
            kept += count;
        }
        points.truncate(kept);
        labels.truncate(kept);
        out.scan.t_s = t_start_s;
        out.scan.sweep_duration_s = self.config.sweep_duration_s();
        out.scan.num_rings = NUM_LASERS as u16;
    }

    /// Casts the 64 beams of one column at its firing time; its returns go,
    /// in beam order, to the front of `points` and `labels` (64 slots each),
    /// and their number is returned. `ground_ranges_m` holds each beam's
    /// ground range in the column before (NaN: none), where the beam's
    /// search starts, and is updated to this column's. `candidates` is
    /// scratch space.
    fn fire_column(
        &self,
        sweep: &Sweep<'_>,
        column: usize,
        points: &mut [LidarPoint],
        labels: &mut [u32],
        ground_ranges_m: &mut [f64; NUM_LASERS],
        candidates: &mut BeamCandidates,
    ) -> u8 {
        let mut count = 0;
        let cfg = &self.config;
        let tau_s = self.column_time_offset_s(column);
        let t_s = sweep.t_start_s + tau_s;
        let (sin_az, cos_az) = cfg.azimuth_at(tau_s).sin_cos();
        let t_world_lidar = sweep.scene.ego.trajectory.pose_at(t_s);
        let origin_world: Point3<f64> = t_world_lidar.translation.vector.into();
        // All 64 beams of the column lie in the LiDAR-frame half-plane
        // {p . n = 0, p . a >= 0} (a = azimuth direction, n its horizontal
        // normal): only agents whose sweep sphere touches it can be hit.
        let visible = sweep
            .agent_spheres
            .iter()
            .enumerate()
            .filter(|(_, (centre, radius))| {
                let v = t_world_lidar
                    .rotation
                    .inverse_transform_vector(&(centre - origin_world));
                let along = v.x * cos_az + v.y * sin_az;
                let across = -v.x * sin_az + v.y * cos_az;
                across.abs() <= *radius && along >= -radius && v.norm() - radius <= cfg.max_range_m
            })
            .map(|(index, _)| index);
        // the statics the column's half-plane meets, by the same test, each
        // with the range of beam slopes (tan elevation) that can reach it:
        // the plane's section of a static lies in the projection of its
        // bounding box onto the plane, between its corners' slopes
        let along_world = t_world_lidar.rotation * Vector3::new(cos_az, sin_az, 0.0);
        let up_world = t_world_lidar.rotation * Vector3::z();
        let across_world = t_world_lidar.rotation * Vector3::new(-sin_az, cos_az, 0.0);
        let spheres = sweep.world.static_bounding_spheres();
        let corners = sweep.world.static_bounding_corners();
        candidates.clear();
        let statics = sweep
            .static_bins
            .at(cfg.azimuth_at(tau_s))
            .iter()
            .map(|&index| index as usize)
            .filter(|&index| {
                let (centre, radius) = spheres[index];
                let w = centre - origin_world;
                let norm = w.norm();
                let radius = radius + 1e-6 + 1e-9 * norm;
                let (along, across) = (w.dot(&along_world), w.dot(&across_world));
                across.abs() <= radius && along >= -radius && norm - radius <= cfg.max_range_m
            })
            .map(|index| {
                let (mut lo, mut hi, mut nearest) =
                    (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY);
                for corner in &corners[index] {
                    let w = corner - origin_world;
                    let (along, up) = (w.dot(&along_world), w.dot(&up_world));
                    nearest = nearest.min(along);
                    let slope = up / along;
                    lo = lo.min(slope);
                    hi = hi.max(slope);
                }
                if nearest > MIN_SLOPE_ALONG_M {
                    (
                        index,
                        lo - SLOPE_MARGIN * (1.0 + lo.abs()),
                        hi + SLOPE_MARGIN * (1.0 + hi.abs()),
                    )
                } else {
                    // beside or behind the sensor: any beam may reach it
                    (index, f64::NEG_INFINITY, f64::INFINITY)
                }
            });
        for (index, lo, hi) in statics {
            candidates.add(index, &self.elevation_tan, lo, hi);
        }
        candidates.finish();
        let snapshot = sweep.world.snapshot_agents(t_s, visible);
        let mut rng = column_rng(self.seed, sweep.frame_index, column);
        for (beam, &(cos_el, sin_el)) in self.elevation_cos_sin.iter().enumerate() {
            let dir_lidar = Vector3::new(cos_el * cos_az, cos_el * sin_az, sin_el);
            let dir_world = Unit::new_unchecked(t_world_lidar.rotation * dir_lidar);
            // three draws per beam, hit or not, so the stream layout is fixed
            let noise: f64 = rng.sample(StandardNormal);
            let dropout: f64 = rng.random();
            let speckle: f64 = rng.sample(StandardNormal);
            let Some(hit) = snapshot.cast_ray_next_to(
                &origin_world,
                &dir_world,
                cfg.max_range_m,
                candidates.of_beam(beam),
                &mut ground_ranges_m[beam],
            ) else {
                continue;
            };
            if dropout < cfg.dropout_probability {
                continue;
            }
            let range_m = hit.range_m + cfg.range_noise_sigma_m * noise;
            if range_m < cfg.min_range_m || range_m > cfg.max_range_m {
                continue;
            }
            let p = dir_lidar * range_m;
            (points[count], labels[count]) = (
                LidarPoint {
                    x: p.x as f32,
                    y: p.y as f32,
                    z: p.z as f32,
                    intensity: intensity(
                        &hit,
                        &dir_world,
                        self.laser_gain[beam] * (SPECKLE_SIGMA * speckle).exp(),
                    ) as f32,
                    ring: ring_of_beam(beam),
                    time_offset_s: tau_s as f32,
                },
                hit.instance_id,
            );
            count += 1;
        }
        count as u8
    }
}

/// What every column of one sweep shares.
struct Sweep<'a> {
    scene: &'a Scene,
    world: &'a World,
    /// Per agent: a world sphere holding its box during the whole sweep.
    agent_spheres: &'a [(Point3<f64>, f64)],
    static_bins: &'a StaticBins,
    frame_index: u64,
    t_start_s: f64,
}

/// The statics each beam of one column may hit: those whose range of beam
/// slopes (tan elevation) holds the beam's, listed per beam in the order
/// they were added. A static's beams are a run of consecutive beams, as the
/// beams' slopes fall with the beam index; the lists are kept flat, and
/// the buffers are reused from column to column.
#[derive(Debug)]
struct BeamCandidates {
    /// Per static added: its index and its run of beams, `first..end`.
    runs: Vec<(usize, u8, u8)>,
    /// Where each beam's list starts in `flat` (and where the last ends).
    starts: [u32; NUM_LASERS + 1],
    flat: Vec<usize>,
}

impl Default for BeamCandidates {
    fn default() -> Self {
        BeamCandidates {
            runs: Vec::new(),
            starts: [0; NUM_LASERS + 1],
            flat: Vec::new(),
        }
    }
}

impl BeamCandidates {
    /// Forgets every static.
    fn clear(&mut self) {
        self.runs.clear();
    }

    /// Adds static `index`, which beams with slopes in `[lo, hi]` may hit;
    /// `slopes` are the beams', falling with the beam index.
    fn add(&mut self, index: usize, slopes: &[f64; NUM_LASERS], lo: f64, hi: f64) {
        let first = slopes.partition_point(|&slope| slope > hi);
        let end = slopes.partition_point(|&slope| slope >= lo);
        if first < end {
            self.runs.push((index, first as u8, end as u8));
        }
    }

    /// Lays out the lists of the statics added since [`BeamCandidates::clear`].
    fn finish(&mut self) {
        let mut starts = [0u32; NUM_LASERS + 1];
        for &(_, first, end) in &self.runs {
            for beam in first..end {
                starts[usize::from(beam) + 1] += 1;
            }
        }
        for beam in 0..NUM_LASERS {
            starts[beam + 1] += starts[beam];
        }
        self.starts = starts;
        self.flat.clear();
        self.flat.resize(starts[NUM_LASERS] as usize, 0);
        let mut next = starts;
        for &(index, first, end) in &self.runs {
            for slot in &mut next[usize::from(first)..usize::from(end)] {
                self.flat[*slot as usize] = index;
                *slot += 1;
            }
        }
    }

    /// The statics beam `beam` may hit, in the order they were added.
    fn of_beam(&self, beam: usize) -> &[usize] {
        &self.flat[self.starts[beam] as usize..self.starts[beam + 1] as usize]
    }
}

/// A static's bounding box must lie at least this far ahead of the sensor
/// in a column's plane for its beam-slope range to be used, m.
const MIN_SLOPE_ALONG_M: f64 = 1e-3;
/// Relative widening of a static's beam-slope range (rounding of the
/// corners, the plane and the beams' directions is far below it).
const SLOPE_MARGIN: f64 = 1e-9;

/// Bins of LiDAR azimuth of [`StaticBins`].
const STATIC_AZIMUTH_BINS: usize = 360;
/// Ego poses are sampled this often over a sweep to bound its motion, s.
const EGO_SAMPLE_STEP_S: f64 = 0.001;
/// Added to the sampled bounds of the ego's displacement (m) and rotation
/// (rad) for the motion between samples: far beyond what a road vehicle
/// does in a millisecond.
const EGO_MOTION_MARGIN_M: f64 = 0.05;
const EGO_ROTATION_MARGIN_RAD: f64 = 0.01;

/// The statics the columns of one sweep may see, by LiDAR azimuth: bin `b`
/// lists (ascending) every static whose bounding sphere can meet the
/// half-plane of a column with an azimuth in `b` at any time of the sweep
/// (the ego's motion over the sweep bounded from poses sampled every
/// [`EGO_SAMPLE_STEP_S`]). A superset: each column still tests its bin's
/// statics against its own half-plane.
struct StaticBins {
    bins: Vec<Vec<u32>>,
}

impl StaticBins {
    fn new(scene: &Scene, world: &World, cfg: &LidarConfig, t_start_s: f64) -> StaticBins {
        use std::f64::consts::{PI, SQRT_2, TAU};
        let span = cfg.sweep_duration_s();
        let samples = ((span / EGO_SAMPLE_STEP_S).ceil() as usize).clamp(1, 100_000);
        let trajectory = &scene.ego.trajectory;
        let start = trajectory.pose_at(t_start_s);
        let (mut displacement, mut rotation) = (0.0_f64, 0.0_f64);
        for i in 1..=samples {
            let pose = trajectory.pose_at(t_start_s + span * i as f64 / samples as f64);
            displacement =
                displacement.max((pose.translation.vector - start.translation.vector).norm());
            rotation = rotation.max(start.rotation.angle_to(&pose.rotation));
        }
        let displacement = displacement + EGO_MOTION_MARGIN_M;
        let rotation = rotation + EGO_ROTATION_MARGIN_RAD;
        let origin = Point3::from(start.translation.vector);
        let bin_width = TAU / STATIC_AZIMUTH_BINS as f64;
        let mut bins = vec![Vec::new(); STATIC_AZIMUTH_BINS];
        for (index, &(centre, radius)) in world.static_bounding_spheres().iter().enumerate() {
            let to_centre = centre - origin;
            let distance = to_centre.norm();
            if distance - radius - displacement > cfg.max_range_m {
                continue;
            }
            // the static, seen from the LiDAR at any time of the sweep, lies
            // in this sphere around where it is seen at the start
            let v = start.rotation.inverse_transform_vector(&to_centre);
            let reach = radius + displacement + rotation * (distance + radius);
            let horizontal = v.xy().norm();
            let (first, count) = if horizontal <= SQRT_2 * reach {
                // near (or above) the sensor: any column's half-plane may meet it
                (0, STATIC_AZIMUTH_BINS)
            } else {
                let half = (reach / horizontal).asin() + bin_width;
                let lo = v.y.atan2(v.x) - half;
                let first = ((lo + PI) / bin_width).floor() as i64;
                let count = (2.0 * half / bin_width).ceil() as usize + 1;
                (
                    first.rem_euclid(STATIC_AZIMUTH_BINS as i64) as usize,
                    count.min(STATIC_AZIMUTH_BINS),
                )
            };
            for k in 0..count {
                bins[(first + k) % STATIC_AZIMUTH_BINS].push(index as u32);
            }
        }
        StaticBins { bins }
    }

    /// The statics of the bin holding `azimuth_rad` (in (-pi, pi]).
    fn at(&self, azimuth_rad: f64) -> &[u32] {
        use std::f64::consts::{PI, TAU};
        let bin = ((azimuth_rad + PI) / TAU * STATIC_AZIMUTH_BINS as f64).floor() as usize;
        &self.bins[bin.min(STATIC_AZIMUTH_BINS - 1)]
    }
}

/// Checks every field; NaN fails every comparison and is caught first.
fn validate(cfg: &LidarConfig) -> Result<(), LidarError> {
    let finite = [
        ("rotation_hz", cfg.rotation_hz),
        ("max_range_m", cfg.max_range_m),
        ("min_range_m", cfg.min_range_m),
        ("range_noise_sigma_m", cfg.range_noise_sigma_m),
        ("dropout_probability", cfg.dropout_probability),
    ];
    for (field, value) in finite {
        if !value.is_finite() {
            return Err(LidarError::NotFinite { field, value });
        }
    }
    if cfg.rotation_hz <= 0.0 {
        return Err(LidarError::NotPositive {
            field: "rotation_hz",
            value: cfg.rotation_hz,
        });
    }
    if cfg.max_range_m <= 0.0 {
        return Err(LidarError::NotPositive {
            field: "max_range_m",
            value: cfg.max_range_m,
        });
    }
    for (field, value) in [
        ("min_range_m", cfg.min_range_m),
        ("range_noise_sigma_m", cfg.range_noise_sigma_m),
    ] {
        if value < 0.0 {
            return Err(LidarError::Negative { field, value });
        }
    }
    if !(0.0..1.0).contains(&cfg.dropout_probability) {
        return Err(LidarError::BadProbability(cfg.dropout_probability));
    }
    if cfg.min_range_m >= cfg.max_range_m {
        return Err(LidarError::RangeOrder {
            min_range_m: cfg.min_range_m,
            max_range_m: cfg.max_range_m,
        });
    }
    if cfg.azimuth_steps == 0 || cfg.azimuth_steps > 1_000_000 {
        return Err(LidarError::BadAzimuthSteps(cfg.azimuth_steps));
    }
    Ok(())
}

/// The noise stream of one column: key from (seed, frame), stream = column.
fn column_rng(seed: u64, frame_index: u64, column: usize) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(&frame_index.to_le_bytes());
    key[16..24].copy_from_slice(b"lidarscn");
    let mut rng = ChaCha8Rng::from_seed(key);
    rng.set_stream(column as u64);
    rng
}

/// Diffuse reflectivity of a surface kind (see the module docs).
pub fn reflectivity(surface: Surface) -> f64 {
    match surface {
        Surface::Ground => 0.22,
        Surface::Static(kind) => match kind {
            StaticKind::Building | StaticKind::Facade => 0.3,
            StaticKind::TreeTrunk | StaticKind::TreeCrown => 0.3,
            StaticKind::Shrub | StaticKind::Embankment => 0.3,
            StaticKind::Wall | StaticKind::Kerb | StaticKind::Bridge => 0.35,
            StaticKind::Fence => 0.4,
            StaticKind::Pole => 0.4,
            StaticKind::GuardRail => 0.5,
            StaticKind::Sign => 0.9,
        },
        Surface::Agent(class) => match class {
            ObjectClass::Truck => 0.35,
            ObjectClass::Car | ObjectClass::Cyclist | ObjectClass::Pedestrian => 0.3,
        },
    }
}

/// Range at which the intensity falloff halves a return, m.
const INTENSITY_FALLOFF_RANGE_M: f64 = 45.0;

/// The stored intensity of a hit (module docs); `gain` is the laser's gain
/// times the return's speckle.
fn intensity(hit: &RayHit, dir_world: &Unit<Vector3<f64>>, gain: f64) -> f64 {
    let cos_incidence = hit.normal_world.dot(dir_world).abs();
    let falloff = 1.0 / (1.0 + (hit.range_m / INTENSITY_FALLOFF_RANGE_M).powi(4));
    (reflectivity(hit.surface) * (0.8 + 0.2 * cos_incidence) * falloff * gain).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::scene::{Ego, Ground};
    use crate::trajectory::Trajectory;
    use nalgebra::Isometry3;

    #[test]
    fn min_and_max_range_are_respected() {
        let lidar_height_m = 1.73;
        let pose = Isometry3::translation(3.0, -2.0, lidar_height_m);
        let scene = Scene {
            duration_s: 1.0,
            ground: Ground::flat(0.0),
            statics: Vec::new(),
            agents: Vec::new(),
            ego: Ego {
                trajectory: Trajectory::stationary(0.0, 1.0, &pose),
                size_lwh_m: Vector3::new(4.5, 1.8, 1.5),
                box_center_lidar_m: Vector3::new(0.0, 0.0, -0.98),
                t_lidar_imu: Isometry3::identity(),
            },
        };
        let world = World::new(&scene);
        let config = LidarConfig {
            azimuth_steps: 100,
            min_range_m: 4.5,
            max_range_m: 30.0,
            range_noise_sigma_m: 0.0,
            dropout_probability: 0.0,
            ..LidarConfig::default()
        };
        let lidar = LidarSimulator::new(config, 0).unwrap();
        let sweep = lidar.scan(&scene, &world, 0, 0.0);
        // beam b sees the flat ground at h / sin(-elevation), in every column
        let expected: Vec<u16> = elevation_table_rad()
            .iter()
            .enumerate()
            .filter(|(_, el)| {
                **el < 0.0 && (4.5..=30.0).contains(&(lidar_height_m / (-**el).sin()))
            })
            .map(|(beam, _)| ring_of_beam(beam))
            .collect();
        assert!(expected.len() > 20 && expected.len() < 60);
        assert_eq!(sweep.scan.points.len(), 100 * expected.len());
        let mut log_gains = Vec::new();
        for (p, &label) in sweep.scan.points.iter().zip(&sweep.labels) {
            let range = p.position().norm();
            assert!((4.5..=30.0).contains(&range), "{range}");
            assert!(expected.contains(&p.ring));
            assert_eq!(label, 0);
            // ground at the LiDAR height below, exactly (f32 storage)
            assert!((p.z as f64 + lidar_height_m).abs() < 1e-5);
            // intensity: the surface model times a log-normal gain
            let cos_incidence = -p.z as f64 / range;
            let falloff = 1.0 / (1.0 + (range / INTENSITY_FALLOFF_RANGE_M).powi(4));
            let model = reflectivity(Surface::Ground) * (0.8 + 0.2 * cos_incidence) * falloff;
            assert!(p.intensity > 0.0 && p.intensity <= 1.0);
            log_gains.push((p.intensity as f64 / model).ln());
        }
        let n = log_gains.len() as f64;
        let mean = log_gains.iter().sum::<f64>() / n;
        let sd = (log_gains.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / n).sqrt();
        // ~30 lasers' gains (sigma 0.25) and per-return speckle (0.35)
        let want_sd = (LASER_GAIN_SIGMA.powi(2) + SPECKLE_SIGMA.powi(2)).sqrt();
        assert!(
            mean.abs() < 0.15 && (sd - want_sd).abs() < 0.1,
            "{mean} {sd}"
        );
    }

    #[test]
    fn beam_candidates_are_the_statics_whose_slope_range_holds_the_beam() {
        let table = elevation_table_rad();
        assert!(table.windows(2).all(|pair| pair[0] > pair[1]));
        let slopes = table.map(f64::tan);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut candidates = BeamCandidates::default();
        for _ in 0..50 {
            candidates.clear();
            let mut ranges = Vec::new();
            for index in 0..rng.random_range(0..40) {
                let (a, b): (f64, f64) = (rng.random_range(-0.6..0.1), rng.random_range(-0.6..0.1));
                let (lo, hi) = match rng.random_range(0..4) {
                    0 => (f64::NEG_INFINITY, f64::INFINITY),
                    // exactly a beam's slope at either end
                    1 => (slopes[index % NUM_LASERS], slopes[index % NUM_LASERS]),
                    _ => (a.min(b), a.max(b)),
                };
                candidates.add(index * 7, &slopes, lo, hi);
                ranges.push((index * 7, lo, hi));
            }
            candidates.finish();
            for (beam, slope) in slopes.iter().enumerate() {
                let want: Vec<usize> = ranges
                    .iter()
                    .filter(|(_, lo, hi)| (*lo..=*hi).contains(slope))
                    .map(|(index, _, _)| *index)
                    .collect();
                assert_eq!(candidates.of_beam(beam), want.as_slice(), "{beam}");
            }
        }
    }

    #[test]
    fn config_validation_rejects_bad_fields() {
        let ok = LidarConfig::default();
        assert!(LidarSimulator::new(ok.clone(), 1).is_ok());
        let bad = |f: fn(&mut LidarConfig)| {
            let mut c = ok.clone();
            f(&mut c);
            LidarSimulator::new(c, 1).unwrap_err()
        };
        assert!(matches!(
            bad(|c| c.rotation_hz = f64::NAN),
            LidarError::NotFinite {
                field: "rotation_hz",
                ..
            }
        ));
        assert!(matches!(
            bad(|c| c.rotation_hz = 0.0),
            LidarError::NotPositive { .. }
        ));
        assert!(matches!(
            bad(|c| c.range_noise_sigma_m = -0.1),
            LidarError::Negative { .. }
        ));
        assert!(matches!(
            bad(|c| c.dropout_probability = 1.0),
            LidarError::BadProbability(_)
        ));
        assert!(matches!(
            bad(|c| c.min_range_m = 200.0),
            LidarError::RangeOrder { .. }
        ));
        assert!(matches!(
            bad(|c| c.azimuth_steps = 0),
            LidarError::BadAzimuthSteps(0)
        ));
        assert!(matches!(
            bad(|c| c.max_range_m = f64::INFINITY),
            LidarError::NotFinite { .. }
        ));
    }
}
