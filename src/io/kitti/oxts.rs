//! OXTS GPS/IMU records (`training/oxts/00NN.txt`, one 30-column line per frame).
//!
//! Field meanings from the KITTI raw devkit `dataformat.txt`:
//! lat/lon (deg), alt (m), roll/pitch/yaw (rad; roll 0 = level, pitch 0 =
//! level, yaw 0 = east, positive counter-clockwise), vn/ve (m/s north/east),
//! vf/vl/vu (m/s forward/left/up), ax/ay/az (m/s², acceleration in the
//! vehicle body frame x = front, y = left, z = top), af/al/au (m/s², the same
//! acceleration in the forward/left/up frame that follows heading but stays
//! level), wx/wy/wz (rad/s, angular rate about the body axes), wf/wl/wu
//! (rad/s, about forward/left/up), pos_accuracy/vel_accuracy (m, m/s),
//! navstat, numsats, posmode, velmode, orimode (integers).
//!
//! The accelerations are what an accelerometer measures, i.e. they contain
//! gravity: a car at rest on level ground reads az ≈ +9.81 m/s². That is the
//! specific force of [`ImuSample::accel_mps2`]. [`oxts_to_imu`] uses the body
//! frame fields (ax, ay, az) and (wx, wy, wz); the level-frame fields are kept
//! for checks (see the tests: rotating (ax, ay, az) by pitch and roll gives
//! (af, al, au)).

use super::{LineCtx, Result, content_lines, read_text};
use limot_estimator::input::ImuSample;
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use std::fmt::Write as _;
use std::path::Path;

/// Earth radius used by the KITTI devkit for the Mercator projection (m).
pub const EARTH_RADIUS_M: f64 = 6_378_137.0;

/// Column names, in file order.
pub const FIELD_NAMES: [&str; 30] = [
    "lat",
    "lon",
    "alt",
    "roll",
    "pitch",
    "yaw",
    "vn",
    "ve",
    "vf",
    "vl",
    "vu",
    "ax",
    "ay",
    "az",
    "af",
    "al",
    "au",
    "wx",
    "wy",
    "wz",
    "wf",
    "wl",
    "wu",
    "pos_accuracy",
    "vel_accuracy",
    "navstat",
    "numsats",
    "posmode",
    "velmode",
    "orimode",
];

/// One OXTS line (see the module docs for units and frames).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct OxtsRecord {
    /// Latitude (deg).
    pub lat_deg: f64,
    /// Longitude (deg).
    pub lon_deg: f64,
    /// Altitude (m).
    pub alt_m: f64,
    /// Roll (rad, 0 = level).
    pub roll_rad: f64,
    /// Pitch (rad, 0 = level).
    pub pitch_rad: f64,
    /// Heading (rad, 0 = east, counter-clockwise).
    pub yaw_rad: f64,
    /// Velocity north (m/s).
    pub vn_mps: f64,
    /// Velocity east (m/s).
    pub ve_mps: f64,
    /// Velocity forward (m/s).
    pub vf_mps: f64,
    /// Velocity left (m/s).
    pub vl_mps: f64,
    /// Velocity up (m/s).
    pub vu_mps: f64,
    /// Specific force along body x (front), m/s².
    pub ax_mps2: f64,
    /// Specific force along body y (left), m/s².
    pub ay_mps2: f64,
    /// Specific force along body z (top), m/s².
    pub az_mps2: f64,
    /// Specific force forward, level frame (m/s²).
    pub af_mps2: f64,
    /// Specific force left, level frame (m/s²).
    pub al_mps2: f64,
    /// Specific force up, level frame (m/s²).
    pub au_mps2: f64,
    /// Angular rate about body x (rad/s).
    pub wx_radps: f64,
    /// Angular rate about body y (rad/s).
    pub wy_radps: f64,
    /// Angular rate about body z (rad/s).
    pub wz_radps: f64,
    /// Angular rate about forward, level frame (rad/s).
    pub wf_radps: f64,
    /// Angular rate about left, level frame (rad/s).
    pub wl_radps: f64,
    /// Angular rate about up, level frame (rad/s).
    pub wu_radps: f64,
    /// Position accuracy (m).
    pub pos_accuracy_m: f64,
    /// Velocity accuracy (m/s).
    pub vel_accuracy_mps: f64,
    /// Navigation status.
    pub navstat: i64,
    /// Number of satellites tracked.
    pub numsats: i64,
    /// Position mode.
    pub posmode: i64,
    /// Velocity mode.
    pub velmode: i64,
    /// Orientation mode.
    pub orimode: i64,
}

impl OxtsRecord {
    /// The 25 real-valued fields in file order.
    fn floats(&self) -> [f64; 25] {
        [
            self.lat_deg,
            self.lon_deg,
            self.alt_m,
            self.roll_rad,
            self.pitch_rad,
            self.yaw_rad,
            self.vn_mps,
            self.ve_mps,
            self.vf_mps,
            self.vl_mps,
            self.vu_mps,
            self.ax_mps2,
            self.ay_mps2,
            self.az_mps2,
            self.af_mps2,
            self.al_mps2,
            self.au_mps2,
            self.wx_radps,
            self.wy_radps,
            self.wz_radps,
            self.wf_radps,
            self.wl_radps,
            self.wu_radps,
            self.pos_accuracy_m,
            self.vel_accuracy_mps,
        ]
    }

    fn from_fields(f: &[f64; 25], ints: &[i64; 5]) -> OxtsRecord {
        OxtsRecord {
            lat_deg: f[0],
            lon_deg: f[1],
            alt_m: f[2],
            roll_rad: f[3],
            pitch_rad: f[4],
            yaw_rad: f[5],
            vn_mps: f[6],
            ve_mps: f[7],
            vf_mps: f[8],
            vl_mps: f[9],
            vu_mps: f[10],
            ax_mps2: f[11],
            ay_mps2: f[12],
            az_mps2: f[13],
            af_mps2: f[14],
            al_mps2: f[15],
            au_mps2: f[16],
            wx_radps: f[17],
            wy_radps: f[18],
            wz_radps: f[19],
            wf_radps: f[20],
            wl_radps: f[21],
            wu_radps: f[22],
            pos_accuracy_m: f[23],
            vel_accuracy_mps: f[24],
            navstat: ints[0],
            numsats: ints[1],
            posmode: ints[2],
            velmode: ints[3],
            orimode: ints[4],
        }
    }

    /// Parses one line; `ctx` names the file and line in errors.
    pub(crate) fn parse_line(line: &str, ctx: LineCtx<'_>) -> Result<OxtsRecord> {
        let tokens: Vec<&str> = line.split_whitespace().collect();
        if tokens.len() != 30 {
            return Err(ctx.column_count("30", tokens.len()));
        }
        let mut floats = [0.0; 25];
        for (i, value) in floats.iter_mut().enumerate() {
            *value = ctx.f64(tokens[i], i + 1, FIELD_NAMES[i])?;
        }
        let mut ints = [0i64; 5];
        for (k, value) in ints.iter_mut().enumerate() {
            let i = 25 + k;
            *value = ctx.i64(tokens[i], i + 1, FIELD_NAMES[i])?;
        }
        Ok(OxtsRecord::from_fields(&floats, &ints))
    }

    /// Formats the record as one OXTS line (no newline); shortest
    /// round-trip numbers, so `parse(to_line(r)) == r` exactly.
    pub fn to_line(&self) -> String {
        let mut out = String::new();
        for v in self.floats() {
            let _ = write!(out, "{v} ");
        }
        let _ = write!(
            out,
            "{} {} {} {} {}",
            self.navstat, self.numsats, self.posmode, self.velmode, self.orimode
        );
        out
    }

    /// Rotation of the IMU body frame relative to the local east-north-up
    /// frame, as the devkit builds it: `Rz(yaw) · Ry(pitch) · Rx(roll)`.
    pub fn rotation_enu_imu(&self) -> Matrix3<f64> {
        let (sr, cr) = self.roll_rad.sin_cos();
        let (sp, cp) = self.pitch_rad.sin_cos();
        let (sy, cy) = self.yaw_rad.sin_cos();
        let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, cr, -sr, 0.0, sr, cr);
        let ry = Matrix3::new(cp, 0.0, sp, 0.0, 1.0, 0.0, -sp, 0.0, cp);
        let rz = Matrix3::new(cy, -sy, 0.0, sy, cy, 0.0, 0.0, 0.0, 1.0);
        rz * ry * rx
    }
}

/// Parses an OXTS file's text (one record per non-blank line).
///
/// # Errors
/// A line without 30 columns or a malformed field (file, line and column).
pub fn parse_oxts(text: &str, path: &Path) -> Result<Vec<OxtsRecord>> {
    content_lines(text)
        .map(|(line_no, line)| OxtsRecord::parse_line(line, LineCtx::new(path, line_no)))
        .collect()
}

/// Reads an OXTS file.
///
/// # Errors
/// An unreadable file, or a malformed line (see [`parse_oxts`]).
pub fn read_oxts(path: &Path) -> Result<Vec<OxtsRecord>> {
    parse_oxts(&read_text(path)?, path)
}

/// Formats records as an OXTS file (one line each).
pub fn write_oxts(records: &[OxtsRecord]) -> String {
    records.iter().map(|r| r.to_line() + "\n").collect()
}

/// Mercator scale of the devkit: `cos(lat0)`.
pub fn lat_to_scale(lat_deg: f64) -> f64 {
    (lat_deg.to_radians()).cos()
}

/// Devkit `latlonToMercator`: metres east/north on a Mercator map scaled so
/// that distances near `lat0` are true.
pub fn lat_lon_to_mercator(lat_deg: f64, lon_deg: f64, scale: f64) -> (f64, f64) {
    let mx = scale * lon_deg * std::f64::consts::PI * EARTH_RADIUS_M / 180.0;
    let my = scale * EARTH_RADIUS_M * ((90.0 + lat_deg) * std::f64::consts::PI / 360.0).tan().ln();
    (mx, my)
}

/// IMU poses `T_w_imu` exactly as the devkit's `convertOxtsToPose`: Mercator
/// translation with the scale of the first latitude, rotation
/// `Rz(yaw)·Ry(pitch)·Rx(roll)`, all relative to the first pose (so the world
/// frame is the first IMU frame and `poses[0]` is the identity).
pub fn oxts_to_poses(records: &[OxtsRecord]) -> Vec<Isometry3<f64>> {
    let Some(first) = records.first() else {
        return Vec::new();
    };
    let scale = lat_to_scale(first.lat_deg);
    let absolute = |r: &OxtsRecord| {
        let (x, y) = lat_lon_to_mercator(r.lat_deg, r.lon_deg, scale);
        let rotation = Rotation3::from_matrix_unchecked(r.rotation_enu_imu());
        Isometry3::from_parts(
            Translation3::new(x, y, r.alt_m),
            UnitQuaternion::from_rotation_matrix(&rotation),
        )
    };
    let t_0_inv = absolute(first).inverse();
    records.iter().map(|r| t_0_inv * absolute(r)).collect()
}

/// IMU samples at `t0_s + i·dt_s` (tracking OXTS is 10 Hz: `dt_s = 0.1`):
/// specific force (ax, ay, az) and angular rate (wx, wy, wz), both in the IMU
/// body frame (x forward, y left, z up). See the module docs.
pub fn oxts_to_imu(records: &[OxtsRecord], t0_s: f64, dt_s: f64) -> Vec<ImuSample> {
    records
        .iter()
        .enumerate()
        .map(|(i, r)| ImuSample {
            t_s: t0_s + i as f64 * dt_s,
            accel_mps2: Vector3::new(r.ax_mps2, r.ay_mps2, r.az_mps2),
            gyro_radps: Vector3::new(r.wx_radps, r.wy_radps, r.wz_radps),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const LINES: &str = "\
49.009347760599 8.4371344308375 114.45652008057 0.072242 0.001566 -0.2697266732051 -2.9301818443449 10.286884437741 10.695750797331 0.082893715568935 -0.075015404010604 0.0059525410318346 0.845164147132 9.9149729634473 0.041978129261809 0.13652761309179 9.9501668070309 0.016662646247367 -0.036831580656409 0.003311640516573 0.016662387052679 -0.036976147506788 0.00060422104178454 0.42856154750514 0.057982756057297 4 7 4 4 0
49.009344871709 8.4371499178574 114.45387268066 0.073139 -0.000124 -0.2696086732051 -2.9197146576057 10.304161163296 10.709610967122 0.068612964517919 -0.036819526034639 0.081271437896475 0.99064156439495 10.267645855742 0.087095268433451 0.23917236586171 10.312656380529 0.0027339720243652 -0.012582267935983 0.0028883653449442 0.0027336596878896 -0.012759610755965 0.0019557415013945 0.42856154750514 0.057982756057297 4 7 4 4 0
";

    #[test]
    fn parses_and_round_trips() {
        let path = Path::new("oxts.txt");
        let records = parse_oxts(LINES, path).unwrap();
        assert_eq!(records.len(), 2);
        assert_eq!(records[0].lat_deg, 49.009347760599);
        assert_eq!(records[0].az_mps2, 9.9149729634473);
        assert_eq!(records[0].numsats, 7);
        assert_eq!(records[1].orimode, 0);
        let again = parse_oxts(&write_oxts(&records), path).unwrap();
        assert_eq!(again, records);
    }

    #[test]
    fn first_pose_is_identity_and_motion_matches_velocity() {
        let records = parse_oxts(LINES, Path::new("o.txt")).unwrap();
        let poses = oxts_to_poses(&records);
        let d0 = poses[0].translation.vector.norm() + poses[0].rotation.angle();
        assert!(d0 < 1e-9);
        // Moving at ~10.7 m/s forward for 0.1 s: ~1.07 m along the IMU x axis
        // (GPS says 1.18 m: the 10 Hz GPS fixes jitter in time).
        let step = poses[1].translation.vector;
        assert!((step.norm() - 1.07).abs() < 0.15, "{step}");
        assert!(step.x > 1.0 && step.y.abs() < 0.05 * step.x, "{step}");
    }

    #[test]
    fn mercator_matches_devkit_formula_at_known_point() {
        // Independent evaluation: at lat0 = lat, my = s·R·ln(tan(45° + lat/2)).
        let lat: f64 = 49.0;
        let s = lat_to_scale(lat);
        let (mx, my) = lat_lon_to_mercator(lat, 8.0, s);
        let expected_my = s
            * EARTH_RADIUS_M
            * (std::f64::consts::FRAC_PI_4 + lat.to_radians() / 2.0)
                .tan()
                .ln();
        assert!((my - expected_my).abs() < 1e-6);
        assert!((mx - s * 8.0f64.to_radians() * EARTH_RADIUS_M).abs() < 1e-6);
        // One degree of longitude at 49°N is ~73 km.
        let (mx2, _) = lat_lon_to_mercator(lat, 9.0, s);
        assert!((mx2 - mx - 73_000.0).abs() < 200.0);
    }

    #[test]
    fn body_and_level_accelerations_agree_through_roll_and_pitch() {
        // Documents the frame of (ax, ay, az): rotating it by Ry(pitch)·Rx(roll)
        // gives (af, al, au), so ax..az are in the tilted body frame.
        let records = parse_oxts(LINES, Path::new("o.txt")).unwrap();
        for r in &records {
            let level = Rotation3::from_axis_angle(&Vector3::y_axis(), r.pitch_rad)
                * Rotation3::from_axis_angle(&Vector3::x_axis(), r.roll_rad)
                * Vector3::new(r.ax_mps2, r.ay_mps2, r.az_mps2);
            let flu = Vector3::new(r.af_mps2, r.al_mps2, r.au_mps2);
            assert!((level - flu).norm() < 0.1, "{level} vs {flu}");
        }
        let imu = oxts_to_imu(&records, 5.0, 0.1);
        assert_eq!(imu[1].t_s, 5.1);
        assert!(imu[0].accel_mps2.z > 9.0);
        assert!(imu.iter().all(|s| s.validate().is_ok()));
    }

    #[test]
    fn errors_name_file_line_and_field() {
        let path = Path::new("seq.txt");
        let bad = LINES.replacen("9.9149729634473", "nan", 1);
        let err = parse_oxts(&bad, path).unwrap_err().to_string();
        assert!(err.contains("seq.txt:1") && err.contains("`az`"), "{err}");
        let bad = LINES.replacen(" 4 7 4 4 0\n49", " 4 7 4 4\n49", 1);
        let err = parse_oxts(&bad, path).unwrap_err().to_string();
        assert!(
            err.contains("seq.txt:1") && err.contains("expected 30"),
            "{err}"
        );
        let bad = format!("{LINES}1 2 x\n");
        let err = parse_oxts(&bad, path).unwrap_err().to_string();
        assert!(err.contains("seq.txt:3"), "{err}");
    }
}
