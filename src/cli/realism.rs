//! `limot realism`: realism statistics of a sequence, optionally beside a reference.

use std::path::PathBuf;

/// Writes OUT/realism.json and OUT/realism.md of `path` (with a progress bar).
pub(super) fn run_realism(
    path: PathBuf,
    sequence: u32,
    out: Option<PathBuf>,
    reference: Option<PathBuf>,
    reference_sequence: u32,
) -> Result<(), Box<dyn std::error::Error>> {
    crate::experiments::run_realism(&crate::experiments::RealismOptions {
        path,
        sequence,
        out,
        reference,
        reference_sequence,
        progress: true,
    })
    .map(|_| ())
    .map_err(Into::into)
}
