//! Closed-form eigen-decomposition of a symmetric 3×3 matrix.
//!
//! Scan matching fits a line or a plane to five map points for every
//! feature point and iteration, i.e. hundreds of thousands of 3×3
//! decompositions per sweep; nalgebra's general iterative solver is several
//! times slower than the closed form for this size. The method is Eigen's
//! `SelfAdjointEigenSolver::computeDirect`: the eigenvalues are the roots of
//! the characteristic cubic (trigonometric form, on the matrix shifted by
//! its mean eigenvalue and scaled to [-1, 1]), each eigenvector the cross
//! product of two rows of `A − λI`. Eigenvalues and eigenvector residuals
//! are accurate to ~1e-15 of the matrix norm when the eigenvalues are well
//! apart and to ~√ε ≈ 1e-8 of it for a (nearly) repeated pair, whose
//! eigenvectors are then any orthonormal basis of their plane; a line or
//! plane fit reads only well-separated ones.

use nalgebra::{Matrix3, Vector3};

/// Eigenvalues in ascending order and the unit eigenvectors as the matching
/// columns (a right-handed orthonormal basis) of the symmetric matrix `m`
/// (only its lower triangle is read). Non-finite input gives non-finite
/// output, never a panic.
///
/// ```
/// use limot_estimator::eigen3::symmetric_eigen3;
/// use nalgebra::{Matrix3, Vector3};
///
/// let m = Matrix3::new(2.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 5.0);
/// let (values, vectors) = symmetric_eigen3(&m);
/// assert!((values - Vector3::new(1.0, 3.0, 5.0)).norm() < 1e-12);
/// for k in 0..3 {
///     let v = vectors.column(k);
///     assert!((m * v - v * values[k]).norm() < 1e-12);
/// }
/// ```
pub fn symmetric_eigen3(m: &Matrix3<f64>) -> (Vector3<f64>, Matrix3<f64>) {
    let parts = Decomposition::of(m);
    let mut vectors = Matrix3::identity();
    if let Some(extreme) = parts.most_distinct() {
        let (k, l) = (extreme.index, 2 - extreme.index);
        let v_k = extreme.vector;
        let v_l = parts.other_extreme(&extreme);
        vectors.set_column(k, &v_k);
        vectors.set_column(l, &v_l);
        let v_mid = vectors.column(2).cross(&vectors.column(0)).normalize();
        vectors.set_column(1, &v_mid);
    }
    (parts.values(), vectors)
}

/// The eigenvector of an extreme eigenvalue.
struct Extreme {
    /// 0 (smallest eigenvalue) or 2 (largest).
    index: usize,
    /// Unit eigenvector.
    vector: Vector3<f64>,
    /// A row of the shifted matrix whose kernel `vector` spans (orthogonal
    /// to it).
    row: Vector3<f64>,
}

/// The eigenvalues of a symmetric 3×3 matrix, with what it takes to find an
/// extreme eigenvector on demand: [`symmetric_eigen3`]'s results, bit for
/// bit, without computing the vectors a caller does not read (a line fit
/// that its eigenvalues reject reads none, a plane fit only the normal).
///
/// ```
/// use limot_estimator::eigen3::{Decomposition, symmetric_eigen3};
/// use nalgebra::Matrix3;
///
/// let m = Matrix3::new(2.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 5.0);
/// let (values, vectors) = symmetric_eigen3(&m);
/// let d = Decomposition::of(&m);
/// assert_eq!(d.values(), values);
/// assert_eq!(d.extreme_vector(false), vectors.column(0).into_owned());
/// assert_eq!(d.extreme_vector(true), vectors.column(2).into_owned());
/// ```
pub struct Decomposition {
    /// The matrix shifted by its mean eigenvalue and scaled to [-1, 1].
    scaled: Matrix3<f64>,
    /// Eigenvalues of `scaled`, ascending.
    values: Vector3<f64>,
    shift: f64,
    scale: f64,
}

impl Decomposition {
    /// The eigenvalues of the symmetric `m` (only its lower triangle is
    /// read).
    pub fn of(m: &Matrix3<f64>) -> Self {
        let mut sym = *m;
        sym.fill_upper_triangle_with_lower_triangle();
        let shift = sym.trace() / 3.0;
        let scaled = sym - Matrix3::identity() * shift;
        let scale = match scaled.amax() {
            s if s > 0.0 => s,
            _ => 1.0,
        };
        let scaled = scaled / scale;
        let values = cubic_roots(&scaled);
        Self {
            scaled,
            values,
            shift,
            scale,
        }
    }

    /// The input's eigenvalues, ascending.
    pub fn values(&self) -> Vector3<f64> {
        self.values * self.scale + Vector3::repeat(self.shift)
    }

    /// The unit eigenvector of the smallest eigenvalue or, with `largest`,
    /// of the largest: [`symmetric_eigen3`]'s column 0 or 2.
    pub fn extreme_vector(&self, largest: bool) -> Vector3<f64> {
        let column = if largest { 2 } else { 0 };
        match self.most_distinct() {
            Some(extreme) if extreme.index == column => extreme.vector,
            Some(extreme) => self.other_extreme(&extreme),
            None => Matrix3::identity().column(column).into_owned(),
        }
    }

    /// The index (0 or 2) and unit eigenvector of the extreme eigenvalue
    /// farther from the middle one; `None` when all three are equal (or the
    /// input is not finite), where any basis is an eigenbasis.
    fn most_distinct(&self) -> Option<Extreme> {
        let values = &self.values;
        if values[2] - values[0] <= f64::EPSILON {
            return None;
        }
        let (d0, d1) = (values[2] - values[1], values[1] - values[0]);
        let index = if d0 > d1 { 2 } else { 0 };
        let (vector, row) = kernel(&(self.scaled - Matrix3::identity() * values[index]));
        Some(Extreme { index, vector, row })
    }

    /// The unit eigenvector of the other extreme eigenvalue, orthogonal to
    /// the one [`Decomposition::most_distinct`] found.
    fn other_extreme(&self, extreme: &Extreme) -> Vector3<f64> {
        let values = &self.values;
        let (k, v_k) = (extreme.index, &extreme.vector);
        let l = 2 - k;
        let (d0, d1) = (values[2] - values[1], values[1] - values[0]);
        let gap = if k == 2 { d1 } else { d0 };
        // The roots of a repeated pair carry √ε of error: below a
        // millionth of the larger gap the pair counts as repeated.
        let v_l = if gap <= 1e-6 * d0.max(d1) {
            // Any unit vector orthogonal to v_k in the pair's plane; the
            // saved row is orthogonal to v_k already.
            extreme.row
        } else {
            kernel(&(self.scaled - Matrix3::identity() * values[l])).0
        };
        (v_l - v_k * v_k.dot(&v_l)).normalize()
    }
}

/// The three real roots, ascending, of the characteristic polynomial of
/// the symmetric `m`.
fn cubic_roots(m: &Matrix3<f64>) -> Vector3<f64> {
    let (m00, m10, m20, m11, m21, m22) = (
        m[(0, 0)],
        m[(1, 0)],
        m[(2, 0)],
        m[(1, 1)],
        m[(2, 1)],
        m[(2, 2)],
    );
    // x³ − c2 x² + c1 x − c0 = 0
    let c0 = m00 * m11 * m22 + 2.0 * m10 * m20 * m21
        - m00 * m21 * m21
        - m11 * m20 * m20
        - m22 * m10 * m10;
    let c1 = m00 * m11 - m10 * m10 + m00 * m22 - m20 * m20 + m11 * m22 - m21 * m21;
    let c2 = m00 + m11 + m22;
    let c2_over_3 = c2 / 3.0;
    let a_over_3 = ((c2 * c2_over_3 - c1) / 3.0).max(0.0);
    let half_b = 0.5 * (c0 + c2_over_3 * (2.0 * c2_over_3 * c2_over_3 - c1));
    let q = (a_over_3 * a_over_3 * a_over_3 - half_b * half_b).max(0.0);
    let rho = a_over_3.sqrt();
    // θ in [0, π/3]: the roots come out sorted
    let theta = q.sqrt().atan2(half_b) / 3.0;
    let (sin_theta, cos_theta) = theta.sin_cos();
    let sqrt3 = 3f64.sqrt();
    Vector3::new(
        c2_over_3 - rho * (cos_theta + sqrt3 * sin_theta),
        c2_over_3 - rho * (cos_theta - sqrt3 * sin_theta),
        c2_over_3 + 2.0 * rho * cos_theta,
    )
}

/// A unit vector spanning the kernel of the rank-2 symmetric `a` (the
/// largest cross product of its row of largest diagonal with another row),
/// and that row (orthogonal to the kernel).
fn kernel(a: &Matrix3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let diagonal = Vector3::new(a[(0, 0)].abs(), a[(1, 1)].abs(), a[(2, 2)].abs());
    let i0 = diagonal.iamax();
    let representative: Vector3<f64> = a.column(i0).into_owned();
    let c0 = representative.cross(&a.column((i0 + 1) % 3));
    let c1 = representative.cross(&a.column((i0 + 2) % 3));
    let (n0, n1) = (c0.norm_squared(), c1.norm_squared());
    let v = if n0 > n1 {
        c0 / n0.sqrt()
    } else {
        c1 / n1.sqrt()
    };
    (v, representative)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diagonal_and_zero_matrices() {
        let (values, vectors) =
            symmetric_eigen3(&Matrix3::from_diagonal(&Vector3::new(3.0, -1.0, 2.0)));
        assert!((values - Vector3::new(-1.0, 2.0, 3.0)).norm() < 1e-14);
        assert!(
            (vectors.column(0).into_owned() - Vector3::y()).norm() < 1e-12
                || (vectors.column(0).into_owned() + Vector3::y()).norm() < 1e-12
        );
        let (values, vectors) = symmetric_eigen3(&Matrix3::zeros());
        assert_eq!(values, Vector3::zeros());
        assert_eq!(vectors, Matrix3::identity());
    }

    #[test]
    fn non_finite_input_does_not_panic() {
        let mut m = Matrix3::identity();
        m[(1, 0)] = f64::NAN;
        let (values, _) = symmetric_eigen3(&m);
        assert!(values.iter().any(|v| !v.is_finite()));
    }
}
