//! An ego estimate's per-pose error as plot data: translation and rotation
//! error over time, and the aligned top-view path carrying its translation
//! error (to colour it), so a centimetre error shows on a 250 m drive.

use super::plot::{ColouredPath, Series2D};
use crate::metrics::AteResult;
use nalgebra::Isometry3;
use std::collections::HashMap;

/// The plot series of one estimate's error.
#[derive(Debug, Clone, PartialEq)]
pub struct EgoErrorSeries {
    /// (t_s, translation error m).
    pub translation_m: Series2D,
    /// (t_s, rotation error deg).
    pub rotation_deg: Series2D,
    /// The aligned path, (x_m, y_m, translation error m) per pose.
    pub path: ColouredPath,
}

/// The series of `label`'s estimate `est` (timestamped `t_world_lidar`, the
/// poses `ate` was computed from) from its ATE's per-pose errors: the path is
/// the estimate moved by the ATE's alignment; poses the ATE did not
/// associate with the truth are left out.
pub fn ego_error_series(
    label: &str,
    est: &[(f64, Isometry3<f64>)],
    ate: &AteResult,
) -> EgoErrorSeries {
    let by_time: HashMap<u64, &Isometry3<f64>> =
        est.iter().map(|(t, pose)| (t.to_bits(), pose)).collect();
    let path = ate
        .per_pose
        .iter()
        .filter_map(|&(t, e_t, _)| {
            let p = ate.alignment.transform_pose(by_time.get(&t.to_bits())?);
            Some((p.translation.vector.x, p.translation.vector.y, e_t))
        })
        .collect();
    EgoErrorSeries {
        translation_m: Series2D::line(
            label,
            ate.per_pose.iter().map(|&(t, e_t, _)| (t, e_t)).collect(),
        ),
        rotation_deg: Series2D::line(
            label,
            ate.per_pose
                .iter()
                .map(|&(t, _, e_r)| (t, e_r.to_degrees()))
                .collect(),
        ),
        path: ColouredPath {
            label: label.to_string(),
            points: path,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::{AlignMode, ate_with};
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    /// Four poses 1 m apart along x; the estimate is off by 0, 0.1, 0.2 and
    /// 0.3 m in y and 0, 1, 2, 3 deg of yaw.
    #[test]
    fn per_pose_errors_in_metres_and_degrees_along_the_path() {
        let truth: Vec<(f64, Isometry3<f64>)> = (0..4)
            .map(|k| {
                let t = 0.1 * k as f64;
                (t, Isometry3::translation(k as f64, 0.0, 0.0))
            })
            .collect();
        let est: Vec<(f64, Isometry3<f64>)> = (0..4)
            .map(|k| {
                let t = 0.1 * k as f64;
                let pose = Isometry3::from_parts(
                    Translation3::new(k as f64, 0.1 * k as f64, 0.0),
                    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), (k as f64).to_radians()),
                );
                (t, pose)
            })
            .collect();
        let ate = ate_with(&est, &truth, 0.01, AlignMode::None).unwrap();
        let s = ego_error_series("lio", &est, &ate);
        assert_eq!(s.translation_m.label, "lio");
        for k in 0..4 {
            let (t, e_t) = s.translation_m.points[k];
            let (t_r, e_r) = s.rotation_deg.points[k];
            assert!((t - 0.1 * k as f64).abs() < 1e-12 && t_r == t);
            assert!((e_t - 0.1 * k as f64).abs() < 1e-9, "{k}: {e_t} m");
            assert!((e_r - k as f64).abs() < 1e-9, "{k}: {e_r} deg");
            let (x, y, v) = s.path.points[k];
            assert!((x - k as f64).abs() < 1e-12 && (y - 0.1 * k as f64).abs() < 1e-12);
            assert_eq!(v, e_t);
        }
        // an estimate pose without a truth pose near it is left out
        let mut longer = est.clone();
        longer.push((5.0, Isometry3::identity()));
        let ate = ate_with(&longer, &truth, 0.01, AlignMode::None).unwrap();
        let s = ego_error_series("lio", &longer, &ate);
        assert_eq!(s.path.points.len(), 4);
        assert_eq!(s.translation_m.points.len(), 4);
    }
}
