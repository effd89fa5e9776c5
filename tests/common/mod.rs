//! Helpers shared by the integration tests.

use std::path::PathBuf;

/// `../shared/data` when it exists. When it does not, says loudly that the
/// `what` tests did not run (they never skip silently while it is there).
pub fn data_root(what: &str) -> Option<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if root.is_dir() {
        Some(root)
    } else {
        eprintln!(
            "\n!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!\n\
             !!! NOTE: {} is absent: {what} tests NOT RUN\n\
             !!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!\n",
            root.display()
        );
        None
    }
}
