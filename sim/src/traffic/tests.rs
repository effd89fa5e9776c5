use super::*;
use crate::scene::{Agent, Ego, Ground, Scene, Undulation};
use crate::trajectory::{Jet, Knot, Trajectory};
use limot_estimator::input::ObjectClass;
use nalgebra::Vector3;
use nalgebra::{Isometry3, Vector2};

fn car(id: u32, lane: usize, s: f64, v: f64, v0: f64) -> VehicleSpec {
    VehicleSpec {
        id,
        class: ObjectClass::Car,
        size_lwh_m: Vector3::new(4.5, 1.8, 1.5),
        lane,
        start_s_m: s,
        start_speed_mps: v,
        desired_speed_mps: v0,
        depart_s: 0.0,
        lane_changes: Vec::new(),
        driver: DriverParams::car(),
    }
}

fn straight(length_m: f64, offset_m: f64) -> LanePath {
    LanePath::from_pieces(
        Point2::new(0.0, 0.0),
        0.0,
        &[PathPiece::Straight { length_m }],
        offset_m,
    )
    .unwrap()
}

fn spec(lanes: Vec<LanePath>, vehicles: Vec<VehicleSpec>, duration_s: f64) -> TrafficSpec {
    TrafficSpec {
        lanes,
        vehicles,
        stop_lines: Vec::new(),
        jam_fronts: Vec::new(),
        duration_s,
    }
}

/// Scene of the tracks on flat ground with the ego parked far away.
fn scene_of(spec: &TrafficSpec, tracks: &[PlanarTrack]) -> Scene {
    let ground = Ground::flat(0.0);
    let agents = tracks
        .iter()
        .zip(&spec.vehicles)
        .map(|(tr, vs)| Agent {
            id: vs.id,
            class: vs.class,
            size_lwh_m: vs.size_lwh_m,
            parked: false,
            trajectory: lift_to_ground(tr, &ground, &vs.size_lwh_m, None),
            presence: crate::scene::Presence::ALWAYS,
            labelled: crate::scene::Labelling::Seen,
        })
        .collect();
    Scene {
        duration_s: spec.duration_s,
        ground,
        statics: Vec::new(),
        agents,
        ego: Ego {
            trajectory: Trajectory::stationary(
                0.0,
                spec.duration_s,
                &Isometry3::translation(-1e4, -1e4, 0.0),
            ),
            size_lwh_m: Vector3::new(4.5, 1.8, 1.5),
            box_center_lidar_m: Vector3::new(0.0, 0.0, -1.0),
            t_lidar_imu: Isometry3::identity(),
        },
    }
}

#[test]
fn single_car_reaches_desired_speed_on_a_straight() {
    let s = spec(
        vec![straight(2000.0, 0.0)],
        vec![car(1, 0, 10.0, 0.0, 20.0)],
        40.0,
    );
    let tracks = simulate_traffic(&s).unwrap();
    let samples = &tracks[0].samples;
    assert_eq!(samples.len(), 4001);
    let last = samples.last().unwrap();
    assert!(
        (last.speed_mps - 20.0).abs() < 0.5,
        "speed {}",
        last.speed_mps
    );
    assert!(
        samples
            .iter()
            .all(|p| p.y.abs() < 1e-9 && p.speed_mps <= 20.0 + 1e-9)
    );
    // recorded velocity integrates to the recorded positions
    for w in samples.windows(2) {
        let mid_vx = 0.5 * (w[0].vx_mps + w[1].vx_mps);
        assert!((w[1].x - w[0].x - mid_vx * 0.01).abs() < 1e-4);
    }
}

#[test]
fn car_stops_before_the_lane_ends() {
    let s = spec(
        vec![straight(120.0, 0.0)],
        vec![car(1, 0, 10.0, 15.0, 15.0)],
        30.0,
    );
    let tracks = simulate_traffic(&s).unwrap();
    let front_max = tracks[0]
        .samples
        .iter()
        .map(|p| p.x + 2.25)
        .fold(f64::MIN, f64::max);
    let last = tracks[0].samples.last().unwrap();
    eprintln!("stopped {:.2} m before the lane end", 120.0 - front_max);
    assert!(front_max < 120.0 && front_max > 115.0, "front {front_max}");
    assert!(last.speed_mps < 0.01);
}

#[test]
fn car_on_an_arc_stays_near_the_lane_centre() {
    let radius = 60.0;
    let lane = LanePath::from_pieces(
        Point2::new(0.0, 0.0),
        0.0,
        &[
            PathPiece::Straight { length_m: 30.0 },
            PathPiece::Arc {
                length_m: 300.0,
                curvature_1pm: 1.0 / radius,
            },
        ],
        0.0,
    )
    .unwrap();
    let s = spec(vec![lane.clone()], vec![car(1, 0, 5.0, 12.0, 12.0)], 25.0);
    let tracks = simulate_traffic(&s).unwrap();
    let mut worst: f64 = 0.0;
    for (k, p) in tracks[0].samples.iter().enumerate() {
        let (s_m, d) = lane.project(&Point2::new(p.x, p.y));
        if k as f64 * 0.01 > 8.0 && s_m < 300.0 {
            worst = worst.max(d.abs());
        }
    }
    eprintln!("arc steady-state lateral error {worst:.4} m");
    assert!(worst < 0.2, "lateral error {worst}");
    // whole run, including the straight-to-arc transition
    let all = tracks[0]
        .samples
        .iter()
        .map(|p| lane.project(&Point2::new(p.x, p.y)).1.abs())
        .fold(0.0, f64::max);
    assert!(all < 0.5, "transient lateral error {all}");
}

#[test]
fn follower_keeps_min_gap_and_acceleration_is_continuous() {
    let mut leader = car(1, 0, 100.0, 10.0, 10.0);
    leader.size_lwh_m = Vector3::new(12.0, 2.5, 3.5);
    leader.class = ObjectClass::Truck;
    leader.driver = DriverParams::truck();
    let follower = car(2, 0, 20.0, 25.0, 30.0);
    let s = spec(vec![straight(3000.0, 0.0)], vec![leader, follower], 60.0);
    let tracks = simulate_traffic(&s).unwrap();
    let p = DriverParams::car();
    let mut min_gap = f64::INFINITY;
    for (a, b) in tracks[0].samples.iter().zip(&tracks[1].samples) {
        min_gap = min_gap.min(a.x - b.x - 6.0 - 2.25);
    }
    let last_gap = {
        let (a, b) = (
            tracks[0].samples.last().unwrap(),
            tracks[1].samples.last().unwrap(),
        );
        a.x - b.x - 6.0 - 2.25
    };
    eprintln!("min gap {min_gap:.3} m, final gap {last_gap:.3} m");
    assert!(min_gap >= p.min_gap_m, "min gap {min_gap}");
    // converges towards the IDM equilibrium gap s0 + v T (+ a little)
    let equilibrium = p.min_gap_m + 10.0 * p.time_headway_s;
    assert!((last_gap - equilibrium).abs() < 1.5, "final gap {last_gap}");
    // acceleration only changes as fast as the lag allows
    let max_jump = (p.max_accel_mps2 + p.max_decel_mps2) / p.accel_lag_s * 0.01;
    let mut worst_jump: f64 = 0.0;
    for w in tracks[1].samples.windows(2) {
        worst_jump = worst_jump.max((w[1].accel_mps2 - w[0].accel_mps2).abs());
        // centre acceleration is continuous as well
        let da =
            ((w[1].ax_mps2 - w[0].ax_mps2).powi(2) + (w[1].ay_mps2 - w[0].ay_mps2).powi(2)).sqrt();
        assert!(da <= max_jump + 1e-6, "centre accel jump {da}");
    }
    eprintln!("largest accel change per 10 ms {worst_jump:.4} (bound {max_jump:.3})");
    assert!(worst_jump <= max_jump);
    // the follower did brake in earnest
    assert!(tracks[1].samples.iter().any(|p| p.accel_mps2 < -1.0));
}

#[test]
fn follower_stops_behind_a_leader_that_stops_at_a_red_line() {
    let leader = car(1, 0, 150.0, 15.0, 15.0);
    let follower = car(2, 0, 60.0, 25.0, 30.0);
    let mut s = spec(vec![straight(3000.0, 0.0)], vec![leader, follower], 40.0);
    s.stop_lines.push(StopLine {
        lane: 0,
        s_m: 330.0,
        red_intervals_s: vec![(0.0, 30.0)],
    });
    let tracks = simulate_traffic(&s).unwrap();
    let gaps: Vec<f64> = tracks[0]
        .samples
        .iter()
        .zip(&tracks[1].samples)
        .map(|(a, b)| a.x - b.x - 4.5)
        .collect();
    let min_gap = gaps.iter().copied().fold(f64::INFINITY, f64::min);
    eprintln!(
        "stopped queue: min gap {min_gap:.3} m, gap at 29.9 s {:.3} m",
        gaps[2990]
    );
    assert!(
        min_gap >= DriverParams::car().min_gap_m,
        "min gap {min_gap}"
    );
    assert!(tracks[1].samples[2990].speed_mps < 0.05);
    // both move on after the red
    assert!(tracks[1].samples.last().unwrap().speed_mps > 5.0);
}

#[test]
fn car_stops_at_a_red_line_and_goes_on_green() {
    let mut s = spec(
        vec![straight(600.0, 0.0)],
        vec![car(1, 0, 20.0, 12.0, 12.0)],
        40.0,
    );
    s.stop_lines.push(StopLine {
        lane: 0,
        s_m: 150.0,
        red_intervals_s: vec![(0.0, 25.0)],
    });
    let tracks = simulate_traffic(&s).unwrap();
    let samples = &tracks[0].samples;
    let front = |p: &PlanarSample| p.x + 2.25;
    for p in &samples[..2500] {
        assert!(front(p) < 150.0, "crossed on red: {}", front(p));
    }
    let at_red_end = &samples[2499];
    eprintln!(
        "stopped {:.2} m before the line, speed {:.4}",
        150.0 - front(at_red_end),
        at_red_end.speed_mps
    );
    assert!(at_red_end.speed_mps < 0.05);
    assert!(150.0 - front(at_red_end) < 4.0);
    assert!(front(samples.last().unwrap()) > 170.0);
    // a car too close to stop comfortably when the red starts goes on
    let mut late = spec(
        vec![straight(600.0, 0.0)],
        vec![car(1, 0, 140.0, 15.0, 15.0)],
        5.0,
    );
    late.stop_lines.push(StopLine {
        lane: 0,
        s_m: 150.0,
        red_intervals_s: vec![(0.0, 25.0)],
    });
    let tracks = simulate_traffic(&late).unwrap();
    assert!(tracks[0].samples.last().unwrap().x > 180.0);
}

#[test]
fn lane_change_executes_when_free_and_waits_when_blocked() {
    let lanes = vec![straight(2000.0, 0.0), straight(2000.0, 3.5)];
    let mut changer = car(1, 0, 50.0, 15.0, 15.0);
    changer.lane_changes.push(LaneChange {
        t_s: 2.0,
        to_lane: 1,
        cooperative: false,
    });
    let free = spec(lanes.clone(), vec![changer.clone()], 15.0);
    let tracks = simulate_traffic(&free).unwrap();
    let first = tracks[0].samples.iter().position(|p| p.lane == 1).unwrap();
    assert_eq!(first, 200, "change should start at the request");
    let last = tracks[0].samples.last().unwrap();
    assert!((last.y - 3.5).abs() < 0.05, "ended at y {}", last.y);
    // lateral motion is smooth: the lateral acceleration stays moderate
    let max_ay = tracks[0]
        .samples
        .iter()
        .map(|p| p.ay_mps2.abs())
        .fold(0.0, f64::max);
    assert!(max_ay < 2.0, "lateral accel {max_ay}");

    // a car alongside in the target lane blocks until it has pulled ahead
    let blocker = car(2, 1, 50.0, 15.0, 22.0);
    let blocked = spec(lanes, vec![changer, blocker], 30.0);
    let tracks = simulate_traffic(&blocked).unwrap();
    let first = tracks[0].samples.iter().position(|p| p.lane == 1).unwrap();
    eprintln!(
        "blocked lane change started at {:.2} s",
        first as f64 * 0.01
    );
    assert!(first > 300, "started too early at sample {first}");
    let (a, b) = (&tracks[0].samples[first], &tracks[1].samples[first]);
    assert!(b.x - a.x - 4.5 > DriverParams::car().min_gap_m);
    assert!((tracks[0].samples.last().unwrap().y - 3.5).abs() < 0.05);
    let scene = scene_of(&blocked, &tracks);
    assert_eq!(first_overlap(&scene, 0.01), None);
}

#[test]
fn a_cooperative_change_gets_room_beside_a_pacing_car_and_a_plain_one_waits() {
    // a car in the target lane paces the changer, a little behind it: a
    // plain request waits for ever, a cooperative one makes it drop back
    let lanes = vec![straight(2000.0, 0.0), straight(2000.0, 3.5)];
    let pacer = car(2, 1, 48.0, 20.0, 20.0);
    let with = |cooperative| {
        let mut changer = car(1, 0, 50.0, 20.0, 20.0);
        changer.lane_changes.push(LaneChange {
            t_s: 2.0,
            to_lane: 1,
            cooperative,
        });
        let traffic = spec(lanes.clone(), vec![changer, pacer.clone()], 30.0);
        let tracks = simulate_traffic(&traffic).unwrap();
        let first = tracks[0].samples.iter().position(|p| p.lane == 1);
        (traffic, tracks, first)
    };
    let (_, _, first) = with(false);
    assert_eq!(first, None, "the plain change found no gap");
    let (traffic, tracks, first) = with(true);
    let first = first.expect("the cooperative change happens");
    eprintln!("cooperative change started at {:.2} s", first as f64 * 0.01);
    assert!((200..1000).contains(&first), "started at sample {first}");
    // the pacer made room, braking at most comfortably, and nobody overlaps
    let (a, b) = (&tracks[0].samples[first], &tracks[1].samples[first]);
    assert!(a.x - b.x - 4.5 > DriverParams::car().min_gap_m);
    let hardest = tracks[1]
        .samples
        .iter()
        .map(|p| p.accel_mps2)
        .fold(0.0, f64::min);
    assert!(
        hardest >= -DriverParams::car().comfortable_decel_mps2 - 0.05,
        "{hardest}"
    );
    assert!((tracks[0].samples.last().unwrap().y - 3.5).abs() < 0.05);
    assert_eq!(first_overlap(&scene_of(&traffic, &tracks), 0.01), None);
}

#[test]
fn lifted_trajectory_follows_the_dense_samples() {
    let lane = LanePath::from_pieces(
        Point2::new(0.0, 0.0),
        0.2,
        &[
            PathPiece::Straight { length_m: 20.0 },
            PathPiece::Arc {
                length_m: 80.0,
                curvature_1pm: -0.04,
            },
            PathPiece::Straight { length_m: 200.0 },
        ],
        0.0,
    )
    .unwrap();
    let mut s = spec(vec![lane], vec![car(1, 0, 5.0, 3.0, 14.0)], 12.0);
    s.stop_lines.push(StopLine {
        lane: 0,
        s_m: 120.0,
        red_intervals_s: vec![(0.0, 7.0)],
    });
    let ground = Ground {
        base_height_m: 1.0,
        slope: Vector2::new(0.02, -0.01),
        undulations: vec![Undulation {
            amplitude_m: 0.4,
            wave_vector: Vector2::new(0.15, 0.1),
            phase_rad: 0.3,
        }],
        ..Ground::flat(0.0)
    };
    let size = s.vehicles[0].size_lwh_m;
    let track = &simulate(&s, RECORD_EVERY).unwrap()[0];
    let dense = &simulate(&s, 1).unwrap()[0];
    let traj = lift_to_ground(track, &ground, &size, None);
    let mut worst_xy: f64 = 0.0;
    let mut worst_z: f64 = 0.0;
    let mut worst_yaw: f64 = 0.0;
    for (k, p) in dense.samples.iter().enumerate() {
        let t = k as f64 * 1e-3;
        let pose = traj.pose_at(t);
        let v = pose.translation.vector;
        worst_xy = worst_xy.max(((v.x - p.x).powi(2) + (v.y - p.y).powi(2)).sqrt());
        worst_z = worst_z.max((v.z - ground.height(p.x, p.y) - 0.75).abs());
        let (_, _, yaw) = pose.rotation.euler_angles();
        worst_yaw = worst_yaw.max(wrap_angle_rad(yaw - p.yaw).abs());
    }
    eprintln!("lift error: xy {worst_xy:.2e} m, z {worst_z:.2e} m, yaw {worst_yaw:.2e} rad");
    assert!(worst_xy < 1e-3 && worst_z < 1e-3 && worst_yaw < 1e-4);
    // pitch/roll knot rates match finite differences of the interpolant
    let state = traj.state_at(3.333);
    let e = 1e-4;
    let fd = (traj.pose_at(3.333 + e).translation.vector
        - traj.pose_at(3.333 - e).translation.vector)
        / (2.0 * e);
    assert!((state.velocity_world_mps - fd).norm() < 1e-5);
    let r0 = traj.pose_at(3.333 - e).rotation;
    let r1 = traj.pose_at(3.333 + e).rotation;
    let omega_fd = (r0.inverse() * r1).scaled_axis() / (2.0 * e);
    assert!((state.angular_velocity_body_radps - omega_fd).norm() < 1e-4);
    // the ground is actually tilting the body
    let (roll, pitch, _) = traj.pose_at(6.0).rotation.euler_angles();
    assert!(roll.abs() + pitch.abs() > 1e-3);
}

/// The lifted trajectories of a drive are what the simulator keeps of it,
/// for every agent: they store the sampled values alone (six f64 a sample),
/// not a knot with its derivatives, and a scene's world shares them.
#[test]
fn lifted_trajectories_store_six_values_a_sample() {
    let s = spec(
        vec![straight(400.0, 0.0)],
        vec![car(1, 0, 5.0, 3.0, 14.0)],
        10.0,
    );
    let tracks = simulate(&s, RECORD_EVERY).unwrap();
    let size = s.vehicles[0].size_lwh_m;
    let traj = lift_to_ground(&tracks[0], &Ground::flat(0.0), &size, None);
    let samples = tracks[0].samples.len();
    assert_eq!(traj.knot_count(), samples);
    assert_eq!(traj.knot_bytes(), samples * 6 * std::mem::size_of::<f64>());
    // the derived knots are the finite differences of the values
    let h = traj.dt_s;
    let (a, b, c) = (traj.knot(99), traj.knot(100), traj.knot(101));
    let x = |k: &Knot| k.position[0].value;
    assert_eq!(b.position[0].rate, (x(&c) - x(&a)) / (2.0 * h));
    assert_eq!(b.position[0].accel, (x(&c) - 2.0 * x(&b) + x(&a)) / (h * h));
    let scene = scene_of(&s, &tracks);
    let world = crate::world::World::new(&scene);
    assert!(world.shares_trajectories_with(&scene));
}

/// Lifting as the traffic is simulated gives the trajectories of lifting
/// the finished tracks, bit for bit, sprung or rigid, on raised ground.
#[test]
fn tracks_lifted_as_they_are_recorded_are_those_lifted_afterwards() {
    let mut cyclist = car(2, 1, 30.0, 4.0, 6.0);
    cyclist.class = ObjectClass::Cyclist;
    cyclist.size_lwh_m = Vector3::new(1.8, 0.6, 1.7);
    let mut truck = car(3, 0, 40.0, 8.0, 12.0);
    truck.class = ObjectClass::Truck;
    truck.size_lwh_m = Vector3::new(10.0, 2.5, 3.5);
    let s = spec(
        vec![straight(400.0, 0.0), straight(400.0, 3.5)],
        vec![car(1, 0, 5.0, 3.0, 14.0), cyclist, truck],
        6.0,
    );
    let ground = Ground {
        undulations: vec![Undulation {
            amplitude_m: 0.3,
            wave_vector: Vector2::new(0.2, 0.1),
            phase_rad: 0.1,
        }],
        ..Ground::flat(0.5)
    };
    let raised = |x: f64, y: f64| if y > 2.0 { 0.15 + 1e-3 * x } else { 0.0 };
    let lifted = simulate_traffic_lifted(&s, &ground, &raised).unwrap();
    let tracks = simulate_traffic(&s).unwrap();
    for ((vs, track), streamed) in s.vehicles.iter().zip(&tracks).zip(&lifted) {
        let suspension = Suspension::for_class(vs.class);
        let afterwards = lift_onto(track, &ground, &raised, &vs.size_lwh_m, suspension.as_ref());
        assert_eq!(streamed, &afterwards, "vehicle {}", vs.id);
    }
}

fn jam_front(lane: usize, start_s_m: f64, phase_s: f64) -> JamFront {
    JamFront {
        lane,
        start_s_m,
        period_s: 30.0,
        stopped_s: 10.0,
        peak_speed_mps: 14.0,
        accel_mps2: 1.5,
        phase_s,
    }
}

#[test]
fn a_jam_front_cruises_brakes_stands_and_pulls_away_each_period() {
    for phase_s in [0.0, 7.3, 29.9] {
        let front = jam_front(0, 100.0, phase_s);
        assert_eq!(front.state_at(0.0).0, 100.0);
        let dt = 0.01;
        let (mut last_s, mut last_v) = front.state_at(0.0);
        let mut standing_s = 0.0;
        for k in 1..=9000 {
            let (s, v) = front.state_at(k as f64 * dt);
            assert!((0.0..=14.0).contains(&v), "speed {v} at {}", k as f64 * dt);
            // continuous, never backwards, its speed the slope of its path
            assert!(s >= last_s && s - last_s <= 14.0 * dt + 1e-9);
            assert!(
                (v - last_v).abs() <= 1.5 * dt + 1e-9,
                "jump {last_v} -> {v}"
            );
            // (within a step's acceleration where it crosses a phase)
            assert!(((s - last_s) / dt - 0.5 * (v + last_v)).abs() < 1.5 * dt);
            if v == 0.0 {
                standing_s += dt;
            }
            (last_s, last_v) = (s, v);
        }
        // 90 s = three periods, each standing 10 s
        assert!((standing_s - 30.0).abs() < 0.05, "stood {standing_s} s");
        // each period covers the same distance
        let (a, b, c) = (
            front.state_at(5.0).0,
            front.state_at(35.0).0,
            front.state_at(65.0).0,
        );
        assert!(((b - a) - (c - b)).abs() < 1e-9);
    }
}

#[test]
fn traffic_queues_behind_a_jam_front_and_moves_off_in_waves() {
    // two lanes, cars behind the front and one ahead of it
    let lanes = vec![straight(3000.0, 0.0), straight(3000.0, 3.7)];
    let vehicles = vec![
        car(1, 0, 400.0, 15.0, 25.0),
        car(2, 0, 120.0, 14.0, 25.0),
        car(3, 0, 60.0, 14.0, 25.0),
        car(4, 1, 100.0, 14.0, 25.0),
    ];
    let mut s = spec(lanes, vehicles, 90.0);
    s.jam_fronts = vec![jam_front(0, 200.0, 0.0), jam_front(1, 200.0, 26.0)];
    let tracks = simulate_traffic(&s).unwrap();
    assert_eq!(first_overlap(&scene_of(&s, &tracks), 0.01), None);
    for (track, vs) in tracks.iter().zip(&s.vehicles) {
        let front = &s.jam_fronts[vs.lane];
        let behind = vs.start_s_m < front.start_s_m;
        let mut stands = 0;
        let mut standing = false;
        for (k, p) in track.samples.iter().enumerate() {
            let (front_s, _) = front.state_at(k as f64 * track.dt_s);
            if behind {
                // never through the head: its front bumper stays behind it
                assert!(
                    p.x + 2.25 <= front_s + 1e-6,
                    "car {} passed the head",
                    vs.id
                );
            }
            if p.speed_mps < 0.5 && !standing {
                stands += 1;
            }
            standing = p.speed_mps < 0.5 || (standing && p.speed_mps < 3.0);
        }
        let top = track
            .samples
            .iter()
            .map(|p| p.speed_mps)
            .fold(0.0, f64::max);
        // once caught up with the jam (after its first period)
        let top_in_jam = track.samples[3000..]
            .iter()
            .map(|p| p.speed_mps)
            .fold(0.0, f64::max);
        if behind {
            // stop and go: a stand every period, no faster than the head
            // in the jam (a queued car may close up a little)
            assert!(stands >= 2, "car {}: {stands} stands", vs.id);
            assert!(top_in_jam < 15.0, "car {}: top speed {top_in_jam}", vs.id);
        } else {
            // the car ahead of the head drives on at its desired speed
            assert_eq!(stands, 0);
            assert!(top > 24.0);
        }
    }
    // a head that cannot cruise is refused
    s.jam_fronts[1].period_s = 20.0;
    let err = simulate_traffic(&s).unwrap_err().to_string();
    assert!(err.contains("jam_fronts[1].period_s"), "{err}");
}

#[test]
fn invalid_specs_are_reported() {
    let lane = straight(500.0, 0.0);
    let mut bad_lane = car(7, 3, 10.0, 0.0, 10.0);
    let err = simulate_traffic(&spec(vec![lane.clone()], vec![bad_lane.clone()], 5.0));
    assert!(
        matches!(err, Err(TrafficError::InvalidVehicle { id: 7, ref field, .. }) if field == "lane")
    );
    bad_lane.lane = 0;
    bad_lane.start_speed_mps = f64::NAN;
    let err = simulate_traffic(&spec(vec![lane.clone()], vec![bad_lane], 5.0));
    assert!(err.unwrap_err().to_string().contains("start_speed_mps"));
    let close = vec![car(1, 0, 50.0, 10.0, 10.0), car(2, 0, 44.0, 10.0, 10.0)];
    let err = simulate_traffic(&spec(vec![lane.clone()], close, 5.0));
    assert!(
        matches!(
            err,
            Err(TrafficError::StartTooClose {
                follower: 2,
                leader: 1,
                ..
            })
        ),
        "{err:?}"
    );
    let err = simulate_traffic(&spec(vec![lane], vec![car(1, 0, 5.0, 0.0, 10.0)], -1.0));
    assert!(matches!(err, Err(TrafficError::InvalidSpec { .. })));
}

/// Constant-velocity planar trajectory at height 0.75 m.
fn straight_motion(x0: f64, y0: f64, vx: f64, vy: f64, duration_s: f64) -> Trajectory {
    let yaw = vy.atan2(vx);
    let knots = (0..=(duration_s / 0.1).round() as usize)
        .map(|k| {
            let t = k as f64 * 0.1;
            Knot {
                position: [
                    Jet::new(x0 + vx * t, vx, 0.0),
                    Jet::new(y0 + vy * t, vy, 0.0),
                    Jet::new(0.75, 0.0, 0.0),
                ],
                euler: [Jet::new(yaw, 0.0, 0.0), Jet::default(), Jet::default()],
            }
        })
        .collect();
    Trajectory::new(0.0, 0.1, knots)
}

#[test]
fn first_overlap_reports_collisions_with_agents_ego_and_statics() {
    let s = spec(vec![straight(10.0, 0.0)], Vec::new(), 6.0);
    let mut scene = scene_of(&s, &[]);
    let size = Vector3::new(4.5, 1.8, 1.5);
    let agent = |id: u32, trajectory: Trajectory| Agent {
        id,
        class: ObjectClass::Car,
        size_lwh_m: size,
        parked: false,
        trajectory,
        presence: crate::scene::Presence::ALWAYS,
        labelled: crate::scene::Labelling::Seen,
    };
    // two cars crossing at right angles, centres 30 m from the crossing
    scene
        .agents
        .push(agent(1, straight_motion(-30.0, 0.0, 10.0, 0.0, 6.0)));
    scene
        .agents
        .push(agent(2, straight_motion(0.0, -30.0, 0.0, 10.0, 6.0)));
    let hit = first_overlap(&scene, 0.01).expect("crossing cars collide");
    assert_eq!((hit.a, hit.b), (Body::Agent(1), Body::Agent(2)));
    // fronts reach the other's side after 30 - 2.25 - 0.9 m at 10 m/s, plus the 1 cm shrink
    assert!((hit.t_s - 2.69).abs() < 0.015, "{}", hit.t_s);
    // the ego box (below the LiDAR origin) against an agent driving into it
    scene.agents.truncate(1);
    scene.ego.trajectory =
        Trajectory::stationary(0.0, 6.0, &Isometry3::translation(20.0, 0.0, 1.75));
    let hit = first_overlap(&scene, 0.01).expect("agent hits the ego");
    assert_eq!((hit.a, hit.b), (Body::Ego, Body::Agent(1)));
    assert!((hit.t_s - 4.55).abs() < 0.015, "{}", hit.t_s);
    // lifting the ego 2 m higher clears it; a pole in the way is then hit
    scene.ego.trajectory =
        Trajectory::stationary(0.0, 6.0, &Isometry3::translation(20.0, 0.0, 3.9));
    assert_eq!(first_overlap(&scene, 0.01), None);
    scene.statics.push(crate::scene::StaticObject {
        kind: crate::scene::StaticKind::Pole,
        shape: crate::scene::Shape::Cylinder {
            radius_m: 0.2,
            half_height_m: 3.0,
        },
        t_world_object: Isometry3::translation(10.0, 1.0, 3.0),
    });
    let hit = first_overlap(&scene, 0.01).expect("agent hits the pole");
    assert_eq!((hit.a, hit.b), (Body::Agent(1), Body::Static(0)));
    // front at 10 - 0.2 m: centre at 7.55 m, 37.55 m travelled
    assert!((hit.t_s - 3.76).abs() < 0.015, "{}", hit.t_s);
}
