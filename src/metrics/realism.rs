//! Realism statistics of a LiDAR sequence: what its scans and its true
//! sensor attitude look like to a scan matcher, computed alike for simulated
//! and real sequences so the two can be put side by side (definitions and
//! figures in docs/realism.md).
//!
//! Input, per sweep: the points in the sensor frame with their rings
//! (0 = lowest laser) and the sensor attitude in a gravity-aligned world
//! (`r_level_lidar`). Per sequence:
//! - **attitude change**: |Δroll| and |Δpitch| of the sensor between
//!   consecutive sweeps (deg; roll and pitch as in `Rz(yaw) Ry(pitch) Rx(roll)`);
//! - **ground-ring displacement**: each sweep's ground is a plane fitted to the
//!   near rings (rings `0..near_rings`); per near ring and azimuth bin the mean
//!   range of its ground returns; for consecutive sweeps the median |Δrange|
//!   over the (ring, bin) cells both have (m), summarised over sweep pairs;
//! - **along-track information share**: the points more than
//!   `above_ground_m` above the ground plane, voxel-thinned; each one's
//!   surface normal by PCA of its nearest neighbours, rotated into the vehicle
//!   frame (x forward); the share of `sum n nᵀ`'s trace on x, y and z (%);
//! - **range and intensity**: histograms (fraction of points per bin), medians,
//!   fraction of points beyond `far_range_m`; points per sweep.
//!
//! Every statistic is a property of the sensor-frame data and the truth only:
//! no estimator is involved. [`compare`] gives each scalar statistic's ratio
//! to a reference sequence's.

use super::EvalError;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use limot_estimator::geometry::wrap_angle_rad;
use limot_estimator::input::LidarPoint;
use limot_estimator::lidar::voxel_downsample;
use nalgebra::{Matrix3, SymmetricEigen, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};
use std::num::NonZeroUsize;

/// Parameters of the statistics (the defaults are the documented ones).
#[derive(Debug, Clone, PartialEq)]
pub struct RealismConfig {
    /// Rings `0..near_rings` are the near rings (ground fit and displacement);
    /// 32 = the HDL-64E's lower block, which meets a flat road within ~12 m.
    pub near_rings: u16,
    /// Azimuth bins per revolution for the ground-ring cells. 36 (10°) puts
    /// ~50 returns of an HDL-64E ring in a cell, so 2 cm of range noise
    /// leaves a floor of ~3 mm in the median |Δrange|.
    pub azimuth_bins: usize,
    /// Near-ring points up to this horizontal range fit the ground plane, m.
    pub ground_fit_max_range_m: f64,
    /// A near-ring point within this distance (along z) of the plane is ground, m.
    pub ground_tolerance_m: f64,
    /// A pair of sweeps needs this many common ground cells to count.
    pub min_common_cells: usize,
    /// Points more than this above the ground plane carry the information, m.
    pub above_ground_m: f64,
    /// Voxel edge of the thinning before the normals, m.
    pub information_voxel_m: f64,
    /// Neighbours of a point's PCA (the point included).
    pub normal_neighbours: usize,
    /// Neighbours farther than this are not used, m; fewer than 5 left: no normal.
    pub normal_radius_m: f64,
    /// Width of the coarse range bins, m, and their count (the last takes all beyond).
    pub range_bin_m: f64,
    /// Number of range bins.
    pub range_bins: usize,
    /// Intensity bins over [0, 1] (values outside go to the end bins).
    pub intensity_bins: usize,
    /// Range beyond which a point counts as far, m.
    pub far_range_m: f64,
    /// A pair of consecutive sweeps counts for the attitude change and the
    /// ground-ring displacement when the sensor moved at least this far
    /// between them, m: a car standing at a light is not compared with a
    /// moving one.
    pub moving_min_m: f64,
}

impl Default for RealismConfig {
    fn default() -> Self {
        RealismConfig {
            near_rings: 32,
            azimuth_bins: 36,
            ground_fit_max_range_m: 30.0,
            ground_tolerance_m: 0.15,
            min_common_cells: 50,
            above_ground_m: 0.3,
            information_voxel_m: 0.25,
            normal_neighbours: 10,
            normal_radius_m: 1.0,
            range_bin_m: 5.0,
            range_bins: 24,
            intensity_bins: 20,
            far_range_m: 40.0,
            moving_min_m: 0.1,
        }
    }
}

/// Mean, median and spread of a list of non-negative values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Spread {
    /// Number of values.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Median.
    pub median: f64,
    /// 5th percentile.
    pub p5: f64,
    /// 95th percentile.
    pub p95: f64,
}

impl Spread {
    /// `None` for an empty list. Percentiles interpolate linearly between
    /// order statistics (numpy's default).
    pub fn of(values: &[f64]) -> Option<Spread> {
        if values.is_empty() {
            return None;
        }
        let mut sorted = values.to_vec();
        sorted.sort_by(f64::total_cmp);
        Some(Spread {
            n: sorted.len(),
            mean: sorted.iter().sum::<f64>() / sorted.len() as f64,
            median: percentile(&sorted, 0.5),
            p5: percentile(&sorted, 0.05),
            p95: percentile(&sorted, 0.95),
        })
    }
}

/// Percentile `q` in [0, 1] of sorted, non-empty values.
fn percentile(sorted: &[f64], q: f64) -> f64 {
    let pos = q * (sorted.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = (lo + 1).min(sorted.len() - 1);
    sorted[lo] + (pos - lo as f64) * (sorted[hi] - sorted[lo])
}

/// A histogram with equal bins from `start`; `fractions` sum to 1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Histogram {
    /// Lower edge of the first bin.
    pub start: f64,
    /// Width of each bin.
    pub bin_width: f64,
    /// Fraction of the points per bin; the first and last bins also take
    /// the values below and beyond the range.
    pub fractions: Vec<f64>,
}

/// The statistics of one sequence (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RealismStats {
    /// Sweeps analysed.
    pub sweeps: usize,
    /// Mean number of points per sweep.
    pub points_per_sweep_mean: f64,
    /// |Δroll| per consecutive sweep pair while moving, deg.
    pub roll_change_deg: Spread,
    /// |Δpitch| per consecutive sweep pair while moving, deg.
    pub pitch_change_deg: Spread,
    /// Per sweep pair while moving: median |Δrange| of the common near-ring
    /// ground cells, m.
    pub ground_ring_displacement_m: Spread,
    /// Consecutive sweep pairs with the sensor standing (left out of the
    /// three spreads above).
    #[serde(default)]
    pub standing_pairs: usize,
    /// Sweep pairs without enough common ground cells (not in the spread).
    pub ground_pairs_skipped: usize,
    /// Share of the information matrix's trace along x (driving direction),
    /// y (left) and z (up) of the vehicle frame, %.
    pub information_share_pct: [f64; 3],
    /// Points that got a normal (after thinning), over all sweeps.
    pub information_points: usize,
    /// Median point range, m.
    pub range_median_m: f64,
    /// Fraction of the points beyond `far_range_m`.
    pub range_beyond_far_fraction: f64,
    /// The far range, m.
    pub far_range_m: f64,
    /// Point ranges in coarse bins.
    pub range_histogram: Histogram,
    /// Median point intensity.
    pub intensity_median: f64,
    /// Point intensities in bins over [0, 1].
    pub intensity_histogram: Histogram,
}

impl RealismStats {
    /// The scalar statistics compared with a reference: (key, unit, value).
    pub fn scalars(&self) -> Vec<(&'static str, &'static str, f64)> {
        vec![
            (
                "roll change per frame, mean",
                "deg",
                self.roll_change_deg.mean,
            ),
            (
                "roll change per frame, p95",
                "deg",
                self.roll_change_deg.p95,
            ),
            (
                "pitch change per frame, mean",
                "deg",
                self.pitch_change_deg.mean,
            ),
            (
                "pitch change per frame, p95",
                "deg",
                self.pitch_change_deg.p95,
            ),
            (
                "ground-ring displacement, median",
                "m",
                self.ground_ring_displacement_m.median,
            ),
            (
                "ground-ring displacement, p95",
                "m",
                self.ground_ring_displacement_m.p95,
            ),
            (
                "along-track information share",
                "%",
                self.information_share_pct[0],
            ),
            ("range, median", "m", self.range_median_m),
            (
                "points beyond 40 m",
                "fraction",
                self.range_beyond_far_fraction,
            ),
            ("intensity, median", "-", self.intensity_median),
            ("points per sweep, mean", "-", self.points_per_sweep_mean),
        ]
    }
}

/// One scalar statistic beside its reference value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StatComparison {
    /// Name of the statistic.
    pub statistic: String,
    /// Its unit.
    pub unit: String,
    /// Value of the analysed sequence.
    pub value: f64,
    /// Value of the reference.
    pub reference: f64,
    /// `value / reference`; 1 when both are 0, infinite when only the reference is.
    pub ratio: f64,
    /// `1/2 <= ratio <= 2`.
    pub within_factor_2: bool,
}

/// Every scalar statistic of `stats` beside the same of `reference`.
pub fn compare_realism(stats: &RealismStats, reference: &RealismStats) -> Vec<StatComparison> {
    stats
        .scalars()
        .into_iter()
        .zip(reference.scalars())
        .map(|((name, unit, value), (_, _, reference))| {
            let ratio = if value == 0.0 && reference == 0.0 {
                1.0
            } else if reference == 0.0 {
                f64::INFINITY
            } else {
                value / reference
            };
            StatComparison {
                statistic: name.to_string(),
                unit: unit.to_string(),
                value,
                reference,
                ratio,
                within_factor_2: (0.5..=2.0).contains(&ratio),
            }
        })
        .collect()
}

/// Roll and pitch (rad) of an attitude in a gravity-aligned world, from
/// `R = Rz(yaw) Ry(pitch) Rx(roll)`.
pub fn roll_pitch_rad(r_level_lidar: &UnitQuaternion<f64>) -> (f64, f64) {
    let m = r_level_lidar.to_rotation_matrix();
    let m = m.matrix();
    let roll = m[(2, 1)].atan2(m[(2, 2)]);
    let pitch = (-m[(2, 0)]).clamp(-1.0, 1.0).asin();
    (roll, pitch)
}

/// A ground plane `z = a + b x + c y` in the sensor frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundPlane {
    /// Coefficient of x in `z = a·x + b·y + c`.
    pub a: f64,
    /// Coefficient of y.
    pub b: f64,
    /// Height at the origin, m.
    pub c: f64,
}

impl GroundPlane {
    /// Height of `p` above the plane (along z), m.
    pub fn height_of(&self, p: &Vector3<f64>) -> f64 {
        p.z - (self.a + self.b * p.x + self.c * p.y)
    }
}

/// Fits the ground plane of one sweep to its near-ring points (see
/// [`RealismConfig`]): the densest 0.2 m height band within 15 m seeds it,
/// then least squares on the points within 0.3 m, 0.3 m (out to
/// `ground_fit_max_range_m`) and `ground_tolerance_m` of the previous fit.
/// `None` when fewer than 20 points support it.
pub fn fit_ground_plane(points: &[LidarPoint], config: &RealismConfig) -> Option<GroundPlane> {
    let near: Vec<Vector3<f64>> = points
        .iter()
        .filter(|p| p.ring < config.near_rings)
        .map(LidarPoint::position)
        .filter(|p| {
            let rho = p.xy().norm();
            (2.0..=config.ground_fit_max_range_m).contains(&rho)
        })
        .collect();
    let mut seed_z: Vec<f64> = near
        .iter()
        .filter(|p| p.xy().norm() <= 15.0)
        .map(|p| p.z)
        .collect();
    if seed_z.len() < 20 {
        return None;
    }
    seed_z.sort_by(f64::total_cmp);
    let (mut best, mut best_count, mut j) = (0usize, 0usize, 0usize);
    for i in 0..seed_z.len() {
        while j < seed_z.len() && seed_z[j] - seed_z[i] <= 0.2 {
            j += 1;
        }
        if j - i > best_count {
            (best, best_count) = (i, j - i);
        }
    }
    let mut plane = GroundPlane {
        a: 0.5 * (seed_z[best] + seed_z[best + best_count - 1]),
        b: 0.0,
        c: 0.0,
    };
    let stages = [
        (15.0, 0.3),
        (config.ground_fit_max_range_m, 0.3),
        (config.ground_fit_max_range_m, config.ground_tolerance_m),
    ];
    for (max_rho, tolerance) in stages {
        let inliers = near
            .iter()
            .filter(|p| p.xy().norm() <= max_rho && plane.height_of(p).abs() < tolerance);
        plane = least_squares_plane(inliers)?;
    }
    Some(plane)
}

fn least_squares_plane<'a>(points: impl Iterator<Item = &'a Vector3<f64>>) -> Option<GroundPlane> {
    let mut ata = Matrix3::zeros();
    let mut atz = Vector3::zeros();
    let mut n = 0usize;
    for p in points {
        let row = Vector3::new(1.0, p.x, p.y);
        ata += row * row.transpose();
        atz += row * p.z;
        n += 1;
    }
    if n < 20 {
        return None;
    }
    let sol = ata.cholesky()?.solve(&atz);
    sol.iter().all(|v| v.is_finite()).then_some(GroundPlane {
        a: sol[0],
        b: sol[1],
        c: sol[2],
    })
}

/// A neighbourhood is a surface, not a line, when its second principal
/// variance is at least this fraction of the first.
const MIN_PLANE_SPREAD: f64 = 0.05;

/// Surface normals of `points` by PCA of each one's nearest neighbours (see
/// [`RealismConfig`]); points without enough neighbours, or whose
/// neighbours lie along a line, get none.
pub fn surface_normals(points: &[Vector3<f64>], config: &RealismConfig) -> Vec<Vector3<f64>> {
    let Some(k) = NonZeroUsize::new(config.normal_neighbours.max(3)) else {
        return Vec::new();
    };
    if points.len() < 5 {
        return Vec::new();
    }
    let coords: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
    let Ok(tree) = ImmutableKdTree::<f64, 3>::new_from_slice(&coords) else {
        return Vec::new();
    };
    let radius_sq = config.normal_radius_m * config.normal_radius_m;
    let mut normals = Vec::with_capacity(points.len());
    for q in &coords {
        let found = tree
            .query(q)
            .nearest_n::<SquaredEuclidean<f64>>(k)
            .execute();
        let near: Vec<Vector3<f64>> = found
            .iter()
            .filter(|n| n.distance <= radius_sq)
            .map(|n| points[n.item as usize])
            .collect();
        if near.len() < 5 {
            continue;
        }
        let mean = near.iter().sum::<Vector3<f64>>() / near.len() as f64;
        let cov = near
            .iter()
            .map(|p| (p - mean) * (p - mean).transpose())
            .sum::<Matrix3<f64>>();
        let eig = SymmetricEigen::new(cov);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        let [smallest, middle, largest] = order;
        // a line (pole, lone ring segment) has no normal
        if eig.eigenvalues[middle] < MIN_PLANE_SPREAD * eig.eigenvalues[largest] {
            continue;
        }
        let normal = eig.eigenvectors.column(smallest).into_owned();
        if normal.iter().all(|v| v.is_finite()) && normal.norm() > 0.5 {
            normals.push(normal.normalize());
        }
    }
    normals
}

/// Accumulates the statistics sweep by sweep (a sequence need not fit in
/// memory).
#[derive(Debug, Clone)]
pub struct RealismAccumulator {
    config: RealismConfig,
    sweeps: usize,
    points: u64,
    previous_attitude: Option<(f64, f64)>,
    previous_position: Option<Vector3<f64>>,
    standing_pairs: usize,
    roll_changes_deg: Vec<f64>,
    pitch_changes_deg: Vec<f64>,
    previous_cells: Option<Vec<f32>>,
    displacements_m: Vec<f64>,
    pairs_skipped: usize,
    information: Matrix3<f64>,
    information_points: usize,
    far_points: u64,
    /// Fine histograms for the medians: 1 cm range bins to 200 m, 0.001 intensity bins.
    range_fine: Vec<u64>,
    intensity_fine: Vec<u64>,
}

const RANGE_FINE_M: f64 = 0.01;
const RANGE_FINE_BINS: usize = 20_000;
const INTENSITY_FINE_BINS: usize = 1000;

impl RealismAccumulator {
    /// An empty accumulator; a configuration out of range is an error.
    ///
    /// # Errors
    ///
    /// [`EvalError::BadParameter`] for an invalid configuration.
    pub fn new(config: RealismConfig) -> Result<RealismAccumulator, EvalError> {
        let bad = |why: &str| EvalError::BadParameter {
            what: "realism config",
            why: why.to_string(),
        };
        if config.near_rings == 0 || config.azimuth_bins == 0 {
            return Err(bad("near_rings and azimuth_bins must be positive"));
        }
        if config.range_bins == 0 || config.intensity_bins == 0 {
            return Err(bad("histograms need at least one bin"));
        }
        let positive = [
            config.ground_fit_max_range_m,
            config.ground_tolerance_m,
            config.above_ground_m,
            config.information_voxel_m,
            config.normal_radius_m,
            config.range_bin_m,
            config.far_range_m,
            config.moving_min_m,
        ];
        if !positive.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(bad("lengths must be positive and finite"));
        }
        Ok(RealismAccumulator {
            config,
            sweeps: 0,
            points: 0,
            previous_attitude: None,
            previous_position: None,
            standing_pairs: 0,
            roll_changes_deg: Vec::new(),
            pitch_changes_deg: Vec::new(),
            previous_cells: None,
            displacements_m: Vec::new(),
            pairs_skipped: 0,
            information: Matrix3::zeros(),
            information_points: 0,
            far_points: 0,
            range_fine: vec![0; RANGE_FINE_BINS],
            intensity_fine: vec![0; INTENSITY_FINE_BINS],
        })
    }

    /// Adds the next sweep: `points` in the sensor frame with rings,
    /// `r_level_lidar` the sensor attitude in a gravity-aligned world,
    /// `p_world_lidar` the sensor position (any fixed world frame),
    /// `r_vehicle_lidar` the sensor's rotation in the vehicle frame (x
    /// forward). An empty sweep or a non-finite point, position or attitude
    /// is an error naming the sweep (0-based) and point.
    ///
    /// # Errors
    ///
    /// [`EvalError`] for non-finite points or poses.
    pub fn add_sweep(
        &mut self,
        points: &[LidarPoint],
        r_level_lidar: &UnitQuaternion<f64>,
        p_world_lidar: &Vector3<f64>,
        r_vehicle_lidar: &UnitQuaternion<f64>,
    ) -> Result<(), EvalError> {
        let sweep = self.sweeps;
        if points.is_empty() {
            return Err(EvalError::Invalid {
                what: "sweep",
                index: sweep,
                field: "points",
                why: "no points".to_string(),
            });
        }
        for (i, p) in points.iter().enumerate() {
            if ![p.x, p.y, p.z, p.intensity].iter().all(|v| v.is_finite()) {
                return Err(EvalError::Invalid {
                    what: "sweep",
                    index: sweep,
                    field: "points",
                    why: format!("point {i} is not finite"),
                });
            }
        }
        let q = r_level_lidar.quaternion();
        let qv = r_vehicle_lidar.quaternion();
        if ![q.i, q.j, q.k, q.w, qv.i, qv.j, qv.k, qv.w]
            .iter()
            .chain(p_world_lidar.iter())
            .all(|v| v.is_finite())
        {
            return Err(EvalError::NotFinite {
                what: "sweep",
                index: sweep,
                field: "attitude",
            });
        }

        // attitude change, while moving
        let moving = self
            .previous_position
            .is_some_and(|p0| (p_world_lidar - p0).norm() >= self.config.moving_min_m);
        if self.previous_position.is_some() && !moving {
            self.standing_pairs += 1;
        }
        self.previous_position = Some(*p_world_lidar);
        let (roll, pitch) = roll_pitch_rad(r_level_lidar);
        if let Some((roll0, pitch0)) = self.previous_attitude
            && moving
        {
            self.roll_changes_deg
                .push(wrap_angle_rad(roll - roll0).abs().to_degrees());
            self.pitch_changes_deg
                .push(wrap_angle_rad(pitch - pitch0).abs().to_degrees());
        }
        self.previous_attitude = Some((roll, pitch));

        // range / intensity
        for p in points {
            let range = p.position().norm();
            if range > self.config.far_range_m {
                self.far_points += 1;
            }
            self.range_fine[bin_of(range, 0.0, RANGE_FINE_M, RANGE_FINE_BINS)] += 1;
            let width = 1.0 / INTENSITY_FINE_BINS as f64;
            self.intensity_fine[bin_of(p.intensity as f64, 0.0, width, INTENSITY_FINE_BINS)] += 1;
        }
        self.points += points.len() as u64;

        // ground cells and information
        let plane = fit_ground_plane(points, &self.config);
        let cells = plane.map(|plane| self.ground_cells(points, &plane));
        match (&self.previous_cells, &cells) {
            _ if sweep > 0 && !moving => {}
            (Some(before), Some(now)) => match self.cell_displacement(before, now) {
                Some(d) => self.displacements_m.push(d),
                None => self.pairs_skipped += 1,
            },
            _ if sweep > 0 => self.pairs_skipped += 1,
            _ => {}
        }
        self.previous_cells = cells;
        if let Some(plane) = plane {
            self.add_information(points, &plane, r_vehicle_lidar);
        }
        self.sweeps += 1;
        Ok(())
    }

    /// Mean range of the ground returns per (near ring, azimuth bin); NaN = none.
    fn ground_cells(&self, points: &[LidarPoint], plane: &GroundPlane) -> Vec<f32> {
        let bins = self.config.azimuth_bins;
        let n = self.config.near_rings as usize * bins;
        let mut sums = vec![(0.0f64, 0u32); n];
        for p in points.iter().filter(|p| p.ring < self.config.near_rings) {
            let pos = p.position();
            if plane.height_of(&pos).abs() >= self.config.ground_tolerance_m {
                continue;
            }
            let az = (pos.y.atan2(pos.x) + PI) / TAU;
            let bin = ((az * bins as f64) as usize).min(bins - 1);
            let cell = &mut sums[p.ring as usize * bins + bin];
            cell.0 += pos.norm();
            cell.1 += 1;
        }
        sums.into_iter()
            .map(|(s, c)| {
                if c > 0 {
                    (s / c as f64) as f32
                } else {
                    f32::NAN
                }
            })
            .collect()
    }

    /// Median |Δrange| over the cells both sweeps have; `None` with too few.
    fn cell_displacement(&self, before: &[f32], now: &[f32]) -> Option<f64> {
        let mut d: Vec<f64> = before
            .iter()
            .zip(now)
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .map(|(a, b)| (f64::from(*b) - f64::from(*a)).abs())
            .collect();
        if d.len() < self.config.min_common_cells.max(1) {
            return None;
        }
        d.sort_by(f64::total_cmp);
        Some(percentile(&d, 0.5))
    }

    fn add_information(
        &mut self,
        points: &[LidarPoint],
        plane: &GroundPlane,
        r_vehicle_lidar: &UnitQuaternion<f64>,
    ) {
        let above: Vec<Vector3<f64>> = points
            .iter()
            .map(LidarPoint::position)
            .filter(|p| plane.height_of(p) > self.config.above_ground_m)
            .collect();
        let thinned = voxel_downsample(&above, self.config.information_voxel_m);
        for n in surface_normals(&thinned, &self.config) {
            let n = r_vehicle_lidar * n;
            self.information += n * n.transpose();
            self.information_points += 1;
        }
    }

    /// The statistics; fewer than two sweeps, no ground pair or no normal
    /// is an error.
    ///
    /// # Errors
    ///
    /// [`EvalError::TooFew`] when too few sweeps or points were added.
    pub fn finish(self) -> Result<RealismStats, EvalError> {
        let too_few =
            |what: &'static str, got: usize, need: usize| EvalError::TooFew { what, got, need };
        let moving_pairs = self.roll_changes_deg.len();
        let roll = Spread::of(&self.roll_changes_deg)
            .ok_or_else(|| too_few("realism: sweep pairs while moving", moving_pairs, 1))?;
        let pitch = Spread::of(&self.pitch_changes_deg)
            .ok_or_else(|| too_few("realism: sweep pairs while moving", moving_pairs, 1))?;
        let ground = Spread::of(&self.displacements_m)
            .ok_or_else(|| too_few("realism: sweep pairs with ground in the near rings", 0, 1))?;
        let trace = self.information.trace();
        if self.information_points == 0 || trace <= 0.0 {
            return Err(too_few("realism: above-ground points with a normal", 0, 1));
        }
        let share = [0, 1, 2].map(|i| 100.0 * self.information[(i, i)] / trace);
        let total = self.points as f64;
        let c = &self.config;
        let range_histogram = coarse(&self.range_fine, RANGE_FINE_M, c.range_bin_m, c.range_bins);
        let intensity_fine_width = 1.0 / INTENSITY_FINE_BINS as f64;
        let intensity_histogram = coarse(
            &self.intensity_fine,
            intensity_fine_width,
            1.0 / c.intensity_bins as f64,
            c.intensity_bins,
        );
        Ok(RealismStats {
            sweeps: self.sweeps,
            points_per_sweep_mean: total / self.sweeps as f64,
            roll_change_deg: roll,
            pitch_change_deg: pitch,
            ground_ring_displacement_m: ground,
            ground_pairs_skipped: self.pairs_skipped,
            standing_pairs: self.standing_pairs,
            information_share_pct: share,
            information_points: self.information_points,
            range_median_m: fine_median(&self.range_fine, RANGE_FINE_M),
            range_beyond_far_fraction: self.far_points as f64 / total,
            far_range_m: c.far_range_m,
            range_histogram,
            intensity_median: fine_median(&self.intensity_fine, intensity_fine_width),
            intensity_histogram,
        })
    }
}

/// Bin of `v` among `bins` bins of `width` from `start`, clamped to the ends.
fn bin_of(v: f64, start: f64, width: f64, bins: usize) -> usize {
    let b = ((v - start) / width).floor();
    if b.is_nan() || b < 0.0 {
        0
    } else {
        (b as usize).min(bins - 1)
    }
}

/// Median of a fine histogram (the value at the middle of its bin).
fn fine_median(counts: &[u64], width: f64) -> f64 {
    let total: u64 = counts.iter().sum();
    let half = total.div_ceil(2);
    let mut seen = 0;
    for (i, c) in counts.iter().enumerate() {
        seen += c;
        if seen >= half && *c > 0 {
            return (i as f64 + 0.5) * width;
        }
    }
    0.0
}

/// Regroups a fine histogram (bins of `fine_width` from 0) into `bins` coarse
/// bins of `width` from 0 (the last takes all beyond), as fractions.
fn coarse(counts: &[u64], fine_width: f64, width: f64, bins: usize) -> Histogram {
    let total: u64 = counts.iter().sum();
    let mut out = vec![0u64; bins];
    for (i, c) in counts.iter().enumerate() {
        let centre = (i as f64 + 0.5) * fine_width;
        out[bin_of(centre, 0.0, width, bins)] += c;
    }
    Histogram {
        start: 0.0,
        bin_width: width,
        fractions: out
            .into_iter()
            .map(|c| c as f64 / total.max(1) as f64)
            .collect(),
    }
}

#[cfg(test)]
mod tests;
