//! Umeyama alignment (Umeyama 1991; Zhang & Scaramuzza 2018, eq. 4-7): the
//! similarity / rigid transform that best maps one point set onto another in
//! the least-squares sense, as evo's `--align` / `--correct_scale`.

use super::{EvalError, check_finite};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// `p_dst ≈ scale · rotation · p_src + translation`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Alignment {
    /// Rotation applied to the source points.
    pub rotation: Rotation3<f64>,
    /// Translation added after rotating and scaling.
    pub translation: Vector3<f64>,
    /// 1 unless scale estimation was requested.
    pub scale: f64,
    /// True when the source points are (nearly) collinear: the cross-covariance
    /// has rank < 2, so the rotation about the line is not determined by the
    /// positions (the SVD picks one of the equally good rotations).
    pub degenerate: bool,
}

impl Alignment {
    /// The identity alignment (scale 1).
    pub fn identity() -> Alignment {
        Alignment {
            rotation: Rotation3::identity(),
            translation: Vector3::zeros(),
            scale: 1.0,
            degenerate: false,
        }
    }

    /// Maps a source point: `s · R · p + t`.
    pub fn transform_point(&self, p_src: &Vector3<f64>) -> Vector3<f64> {
        self.scale * (self.rotation * p_src) + self.translation
    }

    /// Applies the alignment to a pose: `T' = [sR t; 0 1] · T`, with the scale
    /// acting on the translation only (rotations stay orthonormal, as in evo).
    pub fn transform_pose(&self, pose: &Isometry3<f64>) -> Isometry3<f64> {
        let rotation = UnitQuaternion::from_rotation_matrix(&self.rotation) * pose.rotation;
        let translation = self.transform_point(&pose.translation.vector);
        Isometry3::from_parts(Translation3::from(translation), rotation)
    }

    /// The rigid part (scale dropped).
    pub fn isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.translation),
            UnitQuaternion::from_rotation_matrix(&self.rotation),
        )
    }
}

/// Least-squares alignment of `src` onto `dst` (point `i` corresponds to point `i`).
///
/// With `with_scale = false` this is the SE(3) alignment evo uses for ATE;
/// with `true` the Sim(3) one (monocular convention). Needs at least two
/// points; with scale, the source points must not all coincide.
///
/// # Errors
///
/// [`EvalError`] for empty or unequal-length inputs or non-finite points.
pub fn umeyama(
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
    with_scale: bool,
) -> Result<Alignment, EvalError> {
    const WHAT: &str = "umeyama";
    if src.len() != dst.len() {
        return Err(EvalError::LengthMismatch {
            what: WHAT,
            left: src.len(),
            right: dst.len(),
        });
    }
    if src.len() < 2 {
        return Err(EvalError::TooFew {
            what: WHAT,
            got: src.len(),
            need: 2,
        });
    }
    for (i, (s, d)) in src.iter().zip(dst).enumerate() {
        check_finite(WHAT, i, "src", s.as_slice())?;
        check_finite(WHAT, i, "dst", d.as_slice())?;
    }
    let n = src.len() as f64;
    let mean_src = src.iter().sum::<Vector3<f64>>() / n;
    let mean_dst = dst.iter().sum::<Vector3<f64>>() / n;
    let mut sigma_src_sq = 0.0;
    let mut cov = Matrix3::zeros();
    for (s, d) in src.iter().zip(dst) {
        let ds = s - mean_src;
        let dd = d - mean_dst;
        sigma_src_sq += ds.norm_squared();
        cov += dd * ds.transpose();
    }
    sigma_src_sq /= n;
    cov /= n;

    let svd = cov.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(EvalError::BadParameter {
            what: WHAT,
            why: "SVD of the cross-covariance did not converge".into(),
        });
    };
    let d = svd.singular_values; // sorted descending by nalgebra
    // Reflection guard: flip the axis of the smallest singular value when
    // U·Vᵀ would be a reflection.
    let mut s = Vector3::new(1.0, 1.0, 1.0);
    if (u * v_t).determinant() < 0.0 {
        s.z = -1.0;
    }
    let r = u * Matrix3::from_diagonal(&s) * v_t;
    let rotation = Rotation3::from_matrix_unchecked(r);

    let spread = d.x.max(f64::MIN_POSITIVE);
    let degenerate = d.y <= 1e-12 * spread;

    let scale = if with_scale {
        if sigma_src_sq <= f64::MIN_POSITIVE {
            return Err(EvalError::BadParameter {
                what: WHAT,
                why: "all source points coincide, scale is undefined".into(),
            });
        }
        d.dot(&s) / sigma_src_sq
    } else {
        1.0
    };
    let translation = mean_dst - scale * (rotation * mean_src);
    Ok(Alignment {
        rotation,
        translation,
        scale,
        degenerate,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cloud() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.2, -0.3),
            Vector3::new(2.5, -1.0, 0.4),
            Vector3::new(-0.7, 3.0, 1.1),
            Vector3::new(4.0, 2.0, -2.0),
        ]
    }

    #[test]
    fn recovers_known_similarity() {
        let rotation = Rotation3::from_euler_angles(0.3, -0.5, 2.0);
        let translation = Vector3::new(5.0, -2.0, 1.5);
        let scale = 1.7;
        let src = cloud();
        let dst: Vec<_> = src
            .iter()
            .map(|p| scale * (rotation * p) + translation)
            .collect();
        let a = umeyama(&src, &dst, true).unwrap();
        assert!((a.scale - scale).abs() < 1e-12);
        assert!((a.rotation.matrix() - rotation.matrix()).norm() < 1e-12);
        assert!((a.translation - translation).norm() < 1e-12);
        assert!(!a.degenerate);
        let rigid = umeyama(&src, &dst[..], false).unwrap();
        assert_eq!(rigid.scale, 1.0);
        assert!((rigid.rotation.matrix() - rotation.matrix()).norm() < 1e-12);
    }

    #[test]
    fn never_returns_a_reflection() {
        // dst is a mirror image of src: the best proper rotation is still a rotation.
        let src = cloud();
        let dst: Vec<_> = src.iter().map(|p| Vector3::new(p.x, p.y, -p.z)).collect();
        let a = umeyama(&src, &dst, false).unwrap();
        assert!((a.rotation.matrix().determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn collinear_points_are_flagged() {
        let src: Vec<_> = (0..5).map(|i| Vector3::new(i as f64, 0.0, 0.0)).collect();
        let a = umeyama(&src, &src, false).unwrap();
        assert!(a.degenerate);
        for p in &src {
            assert!((a.transform_point(p) - p).norm() < 1e-12);
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let src = cloud();
        assert!(matches!(
            umeyama(&src, &src[..3], false),
            Err(EvalError::LengthMismatch { .. })
        ));
        assert!(matches!(
            umeyama(&src[..1], &src[..1], false),
            Err(EvalError::TooFew { .. })
        ));
        let mut bad = src.clone();
        bad[2].y = f64::NAN;
        assert!(matches!(
            umeyama(&src, &bad, false),
            Err(EvalError::NotFinite { index: 2, .. })
        ));
        let same = vec![Vector3::new(1.0, 1.0, 1.0); 3];
        assert!(umeyama(&same, &src[..3], true).is_err());
    }
}
