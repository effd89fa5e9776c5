//! MCAP chunks compressed with zstd (rosbag2's default), decoded by the
//! pure-Rust `ruzstd` for the `mcap` reader.

use mcap::McapError;
use mcap::sans_io::decompressor::{DecompressResult, Decompressor};
use std::io::Read;

/// A [`Decompressor`] for `zstd` chunks: it asks for the whole compressed
/// chunk, decodes all of its frames at once and hands the bytes out as the
/// reader asks for them.
#[derive(Debug, Default)]
pub struct ZstdChunks {
    decoded: Option<Vec<u8>>,
    served: usize,
}

impl Decompressor for ZstdChunks {
    fn next_read_size(&self) -> usize {
        // the reader caps this at the chunk's compressed size
        if self.decoded.is_none() {
            usize::MAX
        } else {
            0
        }
    }

    fn decompress(&mut self, src: &[u8], dst: &mut [u8]) -> mcap::McapResult<DecompressResult> {
        let mut consumed = 0;
        if self.decoded.is_none() {
            let mut output = Vec::new();
            let mut rest = src;
            while !rest.is_empty() {
                let mut frame = ruzstd::decoding::StreamingDecoder::new(&mut rest)
                    .map_err(|e| McapError::DecompressionError(format!("zstd: {e}")))?;
                frame
                    .read_to_end(&mut output)
                    .map_err(|e| McapError::DecompressionError(format!("zstd: {e}")))?;
            }
            self.decoded = Some(output);
            consumed = src.len();
        }
        let decoded = self.decoded.as_deref().unwrap_or_default();
        let wrote = dst.len().min(decoded.len() - self.served);
        dst[..wrote].copy_from_slice(&decoded[self.served..self.served + wrote]);
        self.served += wrote;
        Ok(DecompressResult { consumed, wrote })
    }

    fn reset(&mut self) -> mcap::McapResult<()> {
        *self = ZstdChunks::default();
        Ok(())
    }

    fn name(&self) -> &'static str {
        "zstd"
    }
}
