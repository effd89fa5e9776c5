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

fn main() -> ExitCode {
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
