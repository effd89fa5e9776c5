//! A `sensor_msgs/PointCloud2` as a LiDAR sweep: which fields are read, the
//! per-point time conventions of the common drivers, the sweep start, and
//! the ring of each point (the `ring` field, or its elevation).
//!
//! The conventions are described for users in `docs/ros2-bags.md`.

use super::msgs::{Bytes, Header, PointCloud2, PointField, Time, ns_to_s};
use limot_estimator::input::LidarPoint;
use std::borrow::Cow;

/// Per-point time fields, in the order they are looked for, with their
/// reference: relative to `header.stamp`, or absolute (since the epoch).
pub const TIME_FIELDS: [(&str, TimeReference); 4] = [
    ("time", TimeReference::Relative),
    ("t", TimeReference::Relative),
    ("offset_time", TimeReference::Relative),
    ("timestamp", TimeReference::Absolute),
];

/// Largest distance between `header.stamp` and the first point's time, and
/// longest sweep, s: point times beyond it are read with the wrong convention
/// or on another clock.
pub const MAX_STAMP_GAP_S: f64 = 1.0;

/// A float time field whose first value is larger than this counts nanoseconds
/// (Livox's `timestamp`): no sweep is 10¹² s after the epoch or long.
const FLOAT_NS_THRESHOLD: f64 = 1e12;

/// Rings from elevation: consecutive sorted elevations further apart than
/// this start a new ring, rad (0.1°; beams of 16- to 128-beam sensors are
/// 0.2° to 2° apart).
pub const RING_GAP_RAD: f64 = 0.1 * std::f64::consts::PI / 180.0;

/// What a time field's value is measured from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeReference {
    /// Seconds or nanoseconds after `header.stamp` (may be negative).
    Relative,
    /// Seconds or nanoseconds after the epoch.
    Absolute,
}

/// Why a cloud cannot be read: the field (a point field's name, or a
/// message field such as `point_step`) and what is wrong with it.
#[derive(Debug, Clone, PartialEq)]
pub struct CloudError {
    /// The field at fault.
    pub field: String,
    /// What is wrong.
    pub message: String,
}

fn error(field: &str, message: impl Into<String>) -> CloudError {
    CloudError {
        field: field.to_string(),
        message: message.into(),
    }
}

/// Where a sweep's rings came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RingSource {
    /// The cloud's `ring` field.
    Field,
    /// Clusters of the points' elevation ([`RING_GAP_RAD`]).
    Elevation,
}

/// One cloud read as a sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// `header.stamp`, ns.
    pub stamp_ns: i64,
    /// The sweep start: `header.stamp`, or the earliest point when it is earlier, s.
    pub t_s: f64,
    /// The points with finite coordinates, not at the origin, in cloud order;
    /// times relative to `t_s`.
    pub points: Vec<LidarPoint>,
    /// Rings in the sweep (largest ring + 1).
    pub rings: u16,
    /// Where the rings came from.
    pub ring_source: RingSource,
}

/// A numeric point field: where it is and how it is stored.
#[derive(Debug, Clone, Copy)]
struct Field {
    offset: usize,
    datatype: u8,
}

impl Field {
    fn size(self) -> usize {
        match self.datatype {
            1 | 2 => 1,
            3 | 4 => 2,
            5..=7 => 4,
            _ => 8,
        }
    }

    fn is_integer(self) -> bool {
        (1..=6).contains(&self.datatype)
    }

    /// The value of this field in `point` (which holds it: checked by [`find`]).
    fn read(self, point: &[u8], big_endian: bool) -> f64 {
        let bytes = &point[self.offset..self.offset + self.size()];
        macro_rules! get {
            ($t:ty) => {{
                let array = bytes.try_into().expect("field size checked");
                if big_endian {
                    <$t>::from_be_bytes(array)
                } else {
                    <$t>::from_le_bytes(array)
                }
            }};
        }
        match self.datatype {
            1 => f64::from(bytes[0] as i8),
            2 => f64::from(bytes[0]),
            3 => f64::from(get!(i16)),
            4 => f64::from(get!(u16)),
            5 => f64::from(get!(i32)),
            6 => f64::from(get!(u32)),
            7 => f64::from(get!(f32)),
            _ => get!(f64),
        }
    }
}

/// The point field `name`, checked against the point size; `None` when absent.
fn find(cloud: &PointCloud2, name: &str) -> Result<Option<Field>, CloudError> {
    let Some(f) = cloud.fields.iter().find(|f| f.name == name) else {
        return Ok(None);
    };
    if !(1..=8).contains(&f.datatype) {
        return Err(error(
            name,
            format!(
                "datatype {} is none of PointField's INT8 (1) .. FLOAT64 (8)",
                f.datatype
            ),
        ));
    }
    let field = Field {
        offset: f.offset as usize,
        datatype: f.datatype,
    };
    if field.offset + field.size() > cloud.point_step as usize {
        return Err(error(
            name,
            format!(
                "offset {} + {} bytes is beyond the {}-byte point_step",
                f.offset,
                field.size(),
                cloud.point_step
            ),
        ));
    }
    Ok(Some(field))
}

fn field_names(cloud: &PointCloud2) -> String {
    let names: Vec<&str> = cloud.fields.iter().map(|f| f.name.as_str()).collect();
    format!("[{}]", names.join(", "))
}

/// How a time field's values become seconds after `header.stamp`.
#[derive(Debug, Clone, Copy)]
struct TimeField {
    name: &'static str,
    field: Field,
    reference: TimeReference,
}

impl TimeField {
    /// Seconds per unit: integers count nanoseconds; floats seconds, unless
    /// `first` (the first point's value) is beyond [`FLOAT_NS_THRESHOLD`].
    fn seconds_per_unit(&self, first: f64) -> f64 {
        if self.field.is_integer() || first.abs() > FLOAT_NS_THRESHOLD {
            1e-9
        } else {
            1.0
        }
    }
}

/// Reads `cloud` as a sweep.
///
/// Points: `x`, `y`, `z` (any numeric type), `intensity` (0 when absent),
/// `ring` (or Livox's `line`) and the first time field of [`TIME_FIELDS`];
/// points with a
/// non-finite coordinate or at the origin (no return) are dropped. Times
/// are relative to `header.stamp` or absolute by the field's name, in
/// nanoseconds for integer fields and in seconds for float fields (in
/// nanoseconds when the first value exceeds 10¹²). The sweep starts at
/// `header.stamp`, or at its earliest point when that is earlier (a stamp
/// taken at the sweep end). Without a `ring` field, rings are clusters of
/// elevation `atan2(z, hypot(x, y))` ([`rings_from_elevation`]).
///
/// # Errors
/// A missing `x`, `y`, `z` or time field, a field that does not fit the
/// point, data shorter than the layout, non-finite times, a ring beyond
/// u16, or point times further than [`MAX_STAMP_GAP_S`] from the stamp or
/// spread over longer than that; each names its field.
pub fn read_sweep(cloud: &PointCloud2) -> Result<Sweep, CloudError> {
    let need = |name: &str| {
        find(cloud, name)?.ok_or_else(|| {
            error(
                name,
                format!(
                    "the cloud has no `{name}` field (fields: {})",
                    field_names(cloud)
                ),
            )
        })
    };
    let [x, y, z] = [need("x")?, need("y")?, need("z")?];
    let intensity = find(cloud, "intensity")?;
    let ring = match find(cloud, "ring")? {
        Some(field) => Some(("ring", field)),
        None => find(cloud, "line")?.map(|field| ("line", field)),
    };
    let mut time = None;
    for (name, reference) in TIME_FIELDS {
        if let Some(field) = find(cloud, name)? {
            time = Some(TimeField {
                name,
                field,
                reference,
            });
            break;
        }
    }
    let wanted: Vec<String> = TIME_FIELDS.iter().map(|(n, _)| format!("`{n}`")).collect();
    let time = time.ok_or_else(|| {
        error(
            "time",
            format!(
                "no per-point time field ({}; fields: {})",
                wanted.join(", "),
                field_names(cloud)
            ),
        )
    })?;

    let step = cloud.point_step as usize;
    let (width, height) = (cloud.width as usize, cloud.height as usize);
    let row_step = cloud.row_step as usize;
    if step == 0 && width * height > 0 {
        return Err(error("point_step", "0 bytes per point"));
    }
    if row_step < width.saturating_mul(step) {
        return Err(error(
            "row_step",
            format!("{row_step} bytes, less than {width} points of {step} bytes"),
        ));
    }
    let data: &[u8] = &cloud.data.0;
    if (data.len() as u128) < row_step as u128 * height as u128 {
        return Err(error(
            "data",
            format!(
                "{} bytes, less than {height} rows of {row_step} bytes",
                data.len()
            ),
        ));
    }
    let big_endian = cloud.is_bigendian;
    let stamp_ns = cloud.header.stamp.ns();
    let stamp_s = ns_to_s(stamp_ns);

    let mut points = Vec::with_capacity(width * height);
    let mut relative_s = Vec::with_capacity(width * height);
    let mut seconds_per_unit = None;
    for row in 0..height {
        for column in 0..width {
            let start = row * row_step + column * step;
            let point = &data[start..start + step];
            let [px, py, pz] = [x, y, z].map(|f| f.read(point, big_endian));
            if !(px.is_finite() && py.is_finite() && pz.is_finite())
                || (px == 0.0 && py == 0.0 && pz == 0.0)
            {
                continue;
            }
            let raw = time.field.read(point, big_endian);
            let scale = *seconds_per_unit.get_or_insert_with(|| time.seconds_per_unit(raw));
            let t_rel_s = match time.reference {
                TimeReference::Relative => raw * scale,
                // in the value's own unit first: f64 nanoseconds since the
                // epoch keep a quarter microsecond, seconds a quarter of that
                TimeReference::Absolute if scale == 1.0 => raw - stamp_s,
                TimeReference::Absolute => (raw - stamp_ns as f64) * scale,
            };
            if !t_rel_s.is_finite() {
                return Err(error(
                    time.name,
                    format!("point {}: {raw} is not a finite time", row * width + column),
                ));
            }
            let ring = match ring {
                Some((name, f)) => {
                    let r = f.read(point, big_endian);
                    if !(0.0..f64::from(u16::MAX)).contains(&r) || r.fract() != 0.0 {
                        return Err(error(
                            name,
                            format!("point {}: {r} is no ring number", row * width + column),
                        ));
                    }
                    r as u16
                }
                None => 0,
            };
            points.push(LidarPoint {
                x: px as f32,
                y: py as f32,
                z: pz as f32,
                intensity: intensity.map_or(0.0, |f| f.read(point, big_endian) as f32),
                ring,
                time_offset_s: 0.0,
            });
            relative_s.push(t_rel_s);
        }
    }

    let earliest_s = relative_s.iter().copied().fold(f64::INFINITY, f64::min);
    let latest_s = relative_s.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !relative_s.is_empty() {
        if earliest_s.abs() > MAX_STAMP_GAP_S {
            return Err(error(
                time.name,
                format!(
                    "the first point is {earliest_s:.6} s from header.stamp ({:?} times): another clock, or not this convention",
                    time.reference
                ),
            ));
        }
        if latest_s - earliest_s > MAX_STAMP_GAP_S {
            return Err(error(
                time.name,
                format!(
                    "the points span {:.6} s, longer than a sweep",
                    latest_s - earliest_s
                ),
            ));
        }
    }
    // a stamp taken at the sweep end (negative relative times) moves the start back
    let shift_s = earliest_s.min(0.0);
    let t_s = if shift_s < 0.0 {
        stamp_s + shift_s
    } else {
        stamp_s
    };
    for (p, t_rel_s) in points.iter_mut().zip(&relative_s) {
        p.time_offset_s = (t_rel_s - shift_s) as f32;
    }
    let (rings, ring_source) = match ring {
        Some(_) => (
            points.iter().map(|p| p.ring + 1).max().unwrap_or(0),
            RingSource::Field,
        ),
        None => (rings_from_elevation(&mut points), RingSource::Elevation),
    };
    Ok(Sweep {
        stamp_ns,
        t_s,
        points,
        rings,
        ring_source,
    })
}

/// Numbers the rings of `points` by elevation `atan2(z, hypot(x, y))`: the
/// points sorted by elevation, a new ring starts wherever the next elevation
/// is more than [`RING_GAP_RAD`] above the previous one; ring 0 is the lowest.
/// Returns the number of rings. Exact for beams that fan out from one point
/// (as a spinning LiDAR's nearly do); a scanner without discrete beams
/// (Livox) gets few, wide rings and should carry a `ring` field.
pub fn rings_from_elevation(points: &mut [LidarPoint]) -> u16 {
    let elevation: Vec<f64> = points
        .iter()
        .map(|p| {
            let (x, y, z) = (f64::from(p.x), f64::from(p.y), f64::from(p.z));
            z.atan2(x.hypot(y))
        })
        .collect();
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| elevation[a].total_cmp(&elevation[b]));
    let mut ring: u16 = 0;
    let mut previous = None;
    for i in order {
        if let Some(prev) = previous
            && elevation[i] - prev > RING_GAP_RAD
        {
            ring = ring.saturating_add(1);
        }
        previous = Some(elevation[i]);
        points[i].ring = ring;
    }
    if points.is_empty() { 0 } else { ring + 1 }
}

/// Bytes per point of [`cloud_message`]: Velodyne's ROS layout.
pub const POINT_STEP: u32 = 22;

/// `points` (times relative to `stamp`) as the cloud a Velodyne ROS 2
/// driver publishes: `x`, `y`, `z`, `intensity` f32 at 0, 4, 8, 12, `ring`
/// u16 at 16, `time` f32 (s after `header.stamp`) at 18; one row, little
/// endian.
pub fn cloud_message(stamp: Time, frame_id: &str, points: &[LidarPoint]) -> PointCloud2<'static> {
    let field = |name: &str, offset, datatype| PointField {
        name: name.to_string(),
        offset,
        datatype,
        count: 1,
    };
    let mut data = Vec::with_capacity(points.len() * POINT_STEP as usize);
    for p in points {
        for v in [p.x, p.y, p.z, p.intensity] {
            data.extend_from_slice(&v.to_le_bytes());
        }
        data.extend_from_slice(&p.ring.to_le_bytes());
        data.extend_from_slice(&p.time_offset_s.to_le_bytes());
    }
    PointCloud2 {
        header: Header {
            stamp,
            frame_id: frame_id.to_string(),
        },
        height: 1,
        width: points.len() as u32,
        fields: vec![
            field("x", 0, 7),
            field("y", 4, 7),
            field("z", 8, 7),
            field("intensity", 12, 7),
            field("ring", 16, 4),
            field("time", 18, 7),
        ],
        is_bigendian: false,
        point_step: POINT_STEP,
        row_step: POINT_STEP * points.len() as u32,
        data: Bytes(Cow::Owned(data)),
        is_dense: true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(x: f32, y: f32, z: f32, ring: u16, time_offset_s: f32) -> LidarPoint {
        LidarPoint {
            x,
            y,
            z,
            intensity: 0.5,
            ring,
            time_offset_s,
        }
    }

    /// A cloud with one field per `(name, datatype)`, 8-byte slots, one row.
    fn custom(stamp_ns: i64, fields: &[(&str, u8)], values: &[Vec<f64>]) -> PointCloud2<'static> {
        let step = 8 * fields.len();
        let mut data = Vec::new();
        for row in values {
            for (&(_, datatype), &v) in fields.iter().zip(row) {
                let mut slot = [0u8; 8];
                let bytes: Vec<u8> = match datatype {
                    2 => vec![v as u8],
                    4 => (v as u16).to_le_bytes().to_vec(),
                    6 => (v as u32).to_le_bytes().to_vec(),
                    7 => (v as f32).to_le_bytes().to_vec(),
                    8 => v.to_le_bytes().to_vec(),
                    _ => unreachable!(),
                };
                slot[..bytes.len()].copy_from_slice(&bytes);
                data.extend_from_slice(&slot);
            }
        }
        PointCloud2 {
            header: Header {
                stamp: Time::from_ns(stamp_ns).unwrap(),
                frame_id: "lidar".into(),
            },
            height: 1,
            width: values.len() as u32,
            fields: fields
                .iter()
                .enumerate()
                .map(|(i, &(name, datatype))| PointField {
                    name: name.into(),
                    offset: 8 * i as u32,
                    datatype,
                    count: 1,
                })
                .collect(),
            is_bigendian: false,
            point_step: step as u32,
            row_step: (step * values.len()) as u32,
            data: Bytes(Cow::Owned(data)),
            is_dense: false,
        }
    }

    #[test]
    fn velodyne_layout_round_trips_exactly() {
        let points = vec![
            point(1.0, 2.0, 0.5, 3, 0.0),
            point(-4.0, 0.25, 1.0, 7, 0.05),
        ];
        let stamp = Time {
            sec: 12,
            nanosec: 3,
        };
        let sweep = read_sweep(&cloud_message(stamp, "lidar", &points)).unwrap();
        assert_eq!(sweep.points, points);
        assert_eq!((sweep.stamp_ns, sweep.rings), (12_000_000_003, 8));
        assert_eq!(sweep.t_s, ns_to_s(12_000_000_003));
        assert_eq!(sweep.ring_source, RingSource::Field);
    }

    #[test]
    fn each_driver_convention_gives_the_same_sweep() {
        let stamp_ns = 1_700_000_000_000_000_000;
        let stamp_s = ns_to_s(stamp_ns);
        let xyz = [[5.0, 0.0, 0.0], [0.0, 5.0, 0.0], [-5.0, 0.0, 0.0]];
        let offsets_s = [0.0, 0.025, 0.05];
        let cases: Vec<(&str, u8, Vec<f64>)> = vec![
            ("time", 7, offsets_s.to_vec()),                       // Velodyne
            ("t", 6, offsets_s.iter().map(|t| t * 1e9).collect()), // Ouster
            (
                "offset_time",
                6,
                offsets_s.iter().map(|t| t * 1e9).collect(),
            ), // Livox
            (
                "timestamp",
                8,
                offsets_s.iter().map(|t| stamp_s + t).collect(),
            ), // Hesai
            (
                "timestamp",
                8,
                offsets_s
                    .iter()
                    .map(|t| stamp_ns as f64 + t * 1e9)
                    .collect(),
            ), // Livox
        ];
        for (name, datatype, times) in cases {
            let rows: Vec<Vec<f64>> = xyz
                .iter()
                .zip(&times)
                .map(|(p, &t)| vec![p[0], p[1], p[2], t])
                .collect();
            let cloud = custom(
                stamp_ns,
                &[("x", 7), ("y", 7), ("z", 7), (name, datatype)],
                &rows,
            );
            let sweep = read_sweep(&cloud).unwrap();
            assert_eq!(sweep.t_s, stamp_s, "{name}");
            for (p, t) in sweep.points.iter().zip(offsets_s) {
                assert!(
                    (f64::from(p.time_offset_s) - t).abs() < 2e-6,
                    "{name}: {p:?}"
                );
            }
            assert_eq!(sweep.ring_source, RingSource::Elevation);
        }
    }

    #[test]
    fn a_stamp_at_the_sweep_end_moves_the_start_back() {
        let rows = vec![vec![5.0, 0.0, 0.0, -0.1], vec![0.0, 5.0, 0.0, 0.0]];
        let cloud = custom(
            2_000_000_000,
            &[("x", 7), ("y", 7), ("z", 7), ("time", 7)],
            &rows,
        );
        let sweep = read_sweep(&cloud).unwrap();
        assert!((sweep.t_s - 1.9).abs() < 1e-7, "{}", sweep.t_s); // -0.1 s in f32
        assert_eq!(sweep.points[0].time_offset_s, 0.0);
        assert!((sweep.points[1].time_offset_s - 0.1).abs() < 1e-7);
    }

    #[test]
    fn missing_and_misplaced_fields_are_named() {
        let rows = vec![vec![1.0, 2.0, 3.0]];
        let no_z = custom(0, &[("x", 7), ("y", 7), ("time", 7)], &rows);
        let e = read_sweep(&no_z).unwrap_err();
        assert_eq!(e.field, "z");
        assert!(e.message.contains("[x, y, time]"), "{e:?}");
        let no_time = custom(0, &[("x", 7), ("y", 7), ("z", 7)], &rows);
        let e = read_sweep(&no_time).unwrap_err();
        assert_eq!(e.field, "time");
        assert!(e.message.contains("`offset_time`"), "{e:?}");
        let mut beyond = custom(0, &[("x", 7), ("y", 7), ("z", 7), ("t", 6)], &rows);
        beyond.fields[3].offset = 30;
        assert_eq!(read_sweep(&beyond).unwrap_err().field, "t");
        let mut short = custom(0, &[("x", 7), ("y", 7), ("z", 7), ("t", 6)], &rows);
        short.data.0.to_mut().truncate(10);
        assert_eq!(read_sweep(&short).unwrap_err().field, "data");
        let far = custom(
            0,
            &[("x", 7), ("y", 7), ("z", 7), ("timestamp", 8)],
            &[vec![1.0, 2.0, 3.0, 1.7e9]],
        );
        let e = read_sweep(&far).unwrap_err();
        assert_eq!(e.field, "timestamp");
        assert!(e.message.contains("another clock"), "{e:?}");
    }

    #[test]
    fn no_returns_are_dropped() {
        let rows = vec![
            vec![0.0, 0.0, 0.0, 0.0],
            vec![f64::NAN, 1.0, 1.0, 0.0],
            vec![1.0, 1.0, 1.0, 0.01],
        ];
        let cloud = custom(0, &[("x", 7), ("y", 7), ("z", 7), ("time", 7)], &rows);
        assert_eq!(read_sweep(&cloud).unwrap().points.len(), 1);
    }

    #[test]
    fn rings_from_elevation_cluster_beams() {
        // three beams at -2, 0 and +1 degrees, several azimuths each
        let mut points = Vec::new();
        for (beam, elevation_deg) in [(0u16, -2.0f64), (1, 0.0), (2, 1.0)] {
            for k in 0..8 {
                let azimuth = f64::from(k) * 0.7;
                let (r, e) = (10.0 + f64::from(k), elevation_deg.to_radians());
                points.push(point(
                    (r * e.cos() * azimuth.cos()) as f32,
                    (r * e.cos() * azimuth.sin()) as f32,
                    (r * e.sin()) as f32,
                    beam,
                    0.0,
                ));
            }
        }
        let truth: Vec<u16> = points.iter().map(|p| p.ring).collect();
        points.iter_mut().for_each(|p| p.ring = 99);
        assert_eq!(rings_from_elevation(&mut points), 3);
        assert_eq!(points.iter().map(|p| p.ring).collect::<Vec<_>>(), truth);
    }
}
