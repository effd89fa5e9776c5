//! The `limot` binary's allocator settings, shared with the benchmarks that
//! measure what the binary does.
//!
//! The binary (and each such benchmark) declares mimalloc its global
//! allocator: mimalloc keeps freed pages for reuse, where with the system
//! allocator every sweep's scan-sized buffers went back to the kernel and
//! were faulted in again (~2k page faults per frame of `limot run`). It is
//! built without transparent huge pages (`no_thp`): memory it gives back and
//! takes again is then faulted in 4 KiB at a time, not zeroed 2 MiB at a
//! time.

/// `mi_option_purge_delay` in mimalloc v3's `mi_option_e` (the version the
/// locked libmimalloc-sys builds; the sys crate names no constant for it).
const MI_OPTION_PURGE_DELAY: libmimalloc_sys::mi_option_t = 15;

/// Never hand freed pages back to the kernel. By default mimalloc purges them
/// 10 ms after the free, shorter than a frame, so every sweep's scan-sized
/// buffers were faulted in (and zeroed, 2 MiB transparent huge pages) again;
/// the peak resident size stays what the live data needs at its largest.
/// Call it first thing in `main`; it has no effect under another allocator.
pub fn keep_freed_pages() {
    // SAFETY: sets a plain integer option; mimalloc reads it on every purge.
    unsafe { libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, -1) };
}
