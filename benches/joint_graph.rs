//! Per-scan cost of the joint ego + object factor graph against
//! the number of tracked objects, one thread:
//! `cargo bench -p limot --bench joint_graph [-- N1 N2 ...]` (default 0 10 30 60).
//!
//! A synthetic window at 10 Hz runs exactly the estimator's per-frame graph
//! cycle (see `Estimator::push_frame`): new ego state (pose, velocity, bias)
//! with the real `ImuFactor` on preintegrated IMU samples, the bias random
//! walk and a LiDAR pose prior with a full 6×6 information; the objects of
//! the frame through `ObjectGraph::add_frame`; `optimize`; then, with a
//! window of 5, `ObjectGraph::marginalize_oldest`. About 20 % of the objects
//! are static. The truth is known, so the end of each run prints the
//! estimation error as a sanity check that the graph timed is a well-posed
//! one.

use limot_estimator::geometry::OrientedBox;
use limot_estimator::graph::{
    BiasRandomWalkFactor, ImuFactor, Key, NoiseModel, PriorFactor, SlidingWindowSmoother,
    SolverConfig, Variable,
};
use limot_estimator::imu::Preintegration;
use limot_estimator::imu::{ImuBias, ImuNoise};
use limot_estimator::input::{Detection, ImuSample, ObjectClass};
use limot_estimator::lidar::SweepMotion;
use limot_estimator::lie;
use limot_estimator::pipeline::EstimatorConfig;
use limot_estimator::pipeline::{ObjectGraph, ObjectGraphConfig};
use limot_estimator::tracking::{Lifecycle, Motion, TrackOutput};
use nalgebra::{DMatrix, Isometry3, Matrix6, Translation3, UnitQuaternion, Vector3, Vector6};
use std::f64::consts::PI;
use std::time::{Duration, Instant};

use limot_test_support::SplitMix64 as Rng;

const FRAME_PERIOD_S: f64 = 0.1;
const SWEEP_DURATION_S: f64 = 0.1;
const IMU_RATE_HZ: f64 = 200.0;
const WARMUP_FRAMES: usize = 10;
const MEASURED_FRAMES: usize = 100;
const GRAVITY_MPS2: f64 = 9.80511;

/// Ego truth: constant world acceleration and yaw rate, so the IMU
/// specific force and rate are known in closed form at any time.
struct EgoTruth {
    velocity0_world_mps: Vector3<f64>,
    accel_world_mps2: Vector3<f64>,
    yaw_rate_radps: f64,
}

impl EgoTruth {
    fn t_world_imu(&self, t_s: f64) -> Isometry3<f64> {
        let p = self.velocity0_world_mps * t_s + self.accel_world_mps2 * (0.5 * t_s * t_s);
        Isometry3::from_parts(
            Translation3::from(p),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.yaw_rate_radps * t_s),
        )
    }

    fn velocity_world_mps(&self, t_s: f64) -> Vector3<f64> {
        self.velocity0_world_mps + self.accel_world_mps2 * t_s
    }

    /// Ideal IMU sample (before bias and noise).
    fn imu(&self, t_s: f64) -> (Vector3<f64>, Vector3<f64>) {
        let rotation = self.t_world_imu(t_s).rotation;
        let specific_force_world = self.accel_world_mps2 + Vector3::new(0.0, 0.0, GRAVITY_MPS2);
        (
            rotation.inverse() * specific_force_world,
            Vector3::new(0.0, 0.0, self.yaw_rate_radps),
        )
    }
}

/// One object moving at constant world velocity (zero when static).
struct ObjectTruth {
    id: u64,
    class: ObjectClass,
    size_lwh: Vector3<f64>,
    position0_world_m: Vector3<f64>,
    velocity_world_mps: Vector3<f64>,
    yaw_rad: f64,
    is_static: bool,
}

impl ObjectTruth {
    fn position_world_m(&self, t_s: f64) -> Vector3<f64> {
        self.position0_world_m + self.velocity_world_mps * t_s
    }
}

fn make_objects(n: usize, ego: &EgoTruth, rng: &mut Rng) -> Vec<ObjectTruth> {
    // Every fifth object is static (20 %).
    (0..n)
        .map(|i| {
            let is_static = i % 5 == 4;
            let class = match i % 7 {
                0..=3 => ObjectClass::Car,
                4 => ObjectClass::Truck,
                5 => ObjectClass::Cyclist,
                _ => ObjectClass::Pedestrian,
            };
            let size_lwh = match class {
                ObjectClass::Car => Vector3::new(4.5, 1.9, 1.6),
                ObjectClass::Truck => Vector3::new(9.0, 2.5, 3.2),
                ObjectClass::Cyclist => Vector3::new(1.8, 0.6, 1.7),
                ObjectClass::Pedestrian => Vector3::new(0.6, 0.6, 1.8),
            };
            let bearing = rng.range(-PI, PI);
            let range_m = rng.range(8.0, 45.0);
            let position0_world_m = Vector3::new(
                range_m * bearing.cos(),
                range_m * bearing.sin(),
                rng.range(-0.3, 0.3),
            );
            // Dynamic objects move with traffic: mostly along the ego's
            // direction, some oncoming or crossing.
            let (velocity_world_mps, yaw_rad) = if is_static {
                (Vector3::zeros(), rng.range(-PI, PI))
            } else {
                let speed_mps = match class {
                    ObjectClass::Pedestrian => rng.range(0.8, 1.8),
                    ObjectClass::Cyclist => rng.range(3.0, 7.0),
                    _ => rng.range(5.0, 15.0),
                };
                let heading = ego.velocity0_world_mps.y.atan2(ego.velocity0_world_mps.x)
                    + match i % 3 {
                        0 => rng.range(-0.2, 0.2),
                        1 => PI + rng.range(-0.2, 0.2),
                        _ => rng.range(-PI, PI),
                    };
                (
                    Vector3::new(heading.cos(), heading.sin(), 0.0) * speed_mps,
                    heading,
                )
            };
            ObjectTruth {
                id: 100 + i as u64,
                class,
                size_lwh,
                position0_world_m,
                velocity_world_mps,
                yaw_rad,
                is_static,
            }
        })
        .collect()
}

/// Timings and solver work of one frame.
#[derive(Debug, Clone, Copy, Default)]
struct FrameTiming {
    build: Duration,
    optimize: Duration,
    marginalize: Duration,
    iterations: usize,
}

impl FrameTiming {
    fn total(&self) -> Duration {
        self.build + self.optimize + self.marginalize
    }
}

/// Estimation errors at the last frame (sanity of the timed graph).
#[derive(Debug, Clone, Copy)]
struct FinalErrors {
    ego_position_m: f64,
    object_position_rms_m: f64,
    objects_in_window: usize,
    window_variables: usize,
    window_factors: usize,
    marginal_priors: usize,
}

/// Runs the window over `WARMUP_FRAMES + MEASURED_FRAMES` frames with `n`
/// objects and returns the timings of the measured frames.
fn run(n_objects: usize, seed: u64) -> (Vec<FrameTiming>, FinalErrors) {
    let mut rng = Rng(seed);
    let config = EstimatorConfig::default();
    let solver: SolverConfig = config.solver;
    let imu_noise = ImuNoise::default();
    let gravity_world = Vector3::new(0.0, 0.0, -GRAVITY_MPS2);
    let ego = EgoTruth {
        velocity0_world_mps: Vector3::new(8.0, 0.5, 0.0),
        accel_world_mps2: Vector3::new(0.4, 0.1, 0.0),
        yaw_rate_radps: 0.05,
    };
    let t_imu_lidar = Isometry3::from_parts(
        Translation3::new(0.3, 0.0, 1.2),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.02),
    );
    let true_bias = ImuBias {
        accel_mps2: Vector3::new(0.05, -0.03, 0.02),
        gyro_radps: Vector3::new(0.002, -0.001, 0.0015),
    };
    let n_frames = WARMUP_FRAMES + MEASURED_FRAMES;
    let imu_period_s = 1.0 / IMU_RATE_HZ;
    let imu: Vec<ImuSample> = (0..=((n_frames as f64 * FRAME_PERIOD_S + 0.2) * IMU_RATE_HZ)
        as usize)
        .map(|i| {
            let t_s = i as f64 * imu_period_s;
            let (accel, gyro) = ego.imu(t_s);
            ImuSample {
                t_s,
                accel_mps2: accel
                    + true_bias.accel_mps2
                    + rng.normal3(imu_noise.accel_noise_density / imu_period_s.sqrt()),
                gyro_radps: gyro
                    + true_bias.gyro_radps
                    + rng.normal3(imu_noise.gyro_noise_density / imu_period_s.sqrt()),
            }
        })
        .collect();
    let objects = make_objects(n_objects, &ego, &mut rng);

    // LiDAR odometry noise: a full 6×6 information like the scan matcher's
    // (translation ~2 cm, rotation ~2 mrad, correlated).
    let sigmas = [0.02, 0.03, 0.02, 0.002, 0.002, 0.003];
    let mixing = Matrix6::from_fn(|r, c| {
        if r == c {
            1.0
        } else {
            0.25 * rng.range(-1.0, 1.0)
        }
    });
    let sqrt_info = Matrix6::from_fn(|r, c| mixing[(r, c)] / sigmas[r]);
    let information = sqrt_info.transpose() * sqrt_info;
    let odometry_noise =
        NoiseModel::from_information(&DMatrix::from_column_slice(6, 6, information.as_slice()))
            .expect("positive definite information");
    let odometry_covariance_sqrt = sqrt_info.try_inverse().expect("invertible");

    let mut smoother = SlidingWindowSmoother::new();
    let graph_config = ObjectGraphConfig::default();
    let mut graph = ObjectGraph::new(graph_config.clone());
    let mut window: std::collections::VecDeque<u64> = Default::default();
    let mut previous: Option<(f64, Isometry3<f64>, Vector3<f64>, ImuBias)> = None;
    let mut timings = Vec::with_capacity(MEASURED_FRAMES);
    let mut last_errors = None;

    for frame in 0..n_frames as u64 {
        let t_s = frame as f64 * FRAME_PERIOD_S;
        // Not timed: the IMU preintegration and the synthetic measurements.
        let (pose_init, velocity_init, bias_init, preintegration) = match previous {
            None => (
                ego.t_world_imu(t_s),
                ego.velocity_world_mps(t_s),
                ImuBias::default(),
                None,
            ),
            Some((t_prev_s, pose, velocity, bias)) => {
                let pre = Preintegration::from_samples(
                    &imu,
                    t_prev_s,
                    t_s,
                    bias,
                    imu_noise,
                    config.max_imu_gap_s,
                )
                .expect("IMU covers the interval");
                let (p, v) = pre.predict(&pose, &velocity, &bias, &gravity_world);
                (p, v, bias, Some(pre))
            }
        };
        let white = Vector6::from_fn(|_, _| rng.normal());
        let t_world_imu_matched =
            lie::oplus(&ego.t_world_imu(t_s), &(odometry_covariance_sqrt * white));
        let guess_t_world_lidar = t_world_imu_matched * t_imu_lidar;
        let true_lidar = |t: f64| ego.t_world_imu(t) * t_imu_lidar;
        let motion = SweepMotion::constant_velocity(
            t_s,
            true_lidar(t_s),
            t_s + SWEEP_DURATION_S,
            true_lidar(t_s + SWEEP_DURATION_S),
        )
        .expect("finite sweep motion");
        let mut detections = Vec::with_capacity(objects.len());
        let mut tracks = Vec::with_capacity(objects.len());
        for (i, object) in objects.iter().enumerate() {
            // Seen when the rotating beam passes its bearing.
            let p_lidar_start =
                true_lidar(t_s).inverse() * nalgebra::Point3::from(object.position_world_m(t_s));
            let bearing = p_lidar_start.y.atan2(p_lidar_start.x);
            let time_offset_s = ((bearing + PI) / (2.0 * PI)).min(0.999) * SWEEP_DURATION_S;
            let t_det_s = t_s + time_offset_s;
            let t_world_lidar_det = true_lidar(t_det_s);
            let center_lidar = t_world_lidar_det.inverse()
                * nalgebra::Point3::from(object.position_world_m(t_det_s));
            let lidar_yaw = {
                let x = t_world_lidar_det.rotation * Vector3::x();
                x.y.atan2(x.x)
            };
            detections.push(Detection {
                box_lidar: OrientedBox {
                    center: center_lidar.coords + rng.normal3(0.12),
                    size_lwh: object.size_lwh,
                    yaw_rad: object.yaw_rad - lidar_yaw + 0.03 * rng.normal(),
                },
                class: object.class,
                score: 0.9,
                time_offset_s,
            });
            tracks.push(TrackOutput {
                id: object.id,
                class: object.class,
                center_world: object.position_world_m(t_s),
                yaw_rad: object.yaw_rad,
                size_lwh: object.size_lwh,
                velocity_world_mps: object.velocity_world_mps,
                lifecycle: Lifecycle::Confirmed,
                motion: if object.is_static {
                    Motion::Static
                } else {
                    Motion::Dynamic
                },
                speed_mps: object.velocity_world_mps.xy().norm(),
                predicted: false,
                detection_index: Some(i),
                detection_score: None,
            });
        }

        // Timed: the graph work of push_frame.
        let clock = Instant::now();
        smoother
            .add_variable(Key::EgoPose(frame), Variable::Pose(pose_init))
            .expect("new key");
        smoother
            .add_variable(Key::EgoVelocity(frame), Variable::Vector3(velocity_init))
            .expect("new key");
        smoother
            .add_variable(Key::EgoBias(frame), Variable::Bias(bias_init))
            .expect("new key");
        match preintegration {
            None => {
                // The first state's priors, as in Estimator::start_inertial.
                let gauge = 1e-3;
                let tilt = 0.01;
                let add = |s: &mut SlidingWindowSmoother, key, value, sigmas: &[f64]| {
                    s.add_factor(Box::new(PriorFactor::new(
                        key,
                        value,
                        NoiseModel::diagonal_sigmas(sigmas),
                    )))
                    .expect("keys in window");
                };
                add(
                    &mut smoother,
                    Key::EgoPose(frame),
                    Variable::Pose(pose_init),
                    &[gauge, gauge, gauge, tilt, tilt, gauge],
                );
                add(
                    &mut smoother,
                    Key::EgoVelocity(frame),
                    Variable::Vector3(velocity_init),
                    &[0.1; 3],
                );
                add(
                    &mut smoother,
                    Key::EgoBias(frame),
                    Variable::Bias(bias_init),
                    &[0.1, 0.1, 0.1, 0.01, 0.01, 0.01],
                );
            }
            Some(pre) => {
                let j = frame - 1;
                let dt_s = pre.delta_t_s();
                smoother
                    .add_factor(Box::new(
                        ImuFactor::new(j, frame, pre, gravity_world).expect("IMU covariance"),
                    ))
                    .expect("keys in window");
                smoother
                    .add_factor(Box::new(
                        BiasRandomWalkFactor::new(j, frame, dt_s, &imu_noise).expect("random walk"),
                    ))
                    .expect("keys in window");
            }
        }
        smoother
            .add_factor(Box::new(PriorFactor::new(
                Key::EgoPose(frame),
                Variable::Pose(t_world_imu_matched),
                odometry_noise.clone(),
            )))
            .expect("keys in window");
        graph
            .add_frame(
                &mut smoother,
                frame,
                window.back().copied(),
                t_s,
                &tracks,
                &detections,
                &motion,
                &guess_t_world_lidar,
                &t_imu_lidar,
            )
            .expect("object nodes");
        window.push_back(frame);
        let build = clock.elapsed();

        let clock = Instant::now();
        // As the estimator does: with dynamic objects conditioned on the ego,
        // the ego's part first, then each object's part on its own.
        let report = if !objects.is_empty() && !graph_config.dynamic_objects_inform_ego {
            let has_ego = |keys: &[Key]| keys.iter().any(|k| matches!(k, Key::EgoPose(_)));
            let ego = smoother.optimize_parts(&solver, has_ego).expect("optimize");
            smoother.refresh_conditioned();
            let parts = smoother
                .optimize_parts(&graph_config.solver, |keys| !has_ego(keys))
                .expect("optimize");
            // Iterations: the ego part's plus the slowest object part's.
            let mut r = ego[0].clone();
            r.iterations += parts.iter().map(|p| p.iterations).max().unwrap_or(0);
            r
        } else {
            smoother.optimize(&solver).expect("optimize")
        };
        let optimize = clock.elapsed();

        let clock = Instant::now();
        while window.len() > config.window_size.max(2) {
            let oldest = window.pop_front().expect("non-empty window");
            graph
                .marginalize_oldest(&mut smoother, oldest)
                .expect("marginalize");
        }
        let marginalize = clock.elapsed();

        let values = smoother.values();
        previous = Some((
            t_s,
            *values.pose(&Key::EgoPose(frame)),
            *values.vector3(&Key::EgoVelocity(frame)),
            *values.bias(&Key::EgoBias(frame)),
        ));
        if frame as usize >= WARMUP_FRAMES {
            timings.push(FrameTiming {
                build,
                optimize,
                marginalize,
                iterations: report.iterations,
            });
        }
        if frame as usize == n_frames - 1 {
            let ego_error = (values.pose(&Key::EgoPose(frame)).translation.vector
                - ego.t_world_imu(t_s).translation.vector)
                .norm();
            let estimates = graph.estimates(&smoother, frame, t_s);
            let mut sq = 0.0;
            for object in &objects {
                let e = estimates.get(&object.id).expect("object estimated");
                let err = e.t_world_object.translation.vector - object.position_world_m(e.t_s);
                sq += err.norm_squared();
            }
            last_errors = Some(FinalErrors {
                ego_position_m: ego_error,
                object_position_rms_m: if objects.is_empty() {
                    0.0
                } else {
                    (sq / objects.len() as f64).sqrt()
                },
                objects_in_window: graph.len(),
                window_variables: values.len(),
                window_factors: smoother.factor_count(),
                marginal_priors: smoother.marginal_priors().len(),
            });
        }
    }
    (timings, last_errors.expect("last frame ran"))
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// (mean, median, p95) in ms.
fn stats(mut d: Vec<Duration>) -> (f64, f64, f64) {
    d.sort();
    let mean = d.iter().sum::<Duration>() / d.len() as u32;
    let at = |p: f64| d[((d.len() - 1) as f64 * p).round() as usize];
    (ms(mean), ms(at(0.5)), ms(at(0.95)))
}

fn main() {
    let counts: Vec<usize> = {
        let given: Vec<usize> = std::env::args()
            .skip(1)
            .filter_map(|a| a.parse().ok())
            .collect();
        if given.is_empty() {
            vec![0, 10, 30, 60]
        } else {
            given
        }
    };
    println!(
        "joint graph, window {}, {} warm-up + {} measured frames at 10 Hz, one thread",
        EstimatorConfig::default().window_size,
        WARMUP_FRAMES,
        MEASURED_FRAMES
    );
    let mut rows = Vec::new();
    println!("\n| objects | stage | mean ms | median ms | p95 ms |\n|---|---|---|---|---|");
    for &n in &counts {
        let (t, errors) = run(n, 0x5EED_0000 + 17);
        let stages: [(&str, Vec<Duration>); 4] = [
            ("build", t.iter().map(|f| f.build).collect()),
            ("optimize", t.iter().map(|f| f.optimize).collect()),
            (
                "condition+marginalize",
                t.iter().map(|f| f.marginalize).collect(),
            ),
            ("total", t.iter().map(|f| f.total()).collect()),
        ];
        let mut mean_total = 0.0;
        for (name, d) in stages {
            let (mean, median, p95) = stats(d);
            if name == "total" {
                mean_total = mean;
            }
            println!("| {n} | {name} | {mean:.3} | {median:.3} | {p95:.3} |");
        }
        let iterations = t.iter().map(|f| f.iterations).sum::<usize>() as f64 / t.len() as f64;
        let max_iterations = t.iter().map(|f| f.iterations).max().unwrap_or(0);
        rows.push((n, mean_total, iterations, max_iterations, errors));
    }
    println!(
        "\n| objects | LM iterations mean / max | variables | factors | priors | ego err m | object rms m |\n|---|---|---|---|---|---|---|"
    );
    for (n, _, it, it_max, e) in &rows {
        println!(
            "| {n} ({} in window) | {it:.2} / {it_max} | {} | {} | {} | {:.3} | {:.3} |",
            e.objects_in_window,
            e.window_variables,
            e.window_factors,
            e.marginal_priors,
            e.ego_position_m,
            e.object_position_rms_m
        );
    }
    // Least-squares slope of the mean total time against the object count,
    // and the per-object increments between consecutive counts (equal for
    // linear growth).
    if rows.len() >= 2 {
        let k = rows.len() as f64;
        let mx = rows.iter().map(|r| r.0 as f64).sum::<f64>() / k;
        let my = rows.iter().map(|r| r.1).sum::<f64>() / k;
        let sxy: f64 = rows.iter().map(|r| (r.0 as f64 - mx) * (r.1 - my)).sum();
        let sxx: f64 = rows.iter().map(|r| (r.0 as f64 - mx).powi(2)).sum();
        println!(
            "\nper-object slope (least squares over all counts): {:.4} ms/object",
            sxy / sxx
        );
        for w in rows.windows(2) {
            println!(
                "  {} -> {} objects: {:.4} ms/object",
                w[0].0,
                w[1].0,
                (w[1].1 - w[0].1) / (w[1].0 as f64 - w[0].0 as f64)
            );
        }
    }
}
