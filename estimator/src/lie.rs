//! SO(3) and SE(3) in f64: exponential/logarithm maps, Jacobians and the
//! Jacobians of the group operations that the factors need.
//!
//! # Conventions (read this before writing a factor)
//!
//! * **Right perturbation** (GTSAM, Forster et al. 2016): `R ⊕ δ = R·Exp(δ)`,
//!   `T ⊕ ξ = T·Exp(ξ)`. Every Jacobian `∂f/∂X` below is taken with respect to
//!   a right perturbation of `X` (and, when `f` is group-valued, expressed as a
//!   right perturbation of the result: `f(X·Exp(δ)) ≈ f(X)·Exp(J·δ)`).
//! * **SE(3) tangent ordering is `ξ = (ρ, φ)`**: translation part `ρ` first
//!   (indices 0..3), rotation part `φ` second (indices 3..6). This is Barfoot's
//!   (and Sophus') ordering; note that GTSAM's `Pose3` uses `(φ, ρ)` instead.
//!   `Exp(ξ) = [Exp(φ), J_l(φ)·ρ; 0, 1]`.
//! * SO(3) elements are nalgebra [`Rotation3`] (or [`UnitQuaternion`] where
//!   noted), SE(3) elements are [`Isometry3`] (quaternion + translation).
//! * `J_r`/`J_l` are the right/left Jacobians: `Exp(φ+δ) ≈ Exp(φ)·Exp(J_r(φ)δ)
//!   ≈ Exp(J_l(φ)δ)·Exp(φ)`, and `J_l(φ) = J_r(-φ)`, for SO(3) and SE(3) alike.
//!
//! Small angles switch to Taylor series (below [`SMALL_ANGLE_RAD`]) so that
//! nothing divides by a vanishing angle; the logarithm goes through a unit
//! quaternion and `atan2`, which keeps it accurate up to (and at) `θ = π`.

use nalgebra::{
    Isometry3, Matrix3, Matrix3x6, Matrix6, Quaternion, Rotation3, SMatrix, SVector, Translation3,
    UnitQuaternion, Vector3, Vector6,
};

/// Below this rotation angle (rad) the Jacobian coefficients use Taylor
/// series. The series are kept to the θ⁶ term, so their truncation error here
/// is below 1e-15, while the closed forms lose at most ~1e-10 relative to
/// cancellation just above it.
pub const SMALL_ANGLE_RAD: f64 = 0.1;

// ---------------------------------------------------------------------------
// so(3) hat / vee
// ---------------------------------------------------------------------------

/// Skew-symmetric (hat) matrix: `skew(v)·w = v × w`.
#[inline]
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Inverse of [`skew`]. Uses the antisymmetric part of `m`, so a matrix that
/// is only approximately skew-symmetric still maps to the nearest vector.
#[inline]
pub fn vee(m: &Matrix3<f64>) -> Vector3<f64> {
    Vector3::new(
        0.5 * (m[(2, 1)] - m[(1, 2)]),
        0.5 * (m[(0, 2)] - m[(2, 0)]),
        0.5 * (m[(1, 0)] - m[(0, 1)]),
    )
}

// ---------------------------------------------------------------------------
// Scalar coefficients (closed form with Taylor fallback)
// ---------------------------------------------------------------------------

/// `(1 - cos θ) / θ²`.
#[inline]
fn coef_one_minus_cos(theta: f64) -> f64 {
    if theta < SMALL_ANGLE_RAD {
        let t2 = theta * theta;
        0.5 - t2 / 24.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0))
    } else {
        (1.0 - theta.cos()) / (theta * theta)
    }
}

/// `(θ - sin θ) / θ³`.
#[inline]
fn coef_theta_minus_sin(theta: f64) -> f64 {
    if theta < SMALL_ANGLE_RAD {
        let t2 = theta * theta;
        1.0 / 6.0 - t2 / 120.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0))
    } else {
        (theta - theta.sin()) / (theta * theta * theta)
    }
}

/// `1/θ² - (1 + cos θ) / (2θ sin θ)` = `1/θ² - cot(θ/2) / (2θ)`, the φ^²
/// coefficient of `J_r⁻¹`. The half-angle form stays finite at θ = π.
#[inline]
fn coef_jinv(theta: f64) -> f64 {
    if theta < SMALL_ANGLE_RAD {
        let t2 = theta * theta;
        1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0 + t2 * t2 * t2 / 1_209_600.0
    } else {
        let half = 0.5 * theta;
        1.0 / (theta * theta) - half.cos() / (2.0 * theta * half.sin())
    }
}

/// `(θ² + 2 cos θ - 2) / (2θ⁴)` (Barfoot's Q matrix).
#[inline]
fn coef_q2(theta: f64) -> f64 {
    let t2 = theta * theta;
    if theta < SMALL_ANGLE_RAD {
        1.0 / 24.0 - t2 / 720.0 + t2 * t2 / 40320.0 - t2 * t2 * t2 / 3_628_800.0
    } else {
        (t2 + 2.0 * theta.cos() - 2.0) / (2.0 * t2 * t2)
    }
}

/// `(2θ - 3 sin θ + θ cos θ) / (2θ⁵)` (Barfoot's Q matrix).
#[inline]
fn coef_q3(theta: f64) -> f64 {
    let t2 = theta * theta;
    if theta < SMALL_ANGLE_RAD {
        1.0 / 120.0 - t2 / 2520.0 + t2 * t2 / 120_960.0 - t2 * t2 * t2 / 9_979_200.0
    } else {
        (2.0 * theta - 3.0 * theta.sin() + theta * theta.cos()) / (2.0 * t2 * t2 * theta)
    }
}

/// `sin(θ/2) / θ`, used to build the quaternion of `Exp(φ)`.
#[inline]
fn coef_half_sinc(theta: f64) -> f64 {
    if theta < SMALL_ANGLE_RAD {
        let t2 = theta * theta;
        0.5 * (1.0 - t2 / 24.0 * (1.0 - t2 / 80.0 * (1.0 - t2 / 168.0)))
    } else {
        (0.5 * theta).sin() / theta
    }
}

// ---------------------------------------------------------------------------
// SO(3)
// ---------------------------------------------------------------------------

/// `Exp: so(3) → SO(3)` as a unit quaternion (exactly normalised).
#[inline]
pub fn so3_exp_quat(phi: &Vector3<f64>) -> UnitQuaternion<f64> {
    let theta = phi.norm();
    let k = coef_half_sinc(theta);
    let q = Quaternion::new((0.5 * theta).cos(), k * phi.x, k * phi.y, k * phi.z);
    // Renormalise to remove the last ulp of drift between cos and sin.
    UnitQuaternion::new_normalize(q)
}

/// `Exp: so(3) → SO(3)` (Rodrigues), accurate for tiny angles.
#[inline]
pub fn so3_exp(phi: &Vector3<f64>) -> Rotation3<f64> {
    so3_exp_quat(phi).to_rotation_matrix()
}

/// `Log: SO(3) → so(3)` of a unit quaternion; the result has norm in `[0, π]`.
/// Uses `θ = 2·atan2(|v|, w)` with `w ≥ 0`, which is well conditioned both at
/// `θ → 0` and at `θ → π`.
#[inline]
pub fn so3_log_quat(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    let q = q.quaternion().normalize();
    // q and -q are the same rotation; pick w ≥ 0 so that θ ∈ [0, π].
    let (w, v) = if q.w < 0.0 {
        (-q.w, -q.imag())
    } else {
        (q.w, q.imag())
    };
    let n2 = v.norm_squared();
    let scale = if n2 < f64::EPSILON {
        // 2·atan(n/w)/n = (2/w)(1 - n²/(3w²) + …); w ≈ 1 here.
        2.0 / w * (1.0 - n2 / (3.0 * w * w))
    } else {
        let n = n2.sqrt();
        2.0 * n.atan2(w) / n
    };
    v * scale
}

/// `Log: SO(3) → so(3)`; the result has norm in `[0, π]`. Robust near 0 and
/// near π (goes through Shepperd's quaternion extraction).
#[inline]
pub fn so3_log(r: &Rotation3<f64>) -> Vector3<f64> {
    so3_log_quat(&UnitQuaternion::from_rotation_matrix(r))
}

/// SO(3) right Jacobian: `Exp(φ + δ) ≈ Exp(φ)·Exp(J_r(φ)·δ)`.
#[inline]
pub fn so3_right_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let s = skew(phi);
    Matrix3::identity() - s * coef_one_minus_cos(theta) + s * s * coef_theta_minus_sin(theta)
}

/// Inverse of [`so3_right_jacobian`] (closed form; singular only at θ = 2π).
#[inline]
pub fn so3_right_jacobian_inv(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let s = skew(phi);
    Matrix3::identity() + s * 0.5 + s * s * coef_jinv(theta)
}

/// SO(3) left Jacobian: `Exp(φ + δ) ≈ Exp(J_l(φ)·δ)·Exp(φ)`; `J_l(φ) = J_r(-φ)`.
#[inline]
pub fn so3_left_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    so3_right_jacobian(&-phi)
}

/// Inverse of [`so3_left_jacobian`].
#[inline]
pub fn so3_left_jacobian_inv(phi: &Vector3<f64>) -> Matrix3<f64> {
    so3_right_jacobian_inv(&-phi)
}

/// `R·v` with Jacobians wrt a right perturbation of `R` and wrt `v`:
/// returns `(R·v, -R·[v]ₓ, R)`.
#[inline]
pub fn rotate_with_jacobian(
    r: &Rotation3<f64>,
    v: &Vector3<f64>,
) -> (Vector3<f64>, Matrix3<f64>, Matrix3<f64>) {
    let m = r.matrix();
    (m * v, -m * skew(v), *m)
}

/// `Rᵀ·v` with Jacobians wrt a right perturbation of `R` and wrt `v`:
/// returns `(Rᵀ·v, [Rᵀv]ₓ, Rᵀ)`. Used e.g. to bring gravity into the body frame.
#[inline]
pub fn unrotate_with_jacobian(
    r: &Rotation3<f64>,
    v: &Vector3<f64>,
) -> (Vector3<f64>, Matrix3<f64>, Matrix3<f64>) {
    let rt = r.matrix().transpose();
    let value = rt * v;
    (value, skew(&value), rt)
}

// ---------------------------------------------------------------------------
// SE(3), tangent ξ = (ρ, φ)
// ---------------------------------------------------------------------------

/// Translation part `ρ` of a twist `ξ = (ρ, φ)`.
#[inline]
pub fn xi_rho(xi: &Vector6<f64>) -> Vector3<f64> {
    xi.fixed_rows::<3>(0).into_owned()
}

/// Rotation part `φ` of a twist `ξ = (ρ, φ)`.
#[inline]
pub fn xi_phi(xi: &Vector6<f64>) -> Vector3<f64> {
    xi.fixed_rows::<3>(3).into_owned()
}

/// Builds a twist `ξ = (ρ, φ)`.
#[inline]
pub fn xi_from_parts(rho: &Vector3<f64>, phi: &Vector3<f64>) -> Vector6<f64> {
    Vector6::new(rho.x, rho.y, rho.z, phi.x, phi.y, phi.z)
}

/// `Exp: se(3) → SE(3)`, `ξ = (ρ, φ)`: rotation `Exp(φ)`, translation `J_l(φ)·ρ`.
#[inline]
pub fn se3_exp(xi: &Vector6<f64>) -> Isometry3<f64> {
    let rho = xi_rho(xi);
    let phi = xi_phi(xi);
    let t = so3_left_jacobian(&phi) * rho;
    Isometry3::from_parts(Translation3::from(t), so3_exp_quat(&phi))
}

/// `Log: SE(3) → se(3)`, returns `ξ = (ρ, φ)` with `|φ| ≤ π`.
#[inline]
pub fn se3_log(t: &Isometry3<f64>) -> Vector6<f64> {
    let phi = so3_log_quat(&t.rotation);
    let rho = so3_left_jacobian_inv(&phi) * t.translation.vector;
    xi_from_parts(&rho, &phi)
}

/// Adjoint of `T = (R, t)` in `(ρ, φ)` ordering: `[R, [t]ₓR; 0, R]`, so that
/// `T·Exp(ξ)·T⁻¹ = Exp(Ad_T·ξ)`.
#[inline]
pub fn se3_adjoint(t: &Isometry3<f64>) -> Matrix6<f64> {
    let r = t.rotation.to_rotation_matrix().into_inner();
    let tr = skew(&t.translation.vector) * r;
    let mut ad = Matrix6::zeros();
    ad.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    ad.fixed_view_mut::<3, 3>(0, 3).copy_from(&tr);
    ad.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
    ad
}

/// Barfoot's `Q(ρ, φ)`, the upper-right block of the SE(3) *left* Jacobian
/// (Barfoot, State Estimation for Robotics, eq. 7.86).
#[inline]
fn barfoot_q(rho: &Vector3<f64>, phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let p = skew(phi);
    let r = skew(rho);
    let pr = p * r;
    let rp = r * p;
    let prp = pr * p;
    let ppr = p * pr;
    let rpp = rp * p;
    let prpp = prp * p;
    let pprp = p * prp;
    r * 0.5
        + (pr + rp + prp) * coef_theta_minus_sin(theta)
        + (ppr + rpp - prp * 3.0) * coef_q2(theta)
        + (prpp + pprp) * coef_q3(theta)
}

/// Assembles `[A, B; 0, A]`.
#[inline]
fn block_upper(a: &Matrix3<f64>, b: &Matrix3<f64>) -> Matrix6<f64> {
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(a);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(b);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(a);
    m
}

/// SE(3) left Jacobian: `Exp(ξ + δ) ≈ Exp(J_l(ξ)·δ)·Exp(ξ)`;
/// `[J_l(φ), Q(ρ, φ); 0, J_l(φ)]`.
#[inline]
pub fn se3_left_jacobian(xi: &Vector6<f64>) -> Matrix6<f64> {
    let rho = xi_rho(xi);
    let phi = xi_phi(xi);
    block_upper(&so3_left_jacobian(&phi), &barfoot_q(&rho, &phi))
}

/// Inverse of [`se3_left_jacobian`]:
/// `[J_l⁻¹, -J_l⁻¹·Q·J_l⁻¹; 0, J_l⁻¹]`.
#[inline]
pub fn se3_left_jacobian_inv(xi: &Vector6<f64>) -> Matrix6<f64> {
    let rho = xi_rho(xi);
    let phi = xi_phi(xi);
    let jinv = so3_left_jacobian_inv(&phi);
    let q = barfoot_q(&rho, &phi);
    block_upper(&jinv, &(-jinv * q * jinv))
}

/// SE(3) right Jacobian: `Exp(ξ + δ) ≈ Exp(ξ)·Exp(J_r(ξ)·δ)`; `J_r(ξ) = J_l(-ξ)`.
#[inline]
pub fn se3_right_jacobian(xi: &Vector6<f64>) -> Matrix6<f64> {
    se3_left_jacobian(&-xi)
}

/// Inverse of [`se3_right_jacobian`] (closed form with the Q matrix).
#[inline]
pub fn se3_right_jacobian_inv(xi: &Vector6<f64>) -> Matrix6<f64> {
    se3_left_jacobian_inv(&-xi)
}

/// `T ⊕ ξ = T·Exp(ξ)`.
#[inline]
///
/// ```
/// use limot_estimator::lie::{ominus, oplus};
/// use nalgebra::{Isometry3, Vector3, Vector6};
///
/// let t = Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.1, -0.2, 0.3));
/// // ξ = (ρ, φ): translation part first.
/// let xi = Vector6::new(0.5, 0.0, 0.0, 0.0, 0.0, 0.2);
/// let moved = oplus(&t, &xi);
/// assert!((ominus(&moved, &t) - xi).norm() < 1e-12);
/// ```
pub fn oplus(t: &Isometry3<f64>, xi: &Vector6<f64>) -> Isometry3<f64> {
    t * se3_exp(xi)
}

/// `T1 ⊖ T2 = Log(T2⁻¹·T1)`, so that `T2 ⊕ (T1 ⊖ T2) = T1`.
#[inline]
pub fn ominus(t1: &Isometry3<f64>, t2: &Isometry3<f64>) -> Vector6<f64> {
    se3_log(&(t2.inverse() * t1))
}

/// `T1⁻¹·T2`: `T2` expressed in the frame of `T1`.
#[inline]
pub fn between(t1: &Isometry3<f64>, t2: &Isometry3<f64>) -> Isometry3<f64> {
    t1.inverse() * t2
}

/// `Log(T)` with its Jacobian wrt a right perturbation of `T`:
/// `Log(T·Exp(δ)) ≈ Log(T) + J_r⁻¹(Log T)·δ`.
#[inline]
pub fn se3_log_with_jacobian(t: &Isometry3<f64>) -> (Vector6<f64>, Matrix6<f64>) {
    let xi = se3_log(t);
    (xi, se3_right_jacobian_inv(&xi))
}

/// `ξ = Log(T1⁻¹·T2)` with its Jacobians wrt right perturbations of `T1` and
/// `T2`: `(ξ, -J_l⁻¹(ξ), J_r⁻¹(ξ))`. (`-J_l⁻¹(ξ) = -J_r⁻¹(ξ)·Ad(T12⁻¹)`.)
/// This is the residual of a between factor with an identity measurement.
#[inline]
pub fn between_with_jacobians(
    t1: &Isometry3<f64>,
    t2: &Isometry3<f64>,
) -> (Vector6<f64>, Matrix6<f64>, Matrix6<f64>) {
    let xi = se3_log(&between(t1, t2));
    (xi, -se3_left_jacobian_inv(&xi), se3_right_jacobian_inv(&xi))
}

/// `T·p` with Jacobians wrt a right perturbation `ξ = (ρ, φ)` of `T` and wrt
/// `p`: `(T·p, [R, -R·[p]ₓ], R)`.
#[inline]
pub fn transform_point_with_jacobians(
    t: &Isometry3<f64>,
    p: &Vector3<f64>,
) -> (Vector3<f64>, Matrix3x6<f64>, Matrix3<f64>) {
    let r = t.rotation.to_rotation_matrix().into_inner();
    let value = r * p + t.translation.vector;
    let mut d_pose = Matrix3x6::zeros();
    d_pose.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    d_pose
        .fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(-r * skew(p)));
    (value, d_pose, r)
}

/// `T⁻¹` with the Jacobian of the result (as a right perturbation) wrt a right
/// perturbation of `T`: `-Ad_T`.
#[inline]
pub fn inverse_with_jacobian(t: &Isometry3<f64>) -> (Isometry3<f64>, Matrix6<f64>) {
    (t.inverse(), -se3_adjoint(t))
}

/// `T1·T2` with the Jacobians of the result (as a right perturbation) wrt
/// right perturbations of `T1` and `T2`: `(T1·T2, Ad(T2⁻¹), I)`.
#[inline]
pub fn compose_with_jacobians(
    t1: &Isometry3<f64>,
    t2: &Isometry3<f64>,
) -> (Isometry3<f64>, Matrix6<f64>, Matrix6<f64>) {
    (t1 * t2, se3_adjoint(&t2.inverse()), Matrix6::identity())
}

// ---------------------------------------------------------------------------
// Numerical differentiation (for tests of this and every factor module)
// ---------------------------------------------------------------------------

/// Central finite-difference Jacobian of `f: ℝᴺ → ℝᴹ` at `x`, step `h`.
/// For group-valued functions, wrap them so that `f` returns local
/// coordinates, e.g. `δ ↦ ominus(g(T ⊕ δ), g(T))`.
pub fn numerical_jacobian<const M: usize, const N: usize>(
    f: impl Fn(&SVector<f64, N>) -> SVector<f64, M>,
    x: &SVector<f64, N>,
    h: f64,
) -> SMatrix<f64, M, N> {
    let mut jac = SMatrix::<f64, M, N>::zeros();
    for i in 0..N {
        let mut xp = *x;
        let mut xm = *x;
        xp[i] += h;
        xm[i] -= h;
        jac.set_column(i, &((f(&xp) - f(&xm)) / (2.0 * h)));
    }
    jac
}

#[cfg(test)]
mod tests {
    use super::*;

    const H: f64 = 1e-6;

    fn assert_close<const M: usize, const N: usize>(
        a: &SMatrix<f64, M, N>,
        b: &SMatrix<f64, M, N>,
        tol: f64,
        what: &str,
    ) {
        let err = (a - b).amax();
        let scale = a.amax().max(b.amax()).max(1.0);
        assert!(
            err <= tol * scale,
            "{what}: max abs diff {err:e} > {tol:e} * {scale}\nanalytic {a}\nnumeric {b}"
        );
    }

    fn sample_phis() -> Vec<Vector3<f64>> {
        vec![
            Vector3::zeros(),
            Vector3::new(1e-9, -2e-9, 0.5e-9),
            Vector3::new(1e-5, 3e-5, -2e-5),
            Vector3::new(0.05, -0.02, 0.07),
            Vector3::new(0.3, -0.8, 0.5),
            Vector3::new(1.2, 0.4, -1.9),
            Vector3::new(0.0, 0.0, std::f64::consts::PI - 1e-6),
            Vector3::new(1.0, 1.0, 1.0).normalize() * (std::f64::consts::PI - 1e-3),
        ]
    }

    fn sample_xis() -> Vec<Vector6<f64>> {
        let rhos = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.5, -0.3, 2.0),
            Vector3::new(-4.0, 7.0, 0.2),
        ];
        let mut out = Vec::new();
        for phi in sample_phis() {
            for rho in &rhos {
                out.push(xi_from_parts(rho, &phi));
            }
        }
        out
    }

    #[test]
    fn skew_vee_round_trip_and_cross_product() {
        let v = Vector3::new(0.3, -1.2, 2.5);
        let w = Vector3::new(-0.7, 0.1, 0.4);
        assert_eq!(vee(&skew(&v)), v);
        assert_close(&(skew(&v) * w), &v.cross(&w), 1e-15, "skew");
    }

    #[test]
    fn so3_exp_log_round_trip() {
        for phi in sample_phis() {
            let r = so3_exp(&phi);
            let back = so3_log(&r);
            assert_close(&back, &phi, 1e-12, "log(exp(phi))");
            // Exp agrees with nalgebra's Rodrigues.
            assert_close(
                r.matrix(),
                Rotation3::new(phi).matrix(),
                1e-14,
                "exp vs nalgebra",
            );
        }
        // Tiny angle: relative accuracy, not just absolute.
        let tiny = Vector3::new(1e-9, -2e-9, 0.5e-9);
        let back = so3_log(&so3_exp(&tiny));
        assert!(
            (back - tiny).norm() <= 1e-12 * tiny.norm(),
            "tiny: {back} vs {tiny}"
        );
    }

    #[test]
    fn so3_log_at_exactly_pi() {
        let axis = Vector3::new(0.0, 0.6, 0.8);
        let r = so3_exp(&(axis * std::f64::consts::PI));
        let phi = so3_log(&r);
        assert!((phi.norm() - std::f64::consts::PI).abs() < 1e-12);
        assert_close(
            so3_exp(&phi).matrix(),
            r.matrix(),
            1e-12,
            "exp(log(R)) at pi",
        );
    }

    #[test]
    fn so3_jacobians_match_finite_differences() {
        for phi in sample_phis() {
            // Skip angles where phi ± H would wrap past pi.
            if phi.norm() > std::f64::consts::PI - 1e-4 {
                continue;
            }
            let r0 = so3_exp(&phi);
            let num_r = numerical_jacobian(
                |d: &Vector3<f64>| so3_log(&(r0.inverse() * so3_exp(&(phi + d)))),
                &Vector3::zeros(),
                H,
            );
            assert_close(&so3_right_jacobian(&phi), &num_r, 1e-6, "J_r");
            let num_l = numerical_jacobian(
                |d: &Vector3<f64>| so3_log(&(so3_exp(&(phi + d)) * r0.inverse())),
                &Vector3::zeros(),
                H,
            );
            assert_close(&so3_left_jacobian(&phi), &num_l, 1e-6, "J_l");
            let num_rinv = numerical_jacobian(
                |d: &Vector3<f64>| so3_log(&(r0 * so3_exp(d))),
                &Vector3::zeros(),
                H,
            );
            assert_close(&so3_right_jacobian_inv(&phi), &num_rinv, 1e-6, "J_r^-1");
        }
    }

    #[test]
    fn so3_jacobian_inverses() {
        for phi in sample_phis() {
            let i3 = Matrix3::identity();
            assert_close(
                &(so3_right_jacobian(&phi) * so3_right_jacobian_inv(&phi)),
                &i3,
                1e-12,
                "J_r J_r^-1",
            );
            assert_close(
                &(so3_left_jacobian(&phi) * so3_left_jacobian_inv(&phi)),
                &i3,
                1e-12,
                "J_l J_l^-1",
            );
        }
    }

    #[test]
    fn taylor_and_closed_forms_agree_at_switch() {
        // Both branches evaluated just around the threshold must agree.
        let a = SMALL_ANGLE_RAD * (1.0 - 1e-12);
        let b = SMALL_ANGLE_RAD * (1.0 + 1e-12);
        for (name, f) in [
            ("1-cos", coef_one_minus_cos as fn(f64) -> f64),
            ("t-sin", coef_theta_minus_sin),
            ("jinv", coef_jinv),
            ("q2", coef_q2),
            ("q3", coef_q3),
            ("half_sinc", coef_half_sinc),
        ] {
            let (fa, fb) = (f(a), f(b));
            assert!(
                ((fa - fb) / fa).abs() < 1e-9,
                "{name}: taylor {fa} vs closed {fb}"
            );
        }
    }

    #[test]
    fn se3_exp_log_round_trip() {
        for xi in sample_xis() {
            let t = se3_exp(&xi);
            assert_close(&se3_log(&t), &xi, 1e-10, "log(exp(xi))");
            let back = se3_exp(&se3_log(&t));
            assert_close(
                &back.to_homogeneous(),
                &t.to_homogeneous(),
                1e-12,
                "exp(log(T))",
            );
        }
    }

    #[test]
    fn se3_jacobians_match_finite_differences() {
        for xi in sample_xis() {
            if xi_phi(&xi).norm() > std::f64::consts::PI - 1e-4 {
                continue;
            }
            let t0 = se3_exp(&xi);
            let num_r = numerical_jacobian(
                |d: &Vector6<f64>| ominus(&se3_exp(&(xi + d)), &t0),
                &Vector6::zeros(),
                H,
            );
            assert_close(&se3_right_jacobian(&xi), &num_r, 1e-6, "SE3 J_r");
            let num_l = numerical_jacobian(
                |d: &Vector6<f64>| se3_log(&(se3_exp(&(xi + d)) * t0.inverse())),
                &Vector6::zeros(),
                H,
            );
            assert_close(&se3_left_jacobian(&xi), &num_l, 1e-6, "SE3 J_l");
            let i6 = Matrix6::identity();
            assert_close(
                &(se3_right_jacobian(&xi) * se3_right_jacobian_inv(&xi)),
                &i6,
                1e-10,
                "SE3 J_r J_r^-1",
            );
        }
    }

    #[test]
    fn adjoint_identity() {
        let t = se3_exp(&Vector6::new(1.0, -2.0, 0.5, 0.3, 0.2, -0.9));
        let xi = Vector6::new(0.4, 0.1, -0.3, -0.5, 0.7, 0.05);
        let lhs = t * se3_exp(&xi) * t.inverse();
        let rhs = se3_exp(&(se3_adjoint(&t) * xi));
        assert_close(
            &lhs.to_homogeneous(),
            &rhs.to_homogeneous(),
            1e-12,
            "adjoint",
        );
    }

    #[test]
    fn group_operation_jacobians_match_finite_differences() {
        let t1 = se3_exp(&Vector6::new(1.0, -2.0, 0.5, 0.3, 0.2, -0.9));
        let t2 = se3_exp(&Vector6::new(-0.5, 0.7, 3.0, -1.1, 0.4, 0.6));
        let p = Vector3::new(2.0, -1.0, 0.5);
        let z6 = Vector6::zeros();

        let (xi, j1, j2) = between_with_jacobians(&t1, &t2);
        assert_close(&xi, &se3_log(&between(&t1, &t2)), 0.0, "between value");
        let n1 = numerical_jacobian(|d| se3_log(&between(&oplus(&t1, d), &t2)), &z6, H);
        let n2 = numerical_jacobian(|d| se3_log(&between(&t1, &oplus(&t2, d))), &z6, H);
        assert_close(&j1, &n1, 1e-6, "between J1");
        assert_close(&j2, &n2, 1e-6, "between J2");

        let (y, jt, jp) = transform_point_with_jacobians(&t1, &p);
        assert_close(&y, &(t1 * nalgebra::Point3::from(p)).coords, 1e-14, "T p");
        let nt = numerical_jacobian(
            |d| (oplus(&t1, d) * nalgebra::Point3::from(p)).coords,
            &z6,
            H,
        );
        assert_close(&jt, &nt, 1e-6, "d(Tp)/dxi");
        let np = numerical_jacobian(
            |q: &Vector3<f64>| (t1 * nalgebra::Point3::from(*q)).coords,
            &p,
            H,
        );
        assert_close(&jp, &np, 1e-6, "d(Tp)/dp");

        let (ti, ji) = inverse_with_jacobian(&t1);
        let ni = numerical_jacobian(|d| ominus(&oplus(&t1, d).inverse(), &ti), &z6, H);
        assert_close(&ji, &ni, 1e-6, "inverse J");

        let (t12, jc1, jc2) = compose_with_jacobians(&t1, &t2);
        let nc1 = numerical_jacobian(|d| ominus(&(oplus(&t1, d) * t2), &t12), &z6, H);
        let nc2 = numerical_jacobian(|d| ominus(&(t1 * oplus(&t2, d)), &t12), &z6, H);
        assert_close(&jc1, &nc1, 1e-6, "compose J1");
        assert_close(&jc2, &nc2, 1e-6, "compose J2");

        let (_, jl) = se3_log_with_jacobian(&t1);
        let nl = numerical_jacobian(|d| se3_log(&oplus(&t1, d)), &z6, H);
        assert_close(&jl, &nl, 1e-6, "log J");

        let r = so3_exp(&Vector3::new(0.3, 0.2, -0.9));
        let z3 = Vector3::zeros();
        let (_, jr, jv) = rotate_with_jacobian(&r, &p);
        let nr = numerical_jacobian(|d| (r * so3_exp(d)) * p, &z3, H);
        let nv = numerical_jacobian(|v: &Vector3<f64>| r * v, &p, H);
        assert_close(&jr, &nr, 1e-6, "rotate J_R");
        assert_close(&jv, &nv, 1e-6, "rotate J_v");
        let (_, jr, jv) = unrotate_with_jacobian(&r, &p);
        let nr = numerical_jacobian(|d| (r * so3_exp(d)).inverse() * p, &z3, H);
        let nv = numerical_jacobian(|v: &Vector3<f64>| r.inverse() * v, &p, H);
        assert_close(&jr, &nr, 1e-6, "unrotate J_R");
        assert_close(&jv, &nv, 1e-6, "unrotate J_v");
    }
}
