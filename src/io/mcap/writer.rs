//! An MCAP file written whole or not at all, with its channels keyed by topic.
//!
//! The file is written as `FILE.partial` and renamed to `FILE` by
//! [`McapFile::finish`]; a writer dropped before that (an error on the way)
//! deletes the partial file, so no half-written recording is left. The
//! output is a function of what was written: message times come from the
//! caller, the header names limot's version and nothing reads the clock, so
//! the same messages give a byte-identical file.

use foxglove::{Encode, Schema};
use mcap::records::MessageHeader;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// The MCAP header's `library` field.
pub const LIBRARY: &str = concat!("limot ", env!("CARGO_PKG_VERSION"));

/// Uncompressed size a chunk is closed at, bytes: a little over two of the
/// simulated HDL-64E's clouds, so the per-frame messages of a sweep share a
/// chunk with it.
const CHUNK_SIZE_BYTES: u64 = 4 << 20;

/// Why an MCAP file could not be written. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum McapError {
    /// The file could not be created, written or renamed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The MCAP writer refused a record.
    #[error("{path}: {source}")]
    Mcap {
        /// The file.
        path: PathBuf,
        /// The writer's error.
        #[source]
        source: mcap::McapError,
    },
    /// A message could not be encoded.
    #[error("{path}: a message on `{topic}` could not be encoded: {message}")]
    Encode {
        /// The file.
        path: PathBuf,
        /// Its topic.
        topic: String,
        /// The encoder's error.
        message: String,
    },
    /// A message was given for a topic whose channel has another schema.
    #[error("{path}: topic `{topic}` carries `{channel_schema}`, not `{schema}`")]
    SchemaMismatch {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// The schema its channel was created with.
        channel_schema: String,
        /// The schema of the rejected message.
        schema: String,
    },
    /// A time of the data that an MCAP log time cannot hold.
    #[error(
        "{path}: frame {frame} is at t = {t_s} s, which is no MCAP time (finite, >= 0, before 2106)"
    )]
    Time {
        /// The file.
        path: PathBuf,
        /// The frame index.
        frame: usize,
        /// The frame's time, s.
        t_s: f64,
    },
    /// The frames, poses or ground truth to record could not be read or used.
    #[error("{path}: {message}")]
    Input {
        /// The file being written.
        path: PathBuf,
        /// What went wrong, naming the input file where there is one.
        message: String,
    },
}

/// Why a frame could not be written into an MCAP file while a source's
/// frames are streamed into it: the MCAP, or the frame's source.
pub(crate) enum FrameError {
    Mcap(McapError),
    Source(crate::io::SourceError),
}

impl FrameError {
    /// The error as the MCAP file `path`'s: a source error becomes
    /// [`McapError::Input`].
    pub(crate) fn into_mcap(self, path: &Path) -> McapError {
        match self {
            FrameError::Mcap(e) => e,
            FrameError::Source(e) => McapError::Input {
                path: path.to_path_buf(),
                message: e.to_string(),
            },
        }
    }
}

impl From<McapError> for FrameError {
    fn from(e: McapError) -> Self {
        FrameError::Mcap(e)
    }
}

impl From<crate::io::SourceError> for FrameError {
    fn from(e: crate::io::SourceError) -> Self {
        FrameError::Source(e)
    }
}

/// One channel: its MCAP id, schema name and the next sequence number.
#[derive(Debug)]
struct Channel {
    id: u16,
    schema_name: String,
    sequence: u32,
}

/// What was written, as [`McapFile::finish`] reports it.
#[derive(Debug, Clone, PartialEq)]
pub struct McapStats {
    /// The finished file.
    pub path: PathBuf,
    /// Its size, bytes.
    pub bytes: u64,
    /// Messages written.
    pub messages: u64,
    /// Log time of the first and last message, ns (`None` without messages).
    pub time_range_ns: Option<(u64, u64)>,
}

/// An MCAP file being written (uncompressed chunks, with the summary and
/// indexes Foxglove seeks with). Channels are created on their topic's first
/// message, in the order of those first messages.
pub struct McapFile {
    path: PathBuf,
    partial: PathBuf,
    writer: Option<mcap::Writer<BufWriter<File>>>,
    schemas: BTreeMap<String, u16>,
    channels: BTreeMap<String, Channel>,
    buffer: Vec<u8>,
    messages: u64,
    time_range_ns: Option<(u64, u64)>,
}

impl McapFile {
    /// Starts `path` (written as `path.partial` until [`McapFile::finish`]).
    ///
    /// # Errors
    /// [`McapError::Io`] when the partial file cannot be created,
    /// [`McapError::Mcap`] when its header cannot be written.
    pub fn create(path: &Path) -> Result<McapFile, McapError> {
        McapFile::create_with_profile(path, "")
    }

    /// [`McapFile::create`] with the header's `profile` (`ros2` for a ROS 2
    /// bag, as rosbag2 writes it; empty for Foxglove's schemas).
    ///
    /// # Errors
    /// As [`McapFile::create`].
    pub fn create_with_profile(path: &Path, profile: &str) -> Result<McapFile, McapError> {
        let mut partial = path.as_os_str().to_owned();
        partial.push(".partial");
        let partial = PathBuf::from(partial);
        let file = File::create(&partial).map_err(|source| McapError::Io {
            path: partial.clone(),
            source,
        })?;
        let options = mcap::WriteOptions::new()
            // uncompressed: zstd would save about a fifth of a cloud's f32s
            // but its C build costs more than a minute of every clean build
            .compression(None)
            .chunk_size(Some(CHUNK_SIZE_BYTES))
            .profile(profile)
            .library(LIBRARY);
        let mut mcap_file = McapFile {
            path: path.to_path_buf(),
            partial,
            writer: None,
            schemas: BTreeMap::new(),
            channels: BTreeMap::new(),
            buffer: Vec::new(),
            messages: 0,
            time_range_ns: None,
        };
        let writer = options
            .create(BufWriter::new(file))
            .map_err(|e| mcap_file.mcap_error(e))?;
        mcap_file.writer = Some(writer);
        Ok(mcap_file)
    }

    /// The file being written (its final name).
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn mcap_error(&self, source: mcap::McapError) -> McapError {
        match source {
            mcap::McapError::Io(source) => McapError::Io {
                path: self.partial.clone(),
                source,
            },
            source => McapError::Mcap {
                path: self.partial.clone(),
                source,
            },
        }
    }

    /// Writes `message` on `topic` at `log_time_ns` (also its publish time),
    /// creating the topic's channel with `T`'s schema on its first message.
    ///
    /// # Errors
    /// A topic already carrying another schema, a message that cannot be
    /// encoded, or a write that fails.
    pub fn write<T: Encode>(
        &mut self,
        topic: &str,
        log_time_ns: u64,
        message: &T,
    ) -> Result<(), McapError> {
        let schema = T::get_schema();
        let encoding = T::get_message_encoding();
        self.buffer.clear();
        if let Some(len) = message.encoded_len() {
            self.buffer.reserve(len);
        }
        let mut buffer = std::mem::take(&mut self.buffer);
        let encoded = message.encode(&mut buffer).map_err(|e| McapError::Encode {
            path: self.path.clone(),
            topic: topic.to_string(),
            message: e.to_string(),
        });
        let written = encoded
            .and_then(|()| self.write_encoded(topic, schema, &encoding, log_time_ns, &buffer));
        self.buffer = buffer;
        written
    }

    /// Writes one already-encoded message (`message_encoding`, e.g.
    /// `protobuf` or `cdr`) on `topic`, whose channel gets `schema` on its
    /// first message: the way in for messages of schemas other than
    /// Foxglove's (ROS 2 `sensor_msgs`, for one).
    ///
    /// # Errors
    /// As [`McapFile::write`].
    pub fn write_encoded(
        &mut self,
        topic: &str,
        schema: Option<Schema>,
        message_encoding: &str,
        log_time_ns: u64,
        data: &[u8],
    ) -> Result<(), McapError> {
        let schema_name = schema.as_ref().map_or(String::new(), |s| s.name.clone());
        if !self.channels.contains_key(topic) {
            let schema_id = match &schema {
                None => 0,
                Some(s) => match self.schemas.get(&s.name) {
                    Some(&id) => id,
                    None => {
                        let added = self.writer_mut().add_schema(&s.name, &s.encoding, &s.data);
                        let id = added.map_err(|e| self.mcap_error(e))?;
                        self.schemas.insert(s.name.clone(), id);
                        id
                    }
                },
            };
            let added =
                self.writer_mut()
                    .add_channel(schema_id, topic, message_encoding, &BTreeMap::new());
            let id = added.map_err(|e| self.mcap_error(e))?;
            self.channels.insert(
                topic.to_string(),
                Channel {
                    id,
                    schema_name: schema_name.clone(),
                    sequence: 0,
                },
            );
        }
        let channel = &self.channels[topic];
        if channel.schema_name != schema_name {
            return Err(McapError::SchemaMismatch {
                path: self.path.clone(),
                topic: topic.to_string(),
                channel_schema: channel.schema_name.clone(),
                schema: schema_name,
            });
        }
        let header = MessageHeader {
            channel_id: channel.id,
            sequence: channel.sequence,
            log_time: log_time_ns,
            publish_time: log_time_ns,
        };
        let written = self.writer_mut().write_to_known_channel(&header, data);
        written.map_err(|e| self.mcap_error(e))?;
        if let Some(channel) = self.channels.get_mut(topic) {
            channel.sequence = channel.sequence.wrapping_add(1);
        }
        self.messages += 1;
        self.time_range_ns = Some(match self.time_range_ns {
            None => (log_time_ns, log_time_ns),
            Some((first, last)) => (first.min(log_time_ns), last.max(log_time_ns)),
        });
        Ok(())
    }

    fn writer_mut(&mut self) -> &mut mcap::Writer<BufWriter<File>> {
        self.writer
            .as_mut()
            .expect("the writer lives until finish or drop")
    }

    /// Writes the summary, flushes and renames the partial file to its name.
    ///
    /// # Errors
    /// A summary, flush or rename that fails (the partial file is deleted).
    pub fn finish(mut self) -> Result<McapStats, McapError> {
        let mut writer = self.writer.take().expect("finish runs once");
        writer.finish().map_err(|e| self.mcap_error(e))?;
        let file = writer
            .into_inner()
            .into_inner()
            .map_err(|e| McapError::Io {
                path: self.partial.clone(),
                source: e.into_error(),
            })?;
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| McapError::Io { path, source }
        };
        file.sync_all().map_err(io(&self.partial))?;
        let bytes = file.metadata().map_err(io(&self.partial))?.len();
        drop(file);
        std::fs::rename(&self.partial, &self.path).map_err(io(&self.path))?;
        Ok(McapStats {
            path: self.path.clone(),
            bytes,
            messages: self.messages,
            time_range_ns: self.time_range_ns,
        })
    }
}

impl Drop for McapFile {
    /// An unfinished file is deleted: a recording is whole or absent.
    fn drop(&mut self) {
        if let Some(writer) = self.writer.take() {
            drop(writer);
            let _ = std::fs::remove_file(&self.partial);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use foxglove::schemas::{PosesInFrame, Vector3};
    use limot_test_support::ScratchDir;

    #[test]
    fn finished_file_appears_under_its_name_and_reads_back() {
        let dir = ScratchDir::new("mcap-writer");
        let path = dir.join("ok.mcap");
        let mut file = McapFile::create(&path).unwrap();
        assert!(!path.exists(), "written under FILE.partial until finished");
        let v = Vector3 {
            x: 1.0,
            y: 2.0,
            z: 3.0,
        };
        file.write("/v", 5, &v).unwrap();
        file.write("/v", 9, &v).unwrap();
        let stats = file.finish().unwrap();
        assert_eq!((stats.messages, stats.time_range_ns), (2, Some((5, 9))));
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(bytes.len() as u64, stats.bytes);
        assert!(!dir.join("ok.mcap.partial").exists());
        let messages: Vec<_> = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(Result::unwrap)
            .collect();
        assert_eq!(messages.len(), 2);
        assert_eq!(messages[1].sequence, 1);
        let schema = messages[0].channel.schema.as_ref().unwrap();
        assert_eq!(schema.name, "foxglove.Vector3");
        assert_eq!(messages[0].channel.message_encoding, "protobuf");
    }

    #[test]
    fn dropped_file_leaves_nothing_and_a_topic_keeps_its_schema() {
        let dir = ScratchDir::new("mcap-writer");
        let path = dir.join("dropped.mcap");
        let mut file = McapFile::create(&path).unwrap();
        file.write("/v", 1, &Vector3::default()).unwrap();
        let e = file.write("/v", 2, &PosesInFrame::default()).unwrap_err();
        assert!(matches!(e, McapError::SchemaMismatch { .. }), "{e}");
        drop(file);
        assert!(!path.exists() && !dir.join("dropped.mcap.partial").exists());
    }

    #[test]
    fn uncreatable_file_is_named_in_the_error() {
        let dir = ScratchDir::new("mcap-writer");
        let path = dir.join("no/such/dir/x.mcap");
        let e = McapFile::create(&path).err().unwrap();
        assert!(e.to_string().contains("no/such/dir/x.mcap.partial"), "{e}");
    }
}
