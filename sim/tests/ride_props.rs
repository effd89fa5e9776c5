//! The vehicles' ride in generated scenes: the ego's body pitches with its
//! braking and accelerating and rolls out of turns by the suspension's
//! gradients, the road's roughness makes it vibrate, and the IMU (derived
//! from the same motion) sees all of it.

use limot_sim::scenario::ScenarioSpec;
use limot_sim::scene::Scene;
use limot_sim::sensors::{ImuConfig, ImuSimulator};
use limot_sim::traffic::Suspension;

/// Pitch (nose down positive) and roll (left up) of a rotation R = Rz Ry Rx.
fn pitch_roll(q: &nalgebra::UnitQuaternion<f64>) -> (f64, f64) {
    let (roll, pitch, _) = q.euler_angles();
    (pitch, roll)
}

/// The untextured road's pitch and roll under a body of `length` x `width`
/// at the pose (as the suspension sees its wheels, minus the texture).
fn road_attitude(scene: &Scene, x: f64, y: f64, yaw: f64, length: f64, width: f64) -> (f64, f64) {
    let (s, c) = yaw.sin_cos();
    let h = |dx: f64, dy: f64| {
        scene
            .ground
            .untextured_height(x + c * dx - s * dy, y + s * dx + c * dy)
    };
    let (a, b) = (0.3 * length, 0.425 * width);
    let pitch = (0.5 * (h(-a, b) + h(-a, -b) - h(a, b) - h(a, -b))).atan2(2.0 * a);
    let roll = (0.5 * (h(a, b) + h(-a, b) - h(a, -b) - h(-a, -b))).atan2(2.0 * b);
    (pitch, roll)
}

/// Centred moving average over `window` samples (the steady part of a
/// load: the body's lag and overshoot average out).
fn smooth(values: &[f64], window: usize) -> Vec<f64> {
    values
        .windows(window)
        .map(|w| w.iter().sum::<f64>() / window as f64)
        .collect()
}

/// Least-squares slope of y on x.
fn slope(xs: &[f64], ys: &[f64]) -> f64 {
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    sxy / sxx
}

#[test]
fn the_ego_pitches_with_braking_and_rolls_out_of_turns_by_the_car_gradients() {
    let car = Suspension::car();
    for (name, seed) in [("urban", 2), ("highway", 1)] {
        let mut spec = ScenarioSpec::builtin(name).unwrap();
        spec.seed = seed;
        spec.duration_s = 40.0;
        let scene = spec.build().unwrap();
        let size = scene.ego.size_lwh_m;
        let (mut decel, mut pitch_rel, mut lateral, mut roll_rel) =
            (vec![], vec![], vec![], vec![]);
        let mut rates = Vec::new();
        for k in 20..4000 {
            let t = k as f64 * 0.01;
            let state = scene.ego.trajectory.state_at(t);
            let pose = state.t_world_body;
            let (pitch, roll) = pitch_roll(&pose.rotation);
            let r = pose.rotation.to_rotation_matrix();
            let yaw = r[(1, 0)].atan2(r[(0, 0)]);
            let p = pose.translation.vector;
            let (road_pitch, road_roll) = road_attitude(&scene, p.x, p.y, yaw, size.x, size.y);
            let a = state.accel_world_mps2;
            let (s, c) = yaw.sin_cos();
            decel.push(-(c * a.x + s * a.y));
            lateral.push(-s * a.x + c * a.y);
            pitch_rel.push(pitch - road_pitch);
            roll_rel.push(roll - road_roll);
            rates.push(state.angular_velocity_body_radps);
        }
        // the body's attitude over the road follows the driving loads (over
        // a second) with the static gradients
        let second = 100;
        let pitch_gradient = slope(&smooth(&decel, second), &smooth(&pitch_rel, second));
        let want = car.pitch_per_decel_rad_per_mps2;
        eprintln!("{name}: pitch gradient {pitch_gradient:.5} rad per m/s^2 (car {want:.5})");
        assert!(
            (pitch_gradient / want - 1.0).abs() < 0.15,
            "{name}: {pitch_gradient}"
        );
        // roll where the drive turns (the straight urban street barely does)
        let lateral = smooth(&lateral, second);
        let lateral_spread = lateral.iter().map(|a| a.abs()).fold(0.0, f64::max);
        assert!(
            name != "highway" || lateral_spread > 0.3,
            "no turn: {lateral_spread}"
        );
        if lateral_spread > 0.3 {
            let roll_gradient = slope(&lateral, &smooth(&roll_rel, second));
            let want = car.roll_per_lateral_rad_per_mps2;
            eprintln!("{name}: roll gradient {roll_gradient:.5} rad per m/s^2 (car {want:.5})");
            assert!(
                (roll_gradient / want - 1.0).abs() < 0.25,
                "{name}: {roll_gradient}"
            );
        }
        // the texture makes the body vibrate: pitch and roll rates of a
        // tenth of a degree per second and more while driving
        let moving: Vec<f64> = rates
            .iter()
            .zip(&decel)
            .map(|(w, _)| w.x.hypot(w.y))
            .collect();
        let mean_rate = moving.iter().sum::<f64>() / moving.len() as f64;
        assert!(
            mean_rate.to_degrees() > 0.1,
            "{name}: {}",
            mean_rate.to_degrees()
        );

        // a noise-free IMU reports that very motion
        let quiet = ImuConfig::noise_free();
        let imu = ImuSimulator::new(quiet, 3).unwrap();
        let stream = imu.simulate(&scene.ego, 0.2, 40.0).unwrap();
        let mut worst: f64 = 0.0;
        for sample in &stream.samples {
            let state = scene.ego.trajectory.state_at(sample.t_s);
            // the IMU is rigidly mounted with identity rotation: body rates
            worst = worst.max((sample.gyro_radps - state.angular_velocity_body_radps).norm());
        }
        assert!(worst < 1e-9, "{name}: gyro vs trajectory {worst}");
    }
}
