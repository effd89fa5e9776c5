//! A KITTI tracking sequence as the simulator's replay input
//! ([`limot_sim::replay::ReplayInput`]): the digital twin's ego poses, object
//! tracks and (optionally) recorded detections, read with this module's
//! siblings (OXTS, labels, calibration, detections).
//!
//! Frames and times: twin frame `k` is KITTI frame `first_frame + k`, at
//! `k * KITTI_FRAME_PERIOD_S` (the sweep start, as `limot run` times a
//! tracking sequence). The world is the first replayed IMU pose made level:
//! `t_world_lidar = L * oxts_to_poses(records)[k] * Tr_imu_velo⁻¹`, with
//! `oxts_to_poses` the devkit's poses relative to the first replayed record
//! (what `limot eval` and `limot run` use as ground truth) and
//! `L = Ry(pitch_0) Rx(roll_0)` the first record's attitude, so z is up
//! (the simulator's gravity) and x the first heading. Ground truth of a twin
//! and of the real sequence thus differ by the constant rotation `L`, which
//! every aligned metric (ATE, RPE) ignores.
//!
//! Positions are weighted by [`NOMINAL_POSITION_SIGMA_M`], inflated in
//! proportion where OXTS reports a `pos_accuracy` above
//! [`DEGRADED_POS_ACCURACY_M`] (GPS dropouts), so the fit leans on the
//! smooth motion there.
//!
//! Tracks: every label with a class (`Car`/`Van`, `Truck`, `Pedestrian`,
//! `Person_sitting`, `Cyclist`) of the replayed frames; `DontCare`, `Tram`
//! and `Misc` are left out and counted. Agent id = KITTI track id + 1; a
//! track id reused for a second class (KITTI ids are per sequence, but
//! nothing stops a file reusing one) becomes a second track with an id
//! above all others. A track's box size is the median of its labels'. The
//! box centre is the label's, through the calibration and the frame's pose;
//! its heading is the labelled one projected on the level world plane.
//!
//! Labels exist only inside the left camera's field of view (about ±45° of
//! the heading). Traffic behind and beside the ego is therefore absent from
//! a twin unless it was in view at some labelled frame: a car overtaking the
//! ego appears only once ahead; a car followed by the ego is missing until
//! then; oncoming cars disappear as they pass. Moving traffic exists while
//! labelled (nothing is seen that the labels did not place; inventing
//! unlabelled traffic would make the twin's ground truth disagree with the
//! real sequence's). Parked cars are the exception: one labelled at rest
//! stays where it was for the whole drive, as the real one did while the
//! ego drove past it, wherever that overlaps neither the ego nor another
//! agent (`limot_sim::replay`, `park_for_the_drive`); its ground truth stays
//! the frames KITTI labelled (`gt/boxes.csv`'s `labelled` column), so that a
//! twin is scored against the same truth as the real sequence. Without that the cars
//! lining a street vanished as the ego passed them, and with them most of
//! the structure beside the ego (reports/kitti-twins). The moving-traffic
//! gap left is part of what the twin-vs-real comparison measures.

use super::calib::Calib;
use super::detections::{ScoreMap, camera_box_to_lidar, detections_by_frame, read_ab3dmot_csv};
use super::labels::{TrackingLabel, read_labels};
use super::oxts::{OxtsRecord, oxts_to_poses, read_oxts};
use super::{KITTI_FRAME_PERIOD_S, KittiError, Result, sequence_file};
use limot_estimator::input::ObjectClass;
use limot_sim::replay::{ReplayInput, ReplayTrack, TrackBox};
use limot_sim::scenario::KittiParams;
use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion, Vector3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// 1-sigma of an OXTS position in the fit when GPS is good, m (the frame to
/// frame jitter of RTK-aided INS positions is a few cm).
pub const NOMINAL_POSITION_SIGMA_M: f64 = 0.05;
/// `pos_accuracy` above this counts as degraded GPS, m.
pub const DEGRADED_POS_ACCURACY_M: f64 = 1.0;

/// What the conversion left out or changed, for the report.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TwinNotes {
    /// KITTI frames replayed: first and count.
    pub first_frame: usize,
    /// Frames replayed.
    pub frames: usize,
    /// Replayed frames with degraded GPS (see [`DEGRADED_POS_ACCURACY_M`]).
    pub degraded_gps_frames: usize,
    /// Labels without a class of ours, by KITTI type (`DontCare`, `Tram`, `Misc`).
    pub skipped_labels: BTreeMap<String, usize>,
    /// Track ids reused for a second class.
    pub reused_ids: usize,
    /// The ego's path length over the replayed frames, m.
    pub path_length_m: f64,
    /// The label file did not exist (a testing sequence): no tracks.
    pub no_labels: bool,
}

/// The files of one sequence.
fn files(training: &Path, sequence: u32) -> [PathBuf; 3] {
    [
        sequence_file(&training.join("oxts"), sequence),
        sequence_file(&training.join("calib"), sequence),
        sequence_file(&training.join("label_02"), sequence),
    ]
}

/// Reads the sequence `params` names and converts it (see the module docs);
/// at most `max_frames` frames (the scenario's duration).
///
/// # Errors
/// An unreadable or malformed OXTS, calibration, label or detection file
/// (file, line, field), a `first_frame` beyond the OXTS record or fewer than
/// two frames to replay ([`KittiError::Invalid`] naming the OXTS file).
pub fn replay_input(params: &KittiParams, max_frames: usize) -> Result<(ReplayInput, TwinNotes)> {
    let training = PathBuf::from(&params.training);
    let [oxts_path, calib_path, labels_path] = files(&training, params.sequence);
    let records = read_oxts(&oxts_path)?;
    let calib = Calib::read(&calib_path)?;
    let first = params.first_frame;
    let available = records.len().saturating_sub(first);
    let n = params
        .frames
        .unwrap_or(usize::MAX)
        .min(available)
        .min(max_frames);
    if n < 2 {
        return Err(KittiError::Invalid {
            path: oxts_path,
            why: format!(
                "{} records: frames {first}.. leave {n} to replay (at least 2 needed)",
                records.len()
            ),
        });
    }
    let replayed = &records[first..first + n];
    let t_world_lidar = world_lidar_poses(replayed, &calib);
    let position_sigma_m: Vec<f64> = replayed
        .iter()
        .map(|r| NOMINAL_POSITION_SIGMA_M * (r.pos_accuracy_m / DEGRADED_POS_ACCURACY_M).max(1.0))
        .collect();
    let mut notes = TwinNotes {
        first_frame: first,
        frames: n,
        degraded_gps_frames: replayed
            .iter()
            .filter(|r| r.pos_accuracy_m > DEGRADED_POS_ACCURACY_M)
            .count(),
        path_length_m: t_world_lidar
            .windows(2)
            .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
            .sum(),
        ..TwinNotes::default()
    };
    let labels = if labels_path.is_file() {
        read_labels(&labels_path)?
    } else {
        notes.no_labels = true;
        Vec::new()
    };
    let tracks = tracks(&labels, &calib, &t_world_lidar, first, &mut notes);
    let detections = match &params.detections {
        Some(file) => {
            let all = read_ab3dmot_csv(Path::new(file))?;
            let by_frame = detections_by_frame(&all, &calib, ScoreMap::Sigmoid, records.len());
            Some(by_frame[first..first + n].to_vec())
        }
        None => None,
    };
    Ok((
        ReplayInput {
            frame_period_s: KITTI_FRAME_PERIOD_S,
            t_world_lidar,
            position_sigma_m,
            t_lidar_imu: calib.t_velo_imu,
            tracks,
            detections,
        },
        notes,
    ))
}

/// `t_world_lidar` of each record in the level world of the first (see the
/// module docs).
pub fn world_lidar_poses(records: &[OxtsRecord], calib: &Calib) -> Vec<Isometry3<f64>> {
    let Some(first) = records.first() else {
        return Vec::new();
    };
    let level = Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_euler_angles(first.roll_rad, first.pitch_rad, 0.0),
    );
    let t_imu_velo = calib.t_velo_imu.inverse();
    oxts_to_poses(records)
        .iter()
        .map(|t_world_imu| level * t_world_imu * t_imu_velo)
        .collect()
}

/// The agent (and ground-truth) id of KITTI track `kitti_track_id` in its
/// twin (its first class; see the module docs for reused ids).
pub fn twin_agent_id(kitti_track_id: i64) -> u32 {
    u32::try_from(kitti_track_id + 1).unwrap_or(u32::MAX)
}

/// The labelled tracks of the replayed frames (see the module docs).
fn tracks(
    labels: &[TrackingLabel],
    calib: &Calib,
    t_world_lidar: &[Isometry3<f64>],
    first_frame: usize,
    notes: &mut TwinNotes,
) -> Vec<ReplayTrack> {
    // (KITTI id, class index) -> the class and its boxes with their sizes,
    // in label order
    type Boxes = Vec<(TrackBox, Vector3<f64>)>;
    let mut groups: BTreeMap<(i64, usize), (ObjectClass, Boxes)> = BTreeMap::new();
    for label in labels {
        let frame = label.frame as usize;
        if frame < first_frame || frame >= first_frame + t_world_lidar.len() {
            continue;
        }
        let Some(class) = label.class().filter(|_| !label.is_dont_care()) else {
            *notes
                .skipped_labels
                .entry(label.type_name.clone())
                .or_default() += 1;
            continue;
        };
        let k = frame - first_frame;
        let box_lidar = camera_box_to_lidar(&label.cam_box, calib);
        let pose = &t_world_lidar[k];
        let heading =
            pose.rotation * Vector3::new(box_lidar.yaw_rad.cos(), box_lidar.yaw_rad.sin(), 0.0);
        let t_world_box = Isometry3::from_parts(
            Translation3::from(pose.transform_point(&box_lidar.center.into()).coords),
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_euler_angles(
                0.0,
                0.0,
                heading.y.atan2(heading.x),
            )),
        );
        let class_index = ObjectClass::ALL
            .iter()
            .position(|c| *c == class)
            .unwrap_or(0);
        groups
            .entry((label.track_id, class_index))
            .or_insert_with(|| (class, Vec::new()))
            .1
            .push((
                TrackBox {
                    frame: k,
                    t_world_box,
                },
                box_lidar.size_lwh,
            ));
    }
    let max_id = groups.keys().map(|(id, _)| *id).max().unwrap_or(0);
    let mut next_spare = u32::try_from(max_id + 2).unwrap_or(u32::MAX);
    let mut seen = std::collections::BTreeSet::new();
    let mut out = Vec::new();
    for ((kitti_id, _), (class, boxes)) in groups {
        let id = if seen.insert(kitti_id) {
            twin_agent_id(kitti_id)
        } else {
            notes.reused_ids += 1;
            next_spare = next_spare.saturating_add(1);
            next_spare - 1
        };
        let median = |axis: usize| {
            let mut v: Vec<f64> = boxes.iter().map(|(_, s)| s[axis]).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        out.push(ReplayTrack {
            id,
            class,
            size_lwh_m: Vector3::new(median(0), median(1), median(2)),
            boxes: boxes.into_iter().map(|(b, _)| b).collect(),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::kitti::oxts::write_oxts;
    use limot_sim::scenario::ScenarioSpec;

    /// A driven sequence of `n` frames northwards at ~11 m/s, GPS degraded
    /// (pos_accuracy 5 m) at frames 10..15.
    fn oxts(n: usize) -> Vec<OxtsRecord> {
        (0..n)
            .map(|k| OxtsRecord {
                lat_deg: 49.0 + k as f64 * 1e-5,
                lon_deg: 8.4,
                alt_m: 110.0 + 0.01 * k as f64,
                yaw_rad: std::f64::consts::FRAC_PI_2,
                pos_accuracy_m: if (10..15).contains(&k) { 5.0 } else { 0.3 },
                ..OxtsRecord::default()
            })
            .collect()
    }

    /// A label line: `frame id type`, a box 10 m ahead in the camera frame.
    fn label(frame: usize, id: i64, kind: &str) -> String {
        format!("{frame} {id} {kind} 0 0 0 0 0 10 10 1.5 1.8 4.2 1.0 1.7 10.0 0.0\n")
    }

    fn write_sequence(dir: &Path, records: &[OxtsRecord], labels: &str) -> KittiParams {
        for sub in ["oxts", "calib", "label_02"] {
            std::fs::create_dir_all(dir.join(sub)).unwrap();
        }
        std::fs::write(dir.join("oxts/0000.txt"), write_oxts(records)).unwrap();
        let calib = crate::io::kitti::calib::tests::sample().write();
        std::fs::write(dir.join("calib/0000.txt"), calib).unwrap();
        std::fs::write(dir.join("label_02/0000.txt"), labels).unwrap();
        KittiParams {
            training: dir.display().to_string(),
            sequence: 0,
            first_frame: 0,
            frames: None,
            corridor: None,
            detections: None,
        }
    }

    fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("limot-twin-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    #[test]
    fn gaps_reused_ids_dont_care_and_gps_dropouts_are_handled() {
        let dir = temp_dir("gaps");
        let mut labels = String::new();
        // track 0 labelled at 0..10 and 14..20 (a 4-frame gap), then its id
        // reused for a pedestrian; a DontCare region and a tram
        for f in (0..10).chain(14..20) {
            labels += &label(f, 0, "Car");
        }
        labels += &label(25, 0, "Pedestrian");
        labels += "3 -1 DontCare -1 -1 -10 0 0 10 10 -1000 -1000 -1000 -10 -1 -1 -1\n";
        labels += &label(4, 7, "Tram");
        let params = write_sequence(&dir, &oxts(30), &labels);
        let (input, notes) = replay_input(&params, usize::MAX).unwrap();
        assert_eq!(notes.frames, 30);
        assert_eq!(notes.degraded_gps_frames, 5);
        assert_eq!(notes.reused_ids, 1);
        assert_eq!(notes.skipped_labels.get("DontCare"), Some(&1));
        assert_eq!(notes.skipped_labels.get("Tram"), Some(&1));
        assert!(input.position_sigma_m[12] > 4.0 * input.position_sigma_m[0]);
        assert_eq!(input.tracks.len(), 2);
        assert_eq!(input.tracks[0].id, 1);
        assert!(input.tracks[1].id > 1);
        assert!((input.t_world_lidar[29].translation.vector.norm() - 32.0).abs() < 2.0);
        // the simulator takes it: the gap is bridged, the reused id is its own agent
        let spec = ScenarioSpec::kitti(params);
        let sim = limot_sim::Simulation::from_replay(&spec, &input).unwrap();
        let report = sim.replay_report().unwrap();
        assert_eq!(report.tracks.bridged_frames, 4);
        assert_eq!(sim.scene().agents.len(), 2);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn frame_windows_and_a_missing_label_file() {
        let dir = temp_dir("window");
        let mut params = write_sequence(&dir, &oxts(30), &label(12, 3, "Car"));
        params.first_frame = 10;
        params.frames = Some(5);
        let (input, notes) = replay_input(&params, usize::MAX).unwrap();
        assert_eq!((input.t_world_lidar.len(), notes.first_frame), (5, 10));
        assert_eq!(input.tracks[0].boxes[0].frame, 2);
        // the scenario's duration caps the frames too
        let (input, _) = replay_input(&params, 3).unwrap();
        assert_eq!(input.t_world_lidar.len(), 3);
        params.first_frame = 29;
        let err = replay_input(&params, usize::MAX).unwrap_err().to_string();
        assert!(
            err.contains("oxts/0000.txt") && err.contains("at least 2"),
            "{err}"
        );
        std::fs::remove_file(dir.join("label_02/0000.txt")).unwrap();
        params.first_frame = 0;
        let (input, notes) = replay_input(&params, usize::MAX).unwrap();
        assert!(notes.no_labels && input.tracks.is_empty());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn malformed_files_name_file_line_and_field() {
        let dir = temp_dir("malformed");
        let bad_label = label(2, 1, "Car").replacen(" 1.5 ", " tall ", 1);
        let params = write_sequence(
            &dir,
            &oxts(10),
            &format!("{}{bad_label}", label(1, 1, "Car")),
        );
        let err = replay_input(&params, usize::MAX).unwrap_err().to_string();
        assert!(
            err.contains("label_02/0000.txt:2") && err.contains("`h`"),
            "{err}"
        );
        let mut text = write_oxts(&oxts(10));
        text = text.replacen(" 0.3 ", " nan ", 1);
        std::fs::write(dir.join("oxts/0000.txt"), text).unwrap();
        let err = replay_input(&params, usize::MAX).unwrap_err().to_string();
        assert!(
            err.contains("oxts/0000.txt:1") && err.contains("pos_accuracy"),
            "{err}"
        );
        std::fs::remove_file(dir.join("calib/0000.txt")).unwrap();
        std::fs::write(dir.join("oxts/0000.txt"), write_oxts(&oxts(10))).unwrap();
        let err = replay_input(&params, usize::MAX).unwrap_err().to_string();
        assert!(err.contains("calib/0000.txt"), "{err}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
