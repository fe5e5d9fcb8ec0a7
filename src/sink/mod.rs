//! Stage 5b, write: the container writers behind one [`Sink`] trait, and the JSON documents
//! beside them.
//!
//! `exec` drives every sink the same way and in the same order: image frames episode by episode
//! (already encoded the way the sink asked, in parallel, once per rate and encoding), then every
//! low-dimensional channel whole, then the window index, then `finish`.
//!
//! - `hdf5` (+ `hdf5_chunks`): chunkc's own HDF5 layouts `index`, `materialized`, `virtual`.
//! - `zarr`: a Diffusion Policy replay buffer (raw values) + the window index.
//! - `windows`: the rows of one window, as the loader resolves them.
//! - `act_episodes`: ACT's `episode_<i>.hdf5` files (raw values).
//! - `lerobot`: a LeRobot v3.0 parquet dataset + the window index (raw values).
//! - `robomimic`: robomimic's `data.hdf5` with `data/demo_<i>` (raw values).
//! - `documents`: `meta.json` and `stats.json`.
//! - `dump`: canonical text dumps of written files (golden tests).

pub mod act_episodes;
pub mod documents;
pub mod dump;
pub mod hdf5;
mod hdf5_chunks;
pub mod lerobot;
pub mod robomimic;
pub mod windows;
pub mod zarr;

use std::path::Path;
use std::sync::Arc;

use crate::error::Result;
use crate::exec::LowdimStore;
use crate::plan::ProfilePlan;
use crate::spec::OutputFormat;
use crate::stats::normalize::Normalizer;

/// How a sink wants image frames handed to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum FrameEncoding {
    /// The frame's bytes as they are (HWC `u8`).
    Raw,
    /// A zlib stream at this level: what HDF5's deflate filter stores as a chunk.
    Zlib(u8),
}

/// Encodes one HWC `u8` frame.
pub fn encode_frame(encoding: FrameEncoding, frame: &[u8]) -> Vec<u8> {
    match encoding {
        FrameEncoding::Raw => frame.to_vec(),
        FrameEncoding::Zlib(level) => {
            use std::io::Write;
            let mut enc = flate2::write::ZlibEncoder::new(
                Vec::with_capacity(frame.len() / 2),
                flate2::Compression::new(u32::from(level)),
            );
            enc.write_all(frame).expect("writing to a Vec cannot fail");
            enc.finish().expect("writing to a Vec cannot fail")
        }
    }
}

/// What a sink needs to lay out its container.
pub struct SinkContext<'a> {
    pub profile: &'a ProfilePlan,
    /// The profile's staging directory.
    pub dir: &'a Path,
    /// Exclusive ends of each episode in the stored per-step arrays.
    pub episode_ends: &'a [u64],
    /// Source episode ids, in stored order.
    pub episode_ids: &'a [u64],
}

/// One output container being written.
pub trait Sink: Send {
    /// The file `meta.json` names as the data (relative to the profile directory).
    fn data_file(&self) -> &str;
    fn frame_encoding(&self) -> FrameEncoding;
    /// Whether low-dimensional values are stored normalized (`meta.json` `stored_values`).
    fn stores_normalized(&self) -> bool {
        true
    }
    /// Encoded frames of image channel `channel` for one episode, from stored row `row`.
    fn write_frames(&mut self, channel: usize, row: usize, frames: &[Vec<u8>]) -> Result<()>;
    /// A whole low-dimensional channel in raw units, and the profile's normalizer for it: the
    /// sink decides whether it stores normalized or raw values. The store may be on disk: read it
    /// a block of rows at a time, and keep the `Arc` (not a copy) to read it again in `finish`.
    fn write_lowdim(
        &mut self,
        channel: usize,
        raw: &Arc<LowdimStore>,
        normalizer: &Normalizer,
    ) -> Result<()>;
    /// The window index of both splits: rows of (episode position, t, limit, sub), read a block
    /// at a time (or whole, by sinks that need it whole).
    fn write_index(&mut self, index: &dyn WindowIndex) -> Result<()>;
    /// Completes the container.
    fn finish(self: Box<Self>) -> Result<()>;
}

/// Which split of the window index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Split {
    Train,
    Val,
}

/// The window index of a profile, produced on demand so that it need not be in memory whole.
pub trait WindowIndex {
    /// Number of rows of `split`.
    fn count(&self, split: Split) -> usize;
    /// Rows `lo..hi` of `split`: (episode position, t, limit, sub).
    fn rows(&self, split: Split, lo: usize, hi: usize) -> Result<Vec<[i64; 4]>>;
    /// Every row of `split`.
    fn all(&self, split: Split) -> Result<Vec<[i64; 4]>> {
        self.rows(split, 0, self.count(split))
    }
}

/// A window index already in memory: (train rows, val rows).
impl WindowIndex for (&[[i64; 4]], &[[i64; 4]]) {
    fn count(&self, split: Split) -> usize {
        match split {
            Split::Train => self.0.len(),
            Split::Val => self.1.len(),
        }
    }
    fn rows(&self, split: Split, lo: usize, hi: usize) -> Result<Vec<[i64; 4]>> {
        let rows = match split {
            Split::Train => self.0,
            Split::Val => self.1,
        };
        Ok(rows[lo..hi].to_vec())
    }
}

/// The sink for a profile's output format.
pub fn create(ctx: &SinkContext) -> Result<Box<dyn Sink>> {
    match ctx.profile.values.format {
        OutputFormat::Hdf5 => Ok(Box::new(hdf5::Hdf5Writer::create(ctx)?)),
        OutputFormat::Zarr => Ok(Box::new(zarr::ZarrWriter::create(ctx)?)),
        OutputFormat::ActEpisodes => Ok(Box::new(act_episodes::ActEpisodesWriter::create(ctx)?)),
        OutputFormat::Parquet => Ok(Box::new(lerobot::LerobotWriter::create(ctx)?)),
        OutputFormat::RobomimicHdf5 => Ok(Box::new(robomimic::RobomimicWriter::create(ctx)?)),
    }
}
