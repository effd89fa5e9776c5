//! Property and behaviour tests of the graph back end: factor Jacobians,
//! marginalization exactness on linear-Gaussian problems, LM on a nonlinear
//! pose graph, robust kernels, error paths and timing of window-sized solves.

use limot_estimator::graph::{
    BetweenFactor, Factor, JacobiansMut, Key, Linearization, MarginalizationConfig, NoiseModel,
    PriorFactor, RobustKernel, SlidingWindowSmoother, SolverConfig, SolverError, Values, Variable,
    VariableIndex, WindowError, check_factor_jacobians, gauss_newton_step,
    linearize_normal_equations, marginal_covariance, marginalize, optimize, total_cost,
};
use limot_estimator::imu::ImuBias;
use limot_estimator::lie;
use nalgebra::{DMatrix, DVector, Isometry3, Translation3, UnitQuaternion, Vector3, Vector6};
use proptest::prelude::*;
use std::time::Instant;

use limot_test_support::SplitMix64 as Rng;

/// Samples drawn from the shared test generator: Lie-group elements and a bounded normal.
trait LieSamples {
    /// Approximately normal (sum of twelve uniforms, bounded at ±6), unit variance.
    fn irwin_hall_normal(&mut self) -> f64;
    fn vector6(&mut self, scale_rho: f64, scale_phi: f64) -> Vector6<f64>;
    fn pose(&mut self) -> Isometry3<f64>;
}

impl LieSamples for Rng {
    fn irwin_hall_normal(&mut self) -> f64 {
        (0..12).map(|_| self.uniform()).sum::<f64>() - 6.0
    }
    fn vector6(&mut self, scale_rho: f64, scale_phi: f64) -> Vector6<f64> {
        lie::xi_from_parts(&self.vector3(scale_rho), &self.vector3(scale_phi))
    }
    fn pose(&mut self) -> Isometry3<f64> {
        lie::se3_exp(&self.vector6(5.0, 3.0))
    }
}

// ---------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------

fn vector_of(value: &Variable) -> DVector<f64> {
    match value {
        Variable::Vector3(v) => DVector::from_column_slice(v.as_slice()),
        Variable::Bias(b) => DVector::from_column_slice(b.to_vector6().as_slice()),
        Variable::Pose(_) => panic!("linear test factor on a pose"),
    }
}

/// `r = Σ Aᵢ·xᵢ - b` on Euclidean variables: the linear-Gaussian test factor.
#[derive(Debug)]
struct LinearFactor {
    keys: Vec<Key>,
    a: Vec<DMatrix<f64>>,
    b: DVector<f64>,
    noise: NoiseModel,
}

impl Factor for LinearFactor {
    fn keys(&self) -> &[Key] {
        &self.keys
    }
    fn residual_dim(&self) -> usize {
        self.b.len()
    }
    fn linearize_into(
        &self,
        values: &Values,
        residual: &mut [f64],
        jacobians: &mut JacobiansMut<'_>,
    ) {
        self.residual_into(values, residual);
        for (i, a) in self.a.iter().enumerate() {
            jacobians.set(i, a);
        }
    }
    fn residual_into(&self, values: &Values, residual: &mut [f64]) {
        let mut r = -self.b.clone();
        for (key, a) in self.keys.iter().zip(&self.a) {
            r += a * vector_of(values.get(key).expect("key"));
        }
        residual.copy_from_slice(r.as_slice());
    }
    fn noise(&self) -> &NoiseModel {
        &self.noise
    }
}

/// A factor whose residual is NaN.
#[derive(Debug)]
struct NanFactor {
    keys: [Key; 1],
    noise: NoiseModel,
}

impl Factor for NanFactor {
    fn keys(&self) -> &[Key] {
        &self.keys
    }
    fn residual_dim(&self) -> usize {
        3
    }
    fn linearize_into(
        &self,
        values: &Values,
        residual: &mut [f64],
        jacobians: &mut JacobiansMut<'_>,
    ) {
        self.residual_into(values, residual);
        jacobians.set_scaled_identity(0, 1.0);
    }
    fn residual_into(&self, _values: &Values, residual: &mut [f64]) {
        residual.fill(f64::NAN);
    }
    fn noise(&self) -> &NoiseModel {
        &self.noise
    }
}

fn gauss_newton() -> SolverConfig {
    SolverConfig {
        initial_lambda: 0.0,
        ..SolverConfig::default()
    }
}

fn pose_distance(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    let xi = lie::ominus(a, b);
    (lie::xi_rho(&xi).norm(), lie::xi_phi(&xi).norm())
}

// ---------------------------------------------------------------------------
// Jacobians against finite differences
// ---------------------------------------------------------------------------

const FD_STEP: f64 = 1e-6;
const FD_TOL: f64 = 1e-6;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn between_factor_jacobians(seed in any::<u64>()) {
        let mut rng = Rng(seed);
        let (t_a, t_b) = (rng.pose(), rng.pose());
        let measured = rng.pose();
        let mut values = Values::new();
        values.insert(Key::EgoPose(0), Variable::Pose(t_a));
        values.insert(Key::ObjectPose { id: 3, frame: 0 }, Variable::Pose(t_b));
        let factor = BetweenFactor::new(
            Key::EgoPose(0),
            Key::ObjectPose { id: 3, frame: 0 },
            measured,
            NoiseModel::diagonal_sigmas(&[0.1; 6]),
        );
        // Residual within the log's injectivity radius (|φ| < π) only.
        let r = factor.residual(&values);
        prop_assume!(r.rows(3, 3).norm() < 3.0);
        let err = check_factor_jacobians(&factor, &values, FD_STEP);
        prop_assert!(err < FD_TOL * r.amax().max(1.0), "error {err:e}");
    }

    #[test]
    fn prior_factor_jacobians(seed in any::<u64>()) {
        let mut rng = Rng(seed);
        let pose_value = Variable::Pose(rng.pose());
        let pose_prior = Variable::Pose(rng.pose());
        let cases = [
            (Key::EgoPose(1), pose_value, pose_prior),
            (Key::EgoVelocity(1), Variable::Vector3(rng.vector3(10.0)), Variable::Vector3(rng.vector3(10.0))),
            (
                Key::EgoBias(1),
                Variable::Bias(ImuBias::from_vector6(&rng.vector6(0.5, 0.05))),
                Variable::Bias(ImuBias::from_vector6(&rng.vector6(0.5, 0.05))),
            ),
        ];
        for (key, value, prior) in cases {
            let mut values = Values::new();
            values.insert(key, value);
            let factor = PriorFactor::new(key, prior, NoiseModel::diagonal_sigmas(&vec![0.2; value.dim()]));
            let r = factor.residual(&values);
            if matches!(value, Variable::Pose(_)) && r.rows(3, 3).norm() > 3.0 {
                continue;
            }
            let err = check_factor_jacobians(&factor, &values, FD_STEP);
            prop_assert!(err < FD_TOL * r.amax().max(1.0), "{key}: error {err:e}");
        }
    }

    #[test]
    fn marginal_prior_factor_jacobians(seed in any::<u64>()) {
        let mut rng = Rng(seed);
        // x0 — x1 — x2 poses, v1 velocity, b1 bias; marginalize x0 and a
        // mixed set of keys so the prior covers poses and Euclidean keys.
        let mut values = Values::new();
        for k in 0..3 {
            values.insert(Key::EgoPose(k), Variable::Pose(rng.pose()));
        }
        values.insert(Key::EgoVelocity(1), Variable::Vector3(rng.vector3(3.0)));
        values.insert(Key::EgoBias(1), Variable::Bias(ImuBias::from_vector6(&rng.vector6(0.2, 0.02))));
        let noise = NoiseModel::diagonal_sigmas(&[0.1, 0.1, 0.1, 0.05, 0.05, 0.05]);
        let mut factors: Vec<Box<dyn Factor>> = vec![
            Box::new(PriorFactor::new(Key::EgoPose(0), Variable::Pose(rng.pose()), noise.clone())),
        ];
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            let t_ab = lie::between(values.pose(&Key::EgoPose(a)), values.pose(&Key::EgoPose(b)));
            factors.push(Box::new(BetweenFactor::new(
                Key::EgoPose(a),
                Key::EgoPose(b),
                t_ab * lie::se3_exp(&rng.vector6(0.1, 0.05)),
                noise.clone(),
            )));
        }
        factors.push(Box::new(LinearFactor {
            keys: vec![Key::EgoVelocity(1), Key::EgoBias(1)],
            a: vec![DMatrix::identity(3, 3), DMatrix::from_fn(3, 6, |_, _| rng.range(-1.0, 1.0))],
            b: DVector::from_fn(3, |_, _| rng.range(-1.0, 1.0)),
            noise: NoiseModel::diagonal_sigmas(&[0.5; 3]),
        }));
        let touching: Vec<&dyn Factor> = factors.iter().map(|f| f.as_ref()).collect();
        let prior = marginalize(
            &touching,
            &values,
            &[Key::EgoPose(0), Key::EgoVelocity(1)],
            &MarginalizationConfig::default(),
        )
        .unwrap()
        .expect("a prior on the kept keys");
        prop_assert_eq!(prior.keys(), &[Key::EgoPose(1), Key::EgoPose(2), Key::EgoBias(1)]);
        // At the linearization point, its gradient and Hessian are those of
        // the Schur complement; away from it, the Jacobian must still match FD.
        let mut moved = values.clone();
        moved.remove(&Key::EgoPose(0));
        moved.remove(&Key::EgoVelocity(1));
        for key in [Key::EgoPose(1), Key::EgoPose(2)] {
            let d = rng.vector6(0.5, 0.4);
            moved.retract_key(&key, d.as_slice());
        }
        moved.retract_key(&Key::EgoBias(1), rng.vector6(0.1, 0.1).as_slice());
        let err = check_factor_jacobians(&prior, &moved, FD_STEP);
        let scale = prior.residual(&moved).amax().max(1.0);
        prop_assert!(err < FD_TOL * scale * 10.0, "error {err:e}");
    }
}

// ---------------------------------------------------------------------------
// Marginalization exactness on linear-Gaussian problems
// ---------------------------------------------------------------------------

/// A random linear-Gaussian chain: factors grouped by the newest state they
/// touch, so a smoother can add them when that state arrives.
struct LinearProblem {
    num_states: u64,
    /// `factors_at[k]`: factors whose newest state is `k`.
    factors_at: Vec<Vec<LinearFactor>>,
}

fn state(k: u64) -> Key {
    Key::EgoVelocity(k)
}

fn linear_problem(seed: u64, max_span: u64) -> LinearProblem {
    let mut rng = Rng(seed);
    let num_states = 8 + rng.index(8) as u64;
    let truth: Vec<Vector3<f64>> = (0..num_states).map(|_| rng.vector3(5.0)).collect();
    let mut factors_at: Vec<Vec<LinearFactor>> = (0..num_states).map(|_| Vec::new()).collect();
    let noisy = |rng: &mut Rng, v: DVector<f64>, sigmas: &[f64]| {
        DVector::from_fn(v.len(), |i, _| v[i] + sigmas[i] * rng.irwin_hall_normal())
    };
    // Prior on the first state.
    let sigmas: Vec<f64> = (0..3).map(|_| rng.range(0.2, 2.0)).collect();
    let b = noisy(
        &mut rng,
        DVector::from_column_slice(truth[0].as_slice()),
        &sigmas,
    );
    factors_at[0].push(LinearFactor {
        keys: vec![state(0)],
        a: vec![DMatrix::identity(3, 3)],
        b,
        noise: NoiseModel::diagonal_sigmas(&sigmas),
    });
    for k in 1..num_states {
        // Between-type factor on the difference.
        let sigmas: Vec<f64> = (0..3).map(|_| rng.range(0.1, 1.0)).collect();
        let diff = truth[k as usize] - truth[k as usize - 1];
        let b = noisy(
            &mut rng,
            DVector::from_column_slice(diff.as_slice()),
            &sigmas,
        );
        factors_at[k as usize].push(LinearFactor {
            keys: vec![state(k - 1), state(k)],
            a: vec![-DMatrix::identity(3, 3), DMatrix::identity(3, 3)],
            b,
            noise: NoiseModel::diagonal_sigmas(&sigmas),
        });
    }
    // Random extra measurements: unary (these touch only the state being
    // marginalized later) and multi-state ones within `max_span`.
    for k in 0..num_states {
        for _ in 0..rng.index(3) {
            let span = rng.index(max_span as usize + 1) as u64;
            let oldest = k.saturating_sub(span);
            let mut keys = vec![state(k)];
            if oldest < k {
                keys.push(state(oldest + rng.index((k - oldest) as usize) as u64));
            }
            let rows = 1 + rng.index(3);
            let a: Vec<DMatrix<f64>> = keys
                .iter()
                .map(|_| DMatrix::from_fn(rows, 3, |_, _| rng.range(-1.5, 1.5)))
                .collect();
            let mut exact = DVector::zeros(rows);
            for (key, a) in keys.iter().zip(&a) {
                let Key::EgoVelocity(j) = key else {
                    unreachable!()
                };
                exact += a * DVector::from_column_slice(truth[*j as usize].as_slice());
            }
            let sigmas: Vec<f64> = (0..rows).map(|_| rng.range(0.3, 3.0)).collect();
            let b = noisy(&mut rng, exact, &sigmas);
            factors_at[k as usize].push(LinearFactor {
                keys,
                a,
                b,
                noise: NoiseModel::diagonal_sigmas(&sigmas),
            });
        }
    }
    LinearProblem {
        num_states,
        factors_at,
    }
}

fn clone_linear(f: &LinearFactor) -> LinearFactor {
    LinearFactor {
        keys: f.keys.clone(),
        a: f.a.clone(),
        b: f.b.clone(),
        noise: f.noise.clone(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn marginalized_window_equals_batch_on_linear_gaussian_problems(seed in any::<u64>()) {
        const WINDOW: usize = 5;
        let problem = linear_problem(seed, WINDOW as u64 - 1);

        // (a) Batch over all states.
        let batch_factors: Vec<Box<dyn Factor>> = problem
            .factors_at
            .iter()
            .flatten()
            .map(|f| Box::new(clone_linear(f)) as Box<dyn Factor>)
            .collect();
        let mut batch = Values::new();
        for k in 0..problem.num_states {
            batch.insert(state(k), Variable::Vector3(Vector3::zeros()));
        }
        let report = optimize(&batch_factors, &mut batch, &gauss_newton()).unwrap();
        prop_assert!(report.converged);

        // (b) Window of 5, marginalizing the oldest state after each addition.
        let mut window = SlidingWindowSmoother::new();
        for k in 0..problem.num_states {
            window.add_variable(state(k), Variable::Vector3(Vector3::zeros())).unwrap();
            for f in &problem.factors_at[k as usize] {
                window.add_factor(Box::new(clone_linear(f))).unwrap();
            }
            window.optimize(&gauss_newton()).unwrap();
            if window.keys().len() > WINDOW {
                let oldest = window.oldest_frame().unwrap();
                let removed = window.marginalize_frame(oldest).unwrap();
                prop_assert_eq!(removed, vec![state(oldest)]);
            }
        }
        prop_assert_eq!(window.keys().len(), WINDOW);
        let report = window.optimize(&gauss_newton()).unwrap();
        prop_assert!(report.converged);

        let batch_refs: Vec<&dyn Factor> = batch_factors.iter().map(|f| f.as_ref()).collect();
        for key in window.keys() {
            let w = vector_of(window.values().get(&key).unwrap());
            let b = vector_of(batch.get(&key).unwrap());
            prop_assert!((&w - &b).amax() < 1e-9, "{key}: window {w} batch {b}");
            let cov_window = window.marginal_covariance(key).unwrap();
            let cov_batch = marginal_covariance(&batch_refs, &batch, &[key]).unwrap();
            prop_assert!(
                (&cov_window - &cov_batch).amax() < 1e-9,
                "{key}: covariance window {cov_window} batch {cov_batch}"
            );
        }
    }
}

// ---------------------------------------------------------------------------
// Nonlinear pose graph
// ---------------------------------------------------------------------------

struct PoseGraph {
    factors: Vec<Box<dyn Factor>>,
    truth: Values,
    initial: Values,
}

/// A loop of `n` poses on a circle, noisy between factors (including the
/// loop closure), a prior on the first pose; initial values perturbed by
/// 0.5 m and 10° in random directions.
fn pose_loop(seed: u64, n: u64) -> PoseGraph {
    let mut rng = Rng(seed);
    let mut truth = Values::new();
    for k in 0..n {
        let angle = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
        let t = Isometry3::from_parts(
            Translation3::new(
                10.0 * angle.cos(),
                10.0 * angle.sin(),
                0.5 * (3.0 * angle).sin(),
            ),
            UnitQuaternion::from_euler_angles(0.1 * angle.sin(), 0.05, angle + 1.5),
        );
        truth.insert(Key::EgoPose(k), Variable::Pose(t));
    }
    let sigmas = [0.05, 0.05, 0.05, 0.01, 0.01, 0.01];
    let noise = NoiseModel::diagonal_sigmas(&sigmas);
    let mut factors: Vec<Box<dyn Factor>> = vec![Box::new(PriorFactor::new(
        Key::EgoPose(0),
        *truth.get(&Key::EgoPose(0)).unwrap(),
        NoiseModel::diagonal_sigmas(&[0.01; 6]),
    ))];
    let mut edges: Vec<(u64, u64)> = (0..n).map(|k| (k, (k + 1) % n)).collect();
    edges.push((0, n / 2));
    for (a, b) in edges {
        let t_ab = lie::between(truth.pose(&Key::EgoPose(a)), truth.pose(&Key::EgoPose(b)));
        let noise_xi = Vector6::from_fn(|i, _| sigmas[i] * rng.irwin_hall_normal());
        factors.push(Box::new(BetweenFactor::new(
            Key::EgoPose(a),
            Key::EgoPose(b),
            t_ab * lie::se3_exp(&noise_xi),
            noise.clone(),
        )));
    }
    let mut initial = truth.clone();
    for k in 0..n {
        let rho = rng.vector3(1.0).normalize() * 0.5;
        let phi = rng.vector3(1.0).normalize() * 10f64.to_radians();
        initial.retract_key(&Key::EgoPose(k), lie::xi_from_parts(&rho, &phi).as_slice());
    }
    PoseGraph {
        factors,
        truth,
        initial,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    #[test]
    fn lm_converges_to_the_least_squares_optimum_of_a_pose_loop(seed in any::<u64>()) {
        let graph = pose_loop(seed, 12);
        let mut values = graph.initial.clone();
        let report = optimize(&graph.factors, &mut values, &SolverConfig::default()).unwrap();
        prop_assert!(report.converged, "{report:?}");
        prop_assert!(report.final_cost < report.initial_cost);
        // First-order optimality: the Gauss–Newton step at the solution vanishes.
        let (_, step) = gauss_newton_step(&graph.factors, &values).unwrap();
        prop_assert!(step.amax() < 1e-7, "remaining step {:e}", step.amax());
        // Same optimum as LM started from the truth.
        let mut from_truth = graph.truth.clone();
        optimize(&graph.factors, &mut from_truth, &SolverConfig::default()).unwrap();
        for (key, v) in values.iter() {
            let (dt, dr) = pose_distance(
                match v { Variable::Pose(t) => t, _ => unreachable!() },
                from_truth.pose(key),
            );
            prop_assert!(dt < 1e-6 && dr < 1e-7, "{key}: {dt:e} m {dr:e} rad");
        }
        prop_assert!((report.final_cost - total_cost(&graph.factors, &from_truth).unwrap()).abs() < 1e-9 * report.final_cost.max(1.0));
        // The estimate is close to the truth (noise-limited).
        for k in 0..12 {
            let (dt, dr) = pose_distance(values.pose(&Key::EgoPose(k)), graph.truth.pose(&Key::EgoPose(k)));
            prop_assert!(dt < 1.0 && dr < 0.15, "x{k}: {dt} m {dr} rad from truth");
        }
    }

    #[test]
    fn sparse_gauss_newton_step_equals_dense_solve(seed in any::<u64>()) {
        let graph = pose_loop(seed, 10);
        let (normal, step) = gauss_newton_step(&graph.factors, &graph.initial).unwrap();
        let h = normal.dense_hessian();
        prop_assert!((&h - h.transpose()).amax() < 1e-9 * h.amax());
        let dense = h.clone().cholesky().expect("SPD").solve(&(-&normal.gradient));
        let err = (&step - &dense).amax();
        prop_assert!(err < 1e-9 * dense.amax().max(1.0), "sparse vs dense {err:e}");
        // And the step satisfies the normal equations.
        prop_assert!((h * &step + &normal.gradient).amax() < 1e-6 * normal.gradient.amax().max(1.0));
    }
}

#[test]
fn normal_equations_match_dense_jacobian_products() {
    // H = JᵀJ and g = Jᵀr from an explicitly stacked dense J.
    let graph = pose_loop(7, 6);
    let values = &graph.initial;
    let index = VariableIndex::from_values(values);
    let normal = linearize_normal_equations(&graph.factors, values, &index).unwrap();
    let rows: usize = graph.factors.iter().map(|f| f.noise().dim()).sum();
    let mut j = DMatrix::zeros(rows, index.total_dim());
    let mut r = DVector::zeros(rows);
    let mut row = 0;
    for f in &graph.factors {
        let lin = Linearization::of(f.as_ref(), values);
        let l = &f.noise().sqrt_information;
        let d = lin.residual.len();
        r.rows_mut(row, d).copy_from(&(l * &lin.residual));
        for (key, jac) in f.keys().iter().zip(&lin.jacobians) {
            let (o, dim) = index.span(key).unwrap();
            j.view_mut((row, o), (d, dim)).copy_from(&(l * jac));
        }
        row += d;
    }
    let h = j.transpose() * &j;
    let g = j.transpose() * &r;
    assert!((normal.dense_hessian() - h).amax() < 1e-6);
    assert!((normal.gradient - g).amax() < 1e-6);
    assert!((normal.cost - 0.5 * r.norm_squared()).abs() < 1e-9 * normal.cost);
}

// ---------------------------------------------------------------------------
// Robust kernels
// ---------------------------------------------------------------------------

/// A chain of 6 poses, each link measured three times (exactly), a prior,
/// and one gross outlier on link 2→3 (3 m, 30°); returns the worst distance
/// of the solution from the outlier-free optimum (the truth).
fn outlier_displacement(kernel: Option<RobustKernel>) -> (f64, f64) {
    let sigmas = [0.05, 0.05, 0.05, 0.01, 0.01, 0.01];
    let mut noise = NoiseModel::diagonal_sigmas(&sigmas);
    noise.robust = kernel;
    let mut truth = Values::new();
    for k in 0..6 {
        let t = Isometry3::from_parts(
            Translation3::new(2.0 * k as f64, 0.1 * k as f64, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.05 * k as f64),
        );
        truth.insert(Key::EgoPose(k), Variable::Pose(t));
    }
    let mut factors: Vec<Box<dyn Factor>> = vec![Box::new(PriorFactor::new(
        Key::EgoPose(0),
        *truth.get(&Key::EgoPose(0)).unwrap(),
        NoiseModel::diagonal_sigmas(&[0.01; 6]),
    ))];
    for k in 0..5 {
        let t_ab = lie::between(
            truth.pose(&Key::EgoPose(k)),
            truth.pose(&Key::EgoPose(k + 1)),
        );
        for _ in 0..3 {
            factors.push(Box::new(BetweenFactor::new(
                Key::EgoPose(k),
                Key::EgoPose(k + 1),
                t_ab,
                noise.clone(),
            )));
        }
    }
    let t_23 = lie::between(truth.pose(&Key::EgoPose(2)), truth.pose(&Key::EgoPose(3)));
    let outlier = t_23 * lie::se3_exp(&Vector6::new(3.0, -1.0, 0.5, 0.1, 0.2, 0.5));
    factors.push(Box::new(BetweenFactor::new(
        Key::EgoPose(2),
        Key::EgoPose(3),
        outlier,
        noise,
    )));
    let mut values = truth.clone();
    let report = optimize(&factors, &mut values, &SolverConfig::default()).unwrap();
    assert!(report.converged, "{report:?}");
    (0..6)
        .map(|k| pose_distance(values.pose(&Key::EgoPose(k)), truth.pose(&Key::EgoPose(k))))
        .fold((0.0, 0.0), |(t, r), (dt, dr)| {
            (f64::max(t, dt), f64::max(r, dr))
        })
}

#[test]
fn robust_kernels_reject_a_gross_outlier() {
    let (plain_t, plain_r) = outlier_displacement(None);
    let (huber_t, huber_r) = outlier_displacement(Some(RobustKernel::Huber { k: 1.345 }));
    let (cauchy_t, cauchy_r) = outlier_displacement(Some(RobustKernel::Cauchy { k: 2.0 }));
    println!(
        "outlier displacement: plain {plain_t:.4} m {plain_r:.4} rad, Huber {huber_t:.5} m {huber_r:.5} rad, Cauchy {cauchy_t:.6} m {cauchy_r:.6} rad"
    );
    // Without a kernel the outlier drags the chain by a large fraction of its error.
    assert!(plain_t > 0.5, "plain {plain_t}");
    assert!(
        huber_t < 0.05 && huber_r < 0.01,
        "Huber {huber_t} {huber_r}"
    );
    assert!(
        cauchy_t < 0.01 && cauchy_r < 0.002,
        "Cauchy {cauchy_t} {cauchy_r}"
    );
}

// ---------------------------------------------------------------------------
// Error paths
// ---------------------------------------------------------------------------

#[test]
fn missing_key_and_non_finite_residual_are_errors() {
    let mut values = Values::new();
    values.insert(Key::EgoVelocity(0), Variable::Vector3(Vector3::zeros()));
    let prior = PriorFactor::new(
        Key::EgoVelocity(0),
        Variable::Vector3(Vector3::new(1.0, 2.0, 3.0)),
        NoiseModel::diagonal_sigmas(&[1.0; 3]),
    );
    let missing = PriorFactor::new(
        Key::EgoVelocity(7),
        Variable::Vector3(Vector3::zeros()),
        NoiseModel::diagonal_sigmas(&[1.0; 3]),
    );
    let factors: Vec<&dyn Factor> = vec![&prior, &missing];
    let err = optimize(&factors, &mut values.clone(), &SolverConfig::default()).unwrap_err();
    assert_eq!(
        err,
        SolverError::MissingKey {
            factor: 1,
            key: Key::EgoVelocity(7)
        }
    );
    assert!(err.to_string().contains("v7"));

    let nan = NanFactor {
        keys: [Key::EgoVelocity(0)],
        noise: NoiseModel::diagonal_sigmas(&[1.0; 3]),
    };
    let factors: Vec<&dyn Factor> = vec![&prior, &nan];
    let err = optimize(&factors, &mut values.clone(), &SolverConfig::default()).unwrap_err();
    assert!(
        matches!(err, SolverError::NonFinite { factor: 1, .. }),
        "{err:?}"
    );

    // A NaN prior value gives a NaN residual too.
    let nan_prior = PriorFactor::new(
        Key::EgoVelocity(0),
        Variable::Vector3(Vector3::new(f64::NAN, 0.0, 0.0)),
        NoiseModel::diagonal_sigmas(&[1.0; 3]),
    );
    let factors: Vec<&dyn Factor> = vec![&nan_prior];
    assert!(matches!(
        optimize(&factors, &mut values.clone(), &SolverConfig::default()),
        Err(SolverError::NonFinite { factor: 0, .. })
    ));

    // Noise of the wrong dimension.
    let bad_noise = PriorFactor::new(
        Key::EgoVelocity(0),
        Variable::Vector3(Vector3::zeros()),
        NoiseModel::diagonal_sigmas(&[1.0; 2]),
    );
    let factors: Vec<&dyn Factor> = vec![&bad_noise];
    assert!(matches!(
        optimize(&factors, &mut values.clone(), &SolverConfig::default()),
        Err(SolverError::DimensionMismatch { factor: 0, .. })
    ));

    // Unknown key for a covariance query.
    let factors: Vec<&dyn Factor> = vec![&prior];
    assert_eq!(
        marginal_covariance(&factors, &values, &[Key::EgoPose(3)]).unwrap_err(),
        SolverError::UnknownKey(Key::EgoPose(3))
    );
}

#[test]
fn sliding_window_rejects_bad_use() {
    let mut window = SlidingWindowSmoother::new();
    window
        .add_variable(Key::EgoVelocity(0), Variable::Vector3(Vector3::zeros()))
        .unwrap();
    assert_eq!(
        window.add_variable(Key::EgoVelocity(0), Variable::Vector3(Vector3::zeros())),
        Err(WindowError::DuplicateKey(Key::EgoVelocity(0)))
    );
    let dangling = PriorFactor::new(
        Key::EgoVelocity(1),
        Variable::Vector3(Vector3::zeros()),
        NoiseModel::diagonal_sigmas(&[1.0; 3]),
    );
    assert_eq!(
        window.add_factor(Box::new(dangling)),
        Err(WindowError::FactorKeyMissing(Key::EgoVelocity(1)))
    );
    assert_eq!(
        window.marginalize(&[Key::EgoPose(0)]),
        Err(WindowError::UnknownKey(Key::EgoPose(0)))
    );
    // A variable with only a NaN factor: the solver error surfaces, no panic.
    window
        .add_factor(Box::new(NanFactor {
            keys: [Key::EgoVelocity(0)],
            noise: NoiseModel::diagonal_sigmas(&[1.0; 3]),
        }))
        .unwrap();
    assert!(matches!(
        window.optimize(&SolverConfig::default()),
        Err(WindowError::Solver(SolverError::NonFinite { .. }))
    ));
    // Marginalizing it (with a kept neighbour, so it must be linearized)
    // fails the same way and leaves the window intact.
    window
        .add_variable(Key::EgoVelocity(1), Variable::Vector3(Vector3::zeros()))
        .unwrap();
    window
        .add_factor(Box::new(difference_factor(
            Key::EgoVelocity(0),
            Key::EgoVelocity(1),
            3,
            1.0,
        )))
        .unwrap();
    assert!(matches!(
        window.marginalize(&[Key::EgoVelocity(0)]),
        Err(WindowError::Marginalization(_))
    ));
    assert_eq!(window.factor_count(), 2);
    assert_eq!(
        window.keys(),
        vec![Key::EgoVelocity(0), Key::EgoVelocity(1)]
    );
}

#[test]
fn factors_touching_only_removed_keys_vanish_with_them() {
    let mut window = SlidingWindowSmoother::new();
    for k in 0..3 {
        window
            .add_variable(
                state(k),
                Variable::Vector3(Vector3::new(k as f64, 0.0, 0.0)),
            )
            .unwrap();
    }
    let unary = |k: u64| LinearFactor {
        keys: vec![state(k)],
        a: vec![DMatrix::identity(3, 3)],
        b: DVector::from_element(3, k as f64),
        noise: NoiseModel::diagonal_sigmas(&[1.0; 3]),
    };
    for k in 0..3 {
        window.add_factor(Box::new(unary(k))).unwrap();
    }
    // State 0 has only a unary factor: nothing is left to carry over.
    window.marginalize_frame(0).unwrap();
    assert_eq!(window.factor_count(), 2);
    assert!(window.marginal_priors().is_empty());
    assert_eq!(window.keys(), vec![state(1), state(2)]);
    window.optimize(&gauss_newton()).unwrap();
}

/// Two independent linear chains (the ego and an object) with an optional
/// coupling factor per frame, as factors per frame, and the truth; the
/// measurements are exact plus uniform noise of half-width `noise`.
fn two_chains(frames: u64, coupled: bool, noise: f64) -> (Vec<Vec<LinearFactor>>, Values) {
    let ego = state;
    let object = |k: u64| Key::ObjectMotion { id: 9, frame: k };
    let mut rng = Rng(frames * 31 + coupled as u64);
    let mut truth = Values::new();
    for k in 0..frames {
        for key in [ego(k), object(k)] {
            truth.insert(key, Variable::Vector3(rng.vector3(5.0)));
        }
    }
    let value = |key: Key| vector_of(truth.get(&key).unwrap());
    let mut measure = |exact: DVector<f64>| exact.map(|v| v + noise * rng.range(-1.0, 1.0));
    let mut at: Vec<Vec<LinearFactor>> = (0..frames).map(|_| Vec::new()).collect();
    for chain in [ego as fn(u64) -> Key, object] {
        at[0].push(LinearFactor {
            keys: vec![chain(0)],
            a: vec![DMatrix::identity(3, 3)],
            b: measure(value(chain(0))),
            noise: NoiseModel::diagonal_sigmas(&[0.5; 3]),
        });
        for k in 1..frames {
            let mut f = difference_factor(chain(k - 1), chain(k), 3, 0.2);
            f.b = measure(value(chain(k)) - value(chain(k - 1)));
            at[k as usize].push(f);
        }
    }
    if coupled {
        for k in 0..frames {
            let mut f = difference_factor(ego(k), object(k), 3, 0.3);
            f.b = measure(value(object(k)) - value(ego(k)));
            at[k as usize].push(f);
        }
    }
    (at, truth)
}

fn solve_window(
    at: Vec<Vec<LinearFactor>>,
    window_size: u64,
    condition: bool,
) -> SlidingWindowSmoother {
    let mut window = SlidingWindowSmoother::new();
    let object = |k: u64| Key::ObjectMotion { id: 9, frame: k };
    for (k, factors) in at.into_iter().enumerate() {
        let k = k as u64;
        for key in [state(k), object(k)] {
            window
                .add_variable(key, Variable::Vector3(Vector3::zeros()))
                .unwrap();
        }
        for f in factors {
            window.add_factor(Box::new(f)).unwrap();
        }
        window.optimize(&gauss_newton()).unwrap();
        if k + 1 >= window_size {
            let oldest = k + 1 - window_size;
            if condition {
                // The coupling factors of the oldest frame: ego held fixed.
                let n = window
                    .condition_factors(&[state(oldest)], |f| f.keys().contains(&object(oldest)))
                    .unwrap();
                assert_eq!(n, 1);
                window.marginalize(&[object(oldest)]).unwrap();
                window.marginalize(&[state(oldest)]).unwrap();
            } else {
                window.marginalize_frame(oldest).unwrap();
            }
        }
    }
    window
}

#[test]
fn independent_parts_keep_separate_priors_and_equal_the_batch() {
    let (at, _) = two_chains(9, false, 1.0);
    let mut batch_factors: Vec<Box<dyn Factor>> = Vec::new();
    let mut batch = Values::new();
    for (k, fs) in at.iter().enumerate() {
        batch.insert(state(k as u64), Variable::Vector3(Vector3::zeros()));
        batch.insert(
            Key::ObjectMotion {
                id: 9,
                frame: k as u64,
            },
            Variable::Vector3(Vector3::zeros()),
        );
        for f in fs {
            batch_factors.push(Box::new(clone_linear(f)));
        }
    }
    optimize(&batch_factors, &mut batch, &gauss_newton()).unwrap();
    let window = solve_window(at, 3, false);
    // One prior per independent chain, each on its own chain's keys only.
    assert_eq!(window.marginal_priors().len(), 2);
    assert_priors_separate(&window);
    for (key, value) in window.values().iter() {
        let err = (vector_of(value) - vector_of(batch.get(key).unwrap())).amax();
        assert!(err < 1e-9, "{key}: {err:e}");
    }
}

fn assert_priors_separate(window: &SlidingWindowSmoother) {
    for prior in window.marginal_priors() {
        let ego = prior
            .keys()
            .iter()
            .filter(|k| matches!(k, Key::EgoVelocity(_)))
            .count();
        assert!(ego == 0 || ego == prior.keys().len(), "{:?}", prior.keys());
    }
}

#[test]
fn conditioning_the_oldest_coupling_keeps_the_object_prior_off_the_ego() {
    // Without conditioning the coupling makes one joint prior.
    let joint = solve_window(two_chains(9, true, 1.0).0, 3, false);
    assert_eq!(joint.marginal_priors().len(), 1);
    let window = solve_window(two_chains(9, true, 1.0).0, 3, true);
    assert_eq!(window.marginal_priors().len(), 2);
    assert_priors_separate(&window);
    // Exact measurements: conditioning at the truth loses nothing.
    let (at, truth) = two_chains(9, true, 0.0);
    let window = solve_window(at, 3, true);
    for (key, value) in window.values().iter() {
        let err = (vector_of(value) - vector_of(truth.get(key).unwrap())).amax();
        assert!(err < 1e-9, "{key}: {err:e}");
    }
}

#[test]
fn optimizing_parts_alone_reaches_the_joint_optimum() {
    let (at, _) = two_chains(6, false, 1.0);
    let mut joint = solve_window(two_chains(6, false, 1.0).0, 10, false);
    let mut parts = solve_window(at, 10, false);
    for window in [&mut joint, &mut parts] {
        for key in window.keys() {
            window
                .set_value(key, Variable::Vector3(Vector3::new(3.0, -2.0, 1.0)))
                .unwrap();
        }
    }
    joint.optimize(&gauss_newton()).unwrap();
    let is_ego = |keys: &[Key]| keys.iter().any(|k| matches!(k, Key::EgoVelocity(_)));
    let ego = parts.optimize_parts(&gauss_newton(), is_ego).unwrap();
    assert_eq!(ego.len(), 1);
    // Only the ego chain moved so far.
    let object = Key::ObjectMotion { id: 9, frame: 0 };
    assert_eq!(
        vector_of(parts.values().get(&object).unwrap()),
        DVector::from_column_slice(&[3.0, -2.0, 1.0])
    );
    let rest = parts
        .optimize_parts(&gauss_newton(), |k| !is_ego(k))
        .unwrap();
    assert_eq!(rest.len(), 1);
    for (key, value) in parts.values().iter() {
        let err = (vector_of(value) - vector_of(joint.values().get(key).unwrap())).amax();
        assert!(err < 1e-9, "{key}: {err:e}");
    }
}

#[test]
fn folding_factors_keeps_the_optimum() {
    let (at, _) = two_chains(4, true, 1.0);
    let mut window = solve_window(at, 10, false);
    let before = window.values().clone();
    let count = window.factor_count();
    let keys = window.keys();
    window.fold_factors(&keys).unwrap();
    assert_eq!(window.factor_count(), 0, "{count} factors folded");
    assert_eq!(window.marginal_priors().len(), 1);
    // Start elsewhere: the folded (linear) problem has the same optimum.
    for key in &keys {
        window
            .set_value(*key, Variable::Vector3(Vector3::new(3.0, -2.0, 1.0)))
            .unwrap();
    }
    window.optimize(&gauss_newton()).unwrap();
    for (key, value) in window.values().iter() {
        let err = (vector_of(value) - vector_of(before.get(key).unwrap())).amax();
        assert!(err < 1e-8, "{key}: {err:e}");
    }
}

// ---------------------------------------------------------------------------
// Timing (printed, not asserted) and linear growth of the sparse structure
// ---------------------------------------------------------------------------

fn difference_factor(a: Key, b: Key, dim: usize, sigma: f64) -> LinearFactor {
    LinearFactor {
        keys: vec![a, b],
        a: vec![-DMatrix::identity(dim, dim), DMatrix::identity(dim, dim)],
        b: DVector::zeros(dim),
        noise: NoiseModel::diagonal_sigmas(&vec![sigma; dim]),
    }
}

/// Ego window of `frames` frames (pose, velocity, bias) plus `objects`
/// objects with a pose and a motion node per frame.
fn window_graph(frames: u64, objects: u64, rng: &mut Rng) -> (Vec<Box<dyn Factor>>, Values) {
    let mut values = Values::new();
    let mut factors: Vec<Box<dyn Factor>> = Vec::new();
    let pose_noise = NoiseModel::diagonal_sigmas(&[0.05, 0.05, 0.05, 0.01, 0.01, 0.01]);
    let step = Isometry3::translation(1.0, 0.0, 0.0);
    for k in 0..frames {
        let t = Isometry3::translation(k as f64, 0.0, 0.0);
        values.insert(
            Key::EgoPose(k),
            Variable::Pose(lie::oplus(&t, &rng.vector6(0.1, 0.02))),
        );
        values.insert(
            Key::EgoVelocity(k),
            Variable::Vector3(Vector3::new(10.0, 0.0, 0.0)),
        );
        values.insert(Key::EgoBias(k), Variable::Bias(ImuBias::default()));
        if k == 0 {
            factors.push(Box::new(PriorFactor::new(
                Key::EgoPose(0),
                Variable::Pose(t),
                pose_noise.clone(),
            )));
            factors.push(Box::new(PriorFactor::new(
                Key::EgoVelocity(0),
                Variable::Vector3(Vector3::new(10.0, 0.0, 0.0)),
                NoiseModel::diagonal_sigmas(&[0.1; 3]),
            )));
            factors.push(Box::new(PriorFactor::new(
                Key::EgoBias(0),
                Variable::Bias(ImuBias::default()),
                NoiseModel::diagonal_sigmas(&[0.1, 0.1, 0.1, 0.01, 0.01, 0.01]),
            )));
        } else {
            factors.push(Box::new(BetweenFactor::new(
                Key::EgoPose(k - 1),
                Key::EgoPose(k),
                step,
                pose_noise.clone(),
            )));
            factors.push(Box::new(difference_factor(
                Key::EgoVelocity(k - 1),
                Key::EgoVelocity(k),
                3,
                0.1,
            )));
            factors.push(Box::new(difference_factor(
                Key::EgoBias(k - 1),
                Key::EgoBias(k),
                6,
                0.01,
            )));
        }
        for id in 0..objects {
            let pose_key = Key::ObjectPose { id, frame: k };
            let motion_key = Key::ObjectMotion { id, frame: k };
            let t_obj = Isometry3::translation(k as f64 * 0.5 + id as f64, 5.0, 0.0);
            values.insert(
                pose_key,
                Variable::Pose(lie::oplus(&t_obj, &rng.vector6(0.1, 0.02))),
            );
            values.insert(
                motion_key,
                Variable::Pose(lie::se3_exp(&rng.vector6(0.1, 0.02))),
            );
            // Detection: object pose seen from the ego pose.
            factors.push(Box::new(BetweenFactor::new(
                Key::EgoPose(k),
                pose_key,
                lie::between(&t, &t_obj),
                pose_noise.clone(),
            )));
            factors.push(Box::new(PriorFactor::new(
                motion_key,
                Variable::Pose(Isometry3::translation(0.5, 0.0, 0.0)),
                NoiseModel::diagonal_sigmas(&[1.0; 6]),
            )));
            if k > 0 {
                factors.push(Box::new(BetweenFactor::new(
                    Key::ObjectPose { id, frame: k - 1 },
                    pose_key,
                    Isometry3::translation(0.5, 0.0, 0.0),
                    pose_noise.clone(),
                )));
                factors.push(Box::new(BetweenFactor::new(
                    Key::ObjectMotion { id, frame: k - 1 },
                    motion_key,
                    Isometry3::identity(),
                    pose_noise.clone(),
                )));
            }
        }
    }
    (factors, values)
}

#[test]
fn timing_of_window_solves_and_linear_growth() {
    let mut rng = Rng(42);
    let mut block_counts = Vec::new();
    for objects in [0u64, 30, 60] {
        let (factors, mut values) = window_graph(5, objects, &mut rng);
        let index = VariableIndex::from_values(&values);
        let normal = linearize_normal_equations(&factors, &values, &index).unwrap();
        block_counts.push(normal.block_count());
        let start = Instant::now();
        linearize_normal_equations(&factors, &values, &index).unwrap();
        let t_linearize = start.elapsed();
        let start = Instant::now();
        total_cost(&factors, &values).unwrap();
        let t_cost = start.elapsed();
        let start = Instant::now();
        gauss_newton_step(&factors, &values).unwrap();
        let t_step = start.elapsed();
        println!(
            "  {objects} objects: linearize {:.3} ms, cost {:.3} ms, linearize+factorize+solve {:.3} ms",
            t_linearize.as_secs_f64() * 1e3,
            t_cost.as_secs_f64() * 1e3,
            t_step.as_secs_f64() * 1e3
        );
        let start = Instant::now();
        let report = optimize(&factors, &mut values, &SolverConfig::default()).unwrap();
        let elapsed = start.elapsed();
        assert!(report.converged, "{report:?}");
        assert!(report.final_cost <= report.initial_cost);
        println!(
            "window 5 frames, {objects} objects: {} unknowns, {} factors, {} H blocks: {} iterations in {:.2} ms ({:.3} ms/iteration), cost {:.3e} -> {:.3e}",
            index.total_dim(),
            factors.len(),
            normal.block_count(),
            report.iterations,
            elapsed.as_secs_f64() * 1e3,
            elapsed.as_secs_f64() * 1e3 / report.iterations as f64,
            report.initial_cost,
            report.final_cost
        );
    }
    // The number of Hessian blocks grows linearly with the objects.
    let per_object_30 = (block_counts[1] - block_counts[0]) as f64 / 30.0;
    let per_object_60 = (block_counts[2] - block_counts[0]) as f64 / 60.0;
    assert!(
        (per_object_30 - per_object_60).abs() < 1e-9,
        "{block_counts:?}"
    );
}

#[test]
fn singular_normal_equations_are_handled_by_raising_the_damping() {
    // No prior: the pose loop has a 6-dof gauge freedom, so the undamped
    // normal equations are singular; Gauss–Newton's first solve fails and
    // the solver must fall back to damping instead of erroring or panicking.
    let graph = pose_loop(11, 8);
    let factors: Vec<&dyn Factor> = graph.factors[1..].iter().map(|f| f.as_ref()).collect();
    let mut values = graph.initial.clone();
    let report = optimize(&factors, &mut values, &gauss_newton()).unwrap();
    assert!(report.lambda > 0.0, "{report:?}");
    assert!(report.final_cost < 1e-3 * report.initial_cost, "{report:?}");
    // The undamped step itself is reported as not positive definite.
    assert!(matches!(
        gauss_newton_step(&factors, &values),
        Err(SolverError::NotPositiveDefinite { .. })
    ));
}

/// Ego-like chain (pose, velocity, bias per frame) with between factors over
/// one and two frames; `noise_scale` 0 gives exact measurements.
fn ego_chain(
    seed: u64,
    frames: u64,
    noise_scale: f64,
) -> (Vec<Vec<Box<dyn Factor>>>, Values, Values) {
    let mut rng = Rng(seed);
    let sigmas = [0.05, 0.05, 0.05, 0.01, 0.01, 0.01];
    let noise = NoiseModel::diagonal_sigmas(&sigmas);
    let mut truth = Values::new();
    let mut initial = Values::new();
    let mut factors_at: Vec<Vec<Box<dyn Factor>>> = Vec::new();
    for k in 0..frames {
        let t = lie::se3_exp(&lie::xi_from_parts(
            &Vector3::new(2.0 * k as f64, 0.3 * (k as f64).sin(), 0.1 * k as f64),
            &Vector3::new(0.02 * k as f64, -0.01 * k as f64, 0.1 * k as f64),
        ));
        let v = Vector3::new(10.0, (k as f64).cos(), 0.0);
        let b = ImuBias::from_vector6(&Vector6::new(0.1, -0.05, 0.02, 0.001, 0.002, -0.001));
        truth.insert(Key::EgoPose(k), Variable::Pose(t));
        truth.insert(Key::EgoVelocity(k), Variable::Vector3(v));
        truth.insert(Key::EgoBias(k), Variable::Bias(b));
        initial.insert(
            Key::EgoPose(k),
            Variable::Pose(lie::oplus(&t, &rng.vector6(0.3, 0.05))),
        );
        initial.insert(Key::EgoVelocity(k), Variable::Vector3(v + rng.vector3(0.5)));
        initial.insert(Key::EgoBias(k), Variable::Bias(ImuBias::default()));
        let mut here: Vec<Box<dyn Factor>> = Vec::new();
        let measure = |rng: &mut Rng, a: u64, b: u64| -> Box<dyn Factor> {
            let t_ab = lie::between(truth.pose(&Key::EgoPose(a)), truth.pose(&Key::EgoPose(b)));
            let xi = Vector6::from_fn(|i, _| noise_scale * sigmas[i] * rng.irwin_hall_normal());
            Box::new(BetweenFactor::new(
                Key::EgoPose(a),
                Key::EgoPose(b),
                t_ab * lie::se3_exp(&xi),
                noise.clone(),
            ))
        };
        if k == 0 {
            here.push(Box::new(PriorFactor::new(
                Key::EgoPose(0),
                Variable::Pose(t),
                noise.clone(),
            )));
            here.push(Box::new(PriorFactor::new(
                Key::EgoVelocity(0),
                Variable::Vector3(v),
                NoiseModel::diagonal_sigmas(&[0.1; 3]),
            )));
            here.push(Box::new(PriorFactor::new(
                Key::EgoBias(0),
                Variable::Bias(b),
                NoiseModel::diagonal_sigmas(&[0.1, 0.1, 0.1, 0.01, 0.01, 0.01]),
            )));
        } else {
            here.push(measure(&mut rng, k - 1, k));
            if k >= 2 {
                here.push(measure(&mut rng, k - 2, k));
            }
            let v_prev = *truth.vector3(&Key::EgoVelocity(k - 1));
            let mut dv = difference_factor(Key::EgoVelocity(k - 1), Key::EgoVelocity(k), 3, 0.1);
            dv.b = DVector::from_fn(3, |i, _| {
                v[i] - v_prev[i] + noise_scale * 0.1 * rng.irwin_hall_normal()
            });
            here.push(Box::new(dv));
            here.push(Box::new(difference_factor(
                Key::EgoBias(k - 1),
                Key::EgoBias(k),
                6,
                0.01,
            )));
            // Velocity also observed directly (as a LiDAR-derived speed would be).
            here.push(Box::new(PriorFactor::new(
                Key::EgoVelocity(k),
                Variable::Vector3(v + noise_scale * 0.2 * rng.vector3(1.0)),
                NoiseModel::diagonal_sigmas(&[0.2; 3]),
            )));
        }
        factors_at.push(here);
    }
    (factors_at, truth, initial)
}

fn run_window(
    factors_at: Vec<Vec<Box<dyn Factor>>>,
    initial: &Values,
    window_frames: usize,
) -> SlidingWindowSmoother {
    let mut window = SlidingWindowSmoother::new();
    for (k, factors) in factors_at.into_iter().enumerate() {
        let k = k as u64;
        for key in [Key::EgoPose(k), Key::EgoVelocity(k), Key::EgoBias(k)] {
            window
                .add_variable(key, *initial.get(&key).unwrap())
                .unwrap();
        }
        for f in factors {
            window.add_factor(f).unwrap();
        }
        window.optimize(&SolverConfig::default()).unwrap();
        if window.keys().len() > 3 * window_frames {
            let oldest = window.oldest_frame().unwrap();
            let removed = window.marginalize_frame(oldest).unwrap();
            assert_eq!(removed.len(), 3);
        }
    }
    window
}

#[test]
fn nonlinear_window_is_exact_without_noise_and_close_to_batch_with_noise() {
    // Noise-free: the marginal priors are linearized at the truth, so the
    // window must recover the truth exactly, whatever the initial values.
    let (factors_at, truth, initial) = ego_chain(5, 12, 0.0);
    let window = run_window(factors_at, &initial, 5);
    // Poses, velocities and biases are separate chains here: one prior each.
    assert_eq!(window.marginal_priors().len(), 3);
    for (key, value) in window.values().iter() {
        let err = value.local(truth.get(key).unwrap()).amax();
        assert!(err < 1e-8, "{key}: {err:e}");
    }

    // Noisy: the window (relinearization frozen in the priors) stays close
    // to the batch optimum of all frames.
    let (factors_at, _, initial) = ego_chain(6, 12, 1.0);
    let batch_factors: Vec<&dyn Factor> = factors_at.iter().flatten().map(|f| f.as_ref()).collect();
    let mut batch = initial.clone();
    let report = optimize(&batch_factors, &mut batch, &SolverConfig::default()).unwrap();
    assert!(report.converged);
    drop(batch_factors);
    let window = run_window(factors_at, &initial, 5);
    let mut worst: f64 = 0.0;
    for (key, value) in window.values().iter() {
        worst = worst.max(value.local(batch.get(key).unwrap()).amax());
    }
    println!("noisy ego chain: window vs batch, worst tangent difference {worst:.3e}");
    assert!(worst < 1e-3, "{worst:e}");
}
