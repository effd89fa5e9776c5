//! The `kitti` family of a suite: the digital twins of KITTI tracking
//! sequences (`limot simulate kitti`), one suite family `kitti-SSSS` per
//! sequence, so that seeds, caching, parallel jobs, shards and merging treat
//! a twin like any other simulated sequence.

use super::{Result, SuiteError};
use crate::io::kitti::sequence_file;
use crate::simulate::kitti_scenario;
use limot_sim::scenario::ScenarioSpec;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The family name that stands for the twins of [`KittiTwins::sequences`].
pub const TWIN_FAMILY: &str = "kitti";

/// Highest KITTI sequence number a twin can have (four-digit file names).
const MAX_SEQUENCE: u32 = 9999;

/// Where a suite's KITTI twins come from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct KittiTwins {
    /// KITTI tracking `training` directory (`oxts/`, `calib/`, `label_02/`).
    pub training: PathBuf,
    /// The sequences asked for, in order; those without files in `training`
    /// are kept and reported as not available.
    pub sequences: Vec<u32>,
    /// AB3DMOT-format detection directory (`SSSS.txt`, logit scores as
    /// PointRCNN's) whose boxes the twins record instead of the detector
    /// model's; `None`: the simulator's detector model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detections: Option<PathBuf>,
}

/// The suite family of KITTI sequence `sequence`'s twin (`kitti-SSSS`, the
/// name `ScenarioSpec::kitti` gives it).
pub fn twin_family(sequence: u32) -> String {
    format!("{TWIN_FAMILY}-{sequence:04}")
}

/// The KITTI sequence of a twin family (`kitti-SSSS`), `None` for any other family.
pub fn twin_sequence(family: &str) -> Option<u32> {
    let digits = family.strip_prefix(TWIN_FAMILY)?.strip_prefix('-')?;
    if digits.len() != 4 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// Parses a sequence list of numbers and inclusive ranges (`0-20`, `0,3,5-7`),
/// naming the option in errors.
///
/// # Errors
///
/// [`SuiteError::Spec`] for an empty list, an entry that is not a number or
/// an ascending range, a number above 9999 or a sequence given twice.
pub fn parse_sequences(option: &str, text: &str) -> Result<Vec<u32>> {
    let bad = |entry: &str, why: &str| SuiteError::Spec(format!("--{option} `{entry}`: {why}"));
    let number = |entry: &str, s: &str| -> Result<u32> {
        let n: u32 = s
            .trim()
            .parse()
            .map_err(|_| bad(entry, "expected a sequence number or a range such as 0-20"))?;
        if n > MAX_SEQUENCE {
            return Err(bad(entry, "KITTI sequences are numbered 0 to 9999"));
        }
        Ok(n)
    };
    let mut out: Vec<u32> = Vec::new();
    for entry in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let (first, last) = match entry.split_once('-') {
            Some((a, b)) => (number(entry, a)?, number(entry, b)?),
            None => {
                let n = number(entry, entry)?;
                (n, n)
            }
        };
        if first > last {
            return Err(bad(
                entry,
                "a range runs from the lower number to the higher",
            ));
        }
        for n in first..=last {
            if out.contains(&n) {
                return Err(bad(entry, &format!("sequence {n} given twice")));
            }
            out.push(n);
        }
    }
    if out.is_empty() {
        return Err(SuiteError::Spec(format!("--{option}: no sequence given")));
    }
    Ok(out)
}

/// A sequence list as [`parse_sequences`] reads it, runs of consecutive
/// numbers as ranges (`0-18,20`).
pub fn format_sequences(sequences: &[u32]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < sequences.len() {
        let mut j = i;
        while j + 1 < sequences.len() && sequences[j + 1] == sequences[j] + 1 {
            j += 1;
        }
        parts.push(if j > i {
            format!("{}-{}", sequences[i], sequences[j])
        } else {
            sequences[i].to_string()
        });
        i = j + 1;
    }
    parts.join(",")
}

impl KittiTwins {
    /// The twins of every sequence with an OXTS file in `training`, ascending.
    ///
    /// # Errors
    ///
    /// [`SuiteError`] when `training/oxts` cannot be read.
    pub fn every_sequence(training: &Path, detections: Option<PathBuf>) -> Result<KittiTwins> {
        Ok(KittiTwins {
            training: training.to_path_buf(),
            sequences: crate::experiments::oxts_sequences(training)?,
            detections,
        })
    }

    /// Checks the directories before any work: `training` (and the detection
    /// directory, when given) exist, and at least one sequence asked for has
    /// its files.
    ///
    /// # Errors
    ///
    /// [`SuiteError::Spec`] naming the missing directory, or every sequence
    /// asked for and the directory none of them is in.
    pub fn check(&self) -> Result<()> {
        if !self.training.is_dir() {
            return Err(SuiteError::Spec(format!(
                "--training {}: not a directory (a KITTI tracking `training` dir with oxts/, calib/, label_02/)",
                self.training.display()
            )));
        }
        if let Some(dir) = self.detections.as_ref().filter(|d| !d.is_dir()) {
            return Err(SuiteError::Spec(format!(
                "--detections {}: not a directory (AB3DMOT-format SSSS.txt files)",
                dir.display()
            )));
        }
        if self
            .sequences
            .iter()
            .all(|&n| self.missing_files(n).is_some())
        {
            let names: Vec<String> = self.sequences.iter().map(|n| format!("{n:04}")).collect();
            return Err(SuiteError::Spec(format!(
                "no sequence of --sequences is in {}: {} (no oxts/SSSS.txt)",
                self.training.display(),
                names.join(", ")
            )));
        }
        Ok(())
    }

    /// Why sequence `sequence` has no twin here (a file its twin needs is
    /// missing), or `None` when its files are there.
    pub fn missing_files(&self, sequence: u32) -> Option<String> {
        let mut needed = vec![
            sequence_file(&self.training.join("oxts"), sequence),
            sequence_file(&self.training.join("calib"), sequence),
        ];
        needed.extend(self.detection_file(sequence));
        let missing: Vec<String> = needed
            .iter()
            .filter(|p| !p.is_file())
            .map(|p| p.display().to_string())
            .collect();
        (!missing.is_empty()).then(|| {
            format!(
                "KITTI sequence {sequence:04} is not in the data: {} missing",
                missing.join(", ")
            )
        })
    }

    fn detection_file(&self, sequence: u32) -> Option<PathBuf> {
        self.detections.as_ref().map(|d| sequence_file(d, sequence))
    }

    /// The scenario of sequence `sequence`'s twin: the whole sequence, the
    /// corridor chosen from it, the recorded detections when given.
    ///
    /// # Errors
    ///
    /// [`SuiteError::Scenario`] when the scenario is invalid.
    pub fn scenario(&self, sequence: u32) -> Result<ScenarioSpec> {
        kitti_scenario(
            &self.training,
            sequence,
            0,
            None,
            None,
            self.detection_file(sequence).as_deref(),
        )
        .map_err(|source| SuiteError::Scenario {
            family: twin_family(sequence),
            source: Box::new(source),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sequence_lists_take_numbers_and_ranges() {
        assert_eq!(parse_sequences("s", "0-3").unwrap(), [0, 1, 2, 3]);
        assert_eq!(parse_sequences("s", " 5, 0-1 ,20").unwrap(), [5, 0, 1, 20]);
        for (text, expected) in [
            ("", "no sequence"),
            ("4-2", "`4-2`: a range runs from the lower"),
            ("1,x", "`x`: expected a sequence number"),
            ("0-2,2", "sequence 2 given twice"),
            ("10000", "0 to 9999"),
            ("1-", "`1-`: expected"),
        ] {
            let e = parse_sequences("sequences", text).unwrap_err().to_string();
            assert!(e.contains(expected), "{text:?}: {e}");
            assert!(e.contains("--sequences"), "{e}");
        }
    }

    #[test]
    fn formatted_lists_parse_back() {
        for list in [vec![0, 1, 2, 3, 5, 20], vec![7], vec![3, 1, 2]] {
            let text = format_sequences(&list);
            assert_eq!(parse_sequences("s", &text).unwrap(), list, "{text}");
        }
        assert_eq!(format_sequences(&[0, 1, 2, 4, 6, 7]), "0-2,4,6-7");
    }

    #[test]
    fn twin_families_name_their_sequence() {
        assert_eq!(twin_family(7), "kitti-0007");
        assert_eq!(twin_sequence("kitti-0007"), Some(7));
        for other in ["kitti", "urban", "kitti-7", "kitti-00a7", "xkitti-0007"] {
            assert_eq!(twin_sequence(other), None, "{other}");
        }
    }

    #[test]
    fn a_missing_directory_or_sequence_is_named() {
        let dir = std::env::temp_dir().join(format!("limot-twins-{}", std::process::id()));
        let twins = KittiTwins {
            training: dir.join("no-such-training"),
            sequences: vec![3],
            detections: None,
        };
        let e = twins.check().unwrap_err().to_string();
        assert!(
            e.contains("no-such-training") && e.contains("not a directory"),
            "{e}"
        );
        std::fs::create_dir_all(dir.join("oxts")).unwrap();
        std::fs::create_dir_all(dir.join("calib")).unwrap();
        let twins = KittiTwins {
            training: dir.clone(),
            sequences: vec![3, 19],
            detections: None,
        };
        let e = twins.check().unwrap_err().to_string();
        assert!(
            e.contains("0003, 0019") && e.contains(&dir.display().to_string()),
            "{e}"
        );
        std::fs::write(dir.join("oxts/0003.txt"), "").unwrap();
        std::fs::write(dir.join("calib/0003.txt"), "").unwrap();
        twins.check().unwrap();
        assert_eq!(twins.missing_files(3), None);
        let why = twins.missing_files(19).unwrap();
        assert!(why.contains("0019 is not in the data") && why.contains("oxts/0019.txt"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
