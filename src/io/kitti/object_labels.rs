//! KITTI *object detection* label format: one file per frame
//! (`label_2/NNNNNN.txt`, and what most 3D detectors write for the KITTI
//! object benchmark), one object per line:
//!
//! `type truncated occluded alpha x1 y1 x2 y2 h w l x y z rot_y [score]`
//!
//! 15 columns in ground truth, 16 with a detector score. The columns are the
//! tracking label columns (see [`super::labels`]) without `frame` and
//! `track_id`: the frame is the file name. Parsing goes through
//! `TrackingLabel::parse_line` so both formats share one set of checks
//! (finite numbers, known type names); error columns are reported in this
//! format's numbering.
//!
//! Which lines become detections follows [`detections_from_labels`]:
//! `DontCare`, `Misc`, `Tram` lines are skipped; a type name that KITTI does
//! not know (not in [`super::labels::KNOWN_TYPES`]) is an error, as in the
//! tracking reader.
//!
//! Scores: a missing score (ground truth) becomes `score_raw = 1.0`, which
//! [`ScoreMap::Clamp01`](super::detections::ScoreMap::Clamp01) maps to a
//! certain detection (1.0). Detector scores are stored as written; choose
//! `Clamp01` for probabilities and `Sigmoid` for logits when converting.

use super::detections::{CameraDetection, detections_from_labels};
use super::labels::TrackingLabel;
use super::{KittiError, LineCtx, Result, content_lines, read_text};
use std::path::{Path, PathBuf};

/// Columns `frame` and `track_id` of the tracking format that this format lacks.
const PREFIX_COLUMNS: usize = 2;

/// Parses one object-label line as the tracking line `frame -1 <line>` and
/// renumbers error columns to this format.
fn parse_object_line(line: &str, frame: u32, ctx: LineCtx<'_>) -> Result<TrackingLabel> {
    let tracking_line = format!("{frame} -1 {line}");
    TrackingLabel::parse_line(&tracking_line, ctx).map_err(|err| match err {
        KittiError::Field {
            path,
            line,
            column,
            field,
            why,
        } => KittiError::Field {
            path,
            line,
            column: column.saturating_sub(PREFIX_COLUMNS),
            field,
            why,
        },
        KittiError::ColumnCount { .. } => {
            ctx.column_count("15 or 16", line.split_whitespace().count())
        }
        other => other,
    })
}

/// Parses one per-frame object label file; every detection gets `frame`.
/// See the module docs for skipped lines and the missing-score rule.
///
/// # Errors
/// A line with the wrong column count or a malformed field (file, line and column).
pub fn parse_object_labels(text: &str, path: &Path, frame: u32) -> Result<Vec<CameraDetection>> {
    let labels = content_lines(text)
        .map(|(line_no, line)| parse_object_line(line, frame, LineCtx::new(path, line_no)))
        .collect::<Result<Vec<_>>>()?;
    Ok(detections_from_labels(&labels))
}

/// Reads one per-frame object label file.
///
/// # Errors
/// An unreadable file, or a malformed line (see [`parse_object_labels`]).
pub fn read_object_labels(path: &Path, frame: u32) -> Result<Vec<CameraDetection>> {
    parse_object_labels(&read_text(path)?, path, frame)
}

/// The frame number of a per-frame file name (`000042.txt` → 42); `None`
/// for entries that are not `.txt` files.
fn frame_of_file_name(path: &Path) -> Result<Option<u32>> {
    if path.extension().and_then(|e| e.to_str()) != Some("txt") {
        return Ok(None);
    }
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
    let invalid = |why: String| KittiError::Invalid {
        path: path.to_path_buf(),
        why,
    };
    if stem.is_empty() || !stem.bytes().all(|b| b.is_ascii_digit()) {
        return Err(invalid(format!(
            "file name `{stem}.txt` is not a frame number (NNNNNN.txt)"
        )));
    }
    stem.parse::<u32>()
        .map(Some)
        .map_err(|_| invalid(format!("frame number `{stem}` does not fit in u32")))
}

/// Reads a directory of per-frame object label files (`NNNNNN.txt`) into
/// detections per frame: entry `k` holds frame `k`'s detections.
///
/// - Frames missing from the numbering (gaps, and frames before the first
///   file) are empty: detectors usually write no file, or an empty one, for
///   frames without detections. The result ends at the highest frame number.
/// - A `.txt` file whose stem is not a number, or two files naming the same
///   frame (`1.txt` and `000001.txt`), are errors. Other entries
///   (subdirectories, files with other extensions) are ignored.
///
/// # Errors
/// An unreadable directory or label file, or a malformed line.
pub fn read_object_label_dir(dir: &Path) -> Result<Vec<Vec<CameraDetection>>> {
    let io_err = |source| KittiError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut files: Vec<(u32, PathBuf)> = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io_err)? {
        let entry = entry.map_err(io_err)?;
        let path = entry.path();
        if !entry.file_type().map_err(io_err)?.is_file() {
            continue;
        }
        if let Some(frame) = frame_of_file_name(&path)? {
            files.push((frame, path));
        }
    }
    files.sort();
    for pair in files.windows(2) {
        if pair[0].0 == pair[1].0 {
            return Err(KittiError::Invalid {
                path: pair[1].1.clone(),
                why: format!("frame {} also read from {}", pair[1].0, pair[0].1.display()),
            });
        }
    }
    let len = files.last().map_or(0, |(frame, _)| *frame as usize + 1);
    let mut frames = vec![Vec::new(); len];
    for (frame, path) in &files {
        frames[*frame as usize] = read_object_labels(path, *frame)?;
    }
    Ok(frames)
}

/// Formats detections as one per-frame object label file (16 columns, with
/// the raw score; `truncated` and `occluded` are unknown for detections and
/// written as -1, as detectors do). The `frame` field is not written: it is
/// the file name. Numbers are shortest round-trip, so parsing gives back
/// the same detections.
pub fn write_object_labels(detections: &[CameraDetection]) -> String {
    let mut text = String::new();
    for d in detections {
        let label = TrackingLabel {
            frame: d.frame,
            track_id: -1,
            type_name: d.class.name().to_string(),
            truncated: -1.0,
            occluded: -1,
            alpha_rad: d.alpha_rad,
            bbox_2d: d.bbox_2d,
            cam_box: d.cam_box,
            score: Some(d.score_raw),
        };
        // Same column formatting as the tracking writer, minus frame and id.
        let line = label.to_line();
        let object_columns = line
            .splitn(PREFIX_COLUMNS + 1, ' ')
            .nth(PREFIX_COLUMNS)
            .unwrap_or_default();
        text.push_str(object_columns);
        text.push('\n');
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::kitti::calib::Calib;
    use crate::io::kitti::detections::ScoreMap;
    use limot_estimator::input::ObjectClass;
    use nalgebra::Vector3;

    /// KITTI object ground truth (15 columns), from `label_2/000000.txt`-like files.
    const GT: &str = "\
Pedestrian 0.00 0 -0.20 712.40 143.00 810.73 307.92 1.89 0.48 1.20 1.84 1.47 8.41 0.01
DontCare -1 -1 -10 503.89 169.71 590.61 190.13 -1 -1 -1 -1000 -1000 -1000 -10
Misc 0.00 1 -1.5 10 20 30 40 1.5 1.5 2.0 -3.0 1.7 20.0 0.3
";

    /// Detector output (16 columns).
    const SCORED: &str = "\
Car -1 -1 -1.5827 296.7 161.7 455.2 292.3 1.52 1.68 4.45 2.93 1.61 6.43 -1.58 0.93
Cyclist -1 -1 0.2 600 170 640 230 1.7 0.6 1.8 -1.2 1.65 17.5 1.45 0.41
";

    fn real_or_sample_calib() -> Calib {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/data/kitti_tracking/training/calib/0001.txt");
        if path.exists() {
            Calib::read(&path).unwrap()
        } else {
            crate::io::kitti::calib::tests::sample()
        }
    }

    #[test]
    fn ground_truth_line_parses_with_score_one_and_skips_dont_care_misc() {
        let dets = parse_object_labels(GT, Path::new("label_2/000007.txt"), 7).unwrap();
        assert_eq!(dets.len(), 1);
        let d = &dets[0];
        assert_eq!(d.frame, 7);
        assert_eq!(d.class, ObjectClass::Pedestrian);
        assert_eq!(d.score_raw, 1.0);
        assert_eq!(ScoreMap::Clamp01.apply(d.score_raw), 1.0);
        assert_eq!(d.alpha_rad, -0.20);
        assert_eq!(d.bbox_2d, [712.40, 143.00, 810.73, 307.92]);
        assert_eq!(d.cam_box.dims_hwl, Vector3::new(1.89, 0.48, 1.20));
        assert_eq!(d.cam_box.bottom_center_rect, Vector3::new(1.84, 1.47, 8.41));
        assert_eq!(d.cam_box.rotation_y_rad, 0.01);
    }

    #[test]
    fn scored_lines_keep_the_raw_score() {
        let dets = parse_object_labels(SCORED, Path::new("d/000003.txt"), 3).unwrap();
        assert_eq!(dets.len(), 2);
        assert_eq!(dets[0].class, ObjectClass::Car);
        assert_eq!(dets[0].score_raw, 0.93);
        assert_eq!(dets[1].class, ObjectClass::Cyclist);
        assert_eq!(dets[1].score_raw, 0.41);
        assert_eq!(dets[1].cam_box.bottom_center_rect.z, 17.5);
        assert!(dets.iter().all(|d| d.frame == 3));
    }

    #[test]
    fn write_then_parse_round_trips_exactly() {
        let path = Path::new("d/000003.txt");
        let mut dets = parse_object_labels(SCORED, path, 3).unwrap();
        dets.extend(parse_object_labels(GT, path, 3).unwrap());
        // Awkward numbers: shortest round-trip formatting must keep every bit.
        dets[0].cam_box.rotation_y_rad = -std::f64::consts::FRAC_PI_3;
        dets[1].score_raw = 1.0 / 3.0;
        dets[2].bbox_2d[1] = 1e-7;
        let text = write_object_labels(&dets);
        assert_eq!(text.lines().count(), 3);
        assert!(text.lines().all(|l| l.split_whitespace().count() == 16));
        assert!(text.starts_with("Car -1 -1 "), "{text}");
        assert_eq!(parse_object_labels(&text, path, 3).unwrap(), dets);
    }

    #[test]
    fn lidar_detection_equals_the_tracking_format_path() {
        let calib = real_or_sample_calib();
        let object_line = SCORED.lines().next().unwrap();
        let tracking_text = format!("12 5 {object_line}\n");
        let via_tracking = detections_from_labels(
            &crate::io::kitti::labels::parse_labels(&tracking_text, Path::new("t.txt")).unwrap(),
        );
        let via_object = parse_object_labels(object_line, Path::new("o.txt"), 12).unwrap();
        assert_eq!(via_object, via_tracking);
        let a = via_object[0].to_detection(&calib, ScoreMap::Clamp01);
        let b = via_tracking[0].to_detection(&calib, ScoreMap::Clamp01);
        assert_eq!(a, b);
        // And the conversion is a sensible one: 6.4 m ahead, 2.9 m right.
        assert!(
            (a.box_lidar.center.x - 6.7).abs() < 0.3,
            "{}",
            a.box_lidar.center
        );
        assert!(
            (a.box_lidar.center.y - -2.93).abs() < 0.3,
            "{}",
            a.box_lidar.center
        );
        assert_eq!(a.box_lidar.size_lwh, Vector3::new(4.45, 1.68, 1.52));
        assert_eq!(a.score, 0.93);
    }

    #[test]
    fn errors_name_file_line_column_and_field() {
        let path = Path::new("label_2/000042.txt");
        let bad = SCORED.replacen("6.43", "NaN", 1);
        let err = parse_object_labels(&bad, path, 42).unwrap_err().to_string();
        assert!(
            err.contains("label_2/000042.txt:1")
                && err.contains("column 14")
                && err.contains("`z`"),
            "{err}"
        );
        let bad = SCORED.replacen("0.2 600", "0.2 x600", 1);
        let err = parse_object_labels(&bad, path, 42).unwrap_err().to_string();
        assert!(
            err.contains("000042.txt:2") && err.contains("column 5") && err.contains("`x1`"),
            "{err}"
        );
        let bad = SCORED.replacen(" 0.41", " 0.41 7", 1);
        let err = parse_object_labels(&bad, path, 42).unwrap_err().to_string();
        assert!(
            err.contains("000042.txt:2") && err.contains("15 or 16") && err.contains("found 17"),
            "{err}"
        );
        let bad = GT.replacen("Pedestrian", "Spaceship", 1);
        let err = parse_object_labels(&bad, path, 42).unwrap_err().to_string();
        assert!(
            err.contains("000042.txt:1") && err.contains("column 1") && err.contains("type"),
            "{err}"
        );
    }

    fn scratch_dir(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("limot_object_labels_{name}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn directory_reads_frames_in_order_with_gaps_empty() {
        let dir = scratch_dir("gap");
        std::fs::write(dir.join("000000.txt"), GT).unwrap();
        // Frame 1 missing: a gap. Frame 2 written empty by the detector.
        std::fs::write(dir.join("000002.txt"), "").unwrap();
        std::fs::write(dir.join("000003.txt"), SCORED).unwrap();
        std::fs::write(dir.join("notes.md"), "ignored").unwrap();
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let frames = read_object_label_dir(&dir).unwrap();
        assert_eq!(frames.len(), 4);
        assert_eq!(frames[0].len(), 1);
        assert!(frames[1].is_empty());
        assert!(frames[2].is_empty());
        assert_eq!(frames[3].len(), 2);
        assert!(frames[3].iter().all(|d| d.frame == 3));
        assert_eq!(frames[0][0].frame, 0);

        // A non-numeric file name is an error naming the file.
        std::fs::write(dir.join("frame_x.txt"), SCORED).unwrap();
        let err = read_object_label_dir(&dir).unwrap_err().to_string();
        assert!(err.contains("frame_x.txt"), "{err}");
        std::fs::remove_file(dir.join("frame_x.txt")).unwrap();

        // Two files for one frame.
        std::fs::write(dir.join("3.txt"), SCORED).unwrap();
        let err = read_object_label_dir(&dir).unwrap_err().to_string();
        assert!(err.contains("frame 3"), "{err}");
        std::fs::remove_file(dir.join("3.txt")).unwrap();

        // A bad line inside one frame file names that file and line.
        std::fs::write(dir.join("000002.txt"), "Car 0 0 0 1 2 3\n").unwrap();
        let err = read_object_label_dir(&dir).unwrap_err().to_string();
        assert!(
            err.contains("000002.txt:1") && err.contains("15 or 16"),
            "{err}"
        );

        let _ = std::fs::remove_dir_all(&dir);
        let empty = scratch_dir("empty");
        assert!(read_object_label_dir(&empty).unwrap().is_empty());
        let _ = std::fs::remove_dir_all(&empty);
        assert!(read_object_label_dir(&empty).is_err());
    }

    mod fuzz {
        use super::*;
        use proptest::prelude::*;

        fn token() -> impl Strategy<Value = String> {
            prop_oneof![
                Just("NaN".to_string()),
                Just("inf".to_string()),
                Just("-1e400".to_string()),
                Just("Car".to_string()),
                Just("DontCare".to_string()),
                Just("".to_string()),
                "[a-zA-Z_]{1,8}",
                (-1.0e3..1.0e3f64).prop_map(|v| v.to_string()),
                "[0-9.eE+-]{1,6}",
            ]
        }

        proptest! {
            #![proptest_config(ProptestConfig::with_cases(512))]

            /// Garbage, NaN and truncated lines never panic; a line that is
            /// not a valid 15/16-column line with finite numbers is an error
            /// that names the file and its line.
            #[test]
            fn garbage_lines_give_located_errors(
                good_lines in 0usize..3,
                tokens in proptest::collection::vec(token(), 0..20),
                truncate_at in 0usize..200,
            ) {
                let path = Path::new("fuzz/000009.txt");
                let mut text = String::new();
                for _ in 0..good_lines {
                    text.push_str(SCORED.lines().next().unwrap());
                    text.push('\n');
                }
                let garbage = tokens.join(" ");
                let scored_line = SCORED.lines().nth(1).unwrap();
                let cut = scored_line.len().min(truncate_at);
                // Either a garbage line or a cut-off copy of a good line.
                let bad_line = if truncate_at % 2 == 0 { garbage } else {
                    scored_line[..cut].to_string()
                };
                if bad_line.trim().is_empty() {
                    return Ok(());
                }
                text.push_str(&bad_line);
                text.push('\n');
                let line_no = good_lines + 1;
                match parse_object_labels(&text, path, 9) {
                    Ok(dets) => {
                        // Only acceptable if the line really was well formed.
                        let n = bad_line.split_whitespace().count();
                        prop_assert!(n == 15 || n == 16, "accepted `{}`", bad_line);
                        prop_assert!(!bad_line.contains("NaN") && !bad_line.contains("inf"));
                        prop_assert!(dets.len() >= good_lines);
                    }
                    Err(err) => {
                        let msg = err.to_string();
                        let expect = format!("fuzz/000009.txt:{line_no}");
                        prop_assert!(msg.contains(&expect), "{}", msg);
                    }
                }
            }
        }
    }
}
