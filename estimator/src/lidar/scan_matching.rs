//! LOAM / LIO-SAM scan-to-map matching on SE(3).
//!
//! Edge points of the scan are matched to lines fitted to their `k` nearest
//! edge-map points, planar points to the plane of the planar map's grid
//! octant they fall in when they lie on it or else to a plane fitted to
//! their `k` nearest planar-map points. The pose `T = t_world_lidar` is
//! refined by robust Gauss–Newton in OUR right-perturbation tangent
//! `T·Exp(ξ)`, `ξ = (ρ, φ)`.
//!
//! Residuals (metres, unit variance; the pipeline scales the information):
//! * point-to-line: `r = u × (T·p − a)` (3-vector, norm = distance to the
//!   line through `a` with unit direction `u`); unlike LOAM's scalar distance
//!   it is smooth at zero and constrains both directions normal to the line.
//! * point-to-plane: `r = nᵀ(T·p) + d` (signed distance to the plane).
//!
//! Degeneracy (LOAM, Zhang et al. 2016 "On degeneracy of optimization-based
//! state estimation problems"): every iteration the unweighted normal matrix
//! `JᵀJ` is eigen-decomposed; eigen-directions with eigenvalue below
//! [`ScanMatchConfig::degeneracy_eigenvalue_threshold`] receive no update
//! ("solution remapping"), so along them the estimate stays at the initial
//! guess, which comes from the IMU prediction. The step is the robust
//! Gauss–Newton step restricted to the well-conditioned subspace (see
//! `restricted_gauss_newton_step`).
//!
//! Speed: a planar point takes the plane of the map's grid octant it falls
//! in ([`MapCloud::plane_at`], fitted once per keyframe) where that octant
//! has one and the point lies on it, and searches its `k` neighbours only
//! otherwise; neighbours come from the local map's hash grid
//! ([`MapCloud::nearest_k_within`], faster than the k-d tree on these clouds);
//! correspondences are cached per scan point and re-searched only when the
//! point's world position moved more than
//! [`ScanMatchConfig::reassociation_distance_m`] since its last search, so
//! after the first iteration or two an iteration costs only the accumulation
//! of `H` (fixed-size 6×6 arithmetic, no per-point allocation).

use std::num::NonZeroUsize;

use nalgebra::{Isometry3, Matrix3, Matrix3x6, Matrix6, SymmetricEigen, Vector3, Vector6};
use thiserror::Error;

use super::cell_planes::MapPlane;
use super::local_map::{LocalMap, MapCloud};
use super::neighbour_grid::Neighbour;
use crate::eigen3::Decomposition;
use crate::graph::RobustKernel;
use crate::lie::{self, skew};

/// Settings of [`match_scan`]. Defaults follow LOAM / LIO-SAM.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanMatchConfig {
    /// Maximum Gauss–Newton iterations (LIO-SAM: 30).
    pub max_iterations: usize,
    /// Map neighbours per scan point for the line / plane fit (LOAM: 5).
    pub num_neighbours: usize,
    /// A correspondence is used only if all its neighbours lie within this
    /// distance of the transformed scan point, m (LOAM: 1.0).
    pub max_neighbour_dist_m: f64,
    /// Line test: largest eigenvalue of the neighbours' covariance must
    /// exceed this many times the second largest (LOAM: 3).
    pub line_eigenvalue_ratio: f64,
    /// Plane test: every neighbour within this distance of the fitted
    /// plane, m (LOAM: 0.2).
    pub max_plane_fit_residual_m: f64,
    /// Robust kernel on the point residual norm (m); `None` = least squares.
    /// Default Cauchy with k = 0.1 m: residuals of a converged match are
    /// centimetres, outliers that survive the neighbour tests decimetres.
    pub robust_kernel: Option<RobustKernel>,
    /// Converged when the rotation update is below this, deg (LIO-SAM 0.05)…
    pub convergence_rotation_deg: f64,
    /// …and the translation update below this, m (LIO-SAM: 0.05 cm).
    pub convergence_translation_m: f64,
    /// Eigen-directions of the unweighted normal matrix `JᵀJ` (residuals in
    /// metres, tangent `(ρ [m], φ [rad])`) with eigenvalue below this are
    /// degenerate. A translation eigenvalue equals the number of
    /// correspondences constraining that direction (`Σ (nᵀv)²` over the
    /// plane normals / line normal spaces), so the default 100 (LOAM's value,
    /// whose residuals have the same scaling) means "fewer than ~100 points
    /// constrain it". Rotation eigenvalues carry an extra lever arm² (m²).
    pub degeneracy_eigenvalue_threshold: f64,
    /// Fewer valid correspondences than this is an error (LIO-SAM needs
    /// > 10 edge and > 100 planar points; we require 50 in total).
    pub min_correspondences: usize,
    /// A scan point's correspondence is searched again only when its world
    /// position moved more than this since the last search, m (default 0.1:
    /// a tenth of the neighbour radius, so the fitted line / plane is still
    /// the local one). 0 = search every iteration (LIO-SAM's behaviour,
    /// slower).
    pub reassociation_distance_m: f64,
}

impl Default for ScanMatchConfig {
    fn default() -> Self {
        Self {
            max_iterations: 30,
            num_neighbours: 5,
            max_neighbour_dist_m: 1.0,
            line_eigenvalue_ratio: 3.0,
            max_plane_fit_residual_m: 0.2,
            robust_kernel: Some(RobustKernel::Cauchy { k: 0.1 }),
            convergence_rotation_deg: 0.05,
            convergence_translation_m: 0.0005,
            degeneracy_eigenvalue_threshold: 100.0,
            min_correspondences: 50,
            reassociation_distance_m: 0.1,
        }
    }
}

impl ScanMatchConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`ScanMatchError::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<(), ScanMatchError> {
        let bad = |field: &'static str, value: f64, reason: &'static str| {
            Err(ScanMatchError::InvalidConfig {
                field,
                value,
                reason,
            })
        };
        if self.max_iterations == 0 {
            return bad("max_iterations", 0.0, "must be at least 1");
        }
        if self.num_neighbours < 3 {
            return bad(
                "num_neighbours",
                self.num_neighbours as f64,
                "a line/plane fit needs at least 3 neighbours",
            );
        }
        for (field, value) in [
            ("max_neighbour_dist_m", self.max_neighbour_dist_m),
            ("line_eigenvalue_ratio", self.line_eigenvalue_ratio),
            ("max_plane_fit_residual_m", self.max_plane_fit_residual_m),
            ("convergence_rotation_deg", self.convergence_rotation_deg),
            ("convergence_translation_m", self.convergence_translation_m),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return bad(field, value, "must be positive and finite");
            }
        }
        for (field, value) in [
            (
                "degeneracy_eigenvalue_threshold",
                self.degeneracy_eigenvalue_threshold,
            ),
            ("reassociation_distance_m", self.reassociation_distance_m),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return bad(field, value, "must be non-negative and finite");
            }
        }
        if let Some(kernel) = self.robust_kernel {
            let (RobustKernel::Huber { k } | RobustKernel::Cauchy { k }) = kernel;
            if !(k.is_finite() && k > 0.0) {
                return bad("robust_kernel.k", k, "must be positive and finite");
            }
        }
        Ok(())
    }
}

/// Errors of [`match_scan`].
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ScanMatchError {
    /// A configuration field is out of range.
    #[error("invalid scan match config: `{field}` = {value} ({reason})")]
    InvalidConfig {
        /// Name of the field.
        field: &'static str,
        /// Its value (counts as `f64`).
        value: f64,
        /// What the field must satisfy.
        reason: &'static str,
    },
    /// The local map has no points to match against.
    #[error("the local map is empty")]
    EmptyMap,
    /// The initial guess has a non-finite translation or rotation.
    #[error("initial pose t_world_lidar is not finite")]
    NonFiniteInitialPose,
    /// A scan point is NaN or infinite.
    #[error("{cloud} point {index} of the scan is not finite")]
    NonFinitePoint {
        /// `"edge"` or `"planar"`.
        cloud: &'static str,
        /// Index of the point in that cloud.
        index: usize,
    },
    /// Too few scan points found a valid line or plane.
    #[error(
        "too few correspondences at iteration {iteration}: {found} (edge {edge}, planar {planar}), need {required}"
    )]
    TooFewCorrespondences {
        /// Gauss–Newton iteration (0-based) at which it happened; the final
        /// re-linearisation counts as the one after the last iteration.
        iteration: usize,
        /// Correspondences found in all.
        found: usize,
        /// Of which point-to-line.
        edge: usize,
        /// Of which point-to-plane.
        planar: usize,
        /// [`ScanMatchConfig::min_correspondences`].
        required: usize,
    },
    /// The Gauss–Newton update became NaN or infinite.
    #[error("the optimisation diverged (non-finite update) at iteration {iteration}")]
    Diverged {
        /// Iteration (0-based) of the bad update.
        iteration: usize,
    },
}

/// Result of [`match_scan`]. "At the solution" below means at the last
/// linearisation point: for a converged match the pose before the final
/// update, which is within the convergence thresholds of `t_world_lidar`;
/// for an unconverged one `t_world_lidar` itself.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanMatchResult {
    /// The matched pose.
    pub t_world_lidar: Isometry3<f64>,
    /// `JᵀWJ` at the solution in the `(ρ, φ)` right-perturbation tangent of
    /// `t_world_lidar`, for unit-variance point residuals (m); robust
    /// weights included. The pipeline scales it by `1/σ²`.
    pub information: Matrix6<f64>,
    /// Eigenvalues, ascending, of the unweighted normal matrix `JᵀJ` at the
    /// solution, on which degeneracy is decided (robust weights of a
    /// converged match are ≈ 1 for inliers, so it is close to
    /// `information`, but does not depend on the kernel).
    pub eigenvalues: Vector6<f64>,
    /// Unit eigenvectors of `JᵀJ` (columns, same order as `eigenvalues`).
    pub eigenvectors: Matrix6<f64>,
    /// True when at least one eigenvalue is below the degeneracy threshold.
    pub degenerate: bool,
    /// Number of eigenvalues below the degeneracy threshold.
    pub degenerate_directions: usize,
    /// Edge (point-to-line) correspondences used at the solution.
    pub edge_matches: usize,
    /// Planar (point-to-plane) correspondences used at the solution.
    pub planar_matches: usize,
    /// Gauss–Newton iterations taken.
    pub iterations: usize,
    /// True when the update fell below the convergence thresholds.
    pub converged: bool,
    /// RMS of the point residual norms at the solution (unweighted), m.
    pub rms_residual_m: f64,
}

/// A map feature a scan point is matched to (world frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum MapFeature {
    /// Line through `point_world` with unit direction `direction_world`.
    Line {
        point_world: Vector3<f64>,
        direction_world: Vector3<f64>,
    },
    /// A plane.
    Plane(MapPlane),
}

/// Point-to-line residual `r = u × (T·p − a)` and its Jacobian wrt the right
/// perturbation `ξ = (ρ, φ)` of `T`: `[u]ₓ·[R, −R·[p]ₓ]`.
#[inline]
pub fn point_to_line_residual(
    t_world_lidar: &Isometry3<f64>,
    p_lidar: &Vector3<f64>,
    line_point_world: &Vector3<f64>,
    line_direction_world: &Vector3<f64>,
) -> (Vector3<f64>, Matrix3x6<f64>) {
    let rot = t_world_lidar.rotation.to_rotation_matrix().into_inner();
    line_residual_with_rot(
        &rot,
        &t_world_lidar.translation.vector,
        p_lidar,
        line_point_world,
        line_direction_world,
    )
}

#[inline]
fn line_residual_with_rot(
    rot: &Matrix3<f64>,
    trans: &Vector3<f64>,
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    u: &Vector3<f64>,
) -> (Vector3<f64>, Matrix3x6<f64>) {
    let q = rot * p + trans;
    let r = u.cross(&(q - a));
    let m = skew(u) * rot;
    let mut jac = Matrix3x6::zeros();
    jac.fixed_view_mut::<3, 3>(0, 0).copy_from(&m);
    jac.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-m * skew(p)));
    (r, jac)
}

/// Point-to-plane residual `r = nᵀ(T·p) + d` and its Jacobian wrt the right
/// perturbation `ξ = (ρ, φ)` of `T`, as a 6-vector: `(m, p × m)` with
/// `m = Rᵀn` (the plane normal in the LiDAR frame).
#[inline]
pub fn point_to_plane_residual(
    t_world_lidar: &Isometry3<f64>,
    p_lidar: &Vector3<f64>,
    normal_world: &Vector3<f64>,
    offset_m: f64,
) -> (f64, Vector6<f64>) {
    let rot = t_world_lidar.rotation.to_rotation_matrix().into_inner();
    plane_residual_with_rot(
        &rot,
        &t_world_lidar.translation.vector,
        p_lidar,
        normal_world,
        offset_m,
    )
}

#[inline]
fn plane_residual_with_rot(
    rot: &Matrix3<f64>,
    trans: &Vector3<f64>,
    p: &Vector3<f64>,
    n: &Vector3<f64>,
    d: f64,
) -> (f64, Vector6<f64>) {
    let q = rot * p + trans;
    let r = n.dot(&q) + d;
    let m = rot.transpose() * n;
    let pm = p.cross(&m);
    (r, Vector6::new(m.x, m.y, m.z, pm.x, pm.y, pm.z))
}

/// Mean and covariance of the neighbours' points.
#[inline]
fn mean_and_covariance(neigh: &[Neighbour]) -> (Vector3<f64>, Matrix3<f64>) {
    let inv_n = 1.0 / neigh.len() as f64;
    let mean = neigh
        .iter()
        .fold(Vector3::zeros(), |acc, n| acc + n.point_world)
        * inv_n;
    let cov = neigh.iter().fold(Matrix3::zeros(), |acc, n| {
        let d = n.point_world - mean;
        acc + d * d.transpose()
    }) * inv_n;
    (mean, cov)
}

/// Fits a line to the neighbours (LOAM): accepted when the largest
/// covariance eigenvalue exceeds `ratio` times the second largest.
pub(crate) fn fit_line(neigh: &[Neighbour], ratio: f64) -> Option<MapFeature> {
    if neigh.len() < 2 {
        return None;
    }
    let (mean, cov) = mean_and_covariance(neigh);
    let eigen = Decomposition::of(&cov);
    // eigenvalues ascending
    let ev = eigen.values();
    // NaN eigenvalues compare false and reject the fit too.
    if ev[2].partial_cmp(&(ratio * ev[1])) != Some(std::cmp::Ordering::Greater) || ev[2] <= 0.0 {
        return None;
    }
    let dir = eigen.extreme_vector(true).normalize();
    Some(MapFeature::Line {
        point_world: mean,
        direction_world: dir,
    })
}

/// Fits a plane to the neighbours (PCA normal through the centroid):
/// accepted when every neighbour lies within `max_residual_m` of it.
pub(crate) fn fit_plane(neigh: &[Neighbour], max_residual_m: f64) -> Option<MapFeature> {
    if neigh.len() < 3 {
        return None;
    }
    let (mean, cov) = mean_and_covariance(neigh);
    // eigenvalues ascending: the normal is the first eigenvector
    let plane = MapPlane::through(&mean, &Decomposition::of(&cov).extreme_vector(false))?;
    if neigh
        .iter()
        .any(|n| plane.signed_distance_m(&n.point_world).abs() > max_residual_m)
    {
        return None;
    }
    Some(MapFeature::Plane(plane))
}

/// Cached correspondence of one scan point.
#[derive(Clone, Copy)]
struct Association {
    /// World position of the point when it was last searched (NaN = never).
    searched_at_world: Vector3<f64>,
    feature: Option<MapFeature>,
}

impl Association {
    const NONE: Self = Self {
        searched_at_world: Vector3::new(f64::NAN, f64::NAN, f64::NAN),
        feature: None,
    };
}

/// True when the point at `q_world` must be searched again: never searched
/// (NaN position) or moved more than the re-association distance.
#[inline]
fn needs_search(q_world: &Vector3<f64>, assoc: &Association, reassoc_sq: f64) -> bool {
    let moved_sq = (q_world - assoc.searched_at_world).norm_squared();
    moved_sq.is_nan() || moved_sq > reassoc_sq
}

/// Accumulated normal equations of one linearisation.
struct NormalEquations {
    /// `JᵀWJ` (robust weights).
    h: Matrix6<f64>,
    /// `JᵀJ` (unit weights), for the degeneracy test.
    h_unweighted: Matrix6<f64>,
    g: Vector6<f64>,
    edge: usize,
    planar: usize,
    sum_sq_m2: f64,
}

/// Working state of one match: caches and scratch buffers (allocated once).
struct Matcher<'a> {
    map: &'a LocalMap,
    config: &'a ScanMatchConfig,
    k: NonZeroUsize,
    edge_points: &'a [Vector3<f64>],
    planar_points: &'a [Vector3<f64>],
    edge_assoc: Vec<Association>,
    planar_assoc: Vec<Association>,
    scratch: Vec<Neighbour>,
}

impl Matcher<'_> {
    /// Searches the neighbours of `q_world` in `cloud`; returns them only if
    /// all `k` exist within the maximum neighbour distance.
    fn neighbours_ok(&mut self, cloud: &MapCloud, q_world: &Vector3<f64>) -> bool {
        let radius = self.config.max_neighbour_dist_m;
        cloud.nearest_k_within(q_world, self.k, radius, &mut self.scratch);
        self.scratch.len() == self.k.get()
    }

    /// Re-associates moved points and accumulates `H`, `g` at `t`.
    fn linearize(&mut self, t: &Isometry3<f64>) -> NormalEquations {
        let rot = t.rotation.to_rotation_matrix().into_inner();
        let trans = t.translation.vector;
        let reassoc_sq = self.config.reassociation_distance_m.powi(2);
        let kernel = self.config.robust_kernel;
        let weight = |s: f64| kernel.map_or(1.0, |k| k.weight(s));
        let mut ne = NormalEquations {
            h: Matrix6::zeros(),
            h_unweighted: Matrix6::zeros(),
            g: Vector6::zeros(),
            edge: 0,
            planar: 0,
            sum_sq_m2: 0.0,
        };

        let map = self.map;
        for i in 0..self.edge_points.len() {
            let p = self.edge_points[i];
            let q = rot * p + trans;
            let assoc = self.edge_assoc[i];
            let feature = if needs_search(&q, &assoc, reassoc_sq) {
                let feature = if self.neighbours_ok(map.edge_cloud(), &q) {
                    fit_line(&self.scratch, self.config.line_eigenvalue_ratio)
                } else {
                    None
                };
                self.edge_assoc[i] = Association {
                    searched_at_world: q,
                    feature,
                };
                feature
            } else {
                assoc.feature
            };
            let Some(MapFeature::Line {
                point_world,
                direction_world,
            }) = feature
            else {
                continue;
            };
            let (r, jac) = line_residual_with_rot(&rot, &trans, &p, &point_world, &direction_world);
            let s_sq = r.norm_squared();
            let w = weight(s_sq.sqrt());
            let jt = jac.transpose();
            let jtj = jt * jac;
            ne.h_unweighted += jtj;
            ne.h += jtj * w;
            ne.g += (jt * r) * w;
            ne.edge += 1;
            ne.sum_sq_m2 += s_sq;
        }

        for i in 0..self.planar_points.len() {
            let p = self.planar_points[i];
            let q = rot * p + trans;
            let assoc = self.planar_assoc[i];
            let feature = if needs_search(&q, &assoc, reassoc_sq) {
                let feature = if let Some(plane) = map.planar_cloud().plane_at(&q) {
                    Some(MapFeature::Plane(plane))
                } else if self.neighbours_ok(map.planar_cloud(), &q) {
                    fit_plane(&self.scratch, self.config.max_plane_fit_residual_m)
                } else {
                    None
                };
                self.planar_assoc[i] = Association {
                    searched_at_world: q,
                    feature,
                };
                feature
            } else {
                assoc.feature
            };
            let Some(MapFeature::Plane(plane)) = feature else {
                continue;
            };
            let (r, j) =
                plane_residual_with_rot(&rot, &trans, &p, &plane.normal_world, plane.offset_m);
            let w = weight(r.abs());
            let jjt = j * j.transpose();
            ne.h_unweighted += jjt;
            ne.h += jjt * w;
            ne.g += j * (r * w);
            ne.planar += 1;
            ne.sum_sq_m2 += r * r;
        }
        ne
    }
}

/// Eigen-decomposition of a symmetric 6×6 matrix, eigenvalues ascending.
fn sorted_eigen(h: &Matrix6<f64>) -> (Vector6<f64>, Matrix6<f64>) {
    let eig = SymmetricEigen::new(*h);
    let mut order = [0usize, 1, 2, 3, 4, 5];
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let mut values = Vector6::zeros();
    let mut vectors = Matrix6::zeros();
    for (dst, &src) in order.iter().enumerate() {
        values[dst] = eig.eigenvalues[src];
        vectors.set_column(dst, &eig.eigenvectors.column(src));
    }
    (values, vectors)
}

/// Gauss–Newton step restricted to the well-conditioned eigen-directions of
/// the unweighted normal matrix `JᵀJ` (LOAM's solution remapping).
///
/// Degeneracy is judged on `JᵀJ` rather than on the robust `JᵀWJ`: far from
/// the solution a redescending kernel down-weights every residual of a
/// direction that is still wrong, which would make exactly the direction that
/// most needs correcting look degenerate. With `P` the projector on the
/// well-conditioned eigen-directions `V_g` of `JᵀJ`, the step solves
/// `(P·H·P + (I − P))·δ = −P·g` with `H = JᵀWJ`: the Gauss–Newton step within
/// `span(V_g)` (`δ ∈ span(V_g)`), zero along the degenerate directions.
fn restricted_gauss_newton_step(ne: &NormalEquations, threshold: f64) -> Option<Vector6<f64>> {
    let (values, vectors) = sorted_eigen(&ne.h_unweighted);
    let mut projector = Matrix6::zeros();
    for i in 0..6 {
        if values[i] >= threshold && values[i] > 0.0 {
            let v = vectors.column(i);
            projector += v * v.transpose();
        }
    }
    let complement = Matrix6::identity() - projector;
    let h = projector * ne.h * projector + complement;
    let rhs = -(projector * ne.g);
    let delta = match h.cholesky() {
        Some(chol) => chol.solve(&rhs),
        // Robust weights can make H singular within span(V_g) only if every
        // weight of a direction underflows; fall back to a pseudo-inverse.
        None => {
            let (hv, hw) = sorted_eigen(&h);
            let mut d = Vector6::zeros();
            for i in 0..6 {
                if hv[i] > 1e-12 * hv[5].abs().max(1e-300) {
                    let v = hw.column(i);
                    d += v * (v.dot(&rhs) / hv[i]);
                }
            }
            d
        }
    };
    delta.iter().all(|v| v.is_finite()).then_some(delta)
}

/// Matches a scan's features (LiDAR frame, de-skewed) to the local map,
/// starting from `initial_t_world_lidar` (the IMU prediction).
///
/// # Errors
/// [`ScanMatchError::InvalidConfig`] for a bad `config`,
/// [`ScanMatchError::EmptyMap`], [`ScanMatchError::NonFiniteInitialPose`] and
/// [`ScanMatchError::NonFinitePoint`] for unusable inputs,
/// [`ScanMatchError::TooFewCorrespondences`] when fewer than
/// `config.min_correspondences` points find a line or plane at some
/// iteration, [`ScanMatchError::Diverged`] for a non-finite update.
pub fn match_scan(
    map: &LocalMap,
    edge_points_lidar: &[Vector3<f64>],
    planar_points_lidar: &[Vector3<f64>],
    initial_t_world_lidar: &Isometry3<f64>,
    config: &ScanMatchConfig,
) -> Result<ScanMatchResult, ScanMatchError> {
    config.validate()?;
    if map.is_empty() {
        return Err(ScanMatchError::EmptyMap);
    }
    let finite_pose = initial_t_world_lidar
        .translation
        .vector
        .iter()
        .chain(initial_t_world_lidar.rotation.coords.iter())
        .all(|v| v.is_finite());
    if !finite_pose {
        return Err(ScanMatchError::NonFiniteInitialPose);
    }
    for (cloud, pts) in [("edge", edge_points_lidar), ("planar", planar_points_lidar)] {
        if let Some(index) = pts.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
            return Err(ScanMatchError::NonFinitePoint { cloud, index });
        }
    }

    let k = NonZeroUsize::new(config.num_neighbours).unwrap_or(NonZeroUsize::MIN);
    let mut matcher = Matcher {
        map,
        config,
        k,
        edge_points: edge_points_lidar,
        planar_points: planar_points_lidar,
        edge_assoc: vec![Association::NONE; edge_points_lidar.len()],
        planar_assoc: vec![Association::NONE; planar_points_lidar.len()],
        scratch: Vec::with_capacity(config.num_neighbours),
    };
    let too_few = |iteration: usize, ne: &NormalEquations| ScanMatchError::TooFewCorrespondences {
        iteration,
        found: ne.edge + ne.planar,
        edge: ne.edge,
        planar: ne.planar,
        required: config.min_correspondences,
    };

    let mut t = *initial_t_world_lidar;
    let mut converged_equations = None;
    let mut iterations = 0;
    let threshold = config.degeneracy_eigenvalue_threshold;
    for iteration in 0..config.max_iterations {
        let ne = matcher.linearize(&t);
        if ne.edge + ne.planar < config.min_correspondences {
            return Err(too_few(iteration, &ne));
        }
        let delta = restricted_gauss_newton_step(&ne, threshold)
            .ok_or(ScanMatchError::Diverged { iteration })?;
        t = lie::oplus(&t, &delta);
        iterations = iteration + 1;
        let rot_deg = lie::xi_phi(&delta).norm().to_degrees();
        let trans_m = lie::xi_rho(&delta).norm();
        if rot_deg < config.convergence_rotation_deg && trans_m < config.convergence_translation_m {
            converged_equations = Some(ne);
            break;
        }
    }

    // A converged match's last update is below the convergence thresholds
    // (0.05 deg, 0.5 mm by default), so the normal equations it was solved
    // from describe the solution; only an unconverged match linearises again.
    let converged = converged_equations.is_some();
    let ne = match converged_equations {
        Some(ne) => ne,
        None => matcher.linearize(&t),
    };
    let found = ne.edge + ne.planar;
    if found < config.min_correspondences {
        return Err(too_few(iterations, &ne));
    }
    let information = ne.h;
    let (eigenvalues, eigenvectors) = sorted_eigen(&ne.h_unweighted);
    let degenerate_directions = eigenvalues.iter().filter(|&&l| l < threshold).count();
    Ok(ScanMatchResult {
        t_world_lidar: t,
        information,
        eigenvalues,
        eigenvectors,
        degenerate: degenerate_directions > 0,
        degenerate_directions,
        edge_matches: ne.edge,
        planar_matches: ne.planar,
        iterations,
        converged,
        rms_residual_m: (ne.sum_sq_m2 / found as f64).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn neigh(points: &[[f64; 3]]) -> Vec<Neighbour> {
        points
            .iter()
            .map(|p| Neighbour {
                point_world: Vector3::new(p[0], p[1], p[2]),
                dist_sq_m2: 0.0,
            })
            .collect()
    }

    #[test]
    fn line_fit_accepts_collinear_and_rejects_spread_points() {
        let on_line = neigh(&[
            [1.0, 2.0, 0.0],
            [1.0, 2.0, 0.3],
            [1.0, 2.0, 0.6],
            [1.0, 2.0, 0.9],
            [1.01, 2.0, 1.2],
        ]);
        let Some(MapFeature::Line {
            point_world,
            direction_world,
        }) = fit_line(&on_line, 3.0)
        else {
            panic!("collinear points must give a line");
        };
        assert!(direction_world.z.abs() > 0.999);
        assert!((point_world - Vector3::new(1.002, 2.0, 0.6)).norm() < 1e-9);
        let blob = neigh(&[
            [0.0, 0.0, 0.0],
            [0.5, 0.0, 0.0],
            [0.0, 0.5, 0.0],
            [0.5, 0.5, 0.1],
            [0.25, 0.25, 0.0],
        ]);
        assert_eq!(fit_line(&blob, 3.0), None);
    }

    #[test]
    fn plane_fit_accepts_planar_and_rejects_bent_points() {
        let flat = neigh(&[
            [0.0, 0.0, 1.0],
            [0.4, 0.0, 1.0],
            [0.0, 0.4, 1.0],
            [0.4, 0.4, 1.0],
            [0.2, 0.1, 1.0],
        ]);
        let Some(MapFeature::Plane(MapPlane {
            normal_world,
            offset_m,
        })) = fit_plane(&flat, 0.2)
        else {
            panic!("coplanar points must give a plane");
        };
        // z = 1: n = ±z, d = ∓1.
        assert!((normal_world.z.abs() - 1.0).abs() < 1e-12);
        assert!((normal_world.z * 1.0 + offset_m).abs() < 1e-12);
        let bent = neigh(&[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.5, 0.5, 1.5],
        ]);
        assert_eq!(fit_plane(&bent, 0.2), None);
        assert_eq!(fit_plane(&flat[..2], 0.2), None);
    }

    #[test]
    fn config_validation_names_the_field() {
        assert!(ScanMatchConfig::default().validate().is_ok());
        let err = ScanMatchConfig {
            num_neighbours: 2,
            ..Default::default()
        }
        .validate()
        .unwrap_err();
        assert!(matches!(
            err,
            ScanMatchError::InvalidConfig {
                field: "num_neighbours",
                ..
            }
        ));
        let err = ScanMatchConfig {
            robust_kernel: Some(RobustKernel::Cauchy { k: 0.0 }),
            ..Default::default()
        }
        .validate()
        .unwrap_err();
        assert!(err.to_string().contains("robust_kernel.k"));
    }

    #[test]
    fn restricted_step_is_zero_along_degenerate_directions() {
        // H has no information along x translation; g pushes along x and y.
        let mut h = Matrix6::identity() * 1000.0;
        h[(0, 0)] = 1.0;
        let ne = NormalEquations {
            h,
            h_unweighted: h,
            g: Vector6::new(5.0, 10.0, 0.0, 0.0, 0.0, 0.0),
            edge: 0,
            planar: 0,
            sum_sq_m2: 0.0,
        };
        let delta = restricted_gauss_newton_step(&ne, 100.0).unwrap();
        assert_eq!(delta[0], 0.0);
        assert!((delta[1] + 0.01).abs() < 1e-12);
    }
}
