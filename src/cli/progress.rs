//! The terminal progress bar of long commands.

use indicatif::{ProgressBar, ProgressStyle};

/// A per-frame progress bar over `total` frames labelled `label` (hidden unless `visible`).
pub(crate) fn frame_progress_bar(total: usize, visible: bool, label: &str) -> ProgressBar {
    if !visible {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(total as u64).with_style(
        ProgressStyle::with_template(
            "{msg:>10} [{bar:40}] {pos}/{len} frames  {per_sec}  eta {eta}",
        )
        .expect("static template")
        .progress_chars("=> "),
    );
    bar.set_message(label.to_string());
    bar
}
