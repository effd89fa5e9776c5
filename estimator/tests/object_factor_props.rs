//! Property tests of the object factors (r_obs, r_moti, r_smoo): analytic
//! Jacobians against finite differences at large random poses, and
//! Levenberg–Marquardt on a synthetic sliding window with an ego, three
//! constant-velocity objects (one turning) and a static object.

use limot_estimator::graph::{
    Factor, Key, NoiseModel, ObjectMotionFactor, ObjectObservationFactor, PriorFactor,
    SmoothMotionFactor, SolverConfig, Values, Variable, check_factor_jacobians,
    marginal_covariance, optimize,
};
use limot_estimator::lie;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3, Vector6};
use proptest::prelude::*;

use limot_test_support::SplitMix64 as Rng;

/// Lie-group samples drawn from the shared test generator.
trait LieSamples {
    fn twist(&mut self, scale_rho: f64, scale_phi: f64) -> Vector6<f64>;
    fn normal_twist(&mut self, sigma_rho: f64, sigma_phi: f64) -> Vector6<f64>;
    fn large_pose(&mut self) -> Isometry3<f64>;
}

impl LieSamples for Rng {
    fn twist(&mut self, scale_rho: f64, scale_phi: f64) -> Vector6<f64> {
        lie::xi_from_parts(&self.vector3(scale_rho), &self.vector3(scale_phi))
    }
    /// Gaussian twist with per-part standard deviations.
    fn normal_twist(&mut self, sigma_rho: f64, sigma_phi: f64) -> Vector6<f64> {
        Vector6::from_fn(|i, _| {
            if i < 3 {
                sigma_rho * self.normal()
            } else {
                sigma_phi * self.normal()
            }
        })
    }
    /// Translation up to 100 m per axis, rotation of any angle up to ~π
    /// (uniform direction, uniform angle in [0, 3.1]).
    fn large_pose(&mut self) -> Isometry3<f64> {
        let axis = loop {
            let v = self.vector3(1.0);
            let n = v.norm();
            if n > 1e-3 && n <= 1.0 {
                break v / n;
            }
        };
        let angle = self.range(0.0, 3.1);
        Isometry3::from_parts(
            Translation3::from(self.vector3(100.0)),
            lie::so3_exp_quat(&(axis * angle)),
        )
    }
}

// ---------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------

fn pose(x: f64, y: f64, z: f64, roll: f64, pitch: f64, yaw: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
}

fn pose_distance(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    let xi = lie::ominus(a, b);
    (lie::xi_rho(&xi).norm(), lie::xi_phi(&xi).norm())
}

fn sigmas(translation_m: f64, rotation_rad: f64) -> NoiseModel {
    NoiseModel::diagonal_sigmas(&[
        translation_m,
        translation_m,
        translation_m,
        rotation_rad,
        rotation_rad,
        rotation_rad,
    ])
}

/// `|φ|` of a 6-dim pose residual: the log is only smooth for `|φ| < π`, so
/// Jacobian checks skip residuals too close to the cut.
fn rotation_norm(factor: &dyn Factor, values: &Values) -> f64 {
    factor.residual(values).rows(3, 3).norm()
}

// ---------------------------------------------------------------------------
// Jacobians against finite differences
// ---------------------------------------------------------------------------

const FD_STEP: f64 = 1e-6;
const FD_TOL: f64 = 1e-6;

/// FD tolerance scaled by the magnitudes involved (residual and translations
/// up to ~200 m enter the Jacobians through adjoints).
fn fd_tolerance(factor: &dyn Factor, values: &Values) -> f64 {
    let translation = factor
        .keys()
        .iter()
        .map(|k| values.pose(k).translation.vector.norm())
        .fold(0.0, f64::max);
    FD_TOL * factor.residual(values).amax().max(translation).max(1.0)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn observation_factor_jacobians(seed in any::<u64>()) {
        let mut rng = Rng(seed);
        let t_imu_lidar = rng.large_pose();
        let measured = rng.large_pose();
        for object in [Key::ObjectPose { id: 4, frame: 9 }, Key::StaticObjectPose { id: 5 }] {
            let mut values = Values::new();
            values.insert(Key::EgoPose(9), Variable::Pose(rng.large_pose()));
            values.insert(object, Variable::Pose(rng.large_pose()));
            let factor = ObjectObservationFactor::new(
                Key::EgoPose(9), object, t_imu_lidar, measured, sigmas(0.15, 0.03));
            if rotation_norm(&factor, &values) > 3.0 {
                continue;
            }
            let err = check_factor_jacobians(&factor, &values, FD_STEP);
            let tol = fd_tolerance(&factor, &values);
            prop_assert!(err < tol, "{object}: error {err:e} > {tol:e}");
        }
    }

    #[test]
    fn motion_factor_jacobians(seed in any::<u64>()) {
        let mut rng = Rng(seed);
        let (prev, next, motion) = (
            Key::ObjectPose { id: 1, frame: 3 },
            Key::ObjectPose { id: 1, frame: 4 },
            Key::ObjectMotion { id: 1, frame: 3 },
        );
        let mut values = Values::new();
        values.insert(prev, Variable::Pose(rng.large_pose()));
        values.insert(next, Variable::Pose(rng.large_pose()));
        values.insert(motion, Variable::Pose(rng.large_pose()));
        let factor = ObjectMotionFactor::new(prev, next, motion, sigmas(0.01, 0.001));
        prop_assume!(rotation_norm(&factor, &values) < 3.0);
        let err = check_factor_jacobians(&factor, &values, FD_STEP);
        let tol = fd_tolerance(&factor, &values);
        prop_assert!(err < tol, "error {err:e} > {tol:e}");
    }

    #[test]
    fn smooth_motion_factor_jacobians(seed in any::<u64>()) {
        let mut rng = Rng(seed);
        let (prev, next) = (
            Key::ObjectMotion { id: 1, frame: 2 },
            Key::ObjectMotion { id: 1, frame: 3 },
        );
        let mut values = Values::new();
        values.insert(prev, Variable::Pose(rng.large_pose()));
        values.insert(next, Variable::Pose(rng.large_pose()));
        let factor = SmoothMotionFactor::new(prev, next, sigmas(0.02, 0.002));
        prop_assume!(rotation_norm(&factor, &values) < 3.0);
        let err = check_factor_jacobians(&factor, &values, FD_STEP);
        let tol = fd_tolerance(&factor, &values);
        prop_assert!(err < tol, "error {err:e} > {tol:e}");
    }
}

// ---------------------------------------------------------------------------
// Synthetic window: ego + 3 moving objects + 1 static object
// ---------------------------------------------------------------------------

const FRAMES: u64 = 5;
const DT_S: f64 = 0.1;
const MOVING: u64 = 3;
const STATIC_ID: u64 = 100;
const OBS_SIGMA_M: f64 = 0.15;
const OBS_SIGMA_RAD: f64 = 0.03;

struct Window {
    truth: Values,
    factors: Vec<Box<dyn Factor>>,
    /// `(object key, frame, t_world_object seen through the true ego pose)`:
    /// the raw observation, to compare against the optimized poses.
    raw_observations: Vec<(Key, u64, Isometry3<f64>)>,
}

/// Noise models of the window's factors: `(σ_t m, σ_r rad)`.
const EGO_PRIOR_SIGMA: (f64, f64) = (0.05, 0.005);
const MOTION_SIGMA: (f64, f64) = (0.01, 0.001);
const SMOOTH_SIGMA: (f64, f64) = (0.02, 0.002);

/// How the synthetic truth and measurements are drawn.
#[derive(Clone, Copy, PartialEq)]
enum Sampling {
    /// Exact detections, constant-velocity objects, priors at the truth.
    Exact,
    /// Noisy detections (object-frame `OBS_SIGMA_*`), otherwise as `Exact`.
    NoisyDetections,
    /// Everything drawn from the graph's own noise models: noisy detections,
    /// ego priors around the truth, motions that change by `SMOOTH_SIGMA`
    /// and poses that deviate from them by `MOTION_SIGMA`. The estimate's
    /// errors then follow the covariance the graph predicts.
    FullModel,
}

fn sigmas_of((translation_m, rotation_rad): (f64, f64)) -> NoiseModel {
    sigmas(translation_m, rotation_rad)
}

/// Builds a window of `FRAMES` ego poses, `MOVING` objects (object 0 turns)
/// and a static object observed every frame.
fn build_window(rng: &mut Rng, sampling: Sampling) -> Window {
    let full_model = sampling == Sampling::FullModel;
    let mut truth = Values::new();
    // Ego: ~10 m/s along a gentle curve from a random start.
    let t_world_imu0 = pose(
        rng.range(-100.0, 100.0),
        rng.range(-100.0, 100.0),
        rng.range(-2.0, 2.0),
        rng.range(-0.05, 0.05),
        rng.range(-0.05, 0.05),
        rng.range(-3.1, 3.1),
    );
    let ego_step = lie::se3_exp(&Vector6::new(10.0 * DT_S, 0.0, 0.0, 0.0, 0.0, 0.02));
    let mut t_world_imu = t_world_imu0;
    for k in 0..FRAMES {
        truth.insert(Key::EgoPose(k), Variable::Pose(t_world_imu));
        t_world_imu *= ego_step;
    }
    let t_imu_lidar = pose(0.8, 0.05, 1.7, 0.01, -0.02, 0.05);

    // Moving objects: constant body-frame motion (constant velocity and yaw
    // rate), so r_moti and r_smoo vanish at the truth, unless `FullModel`.
    for id in 0..MOVING {
        let yaw_rate_radps = if id == 0 { 0.2 } else { 0.0 };
        let speed_mps = rng.range(3.0, 15.0);
        let mut motion = lie::se3_exp(&Vector6::new(
            speed_mps * DT_S,
            0.0,
            0.0,
            0.0,
            0.0,
            yaw_rate_radps * DT_S,
        ));
        let mut t_world_object = t_world_imu0
            * pose(
                rng.range(10.0, 40.0),
                rng.range(-15.0, 15.0),
                rng.range(-0.5, 0.5),
                0.0,
                0.0,
                rng.range(-3.1, 3.1),
            );
        for k in 0..FRAMES {
            truth.insert(
                Key::ObjectPose { id, frame: k },
                Variable::Pose(t_world_object),
            );
            if k + 1 < FRAMES {
                truth.insert(Key::ObjectMotion { id, frame: k }, Variable::Pose(motion));
            }
            t_world_object *= motion;
            if full_model {
                let (sigma_m, sigma_rad) = MOTION_SIGMA;
                t_world_object *= lie::se3_exp(&rng.normal_twist(sigma_m, sigma_rad));
                let (sigma_m, sigma_rad) = SMOOTH_SIGMA;
                motion *= lie::se3_exp(&rng.normal_twist(sigma_m, sigma_rad));
            }
        }
    }
    let t_world_static = t_world_imu0 * pose(25.0, 6.0, 0.2, 0.0, 0.0, rng.range(-3.1, 3.1));
    truth.insert(
        Key::StaticObjectPose { id: STATIC_ID },
        Variable::Pose(t_world_static),
    );

    let mut factors: Vec<Box<dyn Factor>> = Vec::new();
    let mut raw_observations = Vec::new();
    for k in 0..FRAMES {
        let ego = Key::EgoPose(k);
        factors.push(Box::new(PriorFactor::new(
            ego,
            Variable::Pose(if full_model {
                let (sigma_m, sigma_rad) = EGO_PRIOR_SIGMA;
                truth.pose(&ego) * lie::se3_exp(&rng.normal_twist(sigma_m, sigma_rad))
            } else {
                *truth.pose(&ego)
            }),
            sigmas_of(EGO_PRIOR_SIGMA),
        )));
        let t_world_lidar = truth.pose(&ego) * t_imu_lidar;
        let objects = (0..MOVING)
            .map(|id| Key::ObjectPose { id, frame: k })
            .chain([Key::StaticObjectPose { id: STATIC_ID }]);
        for object in objects {
            let true_t_lidar_object = t_world_lidar.inverse() * truth.pose(&object);
            let measured = match sampling {
                Sampling::Exact => true_t_lidar_object,
                Sampling::NoisyDetections | Sampling::FullModel => {
                    true_t_lidar_object
                        * lie::se3_exp(&rng.normal_twist(OBS_SIGMA_M, OBS_SIGMA_RAD))
                }
            };
            raw_observations.push((object, k, t_world_lidar * measured));
            factors.push(Box::new(ObjectObservationFactor::new(
                ego,
                object,
                t_imu_lidar,
                measured,
                sigmas(OBS_SIGMA_M, OBS_SIGMA_RAD),
            )));
        }
    }
    for id in 0..MOVING {
        for k in 0..FRAMES - 1 {
            factors.push(Box::new(ObjectMotionFactor::new(
                Key::ObjectPose { id, frame: k },
                Key::ObjectPose { id, frame: k + 1 },
                Key::ObjectMotion { id, frame: k },
                sigmas_of(MOTION_SIGMA),
            )));
        }
        for k in 0..FRAMES - 2 {
            factors.push(Box::new(SmoothMotionFactor::new(
                Key::ObjectMotion { id, frame: k },
                Key::ObjectMotion { id, frame: k + 1 },
                sigmas_of(SMOOTH_SIGMA),
            )));
        }
    }
    Window {
        truth,
        factors,
        raw_observations,
    }
}

/// Every variable of `truth` perturbed by up to 0.5 m / 0.1 rad per axis.
fn perturbed(truth: &Values, rng: &mut Rng) -> Values {
    let mut initial = truth.clone();
    let keys: Vec<Key> = truth.keys().copied().collect();
    for key in keys {
        initial.retract_key(&key, rng.twist(0.5, 0.1).as_slice());
    }
    initial
}

fn solver_config() -> SolverConfig {
    SolverConfig {
        max_iterations: 100,
        ..SolverConfig::default()
    }
}

/// Figures of one noisy window after optimization.
struct NoisyFigures {
    raw_rmse_m: f64,
    optimized_rmse_m: f64,
    /// `v_est - v_true` of every motion node (object frame at its start, m/s).
    velocity_errors_mps: Vec<Vector3<f64>>,
    /// `eᵀ·Σ_v⁻¹·e` of each of those errors, with `Σ_v` the velocity
    /// covariance the graph itself predicts (marginal covariance at the optimum).
    velocity_nees: Vec<f64>,
    /// Predicted per-axis velocity standard deviation `sqrt(tr Σ_v / 3)` per node.
    velocity_sigma_mps: Vec<f64>,
    /// Naive velocity from two consecutive raw observations, minus the truth.
    raw_velocity_errors_mps: Vec<Vector3<f64>>,
}

fn run_noisy_window(seed: u64, sampling: Sampling) -> NoisyFigures {
    let mut rng = Rng(seed);
    let window = build_window(&mut rng, sampling);
    let mut values = perturbed(&window.truth, &mut rng);
    let report = optimize(&window.factors, &mut values, &solver_config()).expect("optimize");
    assert!(report.converged, "seed {seed}: {report:?}");
    let (mut raw_sq, mut opt_sq) = (0.0, 0.0);
    for (object, _frame, raw) in &window.raw_observations {
        let t_true = window.truth.pose(object).translation.vector;
        raw_sq += (raw.translation.vector - t_true).norm_squared();
        opt_sq += (values.pose(object).translation.vector - t_true).norm_squared();
    }
    let n = window.raw_observations.len() as f64;
    let raw_position = |id: u64, frame: u64| {
        window
            .raw_observations
            .iter()
            .find(|(key, k, _)| *key == Key::ObjectPose { id, frame } && *k == frame)
            .map(|(_, _, t)| t.translation.vector)
            .expect("observed every frame")
    };
    let mut figures = NoisyFigures {
        raw_rmse_m: (raw_sq / n).sqrt(),
        optimized_rmse_m: (opt_sq / n).sqrt(),
        velocity_errors_mps: Vec::new(),
        velocity_nees: Vec::new(),
        velocity_sigma_mps: Vec::new(),
        raw_velocity_errors_mps: Vec::new(),
    };
    for id in 0..MOVING {
        for k in 0..FRAMES - 1 {
            let key = Key::ObjectMotion { id, frame: k };
            let motion = values.pose(&key);
            let v_true = window.truth.pose(&key).translation.vector / DT_S;
            let error = motion.translation.vector / DT_S - v_true;
            // M·Exp(ξ) moves the translation by R_M·ρ to first order.
            let cov = marginal_covariance(&window.factors, &values, &[key]).expect("covariance");
            let r_m = motion.rotation.to_rotation_matrix().into_inner();
            let cov_v = r_m * cov.fixed_view::<3, 3>(0, 0) * r_m.transpose() / (DT_S * DT_S);
            let nees = error.dot(&(cov_v.try_inverse().expect("SPD") * error));
            figures.velocity_errors_mps.push(error);
            figures.velocity_nees.push(nees);
            figures
                .velocity_sigma_mps
                .push((cov_v.trace() / 3.0).sqrt());
            // Two-frame difference of raw detections, in the true object
            // frame at k, as a baseline.
            let r_true = window
                .truth
                .pose(&Key::ObjectPose { id, frame: k })
                .rotation
                .to_rotation_matrix()
                .into_inner();
            let raw_v = r_true.transpose() * (raw_position(id, k + 1) - raw_position(id, k)) / DT_S;
            figures.raw_velocity_errors_mps.push(raw_v - v_true);
        }
    }
    figures
}

/// χ²(3) quantile at 1 - 4·10⁻⁶: one node beyond it in 16 windows is a bug,
/// not bad luck.
const CHI2_3_STRICT: f64 = 27.9;

fn rms_per_axis(errors: &[Vector3<f64>]) -> f64 {
    (errors.iter().map(|e| e.norm_squared()).sum::<f64>() / (3 * errors.len()) as f64).sqrt()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    #[test]
    fn window_converges_to_truth_from_perturbed_values(seed in any::<u64>()) {
        let mut rng = Rng(seed);
        let window = build_window(&mut rng, Sampling::Exact);
        let mut values = perturbed(&window.truth, &mut rng);
        let report = optimize(&window.factors, &mut values, &solver_config()).expect("optimize");
        prop_assert!(report.converged, "{report:?}");
        let (mut worst_m, mut worst_rad): (f64, f64) = (0.0, 0.0);
        for (key, truth) in window.truth.iter() {
            let Variable::Pose(t_true) = truth else { unreachable!("only poses") };
            let (dt_m, dr_rad) = pose_distance(values.pose(key), t_true);
            prop_assert!(dt_m < 1e-6 && dr_rad < 1e-6, "{key}: {dt_m:e} m, {dr_rad:e} rad");
            worst_m = worst_m.max(dt_m);
            worst_rad = worst_rad.max(dr_rad);
        }
        println!(
            "exact window seed {seed:#x}: {} iterations, cost {:.1e} -> {:.1e}, worst error \
             {worst_m:.1e} m / {worst_rad:.1e} rad",
            report.iterations, report.initial_cost, report.final_cost
        );
    }

    #[test]
    fn noisy_window_beats_raw_observations(seed in any::<u64>()) {
        let figures = run_noisy_window(seed, Sampling::NoisyDetections);
        let worst_velocity = figures
            .velocity_errors_mps
            .iter()
            .map(|e| e.norm())
            .fold(0.0, f64::max);
        let worst_nees = figures.velocity_nees.iter().copied().fold(0.0, f64::max);
        println!(
            "seed {seed:#x}: object translation RMSE raw {:.3} m, optimized {:.3} m; \
             velocity RMS/axis {:.3} m/s (two-frame raw {:.3}), worst |e| {:.3} m/s, worst NEES {:.1}",
            figures.raw_rmse_m,
            figures.optimized_rmse_m,
            rms_per_axis(&figures.velocity_errors_mps),
            rms_per_axis(&figures.raw_velocity_errors_mps),
            worst_velocity,
            worst_nees,
        );
        prop_assert!(figures.optimized_rmse_m < figures.raw_rmse_m);
        // Each motion node's velocity error is consistent with the
        // covariance the graph predicts for it.
        prop_assert!(worst_nees < CHI2_3_STRICT, "velocity NEES {worst_nees}");
    }
}

struct Aggregate {
    raw_rmse_m: f64,
    optimized_rmse_m: f64,
    velocity_rms_mps: f64,
    raw_velocity_rms_mps: f64,
    predicted_sigma_mps: f64,
    worst_velocity_error_mps: f64,
    mean_nees: f64,
}

/// Figures pooled over `seeds` windows.
fn aggregate(sampling: Sampling, seeds: u64) -> Aggregate {
    let (mut raw, mut opt) = (0.0, 0.0);
    let (mut errors, mut raw_errors, mut nees, mut sigma) = (vec![], vec![], vec![], vec![]);
    for seed in 0..seeds {
        let figures = run_noisy_window(0xC0FFEE + seed, sampling);
        raw += figures.raw_rmse_m.powi(2);
        opt += figures.optimized_rmse_m.powi(2);
        errors.extend(figures.velocity_errors_mps);
        raw_errors.extend(figures.raw_velocity_errors_mps);
        nees.extend(figures.velocity_nees);
        sigma.extend(figures.velocity_sigma_mps);
    }
    let result = Aggregate {
        raw_rmse_m: (raw / seeds as f64).sqrt(),
        optimized_rmse_m: (opt / seeds as f64).sqrt(),
        velocity_rms_mps: rms_per_axis(&errors),
        raw_velocity_rms_mps: rms_per_axis(&raw_errors),
        predicted_sigma_mps: (sigma.iter().map(|s| s * s).sum::<f64>() / sigma.len() as f64).sqrt(),
        worst_velocity_error_mps: errors.iter().map(|e| e.norm()).fold(0.0, f64::max),
        mean_nees: nees.iter().sum::<f64>() / nees.len() as f64,
    };
    println!(
        "{seeds} windows ({}): object translation RMSE raw {:.3} m, optimized {:.3} m; velocity \
         error RMS/axis {:.3} m/s (predicted σ {:.3}, two-frame raw {:.3}), worst |e| {:.3} m/s, \
         mean NEES {:.2} (3 if consistent)",
        match sampling {
            Sampling::Exact => "exact",
            Sampling::NoisyDetections => "noisy detections, constant velocity",
            Sampling::FullModel => "all drawn from the noise models",
        },
        result.raw_rmse_m,
        result.optimized_rmse_m,
        result.velocity_rms_mps,
        result.predicted_sigma_mps,
        result.raw_velocity_rms_mps,
        result.worst_velocity_error_mps,
        result.mean_nees,
    );
    result
}

/// Constant-velocity truth with noisy detections, pooled over 64 windows: the
/// optimized poses beat the detections, the motion nodes' velocities beat a
/// two-frame difference of detections several times over, and their errors
/// stay within the predicted covariance (mean NEES at most 3; below it
/// because the truth has none of the accelerations the smoothness prior allows).
#[test]
fn noisy_window_velocity_statistics() {
    let a = aggregate(Sampling::NoisyDetections, 64);
    assert!(a.optimized_rmse_m < 0.8 * a.raw_rmse_m);
    assert!(a.velocity_rms_mps < 0.35 * a.raw_velocity_rms_mps);
    assert!(
        (1.5..3.5).contains(&a.mean_nees),
        "mean NEES {}",
        a.mean_nees
    );
}

/// With every measurement and the truth drawn from the graph's own noise
/// models, the velocity errors have exactly the predicted spread: mean NEES
/// ≈ 3 (3072 samples, correlated within a window; the standard error of the
/// mean is ~0.08, and 1024 windows gave 3.03).
#[test]
fn full_model_window_velocity_is_consistent() {
    let a = aggregate(Sampling::FullModel, 256);
    assert!(a.optimized_rmse_m < a.raw_rmse_m);
    assert!(
        (2.6..3.4).contains(&a.mean_nees),
        "mean NEES {}",
        a.mean_nees
    );
}
