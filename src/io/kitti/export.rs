//! KITTI-style copy of a simulated dataset, so tools written for KITTI
//! tracking (AB3DMOT, the devkit, TrackEval, evo) read our scenarios.
//!
//! Layout (one sequence, `0000`, as in `training/`):
//! ```text
//! velodyne/0000/NNNNNN.bin   raw sweeps (x, y, z, intensity as f32), not de-skewed, laser by laser like KITTI
//! oxts/0000.txt              30-field OXTS lines of the IMU at each sweep start (noise-free: an INS)
//! calib/0000.txt             P0..P3, R_rect, Tr_velo_cam (a KITTI-like ideal camera), Tr_imu_velo
//! label_02/0000.txt          labelled ground-truth boxes at the sweep start, camera-visible ones only (as KITTI; `is_label_candidate`)
//! detections/0000.txt        the simulated detections, AB3DMOT CSV (camera frame, score as stored)
//! poses/0000.txt             ground-truth t_world_lidar at each sweep start, KITTI pose format
//! times.txt                  sweep start times, s
//! velodyne_elevation_correction_deg.txt   `0`: our LiDAR needs none of KITTI's scan correction
//! ```
//! The world frame is taken as local ENU; latitude/longitude come from the
//! devkit's Mercator projection around a point in Karlsruhe, chosen so the
//! devkit's `oxts_to_poses` gives back our IMU poses relative to the first.

use crate::io::kitti::KittiError;
use crate::io::kitti::calib::Calib;
use crate::io::kitti::detections::{CameraDetection, ScoreMap, write_ab3dmot_csv};
use crate::io::kitti::labels::{TrackingLabel, write_labels};
use crate::io::kitti::oxts::{
    EARTH_RADIUS_M, OxtsRecord, lat_lon_to_mercator, lat_to_scale, write_oxts,
};
use crate::io::kitti::poses::write_kitti_poses;
use crate::io::kitti::raw::ELEVATION_CORRECTION_FILE;
use crate::io::kitti::results::{ImageSize, TrackBox, image_box, track_to_label};
use crate::io::kitti::velodyne::{encode_bin_into, in_kitti_order};
use limot_estimator::geometry::OrientedBox;
use limot_estimator::input::LidarPoint;
use limot_sim::record::{
    BoxTruth, Dataset, FileWriter, RecordError, RecordedFrame, WriteMode, points_per_instance,
    pose_from_array, pose_to_array,
};
use limot_sim::scenario::ScenarioSpec;
use limot_sim::scene::Scene;
use limot_sim::sensors::ImuSimulator;
use nalgebra::{Isometry3, Matrix3, Matrix3x4, Rotation3, Translation3, UnitQuaternion, Vector3};
use std::fs;
use std::path::{Path, PathBuf};

/// Latitude/longitude/altitude of the world origin (Karlsruhe, as KITTI).
const ORIGIN_LAT_DEG: f64 = 49.011;
const ORIGIN_LON_DEG: f64 = 8.423;
const ORIGIN_ALT_M: f64 = 112.0;
/// Ground-truth boxes farther than this (horizontal, from the LiDAR) are not
/// labelled (KITTI labels ~80 m).
pub const LABEL_RANGE_M: f64 = 80.0;

/// Whether the copy labels a ground-truth box of a frame, short of the image
/// test (a label needs a 2D box in the left colour image): the box is
/// labelled, within [`LABEL_RANGE_M`], and hit by the sweep (`hit`) unless its
/// label is a recording's annotation (`BoxTruth::annotated`: the annotators
/// judged visibility on the real scans; the twin's scene may hide the box).
pub fn is_label_candidate(b: &BoxTruth, t_lidar_box: &Isometry3<f64>, hit: bool) -> bool {
    b.labelled
        && (hit || b.annotated)
        && t_lidar_box.translation.vector.xy().norm() <= LABEL_RANGE_M
}

/// Why the KITTI-style copy of a dataset could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The dataset could not be read.
    #[error(transparent)]
    Record(#[from] RecordError),
    /// A KITTI file could not be written.
    #[error(transparent)]
    Kitti(#[from] KittiError),
    /// A file or directory could not be written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
}

fn create_dir(path: &Path) -> Result<(), ExportError> {
    fs::create_dir_all(path).map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// A KITTI-like calibration: the left colour camera 0.27 m ahead of and 0.08 m
/// below the LiDAR looking forward (as on KITTI's car), KITTI's intrinsics, no rectification,
/// and our LiDAR-IMU extrinsics.
pub fn synthetic_calib(t_lidar_imu: &Isometry3<f64>) -> Calib {
    let (f, cx, cy) = (721.5377, 609.5593, 172.854);
    let p = |tx_px: f64| Matrix3x4::new(f, 0.0, cx, tx_px, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0);
    // camera axes (x right, y down, z forward) expressed in LiDAR axes
    let r_cam_lidar = Matrix3::new(0.0, -1.0, 0.0, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0);
    let t_cam_velo = Isometry3::from_parts(
        Translation3::from(r_cam_lidar * -Vector3::new(0.27, 0.0, -0.08)),
        // Shepperd's method is exact for this axis permutation
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r_cam_lidar)),
    );
    Calib {
        p0: p(0.0),
        p1: p(-0.54 * f),
        p2: p(0.06 * f),
        p3: p(-0.48 * f),
        r_rect: Matrix3::identity(),
        t_cam_velo,
        t_velo_imu: *t_lidar_imu,
    }
}

/// The OXTS record of an IMU pose and its (noise-free) motion.
fn oxts_record(
    t_world_imu: &Isometry3<f64>,
    velocity_world_mps: &Vector3<f64>,
    specific_force_imu: &Vector3<f64>,
    angular_rate_imu: &Vector3<f64>,
    mercator_origin: (f64, f64),
    scale: f64,
) -> OxtsRecord {
    let p = t_world_imu.translation.vector;
    let (mx, my) = (mercator_origin.0 + p.x, mercator_origin.1 + p.y);
    let lon_deg = mx * 180.0 / (std::f64::consts::PI * EARTH_RADIUS_M * scale);
    let lat_deg =
        360.0 / std::f64::consts::PI * (my / (scale * EARTH_RADIUS_M)).exp().atan() - 90.0;
    let (roll, pitch, yaw) = t_world_imu.rotation.euler_angles();
    let r_world_imu = t_world_imu.rotation.to_rotation_matrix();
    let v_imu = r_world_imu.inverse() * velocity_world_mps;
    // "f, l, u": the vehicle frame levelled by roll and pitch (yaw only)
    let r_level_imu = Rotation3::from_euler_angles(roll, pitch, 0.0);
    let f_level = r_level_imu * specific_force_imu;
    let w_level = r_level_imu * angular_rate_imu;
    OxtsRecord {
        lat_deg,
        lon_deg,
        alt_m: ORIGIN_ALT_M + p.z,
        roll_rad: roll,
        pitch_rad: pitch,
        yaw_rad: yaw,
        vn_mps: velocity_world_mps.y,
        ve_mps: velocity_world_mps.x,
        vf_mps: v_imu.x,
        vl_mps: v_imu.y,
        vu_mps: v_imu.z,
        ax_mps2: specific_force_imu.x,
        ay_mps2: specific_force_imu.y,
        az_mps2: specific_force_imu.z,
        af_mps2: f_level.x,
        al_mps2: f_level.y,
        au_mps2: f_level.z,
        wx_radps: angular_rate_imu.x,
        wy_radps: angular_rate_imu.y,
        wz_radps: angular_rate_imu.z,
        wf_radps: w_level.x,
        wl_radps: w_level.y,
        wu_radps: w_level.z,
        pos_accuracy_m: 0.01,
        vel_accuracy_mps: 0.01,
        navstat: 4,
        numsats: 10,
        posmode: 5,
        velmode: 5,
        orimode: 6,
    }
}

/// OXTS records at the given times, from the scene's exact ego motion.
fn oxts_records(scene: &Scene, spec: &ScenarioSpec, times_s: &[f64]) -> Vec<OxtsRecord> {
    // The devkit scales Mercator by cos(first latitude): put the first IMU
    // position at the origin latitude so its scale is ours exactly.
    let scale = lat_to_scale(ORIGIN_LAT_DEG);
    let origin = lat_lon_to_mercator(ORIGIN_LAT_DEG, ORIGIN_LON_DEG, scale);
    let imu = ImuSimulator::new(spec.imu.clone(), 0).expect("validated scenario");
    let first = times_s.first().map_or(Vector3::zeros(), |&t| {
        ImuSimulator::t_world_imu(&scene.ego, t).translation.vector
    });
    let mercator_origin = (origin.0 - first.x, origin.1 - first.y);
    times_s
        .iter()
        .map(|&t| {
            let sample = imu.true_sample(&scene.ego, t);
            oxts_record(
                &ImuSimulator::t_world_imu(&scene.ego, t),
                &ImuSimulator::velocity_world_imu(&scene.ego, t),
                &sample.accel_mps2,
                &sample.gyro_radps,
                mercator_origin,
                scale,
            )
        })
        .collect()
}

/// Writes the KITTI-style copy of a dataset frame by frame: `begin`, then
/// every frame in order ([`KittiCopyWriter::write_frame`]), then `finish`.
/// Frames come from a dataset on disk ([`export_dataset`]) or straight from
/// the simulation (`limot simulate`); for the same frames the files are the
/// same byte for byte.
pub struct KittiCopyWriter {
    out: PathBuf,
    velodyne_dir: PathBuf,
    calib: Calib,
    files: FileWriter,
    frames_written: usize,
    times_s: Vec<f64>,
    poses: Vec<Isometry3<f64>>,
    labels: Vec<TrackingLabel>,
    detections: Vec<CameraDetection>,
    /// The current scan in KITTI's point order.
    ordered: Vec<LidarPoint>,
}

impl KittiCopyWriter {
    /// Creates the copy's directories under `out`; `t_lidar_imu` is the
    /// dataset's extrinsic (as `meta.toml` stores it), files are written in `mode`.
    ///
    /// # Errors
    /// A directory that cannot be created.
    pub fn begin(
        out: &Path,
        t_lidar_imu: &Isometry3<f64>,
        mode: WriteMode,
    ) -> Result<KittiCopyWriter, ExportError> {
        let velodyne_dir = out.join("velodyne").join("0000");
        for sub in ["oxts", "calib", "label_02", "detections", "poses"] {
            create_dir(&out.join(sub))?;
        }
        create_dir(&velodyne_dir)?;
        Ok(KittiCopyWriter {
            out: out.to_path_buf(),
            velodyne_dir,
            calib: synthetic_calib(t_lidar_imu),
            files: FileWriter::new(mode),
            frames_written: 0,
            times_s: Vec::new(),
            poses: Vec::new(),
            labels: Vec::new(),
            detections: Vec::new(),
            ordered: Vec::new(),
        })
    }

    /// Writes the next frame's scan and keeps its labels and detections for
    /// [`KittiCopyWriter::finish`]. `boxes` are the frame's ground-truth
    /// boxes as the dataset stores them (see [`stored_box`]) and `scene` the
    /// scene it was simulated from.
    ///
    /// # Errors
    /// The scan file cannot be written.
    pub fn write_frame(
        &mut self,
        frame: &RecordedFrame,
        boxes: &[BoxTruth],
        scene: &Scene,
    ) -> Result<(), ExportError> {
        let index = self.frames_written;
        let calib = &self.calib;
        let t_s = frame.scan.t_s;
        let t_world_lidar = scene.ego.trajectory.pose_at(t_s);
        let bin = self.velodyne_dir.join(format!("{index:06}.bin"));
        // KITTI's laser-by-laser order, so that the reader takes the rings
        // from the scan lines exactly as on KITTI's own scans
        in_kitti_order(&frame.scan.points, &mut self.ordered);
        let ordered = &self.ordered;
        self.files
            .write_with(&bin, |out| encode_bin_into(ordered, out))?;
        let points_on = points_per_instance(&frame.labels);
        for b in boxes {
            let t_lidar_box = t_world_lidar.inverse() * b.t_world_box;
            let center = t_lidar_box.translation.vector;
            if !is_label_candidate(b, &t_lidar_box, points_on.contains_key(&b.id)) {
                continue;
            }
            let r = t_lidar_box.rotation.to_rotation_matrix();
            let track = TrackBox {
                frame: index as u32,
                track_id: b.id,
                class: b.class,
                lidar_box: OrientedBox {
                    center,
                    size_lwh: b.size_lwh_m,
                    yaw_rad: r[(1, 0)].atan2(r[(0, 0)]),
                },
                score: 1.0,
            };
            if let Some(mut label) = track_to_label(&track, calib, ImageSize::KITTI_DEFAULT) {
                label.score = None;
                self.labels.push(label);
            }
        }
        for d in &frame.detections {
            let mut det = CameraDetection::from_detection(
                index as u32,
                &d.detection,
                calib,
                ScoreMap::Clamp01,
            );
            if let Some(b) = image_box(&det.cam_box, calib, ImageSize::KITTI_DEFAULT) {
                det.bbox_2d = b;
            }
            self.detections.push(det);
        }
        self.times_s.push(t_s);
        self.poses.push(t_world_lidar);
        self.frames_written += 1;
        Ok(())
    }

    /// Writes the per-sequence files (calibration, OXTS, labels, detections,
    /// poses, times) and returns the copy's directory; `spec` and `scene`
    /// are the scenario the frames were simulated from and its built scene.
    ///
    /// # Errors
    /// A file that cannot be written.
    pub fn finish(mut self, spec: &ScenarioSpec, scene: &Scene) -> Result<PathBuf, ExportError> {
        let out = &self.out;
        let times: String = self.times_s.iter().map(|t| format!("{t}\n")).collect();
        let files = [
            ("calib/0000.txt", self.calib.write()),
            (
                "oxts/0000.txt",
                write_oxts(&oxts_records(scene, spec, &self.times_s)),
            ),
            ("label_02/0000.txt", write_labels(&self.labels)),
            ("detections/0000.txt", write_ab3dmot_csv(&self.detections)),
            ("poses/0000.txt", write_kitti_poses(&self.poses)),
            ("times.txt", times),
            (ELEVATION_CORRECTION_FILE, "0\n".to_string()),
        ];
        for (name, text) in files {
            self.files.write(&out.join(name), text.as_bytes())?;
        }
        Ok(self.out)
    }
}

/// A ground-truth box as the dataset stores it and [`Dataset::box_truth`]
/// reads it back (the pose's quaternion renormalised), so a copy written
/// from the simulation's own boxes is the copy written from the dataset.
pub fn stored_box(b: &BoxTruth) -> BoxTruth {
    BoxTruth {
        t_world_box: pose_from_array(&pose_to_array(&b.t_world_box)),
        ..*b
    }
}

/// Writes the KITTI-style copy of the dataset in `dataset_dir` into `out`;
/// `spec` is the scenario the dataset was simulated from and `scene` its
/// built scene (the caller has it: building it again, traffic included,
/// would be a good part of the export's time).
///
/// # Errors
/// An unreadable dataset or a file of the copy that cannot be written.
pub fn export_dataset(
    dataset_dir: &Path,
    spec: &ScenarioSpec,
    scene: &Scene,
    out: &Path,
) -> Result<PathBuf, ExportError> {
    let dataset = Dataset::open(dataset_dir)?;
    let boxes_by_frame = dataset.box_truth()?;
    let mut copy = KittiCopyWriter::begin(out, &dataset.meta.t_lidar_imu(), WriteMode::default())?;
    for index in 0..dataset.frame_count() {
        let frame = dataset.frame(index)?;
        let boxes = boxes_by_frame.get(index).map_or(&[][..], Vec::as_slice);
        copy.write_frame(&frame, boxes, scene)?;
    }
    copy.finish(spec, scene)
}
