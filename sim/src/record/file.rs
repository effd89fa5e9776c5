//! [`FileWriter`]: writes whole files, each from one reused buffer in one
//! write, by direct I/O where the filesystem takes it.

use super::{RecordError, io_err};
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write as _};
use std::path::Path;

/// How a [`FileWriter`] hands files to the operating system.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WriteMode {
    /// Large files by direct I/O (`O_DIRECT`, Linux): the bytes go from the
    /// writer's buffer to the device without a copy into the page cache.
    /// Files below [`DIRECT_MIN_BYTES`], other systems and filesystems that
    /// refuse direct I/O (the first refusal is remembered) go through the
    /// page cache.
    #[default]
    Direct,
    /// Every file through the page cache (an ordinary `write`).
    Buffered,
}

/// Files shorter than this go through the page cache even in
/// [`WriteMode::Direct`].
pub const DIRECT_MIN_BYTES: usize = 256 * 1024;

/// Alignment of a direct write's buffer, offset and length: a page, which
/// covers the 512- and 4096-byte logical blocks of disks.
const DIRECT_ALIGN: usize = 4096;

/// Writes whole files from one buffer that is reused from file to file (no
/// allocation once it has grown to the largest file). Each file is written
/// with a single `write`; a file that cannot be written is removed, so a
/// failed write leaves no partial file behind, and the error names it.
/// The bytes on disk are those the caller serialised, whatever the mode.
#[derive(Debug)]
pub struct FileWriter {
    buffer: Vec<u8>,
    direct: bool,
}

impl Default for FileWriter {
    fn default() -> Self {
        FileWriter::new(WriteMode::default())
    }
}

impl FileWriter {
    /// A writer in `mode`, with an empty buffer.
    pub fn new(mode: WriteMode) -> FileWriter {
        FileWriter {
            buffer: Vec::new(),
            direct: mode == WriteMode::Direct && cfg!(target_os = "linux"),
        }
    }

    /// Whether large files still go by direct I/O (false after the
    /// filesystem refused it once, or in [`WriteMode::Buffered`]).
    pub fn is_direct(&self) -> bool {
        self.direct
    }

    /// Creates (or truncates) `path` and writes `bytes` into it.
    ///
    /// # Errors
    /// [`RecordError::Io`] naming `path`; no partial file is left behind.
    pub fn write(&mut self, path: &Path, bytes: &[u8]) -> Result<(), RecordError> {
        self.write_with(path, |out| out.extend_from_slice(bytes))
    }

    /// Creates (or truncates) `path` and writes into it the bytes `fill`
    /// appends to the buffer it is given (which may already hold bytes
    /// before them that are not written: `fill` only appends).
    ///
    /// # Errors
    /// [`RecordError::Io`] naming `path`; no partial file is left behind.
    pub fn write_with(
        &mut self,
        path: &Path,
        fill: impl FnOnce(&mut Vec<u8>),
    ) -> Result<(), RecordError> {
        // the data starts at an aligned address inside the buffer: pad the
        // front with zeros (they are never written)
        self.buffer.clear();
        let front = self.buffer.as_ptr().align_offset(DIRECT_ALIGN);
        let front = if front < DIRECT_ALIGN { front } else { 0 };
        self.buffer.resize(front, 0);
        fill(&mut self.buffer);
        let len = self.buffer.len() - front;
        let result = if self.direct && len >= DIRECT_MIN_BYTES {
            self.write_direct(path, front, len)
        } else {
            write_buffered(path, &self.buffer[front..])
        };
        result.map_err(|source| {
            // best effort: the error is about the write, not the cleanup
            let _ = fs::remove_file(path);
            io_err(path)(source)
        })
    }

    /// Direct write of `buffer[front..front + len]`, falling back to the
    /// page cache (for good) when the filesystem refuses direct I/O.
    fn write_direct(&mut self, path: &Path, front: usize, len: usize) -> io::Result<()> {
        let padded = len.next_multiple_of(DIRECT_ALIGN);
        // room to realign and pad without another reallocation
        self.buffer.reserve(padded - len + DIRECT_ALIGN);
        let start = self.buffer.as_ptr().align_offset(DIRECT_ALIGN);
        if start >= DIRECT_ALIGN {
            return write_buffered(path, &self.buffer[front..front + len]);
        }
        if start != front {
            // the buffer moved while it was filled: shift the data onto the boundary
            self.buffer.resize(start.max(front) + len, 0);
            self.buffer.copy_within(front..front + len, start);
        }
        self.buffer.resize(start + len, 0);
        self.buffer.resize(start + padded, 0);
        let file = match open_direct(path) {
            Ok(file) => file,
            Err(e) if refuses_direct_io(&e) => {
                self.direct = false;
                return write_buffered(path, &self.buffer[start..start + len]);
            }
            Err(e) => return Err(e),
        };
        match write_padded(file, &self.buffer[start..start + padded], len) {
            Ok(()) => Ok(()),
            Err(e) if refuses_direct_io(&e) => {
                // e.g. a device block larger than DIRECT_ALIGN: rewrite the whole file
                self.direct = false;
                write_buffered(path, &self.buffer[start..start + len])
            }
            Err(e) => Err(e),
        }
    }
}

/// One `write` of the whole file through the page cache.
fn write_buffered(path: &Path, bytes: &[u8]) -> io::Result<()> {
    File::create(path)?.write_all(bytes)
}

/// The padded bytes in one direct write, then the file cut to `len`.
fn write_padded(mut file: File, padded: &[u8], len: usize) -> io::Result<()> {
    file.write_all(padded)?;
    file.set_len(len as u64)
}

/// EINVAL: the filesystem or device does not do direct I/O (or not with
/// this alignment).
fn refuses_direct_io(e: &io::Error) -> bool {
    e.kind() == io::ErrorKind::InvalidInput
}

#[cfg(target_os = "linux")]
fn open_direct(path: &Path) -> io::Result<File> {
    use std::os::unix::fs::OpenOptionsExt as _;
    OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .custom_flags(libc::O_DIRECT)
        .open(path)
}

#[cfg(not(target_os = "linux"))]
fn open_direct(_path: &Path) -> io::Result<File> {
    Err(io::Error::from(io::ErrorKind::InvalidInput))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("limot-file-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// Deterministic bytes that are not all zero.
    fn pattern(len: usize, salt: u8) -> Vec<u8> {
        (0..len)
            .map(|i| (i as u8).wrapping_mul(31).wrapping_add(salt))
            .collect()
    }

    #[test]
    fn every_mode_and_size_writes_exactly_the_bytes() {
        let dir = temp_dir("sizes");
        for mode in [WriteMode::Direct, WriteMode::Buffered] {
            let mut writer = FileWriter::new(mode);
            // small, just below and above the direct threshold, unaligned
            // and aligned lengths, and a shorter file after a longer one
            let lengths = [
                0,
                1,
                4095,
                DIRECT_MIN_BYTES - 1,
                DIRECT_MIN_BYTES,
                DIRECT_MIN_BYTES + 1,
                3 * DIRECT_MIN_BYTES + 4097,
                DIRECT_MIN_BYTES + 7,
            ];
            for (i, &len) in lengths.iter().enumerate() {
                let path = dir.join(format!("{mode:?}-{i}.bin"));
                let bytes = pattern(len, i as u8);
                writer.write(&path, &bytes).unwrap();
                assert_eq!(fs::read(&path).unwrap(), bytes, "{mode:?} {len}");
                // rewriting a longer file with a shorter one leaves no tail
                writer.write(&path, &bytes[..len / 2]).unwrap();
                assert_eq!(fs::read(&path).unwrap(), &bytes[..len / 2]);
            }
        }
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn write_with_writes_what_fill_appends() {
        let dir = temp_dir("with");
        let mut writer = FileWriter::default();
        let big = pattern(DIRECT_MIN_BYTES * 2 + 123, 9);
        writer.write(&dir.join("a"), &big).unwrap();
        writer
            .write_with(&dir.join("b"), |out| out.extend_from_slice(b"hello"))
            .unwrap();
        assert_eq!(fs::read(dir.join("b")).unwrap(), b"hello");
        // growing the buffer while filling moves it: the file is still exact
        let huge = pattern(DIRECT_MIN_BYTES * 8 + 5, 3);
        writer
            .write_with(&dir.join("c"), |out| {
                for chunk in huge.chunks(1000) {
                    out.extend_from_slice(chunk);
                }
            })
            .unwrap();
        assert_eq!(fs::read(dir.join("c")).unwrap(), huge);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_file_that_cannot_be_written_is_an_error_naming_it() {
        let dir = temp_dir("errors");
        let mut writer = FileWriter::default();
        let big = pattern(DIRECT_MIN_BYTES + 1, 1);
        // a directory where the file should be, and a missing parent directory
        fs::create_dir(dir.join("taken")).unwrap();
        for path in [dir.join("taken"), dir.join("missing").join("f.bin")] {
            for bytes in [&big[..], b"small"] {
                let err = writer.write(&path, bytes).unwrap_err();
                assert!(matches!(err, RecordError::Io { .. }), "{err}");
                assert!(err.to_string().contains(&path.display().to_string()));
            }
        }
        assert!(dir.join("taken").is_dir());
        assert!(!dir.join("missing").exists());
        // the writer keeps working after an error
        writer.write(&dir.join("ok"), &big).unwrap();
        assert_eq!(fs::read(dir.join("ok")).unwrap(), big);
        fs::remove_dir_all(&dir).unwrap();
    }
}
