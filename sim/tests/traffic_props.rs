//! Property tests of the traffic model: random multi-lane platoons with random
//! speeds, classes and lane-change requests never produce overlapping bodies,
//! never reverse, and keep the acceleration continuous.

use limot_estimator::input::ObjectClass;
use limot_sim::scene::Trajectory;
use limot_sim::scene::{Agent, Ego, Ground, Scene};
use limot_sim::traffic::{
    DriverParams, JamFront, LaneChange, LanePath, PathPiece, StopLine, Suspension, TrafficSpec,
    VehicleSpec, first_overlap, lift_to_ground, simulate_traffic,
};
use nalgebra::{Isometry3, Point2, Vector3};
use proptest::prelude::*;

const LANE_WIDTH_M: f64 = 3.5;

/// One generated road user before placement.
#[derive(Debug, Clone)]
struct Draft {
    lane: usize,
    class: u8,
    speed_frac: f64,
    desired_mps: f64,
    depart_s: f64,
    /// (time, +1 = left / -1 = right)
    changes: Vec<(f64, i8, bool)>,
}

fn draft() -> impl Strategy<Value = Draft> {
    (
        0usize..4,
        0u8..10,
        0.0f64..1.0,
        3.0f64..32.0,
        prop_oneof![Just(0.0), 0.0f64..5.0],
        prop::collection::vec(
            (
                0.0f64..16.0,
                prop_oneof![Just(1i8), Just(-1i8)],
                any::<bool>(),
            ),
            0..3,
        ),
    )
        .prop_map(
            |(lane, class, speed_frac, desired_mps, depart_s, changes)| Draft {
                lane,
                class,
                speed_frac,
                desired_mps,
                depart_s,
                changes,
            },
        )
}

fn class_of(code: u8) -> (ObjectClass, Vector3<f64>, DriverParams, f64) {
    match code {
        0..=5 => (
            ObjectClass::Car,
            Vector3::new(4.5, 1.85, 1.5),
            DriverParams::car(),
            1.0,
        ),
        6 | 7 => (
            ObjectClass::Truck,
            Vector3::new(11.0, 2.5, 3.6),
            DriverParams::truck(),
            0.8,
        ),
        8 => (
            ObjectClass::Cyclist,
            Vector3::new(1.8, 0.7, 1.7),
            DriverParams::cyclist(),
            0.25,
        ),
        _ => (
            ObjectClass::Pedestrian,
            Vector3::new(0.6, 0.6, 1.75),
            DriverParams::pedestrian(),
            0.06,
        ),
    }
}

/// Parallel lanes of a gently curving road, vehicles placed back to front in
/// each lane with a safe starting gap.
/// `jam`: a jam head in every lane (at the given phase of its cycle), 60 m
/// beyond the farthest vehicle.
fn build_spec(
    n_lanes: usize,
    curvature_1pm: f64,
    drafts: &[Draft],
    red: bool,
    jam: Option<f64>,
) -> TrafficSpec {
    let pieces = [
        PathPiece::Straight { length_m: 80.0 },
        PathPiece::Arc {
            length_m: 250.0,
            curvature_1pm,
        },
        PathPiece::Straight { length_m: 1200.0 },
    ];
    let lanes: Vec<LanePath> = (0..n_lanes)
        .map(|k| {
            LanePath::from_pieces(Point2::new(0.0, 0.0), 0.0, &pieces, k as f64 * LANE_WIDTH_M)
                .unwrap()
        })
        .collect();
    let mut next_rear_s = vec![5.0; n_lanes];
    // (speed, driver) of the previously placed (following) vehicle per lane
    let mut behind: Vec<Option<(f64, DriverParams)>> = vec![None; n_lanes];
    let mut vehicles = Vec::new();
    for (i, d) in drafts.iter().enumerate() {
        let lane = d.lane % n_lanes;
        let (class, size, driver, speed_scale) = class_of(d.class);
        let desired = (d.desired_mps * speed_scale).max(1.0);
        let speed = if d.depart_s > 0.0 {
            0.0
        } else {
            desired * d.speed_frac
        };
        let gap = behind[lane].map_or(0.0, |(v_f, p): (f64, DriverParams)| {
            p.min_gap_m
                + ((v_f * v_f - speed * speed) / (2.0 * p.max_decel_mps2)).max(0.0)
                + v_f * p.accel_lag_s
                + 1.0
        });
        let centre_s = next_rear_s[lane] + gap + 0.5 * size.x;
        next_rear_s[lane] = centre_s + 0.5 * size.x;
        behind[lane] = Some((speed, driver));
        let lane_changes = d
            .changes
            .iter()
            .map(|&(t_s, dir, cooperative)| LaneChange {
                t_s,
                to_lane: (lane as i64 + dir as i64).clamp(0, n_lanes as i64 - 1) as usize,
                cooperative,
            })
            .collect();
        vehicles.push(VehicleSpec {
            id: i as u32 + 1,
            class,
            size_lwh_m: size,
            lane,
            start_s_m: centre_s,
            start_speed_mps: speed,
            desired_speed_mps: desired,
            depart_s: d.depart_s,
            lane_changes,
            driver,
        });
    }
    let stop_lines = if red {
        (0..n_lanes)
            .map(|lane| StopLine {
                lane,
                s_m: 500.0,
                red_intervals_s: vec![(4.0, 12.0)],
            })
            .collect()
    } else {
        Vec::new()
    };
    let head_s_m = next_rear_s.iter().copied().fold(0.0, f64::max) + 60.0;
    let jam_fronts = jam.map_or_else(Vec::new, |phase_s| {
        (0..n_lanes)
            .map(|lane| JamFront {
                lane,
                start_s_m: head_s_m,
                period_s: 16.0,
                stopped_s: 4.0,
                peak_speed_mps: 8.0,
                accel_mps2: 2.0,
                phase_s: phase_s + lane as f64,
            })
            .collect()
    });
    TrafficSpec {
        lanes,
        vehicles,
        stop_lines,
        jam_fronts,
        duration_s: 20.0,
    }
}

fn scene_of(spec: &TrafficSpec, ground: &Ground) -> Scene {
    let tracks = simulate_traffic(spec).expect("generated spec is valid");
    let agents = tracks
        .iter()
        .zip(&spec.vehicles)
        .map(|(track, vs)| {
            assert_eq!(track.id, vs.id);
            Agent {
                id: vs.id,
                class: vs.class,
                size_lwh_m: vs.size_lwh_m,
                parked: false,
                trajectory: lift_to_ground(
                    track,
                    ground,
                    &vs.size_lwh_m,
                    Suspension::for_class(vs.class).as_ref(),
                ),
                presence: limot_sim::scene::Presence::ALWAYS,
                labelled: limot_sim::scene::Labelling::Seen,
            }
        })
        .collect();
    for track in &tracks {
        for w in track.samples.windows(2) {
            assert!(w[0].speed_mps >= 0.0);
            // first-order lag (>= 0.25 s) on commands within [-8, 2] m/s^2 moves
            // at most 40 m/s^3; the final-stop limit -v / 0.15 s at most 8 / 0.15
            assert!(
                (w[1].accel_mps2 - w[0].accel_mps2).abs() < 8.0 / 0.15 * 0.01 + 1e-9,
                "acceleration jump in track {}: {:?} -> {:?}",
                track.id,
                w[0],
                w[1]
            );
        }
    }
    Scene {
        duration_s: spec.duration_s,
        ground: ground.clone(),
        statics: Vec::new(),
        agents,
        ego: Ego {
            trajectory: Trajectory::stationary(
                0.0,
                spec.duration_s,
                &Isometry3::translation(-5000.0, -5000.0, 1.7),
            ),
            size_lwh_m: Vector3::new(4.6, 1.9, 1.5),
            box_center_lidar_m: Vector3::new(0.0, 0.0, -1.0),
            t_lidar_imu: Isometry3::identity(),
        },
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    #[test]
    fn random_platoons_never_overlap(
        n_lanes in 2usize..=4,
        curvature in -0.012f64..0.012,
        drafts in prop::collection::vec(draft(), 5..=20),
        red in any::<bool>(),
        jam in prop::option::of(0.0f64..16.0),
    ) {
        let spec = build_spec(n_lanes, curvature, &drafts, red, jam);
        let scene = scene_of(&spec, &Ground::flat(0.0));
        let overlap = first_overlap(&scene, 0.01);
        prop_assert!(overlap.is_none(), "overlap {overlap:?}");
    }
}

fn piece() -> impl Strategy<Value = PathPiece> {
    prop_oneof![
        (1.0f64..60.0).prop_map(|length_m| PathPiece::Straight { length_m }),
        (1.0f64..60.0, -0.02f64..0.02).prop_map(|(length_m, curvature_1pm)| PathPiece::Arc {
            length_m,
            curvature_1pm
        }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// Offsetting a point sideways from the lane projects back to the same
    /// (s, lateral), and parallel lanes have the analytic length.
    #[test]
    fn lane_projection_inverts_offsets(
        pieces in prop::collection::vec(piece(), 1..5),
        heading in -3.0f64..3.0,
        offset in -4.0f64..4.0,
        u in 0.0f64..1.0,
        lateral in -3.0f64..3.0,
    ) {
        let lane = LanePath::from_pieces(Point2::new(3.0, -7.0), heading, &pieces, offset).unwrap();
        let want_len: f64 = pieces
            .iter()
            .map(|p| match *p {
                PathPiece::Straight { length_m } => length_m,
                PathPiece::Arc { length_m, curvature_1pm } => length_m * (1.0 - curvature_1pm * offset),
            })
            .sum();
        prop_assert!((lane.length_m() - want_len).abs() < 1e-9);
        let s = u * lane.length_m();
        let h = lane.heading_at(s);
        let p = lane.point_at(s) + nalgebra::Vector2::new(-h.sin(), h.cos()) * lateral;
        let (s_p, d_p) = lane.project(&p);
        // the closest point is unique while |lateral| < radius (>= 46 m here)
        // except near the path's corners at the ends, where s clamps
        if s > 0.5 && s < lane.length_m() - 0.5 {
            prop_assert!((s_p - s).abs() < 1e-6, "s {} vs {}", s_p, s);
            prop_assert!((d_p - lateral).abs() < 1e-6, "d {} vs {}", d_p, lateral);
        }
    }
}
