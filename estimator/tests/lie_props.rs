//! Property tests for `limot_estimator::lie`: exp/log round trips, every
//! analytic Jacobian against central finite differences, Jacobian inverses and
//! the adjoint identity, over random inputs that include near-zero and
//! near-π rotations.

use limot_estimator::lie::*;
use nalgebra::{Isometry3, Matrix3, Matrix6, Point3, SMatrix, Vector3, Vector6};
use proptest::prelude::*;
use std::f64::consts::PI;

/// Finite-difference step. Central differences: truncation O(h²), round-off
/// O(ε/h) — both far below the 1e-6 tolerance.
const H: f64 = 1e-6;
/// Relative tolerance for analytic vs numerical Jacobians.
const FD_TOL: f64 = 1e-6;

fn assert_close<const M: usize, const N: usize>(
    a: &SMatrix<f64, M, N>,
    b: &SMatrix<f64, M, N>,
    tol: f64,
    what: &str,
) -> Result<(), TestCaseError> {
    let err = (a - b).amax();
    let scale = a.amax().max(b.amax()).max(1.0);
    prop_assert!(
        err <= tol * scale,
        "{}: max abs diff {:e} > {:e} * {}\nleft {}\nright {}",
        what,
        err,
        tol,
        scale,
        a,
        b
    );
    Ok(())
}

/// A unit direction (rejecting near-zero draws before normalising).
fn direction() -> impl Strategy<Value = Vector3<f64>> {
    (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64)
        .prop_map(|(x, y, z)| Vector3::new(x, y, z))
        .prop_filter("non-degenerate direction", |v| v.norm() > 1e-3)
        .prop_map(|v| v.normalize())
}

/// Rotation vectors with angle in `[0, max_angle]`, with heavy weight on tiny,
/// small (around the Taylor switch) and near-`max_angle` angles.
fn rotation_vector(max_angle: f64) -> impl Strategy<Value = Vector3<f64>> {
    let angle = prop_oneof![
        Just(0.0),
        1e-12..1e-6f64,
        1e-6..0.2f64,
        0.0..max_angle,
        (max_angle - 1e-3)..max_angle,
    ];
    (direction(), angle).prop_map(|(d, a)| d * a)
}

fn translation() -> impl Strategy<Value = Vector3<f64>> {
    prop_oneof![
        Just(Vector3::zeros()),
        (-10.0..10.0f64, -10.0..10.0f64, -10.0..10.0f64)
            .prop_map(|(x, y, z)| Vector3::new(x, y, z)),
    ]
}

fn twist(max_angle: f64) -> impl Strategy<Value = Vector6<f64>> {
    (translation(), rotation_vector(max_angle)).prop_map(|(rho, phi)| xi_from_parts(&rho, &phi))
}

/// Poses whose rotation angle is at most `max_angle`.
fn pose(max_angle: f64) -> impl Strategy<Value = Isometry3<f64>> {
    (translation(), rotation_vector(max_angle))
        .prop_map(|(t, phi)| Isometry3::from_parts(t.into(), so3_exp_quat(&phi)))
}

/// Largest angle used where a finite-difference step must not wrap past π.
const FD_MAX_ANGLE: f64 = PI - 1e-2;
/// Largest angle in the round-trip tests.
const RT_MAX_ANGLE: f64 = PI - 1e-6;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn so3_log_exp_round_trip(phi in rotation_vector(RT_MAX_ANGLE)) {
        let back = so3_log(&so3_exp(&phi));
        // Relative for tiny vectors, absolute 1e-9 near pi (the conditioning
        // of the angle from a matrix degrades like 1/sin θ there).
        let err = (back - phi).norm();
        prop_assert!(err <= 1e-12 * phi.norm() + 1e-10, "{} vs {} (err {:e})", back, phi, err);
    }

    #[test]
    fn so3_exp_log_round_trip(phi in rotation_vector(PI)) {
        let r = so3_exp(&phi);
        let back = so3_exp(&so3_log(&r));
        assert_close(back.matrix(), r.matrix(), 1e-12, "exp(log(R))")?;
        prop_assert!(so3_log(&r).norm() <= PI + 1e-12);
    }

    #[test]
    fn se3_log_exp_round_trip(xi in twist(RT_MAX_ANGLE)) {
        let back = se3_log(&se3_exp(&xi));
        // rho = J_l^-1(phi) t amplifies errors near pi (J_l^-1 ~ 1/(1+cos)).
        let err = (back - xi).amax();
        prop_assert!(err <= 1e-12 * xi.amax() + 1e-9, "{} vs {} (err {:e})", back, xi, err);
        let phi_err = (xi_phi(&back) - xi_phi(&xi)).norm();
        prop_assert!(phi_err <= 1e-12 * xi_phi(&xi).norm() + 1e-10);
    }

    #[test]
    fn se3_log_exp_round_trip_below_pi(xi in twist(FD_MAX_ANGLE)) {
        let back = se3_log(&se3_exp(&xi));
        let err = (back - xi).amax();
        prop_assert!(err <= 1e-12 * xi.amax() + 1e-11, "{} vs {} (err {:e})", back, xi, err);
    }

    #[test]
    fn se3_exp_log_round_trip(t in pose(PI)) {
        let back = se3_exp(&se3_log(&t));
        assert_close(&back.to_homogeneous(), &t.to_homogeneous(), 1e-10, "exp(log(T))")?;
    }

    #[test]
    fn so3_jacobians_vs_finite_differences(phi in rotation_vector(FD_MAX_ANGLE)) {
        let z = Vector3::zeros();
        let r0 = so3_exp(&phi);
        let num_r = numerical_jacobian(|d| so3_log(&(r0.inverse() * so3_exp(&(phi + d)))), &z, H);
        assert_close(&so3_right_jacobian(&phi), &num_r, FD_TOL, "J_r")?;
        let num_l = numerical_jacobian(|d| so3_log(&(so3_exp(&(phi + d)) * r0.inverse())), &z, H);
        assert_close(&so3_left_jacobian(&phi), &num_l, FD_TOL, "J_l")?;
        let num_rinv = numerical_jacobian(|d| so3_log(&(r0 * so3_exp(d))), &z, H);
        assert_close(&so3_right_jacobian_inv(&phi), &num_rinv, FD_TOL, "J_r^-1")?;
        let num_linv = numerical_jacobian(|d| so3_log(&(so3_exp(d) * r0)), &z, H);
        assert_close(&so3_left_jacobian_inv(&phi), &num_linv, FD_TOL, "J_l^-1")?;
    }

    #[test]
    fn so3_jacobian_times_inverse_is_identity(phi in rotation_vector(PI)) {
        let i3 = Matrix3::identity();
        assert_close(&(so3_right_jacobian(&phi) * so3_right_jacobian_inv(&phi)), &i3, 1e-12, "J_r J_r^-1")?;
        assert_close(&(so3_left_jacobian(&phi) * so3_left_jacobian_inv(&phi)), &i3, 1e-12, "J_l J_l^-1")?;
    }

    #[test]
    fn se3_jacobians_vs_finite_differences(xi in twist(FD_MAX_ANGLE)) {
        let z = Vector6::zeros();
        let t0 = se3_exp(&xi);
        let num_r = numerical_jacobian(|d| ominus(&se3_exp(&(xi + d)), &t0), &z, H);
        assert_close(&se3_right_jacobian(&xi), &num_r, FD_TOL, "SE3 J_r")?;
        let num_l = numerical_jacobian(|d| se3_log(&(se3_exp(&(xi + d)) * t0.inverse())), &z, H);
        assert_close(&se3_left_jacobian(&xi), &num_l, FD_TOL, "SE3 J_l")?;
        let num_rinv = numerical_jacobian(|d| se3_log(&oplus(&t0, d)), &z, H);
        assert_close(&se3_right_jacobian_inv(&xi), &num_rinv, FD_TOL, "SE3 J_r^-1")?;
        let num_linv = numerical_jacobian(|d| se3_log(&(se3_exp(d) * t0)), &z, H);
        assert_close(&se3_left_jacobian_inv(&xi), &num_linv, FD_TOL, "SE3 J_l^-1")?;
    }

    #[test]
    fn se3_jacobian_times_inverse_is_identity(xi in twist(PI)) {
        let i6 = Matrix6::identity();
        assert_close(&(se3_right_jacobian(&xi) * se3_right_jacobian_inv(&xi)), &i6, 1e-10, "SE3 J_r J_r^-1")?;
        assert_close(&(se3_left_jacobian(&xi) * se3_left_jacobian_inv(&xi)), &i6, 1e-10, "SE3 J_l J_l^-1")?;
    }

    #[test]
    fn adjoint_identity(t in pose(PI), xi in twist(PI)) {
        let lhs = t * se3_exp(&xi) * t.inverse();
        let rhs = se3_exp(&(se3_adjoint(&t) * xi));
        assert_close(&lhs.to_homogeneous(), &rhs.to_homogeneous(), 1e-10, "T Exp(xi) T^-1 = Exp(Ad xi)")?;
    }

    #[test]
    fn between_jacobians_vs_finite_differences(t1 in pose(PI), rel in twist(FD_MAX_ANGLE)) {
        // Build T2 from a relative twist so that Log(T1⁻¹T2) stays away from
        // the cut at |phi| = pi, where the finite difference of Log is invalid.
        let t2 = t1 * se3_exp(&rel);
        let (xi, j1, j2) = between_with_jacobians(&t1, &t2);
        let z = Vector6::zeros();
        assert_close(&xi, &se3_log(&between(&t1, &t2)), 0.0, "between value")?;
        let n1 = numerical_jacobian(|d| se3_log(&between(&oplus(&t1, d), &t2)), &z, H);
        let n2 = numerical_jacobian(|d| se3_log(&between(&t1, &oplus(&t2, d))), &z, H);
        assert_close(&j1, &n1, FD_TOL, "between J1")?;
        assert_close(&j2, &n2, FD_TOL, "between J2")?;
    }

    #[test]
    fn log_jacobian_vs_finite_differences(t in pose(FD_MAX_ANGLE)) {
        let (xi, j) = se3_log_with_jacobian(&t);
        assert_close(&xi, &se3_log(&t), 0.0, "log value")?;
        let n = numerical_jacobian(|d| se3_log(&oplus(&t, d)), &Vector6::zeros(), H);
        assert_close(&j, &n, FD_TOL, "log J")?;
    }

    #[test]
    fn transform_point_jacobians_vs_finite_differences(
        t in pose(PI),
        p in (-20.0..20.0f64, -20.0..20.0f64, -20.0..20.0f64).prop_map(|(x, y, z)| Vector3::new(x, y, z)),
    ) {
        let (y, jt, jp) = transform_point_with_jacobians(&t, &p);
        assert_close(&y, &(t * Point3::from(p)).coords, 1e-12, "T p")?;
        let nt = numerical_jacobian(|d| (oplus(&t, d) * Point3::from(p)).coords, &Vector6::zeros(), H);
        let np = numerical_jacobian(|q| (t * Point3::from(*q)).coords, &p, H);
        assert_close(&jt, &nt, FD_TOL, "d(Tp)/dxi")?;
        assert_close(&jp, &np, FD_TOL, "d(Tp)/dp")?;
    }

    #[test]
    fn rotate_jacobians_vs_finite_differences(
        phi in rotation_vector(PI),
        v in (-20.0..20.0f64, -20.0..20.0f64, -20.0..20.0f64).prop_map(|(x, y, z)| Vector3::new(x, y, z)),
    ) {
        let r = so3_exp(&phi);
        let z = Vector3::zeros();
        let (rv, jr, jv) = rotate_with_jacobian(&r, &v);
        assert_close(&rv, &(r * v), 1e-12, "R v")?;
        assert_close(&jr, &numerical_jacobian(|d| r * so3_exp(d) * v, &z, H), FD_TOL, "d(Rv)/dR")?;
        assert_close(&jv, &numerical_jacobian(|w| r * w, &v, H), FD_TOL, "d(Rv)/dv")?;
        let (rtv, jr, jv) = unrotate_with_jacobian(&r, &v);
        assert_close(&rtv, &(r.inverse() * v), 1e-12, "R^T v")?;
        assert_close(&jr, &numerical_jacobian(|d| (r * so3_exp(d)).inverse() * v, &z, H), FD_TOL, "d(R^T v)/dR")?;
        assert_close(&jv, &numerical_jacobian(|w| r.inverse() * w, &v, H), FD_TOL, "d(R^T v)/dv")?;
    }

    #[test]
    fn inverse_and_compose_jacobians_vs_finite_differences(t1 in pose(PI), t2 in pose(PI)) {
        let z = Vector6::zeros();
        let (ti, ji) = inverse_with_jacobian(&t1);
        assert_close(&ti.to_homogeneous(), &t1.inverse().to_homogeneous(), 0.0, "inverse value")?;
        let ni = numerical_jacobian(|d| ominus(&oplus(&t1, d).inverse(), &ti), &z, H);
        assert_close(&ji, &ni, FD_TOL, "inverse J")?;

        let (t12, j1, j2) = compose_with_jacobians(&t1, &t2);
        assert_close(&t12.to_homogeneous(), &(t1 * t2).to_homogeneous(), 0.0, "compose value")?;
        let n1 = numerical_jacobian(|d| ominus(&(oplus(&t1, d) * t2), &t12), &z, H);
        let n2 = numerical_jacobian(|d| ominus(&(t1 * oplus(&t2, d)), &t12), &z, H);
        assert_close(&j1, &n1, FD_TOL, "compose J1")?;
        assert_close(&j2, &n2, FD_TOL, "compose J2")?;
    }

    #[test]
    fn oplus_ominus_are_inverse(t in pose(PI), xi in twist(FD_MAX_ANGLE)) {
        let moved = oplus(&t, &xi);
        assert_close(&ominus(&moved, &t), &xi, 1e-9, "(T ⊕ xi) ⊖ T")?;
        let back = oplus(&t, &ominus(&moved, &t));
        assert_close(&back.to_homogeneous(), &moved.to_homogeneous(), 1e-10, "T ⊕ (T2 ⊖ T)")?;
    }
}
