//! 3D detection files and the camera-box ↔ LiDAR-box conversion.
//!
//! Two input formats:
//! - AB3DMOT CSV (`detections/pointrcnn_Car_val/00NN.txt`):
//!   `frame,type,x1,y1,x2,y2,score,h,w,l,x,y,z,rot_y,alpha` with type
//!   1 = Pedestrian, 2 = Car, 3 = Cyclist, and an unbounded detector score
//!   (PointRCNN logits, about -1..16).
//! - KITTI tracking label format with a score column (see [`super::labels`]).
//!
//! Conversion to the LiDAR frame (what [`Detection`] wants):
//! - centre: the bottom centre (camera frame) moved up by h/2 (camera −y),
//!   then mapped by `(R_rect · Tr_velo_cam)⁻¹`;
//! - `size_lwh = (l, w, h)`;
//! - `yaw_lidar = wrap(-rot_y - π/2)`: camera heading (cos ry, 0, −sin ry)
//!   becomes (−sin ry, −cos ry, 0) in the nominal LiDAR axes. The ~0.4° tilt
//!   between camera and LiDAR is ignored for the heading, as every KITTI
//!   tool does, so the conversion is exactly invertible.
//! - score: mapped into [0, 1] by a [`ScoreMap`];
//! - time offset: when the spinning LiDAR swept over the box centre
//!   ([`super::velodyne::sweep_time_offset_s`]).

use super::calib::Calib;
use super::labels::{CameraBox, TrackingLabel};
use super::velodyne::sweep_time_offset_s;
use super::{LineCtx, Result, content_lines, read_text};
use limot_estimator::geometry::{OrientedBox, wrap_angle_rad};
use limot_estimator::input::{Detection, ObjectClass};
use nalgebra::Vector3;
use std::f64::consts::FRAC_PI_2;
use std::path::Path;

/// KITTI camera box → LiDAR-frame box (see the module docs; yaw in (-π, π]).
pub fn camera_box_to_lidar(cam: &CameraBox, calib: &Calib) -> OrientedBox {
    let h = cam.dims_hwl.x;
    // Camera y points down: the geometric centre is h/2 above the bottom.
    let center_rect = cam.bottom_center_rect - Vector3::new(0.0, h / 2.0, 0.0);
    OrientedBox {
        center: calib.rect_to_velo(&center_rect),
        size_lwh: Vector3::new(cam.dims_hwl.z, cam.dims_hwl.y, h),
        yaw_rad: wrap_angle_rad(-cam.rotation_y_rad - FRAC_PI_2),
    }
}

/// LiDAR-frame box → KITTI camera box (inverse of [`camera_box_to_lidar`]).
pub fn lidar_box_to_camera(lidar: &OrientedBox, calib: &Calib) -> CameraBox {
    let h = lidar.size_lwh.z;
    let center_rect = calib.velo_to_rect(&lidar.center);
    CameraBox {
        dims_hwl: Vector3::new(h, lidar.size_lwh.y, lidar.size_lwh.x),
        bottom_center_rect: center_rect + Vector3::new(0.0, h / 2.0, 0.0),
        rotation_y_rad: wrap_angle_rad(-lidar.yaw_rad - FRAC_PI_2),
    }
}

/// Observation angle of KITTI: `alpha = wrap(rot_y − atan2(x, z))`.
pub fn observation_angle_rad(cam: &CameraBox) -> f64 {
    let c = &cam.bottom_center_rect;
    wrap_angle_rad(cam.rotation_y_rad - c.x.atan2(c.z))
}

/// How a file's detector score becomes a [`Detection::score`] in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScoreMap {
    /// Logistic function, for logit-like scores (PointRCNN in AB3DMOT files).
    Sigmoid,
    /// The score already is a probability; values outside [0, 1] are clamped.
    Clamp01,
}

impl ScoreMap {
    /// Maps a raw detector score into [0, 1].
    pub fn apply(self, raw: f64) -> f64 {
        match self {
            ScoreMap::Sigmoid => 1.0 / (1.0 + (-raw).exp()),
            ScoreMap::Clamp01 => raw.clamp(0.0, 1.0),
        }
    }

    /// Inverse for writers (the logit for `Sigmoid`, identity for `Clamp01`).
    pub fn invert(self, score: f64) -> f64 {
        match self {
            ScoreMap::Sigmoid => {
                let p = score.clamp(1e-12, 1.0 - 1e-12);
                (p / (1.0 - p)).ln()
            }
            ScoreMap::Clamp01 => score,
        }
    }
}

/// One camera-frame detection, as stored in a detection file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraDetection {
    /// Frame index.
    pub frame: u32,
    /// Object class.
    pub class: ObjectClass,
    /// Left, top, right, bottom (pixels).
    pub bbox_2d: [f64; 4],
    /// Detector score as stored (not necessarily in [0, 1]).
    pub score_raw: f64,
    /// The 3D box in the rectified camera frame.
    pub cam_box: CameraBox,
    /// Observation angle (rad).
    pub alpha_rad: f64,
}

impl CameraDetection {
    /// The detection in the LiDAR frame.
    pub fn to_detection(&self, calib: &Calib, score_map: ScoreMap) -> Detection {
        let box_lidar = camera_box_to_lidar(&self.cam_box, calib);
        Detection {
            box_lidar,
            class: self.class,
            score: score_map.apply(self.score_raw),
            time_offset_s: sweep_time_offset_s(&box_lidar.center),
        }
    }

    /// The camera-frame detection of a LiDAR-frame one (2D box left at zero:
    /// use [`super::results`] to project one).
    pub fn from_detection(
        frame: u32,
        det: &Detection,
        calib: &Calib,
        score_map: ScoreMap,
    ) -> CameraDetection {
        let cam_box = lidar_box_to_camera(&det.box_lidar, calib);
        CameraDetection {
            frame,
            class: det.class,
            bbox_2d: [0.0; 4],
            score_raw: score_map.invert(det.score),
            alpha_rad: observation_angle_rad(&cam_box),
            cam_box,
        }
    }

    /// The AB3DMOT CSV line (no newline).
    pub fn to_ab3dmot_line(&self) -> String {
        let b = &self.cam_box;
        format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            self.frame,
            ab3dmot_type_id(self.class),
            self.bbox_2d[0],
            self.bbox_2d[1],
            self.bbox_2d[2],
            self.bbox_2d[3],
            self.score_raw,
            b.dims_hwl.x,
            b.dims_hwl.y,
            b.dims_hwl.z,
            b.bottom_center_rect.x,
            b.bottom_center_rect.y,
            b.bottom_center_rect.z,
            b.rotation_y_rad,
            self.alpha_rad
        )
    }
}

const CSV_FIELDS: [&str; 15] = [
    "frame", "type", "x1", "y1", "x2", "y2", "score", "h", "w", "l", "x", "y", "z", "rot_y",
    "alpha",
];

/// AB3DMOT type ids: 1 Pedestrian, 2 Car, 3 Cyclist (Truck has none: 2).
fn ab3dmot_type_id(class: ObjectClass) -> u32 {
    match class {
        ObjectClass::Pedestrian => 1,
        ObjectClass::Car | ObjectClass::Truck => 2,
        ObjectClass::Cyclist => 3,
    }
}

fn parse_csv_line(line: &str, ctx: LineCtx<'_>) -> Result<CameraDetection> {
    let tokens: Vec<&str> = line.split(',').map(str::trim).collect();
    if tokens.len() != 15 {
        return Err(ctx.column_count("15", tokens.len()));
    }
    let num = |i: usize| ctx.f64(tokens[i], i + 1, CSV_FIELDS[i]);
    let frame = ctx.u32(tokens[0], 1, "frame")?;
    let class = match ctx.i64(tokens[1], 2, "type")? {
        1 => ObjectClass::Pedestrian,
        2 => ObjectClass::Car,
        3 => ObjectClass::Cyclist,
        other => {
            return Err(ctx.field_error(2, "type", format!("{other} is not 1, 2 or 3")));
        }
    };
    let bbox_2d = [num(2)?, num(3)?, num(4)?, num(5)?];
    let score_raw = num(6)?;
    let dims_hwl = Vector3::new(num(7)?, num(8)?, num(9)?);
    for (k, d) in dims_hwl.iter().enumerate() {
        if *d <= 0.0 {
            return Err(ctx.field_error(8 + k, CSV_FIELDS[7 + k], format!("size {d} <= 0")));
        }
    }
    let bottom_center_rect = Vector3::new(num(10)?, num(11)?, num(12)?);
    let rotation_y_rad = num(13)?;
    let alpha_rad = num(14)?;
    Ok(CameraDetection {
        frame,
        class,
        bbox_2d,
        score_raw,
        cam_box: CameraBox {
            dims_hwl,
            bottom_center_rect,
            rotation_y_rad,
        },
        alpha_rad,
    })
}

/// Parses an AB3DMOT detection CSV.
///
/// # Errors
/// A line with the wrong column count or a malformed field (file, line and column).
pub fn parse_ab3dmot_csv(text: &str, path: &Path) -> Result<Vec<CameraDetection>> {
    content_lines(text)
        .map(|(line_no, line)| parse_csv_line(line, LineCtx::new(path, line_no)))
        .collect()
}

/// Reads an AB3DMOT detection CSV.
///
/// # Errors
/// An unreadable file, or a malformed line (see [`parse_ab3dmot_csv`]).
pub fn read_ab3dmot_csv(path: &Path) -> Result<Vec<CameraDetection>> {
    parse_ab3dmot_csv(&read_text(path)?, path)
}

/// Formats detections as an AB3DMOT CSV.
pub fn write_ab3dmot_csv(detections: &[CameraDetection]) -> String {
    detections
        .iter()
        .map(|d| d.to_ab3dmot_line() + "\n")
        .collect()
}

/// Camera detections from a label-format detection file: every label with
/// a class of ours (DontCare, Tram, Misc are dropped); a missing score
/// counts as 1.
pub fn detections_from_labels(labels: &[TrackingLabel]) -> Vec<CameraDetection> {
    labels
        .iter()
        .filter(|l| !l.is_dont_care())
        .filter_map(|l| {
            Some(CameraDetection {
                frame: l.frame,
                class: l.class()?,
                bbox_2d: l.bbox_2d,
                score_raw: l.score.unwrap_or(1.0),
                cam_box: l.cam_box,
                alpha_rad: l.alpha_rad,
            })
        })
        .collect()
}

/// Groups detections per frame, in the LiDAR frame. The result has
/// `max(num_frames, last frame + 1)` entries; frames without detections are
/// empty.
pub fn detections_by_frame(
    detections: &[CameraDetection],
    calib: &Calib,
    score_map: ScoreMap,
    num_frames: usize,
) -> Vec<Vec<Detection>> {
    let len = detections
        .iter()
        .map(|d| d.frame as usize + 1)
        .max()
        .unwrap_or(0)
        .max(num_frames);
    let mut frames = vec![Vec::new(); len];
    for d in detections {
        frames[d.frame as usize].push(d.to_detection(calib, score_map));
    }
    frames
}

#[cfg(test)]
mod tests {
    use super::*;

    fn calib() -> Calib {
        crate::io::kitti::calib::tests::sample()
    }

    const CSV: &str = "\
0,2,786.7492,180.1760,1241.0000,374.0000,12.2286,1.5206,1.6824,4.4501,2.9312,1.6089,6.4281,-1.5828,-2.0107
0,2,384.3615,191.2274,463.4154,244.3732,10.3184,1.5171,1.5954,3.7611,-6.0804,2.1715,23.7919,1.5839,1.8341
3,2,636.7738,179.3189,664.3902,202.5576,-0.5,1.5204,1.6288,3.7185,2.7549,1.9867,50.1244,-1.5925,-1.6474
";

    #[test]
    fn csv_parses_and_converts_into_the_lidar_frame() {
        let dets = parse_ab3dmot_csv(CSV, Path::new("d.txt")).unwrap();
        assert_eq!(dets.len(), 3);
        let calib = calib();
        let frames = detections_by_frame(&dets, &calib, ScoreMap::Sigmoid, 5);
        assert_eq!(frames.len(), 5);
        assert_eq!(frames[0].len(), 2);
        assert!(frames[1].is_empty());
        // First box: 6.4 m ahead, 2.9 m right (camera x), bottom at y=1.6 m
        // below the camera → LiDAR: x ≈ 6.4 + 0.27, y ≈ -2.9, z ≈ centre height.
        let d = frames[0][0];
        assert!(
            (d.box_lidar.center.x - 6.7).abs() < 0.2,
            "{}",
            d.box_lidar.center
        );
        assert!(
            (d.box_lidar.center.y - -2.93).abs() < 0.2,
            "{}",
            d.box_lidar.center
        );
        // Camera height 1.65 m above ground, LiDAR 1.73 m: centre ≈ -0.9 m.
        assert!(
            (d.box_lidar.center.z - -0.9).abs() < 0.3,
            "{}",
            d.box_lidar.center
        );
        assert_eq!(d.box_lidar.size_lwh, Vector3::new(4.4501, 1.6824, 1.5206));
        // rot_y ≈ -π/2 means heading along camera +z, i.e. LiDAR +x.
        assert!(d.box_lidar.yaw_rad.abs() < 0.02, "{}", d.box_lidar.yaw_rad);
        assert!(d.score > 0.99 && d.score <= 1.0);
        assert!(d.validate(0.0, 0).is_ok());
        // Boxes ahead were seen half-way through the sweep (which starts at the rear).
        assert!((d.time_offset_s - 0.05).abs() < 0.02, "{}", d.time_offset_s);
        let low = frames[3][0];
        assert!((low.score - 1.0 / (1.0 + 0.5f64.exp())).abs() < 1e-12);
    }

    #[test]
    fn camera_lidar_round_trip_is_exact() {
        let calib = calib();
        let dets = parse_ab3dmot_csv(CSV, Path::new("d.txt")).unwrap();
        for cd in &dets {
            let det = cd.to_detection(&calib, ScoreMap::Sigmoid);
            let back = CameraDetection::from_detection(cd.frame, &det, &calib, ScoreMap::Sigmoid);
            let (a, b) = (&cd.cam_box, &back.cam_box);
            assert!((a.bottom_center_rect - b.bottom_center_rect).norm() < 1e-9);
            assert!((a.dims_hwl - b.dims_hwl).norm() < 1e-12);
            assert!(wrap_angle_rad(a.rotation_y_rad - b.rotation_y_rad).abs() < 1e-12);
            assert!((cd.score_raw - back.score_raw).abs() < 1e-9);
            // The stored alpha agrees with the one recomputed from the box.
            assert!(wrap_angle_rad(cd.alpha_rad - back.alpha_rad).abs() < 2e-3);
        }
    }

    #[test]
    fn csv_round_trips_and_errors_name_line_and_field() {
        let path = Path::new("pointrcnn/0007.txt");
        let dets = parse_ab3dmot_csv(CSV, path).unwrap();
        assert_eq!(
            parse_ab3dmot_csv(&write_ab3dmot_csv(&dets), path).unwrap(),
            dets
        );
        let bad = CSV.replacen("23.7919", "nan", 1);
        let err = parse_ab3dmot_csv(&bad, path).unwrap_err().to_string();
        assert!(err.contains("0007.txt:2") && err.contains("`z`"), "{err}");
        let bad = CSV.replacen("0,2,384", "0,7,384", 1);
        let err = parse_ab3dmot_csv(&bad, path).unwrap_err().to_string();
        assert!(err.contains("0007.txt:2") && err.contains("type"), "{err}");
        let bad = CSV.replacen(",-1.6474", "", 1);
        let err = parse_ab3dmot_csv(&bad, path).unwrap_err().to_string();
        assert!(err.contains("0007.txt:3") && err.contains("15"), "{err}");
        let bad = CSV.replacen("1.5206", "-1.5", 1);
        let err = parse_ab3dmot_csv(&bad, path).unwrap_err().to_string();
        assert!(err.contains("0007.txt:1") && err.contains("`h`"), "{err}");
    }

    #[test]
    fn yaw_convention_matches_box_corners() {
        // Independent check of yaw = -ry - π/2: the box's front face centre
        // (camera: centre + l/2·(cos ry, 0, -sin ry)) maps into LiDAR at
        // centre + l/2·(cos yaw, sin yaw, ~0).
        let calib = calib();
        for ry in [-3.0, -1.55, -0.4, 0.0, 0.9, 2.5] {
            let cam = CameraBox {
                dims_hwl: Vector3::new(1.5, 1.7, 4.0),
                bottom_center_rect: Vector3::new(2.0, 1.6, 15.0),
                rotation_y_rad: ry,
            };
            let lidar = camera_box_to_lidar(&cam, &calib);
            let front_rect = cam.bottom_center_rect - Vector3::new(0.0, 0.75, 0.0)
                + 2.0 * Vector3::new(ry.cos(), 0.0, -ry.sin());
            let front_lidar = calib.rect_to_velo(&front_rect);
            let expected =
                lidar.center + 2.0 * Vector3::new(lidar.yaw_rad.cos(), lidar.yaw_rad.sin(), 0.0);
            assert!((front_lidar - expected).norm() < 0.05, "ry {ry}");
        }
    }

    #[test]
    fn labels_become_detections_without_dont_care() {
        let text = "\
0 -1 DontCare -1 -1 -10 1 2 3 4 -1000 -1000 -1000 -10 -1 -1 -1
0 3 Van 0 0 -1.79 296.7 161.7 455.2 292.3 2.0 1.82 4.43 -4.55 1.86 13.41 -2.12
1 4 Tram 0 0 -1.79 296.7 161.7 455.2 292.3 3.0 2.5 14.0 -4.55 1.86 33.41 -2.12
";
        let labels = crate::io::kitti::labels::parse_labels(text, Path::new("l.txt")).unwrap();
        let dets = detections_from_labels(&labels);
        assert_eq!(dets.len(), 1);
        assert_eq!(dets[0].class, ObjectClass::Car);
        assert_eq!(dets[0].score_raw, 1.0);
        let frames = detections_by_frame(&dets, &calib(), ScoreMap::Clamp01, 0);
        assert_eq!(frames.len(), 1);
        assert!(frames[0][0].box_lidar.center.x > 13.0);
    }
}
