//! Fuzz-style property tests: random truncation, garbage and NaN injection
//! into every KITTI format gives an error naming the file (and the line or
//! byte offset), never a panic.

use limot::io::kitti::calib::Calib;
use limot::io::kitti::detections::parse_ab3dmot_csv;
use limot::io::kitti::labels::parse_labels;
use limot::io::kitti::oxts::parse_oxts;
use limot::io::kitti::poses::{parse_kitti_poses, parse_tum};
use limot::io::kitti::seqmap::parse_seqmap;
use limot::io::kitti::velodyne::parse_bin;
use proptest::prelude::*;
use std::path::Path;

const CALIB: &str = "\
P0: 7.215377e+02 0.0 6.095593e+02 0.0 0.0 7.215377e+02 1.728540e+02 0.0 0.0 0.0 1.0 0.0
P1: 7.215377e+02 0.0 6.095593e+02 -3.875744e+02 0.0 7.215377e+02 1.728540e+02 0.0 0.0 0.0 1.0 0.0
P2: 7.215377e+02 0.0 6.095593e+02 4.485728e+01 0.0 7.215377e+02 1.728540e+02 2.163791e-01 0.0 0.0 1.0 2.745884e-03
P3: 7.215377e+02 0.0 6.095593e+02 -3.395242e+02 0.0 7.215377e+02 1.728540e+02 2.199936e+00 0.0 0.0 1.0 2.729905e-03
R_rect 9.999239e-01 9.837760e-03 -7.445048e-03 -9.869795e-03 9.999421e-01 -4.278459e-03 7.402527e-03 4.351614e-03 9.999631e-01
Tr_velo_cam 7.533745e-03 -9.999714e-01 -6.166020e-04 -4.069766e-03 1.480249e-02 7.280733e-04 -9.998902e-01 -7.631618e-02 9.998621e-01 7.523790e-03 1.480755e-02 -2.717806e-01
Tr_imu_velo 9.999976e-01 7.553071e-04 -2.035826e-03 -8.086759e-01 -7.854027e-04 9.998898e-01 -1.482298e-02 3.195559e-01 2.024406e-03 1.482454e-02 9.998881e-01 -7.997231e-01
";

const OXTS: &str = "\
49.009347760599 8.4371344308375 114.45652008057 0.072242 0.001566 -0.2697266732051 -2.9301818443449 10.286884437741 10.695750797331 0.082893715568935 -0.075015404010604 0.0059525410318346 0.845164147132 9.9149729634473 0.041978129261809 0.13652761309179 9.9501668070309 0.016662646247367 -0.036831580656409 0.003311640516573 0.016662387052679 -0.036976147506788 0.00060422104178454 0.42856154750514 0.057982756057297 4 7 4 4 0

49.009344871709 8.4371499178574 114.45387268066 0.073139 -0.000124 -0.2696086732051 -2.9197146576057 10.304161163296 10.709610967122 0.068612964517919 -0.036819526034639 0.081271437896475 0.99064156439495 10.267645855742 0.087095268433451 0.23917236586171 10.312656380529 0.0027339720243652 -0.012582267935983 0.0028883653449442 0.0027336596878896 -0.012759610755965 0.0019557415013945 0.42856154750514 0.057982756057297 4 7 4 4 0
";

const LABELS: &str = "\
0 -1 DontCare -1 -1 -10.000000 356.400000 195.810000 374.100000 216.650000 -1000.000000 -1000.000000 -1000.000000 -10.000000 -1.000000 -1.000000 -1.000000
0 0 Van 0 0 -1.793451 296.744956 161.752147 455.226042 292.372804 2.000000 1.823255 4.433886 -4.552284 1.858523 13.410495 -2.115488
1 2 Pedestrian 1 2 -1.7 500.0 170.0 600.0 220.0 1.5 1.6 3.9 1.0 1.7 30.0 -1.69
";

const CSV: &str = "\
0,2,786.7492,180.1760,1241.0000,374.0000,12.2286,1.5206,1.6824,4.4501,2.9312,1.6089,6.4281,-1.5828,-2.0107
0,2,718.1009,178.6554,858.6496,280.5958,11.7592,1.5622,1.6099,3.8266,3.0233,1.6841,13.1890,-1.5741,-1.7995
4,2,384.3615,191.2274,463.4154,244.3732,10.3184,1.5171,1.5954,3.7611,-6.0804,2.1715,23.7919,1.5839,1.8341
";

const SEQMAP: &str = "0001 empty 000000 000447\n0006 empty 000000 000270\n";

const KITTI_POSES: &str = "\
1 0 0 0 0 1 0 0 0 0 1 0
0.9998 -0.0199987 0 1.5 0.0199987 0.9998 0 0.1 0 0 1 0
";

const TUM: &str = "0 0 0 0 0 0 0 1\n0.1 1.5 0.1 0 0 0 0.00999983 0.99995\n";

type Parser = fn(&str, &Path) -> Result<(), String>;

fn parsers() -> Vec<(&'static str, &'static str, Parser)> {
    vec![
        ("calib/0003.txt", CALIB, |t, p| {
            Calib::parse(t, p).map(|_| ()).map_err(|e| e.to_string())
        }),
        ("oxts/0003.txt", OXTS, |t, p| {
            parse_oxts(t, p).map(|_| ()).map_err(|e| e.to_string())
        }),
        ("label_02/0003.txt", LABELS, |t, p| {
            parse_labels(t, p).map(|_| ()).map_err(|e| e.to_string())
        }),
        ("pointrcnn/0003.txt", CSV, |t, p| {
            parse_ab3dmot_csv(t, p)
                .map(|_| ())
                .map_err(|e| e.to_string())
        }),
        ("seqmap.val", SEQMAP, |t, p| {
            parse_seqmap(t, p).map(|_| ()).map_err(|e| e.to_string())
        }),
        ("poses/03.txt", KITTI_POSES, |t, p| {
            parse_kitti_poses(t, p)
                .map(|_| ())
                .map_err(|e| e.to_string())
        }),
        ("traj.tum", TUM, |t, p| {
            parse_tum(t, p).map(|_| ()).map_err(|e| e.to_string())
        }),
    ]
}

const GARBAGE: [&str; 8] = ["nan", "NaN", "inf", "-inf", "1e999", "abc", "1.2.3", "0x10"];

/// Replaces token `token_index` (mod its count) of non-empty line
/// `line_index` (mod their count) with `junk`; returns the text and the
/// 1-based line number of the edit.
fn inject(text: &str, line_index: usize, token_index: usize, junk: &str) -> (String, usize) {
    let lines: Vec<&str> = text.lines().collect();
    let non_empty: Vec<usize> = (0..lines.len())
        .filter(|&i| !lines[i].trim().is_empty())
        .collect();
    let target = non_empty[line_index % non_empty.len()];
    let sep = if lines[target].contains(',') {
        ','
    } else {
        ' '
    };
    let mut tokens: Vec<&str> = lines[target].split(sep).filter(|t| !t.is_empty()).collect();
    let k = token_index % tokens.len();
    tokens[k] = junk;
    let new_line = tokens.join(&sep.to_string());
    let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    out[target] = new_line;
    (out.join("\n") + "\n", target + 1)
}

/// Deletes one token of one line (changes the column count).
fn delete_token(text: &str, line_index: usize, token_index: usize) -> (String, usize) {
    let lines: Vec<&str> = text.lines().collect();
    let non_empty: Vec<usize> = (0..lines.len())
        .filter(|&i| !lines[i].trim().is_empty())
        .collect();
    let target = non_empty[line_index % non_empty.len()];
    let sep = if lines[target].contains(',') {
        ','
    } else {
        ' '
    };
    let mut tokens: Vec<&str> = lines[target].split(sep).filter(|t| !t.is_empty()).collect();
    let k = token_index % tokens.len();
    tokens.remove(k);
    let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    out[target] = tokens.join(&sep.to_string());
    (out.join("\n") + "\n", target + 1)
}

#[test]
fn unmodified_samples_parse() {
    for (name, text, parse) in parsers() {
        parse(text, Path::new(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn injected_garbage_names_file_and_line(
        which in 0usize..7, line in 0usize..8, token in 0usize..40, junk in 0usize..GARBAGE.len()
    ) {
        let (name, text, parse) = parsers()[which];
        // The seqmap's second word is unused by the devkit (always "empty").
        prop_assume!(!(name == "seqmap.val" && token % 4 == 1));
        let (bad, line_no) = inject(text, line, token, GARBAGE[junk]);
        let err = parse(&bad, Path::new(name)).expect_err(&bad);
        let needle = format!("{name}:{line_no}");
        prop_assert!(err.contains(&needle), "{} does not contain {}", err, needle);
    }

    #[test]
    fn deleted_column_names_file_and_line(which in 0usize..7, line in 0usize..8, token in 0usize..40) {
        let (name, text, parse) = parsers()[which];
        let (bad, line_no) = delete_token(text, line, token);
        let err = parse(&bad, Path::new(name)).expect_err(&bad);
        let needle = format!("{name}:{line_no}");
        prop_assert!(err.contains(&needle), "{} does not contain {}", err, needle);
    }

    #[test]
    fn truncation_never_panics_and_errors_name_the_file(which in 0usize..7, cut in 0usize..4000) {
        let (name, text, parse) = parsers()[which];
        let mut cut = cut % (text.len() + 1);
        while !text.is_char_boundary(cut) {
            cut -= 1;
        }
        if let Err(err) = parse(&text[..cut], Path::new(name)) {
            prop_assert!(err.contains(name), "{}", err);
        }
    }

    #[test]
    fn random_bytes_never_panic(which in 0usize..7, bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let (name, _, parse) = parsers()[which];
        let text = String::from_utf8_lossy(&bytes);
        if let Err(err) = parse(&text, Path::new(name)) {
            prop_assert!(err.contains(name), "{}", err);
        }
    }

    #[test]
    fn bin_truncation_and_nan_name_the_byte_offset(
        n_points in 1usize..50, cut in 1usize..16, nan_at in 0usize..200, kind in 0usize..3
    ) {
        let mut bytes = Vec::new();
        for i in 0..n_points {
            for v in [i as f32, 1.0, -0.5, 0.3] {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        let path = Path::new("velodyne/0000000042.bin");
        prop_assert!(parse_bin(&bytes, path, 0.0).is_ok());
        // Truncated: the error names the start of the incomplete point.
        let truncated = &bytes[..bytes.len() - cut];
        let err = parse_bin(truncated, path, 0.0).unwrap_err().to_string();
        let offset = (n_points - 1) * 16;
        prop_assert!(err.contains("0000000042.bin") && err.contains(&format!("byte offset {offset}")), "{}", err);
        // Non-finite value: the error names its exact offset.
        let value = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][kind];
        let float_index = nan_at % (n_points * 4);
        bytes[4 * float_index..4 * float_index + 4].copy_from_slice(&value.to_le_bytes());
        let err = parse_bin(&bytes, path, 0.0).unwrap_err().to_string();
        let offset = 4 * float_index;
        prop_assert!(err.contains(&format!("byte offset {offset}:")), "{}", err);
    }
}
