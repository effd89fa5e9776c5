//! Fuzz tests for the two user-facing readers: scenario TOML text and limot
//! dataset directories. Bad input must give an error naming the file (and the
//! line for text files) or be read back faithfully; it must never panic and
//! never be silently misread.

use limot_sim::Simulation;
use limot_sim::record::{Dataset, RecordError, RecordedFrame, decode_scan, encode_scan, scan_path};
use limot_sim::scenario::ScenarioSpec;
use proptest::prelude::*;
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};

// ---------------------------------------------------------------------------
// Scenario text fuzz
// ---------------------------------------------------------------------------

/// Value tokens that are wrong in most places of a scenario file.
const GARBAGE_VALUES: &[&str] = &[
    "garbage",
    "nan",
    "inf",
    "-inf",
    "-1",
    "1e300",
    "-1e300",
    "\"\"",
    "",
    "0",
    "-0.0",
    "18446744073709551616",
    "true",
    "[1.0, nan]",
    "\"urban\"",
    "{ x = 1 }",
    "[",
];

/// A uniform choice in `0..n` drawn as a 64-bit fraction (shrinks to 0).
type Pick = u64;

fn pick(raw: Pick, n: usize) -> usize {
    assert!(n > 0, "pick from an empty range");
    ((n as u128 * raw as u128) >> 64) as usize
}

#[derive(Debug, Clone)]
enum TextMutation {
    DeleteLine(Pick),
    DuplicateLine(Pick),
    /// Replace the value of a `key = value` line with a garbage token.
    ReplaceValue(Pick, usize),
    /// Insert `unknown_key_fuzz = 1` before a line.
    InsertUnknownKey(Pick),
    /// Cut the text at a byte offset (moved down to a char boundary).
    Truncate(Pick),
    /// Replace one character with another.
    FlipChar(Pick, char),
}

fn text_mutation() -> impl Strategy<Value = TextMutation> {
    prop_oneof![
        any::<Pick>().prop_map(TextMutation::DeleteLine),
        any::<Pick>().prop_map(TextMutation::DuplicateLine),
        (any::<Pick>(), 0..GARBAGE_VALUES.len())
            .prop_map(|(i, g)| TextMutation::ReplaceValue(i, g)),
        any::<Pick>().prop_map(TextMutation::InsertUnknownKey),
        any::<Pick>().prop_map(TextMutation::Truncate),
        (any::<Pick>(), any::<char>()).prop_map(|(i, c)| TextMutation::FlipChar(i, c)),
    ]
}

fn floor_char_boundary(text: &str, mut at: usize) -> usize {
    at = at.min(text.len());
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    at
}

fn apply_text_mutation(text: &str, mutation: &TextMutation) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    if lines.is_empty() {
        lines.push(String::new());
    }
    match mutation {
        TextMutation::DeleteLine(i) => {
            lines.remove(pick(*i, lines.len()));
        }
        TextMutation::DuplicateLine(i) => {
            let k = pick(*i, lines.len());
            lines.insert(k, lines[k].clone());
        }
        TextMutation::ReplaceValue(i, g) => {
            let value_lines: Vec<usize> = (0..lines.len())
                .filter(|&k| lines[k].contains(" = "))
                .collect();
            if let Some(&k) = value_lines.get(pick(*i, value_lines.len().max(1))) {
                let key = lines[k].split(" = ").next().unwrap_or("").to_string();
                lines[k] = format!("{key} = {}", GARBAGE_VALUES[*g]);
            }
        }
        TextMutation::InsertUnknownKey(i) => {
            let k = pick(*i, lines.len() + 1);
            lines.insert(k, "unknown_key_fuzz = 1".to_string());
        }
        TextMutation::Truncate(i) => {
            let at = floor_char_boundary(text, pick(*i, text.len() + 1));
            return text[..at].to_string();
        }
        TextMutation::FlipChar(i, c) => {
            let at = floor_char_boundary(text, pick(*i, text.len().max(1)));
            let mut out = text[..at].to_string();
            out.push(*c);
            let rest = &text[at..];
            let skip = rest.chars().next().map_or(0, char::len_utf8);
            out.push_str(&rest[skip..]);
            return out;
        }
    }
    let mut out = lines.join("\n");
    out.push('\n');
    out
}

/// Parses mutated text; checks the error names the origin, or the spec is valid.
fn check_parse(text: &str, origin: &Path) -> Result<Option<ScenarioSpec>, TestCaseError> {
    match ScenarioSpec::parse(text, origin) {
        Ok(spec) => {
            prop_assert!(
                spec.validate().is_ok(),
                "parse accepted a spec that validate() rejects: {:?}",
                spec.validate()
            );
            Ok(Some(spec))
        }
        Err(e) => {
            let message = e.to_string();
            prop_assert!(
                message.contains(&origin.display().to_string()),
                "error does not name {}: {message}",
                origin.display()
            );
            Ok(None)
        }
    }
}

fn family_name() -> impl Strategy<Value = &'static str> {
    prop_oneof![Just("urban"), Just("highway")]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn mutated_scenario_text_never_panics_and_errors_name_the_file(
        family in family_name(),
        mutations in prop::collection::vec(text_mutation(), 1..4),
    ) {
        let mut text = ScenarioSpec::builtin(family).unwrap().to_toml();
        for m in &mutations {
            text = apply_text_mutation(&text, m);
        }
        let origin = PathBuf::from(format!("fuzz/mutated_{family}.toml"));
        check_parse(&text, &origin)?;
    }
}

proptest! {
    // building a scene costs far more than parsing: few cases, 1 s scenarios
    // (about 50 ms per build; roughly a third of the mutants parse)
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn accepted_mutated_scenarios_build_without_panic(
        family in family_name(),
        mutation in text_mutation(),
    ) {
        let mut spec = ScenarioSpec::builtin(family).unwrap();
        spec.duration_s = 1.0;
        let text = apply_text_mutation(&spec.to_toml(), &mutation);
        let origin = PathBuf::from(format!("fuzz/build_{family}.toml"));
        if let Some(mut spec) = check_parse(&text, &origin)? {
            // keep the build cheap: a mutation may have raised the duration
            spec.duration_s = 1.0;
            if spec.validate().is_ok() {
                // Ok or Err are both fine; a panic fails the test
                let _ = spec.build();
            }
        }
    }
}

#[test]
fn scenario_mutations_do_mutate() {
    let text = ScenarioSpec::builtin("urban").unwrap().to_toml();
    let origin = Path::new("fuzz/self_check.toml");
    let nan = apply_text_mutation(&text, &TextMutation::ReplaceValue(0, 1));
    assert_ne!(nan, text);
    let err = ScenarioSpec::parse(&nan, origin).unwrap_err().to_string();
    assert!(err.contains("self_check.toml"), "{err}");
    let unknown = apply_text_mutation(&text, &TextMutation::InsertUnknownKey(0));
    let err = ScenarioSpec::parse(&unknown, origin)
        .unwrap_err()
        .to_string();
    assert!(err.contains("self_check.toml:1:"), "{err}");
}

// ---------------------------------------------------------------------------
// Dataset fuzz
// ---------------------------------------------------------------------------

/// What a reader gets out of a dataset directory, part by part, so one bad
/// file does not hide whether the others still read back unchanged.
struct Reading {
    dataset: Result<Dataset, RecordError>,
    /// One entry per frame of the *baseline* (read only when `open` worked).
    frames: Vec<Result<RecordedFrame, RecordError>>,
    ego: Option<Result<Vec<limot_sim::record::EgoTruth>, RecordError>>,
    bias: Option<Result<Vec<limot_sim::record::BiasTruth>, RecordError>>,
    boxes: Option<Result<Vec<Vec<limot_sim::record::BoxTruth>>, RecordError>>,
}

fn read_dataset(dir: &Path, frame_count: usize) -> Reading {
    let dataset = Dataset::open(dir);
    match &dataset {
        Ok(ds) => {
            let count = ds.frame_count().max(frame_count);
            Reading {
                frames: (0..count).map(|i| ds.frame(i)).collect(),
                ego: Some(ds.ego_truth()),
                bias: Some(ds.bias_truth()),
                boxes: Some(ds.box_truth()),
                dataset,
            }
        }
        Err(_) => Reading {
            dataset,
            frames: Vec::new(),
            ego: None,
            bias: None,
            boxes: None,
        },
    }
}

/// The clean dataset every case starts from, and everything read from it.
struct Baseline {
    dir: PathBuf,
    /// Every file, relative to `dir`.
    files: Vec<PathBuf>,
    dataset: Dataset,
    frames: Vec<RecordedFrame>,
    ego: Vec<limot_sim::record::EgoTruth>,
    bias: Vec<limot_sim::record::BiasTruth>,
    boxes: Vec<Vec<limot_sim::record::BoxTruth>>,
}

fn tmp_root() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("input_fuzz_{}", std::process::id()))
}

/// Removes scratch trees left by earlier, finished runs of this test binary
/// (each holds a ~35 MB dataset). Only where `/proc` tells which pids live.
fn remove_stale_scratch() {
    let (Some(parent), true) = (
        tmp_root().parent().map(Path::to_path_buf),
        Path::new("/proc/self").exists(),
    ) else {
        return;
    };
    let Ok(entries) = fs::read_dir(&parent) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().to_string();
        if let Some(pid) = name
            .strip_prefix("input_fuzz_")
            .and_then(|p| p.parse::<u32>().ok())
            && pid != std::process::id()
            && !Path::new(&format!("/proc/{pid}")).exists()
        {
            let _ = fs::remove_dir_all(entry.path());
        }
    }
}

fn baseline() -> &'static Baseline {
    static BASELINE: OnceLock<Baseline> = OnceLock::new();
    BASELINE.get_or_init(|| {
        remove_stale_scratch();
        let mut spec = ScenarioSpec::builtin("urban").unwrap();
        spec.duration_s = 1.0;
        let dir = tmp_root().join("base");
        let _ = fs::remove_dir_all(&dir);
        Simulation::new(&spec)
            .unwrap()
            .write_dataset(&dir, |_, _| {})
            .unwrap();
        let mut files = Vec::new();
        let mut stack = vec![dir.clone()];
        while let Some(d) = stack.pop() {
            for entry in fs::read_dir(&d).unwrap() {
                let path = entry.unwrap().path();
                if path.is_dir() {
                    stack.push(path);
                } else {
                    files.push(path.strip_prefix(&dir).unwrap().to_path_buf());
                }
            }
        }
        files.sort();
        let reading = read_dataset(&dir, 0);
        let dataset = reading.dataset.expect("clean dataset opens");
        let frames: Vec<RecordedFrame> = reading
            .frames
            .into_iter()
            .map(|f| f.expect("clean frame reads"))
            .collect();
        assert!(frames.len() >= 5, "{} frames", frames.len());
        assert!(
            frames.iter().all(|f| !f.scan.points.is_empty()),
            "every clean frame has points"
        );
        assert!(
            dataset.detections.iter().any(|d| !d.is_empty()),
            "the clean dataset has detections"
        );
        Baseline {
            ego: reading.ego.unwrap().expect("clean ego truth"),
            bias: reading.bias.unwrap().expect("clean bias truth"),
            boxes: reading.boxes.unwrap().expect("clean box truth"),
            dir,
            files,
            dataset,
            frames,
        }
    })
}

/// The CSV files of a dataset with their column counts.
const CSV_FILES: &[&str] = &[
    "imu.csv",
    "detections.csv",
    "gt/ego.csv",
    "gt/imu_bias.csv",
    "gt/boxes.csv",
];

/// Tokens that no CSV field of a dataset may hold.
const CSV_GARBAGE: &[&str] = &[
    "nan", "NaN", "inf", "-inf", "1e400", "abc", "", "1.2.3", "0x10", "--1",
];

/// Values that parse but break a field's own rule: (file, column, token).
const CSV_SEMANTIC_GARBAGE: &[(&str, &str, &str)] = &[
    ("detections.csv", "l", "-1"),
    ("detections.csv", "w", "0"),
    ("detections.csv", "h", "-0.5"),
    ("detections.csv", "score", "1.5"),
    ("detections.csv", "score", "-0.1"),
    ("detections.csv", "truth_id", "-2"),
    ("detections.csv", "frame", "-1"),
    ("detections.csv", "frame", "999999"),
    ("detections.csv", "class", "DontCare"),
    ("detections.csv", "time_offset_s", "-0.05"),
    ("detections.csv", "time_offset_s", "0.5"),
    ("gt/boxes.csv", "class", "DontCare"),
    ("gt/boxes.csv", "l", "-1"),
    ("gt/boxes.csv", "w", "0"),
    ("gt/boxes.csv", "h", "-3"),
    ("gt/boxes.csv", "qw", "5"),
    ("gt/boxes.csv", "parked", "2"),
    ("gt/boxes.csv", "id", "-1"),
    ("gt/boxes.csv", "frame", "999999"),
    ("gt/ego.csv", "qx", "0.9"),
    ("gt/ego.csv", "qw", "0"),
];

/// meta.toml values that are wrong for their key: (key, token).
const META_GARBAGE: &[(&str, &str)] = &[
    ("format_version", "2"),
    ("format_version", "-1"),
    ("duration_s", "nan"),
    ("duration_s", "-1.0"),
    ("duration_s", "0.0"),
    ("frame_count", "-1"),
    ("frame_count", "\"ten\""),
    ("imu_rate_hz", "nan"),
    ("imu_rate_hz", "0.0"),
    ("imu_rate_hz", "-100.0"),
    ("sweep_duration_s", "nan"),
    ("sweep_duration_s", "0.0"),
    ("sweep_duration_s", "0.2"),
    ("num_rings", "0"),
    ("num_rings", "32"),
    ("num_rings", "70000"),
    ("t_lidar_imu", "[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 5.0]"),
    ("t_lidar_imu", "[0.0, nan, 0.0, 0.0, 0.0, 0.0, 1.0]"),
    ("t_lidar_imu", "[1.0]"),
    ("name", "5"),
    ("seed", "-1"),
];

#[derive(Debug, Clone)]
enum CsvDamage {
    /// Replace the field with a token from [`CSV_GARBAGE`].
    Token(usize),
    /// Drop the field (one column too few).
    MissingColumn,
    /// Add a field after it (one column too many).
    ExtraColumn,
}

#[derive(Debug, Clone)]
enum Corruption {
    TruncateScan {
        frame: Pick,
        at: Pick,
    },
    /// Overwrite bytes of the 32-byte scan header.
    ScanHeaderBytes {
        frame: Pick,
        offset: Pick,
        bytes: Vec<u8>,
    },
    /// Overwrite bytes inside the point records.
    ScanPointBytes {
        frame: Pick,
        offset: Pick,
        bytes: Vec<u8>,
    },
    /// Write f32 NaN into x, y or z of one point.
    NanPoint {
        frame: Pick,
        point: Pick,
        coord: usize,
    },
    GarbleCsv {
        file: usize,
        line: Pick,
        column: Pick,
        damage: CsvDamage,
    },
    SemanticCsv {
        which: usize,
        line: Pick,
    },
    /// Swap two data lines of a time-stamped stream (time goes backwards).
    SwapLines {
        file: usize,
        first: Pick,
        second: Pick,
    },
    DeleteMetaKey {
        key: Pick,
    },
    MetaValue {
        which: usize,
    },
    /// Claim more frames than there are scans.
    MetaFrameCountTooLarge {
        extra: usize,
    },
    /// Overwrite one byte of a text file (CSV or meta.toml) with any value,
    /// invalid UTF-8 included; may even leave a valid file with another value.
    TextByte {
        file: usize,
        offset: Pick,
        byte: u8,
    },
}

fn corruption() -> impl Strategy<Value = Corruption> {
    let csv_damage = prop_oneof![
        (0..CSV_GARBAGE.len()).prop_map(CsvDamage::Token),
        Just(CsvDamage::MissingColumn),
        Just(CsvDamage::ExtraColumn),
    ];
    prop_oneof![
        (any::<Pick>(), any::<Pick>())
            .prop_map(|(frame, at)| Corruption::TruncateScan { frame, at }),
        (
            any::<Pick>(),
            any::<Pick>(),
            prop::collection::vec(any::<u8>(), 1..5)
        )
            .prop_map(|(frame, offset, bytes)| Corruption::ScanHeaderBytes {
                frame,
                offset,
                bytes
            }),
        (
            any::<Pick>(),
            any::<Pick>(),
            prop::collection::vec(any::<u8>(), 1..9)
        )
            .prop_map(|(frame, offset, bytes)| Corruption::ScanPointBytes {
                frame,
                offset,
                bytes
            }),
        (any::<Pick>(), any::<Pick>(), 0..3usize).prop_map(|(frame, point, coord)| {
            Corruption::NanPoint {
                frame,
                point,
                coord,
            }
        }),
        (0..CSV_FILES.len(), any::<Pick>(), any::<Pick>(), csv_damage).prop_map(
            |(file, line, column, damage)| Corruption::GarbleCsv {
                file,
                line,
                column,
                damage
            }
        ),
        (0..CSV_SEMANTIC_GARBAGE.len(), any::<Pick>())
            .prop_map(|(which, line)| Corruption::SemanticCsv { which, line }),
        (
            prop_oneof![Just(0usize), Just(2usize), Just(3usize)],
            any::<Pick>(),
            any::<Pick>()
        )
            .prop_map(|(file, first, second)| Corruption::SwapLines {
                file,
                first,
                second
            }),
        any::<Pick>().prop_map(|key| Corruption::DeleteMetaKey { key }),
        (0..META_GARBAGE.len()).prop_map(|which| Corruption::MetaValue { which }),
        (1..5usize).prop_map(|extra| Corruption::MetaFrameCountTooLarge { extra }),
        (0..CSV_FILES.len() + 1, any::<Pick>(), any::<u8>())
            .prop_map(|(file, offset, byte)| Corruption::TextByte { file, offset, byte }),
    ]
}

/// One corrupted file and what the readers must make of it.
struct Damaged {
    /// The corrupted file, relative to the dataset directory.
    file: PathBuf,
    bytes: Vec<u8>,
    /// The 1-based line an error must name, where it is known exactly.
    line: Option<usize>,
    /// Whether reading must fail (the damage is never valid data).
    must_fail: bool,
}

fn scan_file(frame: usize) -> PathBuf {
    scan_path(Path::new(""), frame)
}

/// `lines` with line `k` (0-based) replaced, joined back with a final newline.
fn join_lines(lines: &[String]) -> Vec<u8> {
    let mut out = lines.join("\n");
    out.push('\n');
    out.into_bytes()
}

fn read_lines(base: &Baseline, file: &str) -> Vec<String> {
    fs::read_to_string(base.dir.join(file))
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect()
}

fn damage(base: &Baseline, c: &Corruption) -> Damaged {
    let frames = base.frames.len();
    let scan_bytes = |f: usize| fs::read(base.dir.join(scan_file(f))).unwrap();
    match c {
        Corruption::TruncateScan { frame, at } => {
            let f = pick(*frame, frames);
            let bytes = scan_bytes(f);
            let cut = pick(*at, bytes.len());
            Damaged {
                file: scan_file(f),
                bytes: bytes[..cut].to_vec(),
                line: None,
                must_fail: true,
            }
        }
        Corruption::ScanHeaderBytes {
            frame,
            offset,
            bytes: new,
        } => {
            let f = pick(*frame, frames);
            let mut bytes = scan_bytes(f);
            let at = pick(*offset, 32);
            for (k, b) in new.iter().enumerate() {
                if at + k < 32 {
                    bytes[at + k] = *b;
                }
            }
            Damaged {
                file: scan_file(f),
                bytes,
                line: None,
                must_fail: false,
            }
        }
        Corruption::ScanPointBytes {
            frame,
            offset,
            bytes: new,
        } => {
            let f = pick(*frame, frames);
            let mut bytes = scan_bytes(f);
            let at = 32 + pick(*offset, bytes.len() - 32);
            for (k, b) in new.iter().enumerate() {
                if let Some(slot) = bytes.get_mut(at + k) {
                    *slot = *b;
                }
            }
            Damaged {
                file: scan_file(f),
                bytes,
                line: None,
                must_fail: false,
            }
        }
        Corruption::NanPoint {
            frame,
            point,
            coord,
        } => {
            let f = pick(*frame, frames);
            let mut bytes = scan_bytes(f);
            let p = pick(*point, base.frames[f].scan.points.len());
            let at = 32 + 28 * p + 4 * coord;
            bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
            Damaged {
                file: scan_file(f),
                bytes,
                line: None,
                must_fail: true,
            }
        }
        Corruption::GarbleCsv {
            file,
            line,
            column,
            damage,
        } => {
            let name = CSV_FILES[*file];
            let mut lines = read_lines(base, name);
            let k = pick(*line, lines.len());
            let mut fields: Vec<String> = lines[k].split(',').map(str::to_string).collect();
            let col = pick(*column, fields.len());
            match damage {
                CsvDamage::Token(t) => fields[col] = CSV_GARBAGE[*t].to_string(),
                CsvDamage::MissingColumn => {
                    fields.remove(col);
                }
                CsvDamage::ExtraColumn => fields.insert(col + 1, "0".to_string()),
            }
            lines[k] = fields.join(",");
            Damaged {
                file: PathBuf::from(name),
                bytes: join_lines(&lines),
                line: Some(k + 1),
                must_fail: true,
            }
        }
        Corruption::SemanticCsv { which, line } => {
            let (name, column, token) = CSV_SEMANTIC_GARBAGE[*which];
            let mut lines = read_lines(base, name);
            assert!(lines.len() > 1, "{name} has data rows");
            let col = lines[0]
                .split(',')
                .position(|c| c == column)
                .expect("column exists");
            let k = 1 + pick(*line, lines.len() - 1);
            let mut fields: Vec<&str> = lines[k].split(',').collect();
            fields[col] = token;
            lines[k] = fields.join(",");
            Damaged {
                file: PathBuf::from(name),
                bytes: join_lines(&lines),
                line: Some(k + 1),
                must_fail: true,
            }
        }
        Corruption::SwapLines {
            file,
            first,
            second,
        } => {
            let name = CSV_FILES[*file];
            let mut lines = read_lines(base, name);
            let data = lines.len() - 1;
            assert!(data >= 2, "{name} has {data} rows");
            let a = 1 + pick(*first, data);
            let mut b = 1 + pick(*second, data);
            if a == b {
                b = if a + 1 < lines.len() { a + 1 } else { a - 1 };
            }
            let (a, b) = (a.min(b), a.max(b));
            lines.swap(a, b);
            // line a now holds the later time; line a + 1 (0-based) goes back
            Damaged {
                file: PathBuf::from(name),
                bytes: join_lines(&lines),
                line: Some(a + 2),
                must_fail: true,
            }
        }
        Corruption::DeleteMetaKey { key } => {
            let mut lines = read_lines(base, "meta.toml");
            let keys: Vec<usize> = (0..lines.len())
                .filter(|&k| lines[k].contains(" = "))
                .collect();
            lines.remove(keys[pick(*key, keys.len())]);
            Damaged {
                file: PathBuf::from("meta.toml"),
                bytes: join_lines(&lines),
                line: None,
                must_fail: true,
            }
        }
        Corruption::MetaValue { which } => {
            let (key, token) = META_GARBAGE[*which];
            meta_with(base, key, token)
        }
        Corruption::TextByte { file, offset, byte } => {
            let name = CSV_FILES.get(*file).copied().unwrap_or("meta.toml");
            let mut bytes = fs::read(base.dir.join(name)).unwrap();
            let at = pick(*offset, bytes.len());
            bytes[at] = *byte;
            Damaged {
                file: PathBuf::from(name),
                bytes,
                line: None,
                must_fail: false,
            }
        }
        Corruption::MetaFrameCountTooLarge { extra } => {
            let count = base.dataset.meta.frame_count + extra;
            meta_with(base, "frame_count", &count.to_string())
        }
    }
}

/// meta.toml with `key`'s value replaced by `token`.
fn meta_with(base: &Baseline, key: &str, token: &str) -> Damaged {
    let mut lines = read_lines(base, "meta.toml");
    let k = lines
        .iter()
        .position(|l| l.starts_with(&format!("{key} = ")))
        .unwrap_or_else(|| panic!("meta.toml has no `{key}`"));
    lines[k] = format!("{key} = {token}");
    Damaged {
        file: PathBuf::from("meta.toml"),
        bytes: join_lines(&lines),
        line: None,
        must_fail: true,
    }
}

/// A scratch copy of the baseline with `damaged.file` replaced: untouched
/// files are hard links (never written), the damaged one a fresh file.
fn scratch_copy(base: &Baseline, damaged: &Damaged) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let dir = tmp_root().join(format!("case_{}", COUNTER.fetch_add(1, Ordering::Relaxed)));
    let _ = fs::remove_dir_all(&dir);
    for rel in &base.files {
        let to = dir.join(rel);
        fs::create_dir_all(to.parent().unwrap()).unwrap();
        if *rel == damaged.file {
            fs::write(&to, &damaged.bytes).unwrap();
        } else if fs::hard_link(base.dir.join(rel), &to).is_err() {
            fs::copy(base.dir.join(rel), &to).unwrap();
        }
    }
    dir
}

/// `bytes` with the reserved header field and the per-point padding zeroed:
/// what `encode_scan` writes for the values `decode_scan` returned.
fn without_padding(bytes: &[u8]) -> Vec<u8> {
    let mut out = bytes.to_vec();
    if out.len() >= 32 {
        out[26..28].fill(0);
        let mut o = 32;
        while o + 28 <= out.len() {
            out[o + 26..o + 28].fill(0);
            o += 28;
        }
    }
    out
}

/// The checks shared by every corruption; returns whether any part failed.
fn check_reading(base: &Baseline, damaged: &Damaged, dir: &Path) -> Result<bool, TestCaseError> {
    let reading = read_dataset(dir, base.frames.len());
    let file_name = damaged.file.to_string_lossy().replace('\\', "/");
    let mut failed = false;
    let mut check_err = |part: &str, e: &RecordError| -> Result<(), TestCaseError> {
        failed = true;
        let message = e.to_string();
        prop_assert!(
            message.contains(&file_name),
            "{part}: error does not name the corrupted {file_name}: {message}"
        );
        if let Some(line) = damaged.line {
            let located = format!("{file_name}:{line}:");
            prop_assert!(
                message.contains(&located),
                "{part}: error does not name {located}: {message}"
            );
        }
        Ok(())
    };
    let is = |name: &str| file_name == name;
    match &reading.dataset {
        Err(e) => check_err("open", e)?,
        Ok(ds) => {
            if !is("meta.toml") {
                prop_assert_eq!(&ds.meta, &base.dataset.meta);
            }
            if !is("imu.csv") {
                prop_assert_eq!(&ds.imu, &base.dataset.imu);
            }
            if !is("detections.csv") {
                prop_assert_eq!(&ds.detections, &base.dataset.detections);
            }
        }
    }
    for (i, frame) in reading.frames.iter().enumerate() {
        let this_scan = file_name == scan_file(i).to_string_lossy().replace('\\', "/");
        match frame {
            Err(e) => check_err(&format!("frame {i}"), e)?,
            Ok(f) if this_scan => {
                // accepted damage must be read faithfully, never misread
                let expected = without_padding(&damaged.bytes);
                prop_assert!(
                    encode_scan(&f.scan, &f.labels) == expected,
                    "frame {i}: the accepted scan does not re-encode to the file's bytes"
                );
                prop_assert_eq!(&f.detections, &base.frames[i].detections);
            }
            Ok(f) => {
                prop_assert!(i < base.frames.len(), "frame {i} exists only in meta.toml");
                if is("detections.csv") {
                    prop_assert_eq!(&f.scan, &base.frames[i].scan);
                    prop_assert_eq!(&f.labels, &base.frames[i].labels);
                } else {
                    prop_assert_eq!(f, &base.frames[i]);
                }
            }
        }
    }
    match &reading.ego {
        Some(Err(e)) => check_err("ego truth", e)?,
        Some(Ok(v)) if !is("gt/ego.csv") => prop_assert_eq!(v, &base.ego),
        _ => {}
    }
    match &reading.bias {
        Some(Err(e)) => check_err("bias truth", e)?,
        Some(Ok(v)) if !is("gt/imu_bias.csv") => prop_assert_eq!(v, &base.bias),
        _ => {}
    }
    match &reading.boxes {
        Some(Err(e)) => check_err("box truth", e)?,
        Some(Ok(v)) if !is("gt/boxes.csv") => prop_assert_eq!(v, &base.boxes),
        _ => {}
    }
    if damaged.must_fail {
        prop_assert!(failed, "damaged {file_name} was accepted silently");
    }
    Ok(failed)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    #[test]
    fn corrupted_dataset_files_give_located_errors_or_read_back_faithfully(
        c in corruption(),
    ) {
        let base = baseline();
        let damaged = damage(base, &c);
        let dir = scratch_copy(base, &damaged);
        let result = check_reading(base, &damaged, &dir);
        let _ = fs::remove_dir_all(&dir);
        result?;
    }
}

#[test]
fn clean_copy_reads_back_identically() {
    let base = baseline();
    let untouched = Damaged {
        file: PathBuf::from("none"),
        bytes: Vec::new(),
        line: None,
        must_fail: false,
    };
    let dir = scratch_copy(base, &untouched);
    let failed = check_reading(base, &untouched, &dir).unwrap();
    let _ = fs::remove_dir_all(&dir);
    assert!(!failed);
}

#[test]
fn decode_scan_never_panics_on_random_bytes() {
    // the decoder sees arbitrary bytes when files are swapped or damaged
    let base = baseline();
    let bytes = fs::read(base.dir.join(scan_file(0))).unwrap();
    let path = Path::new("scans/random.bin");
    let mut runner = proptest::test_runner::TestRunner::default();
    runner
        .run(
            &(
                0..bytes.len().min(4096),
                prop::collection::vec(any::<u8>(), 0..64),
            ),
            |(cut, tail)| {
                let mut b = bytes[..cut].to_vec();
                b.extend_from_slice(&tail);
                if let Err(e) = decode_scan(&b, path) {
                    prop_assert!(e.to_string().contains("scans/random.bin"));
                }
                Ok(())
            },
        )
        .unwrap();
}
