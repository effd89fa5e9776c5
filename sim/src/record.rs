//! The limot dataset format: what `limot simulate` writes and `limot run`
//! reads. One directory per dataset, plain text where people look and a small
//! binary format for points:
//!
//! ```text
//! meta.toml          format version, scenario name, seed, frame count, sensor facts, T_lidar_imu
//! scenario.toml      the resolved scenario (regenerates the dataset bit for bit)
//! imu.csv            t_s,ax,ay,az,gx,gy,gz                 (IMU frame, specific force)
//! scans/NNNNNN.bin   one sweep: header + points (x,y,z,intensity,time_offset,label,ring)
//! detections.csv     frame,time_offset_s,class,x,y,z,l,w,h,yaw,score,truth_id   (LiDAR frame)
//! gt/ego.csv         t_s,x,y,z,qx,qy,qz,qw,vx,vy,vz        (t_world_lidar at the IMU rate)
//! gt/imu_bias.csv    t_s,bax,bay,baz,bgx,bgy,bgz
//! gt/boxes.csv       frame,t_s,id,class,x,y,z,qx,qy,qz,qw,l,w,h,vx,vy,vz,parked,labelled,annotated   (world frame, at scan start)
//! ```
//!
//! `truth_id` (-1 for a false positive) and per-point `label` are ground truth:
//! the estimator-facing reader hands them out separately from the sensor data.
//! Numbers are written in Rust's shortest round-trip form, so a dataset is
//! byte-identical whenever the simulation is.
//!
//! The reader rejects, with file, line (0 for binary files) and field:
//! non-finite numbers anywhere; `meta.toml` with a non-positive duration,
//! rate or sweep, zero rings, a non-unit `t_lidar_imu` quaternion or a
//! `frame_count` beyond the scans present; a scan whose ring count or sweep
//! duration disagrees with `meta.toml`, that does not start at
//! `index · sweep_duration_s`, or with a point time offset outside the sweep;
//! time stamps that do not increase in `imu.csv`, `gt/ego.csv` and
//! `gt/imu_bias.csv`; non-positive box sizes, scores outside [0, 1] and
//! detection time offsets outside the sweep; `parked`, `labelled` or
//! `annotated` other than 0 or 1.
//!
//! `gt/boxes.csv` has a row for every object that exists at the frame;
//! `labelled` is 0 for one that is in the world but not in the tracking
//! ground truth (a KITTI twin's parked car outside the frames KITTI labelled
//! it): tracking is scored against the labelled rows, the filter against
//! every row. `annotated` is 1 for an object whose labels come from a
//! recording's annotators (a twin's): they judged what was visible, so a
//! labelled annotated box is truth even where the twin's own scene hides it
//! from the simulated LiDAR; a generated object's labelled box is truth
//! where the scoring's visibility tests pass
//! ([`Labelling`](crate::scene::Labelling)).

use crate::sensors::DetectionWithTruth;
use limot_estimator::geometry::OrientedBox;
use limot_estimator::input::{
    Detection, Extrinsics, Frame, ImuSample, InputError, LidarScan, ObjectClass,
};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

mod csv;
mod file;
mod scan;
mod writer;

use csv::Csv;
pub use file::{DIRECT_MIN_BYTES, FileWriter, WriteMode};
pub use scan::{decode_labels, decode_scan, encode_scan, encode_scan_into, scan_path};
pub use writer::DatasetWriter;

/// Version of the dataset format written to `meta.toml` and every scan header.
pub const FORMAT_VERSION: u32 = 3;

/// A problem with a dataset file, naming where it is.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error("{path}: {source}")]
    /// A file could not be read or written.
    Io {
        /// The file.
        path: PathBuf,
        #[source]
        /// The I/O error.
        source: std::io::Error,
    },
    #[error("{path}:{line}: field `{field}`: {message}")]
    /// A file's contents are invalid.
    Format {
        /// The file.
        path: PathBuf,
        /// 1-based line for text files; 0 for binary files.
        line: usize,
        /// The field (CSV column or TOML key) at fault.
        field: String,
        /// What is wrong with it.
        message: String,
    },
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> RecordError + '_ {
    move |source| RecordError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn format_err(path: &Path, line: usize, field: &str, message: impl Into<String>) -> RecordError {
    RecordError::Format {
        path: path.to_path_buf(),
        line,
        field: field.to_string(),
        message: message.into(),
    }
}

/// Dataset-wide facts, `meta.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Meta {
    /// [`FORMAT_VERSION`] of the writer.
    pub format_version: u32,
    /// Scenario name.
    pub name: String,
    /// Scenario family, `highway` or `urban`.
    pub family: String,
    /// Scenario seed.
    pub seed: u64,
    /// Scenario duration, s.
    pub duration_s: f64,
    /// Number of frames (scans) in the dataset.
    pub frame_count: usize,
    /// IMU sample rate, Hz.
    pub imu_rate_hz: f64,
    /// Duration of one sweep, s; frame `k` starts at `k · sweep_duration_s`.
    pub sweep_duration_s: f64,
    /// Rings (lasers) of the LiDAR.
    pub num_rings: u16,
    /// T_lidar_imu as [x, y, z, qx, qy, qz, qw].
    pub t_lidar_imu: [f64; 7],
}

impl Meta {
    /// `t_lidar_imu` as a pose: maps IMU-frame points into the LiDAR frame.
    pub fn t_lidar_imu(&self) -> Isometry3<f64> {
        pose_from_array(&self.t_lidar_imu)
    }

    /// Rejects values no recording can have (TOML happily parses `nan`,
    /// zero rates and non-unit quaternions); `text` locates the key.
    fn validate(&self, path: &Path, text: &str) -> Result<(), RecordError> {
        let bad = |key: &str, message: String| {
            Err(format_err(path, line_of_key(text, key), key, message))
        };
        for (key, v) in [
            ("duration_s", self.duration_s),
            ("imu_rate_hz", self.imu_rate_hz),
            ("sweep_duration_s", self.sweep_duration_s),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(key, format!("{v} is not finite and positive"));
            }
        }
        if self.num_rings == 0 {
            return bad("num_rings", "a LiDAR has at least one ring".into());
        }
        let a = &self.t_lidar_imu;
        if !a.iter().all(|v| v.is_finite()) {
            return bad("t_lidar_imu", format!("{a:?} is not finite"));
        }
        let qn = (a[3] * a[3] + a[4] * a[4] + a[5] * a[5] + a[6] * a[6]).sqrt();
        if (qn - 1.0).abs() > 1e-3 {
            return bad("t_lidar_imu", format!("quaternion norm {qn} is not 1"));
        }
        Ok(())
    }
}

/// 1-based line of `key = ...` in a flat TOML text; 0 when absent.
fn line_of_key(text: &str, key: &str) -> usize {
    text.lines()
        .position(|l| {
            l.trim_start()
                .strip_prefix(key)
                .is_some_and(|rest| rest.trim_start().starts_with('='))
        })
        .map_or(0, |i| i + 1)
}

/// Ground-truth ego state at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EgoTruth {
    /// Time, s.
    pub t_s: f64,
    /// LiDAR pose in the world.
    pub t_world_lidar: Isometry3<f64>,
    /// LiDAR velocity, world frame, m/s.
    pub velocity_world_mps: Vector3<f64>,
}

/// Ground-truth IMU biases at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasTruth {
    /// Time, s.
    pub t_s: f64,
    /// Accelerometer bias, IMU frame, m/s².
    pub accel_bias: Vector3<f64>,
    /// Gyroscope bias, IMU frame, rad/s.
    pub gyro_bias: Vector3<f64>,
}

/// One ground-truth object box, world frame, at the scan start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxTruth {
    /// Frame index.
    pub frame: usize,
    /// Scan start time of the frame, s.
    pub t_s: f64,
    /// Instance id of the agent (>= 1).
    pub id: u32,
    /// Object class.
    pub class: ObjectClass,
    /// Box pose in the world (centre, x along the heading).
    pub t_world_box: Isometry3<f64>,
    /// Box length, width, height, m.
    pub size_lwh_m: Vector3<f64>,
    /// Box-centre velocity, world frame, m/s.
    pub velocity_world_mps: Vector3<f64>,
    /// True for a vehicle that never moves in the scenario.
    pub parked: bool,
    /// True when the box is part of the tracking ground truth (see the
    /// module docs).
    pub labelled: bool,
    /// True when the label comes from a recording's annotation, which
    /// already judged visibility: scoring keeps such a labelled box whether
    /// or not the simulated LiDAR hits it (see the module docs).
    pub annotated: bool,
}

/// One recorded frame: the sweep with per-point labels and the detections.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedFrame {
    /// The sweep, LiDAR frame (points at their own firing time).
    pub scan: LidarScan,
    /// Ground-truth instance id per point (0 = static scene).
    pub labels: Vec<u32>,
    /// Detections of the sweep with their truth ids.
    pub detections: Vec<DetectionWithTruth>,
}

/// LiDAR returns per ground-truth instance id in a sweep's labels.
pub fn points_per_instance(labels: &[u32]) -> BTreeMap<u32, usize> {
    let mut counts = BTreeMap::new();
    // by runs: a sweep's labels come in long runs of one instance
    for run in labels.chunk_by(|a, b| a == b) {
        *counts.entry(run[0]).or_insert(0) += run.len();
    }
    counts
}

/// The ground-truth instance ids that a sweep's labels contain.
pub fn instances_hit(labels: &[u32]) -> BTreeSet<u32> {
    // by runs, as above
    labels.chunk_by(|a, b| a == b).map(|run| run[0]).collect()
}

/// A pose as `[x, y, z, qx, qy, qz, qw]`, the dataset's pose layout.
pub fn pose_to_array(pose: &Isometry3<f64>) -> [f64; 7] {
    let t = pose.translation.vector;
    let q = pose.rotation.quaternion();
    [t.x, t.y, t.z, q.i, q.j, q.k, q.w]
}

/// The pose of a `[x, y, z, qx, qy, qz, qw]` array (the quaternion is normalised).
pub fn pose_from_array(a: &[f64; 7]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(a[0], a[1], a[2]),
        UnitQuaternion::from_quaternion(Quaternion::new(a[6], a[3], a[4], a[5])),
    )
}

/// A dataset opened for reading. Sensor streams are loaded eagerly except the
/// scans, which are read one at a time.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// The dataset directory.
    pub dir: PathBuf,
    /// `meta.toml`.
    pub meta: Meta,
    /// `imu.csv`, in time order.
    pub imu: Vec<ImuSample>,
    /// Detections per frame.
    pub detections: Vec<Vec<DetectionWithTruth>>,
}

impl Dataset {
    /// Opens the dataset in `dir`: reads and checks `meta.toml`, `imu.csv` and
    /// `detections.csv` (scans are read by [`Dataset::frame`]).
    ///
    /// # Errors
    /// [`RecordError::Io`] for a missing or unreadable file;
    /// [`RecordError::Format`], with file, line and field, for invalid contents.
    pub fn open(dir: &Path) -> Result<Dataset, RecordError> {
        let meta_path = dir.join("meta.toml");
        let meta_text = fs::read_to_string(&meta_path).map_err(io_err(&meta_path))?;
        let meta: Meta = toml::from_str(&meta_text).map_err(|e| {
            let line = e
                .span()
                .map_or(0, |s| meta_text[..s.start].matches('\n').count() + 1);
            format_err(&meta_path, line, "meta", e.message().to_string())
        })?;
        if meta.format_version != FORMAT_VERSION {
            return Err(format_err(
                &meta_path,
                line_of_key(&meta_text, "format_version"),
                "format_version",
                format!(
                    "{} but this build reads {FORMAT_VERSION}",
                    meta.format_version
                ),
            ));
        }
        meta.validate(&meta_path, &meta_text)?;
        // a frame_count beyond the scans present is a bad meta.toml, not a
        // missing-file surprise halfway through a run
        if let Some(missing) = (0..meta.frame_count)
            .map(|i| scan_path(dir, i))
            .find(|p| !p.is_file())
        {
            return Err(format_err(
                &meta_path,
                line_of_key(&meta_text, "frame_count"),
                "frame_count",
                format!(
                    "{} frames but {} does not exist",
                    meta.frame_count,
                    missing.display()
                ),
            ));
        }
        let imu = read_imu(&dir.join("imu.csv"))?;
        let detections = read_detections(&dir.join("detections.csv"), &meta)?;
        Ok(Dataset {
            dir: dir.to_path_buf(),
            meta,
            imu,
            detections,
        })
    }

    /// Number of frames, from `meta.toml`.
    pub fn frame_count(&self) -> usize {
        self.meta.frame_count
    }

    /// Reads frame `index` (scan, labels, detections).
    ///
    /// # Errors
    /// [`RecordError`] for a missing or invalid scan file, or one that is not
    /// the sweep `meta.toml` describes.
    pub fn frame(&self, index: usize) -> Result<RecordedFrame, RecordError> {
        let path = scan_path(&self.dir, index);
        let bytes = fs::read(&path).map_err(io_err(&path))?;
        let (scan, labels) = decode_scan(&bytes, &path)?;
        self.check_scan_header(index, &scan, &path)?;
        Ok(RecordedFrame {
            scan,
            labels,
            detections: self.detections.get(index).cloned().unwrap_or_default(),
        })
    }

    /// The ground-truth instance id of every point of frame `index` (same
    /// order as [`Dataset::frame`]'s), without decoding the points.
    ///
    /// # Errors
    /// As [`Dataset::frame`], for the file and its header.
    pub fn frame_labels(&self, index: usize) -> Result<Vec<u32>, RecordError> {
        let path = scan_path(&self.dir, index);
        let bytes = fs::read(&path).map_err(io_err(&path))?;
        let (header, labels) = decode_labels(&bytes, &path)?;
        self.check_scan_header(index, &header, &path)?;
        Ok(labels)
    }

    /// Frame `index` as the estimator sees it: the sweep and the detections,
    /// without any ground truth (labels and truth ids stay here).
    ///
    /// # Errors
    /// As [`Dataset::frame`].
    pub fn input_frame(&self, index: usize) -> Result<Frame, RecordError> {
        let recorded = self.frame(index)?;
        Ok(Frame {
            scan: recorded.scan,
            detections: recorded.detections.iter().map(|d| d.detection).collect(),
        })
    }

    /// The sensor extrinsics the estimator needs (`T_lidar_imu`).
    pub fn extrinsics(&self) -> Extrinsics {
        Extrinsics {
            t_lidar_imu: self.meta.t_lidar_imu(),
        }
    }

    /// A scan must be the sweep `meta.toml` describes: same ring count and
    /// sweep duration, starting at `index · sweep_duration_s` (scans are
    /// consecutive sweeps; evaluation derives frame times from that).
    fn check_scan_header(
        &self,
        index: usize,
        scan: &LidarScan,
        path: &Path,
    ) -> Result<(), RecordError> {
        let meta = &self.meta;
        if scan.num_rings != meta.num_rings {
            return Err(format_err(
                path,
                0,
                "num_rings",
                format!("{} but meta.toml says {}", scan.num_rings, meta.num_rings),
            ));
        }
        if (scan.sweep_duration_s - meta.sweep_duration_s).abs() > 1e-9 * meta.sweep_duration_s {
            return Err(format_err(
                path,
                0,
                "sweep_duration_s",
                format!(
                    "{} but meta.toml says {}",
                    scan.sweep_duration_s, meta.sweep_duration_s
                ),
            ));
        }
        let expected_t_s = index as f64 * meta.sweep_duration_s;
        if (scan.t_s - expected_t_s).abs() > 1e-6 {
            return Err(format_err(
                path,
                0,
                "t_s",
                format!(
                    "{} but frame {index} starts at {expected_t_s} \
                     (frame index × meta.toml sweep_duration_s)",
                    scan.t_s
                ),
            ));
        }
        Ok(())
    }

    /// Ground-truth ego states, `gt/ego.csv`.
    ///
    /// # Errors
    /// [`RecordError`] for a missing file or invalid contents.
    pub fn ego_truth(&self) -> Result<Vec<EgoTruth>, RecordError> {
        let columns = [
            "t_s", "x", "y", "z", "qx", "qy", "qz", "qw", "vx", "vy", "vz",
        ];
        let mut csv = Csv::open(self.dir.join("gt/ego.csv"), &columns.join(","))?;
        let mut out: Vec<EgoTruth> = Vec::new();
        for r in csv.rows(&columns) {
            let r = r?;
            let t_s = r.increasing_time(0, out.last().map(|e| e.t_s))?;
            out.push(EgoTruth {
                t_s,
                t_world_lidar: r.pose(1)?,
                velocity_world_mps: r.vec3(8)?,
            });
        }
        Ok(out)
    }

    /// Ground-truth IMU biases, `gt/imu_bias.csv`.
    ///
    /// # Errors
    /// [`RecordError`] for a missing file or invalid contents.
    pub fn bias_truth(&self) -> Result<Vec<BiasTruth>, RecordError> {
        let columns = ["t_s", "bax", "bay", "baz", "bgx", "bgy", "bgz"];
        let mut csv = Csv::open(self.dir.join("gt/imu_bias.csv"), &columns.join(","))?;
        let mut out: Vec<BiasTruth> = Vec::new();
        for r in csv.rows(&columns) {
            let r = r?;
            let t_s = r.increasing_time(0, out.last().map(|b| b.t_s))?;
            out.push(BiasTruth {
                t_s,
                accel_bias: r.vec3(1)?,
                gyro_bias: r.vec3(4)?,
            });
        }
        Ok(out)
    }

    /// Ground-truth boxes per frame, `gt/boxes.csv`.
    ///
    /// # Errors
    /// [`RecordError`] for a missing file or invalid contents.
    pub fn box_truth(&self) -> Result<Vec<Vec<BoxTruth>>, RecordError> {
        let columns = [
            "frame",
            "t_s",
            "id",
            "class",
            "x",
            "y",
            "z",
            "qx",
            "qy",
            "qz",
            "qw",
            "l",
            "w",
            "h",
            "vx",
            "vy",
            "vz",
            "parked",
            "labelled",
            "annotated",
        ];
        let mut csv = Csv::open(self.dir.join("gt/boxes.csv"), &columns.join(","))?;
        let mut out = vec![Vec::new(); self.meta.frame_count];
        for r in csv.rows(&columns) {
            let r = r?;
            let frame: usize = r.int(0)?;
            if frame >= out.len() {
                return Err(r.error(
                    0,
                    format!("frame {frame} but the dataset has {}", out.len()),
                ));
            }
            let flag = |i: usize| match r.field(i) {
                "0" => Ok(false),
                "1" => Ok(true),
                other => Err(r.error(i, format!("`{other}` is neither 0 nor 1"))),
            };
            let (parked, labelled, annotated) = (flag(17)?, flag(18)?, flag(19)?);
            out[frame].push(BoxTruth {
                frame,
                t_s: r.f64(1)?,
                id: r.int(2)?,
                class: r.class(3)?,
                t_world_box: r.pose(4)?,
                size_lwh_m: r.size(11)?,
                velocity_world_mps: r.vec3(14)?,
                parked,
                labelled,
                annotated,
            });
        }
        Ok(out)
    }
}

fn read_imu(path: &Path) -> Result<Vec<ImuSample>, RecordError> {
    let columns = ["t_s", "ax", "ay", "az", "gx", "gy", "gz"];
    let mut csv = Csv::open(path.to_path_buf(), &columns.join(","))?;
    let mut out: Vec<ImuSample> = Vec::new();
    for r in csv.rows(&columns) {
        let r = r?;
        let t_s = r.increasing_time(0, out.last().map(|s| s.t_s))?;
        out.push(ImuSample {
            t_s,
            accel_mps2: r.vec3(1)?,
            gyro_radps: r.vec3(4)?,
        });
    }
    Ok(out)
}

fn read_detections(path: &Path, meta: &Meta) -> Result<Vec<Vec<DetectionWithTruth>>, RecordError> {
    let frame_count = meta.frame_count;
    let columns = [
        "frame",
        "time_offset_s",
        "class",
        "x",
        "y",
        "z",
        "l",
        "w",
        "h",
        "yaw",
        "score",
        "truth_id",
    ];
    let mut csv = Csv::open(path.to_path_buf(), &columns.join(","))?;
    let mut out = vec![Vec::new(); frame_count];
    for r in csv.rows(&columns) {
        let r = r?;
        let frame: usize = r.int(0)?;
        if frame >= frame_count {
            return Err(r.error(
                0,
                format!("frame {frame} but the dataset has {frame_count}"),
            ));
        }
        let detection = Detection {
            time_offset_s: r.f64(1)?,
            class: r.class(2)?,
            box_lidar: OrientedBox {
                center: r.vec3(3)?,
                size_lwh: r.vec3(6)?,
                yaw_rad: r.f64(9)?,
            },
            score: r.f64(10)?,
        };
        // a detection is seen during its sweep
        let offset = detection.time_offset_s;
        if !(0.0..=meta.sweep_duration_s).contains(&offset) {
            return Err(r.error(
                1,
                format!(
                    "{offset} s is outside the {} s sweep",
                    meta.sweep_duration_s
                ),
            ));
        }
        let truth: i64 = r.int(11)?;
        let truth_id = match truth {
            -1 => None,
            id if id >= 0 && id <= u32::MAX as i64 => Some(id as u32),
            _ => return Err(r.error(11, format!("{truth} is neither -1 nor an instance id"))),
        };
        let index = out[frame].len();
        detection.validate(0.0, index).map_err(|e| {
            // name the column of the offending field, not just the row
            let column = match &e {
                InputError::BadDetection { field, .. } => match *field {
                    "size_lwh" => {
                        6 + (0..3)
                            .find(|&k| detection.box_lidar.size_lwh[k] <= 0.0)
                            .unwrap_or(0)
                    }
                    "yaw_rad" => 9,
                    "score" => 10,
                    "time_offset_s" => 1,
                    _ => 3,
                },
                _ => 3,
            };
            r.error(column, e.to_string())
        })?;
        out[frame].push(DetectionWithTruth {
            detection,
            truth_id,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use limot_estimator::input::LidarPoint;
    use limot_test_support::ScratchDir;
    use scan::SCAN_HEADER_BYTES;

    fn sample_scan() -> (LidarScan, Vec<u32>) {
        let points = (0..5)
            .map(|i| LidarPoint {
                x: i as f32,
                y: -(i as f32) * 0.5,
                z: 0.25,
                intensity: 0.1 * i as f32,
                ring: i as u16,
                time_offset_s: 0.01 * i as f32,
            })
            .collect();
        let scan = LidarScan {
            t_s: 1.5,
            sweep_duration_s: 0.1,
            num_rings: 64,
            points,
        };
        (scan, vec![0, 0, 3, 3, 0])
    }

    #[test]
    fn scan_round_trips() {
        let (scan, labels) = sample_scan();
        let bytes = encode_scan(&scan, &labels);
        let (back, back_labels) = decode_scan(&bytes, Path::new("x.bin")).unwrap();
        assert_eq!(back, scan);
        assert_eq!(back_labels, labels);
        let (header, labels_alone) = decode_labels(&bytes, Path::new("x.bin")).unwrap();
        assert_eq!(labels_alone, labels);
        assert_eq!((header.t_s, header.num_rings), (scan.t_s, scan.num_rings));
        assert!(header.points.is_empty());
        assert_eq!(instances_hit(&labels), BTreeSet::from([0, 3]));
    }

    #[test]
    fn truncated_and_corrupt_scans_name_the_problem() {
        let (scan, labels) = sample_scan();
        let bytes = encode_scan(&scan, &labels);
        let err = decode_scan(&bytes[..bytes.len() - 3], Path::new("s.bin")).unwrap_err();
        assert!(
            err.to_string().contains("s.bin") && err.to_string().contains("point_count"),
            "{err}"
        );
        let mut nan = bytes.clone();
        nan[SCAN_HEADER_BYTES + 4..SCAN_HEADER_BYTES + 8].copy_from_slice(&f32::NAN.to_le_bytes());
        let err = decode_scan(&nan, Path::new("s.bin")).unwrap_err();
        assert!(err.to_string().contains("`y`"), "{err}");
        for cut in 0..SCAN_HEADER_BYTES {
            assert!(decode_scan(&bytes[..cut], Path::new("s.bin")).is_err());
            assert!(decode_labels(&bytes[..cut], Path::new("s.bin")).is_err());
        }
        let err = decode_labels(&bytes[..bytes.len() - 3], Path::new("s.bin")).unwrap_err();
        assert!(err.to_string().contains("point_count"), "{err}");
        let mut ring = bytes.clone();
        ring[SCAN_HEADER_BYTES + 24..SCAN_HEADER_BYTES + 26].copy_from_slice(&64u16.to_le_bytes());
        let err = decode_scan(&ring, Path::new("s.bin")).unwrap_err();
        assert!(err.to_string().contains("`ring`"), "{err}");
    }

    /// A 2-frame dataset written by [`DatasetWriter`] into a fresh scratch
    /// dir (removed when dropped).
    fn tiny_dataset(name: &str) -> ScratchDir {
        let dir = ScratchDir::new(&format!("record-{name}"));
        let mut writer = DatasetWriter::begin(&dir, "").unwrap();
        let size = Vector3::new(4.0, 1.8, 1.5);
        for frame in 0..2 {
            let (mut scan, labels) = sample_scan();
            scan.t_s = frame as f64 * 0.1;
            let detection = Detection {
                box_lidar: OrientedBox {
                    center: Vector3::new(10.0, 0.0, 0.0),
                    size_lwh: size,
                    yaw_rad: 0.0,
                },
                class: ObjectClass::Car,
                score: 0.9,
                time_offset_s: 0.02,
            };
            let truth = BoxTruth {
                frame,
                t_s: scan.t_s,
                id: 3,
                class: ObjectClass::Car,
                t_world_box: Isometry3::identity(),
                size_lwh_m: size,
                velocity_world_mps: Vector3::zeros(),
                parked: false,
                labelled: true,
                annotated: false,
            };
            let detections = vec![DetectionWithTruth {
                detection,
                truth_id: Some(3),
            }];
            let recorded = RecordedFrame {
                scan,
                labels,
                detections,
            };
            writer.write_frame(&recorded, &[truth]).unwrap();
        }
        let imu: Vec<ImuSample> = (0..20)
            .map(|k| ImuSample {
                t_s: k as f64 * 0.01,
                accel_mps2: Vector3::new(0.0, 0.0, 9.8),
                gyro_radps: Vector3::zeros(),
            })
            .collect();
        let biases: Vec<BiasTruth> = imu
            .iter()
            .map(|s| BiasTruth {
                t_s: s.t_s,
                accel_bias: Vector3::zeros(),
                gyro_bias: Vector3::zeros(),
            })
            .collect();
        let ego: Vec<EgoTruth> = imu
            .iter()
            .map(|s| EgoTruth {
                t_s: s.t_s,
                t_world_lidar: Isometry3::identity(),
                velocity_world_mps: Vector3::zeros(),
            })
            .collect();
        let meta = Meta {
            format_version: FORMAT_VERSION,
            name: "tiny".into(),
            family: "urban".into(),
            seed: 1,
            duration_s: 0.2,
            frame_count: 0,
            imu_rate_hz: 100.0,
            sweep_duration_s: 0.1,
            num_rings: 64,
            t_lidar_imu: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        };
        writer.finish(meta, &imu, &biases, &ego).unwrap();
        dir
    }

    /// Rewrites line `line` (1-based) of `file`: `column` set to `value`.
    fn set_field(dir: &Path, file: &str, line: usize, column: usize, value: &str) {
        let path = dir.join(file);
        let text = fs::read_to_string(&path).unwrap();
        let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
        let mut fields: Vec<&str> = lines[line - 1].split(',').collect();
        fields[column] = value;
        lines[line - 1] = fields.join(",");
        fs::write(&path, lines.join("\n") + "\n").unwrap();
    }

    /// Replaces the only occurrence of `from` in `file`.
    fn replace_in(dir: &Path, file: &str, from: &str, to: &str) {
        let path = dir.join(file);
        let text = fs::read_to_string(&path).unwrap();
        assert_eq!(text.matches(from).count(), 1, "`{from}` in {file}");
        fs::write(&path, text.replace(from, to)).unwrap();
    }

    fn read_everything(dir: &Path) -> Result<(), RecordError> {
        let dataset = Dataset::open(dir)?;
        for i in 0..dataset.frame_count() {
            dataset.frame(i)?;
        }
        dataset.ego_truth()?;
        dataset.bias_truth()?;
        dataset.box_truth()?;
        Ok(())
    }

    fn error_of(dir: &Path) -> String {
        read_everything(dir).unwrap_err().to_string()
    }

    #[test]
    fn tiny_dataset_reads_back() {
        let dir = tiny_dataset("clean");
        let dataset = Dataset::open(&dir).unwrap();
        assert_eq!(dataset.frame_count(), 2);
        assert_eq!(dataset.frame(1).unwrap().scan.t_s, 0.1);
        assert_eq!(
            dataset.frame_labels(1).unwrap(),
            dataset.frame(1).unwrap().labels
        );
        assert_eq!(dataset.box_truth().unwrap()[1][0].size_lwh_m.x, 4.0);
        read_everything(&dir).unwrap();
    }

    #[test]
    fn streamed_tables_are_renamed_when_finished_and_removed_when_not() {
        let dir = tiny_dataset("streamed");
        for name in ["detections.csv", "gt/boxes.csv"] {
            assert!(dir.join(name).is_file(), "{name}");
            assert!(!dir.join(format!("{name}.partial")).exists(), "{name}");
        }
        let dir = ScratchDir::new("record-unfinished");
        let writer = DatasetWriter::begin(&dir, "").unwrap();
        assert!(dir.join("gt/boxes.csv.partial").is_file());
        drop(writer);
        for name in ["detections.csv", "gt/boxes.csv"] {
            assert!(!dir.join(name).exists(), "{name}");
            assert!(!dir.join(format!("{name}.partial")).exists(), "{name}");
        }
    }

    #[test]
    fn meta_values_are_checked_with_their_line() {
        let dir = tiny_dataset("meta-nan");
        replace_in(
            &dir,
            "meta.toml",
            "imu_rate_hz = 100.0",
            "imu_rate_hz = nan",
        );
        let err = error_of(&dir);
        assert!(err.contains("meta.toml:7: field `imu_rate_hz`"), "{err}");

        let dir = tiny_dataset("meta-quat");
        replace_in(&dir, "meta.toml", "0.0, 1.0]", "0.0, 5.0]");
        let err = error_of(&dir);
        assert!(err.contains("meta.toml:10: field `t_lidar_imu`"), "{err}");

        let dir = tiny_dataset("meta-rings");
        replace_in(&dir, "meta.toml", "num_rings = 64", "num_rings = 0");
        assert!(error_of(&dir).contains("field `num_rings`"));
    }

    #[test]
    fn frame_count_beyond_the_scans_names_meta_toml() {
        let dir = tiny_dataset("meta-count");
        replace_in(&dir, "meta.toml", "frame_count = 2", "frame_count = 3");
        let err = error_of(&dir);
        assert!(
            err.contains("meta.toml:6: field `frame_count`") && err.contains("000002.bin"),
            "{err}"
        );
    }

    #[test]
    fn scans_must_match_meta() {
        let dir = tiny_dataset("scan-rings");
        replace_in(&dir, "meta.toml", "num_rings = 64", "num_rings = 32");
        let err = error_of(&dir);
        assert!(
            err.contains("000000.bin:0: field `num_rings`") && err.contains("meta.toml"),
            "{err}"
        );

        let dir = tiny_dataset("scan-time");
        let (mut scan, labels) = sample_scan();
        scan.t_s = 0.5;
        fs::write(scan_path(&dir, 1), encode_scan(&scan, &labels)).unwrap();
        let err = error_of(&dir);
        assert!(err.contains("000001.bin:0: field `t_s`"), "{err}");

        let dir = tiny_dataset("scan-sweep");
        let (mut scan, labels) = sample_scan();
        scan.t_s = 0.0;
        scan.sweep_duration_s = 0.2;
        fs::write(scan_path(&dir, 0), encode_scan(&scan, &labels)).unwrap();
        let err = error_of(&dir);
        assert!(err.contains("field `sweep_duration_s`"), "{err}");
    }

    #[test]
    fn point_times_outside_the_sweep_are_rejected() {
        for bad in [-0.01_f32, 0.2, f32::MAX] {
            let (mut scan, labels) = sample_scan();
            scan.points[2].time_offset_s = bad;
            let err = decode_scan(&encode_scan(&scan, &labels), Path::new("s.bin")).unwrap_err();
            assert!(
                err.to_string().contains("s.bin:0: field `time_offset_s`"),
                "{err}"
            );
        }
        // the last column of a sweep ends right at the sweep duration
        let (mut scan, labels) = sample_scan();
        scan.points[4].time_offset_s = 0.1;
        assert!(decode_scan(&encode_scan(&scan, &labels), Path::new("s.bin")).is_ok());
    }

    #[test]
    fn truth_time_going_backwards_is_rejected() {
        for file in ["gt/ego.csv", "gt/imu_bias.csv", "imu.csv"] {
            let dir = tiny_dataset("time-backwards");
            // data rows 1 and 2 (file lines 2 and 3) swapped
            set_field(&dir, file, 3, 0, "0");
            set_field(&dir, file, 2, 0, "0.01");
            let err = error_of(&dir);
            assert!(err.contains(&format!("{file}:3: field `t_s`")), "{err}");
        }
    }

    #[test]
    fn bad_boxes_are_rejected_by_field() {
        for (line, column, value, field) in [
            (2, 12, "-1", "w"),
            (3, 17, "2", "parked"),
            (2, 18, "yes", "labelled"),
            (3, 19, "-1", "annotated"),
        ] {
            let dir = tiny_dataset(&format!("box-{field}"));
            set_field(&dir, "gt/boxes.csv", line, column, value);
            let err = error_of(&dir);
            let expected = format!("gt/boxes.csv:{line}: field `{field}`");
            assert!(err.contains(&expected), "{err}");
        }
    }

    #[test]
    fn bad_detections_name_their_column() {
        for (column, name, value) in [
            (6, "l", "-1"),
            (10, "score", "1.5"),
            (8, "h", "0"),
            (1, "time_offset_s", "-0.01"),
            (1, "time_offset_s", "0.3"),
        ] {
            let dir = tiny_dataset("detection");
            set_field(&dir, "detections.csv", 3, column, value);
            let err = error_of(&dir);
            assert!(
                err.contains(&format!("detections.csv:3: field `{name}`")),
                "{err}"
            );
        }
    }
}
