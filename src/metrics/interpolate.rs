//! A pose between timestamped samples: linear in translation, slerp in
//! rotation, exact at a sample (evo's and GTSAM's convention for resampling a
//! trajectory).

use nalgebra::{Isometry3, Translation3};

/// The pose at `t_s` from samples sorted by time (`sample` reads a sample's
/// time and pose); `None` outside the samples' time span.
pub fn pose_at<T>(
    samples: &[T],
    t_s: f64,
    sample: impl Fn(&T) -> (f64, Isometry3<f64>),
) -> Option<Isometry3<f64>> {
    let k = samples.partition_point(|s| sample(s).0 < t_s);
    if let Some((t, pose)) = samples.get(k).map(&sample)
        && t == t_s
    {
        return Some(pose);
    }
    if k == 0 || k == samples.len() {
        return None;
    }
    let ((ta, a), (tb, b)) = (sample(&samples[k - 1]), sample(&samples[k]));
    let s = (t_s - ta) / (tb - ta);
    let (pa, pb) = (a.translation.vector, b.translation.vector);
    let rotation = a
        .rotation
        .try_slerp(&b.rotation, s, 1e-12)
        .unwrap_or(a.rotation);
    Some(Isometry3::from_parts(
        Translation3::from(pa + (pb - pa) * s),
        rotation,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn exact_at_samples_linear_between_none_outside() {
        let samples = [
            (0.0, Isometry3::new(Vector3::zeros(), Vector3::zeros())),
            (
                1.0,
                Isometry3::new(Vector3::new(2.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.4)),
            ),
        ];
        let read = |s: &(f64, Isometry3<f64>)| *s;
        let mid = pose_at(&samples, 0.25, read).unwrap();
        assert!((mid.translation.vector.x - 0.5).abs() < 1e-12);
        assert!((mid.rotation.angle() - 0.1).abs() < 1e-12);
        assert_eq!(pose_at(&samples, 1.0, read), Some(samples[1].1));
        assert_eq!(pose_at(&samples, -0.1, read), None);
        assert_eq!(pose_at(&samples, 1.5, read), None);
    }
}
