//! KITTI raw drives (`2011_09_26/2011_09_26_drive_0001_sync` and the
//! unsynchronised `_extract` variant): per-sample timestamps, 100 Hz OXTS
//! (10 Hz in `_sync`), Velodyne sweeps with start/trigger/end times, and the
//! three per-day calibration files.
//!
//! Layout read here:
//! ```text
//! <date>/calib_imu_to_velo.txt   R: (9) T: (3)            -> T_velo_imu
//! <date>/calib_velo_to_cam.txt   R: (9) T: (3) delta_f/c  -> T_cam_velo
//! <date>/calib_cam_to_cam.txt    R_rect_00: P_rect_00..03: (+ unused keys)
//! <drive>/oxts/timestamps.txt    "2011-09-26 13:02:25.964389445" per line
//! <drive>/oxts/data/NNNNNNNNNN.txt          one 30-field OXTS line each
//! <drive>/velodyne_points/timestamps{,_start,_end}.txt
//! <drive>/velodyne_points/data/NNNNNNNNNN.{bin,txt}
//! ```
//! Times are seconds since the Unix epoch (UTC, leap seconds ignored as Unix
//! time does), as f64: at ~1.3e9 s its resolution is ~2.4e-7 s, finer than
//! the microsecond jitter of the recorded clocks.
//!
//! Velodyne times: `timestamps_start` = the laser facing backwards (sweep
//! start, the [`LidarScan::t_s`](limot_estimator::input::LidarScan::t_s) we use), `timestamps` = facing forwards
//! (camera trigger, mid sweep), `timestamps_end` = backwards again. When a
//! drive lacks `timestamps_start`, the start is derived as trigger − 0.05 s
//! or end − 0.1 s (see [`SweepStart`]).
//!
//! Checks: data files must be numbered 0, 1, 2, … without holes; every
//! timestamp file must have as many lines as there are data files; time must
//! not go backwards within a file (equal consecutive stamps are accepted);
//! per sweep start ≤ trigger ≤ end. Holes in the OXTS stream longer than
//! [`GAP_FACTOR`] nominal periods are not errors: they are listed by
//! [`RawDrive::gaps`] so callers can decide (e.g. stop IMU propagation).

mod calib;
mod drive;
mod time;
mod tracking;

pub use calib::RawCalib;
pub use drive::{
    GAP_FACTOR, ImuGap, RawDrive, ScanFormat, SweepStart, TimedOxts, VelodyneFrame,
    nominal_period_s, parse_velodyne_txt, read_velodyne_txt,
};
pub use time::{
    UnixTime, parse_timestamp, parse_timestamps, parse_unix_time, read_timestamps, write_timestamps,
};
pub use tracking::{
    ELEVATION_CORRECTION_FILE, TrackingFrameTimes, declared_elevation_correction_rad,
    tracking_frame_times,
};

#[cfg(test)]
mod tests;
