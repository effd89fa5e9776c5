//! Pose files: TUM (`t x y z qx qy qz qw`) and KITTI odometry (12 numbers,
//! the top 3x4 of the 4x4 pose, row-major).

use super::calib::{isometry_from_3x4, isometry_to_3x4};
use super::{LineCtx, Result, content_lines, read_text};
use nalgebra::{Isometry3, Matrix3x4, Quaternion, Translation3, UnitQuaternion};
use std::fmt::Write as _;
use std::path::Path;

/// A pose at a time (TUM files carry timestamps).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StampedPose {
    /// Time (s).
    pub t_s: f64,
    /// The pose (maps points of the body frame into the world).
    pub pose: Isometry3<f64>,
}

/// Parses a times file (KITTI `times.txt`: one time in seconds per line, the
/// first column is used). Times must be finite and non-decreasing.
///
/// # Errors
/// A malformed or non-finite time, or time going backwards (file and line).
pub fn parse_times(text: &str, path: &Path) -> Result<Vec<f64>> {
    let mut times: Vec<f64> = Vec::new();
    for (line_no, line) in content_lines(text) {
        let ctx = LineCtx::new(path, line_no);
        let token = line.split_whitespace().next().unwrap_or_default();
        let t_s = ctx.f64(token, 1, "t")?;
        if let Some(&prev) = times.last()
            && t_s < prev
        {
            return Err(ctx.field_error(
                1,
                "t",
                format!("{t_s} is before the previous time {prev}"),
            ));
        }
        times.push(t_s);
    }
    Ok(times)
}

/// Reads a times file (see [`parse_times`]).
///
/// # Errors
/// An unreadable file, or a malformed time (see [`parse_times`]).
pub fn read_times(path: &Path) -> Result<Vec<f64>> {
    parse_times(&read_text(path)?, path)
}

/// Formats poses as a TUM trajectory (shortest round-trip numbers).
pub fn write_tum(poses: &[StampedPose]) -> String {
    let mut out = String::new();
    for p in poses {
        let t = p.pose.translation.vector;
        let q = p.pose.rotation.quaternion();
        let _ = writeln!(
            out,
            "{} {} {} {} {} {} {} {}",
            p.t_s, t.x, t.y, t.z, q.i, q.j, q.k, q.w
        );
    }
    out
}

const TUM_FIELDS: [&str; 8] = ["t", "x", "y", "z", "qx", "qy", "qz", "qw"];

/// Parses a TUM trajectory; `#` comment lines are skipped. The quaternion
/// must have a norm within 1e-3 of 1 (it is then normalised).
///
/// # Errors
/// A line without 8 columns, a malformed field or a non-unit quaternion (file, line and column).
pub fn parse_tum(text: &str, path: &Path) -> Result<Vec<StampedPose>> {
    content_lines(text)
        .filter(|(_, l)| !l.trim_start().starts_with('#'))
        .map(|(line_no, line)| {
            let ctx = LineCtx::new(path, line_no);
            let tokens: Vec<&str> = line.split_whitespace().collect();
            if tokens.len() != 8 {
                return Err(ctx.column_count("8", tokens.len()));
            }
            let mut v = [0.0; 8];
            for (i, value) in v.iter_mut().enumerate() {
                *value = ctx.f64(tokens[i], i + 1, TUM_FIELDS[i])?;
            }
            let q = Quaternion::new(v[7], v[4], v[5], v[6]);
            let norm = q.norm();
            if (norm - 1.0).abs() > 1e-3 {
                return Err(ctx.field_error(5, "qx", format!("quaternion norm {norm} is not 1")));
            }
            Ok(StampedPose {
                t_s: v[0],
                pose: Isometry3::from_parts(
                    Translation3::new(v[1], v[2], v[3]),
                    UnitQuaternion::new_normalize(q),
                ),
            })
        })
        .collect()
}

/// Formats poses as a KITTI pose file (one 3x4 row-major matrix a line).
pub fn write_kitti_poses(poses: &[Isometry3<f64>]) -> String {
    let mut out = String::new();
    for pose in poses {
        let m = isometry_to_3x4(pose);
        let row_major = m.transpose();
        let line: Vec<String> = row_major.iter().map(|v| format!("{v:e}")).collect();
        out.push_str(&line.join(" "));
        out.push('\n');
    }
    out
}

/// Parses a KITTI pose file; the rotation must be orthonormal to 1e-3 (it is
/// projected onto the nearest rotation).
///
/// # Errors
/// A line without 12 columns, a malformed field or a non-rotation matrix (file, line and column).
pub fn parse_kitti_poses(text: &str, path: &Path) -> Result<Vec<Isometry3<f64>>> {
    content_lines(text)
        .map(|(line_no, line)| {
            let ctx = LineCtx::new(path, line_no);
            let tokens: Vec<&str> = line.split_whitespace().collect();
            if tokens.len() != 12 {
                return Err(ctx.column_count("12", tokens.len()));
            }
            let mut v = [0.0; 12];
            for (i, value) in v.iter_mut().enumerate() {
                *value = ctx.f64(tokens[i], i + 1, "pose")?;
            }
            isometry_from_3x4(&Matrix3x4::from_row_slice(&v)).map_err(|why| ctx.line_error(why))
        })
        .collect()
}

/// Reads a TUM trajectory file.
///
/// # Errors
/// An unreadable file, or a malformed line (see [`parse_tum`]).
pub fn read_tum(path: &Path) -> Result<Vec<StampedPose>> {
    parse_tum(&read_text(path)?, path)
}

/// Reads a KITTI pose file.
///
/// # Errors
/// An unreadable file, or a malformed line (see [`parse_kitti_poses`]).
pub fn read_kitti_poses(path: &Path) -> Result<Vec<Isometry3<f64>>> {
    parse_kitti_poses(&read_text(path)?, path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn times_parse_and_errors_name_the_line() {
        let path = Path::new("times.txt");
        let t = parse_times("0.000000e+00\n1.000000e-01\n\n2.0e-01 extra\n", path).unwrap();
        assert_eq!(t, vec![0.0, 0.1, 0.2]);
        let err = parse_times("0\n0.1\nabc\n", path).unwrap_err().to_string();
        assert!(err.contains("times.txt:3"), "{err}");
        let err = parse_times("0\n0.2\n0.1\n", path).unwrap_err().to_string();
        assert!(
            err.contains("times.txt:3") && err.contains("before"),
            "{err}"
        );
    }

    fn poses() -> Vec<Isometry3<f64>> {
        (0..5)
            .map(|i| {
                let f = i as f64;
                Isometry3::new(
                    Vector3::new(f * 1.5, -0.2 * f, 0.01 * f * f),
                    Vector3::new(0.01 * f, -0.02 * f, 0.7 * f),
                )
            })
            .collect()
    }

    fn close(a: &Isometry3<f64>, b: &Isometry3<f64>) -> bool {
        let d = a.inverse() * b;
        d.translation.vector.norm() < 1e-12 && d.rotation.angle() < 1e-12
    }

    #[test]
    fn tum_round_trips() {
        let stamped: Vec<StampedPose> = poses()
            .into_iter()
            .enumerate()
            .map(|(i, pose)| StampedPose {
                t_s: 0.1 * i as f64,
                pose,
            })
            .collect();
        let text = format!("# timestamp tx ty tz qx qy qz qw\n{}", write_tum(&stamped));
        let back = parse_tum(&text, Path::new("t.txt")).unwrap();
        assert_eq!(back.len(), stamped.len());
        for (a, b) in stamped.iter().zip(&back) {
            assert_eq!(a.t_s, b.t_s);
            assert!(close(&a.pose, &b.pose));
        }
    }

    #[test]
    fn kitti_round_trips_and_is_row_major() {
        let p = poses();
        let text = write_kitti_poses(&p);
        let back = parse_kitti_poses(&text, Path::new("k.txt")).unwrap();
        for (a, b) in p.iter().zip(&back) {
            assert!(close(a, b));
        }
        // Fourth number of a line is the x translation.
        let line = text.lines().nth(2).unwrap();
        let tx: f64 = line.split_whitespace().nth(3).unwrap().parse().unwrap();
        assert_eq!(tx, 3.0);
    }

    #[test]
    fn errors_name_file_and_line() {
        let path = Path::new("traj.txt");
        let err = parse_tum("0 1 2 3 0 0 0 1\n1 1 2 nan 0 0 0 1\n", path)
            .unwrap_err()
            .to_string();
        assert!(err.contains("traj.txt:2") && err.contains("`z`"), "{err}");
        let err = parse_tum("0 1 2 3 0 0 0 2\n", path)
            .unwrap_err()
            .to_string();
        assert!(err.contains("traj.txt:1") && err.contains("norm"), "{err}");
        let err = parse_kitti_poses("1 0 0 0 0 1 0 0 0 0 1\n", path)
            .unwrap_err()
            .to_string();
        assert!(err.contains("traj.txt:1") && err.contains("12"), "{err}");
        let err = parse_kitti_poses("2 0 0 0 0 1 0 0 0 0 1 0\n", path)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("traj.txt:1") && err.contains("orthonormal"),
            "{err}"
        );
    }
}
