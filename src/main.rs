//! `limot`: command-line interface (see [`limot::cli`]).

use clap::Parser;
use std::process::ExitCode;

/// mimalloc keeps freed pages for reuse: with the system allocator every
/// sweep's scan-sized buffers went back to the kernel and were faulted in
/// again (~2k page faults per frame of `limot run`). Built without
/// transparent huge pages (`no_thp`): memory mimalloc gives back and takes
/// again is then faulted in 4 KiB at a time, not zeroed 2 MiB at a time.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// `mi_option_purge_delay` in mimalloc v3's `mi_option_e` (the version the
/// locked libmimalloc-sys builds; the sys crate names no constant for it).
const MI_OPTION_PURGE_DELAY: libmimalloc_sys::mi_option_t = 15;

/// Never hand freed pages back to the kernel. By default mimalloc purges them
/// 10 ms after the free, shorter than a frame, so every sweep's scan-sized
/// buffers were faulted in (and zeroed, 2 MiB transparent huge pages) again;
/// the peak resident size stays what the live data needs at its largest.
fn keep_freed_pages() {
    // SAFETY: sets a plain integer option; mimalloc reads it on every purge.
    unsafe { libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, -1) };
}

/// End quietly when the reader of stdout goes away (`limot eval ego ... |
/// head -1`), as Unix tools do. Rust ignores SIGPIPE, so a print to a closed
/// pipe would panic instead.
fn die_on_closed_pipe() {
    #[cfg(unix)]
    // SAFETY: restores the default disposition of one signal, before any
    // thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> ExitCode {
    keep_freed_pages();
    die_on_closed_pipe();
    match limot::cli::Cli::parse().run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            let mut source = e.source();
            while let Some(s) = source {
                eprintln!("  caused by: {s}");
                source = s.source();
            }
            ExitCode::FAILURE
        }
    }
}
