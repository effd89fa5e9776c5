//! Unit tests of the raw-drive readers.

use super::calib::*;
use super::drive::*;
use super::time::*;
use super::tracking::*;
use crate::io::kitti::oxts::{EARTH_RADIUS_M, OxtsRecord, lat_lon_to_mercator, lat_to_scale};
use crate::io::kitti::velodyne::{KITTI_HDL64_ELEVATION_CORRECTION_DEG, RingSource, write_bin};
use crate::io::kitti::{Result, read_text, write_text};
use limot_estimator::input::LidarPoint;
use nalgebra::Vector3;
use proptest::prelude::*;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A fresh directory under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir =
            std::env::temp_dir().join(format!("limot_kitti_raw_{}_{n}_{tag}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// 2011-09-26 13:02:25.964389445 UTC.
const T0: UnixTime = UnixTime {
    secs: 1_317_042_145,
    nanos: 964_389_445,
};

fn add_nanos(t: UnixTime, nanos: i64) -> UnixTime {
    let total = t.nanos as i64 + nanos;
    UnixTime {
        secs: t.secs + total.div_euclid(1_000_000_000),
        nanos: total.rem_euclid(1_000_000_000) as u32,
    }
}

// Circular motion: radius 20 m, 10 m/s, counter-clockwise, starting due east.
const RADIUS_M: f64 = 20.0;
const SPEED_MPS: f64 = 10.0;
const YAW_RATE_RADPS: f64 = SPEED_MPS / RADIUS_M;
const LAT0_DEG: f64 = 49.0;
const LON0_DEG: f64 = 8.4;

/// Inverse of the devkit Mercator projection.
fn mercator_to_lat_lon(mx: f64, my: f64, scale: f64) -> (f64, f64) {
    let lon = mx * 180.0 / (scale * PI * EARTH_RADIUS_M);
    let lat = 360.0 / PI * (my / (scale * EARTH_RADIUS_M)).exp().atan() - 90.0;
    (lat, lon)
}

/// Position (east, north) in m and yaw on the circle `tau_s` after the start.
fn circle(tau_s: f64) -> (f64, f64, f64) {
    let a = YAW_RATE_RADPS * tau_s;
    (RADIUS_M * a.sin(), RADIUS_M * (1.0 - a.cos()), a)
}

/// The OXTS record `tau_s` into the circle; `i` varies the fields that
/// do not affect the pose so that field-by-field checks mean something.
fn circle_record(tau_s: f64, i: usize) -> OxtsRecord {
    let scale = lat_to_scale(LAT0_DEG);
    let (mx0, my0) = lat_lon_to_mercator(LAT0_DEG, LON0_DEG, scale);
    let (east, north, yaw) = circle(tau_s);
    let (lat, lon) = mercator_to_lat_lon(mx0 + east, my0 + north, scale);
    let k = i as f64;
    OxtsRecord {
        lat_deg: lat,
        lon_deg: lon,
        alt_m: 112.5,
        roll_rad: 0.0,
        pitch_rad: 0.0,
        yaw_rad: yaw,
        vn_mps: SPEED_MPS * yaw.sin(),
        ve_mps: SPEED_MPS * yaw.cos(),
        vf_mps: SPEED_MPS,
        vl_mps: 0.0,
        vu_mps: 0.0,
        ax_mps2: 0.05 * (0.37 * k).sin(),
        ay_mps2: SPEED_MPS * YAW_RATE_RADPS + 0.01 * (0.11 * k).cos(),
        az_mps2: 9.81 + 0.02 * (0.23 * k).sin(),
        af_mps2: 0.0,
        al_mps2: SPEED_MPS * YAW_RATE_RADPS,
        au_mps2: 9.81,
        wx_radps: 1e-3 * (0.5 * k).sin(),
        wy_radps: -1e-3 * (0.3 * k).cos(),
        wz_radps: YAW_RATE_RADPS,
        wf_radps: 0.0,
        wl_radps: 0.0,
        wu_radps: YAW_RATE_RADPS,
        pos_accuracy_m: 0.05,
        vel_accuracy_mps: 0.02,
        navstat: 4,
        numsats: 9,
        posmode: 5,
        velmode: 5,
        orimode: 6,
    }
}

/// What a synthetic drive was written with.
struct Written {
    records: Vec<OxtsRecord>,
    scan_starts: Vec<UnixTime>,
    scans: Vec<Vec<LidarPoint>>,
}

fn oxts_offset_ns(i: usize) -> i64 {
    // 100 Hz with ±200 µs deterministic jitter, like the real logger.
    i as i64 * 10_000_000 + ((i * 7919) % 401) as i64 * 1000 - 200_000
}

/// A scan in KITTI order (64 lasers top first, azimuth increasing) so
/// that rings come from scan lines; `k` varies range and intensity.
fn scan_points(k: usize) -> Vec<LidarPoint> {
    let mut points = Vec::new();
    for line in 0..64u16 {
        let elevation = (2.0 - 0.4 * line as f64).to_radians();
        for j in 0..12 {
            let az = (j as f64 + 0.5) / 12.0 * 2.0 * PI;
            let r = 10.0 + k as f64 + 0.1 * j as f64;
            points.push(LidarPoint {
                x: (r * elevation.cos() * az.cos()) as f32,
                y: (r * elevation.cos() * az.sin()) as f32,
                z: (r * elevation.sin()) as f32,
                intensity: 0.01 * (j + k) as f32,
                ring: 63 - line,
                time_offset_s: 0.0,
            });
        }
    }
    points
}

/// Writes `<dir>/oxts` (`n_oxts` records at 100 Hz) and
/// `<dir>/velodyne_points` (`n_scans` sweeps at 10 Hz, `.bin` or `.txt`).
fn write_drive(dir: &Path, n_oxts: usize, n_scans: usize, txt_scans: bool) -> Written {
    let oxts_data = dir.join("oxts/data");
    std::fs::create_dir_all(&oxts_data).unwrap();
    let oxts_times: Vec<UnixTime> = (0..n_oxts)
        .map(|i| add_nanos(T0, oxts_offset_ns(i)))
        .collect();
    let tau0 = oxts_times[0];
    let records: Vec<OxtsRecord> = oxts_times
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let tau_s = (t.secs - tau0.secs) as f64 + (t.nanos as f64 - tau0.nanos as f64) * 1e-9;
            circle_record(tau_s, i)
        })
        .collect();
    for (i, r) in records.iter().enumerate() {
        write_text(
            &oxts_data.join(format!("{i:010}.txt")),
            &(r.to_line() + "\n"),
        )
        .unwrap();
    }
    let stamps =
        |times: &[UnixTime]| -> String { times.iter().map(|t| format!("{t}\n")).collect() };
    write_text(&dir.join("oxts/timestamps.txt"), &stamps(&oxts_times)).unwrap();

    let velo_data = dir.join("velodyne_points/data");
    std::fs::create_dir_all(&velo_data).unwrap();
    let scan_starts: Vec<UnixTime> = (0..n_scans)
        .map(|k| add_nanos(T0, k as i64 * 100_000_000 + 3_141_592))
        .collect();
    let mut scans = Vec::new();
    for k in 0..n_scans {
        let points = scan_points(k);
        if txt_scans {
            let text: String = points
                .iter()
                .map(|p| format!("{} {} {} {}\n", p.x, p.y, p.z, p.intensity))
                .collect();
            write_text(&velo_data.join(format!("{k:010}.txt")), &text).unwrap();
        } else {
            write_bin(&velo_data.join(format!("{k:010}.bin")), &points).unwrap();
        }
        scans.push(points);
    }
    let shifted =
        |ns: i64| -> Vec<UnixTime> { scan_starts.iter().map(|t| add_nanos(*t, ns)).collect() };
    let velo = dir.join("velodyne_points");
    write_text(&velo.join("timestamps_start.txt"), &stamps(&scan_starts)).unwrap();
    write_text(&velo.join("timestamps.txt"), &stamps(&shifted(50_000_000))).unwrap();
    write_text(
        &velo.join("timestamps_end.txt"),
        &stamps(&shifted(99_000_000)),
    )
    .unwrap();
    Written {
        records,
        scan_starts,
        scans,
    }
}

fn error_text(result: Result<RawDrive>) -> String {
    match result {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn timestamps_parse_known_values() {
    assert_eq!(parse_timestamp("1970-01-01 00:00:01.5").unwrap(), 1.5);
    assert_eq!(parse_timestamp("1970-01-01 00:00:00").unwrap(), 0.0);
    let t = parse_unix_time("2011-09-26 13:02:25.964389445").unwrap();
    assert_eq!(t, T0);
    let t_s = parse_timestamp("2011-09-26 13:02:25.964389445").unwrap();
    assert!(
        (t_s - 1_317_042_145.0 - 0.964_389_445).abs() < 1e-6,
        "{t_s}"
    );
    // Leap day and year ends (checked against `date -u -d … +%s`).
    assert_eq!(
        parse_unix_time("2012-02-29 00:00:00").unwrap().secs,
        1_330_473_600
    );
    assert_eq!(
        parse_unix_time("1999-12-31 23:59:59.000000001").unwrap(),
        UnixTime {
            secs: 946_684_799,
            nanos: 1
        }
    );
    assert_eq!(
        parse_unix_time("1969-12-31 23:59:59.25").unwrap(),
        UnixTime {
            secs: -1,
            nanos: 250_000_000
        }
    );
    assert_eq!(T0.to_string(), "2011-09-26 13:02:25.964389445");
    for bad in [
        "",
        "2011-09-26",
        "2011-09-26 13:02:25.964389445 x",
        "2011-13-26 13:02:25.1",
        "2011-02-29 13:02:25.1",
        "2011-09-26 24:00:00.0",
        "2011-09-26 13:60:00.0",
        "2011-09-26 13:02:60.0",
        "2011-09-26 13:02:25.",
        "2011-09-26 13:02:25.1234567890",
        "2011-09-26 13:02:2x.1",
        "2011-9-26 13:02:25.1",
        "2011-09-26 13:02:25.-1",
        "+011-09-26 13:02:25.1",
    ] {
        assert!(parse_timestamp(bad).is_err(), "accepted `{bad}`");
    }
}

#[test]
fn malformed_timestamp_names_file_and_line() {
    let text = "2011-09-26 13:02:25.1\n2011-09-26 13:02:25.2\n2011-09-26 13:0:25.3\n";
    let err = parse_timestamps(text, Path::new("oxts/timestamps.txt"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("oxts/timestamps.txt:3") && err.contains("minute"),
        "{err}"
    );
    let back = "2011-09-26 13:02:25.2\n\n2011-09-26 13:02:25.1\n";
    let err = parse_timestamps(back, Path::new("t.txt"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("t.txt:3") && err.contains("backwards"),
        "{err}"
    );
    // Equal consecutive stamps are accepted (documented).
    let equal = "2011-09-26 13:02:25.2\n2011-09-26 13:02:25.2\n";
    assert_eq!(
        parse_timestamps(equal, Path::new("t.txt")).unwrap().len(),
        2
    );
}

#[test]
fn synthetic_100hz_drive_reads_back() {
    let tmp = TempDir::new("drive");
    let written = write_drive(&tmp.0, 200, 3, false);
    let drive = RawDrive::open(&tmp.0).unwrap();
    assert_eq!(drive.oxts.len(), 200);
    assert!(drive.gaps().is_empty(), "{:?}", drive.gaps());
    let period = drive.oxts_period_s.unwrap();
    assert!((period - 0.01).abs() < 4e-4, "{period}");

    // Times exact to 1e-6 s: truth = the known start + the integer
    // nanosecond offsets the files were written with.
    let mut worst_time_err: f64 = 0.0;
    for (i, o) in drive.oxts.iter().enumerate() {
        let truth = 1_317_042_145.0 + (964_389_445 + oxts_offset_ns(i)) as f64 * 1e-9;
        worst_time_err = worst_time_err.max((o.t_s - truth).abs());
    }
    assert!(worst_time_err < 1e-6, "{worst_time_err}");
    let times = drive.oxts_times_s();
    let rewritten = parse_timestamps(&write_timestamps(&times), Path::new("w")).unwrap();
    assert!(
        times
            .iter()
            .zip(&rewritten)
            .all(|(a, b)| (a - b).abs() < 1e-6)
    );

    // IMU samples carry the written fields and their own times.
    let imu = drive.imu_samples();
    assert_eq!(imu.len(), 200);
    for ((s, o), r) in imu.iter().zip(&drive.oxts).zip(&written.records) {
        assert_eq!(o.record, *r);
        assert_eq!(s.t_s, o.t_s);
        assert_eq!(s.accel_mps2, Vector3::new(r.ax_mps2, r.ay_mps2, r.az_mps2));
        assert_eq!(
            s.gyro_radps,
            Vector3::new(r.wx_radps, r.wy_radps, r.wz_radps)
        );
        assert!(s.validate().is_ok());
    }
    assert!(imu.windows(2).all(|w| w[1].t_s > w[0].t_s));

    // Poses follow the circle (world = first IMU frame = ENU at the start).
    let poses = drive.poses();
    let mut worst_pos_m: f64 = 0.0;
    let mut worst_yaw_rad: f64 = 0.0;
    for (pose, o) in poses.iter().zip(&drive.oxts) {
        let (east, north, yaw) = circle(o.t_s - drive.oxts[0].t_s);
        let p = pose.translation.vector;
        worst_pos_m = worst_pos_m.max((p - Vector3::new(east, north, 0.0)).norm());
        let (_, _, pose_yaw) = pose.rotation.euler_angles();
        worst_yaw_rad =
            worst_yaw_rad.max(limot_estimator::geometry::wrap_angle_rad(pose_yaw - yaw).abs());
    }
    // 2 s at 0.5 rad/s: a full 1 rad of arc, 20 m of travel.
    let last = poses.last().unwrap().translation.vector;
    assert!(last.norm() > 15.0, "{last}");
    // τ is rebuilt from f64 times (~2.4e-7 s resolution) → ~2.4e-6 m at 10 m/s.
    println!(
        "synthetic 100 Hz drive: time err {worst_time_err:.2e} s, pose err {worst_pos_m:.2e} m / {worst_yaw_rad:.2e} rad over {:.1} m",
        last.norm()
    );
    assert!(worst_pos_m < 1e-5, "{worst_pos_m}");
    assert!(worst_yaw_rad < 1e-6, "{worst_yaw_rad}");

    // Scans load with t_s = sweep start and the written points, raised by
    // KITTI's elevation correction (a raw drive is KITTI's recording).
    let raised = drive.velodyne_scan(0).unwrap();
    let angle = KITTI_HDL64_ELEVATION_CORRECTION_DEG.to_radians();
    assert_eq!(drive.elevation_correction_rad, angle);
    for (a, b) in raised.scan.points.iter().zip(&written.scans[0]) {
        let p = Vector3::new(b.x as f64, b.y as f64, b.z as f64);
        let q = crate::io::kitti::velodyne::raise_elevation(&p, angle);
        assert_eq!((a.x, a.y, a.z), (q.x as f32, q.y as f32, q.z as f32));
    }
    let mut drive = drive;
    drive.elevation_correction_rad = 0.0;
    assert_eq!(drive.num_scans(), 3);
    for k in 0..3 {
        let frame = &drive.velodyne[k];
        assert_eq!(frame.start_source, SweepStart::Measured);
        assert_eq!(frame.format, ScanFormat::Bin);
        let start = written.scan_starts[k].as_secs_f64();
        assert!((frame.t_start_s - start).abs() < 1e-6);
        assert!((frame.t_trigger_s.unwrap() - (start + 0.05)).abs() < 1e-6);
        assert!((frame.t_end_s.unwrap() - (start + 0.099)).abs() < 1e-6);
        let scan = drive.velodyne_scan(k).unwrap();
        assert_eq!(scan.ring_source, RingSource::ScanLines);
        assert!((scan.scan.t_s - start).abs() < 1e-6);
        assert_eq!(scan.scan.points.len(), written.scans[k].len());
        for (a, b) in scan.scan.points.iter().zip(&written.scans[k]) {
            assert_eq!(
                (a.x, a.y, a.z, a.intensity, a.ring),
                (b.x, b.y, b.z, b.intensity, b.ring)
            );
        }
        assert_eq!(drive.scan(k).unwrap(), scan.scan);
    }
    let err = drive.scan(3).unwrap_err().to_string();
    assert!(err.contains("has 3 scans"), "{err}");
}

#[test]
fn extract_style_text_scans_match_binary_scans() {
    let bin = TempDir::new("bin");
    let txt = TempDir::new("txt");
    write_drive(&bin.0, 12, 2, false);
    write_drive(&txt.0, 12, 2, true);
    let a = RawDrive::open(&bin.0).unwrap();
    let b = RawDrive::open(&txt.0).unwrap();
    assert_eq!(b.velodyne[0].format, ScanFormat::Txt);
    for k in 0..2 {
        assert_eq!(a.velodyne_scan(k).unwrap(), b.velodyne_scan(k).unwrap());
    }
    // Malformed text scan line → file:line and field.
    let path = b.velodyne[1].path.clone();
    let text = read_text(&path)
        .unwrap()
        .replacen('\n', "\n1 2 abc 0.5\n", 1);
    write_text(&path, &text).unwrap();
    let err = b.scan(1).unwrap_err().to_string();
    assert!(
        err.contains("0000000001.txt:2") && err.contains("`z`"),
        "{err}"
    );
    let err = parse_velodyne_txt("1 2 3\n", Path::new("s.txt"), 0.0)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("s.txt:1") && err.contains("expected 4"),
        "{err}"
    );
    let err = parse_velodyne_txt("1 2 1e39 0\n", Path::new("s.txt"), 0.0)
        .unwrap_err()
        .to_string();
    assert!(err.contains("overflows f32"), "{err}");
}

#[test]
fn backwards_time_is_an_error_naming_the_line() {
    let tmp = TempDir::new("backwards");
    write_drive(&tmp.0, 20, 1, false);
    let path = tmp.0.join("oxts/timestamps.txt");
    let mut lines: Vec<String> = read_text(&path)
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect();
    lines.swap(6, 7);
    write_text(&path, &(lines.join("\n") + "\n")).unwrap();
    let err = error_text(RawDrive::open(&tmp.0));
    assert!(
        err.contains("timestamps.txt:8") && err.contains("backwards"),
        "{err}"
    );
}

#[test]
fn gaps_are_reported_not_fatal() {
    let tmp = TempDir::new("gap");
    write_drive(&tmp.0, 100, 1, false);
    // Drop records 40..52 (12 samples, 0.13 s hole) and renumber the files.
    let data = tmp.0.join("oxts/data");
    let stamps_path = tmp.0.join("oxts/timestamps.txt");
    let stamps: Vec<String> = read_text(&stamps_path)
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect();
    let keep: Vec<usize> = (0..100).filter(|i| !(40..52).contains(i)).collect();
    let lines: Vec<String> = (0..100)
        .map(|i| read_text(&data.join(format!("{i:010}.txt"))).unwrap())
        .collect();
    std::fs::remove_dir_all(&data).unwrap();
    std::fs::create_dir_all(&data).unwrap();
    let mut new_stamps = String::new();
    for (j, i) in keep.iter().enumerate() {
        write_text(&data.join(format!("{j:010}.txt")), &lines[*i]).unwrap();
        new_stamps += &stamps[*i];
        new_stamps.push('\n');
    }
    write_text(&stamps_path, &new_stamps).unwrap();
    let drive = RawDrive::open(&tmp.0).unwrap();
    assert_eq!(drive.oxts.len(), 88);
    assert_eq!(drive.imu_samples().len(), 88);
    let gaps = drive.gaps();
    assert_eq!(gaps.len(), 1, "{gaps:?}");
    let gap = gaps[0];
    assert_eq!(gap.index, 39);
    let truth_s = (oxts_offset_ns(52) - oxts_offset_ns(39)) as f64 * 1e-9;
    assert!((gap.duration_s() - truth_s).abs() < 1e-6, "{gap}");
    assert_eq!(gap.missing_samples(), 12, "{gap}");
    assert!(gap.to_string().contains("after record 39"), "{gap}");
}

#[test]
fn count_mismatches_and_holes_are_errors() {
    let tmp = TempDir::new("count");
    write_drive(&tmp.0, 20, 3, false);
    // One timestamp too many.
    let stamps = tmp.0.join("oxts/timestamps.txt");
    let original = read_text(&stamps).unwrap();
    write_text(&stamps, &format!("{original}2011-09-26 13:02:59.0\n")).unwrap();
    let err = error_text(RawDrive::open(&tmp.0));
    assert!(
        err.contains("oxts/timestamps.txt") && err.contains("21 timestamps but 20 data files"),
        "{err}"
    );
    write_text(&stamps, &original).unwrap();
    // A hole in the numbering.
    let f = tmp.0.join("oxts/data/0000000005.txt");
    let kept = read_text(&f).unwrap();
    std::fs::remove_file(&f).unwrap();
    let err = error_text(RawDrive::open(&tmp.0));
    assert!(
        err.contains("0000000006.txt") && err.contains("expected frame 0000000005"),
        "{err}"
    );
    write_text(&f, &kept).unwrap();
    // A missing last Velodyne scan.
    std::fs::remove_file(tmp.0.join("velodyne_points/data/0000000002.bin")).unwrap();
    let err = error_text(RawDrive::open(&tmp.0));
    assert!(
        err.contains("velodyne_points/timestamps") && err.contains("3 timestamps but 2 data files"),
        "{err}"
    );
    // Mixed .bin and .txt scans.
    write_text(
        &tmp.0.join("velodyne_points/data/0000000000.txt"),
        "1 2 3 4\n",
    )
    .unwrap();
    let err = error_text(RawDrive::open(&tmp.0));
    assert!(err.contains("both .bin"), "{err}");
}

#[test]
fn malformed_oxts_and_sweep_times_are_errors() {
    let tmp = TempDir::new("malformed");
    let written = write_drive(&tmp.0, 10, 2, false);
    let f = tmp.0.join("oxts/data/0000000004.txt");
    let line =
        written.records[4]
            .to_line()
            .replacen(&written.records[4].az_mps2.to_string(), "nan", 1);
    write_text(&f, &(line + "\n")).unwrap();
    let err = error_text(RawDrive::open(&tmp.0));
    assert!(
        err.contains("0000000004.txt:1") && err.contains("`az`"),
        "{err}"
    );
    // Two records in one file.
    let two = written.records[4].to_line() + "\n" + &written.records[4].to_line() + "\n";
    write_text(&f, &two).unwrap();
    let err = error_text(RawDrive::open(&tmp.0));
    assert!(
        err.contains("0000000004.txt") && err.contains("found 2"),
        "{err}"
    );
    write_text(&f, &(written.records[4].to_line() + "\n")).unwrap();
    assert!(RawDrive::open(&tmp.0).is_ok());
    // Sweep end before its trigger.
    let end = tmp.0.join("velodyne_points/timestamps_end.txt");
    let mut lines: Vec<String> = read_text(&end)
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect();
    lines[1] = add_nanos(written.scan_starts[1], 10_000_000).to_string();
    write_text(&end, &(lines.join("\n") + "\n")).unwrap();
    let err = error_text(RawDrive::open(&tmp.0));
    assert!(
        err.contains("timestamps_end.txt:2") && err.contains("before"),
        "{err}"
    );
    // Without timestamps_start the start is derived from the trigger.
    std::fs::remove_file(&end).unwrap();
    std::fs::remove_file(tmp.0.join("velodyne_points/timestamps_start.txt")).unwrap();
    let drive = RawDrive::open(&tmp.0).unwrap();
    let frame = &drive.velodyne[1];
    assert_eq!(frame.start_source, SweepStart::FromTrigger);
    assert!((frame.t_start_s - written.scan_starts[1].as_secs_f64()).abs() < 1e-6);
    // No timestamps at all: refused, pointing to the bare-scan reader.
    std::fs::remove_file(tmp.0.join("velodyne_points/timestamps.txt")).unwrap();
    let err = error_text(RawDrive::open(&tmp.0));
    assert!(err.contains("open_bare_scans"), "{err}");
}

#[test]
fn tracking_scans_are_corrected_unless_declared_otherwise() {
    let tmp = TempDir::new("tracking_elev");
    let velo = tmp.0.join("velodyne/0000");
    std::fs::create_dir_all(&velo).unwrap();
    std::fs::create_dir_all(tmp.0.join("oxts")).unwrap();
    let points = scan_points(0);
    write_bin(&velo.join("000000.bin"), &points).unwrap();
    write_text(
        &tmp.0.join("oxts/0000.txt"),
        &format!("{}\n", circle_record(0.0, 0).to_line()),
    )
    .unwrap();
    let z_of = |drive: &RawDrive| drive.scan(0).unwrap().points[0].z;
    let stored = points[0].z;
    let p = Vector3::new(points[0].x as f64, points[0].y as f64, stored as f64);
    let raise =
        |deg: f64| crate::io::kitti::velodyne::raise_elevation(&p, f64::to_radians(deg)).z as f32;

    // KITTI's own layout (no times.txt): KITTI's correction.
    let drive = RawDrive::open_tracking_sequence(&tmp.0, 0).unwrap();
    let kitti = KITTI_HDL64_ELEVATION_CORRECTION_DEG.to_radians();
    assert_eq!(drive.elevation_correction_rad, kitti);
    assert_eq!(z_of(&drive), raise(KITTI_HDL64_ELEVATION_CORRECTION_DEG));
    assert_ne!(z_of(&drive), stored);

    // Our copies (times.txt): the points as stored.
    write_text(&tmp.0.join("times.txt"), "0.0\n").unwrap();
    let drive = RawDrive::open_tracking_sequence(&tmp.0, 0).unwrap();
    assert_eq!(drive.elevation_correction_rad, 0.0);
    assert_eq!(z_of(&drive), stored);

    // The declaration file wins either way.
    let declared = tmp.0.join(ELEVATION_CORRECTION_FILE);
    write_text(&declared, "0.1\n").unwrap();
    let drive = RawDrive::open_tracking_sequence(&tmp.0, 0).unwrap();
    assert!((drive.elevation_correction_rad - 0.1f64.to_radians()).abs() < 1e-15);
    assert_eq!(z_of(&drive), raise(0.1));
    std::fs::remove_file(tmp.0.join("times.txt")).unwrap();
    write_text(&declared, "0\n").unwrap();
    let drive = RawDrive::open_tracking_sequence(&tmp.0, 0).unwrap();
    assert_eq!(z_of(&drive), stored);

    // Garbled declarations name the file and line.
    for (text, why) in [
        ("abc\n", "not a number"),
        ("0.2 0.3\n", "one angle"),
        ("\n9\n", "plausible"),
        ("", "empty"),
    ] {
        write_text(&declared, text).unwrap();
        let err = RawDrive::open_tracking_sequence(&tmp.0, 0)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(ELEVATION_CORRECTION_FILE) && err.contains(why),
            "{err}"
        );
    }
    write_text(&declared, "\n\n0.3\n").unwrap();
    let err = declared_elevation_correction_rad(&tmp.0);
    assert!(err.is_ok());
    write_text(&declared, "9\n").unwrap();
    let err = declared_elevation_correction_rad(&tmp.0)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(&format!("{ELEVATION_CORRECTION_FILE}:1")),
        "{err}"
    );
}

#[test]
fn bare_scans_get_synthetic_10hz_times() {
    let tmp = TempDir::new("bare");
    for k in 0..3 {
        write_bin(&tmp.0.join(format!("{k:010}.bin")), &scan_points(k)).unwrap();
    }
    let drive = RawDrive::open_bare_scans(&tmp.0).unwrap();
    assert!(drive.oxts.is_empty() && drive.imu_samples().is_empty() && drive.gaps().is_empty());
    assert_eq!(drive.num_scans(), 3);
    for k in 0..3 {
        assert_eq!(drive.velodyne[k].start_source, SweepStart::Synthetic10Hz);
        let scan = drive.scan(k).unwrap();
        assert_eq!(scan.t_s, k as f64 * 0.1);
        assert_eq!(scan.points.len(), scan_points(k).len());
        // Read as stored: no elevation correction for bare scans.
        assert_eq!(scan.points[7].z, scan_points(k)[7].z);
    }
    // The 20 real scans of shared/data, when present.
    let real = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kitti_raw_scans");
    if real.is_dir() {
        let drive = RawDrive::open_bare_scans(&real).unwrap();
        assert_eq!(drive.num_scans(), 20);
        let last = drive.velodyne_scan(19).unwrap();
        assert!((last.scan.t_s - 1.9).abs() < 1e-12);
        assert_eq!(last.ring_source, RingSource::ScanLines);
        assert!(last.scan.points.len() > 100_000);
    } else {
        eprintln!(
            "NOTE: {} absent: real bare-scan case not run",
            real.display()
        );
    }
}

// Raw calibration of 2011-09-26 (the day of tracking `calib::tests::SAMPLE`).
const IMU_TO_VELO: &str = "\
calib_time: 25-May-2012 16:47:16
R: 9.999976e-01 7.553071e-04 -2.035826e-03 -7.854027e-04 9.998898e-01 -1.482298e-02 2.024406e-03 1.482454e-02 9.998881e-01
T: -8.086759e-01 3.195559e-01 -7.997231e-01
";
const VELO_TO_CAM: &str = "\
calib_time: 15-Mar-2012 11:37:16
R: 7.533745e-03 -9.999714e-01 -6.166020e-04 1.480249e-02 7.280733e-04 -9.998902e-01 9.998621e-01 7.523790e-03 1.480755e-02
T: -4.069766e-03 -7.631618e-02 -2.717806e-01
delta_f: 0.000000e+00 0.000000e+00
delta_c: 0.000000e+00 0.000000e+00
";
const CAM_TO_CAM: &str = "\
calib_time: 09-Jan-2012 13:57:47
corner_dist: 9.950000e-02
S_00: 1.392000e+03 5.120000e+02
K_00: 9.842439e+02 0.000000e+00 6.900000e+02 0.000000e+00 9.808141e+02 2.331966e+02 0.000000e+00 0.000000e+00 1.000000e+00
D_00: -3.728755e-01 2.037299e-01 2.219027e-03 1.383707e-03 -7.233722e-02
R_00: 1.000000e+00 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00
T_00: 2.573699e-16 -1.059758e-16 1.614870e-16
S_rect_00: 1.242000e+03 3.750000e+02
R_rect_00: 9.999239e-01 9.837760e-03 -7.445048e-03 -9.869795e-03 9.999421e-01 -4.278459e-03 7.402527e-03 4.351614e-03 9.999631e-01
P_rect_00: 7.215377e+02 0.000000e+00 6.095593e+02 0.000000e+00 0.000000e+00 7.215377e+02 1.728540e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00
S_rect_01: 1.242000e+03 3.750000e+02
R_rect_01: 9.996878e-01 -8.976826e-03 2.331651e-02 8.876121e-03 9.999508e-01 4.418952e-03 -2.335503e-02 -4.210612e-03 9.997184e-01
P_rect_01: 7.215377e+02 0.000000e+00 6.095593e+02 -3.875744e+02 0.000000e+00 7.215377e+02 1.728540e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00
P_rect_02: 7.215377e+02 0.000000e+00 6.095593e+02 4.485728e+01 0.000000e+00 7.215377e+02 1.728540e+02 2.163791e-01 0.000000e+00 0.000000e+00 1.000000e+00 2.745884e-03
P_rect_03: 7.215377e+02 0.000000e+00 6.095593e+02 -3.395242e+02 0.000000e+00 7.215377e+02 1.728540e+02 2.199936e+00 0.000000e+00 0.000000e+00 1.000000e+00 2.729905e-03
";

fn write_calib_dir(dir: &Path, cam_to_cam: &str) {
    write_text(&dir.join(RawCalib::IMU_TO_VELO), IMU_TO_VELO).unwrap();
    write_text(&dir.join(RawCalib::VELO_TO_CAM), VELO_TO_CAM).unwrap();
    write_text(&dir.join(RawCalib::CAM_TO_CAM), cam_to_cam).unwrap();
}

#[test]
fn raw_calib_matches_the_tracking_calibration_of_the_same_day() {
    let tmp = TempDir::new("calib");
    write_calib_dir(&tmp.0, CAM_TO_CAM);
    let raw = RawCalib::read(&tmp.0).unwrap();
    let calib = raw.to_calib();
    let tracking = crate::io::kitti::calib::tests::sample();
    assert_eq!(calib.p0, tracking.p0);
    assert_eq!(calib.p1, tracking.p1);
    assert_eq!(calib.p2, tracking.p2);
    assert_eq!(calib.p3, tracking.p3);
    assert_eq!(calib.r_rect, tracking.r_rect);
    for (a, b) in [
        (calib.t_cam_velo, tracking.t_cam_velo),
        (calib.t_velo_imu, tracking.t_velo_imu),
    ] {
        let d = a.inverse() * b;
        assert!(
            d.translation.vector.norm() < 1e-12 && d.rotation.angle() < 1e-12,
            "{d}"
        );
    }
    // The tracking code path works on it: a point ahead projects into the image.
    let px = calib
        .project_velo_to_image(&Vector3::new(15.0, 0.0, 0.0))
        .unwrap();
    assert!(
        (px.x - 609.0).abs() < 30.0 && px.y > 150.0 && px.y < 250.0,
        "{px}"
    );
}

#[test]
fn raw_calib_errors_name_file_line_and_key() {
    let tmp = TempDir::new("calib_err");
    let missing: String = CAM_TO_CAM
        .lines()
        .filter(|l| !l.starts_with("P_rect_02"))
        .map(|l| format!("{l}\n"))
        .collect();
    write_calib_dir(&tmp.0, &missing);
    let err = RawCalib::read(&tmp.0).unwrap_err().to_string();
    assert!(
        err.contains("calib_cam_to_cam.txt") && err.contains("P_rect_02"),
        "{err}"
    );

    let skew = CAM_TO_CAM.replace("R_rect_00: 9.999239e-01", "R_rect_00: 1.5");
    write_calib_dir(&tmp.0, &skew);
    let err = RawCalib::read(&tmp.0).unwrap_err().to_string();
    assert!(
        err.contains("calib_cam_to_cam.txt:9") && err.contains("orthonormal"),
        "{err}"
    );

    let short = CAM_TO_CAM.replace(" 2.745884e-03", "");
    write_calib_dir(&tmp.0, &short);
    let err = RawCalib::read(&tmp.0).unwrap_err().to_string();
    assert!(
        err.contains("calib_cam_to_cam.txt:14") && err.contains("columns"),
        "{err}"
    );

    let p = |name: &str| PathBuf::from(name);
    let (ip, vp, cp) = (p("imu.txt"), p("velo.txt"), p("cam.txt"));
    let bad_t = IMU_TO_VELO.replace("3.195559e-01", "abc");
    let err = RawCalib::parse((&bad_t, &ip), (VELO_TO_CAM, &vp), (CAM_TO_CAM, &cp))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("imu.txt:3") && err.contains("column 3") && err.contains("`T`"),
        "{err}"
    );
    let no_colon = VELO_TO_CAM.replace("delta_f:", "delta_f");
    let err = RawCalib::parse((IMU_TO_VELO, &ip), (&no_colon, &vp), (CAM_TO_CAM, &cp))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("velo.txt:4") && err.contains("key: values"),
        "{err}"
    );
    let dup = format!("{VELO_TO_CAM}T: 0 0 0\n");
    let err = RawCalib::parse((IMU_TO_VELO, &ip), (&dup, &vp), (CAM_TO_CAM, &cp))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("velo.txt:6") && err.contains("duplicate"),
        "{err}"
    );
    let no_r: String = IMU_TO_VELO
        .lines()
        .filter(|l| !l.starts_with("R:"))
        .map(|l| format!("{l}\n"))
        .collect();
    let err = RawCalib::parse((&no_r, &ip), (VELO_TO_CAM, &vp), (CAM_TO_CAM, &cp))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("imu.txt") && err.contains("missing key `R`"),
        "{err}"
    );
}

/// Days since 1970-01-01 by counting, independent of the closed form.
fn naive_days(year: i64, month: u32, day: u32) -> i64 {
    let mut days = 0i64;
    if year >= 1970 {
        for y in 1970..year {
            days += if is_leap_year(y) { 366 } else { 365 };
        }
    } else {
        for y in year..1970 {
            days -= if is_leap_year(y) { 366 } else { 365 };
        }
    }
    for m in 1..month {
        days += days_in_month(year, m) as i64;
    }
    days + day as i64 - 1
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn fuzz_timestamp_parser_never_panics(s in "\\PC{0,40}") {
        let _ = parse_timestamp(&s);
        let _ = parse_timestamps(&s, Path::new("f.txt"));
    }

    #[test]
    fn fuzz_near_valid_timestamps(s in "[0-9]{4}-[0-9]{2}-[0-9]{2} [0-9]{2}:[0-9]{2}:[0-9]{2}(\\.[0-9]{1,10})?") {
        if let Ok(t) = parse_unix_time(&s) {
            // Accepted ⇒ formatting gives the same instant back.
            prop_assert_eq!(parse_unix_time(&t.to_string()).unwrap(), t);
            prop_assert_eq!(&t.to_string()[..19], &s[..19]);
        }
    }

    #[test]
    fn fuzz_date_arithmetic_matches_counting(year in 1900i64..2100, month in 1u32..=12, day in 1u32..=31) {
        prop_assume!(day <= days_in_month(year, month));
        let days = days_from_civil(year, month, day);
        prop_assert_eq!(days, naive_days(year, month, day));
        prop_assert_eq!(civil_from_days(days), (year, month, day));
    }

    #[test]
    fn fuzz_format_parse_round_trip(
        secs in days_from_civil(0, 1, 1) * 86_400..days_from_civil(9999, 12, 31) * 86_400 + 86_400,
        nanos in 0u32..1_000_000_000,
    ) {
        let t = UnixTime { secs, nanos };
        prop_assert_eq!(parse_unix_time(&t.to_string()).unwrap(), t);
    }

    #[test]
    fn fuzz_f64_time_conversion(offset_ns in 0i64..10_000_000_000_000) {
        let t = add_nanos(T0, offset_ns);
        let back = UnixTime::from_secs_f64(t.as_secs_f64());
        let err_ns = (back.secs - t.secs) * 1_000_000_000 + back.nanos as i64 - t.nanos as i64;
        prop_assert!(err_ns.abs() <= 500, "{err_ns}");
    }

    #[test]
    fn fuzz_calib_text_never_panics(pos in 0usize..2000, c in any::<char>(), which in 0usize..3) {
        let mut texts = [IMU_TO_VELO.to_string(), VELO_TO_CAM.to_string(), CAM_TO_CAM.to_string()];
        let t = &mut texts[which];
        let mut chars: Vec<char> = t.chars().collect();
        let i = pos % chars.len();
        chars[i] = c;
        *t = chars.into_iter().collect();
        let (ip, vp, cp) = (PathBuf::from("i"), PathBuf::from("v"), PathBuf::from("c"));
        let _ = RawCalib::parse((&texts[0], &ip), (&texts[1], &vp), (&texts[2], &cp));
    }

    #[test]
    fn fuzz_text_scan_never_panics(s in "([-0-9.e ]{0,30}\n){0,5}") {
        if let Ok(scan) = parse_velodyne_txt(&s, Path::new("s.txt"), 0.0) {
            prop_assert!(scan.scan.points.iter().all(|p| p.position().iter().all(|v| v.is_finite())));
        }
    }
}
