//! Fingerprints the code that writes a simulated dataset, so that
//! `limot eval suite` re-simulates a reused dataset when that code changed
//! even though its scenario did not (src/experiments/suite.rs, `ensure_dataset`).

use std::fs;
use std::path::{Path, PathBuf};

/// Everything a dataset's bytes depend on besides its scenario: the
/// simulator, the input types it writes, the KITTI readers, copy and twin
/// conversion, the scenario-to-simulation glue, the lock file.
const DATASET_SOURCES: [&str; 5] = [
    "sim/src",
    "estimator/src/input.rs",
    "src/io/kitti",
    "src/simulate.rs",
    "Cargo.lock",
];

fn main() {
    let mut files = Vec::new();
    for source in DATASET_SOURCES {
        println!("cargo:rerun-if-changed={source}");
        collect(Path::new(source), &mut files);
    }
    files.sort();
    // FNV-1a over each file's path and bytes: stable across machines and
    // toolchains (std's hashers are not)
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for file in &files {
        let bytes = fs::read(file).unwrap_or_default();
        for b in file.to_string_lossy().bytes().chain([0]).chain(bytes) {
            hash ^= u64::from(b);
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
    }
    println!("cargo:rustc-env=LIMOT_DATASET_CODE={hash:016x}");
}

fn collect(path: &Path, files: &mut Vec<PathBuf>) {
    if path.is_dir() {
        if let Ok(entries) = fs::read_dir(path) {
            for entry in entries.flatten() {
                collect(&entry.path(), files);
            }
        }
    } else if path.is_file() {
        files.push(path.to_path_buf());
    }
}
