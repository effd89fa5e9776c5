//! KITTI tracking calibration files (`training/calib/00NN.txt`).
//!
//! Keys (with or without a trailing colon): `P0`..`P3` (3x4 projection of the
//! rectified cameras), `R_rect` / `R0_rect` (3x3 rectifying rotation of
//! camera 0), `Tr_velo_cam` / `Tr_velo_to_cam` (3x4, maps Velodyne points into
//! the unrectified camera-0 frame), `Tr_imu_velo` / `Tr_imu_to_velo` (3x4,
//! maps IMU points into the Velodyne frame).
//!
//! A Velodyne point reaches the rectified camera frame (the frame of label
//! boxes) as `x_rect = R_rect · Tr_velo_cam · x_velo`, and image pixels as
//! `P2 · x_rect`.

use super::{KittiError, LineCtx, Result, content_lines, read_text};
use nalgebra::{
    Isometry3, Matrix3, Matrix3x4, Point2, Rotation3, Translation3, UnitQuaternion, Vector3,
};
use std::fmt::Write as _;
use std::path::Path;

/// Largest deviation of `RᵀR` from the identity accepted for a stored rotation
/// (the files carry 7 significant digits, so real files deviate by ~1e-7).
const ROTATION_TOLERANCE: f64 = 1e-3;

/// Calibration of one KITTI tracking sequence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calib {
    /// Projection matrices of the four rectified cameras (P2 = left colour).
    pub p0: Matrix3x4<f64>,
    /// P1 (right grey camera).
    pub p1: Matrix3x4<f64>,
    /// P2 (left colour camera, the one labels are drawn in).
    pub p2: Matrix3x4<f64>,
    /// P3 (right colour camera).
    pub p3: Matrix3x4<f64>,
    /// Rectifying rotation of camera 0, kept exactly as stored (it is not
    /// re-orthonormalised so that label boxes convert exactly as the devkit does).
    pub r_rect: Matrix3<f64>,
    /// `Tr_velo_cam`: maps Velodyne points into the (unrectified) camera-0 frame.
    pub t_cam_velo: Isometry3<f64>,
    /// `Tr_imu_velo`: maps IMU (OXTS) points into the Velodyne frame.
    pub t_velo_imu: Isometry3<f64>,
}

impl Calib {
    /// Reads and parses a calibration file.
    ///
    /// # Errors
    /// An unreadable file, a missing key or a malformed matrix (named with file and line).
    pub fn read(path: &Path) -> Result<Calib> {
        Calib::parse(&read_text(path)?, path)
    }

    /// Parses calibration text; `path` is only used in error messages.
    ///
    /// # Errors
    /// A missing key or a malformed matrix (named with file and line).
    pub fn parse(text: &str, path: &Path) -> Result<Calib> {
        let mut p: [Option<Matrix3x4<f64>>; 4] = [None; 4];
        let mut r_rect: Option<Matrix3<f64>> = None;
        let mut t_cam_velo: Option<Isometry3<f64>> = None;
        let mut t_velo_imu: Option<Isometry3<f64>> = None;

        for (line_no, line) in content_lines(text) {
            let ctx = LineCtx::new(path, line_no);
            let mut tokens = line.split_whitespace();
            let Some(first) = tokens.next() else {
                continue;
            };
            // "P0:" or "P0: 1 2 ..." or "P0 1 2 ..." or even "P0:1" (no space).
            let (key, rest_of_first) = match first.split_once(':') {
                Some((k, rest)) => (k, rest),
                None => (first, ""),
            };
            let values: Vec<&str> = std::iter::once(rest_of_first)
                .filter(|s| !s.is_empty())
                .chain(tokens)
                .collect();
            let (field, expected): (&'static str, usize) = match key {
                "P0" => ("P0", 12),
                "P1" => ("P1", 12),
                "P2" => ("P2", 12),
                "P3" => ("P3", 12),
                "R_rect" | "R0_rect" => ("R_rect", 9),
                "Tr_velo_cam" | "Tr_velo_to_cam" => ("Tr_velo_cam", 12),
                "Tr_imu_velo" | "Tr_imu_to_velo" => ("Tr_imu_velo", 12),
                other => return Err(ctx.line_error(format!("unknown calibration key `{other}`"))),
            };
            if values.len() != expected {
                return Err(ctx.column_count(&format!("{field} + {expected}"), values.len() + 1));
            }
            let numbers = values
                .iter()
                .enumerate()
                .map(|(i, tok)| ctx.f64(tok, i + 2, field))
                .collect::<Result<Vec<f64>>>()?;
            let duplicate = || ctx.line_error(format!("duplicate key `{field}`"));
            match field {
                "R_rect" => {
                    if r_rect.is_some() {
                        return Err(duplicate());
                    }
                    let m = Matrix3::from_row_slice(&numbers);
                    check_rotation(&m).map_err(|why| ctx.line_error(format!("{field}: {why}")))?;
                    r_rect = Some(m);
                }
                "Tr_velo_cam" | "Tr_imu_velo" => {
                    let slot = if field == "Tr_velo_cam" {
                        &mut t_cam_velo
                    } else {
                        &mut t_velo_imu
                    };
                    if slot.is_some() {
                        return Err(duplicate());
                    }
                    let m = Matrix3x4::from_row_slice(&numbers);
                    let iso = isometry_from_3x4(&m)
                        .map_err(|why| ctx.line_error(format!("{field}: {why}")))?;
                    *slot = Some(iso);
                }
                _ => {
                    let index = (field.as_bytes()[1] - b'0') as usize;
                    if p[index].is_some() {
                        return Err(duplicate());
                    }
                    p[index] = Some(Matrix3x4::from_row_slice(&numbers));
                }
            }
        }

        let missing = |key| KittiError::MissingKey {
            path: path.to_path_buf(),
            key,
        };
        Ok(Calib {
            p0: p[0].ok_or_else(|| missing("P0"))?,
            p1: p[1].ok_or_else(|| missing("P1"))?,
            p2: p[2].ok_or_else(|| missing("P2"))?,
            p3: p[3].ok_or_else(|| missing("P3"))?,
            r_rect: r_rect.ok_or_else(|| missing("R_rect"))?,
            t_cam_velo: t_cam_velo.ok_or_else(|| missing("Tr_velo_cam"))?,
            t_velo_imu: t_velo_imu.ok_or_else(|| missing("Tr_imu_velo"))?,
        })
    }

    /// Writes the calibration in the tracking spelling (`P0:`..`P3:`,
    /// `R_rect`, `Tr_velo_cam`, `Tr_imu_velo`), with shortest round-trip numbers.
    pub fn write(&self) -> String {
        let mut out = String::new();
        for (name, m) in [
            ("P0:", &self.p0),
            ("P1:", &self.p1),
            ("P2:", &self.p2),
            ("P3:", &self.p3),
        ] {
            write_row_major(&mut out, name, m.transpose().as_slice());
        }
        write_row_major(&mut out, "R_rect", self.r_rect.transpose().as_slice());
        write_row_major(
            &mut out,
            "Tr_velo_cam",
            isometry_to_3x4(&self.t_cam_velo).transpose().as_slice(),
        );
        write_row_major(
            &mut out,
            "Tr_imu_velo",
            isometry_to_3x4(&self.t_velo_imu).transpose().as_slice(),
        );
        out
    }

    /// Inverse of `R_rect` (exact matrix inverse; falls back to the transpose
    /// only for a hand-built singular matrix, which parsing rejects).
    fn r_rect_inverse(&self) -> Matrix3<f64> {
        self.r_rect
            .try_inverse()
            .unwrap_or_else(|| self.r_rect.transpose())
    }

    /// Velodyne-frame point → rectified camera-0 frame (`R_rect · Tr_velo_cam`).
    pub fn velo_to_rect(&self, p_velo: &Vector3<f64>) -> Vector3<f64> {
        self.r_rect * self.t_cam_velo.transform_point(&(*p_velo).into()).coords
    }

    /// Rectified camera-0 point → Velodyne frame (inverse of [`Calib::velo_to_rect`]).
    pub fn rect_to_velo(&self, p_rect: &Vector3<f64>) -> Vector3<f64> {
        let p_cam = self.r_rect_inverse() * p_rect;
        self.t_cam_velo
            .inverse_transform_point(&p_cam.into())
            .coords
    }

    /// IMU-frame point → Velodyne frame.
    pub fn imu_to_velo(&self, p_imu: &Vector3<f64>) -> Vector3<f64> {
        self.t_velo_imu.transform_point(&(*p_imu).into()).coords
    }

    /// Velodyne-frame point → IMU frame.
    pub fn velo_to_imu(&self, p_velo: &Vector3<f64>) -> Vector3<f64> {
        self.t_velo_imu
            .inverse_transform_point(&(*p_velo).into())
            .coords
    }

    /// Projects a rectified camera-0 point into the left colour image with P2
    /// (pixels); `None` when the point is not in front of the camera.
    pub fn project_rect_to_image(&self, p_rect: &Vector3<f64>) -> Option<Point2<f64>> {
        let h = self.p2 * p_rect.push(1.0);
        (h.z > 1e-6).then(|| Point2::new(h.x / h.z, h.y / h.z))
    }

    /// Projects a Velodyne-frame point into the left colour image.
    pub fn project_velo_to_image(&self, p_velo: &Vector3<f64>) -> Option<Point2<f64>> {
        self.project_rect_to_image(&self.velo_to_rect(p_velo))
    }
}

/// Accepts a matrix close to a proper rotation (`RᵀR ≈ I`, det > 0).
fn check_rotation(m: &Matrix3<f64>) -> std::result::Result<(), String> {
    let deviation = (m.transpose() * m - Matrix3::identity()).abs().max();
    if deviation > ROTATION_TOLERANCE {
        return Err(format!(
            "rotation part is not orthonormal (|RᵀR - I| = {deviation:.3e})"
        ));
    }
    if m.determinant() <= 0.0 {
        return Err("rotation part has a non-positive determinant".to_string());
    }
    Ok(())
}

/// `[R | t]` (3x4) → isometry, with R projected onto the nearest rotation.
pub(crate) fn isometry_from_3x4(m: &Matrix3x4<f64>) -> std::result::Result<Isometry3<f64>, String> {
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    check_rotation(&r)?;
    // Shepperd's quaternion of the raw matrix, renormalised, is a proper
    // rotation close to the answer; Müller's iteration then finds the nearest one.
    let raw = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let guess = UnitQuaternion::new_normalize(*raw.quaternion()).to_rotation_matrix();
    let rotation = Rotation3::from_matrix_eps(&r, 1e-15, 100, guess);
    // Renormalise: the quaternion of a rotation matrix is only unit to rounding.
    let rotation = UnitQuaternion::new_normalize(
        *UnitQuaternion::from_rotation_matrix(&rotation).quaternion(),
    );
    let t = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
    Ok(Isometry3::from_parts(Translation3::from(t), rotation))
}

/// Isometry → `[R | t]` (3x4).
pub(crate) fn isometry_to_3x4(iso: &Isometry3<f64>) -> Matrix3x4<f64> {
    iso.to_homogeneous().fixed_view::<3, 4>(0, 0).into_owned()
}

fn write_row_major(out: &mut String, name: &str, values: &[f64]) {
    out.push_str(name);
    for v in values {
        let _ = write!(out, " {v:e}");
    }
    out.push('\n');
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) const SAMPLE: &str = "\
P0: 7.215377000000e+02 0.000000000000e+00 6.095593000000e+02 0.000000000000e+00 0.000000000000e+00 7.215377000000e+02 1.728540000000e+02 0.000000000000e+00 0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00
P1: 7.215377000000e+02 0.000000000000e+00 6.095593000000e+02 -3.875744000000e+02 0.000000000000e+00 7.215377000000e+02 1.728540000000e+02 0.000000000000e+00 0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00
P2: 7.215377000000e+02 0.000000000000e+00 6.095593000000e+02 4.485728000000e+01 0.000000000000e+00 7.215377000000e+02 1.728540000000e+02 2.163791000000e-01 0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 2.745884000000e-03
P3: 7.215377000000e+02 0.000000000000e+00 6.095593000000e+02 -3.395242000000e+02 0.000000000000e+00 7.215377000000e+02 1.728540000000e+02 2.199936000000e+00 0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 2.729905000000e-03
R_rect 9.999239000000e-01 9.837760000000e-03 -7.445048000000e-03 -9.869795000000e-03 9.999421000000e-01 -4.278459000000e-03 7.402527000000e-03 4.351614000000e-03 9.999631000000e-01
Tr_velo_cam 7.533745000000e-03 -9.999714000000e-01 -6.166020000000e-04 -4.069766000000e-03 1.480249000000e-02 7.280733000000e-04 -9.998902000000e-01 -7.631618000000e-02 9.998621000000e-01 7.523790000000e-03 1.480755000000e-02 -2.717806000000e-01
Tr_imu_velo 9.999976000000e-01 7.553071000000e-04 -2.035826000000e-03 -8.086759000000e-01 -7.854027000000e-04 9.998898000000e-01 -1.482298000000e-02 3.195559000000e-01 2.024406000000e-03 1.482454000000e-02 9.998881000000e-01 -7.997231000000e-01
";

    pub(crate) fn sample() -> Calib {
        Calib::parse(SAMPLE, Path::new("calib.txt")).unwrap()
    }

    #[test]
    fn parses_tracking_spelling() {
        let calib = sample();
        assert_eq!(calib.p2[(0, 0)], 721.5377);
        assert_eq!(calib.p2[(0, 3)], 44.85728);
        assert_eq!(calib.r_rect[(0, 1)], 9.837760e-3);
        // Tr_velo_cam maps the Velodyne x axis (forward) onto camera +z.
        let fwd = calib.t_cam_velo.transform_vector(&Vector3::x());
        assert!((fwd - Vector3::z()).norm() < 0.02, "{fwd}");
        assert!((calib.t_cam_velo.translation.vector.z - -0.2717806).abs() < 1e-12);
        assert!((calib.t_velo_imu.translation.vector.x - -0.8086759).abs() < 1e-12);
        // Re-orthonormalisation changes the stored rotation by ~1e-7 only.
        let m = isometry_to_3x4(&calib.t_cam_velo);
        assert!((m[(0, 1)] - -0.9999714).abs() < 1e-6);
    }

    #[test]
    fn object_spelling_parses_to_the_same_calibration() {
        let object_spelling = SAMPLE
            .replace("R_rect", "R0_rect:")
            .replace("Tr_velo_cam", "Tr_velo_to_cam:")
            .replace("Tr_imu_velo", "Tr_imu_to_velo:")
            .replace("P1:", "P1");
        let calib = Calib::parse(&object_spelling, Path::new("c.txt")).unwrap();
        assert_eq!(calib, sample());
    }

    #[test]
    fn write_round_trips() {
        let calib = sample();
        let text = calib.write();
        assert!(text.starts_with("P0: "));
        assert!(text.contains("\nR_rect ") && text.contains("\nTr_velo_cam "));
        let again = Calib::parse(&text, Path::new("w.txt")).unwrap();
        assert_eq!(again.p2, calib.p2);
        assert_eq!(again.r_rect, calib.r_rect);
        let d = again.t_cam_velo.inverse() * calib.t_cam_velo;
        assert!(
            d.translation.vector.norm() < 1e-12 && d.rotation.angle() < 1e-12,
            "{d}"
        );
        let d = again.t_velo_imu.inverse() * calib.t_velo_imu;
        assert!(
            d.translation.vector.norm() < 1e-12 && d.rotation.angle() < 1e-12,
            "{d}"
        );
    }

    #[test]
    fn velo_rect_transform_round_trips_and_projects_forward_points() {
        let calib = sample();
        let p_velo = Vector3::new(12.0, -3.0, 0.5);
        let p_rect = calib.velo_to_rect(&p_velo);
        assert!(p_rect.z > 11.0, "forward is +z in the camera: {p_rect}");
        let back = calib.rect_to_velo(&p_rect);
        assert!((back - p_velo).norm() < 1e-12, "{back} {p_velo}");
        let px = calib.project_velo_to_image(&p_velo).unwrap();
        // A point right of the car (y < 0) lands right of the principal point.
        assert!(px.x > 609.0 && px.x < 1242.0, "{px}");
        assert!(
            calib
                .project_velo_to_image(&Vector3::new(-5.0, 0.0, 0.0))
                .is_none()
        );
        let p_imu = Vector3::new(1.0, 2.0, 3.0);
        assert!((calib.velo_to_imu(&calib.imu_to_velo(&p_imu)) - p_imu).norm() < 1e-12);
    }

    #[test]
    fn errors_name_file_line_and_field() {
        let path = Path::new("bad_calib.txt");
        let nan = SAMPLE.replace("9.999421000000e-01", "nan");
        let err = Calib::parse(&nan, path).unwrap_err().to_string();
        assert!(
            err.contains("bad_calib.txt:5") && err.contains("R_rect"),
            "{err}"
        );

        let short = SAMPLE.replace(" 2.745884000000e-03", "");
        let err = Calib::parse(&short, path).unwrap_err().to_string();
        assert!(
            err.contains("bad_calib.txt:3") && err.contains("columns"),
            "{err}"
        );

        let missing: String = SAMPLE
            .lines()
            .filter(|l| !l.starts_with("P3"))
            .collect::<Vec<_>>()
            .join("\n");
        let err = Calib::parse(&missing, path).unwrap_err().to_string();
        assert!(err.contains("bad_calib.txt") && err.contains("P3"), "{err}");

        let unknown = format!("{SAMPLE}foo 1 2 3\n");
        let err = Calib::parse(&unknown, path).unwrap_err().to_string();
        assert!(
            err.contains("bad_calib.txt:8") && err.contains("foo"),
            "{err}"
        );

        let skew = SAMPLE.replace("9.999976000000e-01", "1.5");
        let err = Calib::parse(&skew, path).unwrap_err().to_string();
        assert!(
            err.contains("bad_calib.txt:7") && err.contains("orthonormal"),
            "{err}"
        );

        let dup = format!("{SAMPLE}{}\n", SAMPLE.lines().next().unwrap());
        let err = Calib::parse(&dup, path).unwrap_err().to_string();
        assert!(err.contains("duplicate"), "{err}");
    }
}
