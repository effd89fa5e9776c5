//! The per-frame tracker: predict every track to the frame time, associate
//! detections per class by min-cost flow, update matched tracks, coast or
//! delete unmatched ones, and start tentative tracks from unmatched
//! detections.

use super::association::{associate_by_class, matching_matrix};
use super::track::{Lifecycle, Motion, TimedBox, Track, rotated_yaw};
use super::trajectory_fit::FitError;
use super::{TrackerConfig, TrackerConfigError};
use crate::geometry::OrientedBox;
use crate::geometry::wrap_angle_rad;
use crate::input::ObjectClass;
use nalgebra::{Isometry3, Vector3};

/// A detection already transformed into the world frame by the caller
/// (with the ego pose at the detection time).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldDetection {
    /// The detected box, world frame.
    pub box_world: OrientedBox,
    /// Detected class; tracks only match detections of their class.
    pub class: ObjectClass,
    /// Detector confidence, compared with `min_score` / `birth_min_score`.
    pub score: f64,
    /// When the sensor saw the object, relative to the update time, s (a
    /// rolling LiDAR sees each object at its own time within the sweep: at
    /// 15 m/s, 0.1 s is 1.5 m). The box joins the track's history at
    /// that time.
    pub time_offset_s: f64,
}

impl WorldDetection {
    /// True when every field is usable (finite, positive size).
    fn is_valid(&self) -> bool {
        self.box_world.center.iter().all(|v| v.is_finite())
            && self
                .box_world
                .size_lwh
                .iter()
                .all(|v| v.is_finite() && *v > 0.0)
            && self.box_world.yaw_rad.is_finite()
            && self.time_offset_s.is_finite()
            && self.score.is_finite()
    }
}

/// One track's state after an update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackOutput {
    /// The track's stable id.
    pub id: u64,
    /// The track's class.
    pub class: ObjectClass,
    /// Fitted (smoothed) centre at the frame time, or the prediction when
    /// `predicted`.
    pub center_world: Vector3<f64>,
    /// Heading wrapped to (−π, π].
    pub yaw_rad: f64,
    /// Running mean of the matched sizes.
    pub size_lwh: Vector3<f64>,
    /// Derivative of the fitted trajectory at the frame time.
    pub velocity_world_mps: Vector3<f64>,
    /// Tentative or confirmed.
    pub lifecycle: Lifecycle,
    /// Static or dynamic.
    pub motion: Motion,
    /// Horizontal speed of the straight-line fit over the motion window, the
    /// statistic `motion` is decided on (steadier than the derivative of
    /// the cubic at the window's end).
    pub speed_mps: f64,
    /// No detection matched this frame: the box is the trajectory prediction.
    pub predicted: bool,
    /// Index (into the slice given to [`Tracker::update`]) of the detection
    /// this track matched or was started from this frame.
    pub detection_index: Option<usize>,
    /// That detection's score (the confidence of this frame's box).
    pub detection_score: Option<f64>,
}

/// Errors of [`Tracker`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrackerError {
    /// The configuration is invalid.
    #[error(transparent)]
    Config(#[from] TrackerConfigError),
    /// The update time is NaN or infinite.
    #[error("tracker update at t={t_s}: time is not finite")]
    TimeNotFinite {
        /// The time given (s).
        t_s: f64,
    },
    /// The update time is not after the previous update's.
    #[error("tracker update at t={t_s} is not after the previous update at t={previous_t_s}")]
    TimeNotIncreasing {
        /// The time given (s).
        t_s: f64,
        /// The previous update's time (s).
        previous_t_s: f64,
    },
    /// A track's trajectory fit failed (a non-finite world transform).
    #[error("tracker: trajectory fit failed: {0}")]
    Fit(#[from] FitError),
}

/// Multi-object tracker over world-frame detections.
///
/// ```
/// use limot_estimator::geometry::OrientedBox;
/// use limot_estimator::input::ObjectClass;
/// use limot_estimator::tracking::{Lifecycle, Motion, Tracker, TrackerConfig, WorldDetection};
/// use nalgebra::Vector3;
///
/// let mut tracker = Tracker::new(TrackerConfig::default()).unwrap();
/// // A car driving along x at 10 m/s, detected at 10 Hz.
/// let mut outputs = Vec::new();
/// for k in 0..8 {
///     let t_s = 0.1 * k as f64;
///     let car = WorldDetection {
///         box_world: OrientedBox {
///             center: Vector3::new(10.0 * t_s, 0.0, 0.8),
///             size_lwh: Vector3::new(4.5, 1.8, 1.6),
///             yaw_rad: 0.0,
///         },
///         class: ObjectClass::Car,
///         score: 0.9,
///         time_offset_s: 0.0,
///     };
///     outputs = tracker.update(t_s, &[car]).unwrap();
///     assert_eq!(outputs.len(), 1);
///     // Tentative until `init_frames` (5) consecutive matched frames.
///     let expected = if k + 1 >= 5 { Lifecycle::Confirmed } else { Lifecycle::Tentative };
///     assert_eq!(outputs[0].lifecycle, expected);
/// }
/// let track = &outputs[0];
/// assert_eq!(track.id, 0);
/// assert_eq!(track.motion, Motion::Dynamic);
/// assert!((track.speed_mps - 10.0).abs() < 1e-6);
/// ```
#[derive(Debug, Clone)]
pub struct Tracker {
    config: TrackerConfig,
    tracks: Vec<Track>,
    /// Confirmed tracks past `max_misses`, kept `revive_frames` frames for
    /// re-association.
    lost: Vec<Track>,
    next_id: u64,
    last_t_s: Option<f64>,
    garbage_detections: u64,
    low_score_detections: u64,
}

impl TrackOutput {
    /// The same state in another world frame (`t_new_old` maps old world
    /// coordinates to new ones).
    pub fn transformed(&self, t_new_old: &Isometry3<f64>) -> TrackOutput {
        TrackOutput {
            center_world: t_new_old.transform_point(&self.center_world.into()).coords,
            yaw_rad: wrap_angle_rad(rotated_yaw(t_new_old, self.yaw_rad)),
            velocity_world_mps: t_new_old.rotation * self.velocity_world_mps,
            ..*self
        }
    }
}

impl Tracker {
    /// Creates an empty tracker.
    ///
    /// # Errors
    /// [`TrackerError::Config`] when [`TrackerConfig::validate`] rejects
    /// `config`.
    pub fn new(config: TrackerConfig) -> Result<Self, TrackerError> {
        config.validate()?;
        Ok(Tracker {
            config,
            tracks: Vec::new(),
            lost: Vec::new(),
            next_id: 0,
            last_t_s: None,
            garbage_detections: 0,
            low_score_detections: 0,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// Live tracks (tentative and confirmed, including coasting ones).
    pub fn tracks(&self) -> &[Track] {
        &self.tracks
    }

    /// Lost confirmed tracks kept for re-association (see
    /// `TrackerConfig::revive_frames`); not in the output.
    pub fn lost_tracks(&self) -> &[Track] {
        &self.lost
    }

    /// Detections skipped so far because a field was not finite or a size
    /// was not positive.
    pub fn garbage_detections(&self) -> u64 {
        self.garbage_detections
    }

    /// Detections ignored so far for a score below `min_score`.
    pub fn low_score_detections(&self) -> u64 {
        self.low_score_detections
    }

    /// Predicted centre and (wrapped) yaw of track `id` at `t_s`, from its
    /// trajectory fit; `None` for an unknown id or a non-finite time.
    pub fn predict_box(&self, id: u64, t_s: f64) -> Option<(Vector3<f64>, f64)> {
        if !t_s.is_finite() {
            return None;
        }
        let track = self.tracks.iter().find(|t| t.id() == id)?;
        let p = track.predict(t_s);
        Some((p.center_world, wrap_angle_rad(p.yaw_rad)))
    }

    /// Re-expresses every track in another world frame (`t_new_old` maps
    /// old world coordinates to new ones), keeping ids, lifecycles and
    /// hit counts: the ego's world may be re-anchored (gravity alignment at
    /// initialisation) without losing what was tracked.
    ///
    /// # Errors
    /// [`TrackerError::Fit`] when a track cannot be refitted (a non-finite
    /// `t_new_old`).
    pub fn transform_world(&mut self, t_new_old: &Isometry3<f64>) -> Result<(), TrackerError> {
        for track in self.tracks.iter_mut().chain(&mut self.lost) {
            track.transform_world(t_new_old, &self.config)?;
        }
        Ok(())
    }

    /// Pairs `tracks` with the detections `candidates` (indices into
    /// `detections`) by the configured metric; returns (track index,
    /// detection index) pairs.
    fn associate(
        &self,
        tracks: &[Track],
        t_s: f64,
        detections: &[&WorldDetection],
        candidates: &[usize],
    ) -> Vec<(usize, usize)> {
        let track_classes: Vec<ObjectClass> = tracks.iter().map(|t| t.class()).collect();
        let det_classes: Vec<ObjectClass> =
            candidates.iter().map(|&j| detections[j].class).collect();
        let psi = matching_matrix(&track_classes, &det_classes, |i, c| {
            let det = detections[candidates[c]];
            let predicted = tracks[i].predict(t_s + det.time_offset_s);
            let predicted_box = OrientedBox {
                center: predicted.center_world,
                yaw_rad: predicted.yaw_rad,
                size_lwh: tracks[i].size_lwh(),
            };
            self.config.association.score(
                &predicted_box,
                &det.box_world,
                self.config.alpha_m,
                self.config.d_thres_m,
            )
        });
        associate_by_class(&psi, &track_classes, &det_classes)
            .into_iter()
            .map(|(i, c)| (i, candidates[c]))
            .collect()
    }

    /// Adds a matched detection to a track (heading folded onto the track's).
    fn record_detection(
        track: &mut Track,
        t_s: f64,
        det: &WorldDetection,
        config: &TrackerConfig,
    ) -> Result<(), FitError> {
        let t_det_s = t_s + det.time_offset_s;
        let yaw_rad = track.unwrap_yaw(t_det_s, det.box_world.yaw_rad);
        track.vote_heading(det.box_world.yaw_rad, yaw_rad);
        track.record_hit(
            TimedBox {
                t_s: t_det_s,
                center_world: det.box_world.center,
                yaw_rad,
                size_lwh: det.box_world.size_lwh,
            },
            config,
        )
    }

    /// Processes one frame of detections taken at `t_s` (strictly after the
    /// previous frame). Returns every live track's state at `t_s`, sorted by id.
    /// Unusable detections (non-finite, non-positive size) and those below
    /// `min_score` are skipped and counted, not errors.
    ///
    /// # Errors
    /// [`TrackerError::TimeNotFinite`], [`TrackerError::TimeNotIncreasing`]
    /// for a bad `t_s` (nothing changes then); [`TrackerError::Fit`] if a
    /// track's refit fails.
    pub fn update(
        &mut self,
        t_s: f64,
        detections: &[WorldDetection],
    ) -> Result<Vec<TrackOutput>, TrackerError> {
        if !t_s.is_finite() {
            return Err(TrackerError::TimeNotFinite { t_s });
        }
        if let Some(previous_t_s) = self.last_t_s
            && t_s <= previous_t_s
        {
            return Err(TrackerError::TimeNotIncreasing { t_s, previous_t_s });
        }
        self.last_t_s = Some(t_s);

        // Usable detections only; count what we drop.
        let mut usable: Vec<&WorldDetection> = Vec::with_capacity(detections.len());
        let mut usable_index: Vec<usize> = Vec::with_capacity(detections.len());
        for (index, det) in detections.iter().enumerate() {
            if !det.is_valid() {
                self.garbage_detections += 1;
            } else if det.score < self.config.min_score {
                self.low_score_detections += 1;
            } else {
                usable.push(det);
                usable_index.push(index);
            }
        }
        let mut observed_by: std::collections::HashMap<u64, usize> =
            std::collections::HashMap::new();

        // Score matrix between the tracks and the detections, each track
        // predicted at the time the rolling LiDAR saw the detection (within
        // a sweep a car at 30 m/s moves 3 m, more than the 2 m gate).
        let all_detections: Vec<usize> = (0..usable.len()).collect();
        let pairs = self.associate(&self.tracks, t_s, &usable, &all_detections);

        let mut track_matched = vec![false; self.tracks.len()];
        let mut det_matched = vec![false; usable.len()];
        for &(i, j) in &pairs {
            let track = &mut self.tracks[i];
            Self::record_detection(track, t_s, usable[j], &self.config)?;
            observed_by.insert(track.id(), usable_index[j]);
            track_matched[i] = true;
            det_matched[j] = true;
        }
        for (track, matched) in self.tracks.iter_mut().zip(&track_matched) {
            if !matched {
                track.record_miss();
            }
        }

        // Lost confirmed tracks of earlier frames may take the detections
        // the live tracks left: they come back with their id.
        if !self.lost.is_empty() {
            let left: Vec<usize> = (0..usable.len()).filter(|&j| !det_matched[j]).collect();
            let revived_pairs = self.associate(&self.lost, t_s, &usable, &left);
            let mut revived = vec![false; self.lost.len()];
            for &(i, j) in &revived_pairs {
                let track = &mut self.lost[i];
                Self::record_detection(track, t_s, usable[j], &self.config)?;
                observed_by.insert(track.id(), usable_index[j]);
                revived[i] = true;
                det_matched[j] = true;
            }
            let mut kept = Vec::with_capacity(self.lost.len());
            for (mut track, back) in std::mem::take(&mut self.lost).into_iter().zip(revived) {
                if back {
                    let at = self.tracks.partition_point(|t| t.id() < track.id());
                    self.tracks.insert(at, track);
                } else {
                    track.record_miss();
                    if track.consecutive_misses()
                        <= self.config.max_misses + self.config.revive_frames
                    {
                        kept.push(track);
                    }
                }
            }
            self.lost = kept;
        }
        let config = &self.config;
        let (live, newly_lost): (Vec<Track>, Vec<Track>) = std::mem::take(&mut self.tracks)
            .into_iter()
            .partition(|t| !t.is_lost(config));
        self.tracks = live;
        if config.revive_frames > 0 {
            self.lost.extend(
                newly_lost
                    .into_iter()
                    .filter(|t| t.lifecycle() == Lifecycle::Confirmed),
            );
        }
        for ((det, matched), &index) in usable.iter().zip(&det_matched).zip(&usable_index) {
            if *matched || det.score < self.config.birth_min_score {
                continue;
            }
            let first = TimedBox {
                t_s: t_s + det.time_offset_s,
                center_world: det.box_world.center,
                yaw_rad: det.box_world.yaw_rad,
                size_lwh: det.box_world.size_lwh,
            };
            let track = Track::new(self.next_id, det.class, first, &self.config)?;
            observed_by.insert(self.next_id, index);
            self.next_id += 1;
            self.tracks.push(track);
        }

        // Ids only grow, new tracks are appended and revived ones inserted
        // in place: the list stays sorted.
        Ok(self
            .tracks
            .iter()
            .map(|t| {
                let p = t.predict(t_s);
                TrackOutput {
                    id: t.id(),
                    class: t.class(),
                    center_world: p.center_world,
                    yaw_rad: wrap_angle_rad(p.yaw_rad),
                    size_lwh: t.size_lwh(),
                    velocity_world_mps: p.velocity_world_mps,
                    lifecycle: t.lifecycle(),
                    motion: t.motion(),
                    speed_mps: t.speed_mps(),
                    predicted: t.consecutive_misses() > 0,
                    detection_index: observed_by.get(&t.id()).copied(),
                    detection_score: observed_by.get(&t.id()).map(|&i| detections[i].score),
                }
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::super::{AssociationMetric, HeadingRule};
    use super::*;
    use std::f64::consts::PI;

    fn car_at(x: f64, y: f64) -> WorldDetection {
        WorldDetection {
            box_world: OrientedBox {
                center: Vector3::new(x, y, 0.8),
                size_lwh: Vector3::new(4.5, 1.8, 1.5),
                yaw_rad: 0.0,
            },
            class: ObjectClass::Car,
            score: 0.9,
            time_offset_s: 0.0,
        }
    }

    #[test]
    fn outputs_name_the_detection_each_track_used() {
        let mut tracker = Tracker::new(TrackerConfig::default()).unwrap();
        let mut garbage = car_at(0.0, 0.0);
        garbage.box_world.center.x = f64::NAN;
        // Index 0 is garbage (skipped), 1 and 2 start tracks.
        let out = tracker
            .update(0.0, &[garbage, car_at(10.0, 0.0), car_at(30.0, 5.0)])
            .unwrap();
        let by_x = |out: &[TrackOutput], x: f64| {
            out.iter()
                .find(|t| (t.center_world.x - x).abs() < 1.0)
                .map(|t| t.detection_index)
                .unwrap()
        };
        assert_eq!(by_x(&out, 10.0), Some(1));
        assert_eq!(by_x(&out, 30.0), Some(2));
        // Next frame: only the car at 30 m is seen, listed first; the other coasts.
        let out = tracker.update(0.1, &[car_at(30.1, 5.0)]).unwrap();
        assert_eq!(by_x(&out, 30.0), Some(0));
        assert_eq!(by_x(&out, 10.0), None);
    }

    #[test]
    fn a_tracker_moved_to_another_world_keeps_its_tracks_and_continues_there() {
        use nalgebra::{Translation3, UnitQuaternion};
        // A car driving along x at 8 m/s with a yaw of 0.3 rad, seen for 6 frames.
        let drive = |k: usize| {
            let mut d = car_at(5.0 + 0.8 * k as f64, 2.0);
            d.box_world.yaw_rad = 0.3;
            d
        };
        let mut tracker = Tracker::new(TrackerConfig::default()).unwrap();
        let mut before = Vec::new();
        for k in 0..6 {
            before = tracker.update(0.1 * k as f64, &[drive(k)]).unwrap();
        }
        // The new world: turned 0.5 rad about z and tilted 2 degrees, shifted.
        let t_new_old = Isometry3::from_parts(
            Translation3::new(1.0, -2.0, 0.5),
            UnitQuaternion::from_euler_angles(0.0, 2f64.to_radians(), 0.5),
        );
        tracker.transform_world(&t_new_old).unwrap();
        let moved: Vec<TrackOutput> = before.iter().map(|t| t.transformed(&t_new_old)).collect();
        assert_eq!(moved.len(), 1);
        let (center, yaw) = tracker.predict_box(moved[0].id, 0.5).unwrap();
        assert!(
            (center - moved[0].center_world).norm() < 1e-6,
            "{center} vs {moved:?}"
        );
        assert!(wrap_angle_rad(yaw - moved[0].yaw_rad).abs() < 1e-6);
        assert!((wrap_angle_rad(moved[0].yaw_rad - (0.3 + 0.5))).abs() < 0.01);
        assert!(
            (moved[0].velocity_world_mps.norm() - before[0].velocity_world_mps.norm()).abs() < 1e-9
        );
        // The next detection, seen in the new world, continues the same track.
        let mut next = drive(6);
        next.box_world.center = t_new_old
            .transform_point(&next.box_world.center.into())
            .coords;
        next.box_world.yaw_rad = wrap_angle_rad(rotated_yaw(&t_new_old, next.box_world.yaw_rad));
        let after = tracker.update(0.6, &[next]).unwrap();
        assert_eq!(after.len(), 1);
        assert_eq!(after[0].id, before[0].id);
        assert_eq!(after[0].lifecycle, Lifecycle::Confirmed);
        assert_eq!(after[0].detection_index, Some(0));
    }

    #[test]
    fn rejects_bad_time_and_config() {
        let mut tracker = Tracker::new(TrackerConfig::default()).unwrap();
        assert!(tracker.update(1.0, &[]).is_ok());
        assert_eq!(
            tracker.update(1.0, &[]),
            Err(TrackerError::TimeNotIncreasing {
                t_s: 1.0,
                previous_t_s: 1.0
            })
        );
        assert!(matches!(
            tracker.update(f64::NAN, &[]),
            Err(TrackerError::TimeNotFinite { .. })
        ));
        let bad = TrackerConfig {
            alpha_m: -1.0,
            ..TrackerConfig::default()
        };
        match Tracker::new(bad) {
            Err(TrackerError::Config(e)) => assert_eq!(e.field, "alpha_m"),
            other => panic!("expected a config error, got {other:?}"),
        }
    }

    #[test]
    fn garbage_and_low_score_are_skipped_and_counted() {
        let config = TrackerConfig {
            min_score: 0.5,
            ..TrackerConfig::default()
        };
        let mut tracker = Tracker::new(config).unwrap();
        let mut nan = car_at(0.0, 0.0);
        nan.box_world.center.x = f64::NAN;
        let mut flat = car_at(5.0, 0.0);
        flat.box_world.size_lwh.z = 0.0;
        let mut weak = car_at(10.0, 0.0);
        weak.score = 0.1;
        let out = tracker
            .update(0.0, &[nan, flat, weak, car_at(20.0, 0.0)])
            .unwrap();
        assert_eq!(out.len(), 1);
        assert_eq!(tracker.garbage_detections(), 2);
        assert_eq!(tracker.low_score_detections(), 1);
    }

    #[test]
    fn weak_detections_continue_tracks_but_start_none() {
        let config = TrackerConfig {
            birth_min_score: 0.5,
            ..TrackerConfig::default()
        };
        let mut tracker = Tracker::new(config).unwrap();
        let mut weak = car_at(30.0, 0.0);
        weak.score = 0.2;
        // Frame 0: the strong car starts a track, the weak one does not.
        let out = tracker.update(0.0, &[car_at(0.0, 0.0), weak]).unwrap();
        assert_eq!(out.len(), 1);
        // Frame 1: a weak detection of the tracked car continues its track.
        let mut weak_hit = car_at(0.1, 0.0);
        weak_hit.score = 0.2;
        let out = tracker.update(0.1, &[weak_hit]).unwrap();
        assert_eq!(out.len(), 1);
        assert!(!out[0].predicted);
        assert_eq!(out[0].detection_score, Some(0.2));
    }

    #[test]
    fn confirmation_on_total_hits_survives_a_miss() {
        let run = |total: bool| {
            let config = TrackerConfig {
                init_frames: 3,
                confirm_on_total_hits: total,
                ..TrackerConfig::default()
            };
            let mut tracker = Tracker::new(config).unwrap();
            // Hit, hit, miss, hit.
            tracker.update(0.0, &[car_at(0.0, 0.0)]).unwrap();
            tracker.update(0.1, &[car_at(0.1, 0.0)]).unwrap();
            tracker.update(0.2, &[]).unwrap();
            tracker.update(0.3, &[car_at(0.3, 0.0)]).unwrap()[0].lifecycle
        };
        assert_eq!(run(true), Lifecycle::Confirmed);
        assert_eq!(run(false), Lifecycle::Tentative);
    }

    #[test]
    fn size_is_the_running_mean_of_matched_sizes() {
        let mut tracker = Tracker::new(TrackerConfig::default()).unwrap();
        let lengths = [4.0, 5.0, 4.5, 4.1];
        let mut out = Vec::new();
        for (k, length) in lengths.iter().enumerate() {
            let mut det = car_at(0.5 * k as f64, 0.0);
            det.box_world.size_lwh.x = *length;
            out = tracker.update(0.1 * k as f64, &[det]).unwrap();
        }
        assert!((out[0].size_lwh.x - 4.4).abs() < 1e-12);
        assert!((out[0].size_lwh.y - 1.8).abs() < 1e-12);
        // A miss does not change it.
        let out = tracker.update(0.4, &[]).unwrap();
        assert!((out[0].size_lwh.x - 4.4).abs() < 1e-12);
    }

    #[test]
    fn heading_flip_is_folded_onto_track() {
        let mut tracker = Tracker::new(TrackerConfig::default()).unwrap();
        for k in 0..8 {
            let mut det = car_at(k as f64, 0.0);
            // Every other frame the detector reports the car backwards.
            det.box_world.yaw_rad = if k % 2 == 0 { 0.05 } else { 0.05 - PI };
            let out = tracker.update(0.1 * k as f64, &[det]).unwrap();
            assert_eq!(out.len(), 1);
            assert!((out[0].yaw_rad - 0.05).abs() < 1e-9, "{}", out[0].yaw_rad);
        }
    }

    #[test]
    fn yaw_across_pi_stays_continuous() {
        let mut tracker = Tracker::new(TrackerConfig::default()).unwrap();
        for k in 0..10 {
            let mut det = car_at(0.0, k as f64);
            det.box_world.yaw_rad = wrap_angle_rad(PI - 0.3 + 0.06 * k as f64);
            tracker.update(0.1 * k as f64, &[det]).unwrap();
        }
        // Turning at 0.6 rad/s through ±π: the fit sees a smooth ramp.
        let (_, yaw) = tracker.predict_box(0, 1.0).unwrap();
        assert!(
            (wrap_angle_rad(yaw - (PI - 0.3 + 0.6))).abs() < 1e-6,
            "{yaw}"
        );
        assert!(tracker.predict_box(99, 1.0).is_none());
    }

    #[test]
    fn lost_confirmed_track_is_revived_with_its_id() {
        let run = |revive_frames: usize| {
            let config = TrackerConfig {
                init_frames: 2,
                max_misses: 1,
                revive_frames,
                ..TrackerConfig::default()
            };
            let mut tracker = Tracker::new(config).unwrap();
            // Confirmed in frames 0-2, missed in 3-5 (lost after the second
            // miss), seen again in frame 6 where it would have been.
            for k in 0..3 {
                tracker
                    .update(0.1 * k as f64, &[car_at(k as f64, 0.0)])
                    .unwrap();
            }
            let mut listed = Vec::new();
            for k in 3..6 {
                listed.push(tracker.update(0.1 * k as f64, &[]).unwrap().len());
            }
            let out = tracker.update(0.6, &[car_at(6.0, 0.0)]).unwrap();
            (listed, out)
        };
        let (listed, out) = run(3);
        // Lost tracks are not in the output.
        assert_eq!(listed, vec![1, 0, 0]);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].id, 0);
        assert_eq!(out[0].lifecycle, Lifecycle::Confirmed);
        assert!(!out[0].predicted);
        assert_eq!(out[0].detection_index, Some(0));
        // Without revival the detection starts a new tentative track.
        let (_, out) = run(0);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].id, 1);
        assert_eq!(out[0].lifecycle, Lifecycle::Tentative);
        // Kept `revive_frames` frames after the loss (frame 4) only: with 2,
        // frame 6 is the last chance; with 1 it is too late.
        let (_, out) = run(2);
        assert_eq!(out[0].id, 0);
        let (_, out) = run(1);
        assert_eq!(out[0].id, 1);
    }

    #[test]
    fn live_tracks_take_detections_before_lost_ones() {
        let config = TrackerConfig {
            init_frames: 1,
            max_misses: 0,
            revive_frames: 5,
            ..TrackerConfig::default()
        };
        let mut tracker = Tracker::new(config).unwrap();
        // Two parked cars 1.5 m apart; car 0 is missed once (lost), car 1
        // is seen throughout. A single detection between them goes to the
        // live track even though the lost one is as close.
        tracker
            .update(0.0, &[car_at(0.0, 0.0), car_at(0.0, 1.5)])
            .unwrap();
        tracker.update(0.1, &[car_at(0.0, 1.5)]).unwrap();
        assert_eq!(tracker.lost_tracks().len(), 1);
        let out = tracker.update(0.2, &[car_at(0.0, 0.75)]).unwrap();
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].id, 1);
        assert_eq!(tracker.lost_tracks()[0].id(), 0);
    }

    #[test]
    fn giou_association_pairs_what_the_centre_gate_refuses() {
        // A car detected 2.5 m sideways of its track (e.g. a poor first
        // box): beyond the 2 m centre gate, within GIoU −0.2.
        let run = |association| {
            let config = TrackerConfig {
                association,
                ..TrackerConfig::default()
            };
            let mut tracker = Tracker::new(config).unwrap();
            tracker.update(0.0, &[car_at(0.0, 0.0)]).unwrap();
            let out = tracker.update(0.1, &[car_at(0.0, 2.5)]).unwrap();
            out.iter().map(|o| o.id).collect::<Vec<_>>()
        };
        assert_eq!(run(AssociationMetric::CentreDistance), vec![0, 1]);
        assert_eq!(
            run(AssociationMetric::Giou3d {
                min_giou: -0.2,
                distance_gate: false
            }),
            vec![0]
        );
    }

    #[test]
    fn heading_follows_motion_or_the_majority() {
        let final_yaw = |rule: HeadingRule, speed_mps: f64, yaws: &[f64]| {
            let config = TrackerConfig {
                heading_rule: rule,
                ..TrackerConfig::default()
            };
            let mut tracker = Tracker::new(config).unwrap();
            let mut out = Vec::new();
            for (k, &yaw) in yaws.iter().enumerate() {
                let t = 0.1 * k as f64;
                let mut det = car_at(speed_mps * t, 0.0);
                det.box_world.yaw_rad = yaw;
                out = tracker.update(t, &[det]).unwrap();
            }
            wrap_angle_rad(out[0].yaw_rad)
        };
        // Parked: the first box backwards, the next four forwards.
        let parked = [PI - 0.02, 0.01, -0.01, 0.0, 0.02];
        let first = final_yaw(HeadingRule::FirstDetection, 0.0, &parked);
        let majority = final_yaw(HeadingRule::MotionOrMajority, 0.0, &parked);
        assert!(wrap_angle_rad(first - PI).abs() < 0.05, "{first}");
        assert!(majority.abs() < 0.05, "{majority}");
        // Driving along +x at 10 m/s, every box backwards: the motion wins.
        let backwards = [PI; 12];
        let first = final_yaw(HeadingRule::FirstDetection, 10.0, &backwards);
        let moving = final_yaw(HeadingRule::MotionOrMajority, 10.0, &backwards);
        assert!(wrap_angle_rad(first - PI).abs() < 0.05, "{first}");
        assert!(moving.abs() < 0.05, "{moving}");
    }
}
