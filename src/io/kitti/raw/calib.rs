//! Raw calibration: the three per-day files of a KITTI raw recording.

use crate::io::kitti::calib::{Calib, isometry_from_3x4};
use crate::io::kitti::{KittiError, LineCtx, Result, content_lines, read_text};
use nalgebra::{Isometry3, Matrix3, Matrix3x4};
use std::path::Path;

// ---------------------------------------------------------------------------
// Calibration
// ---------------------------------------------------------------------------

/// One `key: numbers` line of a raw calibration file.
struct CalibEntry {
    line: usize,
    values: Vec<String>,
}

/// Splits `key: v1 v2 …` lines at the first colon (values such as
/// `calib_time: 09-Jan-2012 13:57:47` contain colons themselves).
fn parse_key_values(text: &str, path: &Path) -> Result<Vec<(String, CalibEntry)>> {
    let mut entries: Vec<(String, CalibEntry)> = Vec::new();
    for (line_no, line) in content_lines(text) {
        let ctx = LineCtx::new(path, line_no);
        let Some((key, rest)) = line.split_once(':') else {
            return Err(ctx.line_error(format!("expected `key: values`, found `{}`", line.trim())));
        };
        let key = key.trim();
        if key.is_empty() || key.contains(char::is_whitespace) {
            return Err(ctx.line_error(format!("`{key}` is not a calibration key")));
        }
        if entries.iter().any(|(k, _)| k == key) {
            return Err(ctx.line_error(format!("duplicate key `{key}`")));
        }
        entries.push((
            key.to_string(),
            CalibEntry {
                line: line_no,
                values: rest.split_whitespace().map(str::to_string).collect(),
            },
        ));
    }
    Ok(entries)
}

/// The numbers of a required key, checked for count and finiteness.
fn numbers<const N: usize>(
    entries: &[(String, CalibEntry)],
    path: &Path,
    key: &'static str,
) -> Result<([f64; N], usize)> {
    let Some((_, entry)) = entries.iter().find(|(k, _)| k == key) else {
        return Err(KittiError::MissingKey {
            path: path.to_path_buf(),
            key,
        });
    };
    let ctx = LineCtx::new(path, entry.line);
    if entry.values.len() != N {
        return Err(ctx.column_count(&format!("{key}: + {N}"), entry.values.len() + 1));
    }
    let mut out = [0.0; N];
    for (i, (value, token)) in out.iter_mut().zip(&entry.values).enumerate() {
        *value = ctx.f64(token, i + 2, key)?;
    }
    Ok((out, entry.line))
}

/// `R:` and `T:` of a rigid-transform file → isometry (rotation checked and
/// re-orthonormalised as in the tracking calibration).
fn rigid_transform(text: &str, path: &Path) -> Result<Isometry3<f64>> {
    let entries = parse_key_values(text, path)?;
    let (r, r_line) = numbers::<9>(&entries, path, "R")?;
    let (t, _) = numbers::<3>(&entries, path, "T")?;
    let m = Matrix3x4::new(
        r[0], r[1], r[2], t[0], r[3], r[4], r[5], t[1], r[6], r[7], r[8], t[2],
    );
    isometry_from_3x4(&m).map_err(|why| LineCtx::new(path, r_line).line_error(format!("R: {why}")))
}

/// Calibration of one KITTI raw recording day (`<date>/calib_*.txt`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawCalib {
    /// `calib_imu_to_velo.txt`: maps IMU (OXTS) points into the Velodyne frame.
    pub t_velo_imu: Isometry3<f64>,
    /// `calib_velo_to_cam.txt`: maps Velodyne points into the unrectified camera-0 frame.
    pub t_cam_velo: Isometry3<f64>,
    /// `R_rect_00`: rectifying rotation of camera 0, as stored.
    pub r_rect_00: Matrix3<f64>,
    /// `P_rect_00` … `P_rect_03`: projections of the rectified cameras (02 = left colour).
    pub p_rect: [Matrix3x4<f64>; 4],
}

impl RawCalib {
    /// File of the IMU-to-Velodyne transform in a date directory.
    pub const IMU_TO_VELO: &'static str = "calib_imu_to_velo.txt";
    /// File of the Velodyne-to-camera transform.
    pub const VELO_TO_CAM: &'static str = "calib_velo_to_cam.txt";
    /// File of the camera intrinsics and rectification.
    pub const CAM_TO_CAM: &'static str = "calib_cam_to_cam.txt";

    /// Reads the three calibration files of a date directory.
    ///
    /// # Errors
    /// An unreadable calibration file, or a malformed one (see [`RawCalib::parse`]).
    pub fn read(date_dir: &Path) -> Result<RawCalib> {
        let imu_path = date_dir.join(Self::IMU_TO_VELO);
        let velo_path = date_dir.join(Self::VELO_TO_CAM);
        let cam_path = date_dir.join(Self::CAM_TO_CAM);
        RawCalib::parse(
            (&read_text(&imu_path)?, &imu_path),
            (&read_text(&velo_path)?, &velo_path),
            (&read_text(&cam_path)?, &cam_path),
        )
    }

    /// Parses the texts of `calib_imu_to_velo`, `calib_velo_to_cam` and
    /// `calib_cam_to_cam` (each with its path for error messages). Keys not
    /// needed here (`calib_time`, `S_xx`, `K_xx`, `D_xx`, `delta_f`, …) are
    /// ignored; needed ones are checked.
    ///
    /// ```
    /// use limot::io::kitti::raw::RawCalib;
    /// use std::path::Path;
    /// // 2011-09-26 (KITTI raw), keys not needed here left out
    /// let imu_to_velo = "\
    /// calib_time: 25-May-2012 16:47:16
    /// R: 9.999976e-01 7.553071e-04 -2.035826e-03 -7.854027e-04 9.998898e-01 -1.482298e-02 2.024406e-03 1.482454e-02 9.998881e-01
    /// T: -8.086759e-01 3.195559e-01 -7.997231e-01
    /// ";
    /// let velo_to_cam = "\
    /// R: 7.533745e-03 -9.999714e-01 -6.166020e-04 1.480249e-02 7.280733e-04 -9.998902e-01 9.998621e-01 7.523790e-03 1.480755e-02
    /// T: -4.069766e-03 -7.631618e-02 -2.717806e-01
    /// ";
    /// let cam_to_cam = "\
    /// R_rect_00: 9.999239e-01 9.837760e-03 -7.445048e-03 -9.869795e-03 9.999421e-01 -4.278459e-03 7.402527e-03 4.351614e-03 9.999631e-01
    /// P_rect_00: 7.215377e+02 0.000000e+00 6.095593e+02 0.000000e+00 0.000000e+00 7.215377e+02 1.728540e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00
    /// P_rect_01: 7.215377e+02 0.000000e+00 6.095593e+02 -3.875744e+02 0.000000e+00 7.215377e+02 1.728540e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00
    /// P_rect_02: 7.215377e+02 0.000000e+00 6.095593e+02 4.485728e+01 0.000000e+00 7.215377e+02 1.728540e+02 2.163791e-01 0.000000e+00 0.000000e+00 1.000000e+00 2.745884e-03
    /// P_rect_03: 7.215377e+02 0.000000e+00 6.095593e+02 -3.395242e+02 0.000000e+00 7.215377e+02 1.728540e+02 2.199936e+00 0.000000e+00 0.000000e+00 1.000000e+00 2.729905e-03
    /// ";
    /// let calib = RawCalib::parse(
    ///     (imu_to_velo, Path::new("calib_imu_to_velo.txt")),
    ///     (velo_to_cam, Path::new("calib_velo_to_cam.txt")),
    ///     (cam_to_cam, Path::new("calib_cam_to_cam.txt")),
    /// )
    /// .unwrap();
    /// // the IMU sits 0.81 m behind and 0.32 m left of the Velodyne
    /// let t = calib.t_velo_imu.translation.vector;
    /// assert_eq!((t.x, t.y, t.z), (-8.086759e-01, 3.195559e-01, -7.997231e-01));
    /// assert_eq!(calib.p_rect[2][(0, 0)], 721.5377); // focal length, pixels
    /// ```
    ///
    /// # Errors
    /// A missing key, a wrong number of values, a non-finite value or a non-rotation matrix (file
    /// and line).
    pub fn parse(
        imu_to_velo: (&str, &Path),
        velo_to_cam: (&str, &Path),
        cam_to_cam: (&str, &Path),
    ) -> Result<RawCalib> {
        let t_velo_imu = rigid_transform(imu_to_velo.0, imu_to_velo.1)?;
        let t_cam_velo = rigid_transform(velo_to_cam.0, velo_to_cam.1)?;
        let (text, path) = cam_to_cam;
        let entries = parse_key_values(text, path)?;
        let (r, r_line) = numbers::<9>(&entries, path, "R_rect_00")?;
        let r_rect_00 = Matrix3::from_row_slice(&r);
        // Same orthonormality check as the tracking `R_rect` (via a 3x4 with t = 0).
        let mut as_3x4 = Matrix3x4::zeros();
        as_3x4.fixed_view_mut::<3, 3>(0, 0).copy_from(&r_rect_00);
        isometry_from_3x4(&as_3x4)
            .map_err(|why| LineCtx::new(path, r_line).line_error(format!("R_rect_00: {why}")))?;
        let keys = ["P_rect_00", "P_rect_01", "P_rect_02", "P_rect_03"];
        let mut p_rect = [Matrix3x4::zeros(); 4];
        for (p, key) in p_rect.iter_mut().zip(keys) {
            let (values, _) = numbers::<12>(&entries, path, key)?;
            *p = Matrix3x4::from_row_slice(&values);
        }
        Ok(RawCalib {
            t_velo_imu,
            t_cam_velo,
            r_rect_00,
            p_rect,
        })
    }

    /// The tracking-style calibration (P0..P3 = P_rect_00..03, R_rect =
    /// R_rect_00), so the tracking code path can be reused on raw drives.
    pub fn to_calib(&self) -> Calib {
        Calib {
            p0: self.p_rect[0],
            p1: self.p_rect[1],
            p2: self.p_rect[2],
            p3: self.p_rect[3],
            r_rect: self.r_rect_00,
            t_cam_velo: self.t_cam_velo,
            t_velo_imu: self.t_velo_imu,
        }
    }
}
