//! Replayed tracks as agents.
//!
//! A track's labelled boxes are sorted by frame (a repeated frame keeps its
//! first box). Gaps of up to [`MAX_GAP_FRAMES`] unlabelled frames are
//! bridged by linear interpolation (the object was there, hidden from the
//! camera); a longer gap splits the track into agents of their own (the
//! later ones get fresh ids above every input id). An agent exists from its
//! first labelled frame until one period after its last
//! ([`crate::scene::Presence`]).
//!
//! Parked or moving is read from the track's own motion: a track whose box
//! centres all lie within [`PARKED_SPREAD_M`] of their mean is a parked
//! agent at rest at the mean position (heading of its first box); any other
//! passes through every labelled box exactly: knots at every frame, rates and
//! accelerations by central differences (see [`super::fit`]). Boxes are
//! upright: only the labelled heading about the world z is kept.
//!
//! Labels exist only in the camera's view, so a parked car the ego drives
//! past would vanish from the twin the moment it leaves that view, while the
//! real LiDAR keeps seeing it beside and behind the ego. [`park_for_the_drive`]
//! keeps such cars where they were labelled for the whole drive wherever
//! that is physically possible (no overlap with the ego or any other agent);
//! their ground truth stays what was labelled ([`Agent::labelled`]: the
//! labelled frames, not the bridged ones), as on the real sequence.

use super::fit::{euler_channels, extrapolated, jets};
use super::{ReplayTrack, TrackBox};
use crate::scene::{Agent, Jet, Knot, Labelling, Presence, Trajectory};
use crate::traffic::overlap::boxes_overlap;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// Longest run of unlabelled frames bridged inside one track (2 s at 10 Hz).
pub const MAX_GAP_FRAMES: usize = 20;
/// A track whose centres stay within this of their mean is parked, m
/// (KITTI labels of a parked car scatter by ~0.1-0.2 m).
pub const PARKED_SPREAD_M: f64 = 0.4;

/// Boxes closer than this are taken to overlap in [`park_for_the_drive`], m
/// (each box grown by half of it on every side).
pub const PARKED_CLEARANCE_M: f64 = 0.3;
/// Time step of the overlap tests of [`park_for_the_drive`], s.
const PARKED_TEST_STEP_S: f64 = 0.1;

/// How the tracks became agents.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TrackSummary {
    /// Agents moving along their labels.
    pub moving: usize,
    /// Parked agents.
    pub parked: usize,
    /// Tracks split at gaps longer than [`MAX_GAP_FRAMES`] (one per split).
    pub splits: usize,
    /// Unlabelled frames bridged by interpolation.
    pub bridged_frames: usize,
    /// Repeated (track, frame) boxes dropped.
    pub duplicates: usize,
    /// Parked agents kept for the whole drive (see `park_for_the_drive`).
    pub parked_for_the_drive: usize,
}

/// The agents of `tracks` (frame period `dt_s`), in input order.
pub(super) fn agents(tracks: &[ReplayTrack], dt_s: f64) -> (Vec<Agent>, TrackSummary) {
    let mut summary = TrackSummary::default();
    let mut next_id = tracks.iter().map(|t| t.id).max().unwrap_or(0);
    let mut out = Vec::new();
    for track in tracks {
        let mut boxes = track.boxes.clone();
        boxes.sort_by_key(|b| b.frame);
        let before = boxes.len();
        boxes.dedup_by_key(|b| b.frame);
        summary.duplicates += before - boxes.len();
        let mut pieces: Vec<Vec<TrackBox>> = Vec::new();
        for b in boxes {
            match pieces.last_mut() {
                Some(piece) if b.frame - piece[piece.len() - 1].frame <= MAX_GAP_FRAMES + 1 => {
                    piece.push(b)
                }
                _ => pieces.push(vec![b]),
            }
        }
        summary.splits += pieces.len().saturating_sub(1);
        for (i, piece) in pieces.iter().enumerate() {
            let id = if i == 0 {
                track.id
            } else {
                next_id = next_id.saturating_add(1);
                next_id
            };
            let agent = agent(track, id, piece, dt_s, &mut summary);
            out.push(agent);
        }
    }
    (out, summary)
}

/// Keeps every parked agent at its place over `[0, until_s)` (its box as
/// labelled, present at every frame) when that box, grown by
/// [`PARKED_CLEARANCE_M`], overlaps none of the ego's boxes (`ego_box_at`:
/// the pose of the box centre and its size, tested every
/// [`PARKED_TEST_STEP_S`]) and no other agent's box at any time the other
/// exists; an agent that would overlap keeps its labelled presence (two
/// pieces of one parked car split at a gap, for instance). Only the
/// presence grows: [`Agent::labelled`] keeps the labelled frames. Returns
/// how many were kept for the drive.
pub(super) fn park_for_the_drive(
    agents: &mut [Agent],
    ego_box_at: impl Fn(f64) -> (Isometry3<f64>, Vector3<f64>),
    until_s: f64,
) -> usize {
    let steps = (until_s / PARKED_TEST_STEP_S).ceil().max(0.0) as usize;
    let times = || (0..=steps).map(|i| (i as f64 * PARKED_TEST_STEP_S).min(until_s));
    let ego: Vec<(Isometry3<f64>, Vector3<f64>)> = times().map(&ego_box_at).collect();
    // Every agent's boxes at the test times while it exists, as labelled.
    let boxes: Vec<Vec<(Isometry3<f64>, Vector3<f64>)>> = agents
        .iter()
        .map(|a| {
            times()
                .filter(|&t| a.is_present(t))
                .map(|t| (a.box_at(t).t_world_box, a.size_lwh_m))
                .collect()
        })
        .collect();
    let mut kept = 0;
    for i in 0..agents.len() {
        if !agents[i].parked || boxes[i].is_empty() {
            continue;
        }
        let (pose, size) = boxes[i][0];
        let grown = size + Vector3::repeat(PARKED_CLEARANCE_M);
        let clear_of = |(other_pose, other_size): &(Isometry3<f64>, Vector3<f64>)| {
            !boxes_overlap(&pose, &grown, other_pose, other_size)
        };
        let clear = ego.iter().all(clear_of)
            && boxes
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .all(|(_, other)| other.iter().all(clear_of));
        if clear {
            agents[i].presence = Presence {
                from_s: 0.0,
                until_s,
            };
            agents[i].trajectory = Trajectory::stationary(0.0, until_s, &pose);
            kept += 1;
        }
    }
    kept
}

fn agent(
    track: &ReplayTrack,
    id: u32,
    boxes: &[TrackBox],
    dt_s: f64,
    summary: &mut TrackSummary,
) -> Agent {
    let (first, last) = (boxes[0].frame, boxes[boxes.len() - 1].frame);
    let presence = Presence {
        from_s: first as f64 * dt_s,
        until_s: (last + 1) as f64 * dt_s,
    };
    let centres: Vec<Vector3<f64>> = boxes
        .iter()
        .map(|b| b.t_world_box.translation.vector)
        .collect();
    let mean = centres.iter().sum::<Vector3<f64>>() / centres.len() as f64;
    let spread = centres
        .iter()
        .map(|c| (c - mean).norm())
        .fold(0.0, f64::max);
    let parked = spread <= PARKED_SPREAD_M;
    let trajectory = if parked {
        summary.parked += 1;
        let (_, _, yaw) = boxes[0].t_world_box.rotation.euler_angles();
        Trajectory::stationary(
            presence.from_s,
            presence.until_s,
            &Isometry3::from_parts(
                Translation3::from(mean),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
            ),
        )
    } else {
        summary.moving += 1;
        let filled = fill_gaps(boxes, summary);
        moving_trajectory(&filled, first, dt_s)
    };
    Agent {
        id,
        class: track.class,
        size_lwh_m: track.size_lwh_m,
        parked,
        trajectory,
        presence,
        labelled: Labelling::Annotated(labelled_spans(boxes, dt_s)),
    }
}

/// One span per run of consecutive labelled frames, each frame covering one
/// period: the bridged frames of a gap are in the world, not in the truth.
fn labelled_spans(boxes: &[TrackBox], dt_s: f64) -> Vec<Presence> {
    let mut spans: Vec<(usize, usize)> = Vec::new();
    for b in boxes {
        match spans.last_mut() {
            Some((_, end)) if b.frame == *end + 1 => *end = b.frame,
            _ => spans.push((b.frame, b.frame)),
        }
    }
    spans
        .into_iter()
        .map(|(first, last)| Presence {
            from_s: first as f64 * dt_s,
            until_s: (last + 1) as f64 * dt_s,
        })
        .collect()
}

/// One pose per frame from the first to the last box: labelled poses as
/// they are, gaps linearly interpolated (heading unwrapped).
fn fill_gaps(boxes: &[TrackBox], summary: &mut TrackSummary) -> Vec<Isometry3<f64>> {
    let poses: Vec<Isometry3<f64>> = boxes.iter().map(|b| b.t_world_box).collect();
    let [yaw, _, _] = euler_channels(&poses);
    let mut out = Vec::new();
    for (i, b) in boxes.iter().enumerate() {
        if i > 0 {
            let prev = &boxes[i - 1];
            let steps = b.frame - prev.frame;
            let (p0, p1) = (
                prev.t_world_box.translation.vector,
                b.t_world_box.translation.vector,
            );
            for s in 1..steps {
                let u = s as f64 / steps as f64;
                let y = yaw[i - 1] + u * (yaw[i] - yaw[i - 1]);
                out.push(Isometry3::from_parts(
                    Translation3::from(p0 + (p1 - p0) * u),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, y),
                ));
                summary.bridged_frames += 1;
            }
        }
        out.push(Isometry3::from_parts(
            b.t_world_box.translation,
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw[i]),
        ));
    }
    out
}

/// Knots through every pose (frame `first_frame + k`), with one extrapolated
/// knot after the last.
fn moving_trajectory(poses: &[Isometry3<f64>], first_frame: usize, dt_s: f64) -> Trajectory {
    let channel =
        |axis: usize| -> Vec<f64> { poses.iter().map(|p| p.translation.vector[axis]).collect() };
    let [yaw, _, _] = euler_channels(poses);
    let (x, y, z, h) = (
        jets(&channel(0), dt_s),
        jets(&channel(1), dt_s),
        jets(&channel(2), dt_s),
        jets(&yaw, dt_s),
    );
    let flat = Jet::new(0.0, 0.0, 0.0);
    let mut knots: Vec<Knot> = (0..poses.len())
        .map(|k| Knot {
            position: [x[k], y[k], z[k]],
            euler: [h[k], flat, flat],
        })
        .collect();
    if let Some(last) = knots.last() {
        knots.push(extrapolated(last, dt_s));
    }
    Trajectory::new(first_frame as f64 * dt_s, dt_s, knots)
}

#[cfg(test)]
mod tests {
    use super::*;
    use limot_estimator::input::ObjectClass;

    fn track(id: u32, boxes: Vec<(usize, f64, f64)>) -> ReplayTrack {
        ReplayTrack {
            id,
            class: ObjectClass::Car,
            size_lwh_m: Vector3::new(4.0, 1.8, 1.5),
            boxes: boxes
                .into_iter()
                .map(|(frame, x, yaw)| TrackBox {
                    frame,
                    t_world_box: Isometry3::from_parts(
                        Translation3::new(x, 2.0, 0.75),
                        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
                    ),
                })
                .collect(),
        }
    }

    #[test]
    fn moving_tracks_pass_through_their_labels_and_exist_while_labelled() {
        // 1 m per frame with a 3-frame gap and a repeated frame
        let mut labels: Vec<(usize, f64, f64)> = (5..30)
            .filter(|f| !(12..15).contains(f))
            .map(|f| (f, f as f64, 0.1))
            .collect();
        labels.push((20, 99.0, 0.0));
        let (agents, summary) = agents(&[track(3, labels)], 0.1);
        assert_eq!(agents.len(), 1);
        assert_eq!(summary.duplicates, 1);
        assert_eq!(summary.bridged_frames, 3);
        let a = &agents[0];
        assert!(!a.parked);
        for f in 5..30 {
            let c = a.trajectory.pose_at(f as f64 * 0.1).translation.vector;
            assert!((c.x - f as f64).abs() < 1e-9, "{f}: {c}");
        }
        assert!(!a.is_present(0.45) && a.is_present(0.5) && a.is_present(2.95));
        assert!(!a.is_present(3.0));
        // in the world through the gap, in the truth only where labelled
        for f in 5..30 {
            let t = f as f64 * 0.1;
            assert!(a.is_present(t), "{f}");
            assert_eq!(a.is_labelled(t), !(12..15).contains(&f), "{f}");
        }
        let v = a.trajectory.state_at(1.25).velocity_world_mps.x;
        assert!((v - 10.0).abs() < 1e-6, "{v}");
    }

    /// A car at rest at (x, y), labelled at `frames`.
    fn parked_at(id: u32, x: f64, y: f64, frames: impl Iterator<Item = usize>) -> ReplayTrack {
        ReplayTrack {
            id,
            class: ObjectClass::Car,
            size_lwh_m: Vector3::new(4.0, 1.8, 1.5),
            boxes: frames
                .map(|frame| TrackBox {
                    frame,
                    t_world_box: Isometry3::translation(x, y, 0.75),
                })
                .collect(),
        }
    }

    #[test]
    fn parked_cars_stay_for_the_drive_only_where_nothing_would_hit_them() {
        // the ego drives along y = 0 at 10 m/s for 10 s
        let ego_size = Vector3::new(4.8, 1.8, 1.5);
        let ego = |t: f64| (Isometry3::translation(10.0 * t, 0.0, 0.75), ego_size);
        let tracks = [
            // beside the lane, labelled for a second: stays
            parked_at(1, 50.0, 4.5, 30..40),
            // in the lane, labelled after the ego has passed its place
            parked_at(2, 20.0, 0.0, 60..70),
            // one car in two pieces (a long gap): they would overlap
            parked_at(3, 80.0, -3.0, (0..10).chain(40..50)),
            // a moving car in the next lane passes a car parked beside it
            track(5, (0..100).map(|f| (f, 0.5 * f as f64, 0.0)).collect()),
        ];
        let (mut agents, _) = agents(&tracks, 0.1);
        // parked in the moving car's lane after it has passed
        agents.extend(super::agents(&[parked_at(9, 30.0, 2.0, 90..95)], 0.1).0);
        let before: Vec<Presence> = agents.iter().map(|a| a.presence).collect();
        assert_eq!(park_for_the_drive(&mut agents, ego, 10.0), 1);
        let by_id = |id: u32| agents.iter().position(|a| a.id == id).unwrap();
        let kept = &agents[by_id(1)];
        assert_eq!((kept.presence.from_s, kept.presence.until_s), (0.0, 10.0));
        assert_eq!(
            kept.trajectory.pose_at(0.0).translation.vector,
            Vector3::new(50.0, 4.5, 0.75)
        );
        assert!(kept.trajectory.end_s() >= 10.0);
        // present for the drive, labelled only where it was labelled
        assert_eq!(
            kept.labelled,
            Labelling::Annotated(vec![Presence {
                from_s: 3.0,
                until_s: 4.0
            }])
        );
        assert!(kept.is_present(2.0) && !kept.is_labelled(2.0));
        assert!(kept.is_labelled(3.5) && !kept.is_labelled(4.0));
        // the others keep their labelled presence
        for (a, was) in agents.iter().zip(&before) {
            assert_eq!(a.labelled, Labelling::Annotated(vec![*was]), "{}", a.id);
            if a.id != 1 {
                assert_eq!(a.presence, *was, "{}", a.id);
            }
        }
    }

    #[test]
    fn still_tracks_are_parked_and_long_gaps_split() {
        let jitter = |f: usize| if f.is_multiple_of(2) { 0.05 } else { -0.05 };
        let mut labels: Vec<(usize, f64, f64)> =
            (0..10).map(|f| (f, 7.0 + jitter(f), 0.0)).collect();
        labels.extend((40..50).map(|f| (f, 7.0 + jitter(f), 0.0)));
        let (agents, summary) = agents(&[track(8, labels)], 0.1);
        assert_eq!(summary.splits, 1);
        assert_eq!(agents.len(), 2);
        assert!(agents.iter().all(|a| a.parked));
        assert_eq!(agents[0].id, 8);
        assert_eq!(agents[1].id, 9);
        assert!(agents[0].is_present(0.5) && !agents[0].is_present(2.0));
        assert!(agents[1].is_present(4.5) && !agents[1].is_present(3.5));
        let c = agents[1].trajectory.pose_at(4.5).translation.vector;
        assert!((c.x - 7.0).abs() < 0.01, "{c}");
    }
}
