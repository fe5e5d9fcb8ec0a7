//! A shard's partial: what the parallel part of the read produced for each of its episodes (the
//! converted low-dim rows, the frames in every encoding the sinks asked for, the statistics
//! partials), in episode order, so that `chunkc merge` can run the sequential part of the same
//! pass (statistics merged in episode order, rows stored, frames written) as if it had read the
//! source itself. Nothing is reduced in a shard that the merge could not redo in the same order,
//! which is why the merged outputs are the single-machine build's bytes.
//!
//! The file: `CHUNKCP1`, a length-prefixed JSON header ([`Header`]: tool version, plan id, shard,
//! episode range), one record per episode, then `END!` and the BLAKE3 of everything before it.
//! Written to a temporary name and renamed, so a shard killed mid-run leaves no partial; the merge
//! checks every checksum before it writes anything. Numbers are little-endian; `f64`/`f32` keep
//! their exact bits. Uncompressed frames that every sink copies from their video packets are
//! written without their pixels (their ends and where the packets are: the merge copies the
//! packets from the source), so a copied camera's partial is not the size of its decoded frames.
//!
//! The format is here; `write` writes it, `read` checks and reads it back.

mod read;
#[cfg(test)]
mod tests;
mod write;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::process::Processed;
use crate::sink::FrameEncoding;

pub use read::verify;
pub(in crate::exec) use read::Reader;
pub(in crate::exec) use write::Writer;

const MAGIC: &[u8; 8] = b"CHUNKCP1";
const TRAILER: &[u8; 4] = b"END!";
/// Bumped when the record layout changes: a merge never reads a partial of another layout.
pub const PARTIAL_FORMAT: u32 = 3;

/// The partial file of shard `index` of `count` in `dir`.
pub fn path_of(dir: &Path, index: usize, count: usize) -> PathBuf {
    dir.join(format!("shard-{index:05}-of-{count:05}.partial"))
}

/// What a partial says of itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    pub format: u32,
    pub tool_version: String,
    /// [`crate::plan::shards::plan_id`] of the plan the shard followed.
    pub plan: String,
    pub shard: usize,
    pub shards: usize,
    /// Episode positions (audited manifest order) the records cover.
    pub episodes: [usize; 2],
}

/// One episode's record.
pub(in crate::exec) enum Record {
    Kept(Processed),
    /// Left out by `[audit] non_finite = "exclude_episode"`, with the reason.
    Excluded(String),
    /// Checked, not kept: an earlier episode of the shard was excluded.
    Checked,
}

/// The kind code of uncompressed frames written without their pixels.
const PIXELLESS: u8 = 4;

fn encoding_code(e: FrameEncoding) -> (u8, u8) {
    match e {
        FrameEncoding::Raw => (0, 0),
        FrameEncoding::Zlib(level) => (1, level),
        FrameEncoding::Png => (2, 0),
        FrameEncoding::Jpeg(quality) => (3, quality),
    }
}

fn encoding_of(kind: u8, level: u8) -> Option<FrameEncoding> {
    match kind {
        0 => Some(FrameEncoding::Raw),
        1 => Some(FrameEncoding::Zlib(level)),
        2 => Some(FrameEncoding::Png),
        3 => Some(FrameEncoding::Jpeg(level)),
        _ => None,
    }
}
