//! KITTI Velodyne HDL-64E scans (`.bin`: little-endian f32 x, y, z,
//! reflectance per point, LiDAR frame, not motion-compensated).
//!
//! KITTI stores neither the laser (ring) nor the time of a point; both are
//! derived here.
//!
//! Ring: KITTI writes the points laser by laser, top laser first, each laser's
//! revolution starting just left of straight ahead and running
//! counter-clockwise (azimuth `atan2(y, x)` taken in [0, 2π) increases
//! within a laser). A new laser starts where that azimuth drops by more than
//! π. With exactly 64 such scan lines, ring = 63 − line (ring 0 = lowest
//! beam, as [`LidarPoint::ring`] wants). Otherwise (e.g. points not in
//! KITTI's order) each point gets the laser of nearest median elevation
//! ([`KITTI_RING_ELEVATION_DEG`], measured on real KITTI scans) — approximate.
//!
//! Time: KITTI raw `timestamps_start` marks the laser facing backwards, the
//! camera trigger (`timestamps`) the laser facing forward, and the HDL-64E
//! spins clockwise seen from above at 10 Hz. So a point at azimuth `az`
//! (rad, in (−π, π]) was measured `(π − az) / 2π · 0.1 s` after the sweep
//! start: rear-left at 0, left at 0.025 s, ahead at 0.05 s, right at
//! 0.075 s, rear-right at 0.1 s.

use super::{KittiError, Result};
use limot_estimator::input::{LidarPoint, LidarScan};
use limot_estimator::lidar::sort_ring_by;
use nalgebra::Vector3;
use std::f64::consts::{PI, TAU};
use std::path::Path;

/// Lasers of the HDL-64E.
pub const HDL64_NUM_RINGS: u16 = 64;
/// Sweep duration of KITTI's Velodyne at 10 Hz.
pub const SWEEP_DURATION_S: f64 = 0.1;
/// Bytes per stored point (4 × f32).
pub const BYTES_PER_POINT: usize = 16;

/// How the rings of a scan were obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RingSource {
    /// From KITTI's laser-by-laser point order (exact).
    ScanLines,
    /// From the nearest median laser elevation of KITTI scans (approximate).
    ElevationBins,
}

/// A scan with the provenance of its rings.
#[derive(Debug, Clone, PartialEq)]
pub struct VelodyneScan {
    /// The points with rings and per-point times.
    pub scan: LidarScan,
    /// How the rings were found.
    pub ring_source: RingSource,
}

/// Elevation error of the point clouds KITTI recorded with its HDL-64E, in
/// degrees: every point KITTI stores lies this much too low, seen from the
/// sensor, so a flat road comes out as a shallow bowl and straight walls
/// lean. Found by Deschaud (IMLS-SLAM, ICRA 2018, 0.22°) and used by CT-ICP
/// (Dellenbach et al., ICRA 2022, 0.22°) and KISS-ICP (its KITTI readers,
/// 0.205°); [`raise_elevation`] undoes it. On KITTI tracking 0000 it lowers
/// limot's attitude error; it does not change the odometry's scale (see
/// docs/kitti-real-data.md).
pub const KITTI_HDL64_ELEVATION_CORRECTION_DEG: f64 = 0.22;

/// `p_lidar` with its elevation raised by `angle_rad`: a rotation by
/// `angle_rad` about the horizontal axis `p × z` through the sensor origin,
/// so range and azimuth are kept (and with them the ring and the sweep
/// time). Points on the z axis have no azimuth and are returned unchanged.
pub fn raise_elevation(p_lidar: &Vector3<f64>, angle_rad: f64) -> Vector3<f64> {
    let rho = p_lidar.xy().norm();
    if rho == 0.0 || angle_rad == 0.0 {
        return *p_lidar;
    }
    let (sin, cos) = angle_rad.sin_cos();
    let new_rho = rho * cos - p_lidar.z * sin;
    let new_z = rho * sin + p_lidar.z * cos;
    Vector3::new(p_lidar.x * new_rho / rho, p_lidar.y * new_rho / rho, new_z)
}

/// Applies [`raise_elevation`] to every point of `scan` (rings, times and
/// intensities unchanged).
pub fn raise_scan_elevation(scan: &mut LidarScan, angle_rad: f64) {
    if angle_rad == 0.0 {
        return;
    }
    for point in &mut scan.points {
        let p = Vector3::new(point.x as f64, point.y as f64, point.z as f64);
        let q = raise_elevation(&p, angle_rad);
        point.x = q.x as f32;
        point.y = q.y as f32;
        point.z = q.z as f32;
    }
}

/// Time after the sweep start at which the laser pointed at `p_lidar`
/// (see the module docs), in [0, 0.1] s.
pub fn sweep_time_offset_s(p_lidar: &Vector3<f64>) -> f64 {
    time_offset_at_azimuth_s(azimuth_rad(p_lidar))
}

/// Azimuth of `p_lidar`, rad in [-pi, pi] (x forward, y left).
fn azimuth_rad(p_lidar: &Vector3<f64>) -> f64 {
    p_lidar.y.atan2(p_lidar.x)
}

/// [`sweep_time_offset_s`] of a point at azimuth `az_rad` ([`azimuth_rad`]).
fn time_offset_at_azimuth_s(az_rad: f64) -> f64 {
    (PI - az_rad) / TAU * SWEEP_DURATION_S
}

/// Median elevation (degrees, seen from the sensor origin) of each KITTI
/// HDL-64E laser, ring 0 = lowest: the median over the 20 raw scans of
/// 2011-09-26 in `shared/data/kitti_raw_scans`, rings from the scan lines.
/// Seen from the origin, elevations differ from the lasers' nominal angles
/// because each laser sits up to ~0.2 m off the origin.
pub const KITTI_RING_ELEVATION_DEG: [f64; 64] = [
    -23.46, -23.01, -22.58, -21.96, -21.51, -21.12, -20.64, -20.04, -19.53, -18.98, -18.53, -18.13,
    -17.64, -17.18, -16.62, -16.10, -15.49, -15.09, -14.59, -14.14, -13.56, -13.05, -12.52, -12.09,
    -11.63, -11.21, -10.69, -10.09, -9.55, -9.11, -8.62, -8.09, -7.74, -7.35, -7.13, -6.77, -6.38,
    -6.08, -5.79, -5.45, -5.06, -4.73, -4.37, -4.03, -3.71, -3.35, -3.06, -2.69, -2.38, -2.02,
    -1.70, -1.38, -1.01, -0.63, -0.32, 0.08, 0.44, 0.81, 1.09, 1.52, 1.80, 2.30, 2.52, 2.84,
];

/// Ring of a point from its elevation: the laser whose median elevation
/// ([`KITTI_RING_ELEVATION_DEG`]) is nearest. Approximate: near points and
/// sloped ground land one or more rings off.
pub fn ring_from_elevation(p_lidar: &Vector3<f64>) -> u16 {
    let elevation_deg = p_lidar.z.atan2(p_lidar.xy().norm()).to_degrees();
    let mut best = 0usize;
    for (ring, e) in KITTI_RING_ELEVATION_DEG.iter().enumerate() {
        if (e - elevation_deg).abs() < (KITTI_RING_ELEVATION_DEG[best] - elevation_deg).abs() {
            best = ring;
        }
    }
    best as u16
}

/// Scan-line index of every point from KITTI's point order (see the module
/// docs); returns the per-point line and the number of lines.
pub fn scan_lines(positions: &[Vector3<f64>]) -> (Vec<u16>, usize) {
    let azimuths: Vec<f64> = positions.iter().map(azimuth_rad).collect();
    scan_lines_of_azimuths(&azimuths)
}

/// [`scan_lines`] from the points' azimuths ([`azimuth_rad`]).
fn scan_lines_of_azimuths(azimuths_rad: &[f64]) -> (Vec<u16>, usize) {
    let mut lines = Vec::with_capacity(azimuths_rad.len());
    let mut line: usize = 0;
    let mut previous_az: Option<f64> = None;
    for az in azimuths_rad {
        let az = az.rem_euclid(TAU);
        if let Some(prev) = previous_az
            && az < prev - PI
        {
            line += 1;
        }
        previous_az = Some(az);
        lines.push(line.min(u16::MAX as usize) as u16);
    }
    let count = if azimuths_rad.is_empty() { 0 } else { line + 1 };
    (lines, count)
}

/// `points` in KITTI's storage order (see the module docs): laser by laser,
/// top ring first, each laser by azimuth in [0, 2π), ties in input order.
/// Written so, a scan's rings come back exactly from [`scan_lines`] whenever
/// every one of the 64 lasers has a point and each laser's first azimuth
/// lies more than π below the one before's last (as on a full revolution);
/// otherwise the reader falls back to [`ring_from_elevation`].
pub fn in_kitti_order(points: &[LidarPoint], out: &mut Vec<LidarPoint>) {
    // counting sort by ring, top ring first, stable
    let rings = points
        .iter()
        .map(|p| usize::from(p.ring) + 1)
        .max()
        .unwrap_or(0);
    let mut start = vec![0usize; rings + 1];
    for p in points {
        start[rings - usize::from(p.ring)] += 1;
    }
    for k in 1..=rings {
        start[k] += start[k - 1];
    }
    let mut keyed = vec![(0.0f64, 0u32); points.len()];
    let mut cursor = start.clone();
    for (i, p) in points.iter().enumerate() {
        let slot = &mut cursor[rings - 1 - usize::from(p.ring)];
        let az = (p.y as f64).atan2(p.x as f64).rem_euclid(TAU);
        keyed[*slot] = (az, i as u32);
        *slot += 1;
    }
    for k in 0..rings {
        // ties in azimuth by input order: a total order
        sort_ring_by(&mut keyed[start[k]..start[k + 1]], |a, b| {
            a.0.total_cmp(&b.0).then(a.1.cmp(&b.1))
        });
    }
    out.clear();
    out.extend(keyed.iter().map(|&(_, i)| points[i as usize]));
}

/// Rings for the points (see the module docs).
pub fn estimate_rings(positions: &[Vector3<f64>]) -> (Vec<u16>, RingSource) {
    let azimuths: Vec<f64> = positions.iter().map(azimuth_rad).collect();
    estimate_rings_at_azimuths(positions, &azimuths)
}

/// [`estimate_rings`] with the points' azimuths ([`azimuth_rad`]) given.
fn estimate_rings_at_azimuths(
    positions: &[Vector3<f64>],
    azimuths_rad: &[f64],
) -> (Vec<u16>, RingSource) {
    let (lines, count) = scan_lines_of_azimuths(azimuths_rad);
    if count == HDL64_NUM_RINGS as usize {
        let rings = lines.iter().map(|l| HDL64_NUM_RINGS - 1 - l).collect();
        (rings, RingSource::ScanLines)
    } else {
        (
            positions.iter().map(ring_from_elevation).collect(),
            RingSource::ElevationBins,
        )
    }
}

/// Decodes a `.bin` scan; `t_s` is the sweep start time. A length that is not
/// a multiple of 16 bytes or a non-finite value is an error naming the byte
/// offset.
///
/// # Errors
/// A length that is not a multiple of 16 bytes or a non-finite value (byte offset).
pub fn parse_bin(bytes: &[u8], path: &Path, t_s: f64) -> Result<VelodyneScan> {
    let remainder = bytes.len() % BYTES_PER_POINT;
    if remainder != 0 {
        return Err(KittiError::Binary {
            path: path.to_path_buf(),
            byte_offset: (bytes.len() - remainder) as u64,
            why: format!(
                "truncated point: {} bytes is not a multiple of {BYTES_PER_POINT}",
                bytes.len()
            ),
        });
    }
    const NAMES: [&str; 4] = ["x", "y", "z", "reflectance"];
    let mut raw = Vec::with_capacity(bytes.len() / BYTES_PER_POINT);
    for (i, chunk) in bytes.chunks_exact(BYTES_PER_POINT).enumerate() {
        let mut v = [0f32; 4];
        for (k, value) in v.iter_mut().enumerate() {
            let b = &chunk[4 * k..4 * k + 4];
            *value = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            if !value.is_finite() {
                return Err(KittiError::Binary {
                    path: path.to_path_buf(),
                    byte_offset: (i * BYTES_PER_POINT + 4 * k) as u64,
                    why: format!("point {i}: `{}` is not finite ({value})", NAMES[k]),
                });
            }
        }
        raw.push(v);
    }
    let positions: Vec<Vector3<f64>> = raw
        .iter()
        .map(|v| Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64))
        .collect();
    // one atan2 per point serves both the scan lines and the sweep time
    let azimuths: Vec<f64> = positions.iter().map(azimuth_rad).collect();
    let (rings, ring_source) = estimate_rings_at_azimuths(&positions, &azimuths);
    let points = raw
        .iter()
        .zip(&azimuths)
        .zip(&rings)
        .map(|((v, &az), ring)| LidarPoint {
            x: v[0],
            y: v[1],
            z: v[2],
            intensity: v[3],
            ring: *ring,
            time_offset_s: time_offset_at_azimuth_s(az) as f32,
        })
        .collect();
    Ok(VelodyneScan {
        scan: LidarScan {
            t_s,
            sweep_duration_s: SWEEP_DURATION_S,
            num_rings: HDL64_NUM_RINGS,
            points,
        },
        ring_source,
    })
}

/// Reads a `.bin` scan.
///
/// # Errors
/// An unreadable file, or a malformed one (see [`parse_bin`]).
pub fn read_bin(path: &Path, t_s: f64) -> Result<VelodyneScan> {
    let bytes = std::fs::read(path).map_err(|source| KittiError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_bin(&bytes, path, t_s)
}

/// Encodes points as a `.bin` scan (x, y, z, intensity; ring and time are
/// not stored, as in KITTI).
pub fn encode_bin(points: &[LidarPoint]) -> Vec<u8> {
    let mut out = Vec::new();
    encode_bin_into(points, &mut out);
    out
}

/// [`encode_bin`], appended to `out`.
pub fn encode_bin_into(points: &[LidarPoint], out: &mut Vec<u8>) {
    out.reserve(points.len() * BYTES_PER_POINT);
    for p in points {
        let mut record = [0u8; BYTES_PER_POINT];
        for (i, v) in [p.x, p.y, p.z, p.intensity].into_iter().enumerate() {
            record[4 * i..4 * i + 4].copy_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&record);
    }
}

/// Writes points as a `.bin` file.
///
/// # Errors
/// The file cannot be written (named).
pub fn write_bin(path: &Path, points: &[LidarPoint]) -> Result<()> {
    std::fs::write(path, encode_bin(points)).map_err(|source| KittiError::Io {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic scan in KITTI's order: 64 lasers top first, each sweeping
    /// azimuth 0 → 2π.
    fn synthetic_points() -> Vec<LidarPoint> {
        let mut points = Vec::new();
        for line in 0..64u16 {
            let ring = 63 - line;
            let elevation = KITTI_RING_ELEVATION_DEG[ring as usize].to_radians();
            for k in 0..100 {
                let az = (k as f64 + 0.5) / 100.0 * TAU;
                let r = 20.0;
                points.push(LidarPoint {
                    x: (r * elevation.cos() * az.cos()) as f32,
                    y: (r * elevation.cos() * az.sin()) as f32,
                    z: (r * elevation.sin()) as f32,
                    intensity: 0.25,
                    ring,
                    time_offset_s: 0.0,
                });
            }
        }
        points
    }

    #[test]
    fn round_trip_recovers_points_and_rings() {
        let points = synthetic_points();
        let bytes = encode_bin(&points);
        assert_eq!(bytes.len(), points.len() * 16);
        let scan = parse_bin(&bytes, Path::new("s.bin"), 3.0).unwrap();
        assert_eq!(scan.ring_source, RingSource::ScanLines);
        assert_eq!(scan.scan.t_s, 3.0);
        assert_eq!(scan.scan.points.len(), points.len());
        for (a, b) in points.iter().zip(&scan.scan.points) {
            assert_eq!(
                (a.x, a.y, a.z, a.intensity, a.ring),
                (b.x, b.y, b.z, b.intensity, b.ring)
            );
            assert!((0.0..=0.1).contains(&b.time_offset_s));
        }
    }

    #[test]
    fn shuffled_points_fall_back_to_elevation_bins() {
        let mut points = synthetic_points();
        points.reverse();
        let scan = parse_bin(&encode_bin(&points), Path::new("s.bin"), 0.0).unwrap();
        assert_eq!(scan.ring_source, RingSource::ElevationBins);
        // Points at the table elevations land on their own lasers.
        for (a, b) in points.iter().zip(&scan.scan.points) {
            assert_eq!(a.ring, b.ring);
        }
    }

    #[test]
    fn points_put_in_kitti_order_give_their_rings_back_from_the_scan_lines() {
        let original = synthetic_points();
        // a simulator's storage: column by column (time order), rings mixed,
        // elevations off the KITTI table so that elevation bins would merge rings
        let mut columns: Vec<LidarPoint> = (0..100)
            .flat_map(|k| original.iter().skip(k).step_by(100).copied())
            .map(|mut p| {
                p.z *= 1.3;
                p
            })
            .collect();
        columns.rotate_left(1234);
        let mut ordered = Vec::new();
        in_kitti_order(&columns, &mut ordered);
        let scan = parse_bin(&encode_bin(&ordered), Path::new("s.bin"), 0.0).unwrap();
        assert_eq!(scan.ring_source, RingSource::ScanLines);
        for (a, b) in ordered.iter().zip(&scan.scan.points) {
            assert_eq!((a.x, a.y, a.z, a.ring), (b.x, b.y, b.z, b.ring));
        }
        let sorted = |points: &[LidarPoint]| {
            let mut v: Vec<_> = points
                .iter()
                .map(|p| (p.ring, p.x.to_bits(), p.y.to_bits()))
                .collect();
            v.sort_unstable();
            v
        };
        assert_eq!(sorted(&ordered), sorted(&columns));
        // the linear passes give exactly the plain sort's order, for the
        // column order, a shuffled one (sorted) and one with ties
        let plain = |points: &[LidarPoint]| {
            let mut keyed: Vec<(u16, f64, usize)> = points
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let az = (p.y as f64).atan2(p.x as f64).rem_euclid(TAU);
                    (u16::MAX - p.ring, az, i)
                })
                .collect();
            keyed.sort_unstable_by(|a, b| {
                a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2))
            });
            keyed.iter().map(|&(_, _, i)| points[i]).collect::<Vec<_>>()
        };
        let mut shuffled = columns.clone();
        for i in 0..shuffled.len() {
            shuffled.swap(i, (i * 7919 + 13) % columns.len());
        }
        let mut with_ties = columns.clone();
        with_ties.extend_from_slice(&columns[..500]);
        for input in [&columns, &shuffled, &with_ties] {
            in_kitti_order(input, &mut ordered);
            assert_eq!(ordered, plain(input));
        }
        // the same scan read from the column order bins elevations: rings merge
        let mixed = parse_bin(&encode_bin(&columns), Path::new("s.bin"), 0.0).unwrap();
        assert_eq!(mixed.ring_source, RingSource::ElevationBins);
        assert!(
            mixed
                .scan
                .points
                .iter()
                .zip(&columns)
                .any(|(b, a)| a.ring != b.ring)
        );
    }

    #[test]
    fn sweep_time_runs_clockwise_from_the_rear() {
        let t = |x: f64, y: f64| sweep_time_offset_s(&Vector3::new(x, y, 0.0));
        assert!((t(-1.0, 1e-9) - 0.0).abs() < 1e-6);
        assert!((t(0.0, 1.0) - 0.025).abs() < 1e-12);
        assert!((t(1.0, 0.0) - 0.05).abs() < 1e-12);
        assert!((t(0.0, -1.0) - 0.075).abs() < 1e-12);
        assert!((t(-1.0, -1e-9) - 0.1).abs() < 1e-6);
    }

    fn elevation_deg(p: &Vector3<f64>) -> f64 {
        p.z.atan2(p.xy().norm()).to_degrees()
    }

    #[test]
    fn raising_elevation_keeps_range_and_azimuth() {
        let angle = KITTI_HDL64_ELEVATION_CORRECTION_DEG.to_radians();
        for (az_deg, el_deg, range) in [
            (0.0, 0.0, 10.0),
            (37.0, -24.0, 5.5),
            (-120.0, 2.0, 80.0),
            (179.0, -8.0, 30.0),
        ] {
            let (az, el) = (f64::to_radians(az_deg), f64::to_radians(el_deg));
            let p = range * Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
            let q = raise_elevation(&p, angle);
            assert!((q.norm() - range).abs() < 1e-12, "range {}", q.norm());
            assert!((q.y.atan2(q.x) - az).abs() < 1e-12, "azimuth");
            let raised = elevation_deg(&q) - el_deg;
            assert!(
                (raised - KITTI_HDL64_ELEVATION_CORRECTION_DEG).abs() < 1e-9,
                "{raised}°"
            );
            // It is the rotation about p × z: the axis is kept and the
            // rotated vector is perpendicular to it.
            let axis = p.cross(&Vector3::z()).normalize();
            let rotated =
                nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle)
                    * p;
            assert!((rotated - q).norm() < 1e-12 * range);
        }
        // At 20 m a level point rises by 20 m · tan(0.22°) = 7.7 cm.
        let q = raise_elevation(&Vector3::new(20.0, 0.0, 0.0), angle);
        assert!((q.z - 0.0768).abs() < 1e-4, "{}", q.z);
        // The z axis has no azimuth plane: unchanged; a zero angle is exact.
        let up = Vector3::new(0.0, 0.0, 3.0);
        assert_eq!(raise_elevation(&up, angle), up);
        let p = Vector3::new(1.5, -2.0, 0.25);
        assert_eq!(raise_elevation(&p, 0.0), p);
    }

    #[test]
    fn raising_a_scan_keeps_rings_times_and_intensities() {
        let points = synthetic_points();
        let mut scan = parse_bin(&encode_bin(&points), Path::new("s.bin"), 0.0)
            .unwrap()
            .scan;
        let before = scan.clone();
        raise_scan_elevation(&mut scan, 0.3f64.to_radians());
        for (a, b) in before.points.iter().zip(&scan.points) {
            assert_eq!(
                (a.ring, a.time_offset_s, a.intensity),
                (b.ring, b.time_offset_s, b.intensity)
            );
            let (pa, pb) = (
                Vector3::new(a.x as f64, a.y as f64, a.z as f64),
                Vector3::new(b.x as f64, b.y as f64, b.z as f64),
            );
            assert!((elevation_deg(&pb) - elevation_deg(&pa) - 0.3).abs() < 1e-4);
        }
    }

    #[test]
    fn truncation_and_nan_are_errors_with_byte_offsets() {
        let points = synthetic_points();
        let mut bytes = encode_bin(&points);
        let path = Path::new("scans/0000000007.bin");
        let err = parse_bin(&bytes[..bytes.len() - 3], path, 0.0)
            .unwrap_err()
            .to_string();
        let expected = format!("byte offset {}", bytes.len() - 16);
        assert!(
            err.contains("0000000007.bin") && err.contains(&expected),
            "{err}"
        );
        bytes[16 * 10 + 8..16 * 10 + 12].copy_from_slice(&f32::NAN.to_le_bytes());
        let err = parse_bin(&bytes, path, 0.0).unwrap_err().to_string();
        assert!(
            err.contains("byte offset 168") && err.contains("`z`"),
            "{err}"
        );
        let empty = parse_bin(&[], path, 0.0).unwrap();
        assert!(empty.scan.points.is_empty());
    }
}
