//! [`DatasetWriter`]: writes a dataset directory frame by frame.

use super::{
    BiasTruth, BoxTruth, EgoTruth, FileWriter, Meta, RecordError, RecordedFrame, WriteMode,
    encode_scan_into, format_err, io_err, pose_to_array, scan_path,
};
use limot_estimator::input::ImuSample;
use std::fmt::Write as _;
use std::fs::{self, File};
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};

/// Writes a dataset directory incrementally: `begin`, then frames in order,
/// then `finish` with the streams known only at the end. Scans and the
/// end-of-run files are written whole by a [`FileWriter`] (one write per
/// file, nothing partial left behind on an error); the per-frame tables
/// (`detections.csv`, `gt/boxes.csv`) are streamed to `NAME.partial` as the
/// frames come and renamed by `finish` (removed if the writer is dropped
/// before), so memory does not grow with the run.
pub struct DatasetWriter {
    dir: PathBuf,
    files: FileWriter,
    detections_csv: StreamedCsv,
    boxes_csv: StreamedCsv,
    /// One frame's rows, formatted before they are streamed (reused).
    rows: String,
    frames_written: usize,
}

/// A CSV file written row by row as `NAME.partial`, renamed to `NAME` by
/// [`StreamedCsv::finish`]; dropped unfinished, the partial file is removed.
struct StreamedCsv {
    path: PathBuf,
    partial: PathBuf,
    out: Option<BufWriter<File>>,
}

impl StreamedCsv {
    /// Creates `path.partial` with the header line `header`.
    fn create(path: PathBuf, header: &str) -> Result<StreamedCsv, RecordError> {
        let mut partial = path.as_os_str().to_owned();
        partial.push(".partial");
        let partial = PathBuf::from(partial);
        let file = File::create(&partial).map_err(io_err(&partial))?;
        let mut csv = StreamedCsv {
            path,
            partial,
            out: Some(BufWriter::new(file)),
        };
        csv.append(header)?;
        Ok(csv)
    }

    /// Appends `text` (whole lines).
    fn append(&mut self, text: &str) -> Result<(), RecordError> {
        let out = self
            .out
            .as_mut()
            .expect("a streamed CSV is open until finished");
        out.write_all(text.as_bytes())
            .map_err(io_err(&self.partial))
    }

    /// Flushes the file and gives it its final name.
    fn finish(mut self) -> Result<(), RecordError> {
        let out = self.out.take().expect("a streamed CSV is finished once");
        let file = out
            .into_inner()
            .map_err(|e| io_err(&self.partial)(e.into_error()))?;
        drop(file);
        fs::rename(&self.partial, &self.path).map_err(io_err(&self.path))
    }
}

impl Drop for StreamedCsv {
    fn drop(&mut self) {
        if self.out.take().is_some() {
            // best effort: an unfinished table is not part of a dataset
            let _ = fs::remove_file(&self.partial);
        }
    }
}

impl DatasetWriter {
    /// Creates the directory (and parents) and writes `scenario.toml`, files
    /// in the default [`WriteMode`].
    ///
    /// # Errors
    /// [`RecordError::Io`] if the directory or file cannot be written.
    pub fn begin(dir: &Path, scenario_toml: &str) -> Result<DatasetWriter, RecordError> {
        Self::begin_with_mode(dir, scenario_toml, WriteMode::default())
    }

    /// [`DatasetWriter::begin`] with files written in `mode`.
    ///
    /// # Errors
    /// [`RecordError::Io`] if the directory or file cannot be written.
    pub fn begin_with_mode(
        dir: &Path,
        scenario_toml: &str,
        mode: WriteMode,
    ) -> Result<DatasetWriter, RecordError> {
        for sub in ["", "scans", "gt"] {
            let d = dir.join(sub);
            fs::create_dir_all(&d).map_err(io_err(&d))?;
        }
        let mut files = FileWriter::new(mode);
        files.write(&dir.join("scenario.toml"), scenario_toml.as_bytes())?;
        Ok(DatasetWriter {
            dir: dir.to_path_buf(),
            files,
            detections_csv: StreamedCsv::create(
                dir.join("detections.csv"),
                "frame,time_offset_s,class,x,y,z,l,w,h,yaw,score,truth_id\n",
            )?,
            boxes_csv: StreamedCsv::create(
                dir.join("gt/boxes.csv"),
                "frame,t_s,id,class,x,y,z,qx,qy,qz,qw,l,w,h,vx,vy,vz,parked,labelled,annotated\n",
            )?,
            rows: String::new(),
            frames_written: 0,
        })
    }

    /// The dataset directory being written.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Appends the next frame with its ground-truth boxes.
    ///
    /// # Errors
    /// [`RecordError::Io`] if the scan file or the frame's table rows cannot
    /// be written.
    pub fn write_frame(
        &mut self,
        frame: &RecordedFrame,
        boxes: &[BoxTruth],
    ) -> Result<(), RecordError> {
        let index = self.frames_written;
        let path = scan_path(&self.dir, index);
        self.files.write_with(&path, |out| {
            encode_scan_into(&frame.scan, &frame.labels, out);
        })?;
        self.rows.clear();
        for d in &frame.detections {
            let det = &d.detection;
            let c = det.box_lidar.center;
            let s = det.box_lidar.size_lwh;
            let truth = d.truth_id.map_or(-1, i64::from);
            let _ = writeln!(
                self.rows,
                "{index},{},{},{},{},{},{},{},{},{},{},{truth}",
                det.time_offset_s,
                det.class,
                c.x,
                c.y,
                c.z,
                s.x,
                s.y,
                s.z,
                det.box_lidar.yaw_rad,
                det.score
            );
        }
        self.detections_csv.append(&self.rows)?;
        self.rows.clear();
        for b in boxes {
            let [x, y, z, qx, qy, qz, qw] = pose_to_array(&b.t_world_box);
            let (s, v) = (b.size_lwh_m, b.velocity_world_mps);
            let _ = writeln!(
                self.rows,
                "{index},{},{},{},{x},{y},{z},{qx},{qy},{qz},{qw},{},{},{},{},{},{},{},{},{}",
                b.t_s,
                b.id,
                b.class,
                s.x,
                s.y,
                s.z,
                v.x,
                v.y,
                v.z,
                b.parked as u8,
                b.labelled as u8,
                b.annotated as u8
            );
        }
        self.boxes_csv.append(&self.rows)?;
        self.frames_written += 1;
        Ok(())
    }

    /// Writes the per-dataset streams and `meta.toml`. `meta.frame_count` is
    /// set from the frames written.
    ///
    /// # Errors
    /// [`RecordError`] if a file cannot be written or `meta` not serialised.
    pub fn finish(
        mut self,
        mut meta: Meta,
        imu: &[ImuSample],
        biases: &[BiasTruth],
        ego: &[EgoTruth],
    ) -> Result<PathBuf, RecordError> {
        meta.frame_count = self.frames_written;
        let mut imu_csv = String::from("t_s,ax,ay,az,gx,gy,gz\n");
        for s in imu {
            let (a, g) = (s.accel_mps2, s.gyro_radps);
            let _ = writeln!(
                imu_csv,
                "{},{},{},{},{},{},{}",
                s.t_s, a.x, a.y, a.z, g.x, g.y, g.z
            );
        }
        let mut bias_csv = String::from("t_s,bax,bay,baz,bgx,bgy,bgz\n");
        for b in biases {
            let (a, g) = (b.accel_bias, b.gyro_bias);
            let _ = writeln!(
                bias_csv,
                "{},{},{},{},{},{},{}",
                b.t_s, a.x, a.y, a.z, g.x, g.y, g.z
            );
        }
        let mut ego_csv = String::from("t_s,x,y,z,qx,qy,qz,qw,vx,vy,vz\n");
        for e in ego {
            let [x, y, z, qx, qy, qz, qw] = pose_to_array(&e.t_world_lidar);
            let v = e.velocity_world_mps;
            let _ = writeln!(
                ego_csv,
                "{},{x},{y},{z},{qx},{qy},{qz},{qw},{},{},{}",
                e.t_s, v.x, v.y, v.z
            );
        }
        let meta_toml = toml::to_string(&meta)
            .map_err(|e| format_err(&self.dir.join("meta.toml"), 0, "meta", e.to_string()))?;
        self.detections_csv.finish()?;
        self.boxes_csv.finish()?;
        let files = [
            ("imu.csv", imu_csv),
            ("gt/imu_bias.csv", bias_csv),
            ("gt/ego.csv", ego_csv),
            ("meta.toml", meta_toml),
        ];
        for (name, text) in files {
            self.files.write(&self.dir.join(name), text.as_bytes())?;
        }
        Ok(self.dir)
    }
}
