//! Sequence maps of the KITTI tracking devkit
//! (`evaluate_tracking.seqmap(.val)`): `0001 empty 000000 000447` =
//! sequence, an unused word, first frame, number of frames (end, exclusive).

use super::{LineCtx, Result, content_lines, read_text};
use std::path::Path;

/// One sequence of a sequence map.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SeqmapEntry {
    /// Sequence number.
    pub sequence: u32,
    /// First frame scored.
    pub first_frame: u32,
    /// One past the last frame (= frame count when `first_frame` is 0).
    pub end_frame: u32,
}

impl SeqmapEntry {
    /// Number of frames scored.
    pub fn num_frames(&self) -> u32 {
        self.end_frame - self.first_frame
    }

    /// The seqmap line of this entry (`SSSS empty FFFFFF EEEEEE`).
    pub fn to_line(&self) -> String {
        format!(
            "{:04} empty {:06} {:06}",
            self.sequence, self.first_frame, self.end_frame
        )
    }
}

/// Parses a sequence map.
///
/// # Errors
/// A malformed line or a frame range that ends before it starts (file and line).
pub fn parse_seqmap(text: &str, path: &Path) -> Result<Vec<SeqmapEntry>> {
    content_lines(text)
        .map(|(line_no, line)| {
            let ctx = LineCtx::new(path, line_no);
            let tokens: Vec<&str> = line.split_whitespace().collect();
            if tokens.len() != 4 {
                return Err(ctx.column_count("4", tokens.len()));
            }
            let sequence = ctx.u32(tokens[0], 1, "sequence")?;
            let first_frame = ctx.u32(tokens[2], 3, "first_frame")?;
            let end_frame = ctx.u32(tokens[3], 4, "end_frame")?;
            if end_frame < first_frame {
                return Err(ctx.field_error(
                    4,
                    "end_frame",
                    format!("{end_frame} < first frame {first_frame}"),
                ));
            }
            Ok(SeqmapEntry {
                sequence,
                first_frame,
                end_frame,
            })
        })
        .collect()
}

/// Reads a sequence map.
///
/// # Errors
/// An unreadable file, or a malformed line (see [`parse_seqmap`]).
pub fn read_seqmap(path: &Path) -> Result<Vec<SeqmapEntry>> {
    parse_seqmap(&read_text(path)?, path)
}

/// Formats a sequence map.
pub fn write_seqmap(entries: &[SeqmapEntry]) -> String {
    entries.iter().map(|e| e.to_line() + "\n").collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_without_trailing_newline_and_round_trips() {
        let text = "0001 empty 000000 000447\n0019 empty 000000 001059";
        let path = Path::new("seqmap.val");
        let entries = parse_seqmap(text, path).unwrap();
        assert_eq!(entries.len(), 2);
        assert_eq!(entries[0].sequence, 1);
        assert_eq!(entries[0].num_frames(), 447);
        assert_eq!(entries[1].end_frame, 1059);
        assert_eq!(write_seqmap(&entries).trim_end(), text);
        assert_eq!(
            parse_seqmap(&write_seqmap(&entries), path).unwrap(),
            entries
        );
    }

    #[test]
    fn errors_name_file_and_line() {
        let path = Path::new("seqmap.val");
        let err = parse_seqmap("0001 empty 0\n", path)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("seqmap.val:1") && err.contains("4 columns"),
            "{err}"
        );
        let err = parse_seqmap("0001 empty 0 5\n0002 empty 9 5\n", path)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("seqmap.val:2") && err.contains("end_frame"),
            "{err}"
        );
    }
}
