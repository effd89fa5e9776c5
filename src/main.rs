//! `limot`: command-line interface (see [`limot::cli`]).

use clap::Parser;
use std::process::ExitCode;

/// mimalloc, configured by [`limot::allocator`] (why: see there).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

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
    limot::allocator::keep_freed_pages();
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
