//! Properties of IMU preintegration and the IMU factors: Jacobians against
//! finite differences, accuracy on an analytic trajectory, covariance
//! against Monte Carlo, first-order bias correction, and input errors.
//!
//! Run with `--nocapture` to see the measured figures.

use limot_estimator::graph::{
    BiasRandomWalkFactor, Factor, ImuFactor, Key, Linearization, Values, Variable,
    check_factor_jacobians,
};
use limot_estimator::imu::{
    ImuBias, ImuNoise, ImuTrajectory, Matrix9, Preintegration, PreintegrationError,
};
use limot_estimator::input::ImuSample;
use limot_estimator::lie;
use nalgebra::{Isometry3, Matrix3, Rotation3, SVector, Translation3, Vector3, Vector6};
use proptest::prelude::*;

const GRAVITY: Vector3<f64> = Vector3::new(0.0, 0.0, -9.80511);

// ---------------------------------------------------------------------------
// Analytic trajectory: p(t) smooth, R(t) = Exp(φ(t)), body rate J_r(φ)·φ̇.
// ---------------------------------------------------------------------------

fn position(t: f64) -> Vector3<f64> {
    Vector3::new(
        3.0 * t + 0.5 * (2.0 * t).sin(),
        (1.5 * t).cos() - 1.0 + 0.2 * t * t,
        0.1 * (3.0 * t).sin(),
    )
}

fn velocity(t: f64) -> Vector3<f64> {
    Vector3::new(
        3.0 + (2.0 * t).cos(),
        -1.5 * (1.5 * t).sin() + 0.4 * t,
        0.3 * (3.0 * t).cos(),
    )
}

fn acceleration(t: f64) -> Vector3<f64> {
    Vector3::new(
        -2.0 * (2.0 * t).sin(),
        -2.25 * (1.5 * t).cos() + 0.4,
        -0.9 * (3.0 * t).sin(),
    )
}

fn phi(t: f64) -> Vector3<f64> {
    Vector3::new(
        0.2 * t.sin(),
        0.1 * t + 0.05 * t * t,
        0.5 * t + 0.3 * (2.0 * t).sin(),
    )
}

fn phi_dot(t: f64) -> Vector3<f64> {
    Vector3::new(0.2 * t.cos(), 0.1 + 0.1 * t, 0.5 + 0.6 * (2.0 * t).cos())
}

fn true_pose(t: f64) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::from(position(t)), lie::so3_exp_quat(&phi(t)))
}

fn true_bias() -> ImuBias {
    ImuBias {
        accel_mps2: Vector3::new(0.08, -0.05, 0.12),
        gyro_radps: Vector3::new(0.004, -0.006, 0.003),
    }
}

/// Noise-free measurements (with `true_bias` added) of the analytic
/// trajectory at `rate_hz` over `[0, duration_s]`.
fn analytic_samples(rate_hz: f64, duration_s: f64) -> Vec<ImuSample> {
    let b = true_bias();
    let n = (duration_s * rate_hz).round() as usize;
    (0..=n)
        .map(|k| {
            let t = k as f64 / rate_hz;
            let r = lie::so3_exp(&phi(t));
            ImuSample {
                t_s: t,
                accel_mps2: r.inverse() * (acceleration(t) - GRAVITY) + b.accel_mps2,
                gyro_radps: lie::so3_right_jacobian(&phi(t)) * phi_dot(t) + b.gyro_radps,
            }
        })
        .collect()
}

/// (rotation error rad, velocity error m/s, position error m) of `predict`
/// from the true state at `t0` to `t1`, with samples at `rate_hz`.
fn prediction_errors(rate_hz: f64, t0: f64, t1: f64) -> (f64, f64, f64) {
    let samples = analytic_samples(rate_hz, t1 + 0.1);
    let pre = Preintegration::from_samples(
        &samples,
        t0,
        t1,
        true_bias(),
        ImuNoise::default(),
        2.0 / rate_hz,
    )
    .unwrap();
    let (pose_j, v_j) = pre.predict(&true_pose(t0), &velocity(t0), &true_bias(), &GRAVITY);
    let truth = true_pose(t1);
    (
        pose_j.rotation.angle_to(&truth.rotation),
        (v_j - velocity(t1)).norm(),
        (pose_j.translation.vector - truth.translation.vector).norm(),
    )
}

#[test]
fn predict_reaches_the_analytic_state() {
    // Interval ends between samples, so the interpolation is exercised.
    let (t0, t1) = (0.2037, 1.2037);
    let (rot_100, vel_100, pos_100) = prediction_errors(100.0, t0, t1);
    let (rot_400, vel_400, pos_400) = prediction_errors(400.0, t0, t1);
    println!(
        "analytic 1 s, 100 Hz: rotation {rot_100:.3e} rad, velocity {vel_100:.3e} m/s, position {pos_100:.3e} m"
    );
    println!(
        "analytic 1 s, 400 Hz: rotation {rot_400:.3e} rad, velocity {vel_400:.3e} m/s, position {pos_400:.3e} m"
    );
    assert!(rot_100 < 1e-5, "rotation error {rot_100:e}");
    assert!(vel_100 < 3e-4, "velocity error {vel_100:e}");
    assert!(pos_100 < 2e-4, "position error {pos_100:e}");
    // Second-order scheme: 4× the rate gives ~16× smaller errors.
    assert!(
        rot_100 / rot_400 > 10.0,
        "rotation ratio {}",
        rot_100 / rot_400
    );
    assert!(
        vel_100 / vel_400 > 10.0,
        "velocity ratio {}",
        vel_100 / vel_400
    );
    assert!(
        pos_100 / pos_400 > 10.0,
        "position ratio {}",
        pos_100 / pos_400
    );
}

#[test]
fn imu_factor_residual_vanishes_at_the_true_states() {
    let (t0, t1) = (0.2037, 1.2037);
    let samples = analytic_samples(100.0, 1.5);
    // Linearised at the true bias, then at a wrong one (zero) that the
    // factor corrects to first order: its bias variable holds the true bias.
    let cases = [
        ("true bias_hat", true_bias(), [1e-5, 3e-4, 2e-4]),
        ("zero bias_hat", ImuBias::default(), [1e-4, 1e-3, 5e-4]),
    ];
    for (name, bias_hat, limits) in cases {
        let pre =
            Preintegration::from_samples(&samples, t0, t1, bias_hat, ImuNoise::default(), 0.02)
                .unwrap();
        let factor = ImuFactor::new(0, 1, pre, GRAVITY).unwrap();
        let (r, _) = factor.evaluate(
            &true_pose(t0),
            &velocity(t0),
            &true_bias(),
            &true_pose(t1),
            &velocity(t1),
            &GRAVITY,
            false,
        );
        let whitened = factor
            .noise()
            .whiten(&nalgebra::DVector::from_column_slice(r.as_slice()));
        let norms = [
            r.fixed_rows::<3>(0).norm(),
            r.fixed_rows::<3>(3).norm(),
            r.fixed_rows::<3>(6).norm(),
        ];
        println!(
            "ImuFactor residual at the true states ({name}): rotation {:.3e} rad, velocity {:.3e} m/s, position {:.3e} m, whitened norm {:.3e}",
            norms[0],
            norms[1],
            norms[2],
            whitened.norm()
        );
        for (n, limit) in norms.iter().zip(limits) {
            assert!(n < &limit, "{name}: residual block {n:e} above {limit:e}");
        }
        // Far below one standard deviation of the preintegration noise.
        assert!(whitened.norm() < 0.5, "whitened {}", whitened.norm());
    }
}

#[test]
fn propagated_trajectory_follows_the_analytic_poses() {
    let (t0, t1) = (0.3, 0.4);
    let samples = analytic_samples(100.0, 1.0);
    let traj = ImuTrajectory::propagate(
        &samples,
        t0,
        t1,
        &true_pose(t0),
        &velocity(t0),
        &true_bias(),
        &GRAVITY,
        0.02,
    )
    .unwrap();
    let mut worst_pos: f64 = 0.0;
    let mut worst_rot: f64 = 0.0;
    for k in 0..=20 {
        let t = t0 + (t1 - t0) * k as f64 / 20.0;
        let pose = traj.pose_at(t).unwrap();
        let truth = true_pose(t);
        worst_pos = worst_pos.max((pose.translation.vector - truth.translation.vector).norm());
        worst_rot = worst_rot.max(pose.rotation.angle_to(&truth.rotation));
    }
    println!(
        "de-skew propagation over 0.1 s: position {worst_pos:.3e} m, rotation {worst_rot:.3e} rad"
    );
    assert!(worst_pos < 1e-5 && worst_rot < 1e-5);
}

// ---------------------------------------------------------------------------
// Covariance against Monte Carlo
// ---------------------------------------------------------------------------

/// Small deterministic Gaussian generator (SplitMix64 + Box–Muller), so the
/// test needs no extra dependency and never flakes.
struct Gauss {
    state: u64,
    spare: Option<f64>,
}

impl Gauss {
    fn new(seed: u64) -> Gauss {
        Gauss {
            state: seed,
            spare: None,
        }
    }

    fn uniform(&mut self) -> f64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        if let Some(s) = self.spare.take() {
            return s;
        }
        let (u1, u2) = (self.uniform(), self.uniform());
        let r = (-2.0 * u1.ln()).sqrt();
        let a = 2.0 * std::f64::consts::PI * u2;
        self.spare = Some(r * a.sin());
        r * a.cos()
    }

    fn vector3(&mut self, sigma: f64) -> Vector3<f64> {
        Vector3::new(self.normal(), self.normal(), self.normal()) * sigma
    }
}

#[test]
fn covariance_matches_monte_carlo() {
    let rate_hz = 100.0;
    let dt = 1.0 / rate_hz;
    let (t0, t1) = (0.0, 1.0);
    let noise = ImuNoise::default();
    let clean = analytic_samples(rate_hz, t1);
    let reference = Preintegration::from_samples(&clean, t0, t1, true_bias(), noise, 0.02).unwrap();
    let model = reference.covariance();
    let sigma_accel = noise.accel_noise_density / dt.sqrt();
    let sigma_gyro = noise.gyro_noise_density / dt.sqrt();

    let runs = 2000;
    let mut gauss = Gauss::new(0x1234_5678);
    let mut errors = Vec::with_capacity(runs);
    let mut noisy = clean.clone();
    let mut chi2_sum = 0.0;
    for _ in 0..runs {
        for (n, c) in noisy.iter_mut().zip(&clean) {
            n.accel_mps2 = c.accel_mps2 + gauss.vector3(sigma_accel);
            n.gyro_radps = c.gyro_radps + gauss.vector3(sigma_gyro);
        }
        let pre = Preintegration::from_samples(&noisy, t0, t1, true_bias(), noise, 0.02).unwrap();
        let d_phi = lie::so3_log(&(reference.delta_rotation().inverse() * pre.delta_rotation()));
        let d_v = pre.delta_velocity() - reference.delta_velocity();
        let d_p = pre.delta_position() - reference.delta_position();
        let mut e = SVector::<f64, 9>::zeros();
        e.fixed_rows_mut::<3>(0).copy_from(&d_phi);
        e.fixed_rows_mut::<3>(3).copy_from(&d_v);
        e.fixed_rows_mut::<3>(6).copy_from(&d_p);
        errors.push(e);
        // Whitened IMU-factor residual at the true states: χ² with 9 dof.
        let factor = ImuFactor::new(0, 1, pre, GRAVITY).unwrap();
        let (r, _) = factor.evaluate(
            &true_pose(t0),
            &velocity(t0),
            &true_bias(),
            &true_pose(t1),
            &velocity(t1),
            &GRAVITY,
            false,
        );
        chi2_sum += factor
            .noise()
            .whiten(&nalgebra::DVector::from_column_slice(r.as_slice()))
            .norm_squared();
    }
    let mean = errors.iter().sum::<SVector<f64, 9>>() / runs as f64;
    let mut empirical = Matrix9::zeros();
    for e in &errors {
        let d = e - mean;
        empirical += d * d.transpose();
    }
    empirical /= (runs - 1) as f64;

    let mut worst_diag: f64 = 0.0;
    let mut worst_off: f64 = 0.0;
    for i in 0..9 {
        worst_diag = worst_diag.max((empirical[(i, i)] / model[(i, i)] - 1.0).abs());
        for j in 0..9 {
            if i != j {
                let scale = (model[(i, i)] * model[(j, j)]).sqrt();
                worst_off = worst_off.max((empirical[(i, j)] - model[(i, j)]).abs() / scale);
            }
        }
    }
    let sd = |m: &Matrix9, i: usize| m[(i, i)].sqrt();
    println!(
        "Monte Carlo ({runs} runs, 1 s at 100 Hz): model σ (φ, v, p) = ({:.3e}, {:.3e}, {:.3e}), empirical ({:.3e}, {:.3e}, {:.3e})",
        sd(&model, 0),
        sd(&model, 3),
        sd(&model, 6),
        sd(&empirical, 0),
        sd(&empirical, 3),
        sd(&empirical, 6)
    );
    println!(
        "worst relative variance error {worst_diag:.3}, worst off-diagonal error (correlation units) {worst_off:.3}"
    );
    assert!(worst_diag < 0.10, "variance mismatch {worst_diag}");
    assert!(worst_off < 0.10, "covariance mismatch {worst_off}");
    // Mean χ² is 9 ± 0.09 (one σ) when residual and noise model agree.
    let chi2_mean = chi2_sum / runs as f64;
    println!("mean whitened ImuFactor χ² at the true states: {chi2_mean:.3} (expect 9)");
    assert!((chi2_mean - 9.0).abs() < 0.45, "mean χ² {chi2_mean}");
}

// ---------------------------------------------------------------------------
// First-order bias correction
// ---------------------------------------------------------------------------

/// Max over (rotation rad, velocity m/s, position m) of the difference between
/// the first-order corrected deltas and a re-integration with `bias`.
fn correction_error(samples: &[ImuSample], bias_hat: ImuBias, bias: ImuBias) -> (f64, f64) {
    let noise = ImuNoise::default();
    let pre = Preintegration::from_samples(samples, 0.05, 1.05, bias_hat, noise, 0.02).unwrap();
    let exact = Preintegration::from_samples(samples, 0.05, 1.05, bias, noise, 0.02).unwrap();
    let (r, v, p) = pre.corrected(&bias);
    let corrected_err = lie::so3_log(&(exact.delta_rotation().inverse() * r))
        .norm()
        .max((v - exact.delta_velocity()).norm())
        .max((p - exact.delta_position()).norm());
    let uncorrected_err = lie::so3_log(&(exact.delta_rotation().inverse() * pre.delta_rotation()))
        .norm()
        .max((pre.delta_velocity() - exact.delta_velocity()).norm())
        .max((pre.delta_position() - exact.delta_position()).norm());
    (corrected_err, uncorrected_err)
}

#[test]
fn bias_correction_error_is_quadratic() {
    let samples = analytic_samples(100.0, 1.2);
    let bias_hat = true_bias();
    let step = Vector6::new(0.2, -0.15, 0.1, 0.02, -0.03, 0.025);
    let mut previous: Option<f64> = None;
    for scale in [1.0, 0.5, 0.25, 0.125] {
        let bias = ImuBias::from_vector6(&(bias_hat.to_vector6() + step * scale));
        let (corrected, uncorrected) = correction_error(&samples, bias_hat, bias);
        println!(
            "bias change ×{scale}: first-order error {corrected:.3e}, uncorrected {uncorrected:.3e}"
        );
        assert!(corrected < 0.05 * uncorrected);
        if let Some(prev) = previous {
            let ratio = prev / corrected;
            assert!(
                (3.5..4.5).contains(&ratio),
                "halving the change divided the error by {ratio}"
            );
        }
        previous = Some(corrected);
    }
}

// ---------------------------------------------------------------------------
// Bias Jacobians of the preintegration against finite differences
// ---------------------------------------------------------------------------

fn preintegrate(steps: &[(Vector3<f64>, Vector3<f64>, f64)], bias_hat: ImuBias) -> Preintegration {
    let mut pre = Preintegration::new(bias_hat, ImuNoise::default());
    for (a, w, dt) in steps {
        pre.integrate(a, w, *dt);
    }
    pre
}

fn arb_vec3(range: f64) -> impl Strategy<Value = Vector3<f64>> {
    prop::array::uniform3(-range..range).prop_map(Vector3::from)
}

fn arb_steps() -> impl Strategy<Value = Vec<(Vector3<f64>, Vector3<f64>, f64)>> {
    prop::collection::vec((arb_vec3(20.0), arb_vec3(3.0), 0.001..0.02f64), 1..40)
}

fn arb_bias(accel: f64, gyro: f64) -> impl Strategy<Value = ImuBias> {
    (arb_vec3(accel), arb_vec3(gyro)).prop_map(|(a, g)| ImuBias {
        accel_mps2: a,
        gyro_radps: g,
    })
}

fn arb_pose() -> impl Strategy<Value = Isometry3<f64>> {
    (arb_vec3(50.0), arb_vec3(3.0))
        .prop_map(|(t, r)| Isometry3::from_parts(Translation3::from(t), lie::so3_exp_quat(&r)))
}

fn relative_error(analytic: &Matrix3<f64>, numeric: &Matrix3<f64>) -> f64 {
    (analytic - numeric).amax() / analytic.amax().max(numeric.amax()).max(1.0)
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 128,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn preintegration_bias_jacobians_match_finite_differences(
        steps in arb_steps(),
        bias_hat in arb_bias(0.5, 0.1),
    ) {
        let pre = preintegrate(&steps, bias_hat);
        let h = 1e-6;
        let at = |dba: &Vector3<f64>, dbg: &Vector3<f64>| {
            preintegrate(&steps, ImuBias {
                accel_mps2: bias_hat.accel_mps2 + dba,
                gyro_radps: bias_hat.gyro_radps + dbg,
            })
        };
        let z = Vector3::zeros();
        let rot = |p: &Preintegration| lie::so3_log(&(pre.delta_rotation().inverse() * p.delta_rotation()));
        let num_r_bg = lie::numerical_jacobian::<3, 3>(|d| rot(&at(&z, d)), &z, h);
        let num_v_ba = lie::numerical_jacobian::<3, 3>(|d| at(d, &z).delta_velocity(), &z, h);
        let num_v_bg = lie::numerical_jacobian::<3, 3>(|d| at(&z, d).delta_velocity(), &z, h);
        let num_p_ba = lie::numerical_jacobian::<3, 3>(|d| at(d, &z).delta_position(), &z, h);
        let num_p_bg = lie::numerical_jacobian::<3, 3>(|d| at(&z, d).delta_position(), &z, h);
        let errs = [
            relative_error(&pre.d_rotation_d_bias_gyro(), &num_r_bg),
            relative_error(&pre.d_velocity_d_bias_accel(), &num_v_ba),
            relative_error(&pre.d_velocity_d_bias_gyro(), &num_v_bg),
            relative_error(&pre.d_position_d_bias_accel(), &num_p_ba),
            relative_error(&pre.d_position_d_bias_gyro(), &num_p_bg),
        ];
        for (name, e) in ["dR/dbg", "dv/dba", "dv/dbg", "dp/dba", "dp/dbg"].iter().zip(errs) {
            prop_assert!(e < 1e-5, "{} relative error {:e}", name, e);
        }
    }

    #[test]
    fn imu_factor_jacobians_match_finite_differences(
        steps in arb_steps(),
        bias_hat in arb_bias(0.5, 0.1),
        bias_offset in arb_bias(0.3, 0.05),
        pose_i in arb_pose(),
        v_i in arb_vec3(20.0),
        pose_err in prop::array::uniform6(-0.5..0.5f64),
        v_err in arb_vec3(1.0),
        gravity in arb_vec3(10.0),
    ) {
        let pre = preintegrate(&steps, bias_hat);
        let bias_i = ImuBias::from_vector6(&(bias_hat.to_vector6() + bias_offset.to_vector6()));
        // State j near the prediction, so the rotation residual stays far from π.
        let (pred_pose, pred_v) = pre.predict(&pose_i, &v_i, &bias_i, &gravity);
        let pose_j = lie::oplus(&pred_pose, &Vector6::from(pose_err));
        let v_j = pred_v + v_err;
        let given = ImuFactor::new(7, 8, pre.clone(), gravity).unwrap();
        // gravity as the variable Key::Gravity, at the same value
        let estimated = ImuFactor::with_estimated_gravity(7, 8, pre).unwrap();
        let mut values = Values::new();
        values.insert(Key::EgoPose(7), Variable::Pose(pose_i));
        values.insert(Key::EgoVelocity(7), Variable::Vector3(v_i));
        values.insert(Key::EgoBias(7), Variable::Bias(bias_i));
        values.insert(Key::EgoPose(8), Variable::Pose(pose_j));
        values.insert(Key::EgoVelocity(8), Variable::Vector3(v_j));
        values.insert(Key::Gravity, Variable::Vector3(gravity));
        for factor in [&given, &estimated] {
            let lin = Linearization::of(factor, &values);
            prop_assert_eq!(lin.jacobians.len(), factor.keys().len());
            let scale = lin.jacobians.iter().map(|j| j.amax()).fold(1.0, f64::max);
            let err = check_factor_jacobians(factor, &values, 1e-6);
            prop_assert!(err < 1e-5 * scale, "Jacobian error {:e} (scale {:e})", err, scale);
            // The residual-only path agrees with linearize.
            prop_assert!((factor.residual(&values) - lin.residual).amax() == 0.0);
        }
        prop_assert!((given.residual(&values) - estimated.residual(&values)).amax() == 0.0);
    }

    #[test]
    fn bias_random_walk_jacobians_match_finite_differences(
        b_i in arb_bias(1.0, 0.2),
        b_j in arb_bias(1.0, 0.2),
        dt in 0.01..1.0f64,
    ) {
        let factor = BiasRandomWalkFactor::new(2, 3, dt, &ImuNoise::default()).unwrap();
        let mut values = Values::new();
        values.insert(Key::EgoBias(2), Variable::Bias(b_i));
        values.insert(Key::EgoBias(3), Variable::Bias(b_j));
        let err = check_factor_jacobians(&factor, &values, 1e-6);
        prop_assert!(err < 1e-5, "Jacobian error {:e}", err);
        let r = factor.residual(&values);
        prop_assert!((r - nalgebra::DVector::from_column_slice((b_j.to_vector6() - b_i.to_vector6()).as_slice())).amax() < 1e-15);
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 128,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// The de-skew propagator and `predict` implement the same scheme: the
    /// propagated end state equals the prediction, and a query inside the
    /// interval equals a propagation that ends there.
    #[test]
    fn trajectory_agrees_with_prediction(
        steps in prop::collection::vec((arb_vec3(20.0), arb_vec3(3.0), 0.002..0.02f64), 3..30),
        bias in arb_bias(0.5, 0.1),
        pose in arb_pose(),
        v in arb_vec3(20.0),
        start_frac in 0.0..0.3f64,
        end_frac in 0.7..1.0f64,
        mid_frac in 0.0..1.0f64,
    ) {
        let mut t = 10.0;
        let samples: Vec<ImuSample> = steps
            .iter()
            .map(|(a, w, dt)| {
                t += dt;
                ImuSample { t_s: t, accel_mps2: *a, gyro_radps: *w }
            })
            .collect();
        let (first, last) = (samples[0].t_s, samples[samples.len() - 1].t_s);
        let t0 = first + (last - first) * start_frac;
        let t1 = first + (last - first) * end_frac;
        let t_mid = t0 + (t1 - t0) * mid_frac;
        let pre = Preintegration::from_samples(&samples, t0, t1, bias, ImuNoise::default(), 0.05).unwrap();
        let (pose_j, v_j) = pre.predict(&pose, &v, &bias, &GRAVITY);
        let traj = ImuTrajectory::propagate(&samples, t0, t1, &pose, &v, &bias, &GRAVITY, 0.05).unwrap();
        let (end_pose, end_v) = traj.end_state();
        let tol = 1e-9 * (1.0 + pose_j.translation.vector.norm() + v_j.norm());
        prop_assert!((end_pose.translation.vector - pose_j.translation.vector).norm() < tol);
        prop_assert!((end_v - v_j).norm() < tol);
        prop_assert!(end_pose.rotation.angle_to(&pose_j.rotation) < 1e-9);
        if t_mid > t0 {
            let sub = ImuTrajectory::propagate(&samples, t0, t_mid, &pose, &v, &bias, &GRAVITY, 0.05)
                .unwrap()
                .end_state()
                .0;
            let at = traj.pose_at(t_mid).unwrap();
            prop_assert!((at.translation.vector - sub.translation.vector).norm() < tol);
            prop_assert!(at.rotation.angle_to(&sub.rotation) < 1e-9);
        }
    }
}

fn arb_sample() -> impl Strategy<Value = ImuSample> {
    let value = prop_oneof![
        8 => -50.0..50.0f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
    ];
    (
        prop_oneof![9 => 0.0..1.0f64, 1 => Just(f64::NAN)],
        prop::array::uniform3(value.clone()),
        prop::array::uniform3(value),
    )
        .prop_map(|(t_s, a, w)| ImuSample {
            t_s,
            accel_mps2: Vector3::from(a),
            gyro_radps: Vector3::from(w),
        })
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Arbitrary (unsorted, non-finite, sparse) input gives Ok or an error,
    /// never a panic, and Ok results are finite.
    #[test]
    fn from_samples_never_panics(
        mut samples in prop::collection::vec(arb_sample(), 0..30),
        sort in any::<bool>(),
        t0 in -0.1..1.1f64,
        len in -0.2..1.0f64,
        max_gap in prop_oneof![Just(0.0), 0.01..0.5f64],
        query in -0.2..1.2f64,
    ) {
        if sort {
            samples.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        }
        let t1 = t0 + len;
        if let Ok(pre) = from(&samples, t0, t1, max_gap) {
            prop_assert!(pre.delta_position().iter().all(|v| v.is_finite()));
            prop_assert!(pre.covariance().iter().all(|v| v.is_finite()));
        }
        let traj = ImuTrajectory::propagate(
            &samples,
            t0,
            t1,
            &Isometry3::identity(),
            &Vector3::zeros(),
            &ImuBias::default(),
            &GRAVITY,
            max_gap,
        );
        if let Ok(traj) = traj
            && let Ok(pose) = traj.pose_at(query)
        {
            prop_assert!(pose.translation.vector.iter().all(|v| v.is_finite()));
        }
    }
}

// ---------------------------------------------------------------------------
// Input errors
// ---------------------------------------------------------------------------

fn regular_samples(n: usize, dt: f64) -> Vec<ImuSample> {
    (0..n)
        .map(|k| ImuSample {
            t_s: k as f64 * dt,
            accel_mps2: Vector3::new(0.0, 0.0, 9.8),
            gyro_radps: Vector3::zeros(),
        })
        .collect()
}

fn from(
    samples: &[ImuSample],
    t0: f64,
    t1: f64,
    max_gap: f64,
) -> Result<Preintegration, PreintegrationError> {
    Preintegration::from_samples(
        samples,
        t0,
        t1,
        ImuBias::default(),
        ImuNoise::default(),
        max_gap,
    )
}

#[test]
fn from_samples_reports_bad_input() {
    let samples = regular_samples(11, 0.01); // t = 0 .. 0.1
    assert!(from(&samples, 0.0, 0.1, 0.02).is_ok());
    assert!(from(&samples, 0.013, 0.087, 0.02).is_ok());

    // Reversed and empty intervals.
    assert!(matches!(
        from(&samples, 0.05, 0.02, 0.02),
        Err(PreintegrationError::BadInterval { .. })
    ));
    assert!(matches!(
        from(&samples, 0.05, 0.05, 0.02),
        Err(PreintegrationError::BadInterval { .. })
    ));
    assert!(matches!(
        from(&samples, f64::NAN, 0.05, 0.02),
        Err(PreintegrationError::BadInterval { .. })
    ));
    assert!(matches!(
        from(&samples, 0.0, 0.1, 0.0),
        Err(PreintegrationError::BadMaxGap { .. })
    ));

    // Not covered at either end, and no samples at all.
    assert!(matches!(
        from(&samples, -0.01, 0.05, 0.02),
        Err(PreintegrationError::NotCovered { .. })
    ));
    assert!(matches!(
        from(&samples, 0.05, 0.11, 0.02),
        Err(PreintegrationError::NotCovered { .. })
    ));
    assert!(matches!(
        from(&samples, 0.2, 0.3, 0.02),
        Err(PreintegrationError::NotCovered { .. })
    ));
    assert!(matches!(
        from(&[], 0.0, 0.1, 0.02),
        Err(PreintegrationError::NoSamples { .. })
    ));

    // A gap: drop the samples at 0.04 and 0.05.
    let mut gappy = samples.clone();
    gappy.drain(4..6);
    let err = from(&gappy, 0.0, 0.1, 0.02).unwrap_err();
    assert!(matches!(err, PreintegrationError::Gap { .. }), "{err}");
    println!("gap error: {err}");
    // ...which is fine when the interval avoids it or the limit allows it.
    assert!(from(&gappy, 0.06, 0.1, 0.02).is_ok());
    assert!(from(&gappy, 0.0, 0.1, 0.05).is_ok());

    // Non-finite values and unordered times inside the interval.
    let mut bad = samples.clone();
    bad[3].accel_mps2.y = f64::NAN;
    let err = from(&bad, 0.0, 0.1, 0.02).unwrap_err();
    assert_eq!(
        err,
        PreintegrationError::NonFinite {
            index: 3,
            t_s: 0.03,
            field: "accel_mps2"
        }
    );
    println!("non-finite error: {err}");
    assert!(
        from(&bad, 0.04, 0.1, 0.02).is_ok(),
        "a bad sample outside the interval is not used"
    );
    let mut bad = samples.clone();
    bad[5].gyro_radps.z = f64::INFINITY;
    assert!(matches!(
        from(&bad, 0.0, 0.1, 0.02),
        Err(PreintegrationError::NonFinite {
            field: "gyro_radps",
            ..
        })
    ));
    let mut bad = samples.clone();
    bad[6].t_s = 0.045;
    assert!(matches!(
        from(&bad, 0.0, 0.1, 0.02),
        Err(PreintegrationError::NotIncreasing { index: 6, .. })
    ));

    // The trajectory propagator shares the checks and rejects queries outside.
    let traj = ImuTrajectory::propagate(
        &samples,
        0.0,
        0.1,
        &Isometry3::identity(),
        &Vector3::zeros(),
        &ImuBias::default(),
        &GRAVITY,
        0.02,
    )
    .unwrap();
    assert!(matches!(
        traj.pose_at(-0.01),
        Err(PreintegrationError::TimeOutside { .. })
    ));
    assert!(matches!(
        traj.pose_at(f64::NAN),
        Err(PreintegrationError::TimeOutside { .. })
    ));
    assert!(
        ImuTrajectory::propagate(
            &gappy,
            0.0,
            0.1,
            &Isometry3::identity(),
            &Vector3::zeros(),
            &ImuBias::default(),
            &GRAVITY,
            0.02,
        )
        .is_err()
    );
}

#[test]
fn static_imu_predicts_rest() {
    // A level IMU at rest measures -g; prediction must stay put.
    let samples: Vec<ImuSample> = (0..=100)
        .map(|k| ImuSample {
            t_s: k as f64 * 0.01,
            accel_mps2: -GRAVITY,
            gyro_radps: Vector3::zeros(),
        })
        .collect();
    let pre = from(&samples, 0.0, 1.0, 0.02).unwrap();
    let start = Isometry3::from_parts(
        Translation3::new(1.0, 2.0, 3.0),
        nalgebra::UnitQuaternion::identity(),
    );
    let (pose, v) = pre.predict(&start, &Vector3::zeros(), &ImuBias::default(), &GRAVITY);
    assert!((pose.translation.vector - start.translation.vector).norm() < 1e-12);
    assert!(v.norm() < 1e-12);
    assert_eq!(pose.rotation.to_rotation_matrix(), Rotation3::identity());
}
