//! Velodyne HDL-64E S2 beam geometry: the per-laser elevation table.
//!
//! The embedded table comes from `64e_utexas.yaml` (ROS velodyne driver
//! calibration, in ../shared/data/velodyne). Of the three HDL-64E files there
//! it is the one that matches KITTI's sensor: it spans +2.02 deg to -24.71 deg
//! (KITTI documents +2 deg .. -24.8 deg, 26.8 deg), with the S2 layout of an
//! upper block spaced ~1/3 deg and a lower block spaced ~1/2 deg. The S2.1
//! `sztaki` file reaches +4.97 deg (8 beams above +2.5 deg), and real KITTI
//! raw scans in ../shared/data/kitti_raw_scans have no returns above ~+3 deg
//! beyond 6 m; the S3 `xiesc` file tops out at +1.96 deg and spans 26.5 deg.
//!
//! Index conventions:
//! - "beam index" `b` of [`elevation_table_rad`]: 0 = highest beam, 63 =
//!   lowest, i.e. KITTI's scan-line order (top to bottom).
//! - [`LidarPoint::ring`](limot_estimator::input::LidarPoint) follows the
//!   estimator's sensor contract, 0 = lowest beam: `ring = 63 - b`
//!   ([`ring_of_beam`]).
//!
//! Only the elevations are used: every column fires all 64 lasers at one
//! azimuth, so `rot_correction` and the offsets are parsed but ignored.

use std::collections::BTreeSet;

/// Number of lasers of the HDL-64E.
pub const NUM_LASERS: usize = 64;

/// One laser of a calibration file. Angles in radians, offsets in metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserCalib {
    /// Laser index in the calibration file (0..64).
    pub laser_id: u32,
    /// Elevation of the beam (positive up).
    pub vert_correction_rad: f64,
    /// Azimuth offset of the beam (ignored by the simulator).
    pub rot_correction_rad: f64,
    /// Range correction, m (parsed, ignored by the simulator).
    pub dist_correction_m: f64,
    /// Vertical offset of the beam origin, m (parsed, ignored).
    pub vert_offset_correction_m: f64,
    /// Horizontal offset of the beam origin, m (parsed, ignored).
    pub horiz_offset_correction_m: f64,
}

/// Why a calibration file was rejected. Line numbers are 1-based.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Hdl64Error {
    #[error("line {line}: field `{field}`: cannot parse `{text}` as a number")]
    /// A value that is not a number.
    BadNumber {
        /// 1-based line of the value.
        line: usize,
        /// Key of the value.
        field: String,
        /// The text that did not parse.
        text: String,
    },
    #[error("line {line}: field `{field}` = {value} is out of range ({why})")]
    /// A number outside the field's valid range.
    OutOfRange {
        /// 1-based line of the value.
        line: usize,
        /// Key of the value.
        field: String,
        /// The rejected value.
        value: f64,
        /// What the field must satisfy.
        why: &'static str,
    },
    #[error("line {line}: expected `key: value`, found `{text}`")]
    /// A line that is not `key: value`.
    Syntax {
        /// 1-based line.
        line: usize,
        /// The offending line.
        text: String,
    },
    #[error("line {line}: laser entry before the `lasers:` list")]
    /// A laser entry outside the `lasers:` list.
    LaserOutsideList {
        /// 1-based line of the entry.
        line: usize,
    },
    #[error("laser entry starting at line {line}: missing field `{field}`")]
    /// A laser entry lacks a required field.
    MissingField {
        /// 1-based line where the entry starts.
        line: usize,
        /// The missing key.
        field: &'static str,
    },
    #[error("line {line}: laser_id {laser_id} appears twice")]
    /// Two entries with the same laser id.
    DuplicateLaserId {
        /// 1-based line of the second entry.
        line: usize,
        /// The repeated id.
        laser_id: u32,
    },
    #[error("`num_lasers: {declared}` but {found} laser entries were found")]
    /// `num_lasers` disagrees with the number of entries.
    CountMismatch {
        /// The `num_lasers` value.
        declared: usize,
        /// Entries found.
        found: usize,
    },
    #[error("expected {expected} lasers, found {found}")]
    /// The file does not describe exactly [`NUM_LASERS`] lasers.
    WrongLaserCount {
        /// [`NUM_LASERS`].
        expected: usize,
        /// Lasers found.
        found: usize,
    },
}

/// Beam elevations (radians, positive up), beam index 0 = highest,
/// 63 = lowest (KITTI scan-line order), from `64e_utexas.yaml`.
pub const ELEVATION_TABLE_RAD: [f64; NUM_LASERS] = [
    0.0352698266506195,    // ring 0, laser_id 29
    0.0293195936828852,    // ring 1, laser_id 28
    0.0233724191784859,    // ring 2, laser_id 25
    0.0174280721694231,    // ring 3, laser_id 24
    0.0114863449707627,    // ring 4, laser_id 3
    0.0055470340885222,    // ring 5, laser_id 2
    -0.000390077300835401, // ring 6, laser_id 31
    -0.00632520206272602,  // ring 7, laser_id 30
    -0.0122585473582149,   // ring 8, laser_id 27
    -0.0181903336197138,   // ring 9, laser_id 26
    -0.024120757356286,    // ring 10, laser_id 21
    -0.0300500374287367,   // ring 11, laser_id 20
    -0.035978376865387,    // ring 12, laser_id 17
    -0.0419059917330742,   // ring 13, laser_id 16
    -0.0478330813348293,   // ring 14, laser_id 13
    -0.05375986546278,     // ring 15, laser_id 12
    -0.0596865378320217,   // ring 16, laser_id 23
    -0.0656133219599724,   // ring 17, laser_id 22
    -0.0715404152870178,   // ring 18, laser_id 19
    -0.0774680152535439,   // ring 19, laser_id 18
    -0.0833963677287102,   // ring 20, laser_id 15
    -0.0893256440758705,   // ring 21, laser_id 14
    -0.0952560678124428,   // ring 22, laser_id 9
    -0.101187855005264,    // ring 23, laser_id 8
    -0.107121199369431,    // ring 24, laser_id 5
    -0.113056324422359,    // ring 25, laser_id 4
    -0.118993431329727,    // ring 26, laser_id 1
    -0.124932751059532,    // ring 27, laser_id 0
    -0.130874469876289,    // ring 28, laser_id 11
    -0.136818811297417,    // ring 29, laser_id 10
    -0.142765983939171,    // ring 30, laser_id 7
    -0.148716226220131,    // ring 31, laser_id 6
    -0.156202226877213,    // ring 32, laser_id 61
    -0.16517236828804,     // ring 33, laser_id 60
    -0.17413204908371,     // ring 34, laser_id 57
    -0.183082059025764,    // ring 35, laser_id 56
    -0.192023113369942,    // ring 36, laser_id 35
    -0.200955957174301,    // ring 37, laser_id 34
    -0.209881335496902,    // ring 38, laser_id 63
    -0.218799933791161,    // ring 39, laser_id 62
    -0.22771255671978,     // ring 40, laser_id 59
    -0.236619830131531,    // ring 41, laser_id 58
    -0.245522528886795,    // ring 42, laser_id 53
    -0.254421383142471,    // ring 43, laser_id 52
    -0.26331701874733,     // ring 44, laser_id 49
    -0.272210210561752,    // ring 45, laser_id 48
    -0.281101644039154,    // ring 46, laser_id 45
    -0.28999200463295,     // ring 47, laser_id 44
    -0.298882067203522,    // ring 48, laser_id 55
    -0.307772427797318,    // ring 49, laser_id 54
    -0.316663861274719,    // ring 50, laser_id 51
    -0.323895305395126,    // ring 51, laser_id 50
    -0.334452718496323,    // ring 52, laser_id 47
    -0.343351542949677,    // ring 53, laser_id 46
    -0.352254241704941,    // ring 54, laser_id 41
    -0.361161530017853,    // ring 55, laser_id 40
    -0.370074152946472,    // ring 56, laser_id 37
    -0.378992766141891,    // ring 57, laser_id 36
    -0.387918144464493,    // ring 58, laser_id 33
    -0.396850973367691,    // ring 59, laser_id 32
    -0.405792057514191,    // ring 60, laser_id 43
    -0.414742022752762,    // ring 61, laser_id 42
    -0.423701733350754,    // ring 62, laser_id 39
    -0.43128889799118,     // ring 63, laser_id 38
];

/// The embedded elevation table (beam index 0 = highest beam).
pub fn elevation_table_rad() -> [f64; NUM_LASERS] {
    ELEVATION_TABLE_RAD
}

/// `LidarPoint::ring` (0 = lowest beam) of beam index `beam` (0 = highest).
pub fn ring_of_beam(beam: usize) -> u16 {
    debug_assert!(beam < NUM_LASERS);
    (NUM_LASERS - 1 - beam) as u16
}

/// Parses a ROS velodyne-driver calibration file (the YAML subset those
/// files use: top-level `key: value` lines and a `lasers:` list of flat
/// `- key: value` maps). Unknown keys are skipped; known numeric keys must
/// parse and be finite. Lasers are returned in file order.
///
/// # Errors
/// [`Hdl64Error`] with the 1-based line of the first problem.
pub fn parse_calibration(text: &str) -> Result<Vec<LaserCalib>, Hdl64Error> {
    let mut lasers = Vec::new();
    let mut current: Option<PartialLaser> = None;
    let mut in_list = false;
    let mut declared: Option<(usize, usize)> = None;
    for (index, raw) in text.lines().enumerate() {
        let line = index + 1;
        let without_comment = raw.split('#').next().unwrap_or("");
        if without_comment.trim().is_empty() {
            continue;
        }
        let indented = without_comment.starts_with(' ') || without_comment.starts_with('\t');
        let mut body = without_comment.trim();
        if let Some(rest) = body.strip_prefix('-') {
            // a new laser entry
            if !in_list {
                return Err(Hdl64Error::LaserOutsideList { line });
            }
            if let Some(done) = current.take() {
                lasers.push(done.finish()?);
            }
            current = Some(PartialLaser::new(line));
            body = rest.trim();
            if body.is_empty() {
                continue;
            }
        } else if !indented {
            // a top-level key ends the current laser entry
            if let Some(done) = current.take() {
                lasers.push(done.finish()?);
            }
            in_list = false;
        }
        let Some((key, value)) = body.split_once(':') else {
            return Err(Hdl64Error::Syntax {
                line,
                text: raw.to_string(),
            });
        };
        let (key, value) = (key.trim(), value.trim());
        match current.as_mut() {
            Some(laser) if indented || raw.trim_start().starts_with('-') => {
                laser.set(line, key, value)?;
            }
            _ => match key {
                "lasers" => in_list = true,
                "num_lasers" => {
                    let n = parse_number(line, key, value)?;
                    if n < 0.0 || n.fract() != 0.0 {
                        return Err(Hdl64Error::OutOfRange {
                            line,
                            field: key.to_string(),
                            value: n,
                            why: "must be a non-negative integer",
                        });
                    }
                    declared = Some((n as usize, line));
                }
                _ => {}
            },
        }
    }
    if let Some(done) = current.take() {
        lasers.push(done.finish()?);
    }
    if let Some((n, _)) = declared
        && n != lasers.len()
    {
        return Err(Hdl64Error::CountMismatch {
            declared: n,
            found: lasers.len(),
        });
    }
    let mut seen = BTreeSet::new();
    for (laser, line) in lasers.iter() {
        if !seen.insert(laser.laser_id) {
            return Err(Hdl64Error::DuplicateLaserId {
                line: *line,
                laser_id: laser.laser_id,
            });
        }
    }
    Ok(lasers.into_iter().map(|(l, _)| l).collect())
}

/// Elevation table (beam index 0 = highest) from parsed calibration lasers.
///
/// # Errors
/// [`Hdl64Error::WrongLaserCount`] unless there are [`NUM_LASERS`] lasers.
pub fn elevation_table_from(lasers: &[LaserCalib]) -> Result<[f64; NUM_LASERS], Hdl64Error> {
    if lasers.len() != NUM_LASERS {
        return Err(Hdl64Error::WrongLaserCount {
            expected: NUM_LASERS,
            found: lasers.len(),
        });
    }
    let mut elevations: Vec<f64> = lasers.iter().map(|l| l.vert_correction_rad).collect();
    elevations.sort_by(|a, b| b.total_cmp(a));
    let mut table = [0.0; NUM_LASERS];
    table.copy_from_slice(&elevations);
    Ok(table)
}

fn parse_number(line: usize, field: &str, text: &str) -> Result<f64, Hdl64Error> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(Hdl64Error::BadNumber {
            line,
            field: field.to_string(),
            text: text.to_string(),
        }),
    }
}

/// A laser entry while its fields are being read.
struct PartialLaser {
    line: usize,
    laser_id: Option<u32>,
    vert_correction_rad: Option<f64>,
    rot_correction_rad: Option<f64>,
    dist_correction_m: f64,
    vert_offset_correction_m: f64,
    horiz_offset_correction_m: f64,
}

impl PartialLaser {
    fn new(line: usize) -> PartialLaser {
        PartialLaser {
            line,
            laser_id: None,
            vert_correction_rad: None,
            rot_correction_rad: None,
            dist_correction_m: 0.0,
            vert_offset_correction_m: 0.0,
            horiz_offset_correction_m: 0.0,
        }
    }

    fn set(&mut self, line: usize, key: &str, value: &str) -> Result<(), Hdl64Error> {
        match key {
            "laser_id" => {
                let v = parse_number(line, key, value)?;
                if v < 0.0 || v.fract() != 0.0 || v > u32::MAX as f64 {
                    return Err(Hdl64Error::OutOfRange {
                        line,
                        field: key.to_string(),
                        value: v,
                        why: "must be a non-negative integer",
                    });
                }
                self.laser_id = Some(v as u32);
            }
            "vert_correction" => {
                let v = parse_number(line, key, value)?;
                if v.abs() >= std::f64::consts::FRAC_PI_2 {
                    return Err(Hdl64Error::OutOfRange {
                        line,
                        field: key.to_string(),
                        value: v,
                        why: "an elevation must be within (-pi/2, pi/2) rad",
                    });
                }
                self.vert_correction_rad = Some(v);
            }
            "rot_correction" => self.rot_correction_rad = Some(parse_number(line, key, value)?),
            "dist_correction" => self.dist_correction_m = parse_number(line, key, value)?,
            "vert_offset_correction" => {
                self.vert_offset_correction_m = parse_number(line, key, value)?
            }
            "horiz_offset_correction" => {
                self.horiz_offset_correction_m = parse_number(line, key, value)?
            }
            _ => {}
        }
        Ok(())
    }

    fn finish(self) -> Result<(LaserCalib, usize), Hdl64Error> {
        let missing = |field| Hdl64Error::MissingField {
            line: self.line,
            field,
        };
        Ok((
            LaserCalib {
                laser_id: self.laser_id.ok_or_else(|| missing("laser_id"))?,
                vert_correction_rad: self
                    .vert_correction_rad
                    .ok_or_else(|| missing("vert_correction"))?,
                rot_correction_rad: self.rot_correction_rad.unwrap_or(0.0),
                dist_correction_m: self.dist_correction_m,
                vert_offset_correction_m: self.vert_offset_correction_m,
                horiz_offset_correction_m: self.horiz_offset_correction_m,
            },
            self.line,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    const DATA_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/velodyne");

    #[test]
    fn embedded_table_is_sorted_and_spans_the_s2_field_of_view() {
        let table = elevation_table_rad();
        assert!(table.windows(2).all(|w| w[0] > w[1]));
        let (top, bottom) = (table[0].to_degrees(), table[63].to_degrees());
        assert!((top - 2.0).abs() < 0.1, "{top}");
        assert!((bottom + 24.8).abs() < 0.2, "{bottom}");
        assert_eq!(ring_of_beam(0), 63);
        assert_eq!(ring_of_beam(63), 0);
    }

    #[test]
    fn data_file_parses_to_the_embedded_table() {
        let path = Path::new(DATA_DIR).join("64e_utexas.yaml");
        let Ok(text) = std::fs::read_to_string(&path) else {
            // Shared data absent (e.g. a fresh clone): the embedded table is
            // still checked by the other tests.
            eprintln!("skipping: {} not found", path.display());
            return;
        };
        let lasers = parse_calibration(&text).expect("parse");
        assert_eq!(lasers.len(), NUM_LASERS);
        assert_eq!(lasers[0].laser_id, 0);
        assert_eq!(lasers[0].vert_correction_rad, -0.124932751059532);
        assert_eq!(elevation_table_from(&lasers).unwrap(), ELEVATION_TABLE_RAD);
    }

    #[test]
    fn all_shared_calibration_files_parse() {
        let Ok(dir) = std::fs::read_dir(DATA_DIR) else {
            return;
        };
        for entry in dir.flatten() {
            let path = entry.path();
            if path.extension().is_some_and(|e| e == "yaml") {
                let text = std::fs::read_to_string(&path).unwrap();
                let lasers =
                    parse_calibration(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                let table = elevation_table_from(&lasers).unwrap();
                assert!(table[0] < 0.1 && table[63] > -0.45, "{}", path.display());
            }
        }
    }

    #[test]
    fn bad_input_names_the_line_and_field() {
        let text = "lasers:\n- laser_id: 0\n  vert_correction: abc\n";
        assert_eq!(
            parse_calibration(text),
            Err(Hdl64Error::BadNumber {
                line: 3,
                field: "vert_correction".into(),
                text: "abc".into()
            })
        );
        let text = "lasers:\n- laser_id: 0\n  rot_correction: 0.1\n";
        assert_eq!(
            parse_calibration(text),
            Err(Hdl64Error::MissingField {
                line: 2,
                field: "vert_correction"
            })
        );
        let text = "lasers:\n- laser_id: 1\n  vert_correction: 0.1\n- laser_id: 1\n  vert_correction: 0.2\nnum_lasers: 2\n";
        assert_eq!(
            parse_calibration(text),
            Err(Hdl64Error::DuplicateLaserId {
                line: 4,
                laser_id: 1
            })
        );
        let text = "lasers:\n- laser_id: 1\n  vert_correction: 0.1\nnum_lasers: 3\n";
        assert_eq!(
            parse_calibration(text),
            Err(Hdl64Error::CountMismatch {
                declared: 3,
                found: 1
            })
        );
        assert!(matches!(
            parse_calibration("- laser_id: 0\n"),
            Err(Hdl64Error::LaserOutsideList { line: 1 })
        ));
        assert!(matches!(
            parse_calibration("lasers:\n- laser_id: 0\n  nonsense\n"),
            Err(Hdl64Error::Syntax { line: 3, .. })
        ));
        assert!(matches!(
            elevation_table_from(&[]),
            Err(Hdl64Error::WrongLaserCount { .. })
        ));
    }
}
