//! KITTI tracking labels (`training/label_02/00NN.txt`) and the same line
//! format with a trailing score (tracking results, label-format detections):
//!
//! `frame track_id type truncated occluded alpha x1 y1 x2 y2 h w l x y z rot_y [score]`
//!
//! Boxes are in the rectified camera-0 frame: (x, y, z) is the bottom centre
//! of the box, (h, w, l) its height, width, length (m), rot_y the rotation
//! about the camera y axis (down), 0 = heading along camera +x.
//! `DontCare` regions (track id -1, no 3D box) are kept and flagged.

use super::{LineCtx, Result, content_lines, read_text};
use limot_estimator::input::ObjectClass;
use nalgebra::Vector3;
use std::path::Path;

/// Type names of KITTI labels (`Person` appears in tracking labels).
pub const KNOWN_TYPES: [&str; 10] = [
    "Car",
    "Van",
    "Truck",
    "Pedestrian",
    "Person_sitting",
    "Person",
    "Cyclist",
    "Tram",
    "Misc",
    "DontCare",
];

const FIELD_NAMES: [&str; 18] = [
    "frame",
    "track_id",
    "type",
    "truncated",
    "occluded",
    "alpha",
    "x1",
    "y1",
    "x2",
    "y2",
    "h",
    "w",
    "l",
    "x",
    "y",
    "z",
    "rot_y",
    "score",
];

/// A 3D box in the rectified camera-0 frame, as KITTI stores it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraBox {
    /// Height, width, length (m).
    pub dims_hwl: Vector3<f64>,
    /// Bottom-face centre, rectified camera-0 frame (m).
    pub bottom_center_rect: Vector3<f64>,
    /// Rotation about the camera y axis (rad).
    pub rotation_y_rad: f64,
}

/// One line of a tracking label / result file.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackingLabel {
    /// Frame index.
    pub frame: u32,
    /// -1 for `DontCare`.
    pub track_id: i64,
    /// KITTI type name, one of [`KNOWN_TYPES`].
    pub type_name: String,
    /// Tracking labels: 0, 1, 2 (truncation level); results: usually -1 or 0.
    pub truncated: f64,
    /// 0 visible, 1 partly, 2 largely occluded, 3 unknown; results: -1.
    pub occluded: i64,
    /// Observation angle (rad).
    pub alpha_rad: f64,
    /// 2D box in the left colour image: left, top, right, bottom (pixels).
    pub bbox_2d: [f64; 4],
    /// The 3D box in the rectified camera frame.
    pub cam_box: CameraBox,
    /// Present in results and detection files, absent in ground truth.
    pub score: Option<f64>,
}

impl TrackingLabel {
    /// `DontCare` regions have no 3D box and must not be matched.
    pub fn is_dont_care(&self) -> bool {
        self.type_name == "DontCare"
    }

    /// Our class of the label (`Van` → Car); `None` for DontCare, Tram, Misc.
    pub fn class(&self) -> Option<ObjectClass> {
        ObjectClass::parse(&self.type_name)
    }

    pub(crate) fn parse_line(line: &str, ctx: LineCtx<'_>) -> Result<TrackingLabel> {
        let tokens: Vec<&str> = line.split_whitespace().collect();
        if tokens.len() != 17 && tokens.len() != 18 {
            return Err(ctx.column_count("17 or 18", tokens.len()));
        }
        let num = |i: usize| ctx.f64(tokens[i], i + 1, FIELD_NAMES[i]);
        let frame = ctx.u32(tokens[0], 1, FIELD_NAMES[0])?;
        let track_id = ctx.i64(tokens[1], 2, FIELD_NAMES[1])?;
        if track_id < -1 {
            return Err(ctx.field_error(2, "track_id", format!("{track_id} < -1")));
        }
        let type_name = tokens[2];
        if !KNOWN_TYPES.contains(&type_name) {
            return Err(ctx.field_error(3, "type", format!("unknown type `{type_name}`")));
        }
        let truncated = num(3)?;
        let occluded = ctx.i64(tokens[4], 5, FIELD_NAMES[4])?;
        let alpha_rad = num(5)?;
        let bbox_2d = [num(6)?, num(7)?, num(8)?, num(9)?];
        let dims_hwl = Vector3::new(num(10)?, num(11)?, num(12)?);
        let bottom_center_rect = Vector3::new(num(13)?, num(14)?, num(15)?);
        let rotation_y_rad = num(16)?;
        let score = if tokens.len() == 18 {
            Some(num(17)?)
        } else {
            None
        };
        Ok(TrackingLabel {
            frame,
            track_id,
            type_name: type_name.to_string(),
            truncated,
            occluded,
            alpha_rad,
            bbox_2d,
            cam_box: CameraBox {
                dims_hwl,
                bottom_center_rect,
                rotation_y_rad,
            },
            score,
        })
    }

    /// Formats the label as one line (no newline), with shortest round-trip
    /// numbers so that parsing gives back the same label exactly.
    pub fn to_line(&self) -> String {
        let b = &self.cam_box;
        let mut line = format!(
            "{} {} {} {} {} {} {} {} {} {} {} {} {} {} {} {} {}",
            self.frame,
            self.track_id,
            self.type_name,
            self.truncated,
            self.occluded,
            self.alpha_rad,
            self.bbox_2d[0],
            self.bbox_2d[1],
            self.bbox_2d[2],
            self.bbox_2d[3],
            b.dims_hwl.x,
            b.dims_hwl.y,
            b.dims_hwl.z,
            b.bottom_center_rect.x,
            b.bottom_center_rect.y,
            b.bottom_center_rect.z,
            b.rotation_y_rad,
        );
        if let Some(score) = self.score {
            line.push_str(&format!(" {score}"));
        }
        line
    }
}

/// Parses a tracking label file's text.
///
/// # Errors
/// A line with the wrong column count or a malformed field (file, line and column).
pub fn parse_labels(text: &str, path: &Path) -> Result<Vec<TrackingLabel>> {
    content_lines(text)
        .map(|(line_no, line)| TrackingLabel::parse_line(line, LineCtx::new(path, line_no)))
        .collect()
}

/// Reads a tracking label file.
///
/// # Errors
/// An unreadable file, or a malformed line (see [`parse_labels`]).
pub fn read_labels(path: &Path) -> Result<Vec<TrackingLabel>> {
    parse_labels(&read_text(path)?, path)
}

/// Formats labels as a file (one line each, in the given order).
pub fn write_labels(labels: &[TrackingLabel]) -> String {
    labels.iter().map(|l| l.to_line() + "\n").collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "\
0 -1 DontCare -1 -1 -10.000000 356.400000 195.810000 374.100000 216.650000 -1000.000000 -1000.000000 -1000.000000 -10.000000 -1.000000 -1.000000 -1.000000
0 0 Van 0 0 -1.793451 296.744956 161.752147 455.226042 292.372804 2.000000 1.823255 4.433886 -4.552284 1.858523 13.410495 -2.115488
153 14 Car 0 2 -1.72 500.0 170.0 600.0 220.0 1.5 1.6 3.9 1.0 1.7 30.0 -1.69 0.87
";

    #[test]
    fn parses_dont_care_classes_and_scores() {
        let labels = parse_labels(TEXT, Path::new("l.txt")).unwrap();
        assert_eq!(labels.len(), 3);
        assert!(labels[0].is_dont_care());
        assert_eq!(labels[0].track_id, -1);
        assert_eq!(labels[0].class(), None);
        assert_eq!(labels[1].class(), Some(ObjectClass::Car));
        assert_eq!(
            labels[1].cam_box.dims_hwl,
            Vector3::new(2.0, 1.823255, 4.433886)
        );
        assert_eq!(labels[1].cam_box.bottom_center_rect.z, 13.410495);
        assert_eq!(labels[1].score, None);
        assert_eq!(labels[2].frame, 153);
        assert_eq!(labels[2].score, Some(0.87));
    }

    #[test]
    fn write_round_trips_exactly() {
        let path = Path::new("l.txt");
        let labels = parse_labels(TEXT, path).unwrap();
        let text = write_labels(&labels);
        assert_eq!(parse_labels(&text, path).unwrap(), labels);
        assert!(
            text.lines()
                .next()
                .unwrap()
                .starts_with("0 -1 DontCare -1 -1 -10 ")
        );
    }

    #[test]
    fn errors_name_file_line_and_field() {
        let path = Path::new("label_02/0003.txt");
        let bad = TEXT.replacen("13.410495", "NaN", 1);
        let err = parse_labels(&bad, path).unwrap_err().to_string();
        assert!(
            err.contains("label_02/0003.txt:2") && err.contains("`z`"),
            "{err}"
        );
        let bad = TEXT.replacen(" -2.115488", "", 1);
        let err = parse_labels(&bad, path).unwrap_err().to_string();
        assert!(
            err.contains("0003.txt:2") && err.contains("17 or 18"),
            "{err}"
        );
        let bad = TEXT.replacen("Van", "Spaceship", 1);
        let err = parse_labels(&bad, path).unwrap_err().to_string();
        assert!(err.contains("0003.txt:2") && err.contains("type"), "{err}");
        let bad = TEXT.replacen("153 14", "x 14", 1);
        let err = parse_labels(&bad, path).unwrap_err().to_string();
        assert!(err.contains("0003.txt:3") && err.contains("frame"), "{err}");
    }
}
