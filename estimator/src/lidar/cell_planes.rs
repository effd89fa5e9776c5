//! Planes fitted once per map update to the planar map's points in each
//! octant of the neighbour grid's cells, so that scan matching can take a
//! planar point's plane from one table lookup instead of a k-NN search and a
//! fit (VoxelMap's idea, Yuan et al. 2022, without its adaptive octree: an
//! octant that is not planar has no plane and its points are matched by
//! k-NN as before).

use nalgebra::{Matrix3, Vector3};

use super::neighbour_grid::{CellTable, NeighbourGrid, pack_cell};
use super::voxel::voxel_key;
use crate::eigen3::Decomposition;

/// When an octant's points make a plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellPlaneConfig {
    /// At least this many map points in the octant (LOAM's neighbour count:
    /// 5).
    pub min_points: usize,
    /// Every point within this distance of the fitted plane, m; a query
    /// farther from it is matched by k-NN instead (0.05: a quarter of
    /// LOAM's 0.2 m for its 5 neighbours, because an octant's plane also
    /// stands for queries up to a metre from its points).
    pub max_residual_m: f64,
    /// The points' second covariance eigenvalue at least this many times
    /// the smallest, so that a line of points (a kerb edge seen from afar,
    /// one ring on the road) does not fix a normal (3).
    pub min_eigenvalue_ratio: f64,
}

impl Default for CellPlaneConfig {
    fn default() -> Self {
        Self {
            min_points: 5,
            max_residual_m: 0.05,
            min_eigenvalue_ratio: 3.0,
        }
    }
}

/// A plane of the map, `normal_world · x + offset_m = 0` (world frame,
/// unit normal): an octant's, or one fitted to a scan point's neighbours.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapPlane {
    /// Unit normal, world frame.
    pub normal_world: Vector3<f64>,
    /// Offset, m.
    pub offset_m: f64,
}

impl MapPlane {
    /// The plane through `point_world` normal to `normal_world` (any
    /// length); `None` when the direction does not normalize to finite
    /// components (zero or non-finite).
    pub fn through(point_world: &Vector3<f64>, normal_world: &Vector3<f64>) -> Option<MapPlane> {
        let normal_world = normal_world.normalize();
        normal_world
            .iter()
            .all(|v| v.is_finite())
            .then(|| MapPlane {
                normal_world,
                offset_m: -normal_world.dot(point_world),
            })
    }

    /// Signed distance of `x_world` from the plane, m (positive on the
    /// normal's side).
    #[inline]
    pub fn signed_distance_m(&self, x_world: &Vector3<f64>) -> f64 {
        self.normal_world.dot(x_world) + self.offset_m
    }
}

/// The planes of a grid's octants (edge half the grid's cell).
#[derive(Debug, Default)]
pub(super) struct CellPlanes {
    octant_m: f64,
    /// [`CellPlaneConfig::max_residual_m`]: also how close a query must be
    /// to count as on the plane.
    max_residual_m: f64,
    /// Packed octant key -> (index into `planes`, 1), for the octants with
    /// a plane only.
    index: CellTable,
    planes: Vec<MapPlane>,
}

/// Running moments of one octant's points, relative to a nearby origin so
/// that world coordinates of hundreds of metres do not cancel.
#[derive(Clone, Copy)]
struct Moments {
    key: u64,
    count: usize,
    sum: Vector3<f64>,
    sum_outer: Matrix3<f64>,
}

impl CellPlanes {
    /// Fits every octant of `grid`'s cells. An octant lies in one cell:
    /// halving the cell's edge is exact in floating point, so
    /// `floor(x / (c / 2))` is `2·floor(x / c)` or one more for every `x`.
    pub(super) fn build(grid: &NeighbourGrid, config: &CellPlaneConfig) -> Self {
        let octant_m = grid.cell_m / 2.0;
        let mut planes: Vec<(u64, MapPlane)> = Vec::new();
        let mut octants: Vec<Moments> = Vec::with_capacity(8);
        let mut fits: Vec<Option<MapPlane>> = Vec::with_capacity(8);
        // Each point's index into `octants`, for the residual pass.
        let mut octant_of: Vec<u8> = Vec::new();
        for points in grid.cells() {
            let origin = points[0];
            octants.clear();
            octant_of.clear();
            for p in points {
                let key = pack_cell(voxel_key(p, octant_m));
                let at = match octants.iter().position(|m| m.key == key) {
                    Some(at) => at,
                    None => {
                        octants.push(Moments {
                            key,
                            count: 0,
                            sum: Vector3::zeros(),
                            sum_outer: Matrix3::zeros(),
                        });
                        octants.len() - 1
                    }
                };
                octant_of.push(at as u8);
                let d = p - origin;
                let m = &mut octants[at];
                m.count += 1;
                m.sum += d;
                m.sum_outer += d * d.transpose();
            }
            fits.clear();
            fits.extend(octants.iter().map(|m| fit(m, &origin, config)));
            if fits.iter().all(Option::is_none) {
                continue;
            }
            // Every point within the residual bound of its octant's plane.
            for (p, &at) in points.iter().zip(&octant_of) {
                let plane = &mut fits[usize::from(at)];
                if plane.is_some_and(|pl| pl.signed_distance_m(p).abs() > config.max_residual_m) {
                    *plane = None;
                }
            }
            planes.extend(
                octants
                    .iter()
                    .zip(&fits)
                    .filter_map(|(m, plane)| Some((m.key, (*plane)?))),
            );
        }
        let mut index = CellTable::with_cells(planes.len());
        for (at, &(key, _)) in planes.iter().enumerate() {
            let slot = index.entry(key);
            debug_assert_eq!(slot.len, 0, "an octant in two grid cells");
            slot.start = at as u32;
            slot.len = 1;
        }
        let planes = planes.into_iter().map(|(_, plane)| plane).collect();
        Self {
            octant_m,
            max_residual_m: config.max_residual_m,
            index,
            planes,
        }
    }

    /// The plane of the octant holding `q_world`, if it has one and
    /// `q_world` lies as close to it as the octant's own points: a point of
    /// another surface that crosses the octant without map points in it (a
    /// wall on the octant's face, a car not in the map) is not matched to
    /// the octant's surface.
    #[inline]
    pub(super) fn plane_at(&self, q_world: &Vector3<f64>) -> Option<MapPlane> {
        let (at, _) = self
            .index
            .get(pack_cell(voxel_key(q_world, self.octant_m)))?;
        let plane = self.planes[at as usize];
        (plane.signed_distance_m(q_world).abs() <= self.max_residual_m).then_some(plane)
    }

    /// Number of octants with a plane.
    pub(super) fn len(&self) -> usize {
        self.planes.len()
    }
}

/// The plane through an octant's points (PCA normal through the centroid)
/// if they are enough and spread over two directions; the residual bound is
/// checked by the caller.
fn fit(m: &Moments, origin: &Vector3<f64>, config: &CellPlaneConfig) -> Option<MapPlane> {
    if m.count < config.min_points.max(3) {
        return None;
    }
    let inv_n = 1.0 / m.count as f64;
    let mean = m.sum * inv_n;
    let cov = m.sum_outer * inv_n - mean * mean.transpose();
    let eigen = Decomposition::of(&cov);
    let values = eigen.values();
    // A spread below a millimetre counts as a millimetre, so that points
    // on a line (second eigenvalue zero up to rounding) are no plane while
    // a noise-free plane (smallest eigenvalue zero) is one. NaN compares
    // false and rejects the fit too.
    const SPREAD_FLOOR_M2: f64 = 1e-6;
    let needed = config.min_eigenvalue_ratio * values[0].max(SPREAD_FLOOR_M2);
    if values[1]
        .partial_cmp(&needed)
        .is_none_or(std::cmp::Ordering::is_lt)
    {
        return None;
    }
    MapPlane::through(&(origin + mean), &eigen.extreme_vector(false))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn planes_of(points: &[Vector3<f64>]) -> CellPlanes {
        CellPlanes::build(
            &NeighbourGrid::build(points, 2.0),
            &CellPlaneConfig::default(),
        )
    }

    /// Points on a tilted plane, 0.25 m apart, over a 6 m square far from
    /// the origin (world coordinates of kilometres must not cost precision).
    fn tilted_plane(origin: Vector3<f64>, normal: Vector3<f64>) -> Vec<Vector3<f64>> {
        let u = normal.cross(&Vector3::new(0.3, 0.5, 0.8)).normalize();
        let v = normal.cross(&u);
        (0..24)
            .flat_map(|i| (0..24).map(move |j| (f64::from(i) * 0.25, f64::from(j) * 0.25)))
            .map(|(s, t)| origin + u * s + v * t)
            .collect()
    }

    #[test]
    fn every_octant_of_a_plane_has_that_plane() {
        let normal = Vector3::new(0.2, -0.3, 0.9).normalize();
        let origin = Vector3::new(4123.7, -2210.3, 31.9);
        let points = tilted_plane(origin, normal);
        let planes = planes_of(&points);
        assert!(planes.len() > 20, "{} planes", planes.len());
        let mut found = 0;
        for p in &points {
            if let Some(plane) = planes.plane_at(p) {
                found += 1;
                let sign = plane.normal_world.dot(&normal).signum();
                assert!((plane.normal_world * sign - normal).norm() < 1e-9);
                assert!(plane.signed_distance_m(p).abs() < 1e-9);
            }
        }
        // Only octants cut by a corner of the plane hold fewer than 5 points.
        assert!(found > points.len() * 9 / 10, "{found} of {}", points.len());
    }

    #[test]
    fn a_query_off_the_plane_gets_none() {
        let points = tilted_plane(Vector3::new(0.05, 0.05, 0.05), Vector3::z());
        let planes = planes_of(&points);
        let bound = CellPlaneConfig::default().max_residual_m;
        let p = points
            .iter()
            .find(|p| planes.plane_at(p).is_some())
            .unwrap();
        assert!(
            planes
                .plane_at(&(p + Vector3::z() * 0.99 * bound))
                .is_some()
        );
        assert_eq!(planes.plane_at(&(p + Vector3::z() * 1.01 * bound)), None);
    }

    #[test]
    fn corners_lines_and_sparse_octants_have_no_plane() {
        // Two faces of a box corner meeting inside one octant [0, 1)^3.
        let mut corner = Vec::new();
        for i in 0..4 {
            for j in 0..4 {
                let (a, b) = (0.1 + 0.25 * f64::from(i), 0.1 + 0.25 * f64::from(j));
                corner.push(Vector3::new(a, b, 0.1));
                corner.push(Vector3::new(0.1, a, b));
            }
        }
        assert_eq!(
            planes_of(&corner).plane_at(&Vector3::new(0.5, 0.5, 0.5)),
            None
        );
        // Collinear points: no normal.
        let line: Vec<_> = (0..8)
            .map(|i| Vector3::new(0.1 + 0.1 * f64::from(i), 0.3, 0.2))
            .collect();
        assert_eq!(
            planes_of(&line).plane_at(&Vector3::new(0.5, 0.3, 0.2)),
            None
        );
        // Four points of a plane: fewer than five.
        let sparse = [
            Vector3::new(0.1, 0.1, 0.5),
            Vector3::new(0.9, 0.1, 0.5),
            Vector3::new(0.1, 0.9, 0.5),
            Vector3::new(0.9, 0.9, 0.5),
        ];
        assert_eq!(
            planes_of(&sparse).plane_at(&Vector3::new(0.5, 0.5, 0.5)),
            None
        );
        let mut five = sparse.to_vec();
        five.push(Vector3::new(0.5, 0.5, 0.5));
        let plane = planes_of(&five)
            .plane_at(&Vector3::new(0.5, 0.5, 0.5))
            .unwrap();
        assert!((plane.normal_world.z.abs() - 1.0).abs() < 1e-12);
        // An empty grid answers every query with no plane.
        assert_eq!(planes_of(&[]).plane_at(&Vector3::zeros()), None);
    }
}
