//! LiDAR front end on a synthetic rolling scan: de-skew against an analytic
//! world (box room, vertical poles, ground plane) seen by a 64-ring spinning
//! LiDAR moving along a curved path with rotation, and LOAM features on it.

use limot_estimator::input::{LidarPoint, LidarScan};
use limot_estimator::lidar::{
    DESKEW_RELATIVE_TOLERANCE, Deskewer, FeatureConfig, FeatureExtractor, ScanFeatures,
    SweepMotion, deskew, extract_features,
};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector2, Vector3};
use proptest::prelude::*;
use std::f64::consts::{PI, TAU};
use std::sync::OnceLock;
use std::time::Instant;

const SWEEP_S: f64 = 0.1;
const COLUMNS: usize = 2000;
const RINGS: usize = 64;
const T_SCAN_S: f64 = 0.0;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Surface {
    WallXMin,
    WallXMax,
    WallYMin,
    WallYMax,
    Ground,
    Pole(usize),
}

impl Surface {
    fn is_pole(self) -> bool {
        matches!(self, Surface::Pole(_))
    }
}

/// Box room with infinitely high walls, a ground plane and vertical poles.
struct World {
    x_min: f64,
    x_max: f64,
    y_min: f64,
    y_max: f64,
    ground_z: f64,
    /// (centre xy, radius)
    poles: Vec<(Vector2<f64>, f64)>,
}

impl World {
    fn new() -> World {
        World {
            x_min: -25.0,
            x_max: 30.0,
            y_min: -12.0,
            y_max: 15.0,
            ground_z: -1.8,
            poles: vec![
                (Vector2::new(5.0, 4.0), 0.2),
                (Vector2::new(10.0, -5.0), 0.3),
                (Vector2::new(-8.0, 6.0), 0.25),
                (Vector2::new(15.0, 8.0), 0.2),
                (Vector2::new(-12.0, -6.0), 0.3),
                (Vector2::new(2.0, -3.0), 0.15),
            ],
        }
    }

    /// Nearest hit of the ray `origin + t·dir` (`dir` unit): (range, surface).
    fn cast(&self, origin: &Vector3<f64>, dir: &Vector3<f64>) -> Option<(f64, Surface)> {
        let mut best: Option<(f64, Surface)> = None;
        let mut consider = |t: f64, s: Surface| {
            if t > 1e-9 && best.is_none_or(|(b, _)| t < b) {
                best = Some((t, s));
            }
        };
        let planes = [
            (self.x_min, 0, Surface::WallXMin),
            (self.x_max, 0, Surface::WallXMax),
            (self.y_min, 1, Surface::WallYMin),
            (self.y_max, 1, Surface::WallYMax),
            (self.ground_z, 2, Surface::Ground),
        ];
        for (value, axis, surface) in planes {
            if dir[axis] != 0.0 {
                consider((value - origin[axis]) / dir[axis], surface);
            }
        }
        for (i, (c, r)) in self.poles.iter().enumerate() {
            let (dx, dy) = (dir.x, dir.y);
            let (ox, oy) = (origin.x - c.x, origin.y - c.y);
            let a = dx * dx + dy * dy;
            let b = 2.0 * (ox * dx + oy * dy);
            let cc = ox * ox + oy * oy - r * r;
            let disc = b * b - 4.0 * a * cc;
            if a > 0.0 && disc >= 0.0 {
                consider((-b - disc.sqrt()) / (2.0 * a), Surface::Pole(i));
            }
        }
        best
    }

    fn distance_to_surface(&self, q: &Vector3<f64>, s: Surface) -> f64 {
        match s {
            Surface::WallXMin => (q.x - self.x_min).abs(),
            Surface::WallXMax => (q.x - self.x_max).abs(),
            Surface::WallYMin => (q.y - self.y_min).abs(),
            Surface::WallYMax => (q.y - self.y_max).abs(),
            Surface::Ground => (q.z - self.ground_z).abs(),
            Surface::Pole(i) => {
                let (c, r) = self.poles[i];
                ((q.xy() - c).norm() - r).abs()
            }
        }
    }

    fn distance_to_any_surface(&self, q: &Vector3<f64>) -> f64 {
        let mut all = vec![
            Surface::WallXMin,
            Surface::WallXMax,
            Surface::WallYMin,
            Surface::WallYMax,
            Surface::Ground,
        ];
        all.extend((0..self.poles.len()).map(Surface::Pole));
        all.iter()
            .map(|s| self.distance_to_surface(q, *s))
            .fold(f64::INFINITY, f64::min)
    }

    /// Distance to the nearest geometric edge: the room's vertical corners,
    /// the wall-ground lines, the poles' feet, and (for a pole point) the pole's silhouette as
    /// seen from `origin` (arc length to the tangent point).
    fn distance_to_edge(&self, q: &Vector3<f64>, s: Surface, origin: &Vector3<f64>) -> f64 {
        let mut d = f64::INFINITY;
        for x in [self.x_min, self.x_max] {
            for y in [self.y_min, self.y_max] {
                d = d.min(((q.x - x).powi(2) + (q.y - y).powi(2)).sqrt());
            }
            d = d.min(((q.x - x).powi(2) + (q.z - self.ground_z).powi(2)).sqrt());
        }
        for y in [self.y_min, self.y_max] {
            d = d.min(((q.y - y).powi(2) + (q.z - self.ground_z).powi(2)).sqrt());
        }
        // where the poles stand on the ground (concave circular edges)
        for (c, r) in &self.poles {
            let radial = (q.xy() - c).norm() - r;
            d = d.min((radial.powi(2) + (q.z - self.ground_z).powi(2)).sqrt());
        }
        if let Surface::Pole(i) = s {
            let (c, r) = self.poles[i];
            let to_point = q.xy() - c;
            let to_origin = origin.xy() - c;
            let phi = to_point.angle(&to_origin);
            let tangent = (r / to_origin.norm()).acos();
            d = d.min(r * (phi - tangent).abs());
        }
        d
    }
}

/// The true LiDAR pose: curved path (lateral sine, quadratic drift), yaw with
/// angular acceleration, small roll/pitch oscillations.
fn true_pose(t_s: f64) -> Isometry3<f64> {
    let t = t_s;
    let translation = Vector3::new(
        -3.0 + 12.0 * t,
        3.0 * t * t + 0.3 * (10.0 * t).sin(),
        0.05 * (20.0 * t).sin(),
    );
    let rotation = UnitQuaternion::from_euler_angles(
        0.03 * (12.0 * t).sin(),
        0.02 * (15.0 * t).sin(),
        0.3 + 1.5 * t + 4.0 * t * t,
    );
    Isometry3::from_parts(translation.into(), rotation)
}

/// Per point ground truth.
#[derive(Clone, Copy)]
struct Truth {
    world: Vector3<f64>,
    surface: Surface,
    origin_world: Vector3<f64>,
    column: usize,
}

struct Synthetic {
    world: World,
    scan: LidarScan,
    truth: Vec<Truth>,
}

fn elevation_rad(ring: usize) -> f64 {
    (-24.8 + ring as f64 * 26.8 / (RINGS - 1) as f64).to_radians()
}

/// Rolling scan, stored column by column as the simulator does. The head
/// turns clockwise from azimuth π (as KITTI's HDL-64E). Times are rounded to
/// f32 first so that the truth uses exactly the stored time.
fn synthesize(world: World, range_noise_sigma_m: f64) -> Synthetic {
    let mut normal = gaussian(12345);
    let mut points = Vec::new();
    let mut truth = Vec::new();
    for column in 0..COLUMNS {
        let tau = (column as f64 * SWEEP_S / COLUMNS as f64) as f32;
        let t_s = T_SCAN_S + tau as f64;
        let azimuth = PI - TAU * tau as f64 / SWEEP_S;
        let pose = true_pose(t_s);
        let origin = pose.translation.vector;
        for ring in 0..RINGS {
            let el = elevation_rad(ring);
            let dir_lidar =
                Vector3::new(el.cos() * azimuth.cos(), el.cos() * azimuth.sin(), el.sin());
            let dir_world = pose.rotation * dir_lidar;
            let Some((range, surface)) = world.cast(&origin, &dir_world) else {
                continue;
            };
            if !(1.0..=120.0).contains(&range) {
                continue;
            }
            let p = dir_lidar * (range + range_noise_sigma_m * normal());
            points.push(LidarPoint {
                x: p.x as f32,
                y: p.y as f32,
                z: p.z as f32,
                intensity: 0.5,
                ring: ring as u16,
                time_offset_s: tau,
            });
            truth.push(Truth {
                world: origin + dir_world * range,
                surface,
                origin_world: origin,
                column,
            });
        }
    }
    Synthetic {
        world,
        scan: LidarScan {
            t_s: T_SCAN_S,
            sweep_duration_s: SWEEP_S,
            num_rings: RINGS as u16,
            points,
        },
        truth,
    }
}

/// Deterministic standard normal samples (splitmix64 + Box-Muller).
fn gaussian(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        let mut uniform = || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        };
        let (u1, u2) = (uniform(), uniform());
        (-2.0 * (1.0 - u1).ln()).sqrt() * (TAU * u2).cos()
    }
}

fn synthetic() -> &'static Synthetic {
    static S: OnceLock<Synthetic> = OnceLock::new();
    S.get_or_init(|| synthesize(World::new(), 0.0))
}

fn motion_with_samples(n: usize) -> SweepMotion {
    let samples = (0..n)
        .map(|i| {
            let t = T_SCAN_S + SWEEP_S * i as f64 / (n - 1) as f64;
            (t, true_pose(t))
        })
        .collect();
    SweepMotion::from_poses(samples).unwrap()
}

const T_REF_S: f64 = T_SCAN_S + SWEEP_S;

fn deskewed_dense() -> &'static Vec<Vector3<f64>> {
    static D: OnceLock<Vec<Vector3<f64>>> = OnceLock::new();
    D.get_or_init(|| {
        let mut out = Vec::new();
        deskew(
            &synthetic().scan,
            &motion_with_samples(1001),
            T_REF_S,
            &mut out,
        );
        out
    })
}

/// Largest distance between de-skewed points and the exact transform of the
/// stored points with the analytic pose.
fn max_deskew_error(out: &[Vector3<f64>]) -> f64 {
    let s = synthetic();
    let inv_ref = true_pose(T_REF_S).inverse();
    s.scan
        .points
        .iter()
        .zip(out)
        .map(|(p, q)| {
            let t = s.scan.t_s + p.time_offset_s as f64;
            let exact = inv_ref * true_pose(t) * Point3::from(p.position());
            (exact.coords - q).norm()
        })
        .fold(0.0, f64::max)
}

#[test]
fn deskew_brings_points_onto_the_static_geometry() {
    let s = synthetic();
    assert!(s.scan.points.len() > 120_000, "{}", s.scan.points.len());
    let t_world_ref = true_pose(T_REF_S);
    let dense = deskewed_dense();
    assert_eq!(dense.len(), s.scan.points.len());

    // 1. against the exact analytic motion: only slerp/linear interpolation
    //    between 1001 samples (0.1 ms apart) remains
    let dense_err = max_deskew_error(dense);
    // 2. in the world: onto the true hit points and surfaces (the stored
    //    points are f32: ~4 µm quantisation at 60 m)
    let mut max_world_err = 0.0f64;
    let mut max_surface_dist = 0.0f64;
    for (q, truth) in dense.iter().zip(&s.truth) {
        let w = t_world_ref * Point3::from(*q);
        max_world_err = max_world_err.max((w.coords - truth.world).norm());
        max_surface_dist = max_surface_dist.max(s.world.distance_to_any_surface(&w.coords));
    }
    // 3. without de-skew (raw points taken as if measured at t_ref)
    let mut max_raw_err = 0.0f64;
    let mut sum_raw_err = 0.0;
    for (p, truth) in s.scan.points.iter().zip(&s.truth) {
        let w = t_world_ref * Point3::from(p.position());
        let e = (w.coords - truth.world).norm();
        max_raw_err = max_raw_err.max(e);
        sum_raw_err += e;
    }
    // 4. IMU-like sparse samples (15 per sweep) and constant velocity
    let mut out = Vec::new();
    deskew(&s.scan, &motion_with_samples(15), T_REF_S, &mut out);
    let sparse_err = max_deskew_error(&out);
    let cv =
        SweepMotion::constant_velocity(T_SCAN_S, true_pose(T_SCAN_S), T_REF_S, true_pose(T_REF_S))
            .unwrap();
    deskew(&s.scan, &cv, T_REF_S, &mut out);
    let cv_err = max_deskew_error(&out);
    println!(
        "deskew on {} points: dense samples max err {dense_err:.2e} m, world max err \
         {max_world_err:.2e} m, max distance to a surface {max_surface_dist:.2e} m; \
         15 samples max err {sparse_err:.2e} m; constant velocity max err {cv_err:.3} m; \
         no de-skew max err {max_raw_err:.3} m (mean {:.3} m)",
        s.scan.points.len(),
        sum_raw_err / s.scan.points.len() as f64
    );
    assert!(dense_err < 1e-6, "{dense_err}");
    assert!(max_world_err < 2e-5, "{max_world_err}");
    assert!(max_surface_dist < 2e-5, "{max_surface_dist}");
    assert!(sparse_err < 5e-3, "{sparse_err}");
    assert!(sparse_err < cv_err, "{sparse_err} vs {cv_err}");
    // the motion over the sweep: 1.2 m forward, 0.19 rad of yaw
    assert!(max_raw_err > 1.0, "{max_raw_err}");
}

#[test]
fn deskew_timing() {
    let s = synthetic();
    let motion = motion_with_samples(15);
    let mut deskewer = Deskewer::new();
    let mut out = Vec::new();
    deskewer.deskew(&s.scan, &motion, T_REF_S, &mut out);
    let start = Instant::now();
    let reps = 10;
    for _ in 0..reps {
        deskewer.deskew(&s.scan, &motion, T_REF_S, &mut out);
    }
    let per_column_ms = start.elapsed().as_secs_f64() * 1e3 / reps as f64;
    // KITTI-like: every point has its own time (from its azimuth)
    let mut kitti = s.scan.clone();
    for (p, truth) in kitti.points.iter_mut().zip(&s.truth) {
        let jitter = (truth.column % 7) as f32 * 1e-7 + p.ring as f32 * 1e-8;
        p.time_offset_s += jitter;
    }
    let start = Instant::now();
    for _ in 0..reps {
        deskewer.deskew(&kitti, &motion, T_REF_S, &mut out);
    }
    let per_point_ms = start.elapsed().as_secs_f64() * 1e3 / reps as f64;
    println!(
        "deskew timing on {} points: {per_column_ms:.2} ms (times shared per column), \
         {per_point_ms:.2} ms (a time per point)",
        s.scan.points.len()
    );
}

fn features_default() -> &'static ScanFeatures {
    static F: OnceLock<ScanFeatures> = OnceLock::new();
    F.get_or_init(|| {
        extract_features(
            deskewed_dense(),
            &synthetic().scan,
            &FeatureConfig::default(),
        )
    })
}

/// Positions in the scan of `ring` sorted by column.
fn ring_members(s: &Synthetic, ring: u16) -> Vec<usize> {
    let mut v: Vec<usize> = (0..s.scan.points.len())
        .filter(|&i| s.scan.points[i].ring == ring)
        .collect();
    v.sort_by_key(|&i| s.truth[i].column);
    v
}

#[test]
fn planar_points_lie_inside_surfaces() {
    let s = synthetic();
    let f = features_default();
    let t_world_ref = true_pose(T_REF_S);
    let dense = deskewed_dense();
    assert!(f.planar_indices.len() > s.scan.points.len() / 2);
    let mut max_dist = 0.0f64;
    let mut on_planes = 0;
    for &i in &f.planar_indices {
        let w = t_world_ref * Point3::from(dense[i]);
        max_dist = max_dist.max(s.world.distance_to_surface(&w.coords, s.truth[i].surface));
        if !s.truth[i].surface.is_pole() {
            on_planes += 1;
        }
    }
    // the ±5 neighbourhood of a planar point (same ring, by column) lies on
    // its surface: no planar point straddles a corner or a silhouette
    let mut straddling = 0;
    let planar: std::collections::HashSet<usize> = f.planar_indices.iter().copied().collect();
    for ring in 0..RINGS as u16 {
        let members = ring_members(s, ring);
        for (k, &i) in members.iter().enumerate() {
            if !planar.contains(&i) {
                continue;
            }
            let lo = k.saturating_sub(1);
            let hi = (k + 2).min(members.len());
            if members[lo..hi]
                .iter()
                .any(|&j| s.truth[j].surface != s.truth[i].surface)
            {
                straddling += 1;
            }
        }
    }
    let straddle_fraction = straddling as f64 / f.planar_indices.len() as f64;
    println!(
        "planar: {} points ({} on walls/ground, rest on poles), max distance to their surface \
         {max_dist:.2e} m, {straddling} ({:.3}%) next to another surface",
        f.planar_indices.len(),
        on_planes,
        100.0 * straddle_fraction
    );
    assert!(max_dist < 2e-5, "{max_dist}");
    assert!(straddle_fraction < 0.005, "{straddle_fraction}");
}

#[test]
fn edges_lie_near_corners_and_pole_silhouettes() {
    let s = synthetic();
    let f = features_default();
    let t_world_ref = true_pose(T_REF_S);
    let dense = deskewed_dense();
    let mut near = 0;
    let mut dists = Vec::new();
    for &i in &f.edge_indices {
        let w = t_world_ref * Point3::from(dense[i]);
        let d = s
            .world
            .distance_to_edge(&w.coords, s.truth[i].surface, &s.truth[i].origin_world);
        dists.push(d);
        if d < 0.3 {
            near += 1;
        }
    }
    dists.sort_by(f64::total_cmp);
    let precision = near as f64 / f.edge_indices.len() as f64;
    let pole_edges: Vec<usize> = (0..s.world.poles.len())
        .map(|p| {
            f.edge_indices
                .iter()
                .filter(|&&i| s.truth[i].surface == Surface::Pole(p))
                .count()
        })
        .collect();
    println!(
        "edges: {} points, precision (within 0.3 m of a corner, wall-ground line, pole foot \
         or pole silhouette) {:.3}, median distance {:.3} m, 95th percentile {:.3} m, per pole {:?}",
        f.edge_indices.len(),
        precision,
        dists[dists.len() / 2],
        dists[dists.len() * 95 / 100],
        pole_edges
    );
    assert!(f.edge_indices.len() > 100);
    assert!(precision > 0.9, "{precision}");
    assert!(pole_edges.iter().all(|&c| c > 0), "{pole_edges:?}");
}

/// Wall/ground points within 6 columns of a closer pole in the same ring:
/// their neighbourhood changes with the viewpoint.
fn occluded_candidates(s: &Synthetic) -> Vec<usize> {
    let mut out = Vec::new();
    for ring in 0..RINGS as u16 {
        let members = ring_members(s, ring);
        for (k, &i) in members.iter().enumerate() {
            if s.truth[i].surface.is_pole() {
                continue;
            }
            let lo = k.saturating_sub(6);
            let hi = (k + 7).min(members.len());
            let range_i = s.scan.points[i].position().norm();
            // behind the pole (more than 0.3 m from its surface), not at its
            // foot, where ground and pole meet in a real concave edge
            if members[lo..hi].iter().any(|&j| {
                let Surface::Pole(p) = s.truth[j].surface else {
                    return false;
                };
                s.scan.points[j].position().norm() < range_i - 0.3
                    && s.truth[j].column.abs_diff(s.truth[i].column) <= 6
                    && s.world
                        .distance_to_surface(&s.truth[i].world, Surface::Pole(p))
                        > 0.3
            }) {
                out.push(i);
            }
        }
    }
    out
}

#[test]
fn occluded_points_behind_pole_edges_are_not_edges() {
    let s = synthetic();
    let candidates = occluded_candidates(s);
    assert!(candidates.len() > 100, "{}", candidates.len());
    let f = features_default();
    let edges: std::collections::HashSet<usize> = f.edge_indices.iter().copied().collect();
    let planar: std::collections::HashSet<usize> = f.planar_indices.iter().copied().collect();
    let occluded_edges = candidates.iter().filter(|i| edges.contains(i)).count();
    let occluded_planar = candidates.iter().filter(|i| planar.contains(i)).count();
    // control: without the occlusion check they do become edges
    let no_check = FeatureConfig {
        occlusion_depth_jump_m: f64::INFINITY,
        ..FeatureConfig::default()
    };
    let f_no_check = extract_features(deskewed_dense(), &s.scan, &no_check);
    let unprotected: std::collections::HashSet<usize> =
        f_no_check.edge_indices.iter().copied().collect();
    let control = candidates
        .iter()
        .filter(|i| unprotected.contains(i))
        .count();
    println!(
        "occlusion: {} wall/ground points next to a pole silhouette; edges among them {} \
         (planar {}), without the occlusion check {}",
        candidates.len(),
        occluded_edges,
        occluded_planar,
        control
    );
    assert_eq!(occluded_edges, 0);
    assert_eq!(occluded_planar, 0);
    assert!(control > 10, "{control}");
}

#[test]
fn a_dropout_gap_makes_no_spurious_edges() {
    let s = synthetic();
    let dense = deskewed_dense();
    // find, in an upper ring, 100 consecutive columns on one wall seen
    // obliquely (range changing fast), and remove the middle 40 columns
    let ring = 56u16;
    let members = ring_members(s, ring);
    let window = 100;
    let start = (0..members.len() - window)
        .find(|&k| {
            let run = &members[k..k + window];
            let surface = s.truth[run[0]].surface;
            run.iter().all(|&i| s.truth[i].surface == surface)
                && !surface.is_pole()
                && run
                    .windows(2)
                    .all(|w| s.truth[w[1]].column == s.truth[w[0]].column + 1)
                && run.windows(2).all(|w| {
                    let r0 = s.scan.points[w[0]].position().norm();
                    let r1 = s.scan.points[w[1]].position().norm();
                    (r1 - r0).abs() > 0.03
                })
        })
        .expect("no oblique wall stretch in the ring");
    let removed: std::collections::HashSet<usize> =
        members[start + 30..start + 70].iter().copied().collect();
    let keep: Vec<usize> = (0..s.scan.points.len())
        .filter(|i| !removed.contains(i))
        .collect();
    let mut scan = s.scan.clone();
    scan.points = keep.iter().map(|&i| s.scan.points[i]).collect();
    let points: Vec<Vector3<f64>> = keep.iter().map(|&i| dense[i]).collect();
    let stretch: std::collections::HashSet<usize> =
        members[start..start + window].iter().copied().collect();
    let count_in_stretch = |f: &ScanFeatures| {
        f.edge_indices
            .iter()
            .filter(|&&k| stretch.contains(&keep[k]))
            .count()
    };
    let f = extract_features(&points, &scan, &FeatureConfig::default());
    let spurious = count_in_stretch(&f);
    let no_segments = FeatureConfig {
        max_azimuth_gap_rad: PI,
        ..FeatureConfig::default()
    };
    let control = count_in_stretch(&extract_features(&points, &scan, &no_segments));
    println!(
        "dropout gap of 40 columns (7.2°) on an oblique wall in ring {ring}: {spurious} edges \
         next to it, {control} without segmenting at gaps"
    );
    assert_eq!(spurious, 0);
    assert!(control > 0);
}

/// A deterministic permutation from a seed (splitmix64 + Fisher-Yates).
fn permutation(n: usize, seed: u64) -> Vec<usize> {
    let mut state = seed;
    let mut next = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let mut p: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        let j = (next() % (i as u64 + 1)) as usize;
        p.swap(i, j);
    }
    p
}

/// Every 4th ring of the synthetic scan (a 16-ring sensor), for speed.
fn sixteen_rings() -> &'static (LidarScan, Vec<Vector3<f64>>) {
    static S: OnceLock<(LidarScan, Vec<Vector3<f64>>)> = OnceLock::new();
    S.get_or_init(|| {
        let s = synthetic();
        let dense = deskewed_dense();
        let keep: Vec<usize> = (0..s.scan.points.len())
            .filter(|&i| s.scan.points[i].ring.is_multiple_of(4))
            .collect();
        let mut scan = s.scan.clone();
        scan.points = keep
            .iter()
            .map(|&i| {
                let mut p = s.scan.points[i];
                p.ring /= 4;
                p
            })
            .collect();
        scan.num_rings = 16;
        (scan, keep.iter().map(|&i| dense[i]).collect())
    })
}

fn sorted(mut v: Vec<usize>) -> Vec<usize> {
    v.sort_unstable();
    v
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Storage order does not matter: shuffled points give the same sets.
    #[test]
    fn shuffled_points_give_the_same_feature_sets(seed in any::<u64>()) {
        let (scan, points) = sixteen_rings();
        let config = FeatureConfig::default();
        let reference = extract_features(points, scan, &config);
        let perm = permutation(scan.points.len(), seed);
        let mut shuffled = scan.clone();
        shuffled.points = perm.iter().map(|&i| scan.points[i]).collect();
        let shuffled_points: Vec<Vector3<f64>> = perm.iter().map(|&i| points[i]).collect();
        let f = extract_features(&shuffled_points, &shuffled, &config);
        let back = |v: &[usize]| sorted(v.iter().map(|&k| perm[k]).collect());
        prop_assert!(!reference.edge_indices.is_empty());
        prop_assert_eq!(back(&f.edge_indices), sorted(reference.edge_indices.clone()));
        prop_assert_eq!(back(&f.planar_indices), sorted(reference.planar_indices.clone()));
    }
}

/// KITTI stores ring by ring, the simulator column by column: same sets.
#[test]
fn ring_major_storage_gives_the_same_features() {
    let s = synthetic();
    let dense = deskewed_dense();
    let mut perm: Vec<usize> = (0..s.scan.points.len()).collect();
    perm.sort_by_key(|&i| (s.scan.points[i].ring, s.truth[i].column));
    let mut scan = s.scan.clone();
    scan.points = perm.iter().map(|&i| s.scan.points[i]).collect();
    let points: Vec<Vector3<f64>> = perm.iter().map(|&i| dense[i]).collect();
    let f = extract_features(&points, &scan, &FeatureConfig::default());
    let reference = features_default();
    let back = |v: &[usize]| sorted(v.iter().map(|&k| perm[k]).collect());
    assert_eq!(
        back(&f.edge_indices),
        sorted(reference.edge_indices.clone())
    );
    assert_eq!(
        back(&f.planar_indices),
        sorted(reference.planar_indices.clone())
    );
}

#[test]
fn feature_extraction_timing() {
    let s = synthetic();
    let dense = deskewed_dense();
    let mut extractor = FeatureExtractor::new(FeatureConfig::default());
    let mut out = ScanFeatures::default();
    extractor.extract_into(dense, &s.scan, &mut out);
    let reps = 10;
    let start = Instant::now();
    for _ in 0..reps {
        extractor.extract_into(dense, &s.scan, &mut out);
    }
    let column_major_ms = start.elapsed().as_secs_f64() * 1e3 / reps as f64;
    // storage that needs the per-ring sort
    let perm = permutation(s.scan.points.len(), 7);
    let mut shuffled = s.scan.clone();
    shuffled.points = perm.iter().map(|&i| s.scan.points[i]).collect();
    let shuffled_points: Vec<Vector3<f64>> = perm.iter().map(|&i| dense[i]).collect();
    let start = Instant::now();
    for _ in 0..reps {
        extractor.extract_into(&shuffled_points, &shuffled, &mut out);
    }
    let shuffled_ms = start.elapsed().as_secs_f64() * 1e3 / reps as f64;
    println!(
        "extract_features on {} points: {column_major_ms:.2} ms (column-major storage), \
         {shuffled_ms:.2} ms (shuffled); {} edges, {} planar",
        s.scan.points.len(),
        out.edge_indices.len(),
        out.planar_indices.len()
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// The fast de-skew equals its definition `pose_at(t_ref)⁻¹·pose_at(t)·p`
    /// (within its documented tolerance) for random motions, point times (also outside the samples) and
    /// reference times.
    #[test]
    fn deskew_equals_its_definition(
        steps in proptest::collection::vec(
            (0.001f64..0.05, proptest::array::uniform3(-0.5f64..0.5),
             proptest::array::uniform3(-0.3f64..0.3)), 1..12),
        taus in proptest::collection::vec(-0.02f32..0.15, 1..40),
        t_ref_frac in -0.2f64..1.2,
    ) {
        let mut t = 3.0;
        let mut pose = Isometry3::identity();
        let mut samples = vec![(t, pose)];
        for (dt, dp, dphi) in &steps {
            t += dt;
            pose *= Isometry3::new(Vector3::from(*dp), Vector3::from(*dphi));
            samples.push((t, pose));
        }
        let motion = SweepMotion::from_poses(samples.clone()).unwrap();
        for (ts, p) in &samples {
            prop_assert_eq!(motion.pose_at(*ts), *p);
        }
        let points: Vec<LidarPoint> = taus
            .iter()
            .enumerate()
            .map(|(i, &tau)| LidarPoint {
                x: 5.0 + i as f32,
                y: -2.0 + 0.3 * i as f32,
                z: 1.0 - 0.1 * i as f32,
                intensity: 0.0,
                ring: 0,
                time_offset_s: tau,
            })
            .collect();
        let scan = LidarScan { t_s: 3.0, sweep_duration_s: 0.1, num_rings: 1, points };
        let t_ref = 3.0 + t_ref_frac * (t - 3.0);
        let mut out = Vec::new();
        deskew(&scan, &motion, t_ref, &mut out);
        let inv_ref = motion.pose_at(t_ref).inverse();
        for (p, q) in scan.points.iter().zip(&out) {
            let expected = inv_ref
                * motion.pose_at(scan.t_s + p.time_offset_s as f64)
                * Point3::from(p.position());
            // within rounding and the rotation table's bound
            let bound = 1e-9 + DESKEW_RELATIVE_TOLERANCE * p.position().norm();
            prop_assert!((expected.coords - q).norm() < bound, "{} vs {}", expected, q);
        }
    }
}

/// KITTI `.bin` scan with rings from KITTI's laser-by-laser storage order
/// (a new laser where the azimuth in [0, 2π) drops by more than π; ring =
/// 63 − line) and times from the azimuth (clockwise from the rear at 10 Hz),
/// as the root crate's KITTI reader derives them. `None` unless 64 lines.
fn read_kitti_bin(path: &std::path::Path) -> Option<LidarScan> {
    let bytes = std::fs::read(path).ok()?;
    let mut points = Vec::with_capacity(bytes.len() / 16);
    let mut line = 0u16;
    let mut previous_az: Option<f64> = None;
    for chunk in bytes.chunks_exact(16) {
        let f = |k: usize| {
            f32::from_le_bytes([
                chunk[4 * k],
                chunk[4 * k + 1],
                chunk[4 * k + 2],
                chunk[4 * k + 3],
            ])
        };
        let (x, y, z, intensity) = (f(0), f(1), f(2), f(3));
        let az = (y as f64).atan2(x as f64);
        let az_pos = az.rem_euclid(TAU);
        if previous_az.is_some_and(|prev| az_pos < prev - PI) {
            line += 1;
        }
        previous_az = Some(az_pos);
        points.push(LidarPoint {
            x,
            y,
            z,
            intensity,
            ring: line,
            time_offset_s: ((PI - az) / TAU * SWEEP_S) as f32,
        });
    }
    if line != 63 {
        return None;
    }
    for p in &mut points {
        p.ring = 63 - p.ring;
    }
    Some(LidarScan {
        t_s: 0.0,
        sweep_duration_s: SWEEP_S,
        num_rings: 64,
        points,
    })
}

/// The 20 real KITTI scans of `shared/data/kitti_raw_scans` (skipped with a
/// message when the directory is absent).
#[test]
fn real_kitti_scans() {
    let dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/kitti_raw_scans");
    let Ok(entries) = std::fs::read_dir(&dir) else {
        println!("no KITTI scans at {}: skipped", dir.display());
        return;
    };
    let mut paths: Vec<_> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    paths.sort();
    let mut extractor = FeatureExtractor::new(FeatureConfig::default());
    let mut deskewer = Deskewer::new();
    let motion = SweepMotion::constant_velocity(
        0.0,
        Isometry3::identity(),
        SWEEP_S,
        Isometry3::translation(0.1, 0.0, 0.0),
    )
    .unwrap();
    let (mut n_scans, mut total_ms, mut total_points, mut total_edges, mut total_planar) =
        (0, 0.0, 0, 0, 0);
    let mut positions = Vec::new();
    let mut features = ScanFeatures::default();
    for path in &paths {
        let Some(scan) = read_kitti_bin(path) else {
            continue;
        };
        deskewer.deskew(&scan, &motion, SWEEP_S, &mut positions);
        let start = Instant::now();
        extractor.extract_into(&positions, &scan, &mut features);
        total_ms += start.elapsed().as_secs_f64() * 1e3;
        let n = scan.points.len();
        assert!(features.edge_indices.iter().all(|&i| i < n));
        assert!(features.planar_indices.iter().all(|&i| i < n));
        let edges: std::collections::HashSet<usize> =
            features.edge_indices.iter().copied().collect();
        assert_eq!(edges.len(), features.edge_indices.len());
        assert!(features.planar_indices.iter().all(|i| !edges.contains(i)));
        assert!(features.edge_indices.len() <= 64 * 6 * 20);
        assert!(
            features.edge_indices.len() > 100,
            "{}",
            features.edge_indices.len()
        );
        assert!(
            features.planar_indices.len() > n / 4,
            "{}",
            features.planar_indices.len()
        );
        if n_scans == 0 {
            // storage order does not matter on real data either
            let perm = permutation(n, 11);
            let mut shuffled = scan.clone();
            shuffled.points = perm.iter().map(|&i| scan.points[i]).collect();
            let shuffled_positions: Vec<Vector3<f64>> =
                perm.iter().map(|&i| positions[i]).collect();
            let f = extract_features(&shuffled_positions, &shuffled, &FeatureConfig::default());
            let back = |v: &[usize]| sorted(v.iter().map(|&k| perm[k]).collect());
            assert_eq!(back(&f.edge_indices), sorted(features.edge_indices.clone()));
            assert_eq!(
                back(&f.planar_indices),
                sorted(features.planar_indices.clone())
            );
        }
        n_scans += 1;
        total_points += n;
        total_edges += features.edge_indices.len();
        total_planar += features.planar_indices.len();
    }
    assert!(
        n_scans > 0,
        "no KITTI scan with 64 scan lines in {}",
        dir.display()
    );
    println!(
        "KITTI: {n_scans} scans, {:.0} points/scan, {:.0} edges and {:.0} planar per scan, \
         extract_features {:.2} ms/scan",
        total_points as f64 / n_scans as f64,
        total_edges as f64 / n_scans as f64,
        total_planar as f64 / n_scans as f64,
        total_ms / n_scans as f64
    );
}

/// With the simulator's range noise (σ = 2 cm) LIO-SAM's thresholds still
/// give edges at corners and silhouettes; the planar set shrinks because
/// the noise alone gives a flat surface a curvature of ~0.04 m² on average.
#[test]
fn features_with_range_noise() {
    let s = synthesize(World::new(), 0.02);
    let mut positions = Vec::new();
    deskew(&s.scan, &motion_with_samples(1001), T_REF_S, &mut positions);
    let f = extract_features(&positions, &s.scan, &FeatureConfig::default());
    let t_world_ref = true_pose(T_REF_S);
    let near = f
        .edge_indices
        .iter()
        .filter(|&&i| {
            let w = t_world_ref * Point3::from(positions[i]);
            s.world
                .distance_to_edge(&w.coords, s.truth[i].surface, &s.truth[i].origin_world)
                < 0.3
        })
        .count();
    let precision = near as f64 / f.edge_indices.len().max(1) as f64;
    let planar_on_surface = f
        .planar_indices
        .iter()
        .filter(|&&i| {
            let w = t_world_ref * Point3::from(positions[i]);
            s.world.distance_to_surface(&w.coords, s.truth[i].surface) < 0.1
        })
        .count();
    println!(
        "range noise 2 cm: {} edges, precision {precision:.3}; {} planar ({:.1}% of the points), \
         {planar_on_surface} within 10 cm of their surface",
        f.edge_indices.len(),
        f.planar_indices.len(),
        100.0 * f.planar_indices.len() as f64 / s.scan.points.len() as f64
    );
    assert!(precision > 0.8, "{precision}");
    assert!(f.planar_indices.len() > s.scan.points.len() / 4);
    assert_eq!(planar_on_surface, f.planar_indices.len());
}

mod symmetric_eigen3_props {
    use limot_estimator::eigen3::{Decomposition, symmetric_eigen3};
    use nalgebra::{Matrix3, Rotation3, SymmetricEigen, Vector3};
    use proptest::prelude::*;

    /// A symmetric matrix with the given eigenvalues in a random basis.
    fn with_eigenvalues(values: [f64; 3], axis_angle: [f64; 3]) -> Matrix3<f64> {
        let r = Rotation3::new(Vector3::from(axis_angle)).into_inner();
        r * Matrix3::from_diagonal(&Vector3::from(values)) * r.transpose()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// Eigenvalues as nalgebra's iterative solver gives them, and each
        /// column an eigenvector of unit length, the basis orthonormal and
        /// right-handed, over scales from point clouds (1e-6) to 1e4: to
        /// 1e-12 of the norm when the eigenvalues are a tenth of it apart,
        /// to 1e-7 (√ε) when two (nearly) coincide.
        #[test]
        fn agrees_with_the_iterative_solver(
            a in -1.0..1.0f64, b in -1.0..1.0f64, c in -1.0..1.0f64,
            axis in prop::array::uniform3(-3.0..3.0f64),
            log_scale in -6.0..4.0f64,
            repeat in 0usize..4,
        ) {
            let scale = 10f64.powf(log_scale);
            // some cases with exactly repeated or zero eigenvalues
            let values = match repeat {
                0 => [a, b, c],
                1 => [a, a, c],
                2 => [a, c, c],
                _ => [0.0, 0.0, c],
            }
            .map(|v| v * scale);
            let m = with_eigenvalues(values, axis);
            let (ours, vectors) = symmetric_eigen3(&m);
            let mut reference: Vec<f64> = SymmetricEigen::new(m).eigenvalues.iter().copied().collect();
            reference.sort_by(f64::total_cmp);
            let norm = m.norm().max(f64::MIN_POSITIVE);
            let mut sorted = values;
            sorted.sort_by(f64::total_cmp);
            let gap = (sorted[1] - sorted[0]).min(sorted[2] - sorted[1]);
            let tolerance = if gap >= 0.1 * norm { 1e-12 } else { 1e-7 } * norm;
            for i in 0..3 {
                prop_assert!((ours[i] - reference[i]).abs() <= tolerance, "{ours} vs {reference:?}");
                let v = vectors.column(i).into_owned();
                prop_assert!((v.norm() - 1.0).abs() < 1e-9);
                prop_assert!((m * v - v * ours[i]).norm() <= tolerance, "column {i} of {vectors}");
            }
            prop_assert!((vectors.transpose() * vectors - Matrix3::identity()).norm() < 1e-9);
            prop_assert!((vectors.determinant() - 1.0).abs() < 1e-9);
            // The on-demand form gives the same bits.
            let lazy = Decomposition::of(&m);
            prop_assert_eq!(lazy.values(), ours);
            prop_assert_eq!(lazy.extreme_vector(false), vectors.column(0).into_owned());
            prop_assert_eq!(lazy.extreme_vector(true), vectors.column(2).into_owned());
        }
    }
}
