//! The binary scan format (`scans/NNNNNN.bin`): one sweep's points with
//! their per-point ground-truth labels.

use super::{FORMAT_VERSION, RecordError, format_err};
use limot_estimator::input::{LidarPoint, LidarScan};
use std::path::{Path, PathBuf};

const SCAN_MAGIC: &[u8; 4] = b"LMTS";
pub(super) const SCAN_HEADER_BYTES: usize = 4 + 4 + 8 + 8 + 2 + 2 + 4;
const POINT_BYTES: usize = 28;
/// Path of scan `index` in dataset `dir`: `scans/NNNNNN.bin`.
pub fn scan_path(dir: &Path, index: usize) -> PathBuf {
    dir.join("scans").join(format!("{index:06}.bin"))
}

/// Encodes one sweep (little endian): magic, version, t_s, sweep duration,
/// ring count, reserved, point count, then per point x, y, z, intensity,
/// time_offset (f32), label (u32), ring (u16), padding (u16).
pub fn encode_scan(scan: &LidarScan, labels: &[u32]) -> Vec<u8> {
    let mut out = Vec::new();
    encode_scan_into(scan, labels, &mut out);
    out
}

/// [`encode_scan`], appended to `out`.
pub fn encode_scan_into(scan: &LidarScan, labels: &[u32], out: &mut Vec<u8>) {
    assert_eq!(scan.points.len(), labels.len(), "one label per point");
    out.reserve(SCAN_HEADER_BYTES + POINT_BYTES * scan.points.len());
    out.extend_from_slice(SCAN_MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&scan.t_s.to_le_bytes());
    out.extend_from_slice(&scan.sweep_duration_s.to_le_bytes());
    out.extend_from_slice(&scan.num_rings.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    out.extend_from_slice(&(scan.points.len() as u32).to_le_bytes());
    for (p, label) in scan.points.iter().zip(labels) {
        let mut record = [0u8; POINT_BYTES];
        for (i, v) in [p.x, p.y, p.z, p.intensity, p.time_offset_s]
            .into_iter()
            .enumerate()
        {
            record[4 * i..4 * i + 4].copy_from_slice(&v.to_le_bytes());
        }
        record[20..24].copy_from_slice(&label.to_le_bytes());
        record[24..26].copy_from_slice(&p.ring.to_le_bytes());
        out.extend_from_slice(&record);
    }
}

/// The header of [`encode_scan`]'s bytes as a sweep without points, and the
/// point count, checked against the file's length.
fn decode_header(bytes: &[u8], path: &Path) -> Result<(LidarScan, usize), RecordError> {
    let bad = |field: &str, message: String| format_err(path, 0, field, message);
    if bytes.len() < SCAN_HEADER_BYTES {
        return Err(bad(
            "header",
            format!(
                "{} bytes, shorter than the {SCAN_HEADER_BYTES}-byte header",
                bytes.len()
            ),
        ));
    }
    if &bytes[0..4] != SCAN_MAGIC {
        return Err(bad("magic", "not a limot scan file".into()));
    }
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    let f64_at = |o: usize| f64::from_le_bytes(bytes[o..o + 8].try_into().expect("8 bytes"));
    let u16_at = |o: usize| u16::from_le_bytes(bytes[o..o + 2].try_into().expect("2 bytes"));
    let version = u32_at(4);
    if version != FORMAT_VERSION {
        return Err(bad(
            "version",
            format!("version {version}, this build reads {FORMAT_VERSION}"),
        ));
    }
    let t_s = f64_at(8);
    let sweep_duration_s = f64_at(16);
    let num_rings = u16_at(24);
    let count = u32_at(28) as usize;
    if !t_s.is_finite() {
        return Err(bad("t_s", "not finite".into()));
    }
    if !(sweep_duration_s.is_finite() && sweep_duration_s > 0.0) {
        return Err(bad(
            "sweep_duration_s",
            format!("{sweep_duration_s} is not a positive duration"),
        ));
    }
    let expected = SCAN_HEADER_BYTES + count * POINT_BYTES;
    if bytes.len() != expected {
        return Err(bad(
            "point_count",
            format!(
                "header says {count} points ({expected} bytes) but the file has {} bytes",
                bytes.len()
            ),
        ));
    }
    Ok((
        LidarScan {
            t_s,
            sweep_duration_s,
            num_rings,
            points: Vec::new(),
        },
        count,
    ))
}

/// Decodes [`encode_scan`]'s bytes; `path` only names the file in errors.
/// Rejects short files, a wrong magic or version, and non-finite values.
///
/// # Errors
/// [`RecordError::Format`] (line 0) naming the field at fault.
pub fn decode_scan(bytes: &[u8], path: &Path) -> Result<(LidarScan, Vec<u32>), RecordError> {
    let bad = |field: &str, message: String| format_err(path, 0, field, message);
    let (mut scan, count) = decode_header(bytes, path)?;
    let (sweep_duration_s, num_rings) = (scan.sweep_duration_s, scan.num_rings);
    let mut points = Vec::with_capacity(count);
    let mut labels = Vec::with_capacity(count);
    for (i, record) in bytes[SCAN_HEADER_BYTES..]
        .chunks_exact(POINT_BYTES)
        .enumerate()
    {
        let f32_at = |o: usize| f32::from_le_bytes(record[o..o + 4].try_into().expect("4 bytes"));
        let (x, y, z, intensity, time_offset_s) =
            (f32_at(0), f32_at(4), f32_at(8), f32_at(12), f32_at(16));
        // One test for the common case; the field is named only on failure.
        if !(x.is_finite()
            && y.is_finite()
            && z.is_finite()
            && intensity.is_finite()
            && time_offset_s.is_finite())
        {
            let (name, v) = [
                ("x", x),
                ("y", y),
                ("z", z),
                ("intensity", intensity),
                ("time_offset_s", time_offset_s),
            ]
            .into_iter()
            .find(|(_, v)| !v.is_finite())
            .expect("one field is not finite");
            return Err(bad(name, format!("point {i}: {v} is not finite")));
        }
        // f32 rounding of an offset near the sweep end may exceed it slightly
        if time_offset_s < 0.0 || f64::from(time_offset_s) > sweep_duration_s * (1.0 + 1e-6) {
            return Err(bad(
                "time_offset_s",
                format!("point {i}: {time_offset_s} s is outside the {sweep_duration_s} s sweep"),
            ));
        }
        let ring = u16::from_le_bytes([record[24], record[25]]);
        if ring >= num_rings {
            return Err(bad(
                "ring",
                format!("point {i}: ring {ring} but the sensor has {num_rings}"),
            ));
        }
        points.push(LidarPoint {
            x,
            y,
            z,
            intensity,
            ring,
            time_offset_s,
        });
        labels.push(u32::from_le_bytes(
            record[20..24].try_into().expect("4 bytes"),
        ));
    }
    scan.points = points;
    Ok((scan, labels))
}

/// The header of [`encode_scan`]'s bytes (a sweep without points) and the
/// per-point labels alone, for readers of the ground truth that do not need
/// the points; same header checks as [`decode_scan`], the points' fields
/// are not read.
///
/// # Errors
/// [`RecordError::Format`] (line 0) naming the header field at fault.
pub fn decode_labels(bytes: &[u8], path: &Path) -> Result<(LidarScan, Vec<u32>), RecordError> {
    let (scan, _) = decode_header(bytes, path)?;
    let labels = bytes[SCAN_HEADER_BYTES..]
        .chunks_exact(POINT_BYTES)
        .map(|record| u32::from_le_bytes(record[20..24].try_into().expect("4 bytes")))
        .collect();
    Ok((scan, labels))
}
