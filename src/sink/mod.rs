//! Stage 5b, write: the container writers behind one [`Sink`] trait, and the JSON documents
//! beside them.
//!
//! `exec` drives every sink the same way and in the same order: image frames episode by episode
//! (already encoded the way the sink asked, in parallel, once per rate and encoding), then every
//! low-dimensional channel whole, then the window index, then `finish`.
//!
//! - `hdf5` (+ `hdf5_chunks`): chunkc's own HDF5 layouts `index`, `materialized`, `virtual`;
//!   `hdf5_jpeg` and `hdf5_video` store its frames as `image_compression = "jpeg"` / `"video"`.
//! - `jpeg`: the JPEG encoding of frames (libjpeg-turbo) that `hdf5_jpeg` stores.
//! - `zarr` (+ `zarr_store`): a Diffusion Policy replay buffer (raw values) + the window index.
//! - `act_episodes`: ACT's `episode_<i>.hdf5` files (raw values).
//! - `hdf5_native`: the writer path `act_episodes` and `robomimic` share.
//! - `hdf5_rows`: rows written into an HDF5 dataset (every HDF5 writer).
//! - `lerobot`: a LeRobot v3.0 parquet dataset + the window index (raw values); its arrow
//!   columns (`lerobot_columns`), the rows of a data file (`lerobot_rows`), `info.json`'s
//!   features (`lerobot_features`), how its files are written (`lerobot_files`), the frames
//!   spilled until their row groups (`lerobot_spill`) and its tasks (`lerobot_tasks`).
//! - `lerobot_v21`: a LeRobot v2.1 dataset (`lerobot_version = "v2.1"`): a parquet file and a
//!   video per episode, the validation episodes a second dataset in `val/`; its layout and
//!   `meta/` files (`lerobot_v21_meta`), its per-episode statistics (`lerobot_episode_stats`),
//!   its data files and their statistics written side by side (`lerobot_v21_data`).
//! - `groot`: GR00T's files of a `groot` profile's v2.1 datasets (`meta/modality.json`, its
//!   `meta/stats.json` and `meta/relative_stats.json`).
//! - `lerobot_cameras`: how either LeRobot export encodes (or copies) a camera's video;
//!   `lerobot_v3_videos`: v3.0's video files (one of every episode, or one per episode).
//! - `png`: the PNG encoding of frames that `lerobot` stores.
//! - `video_copy`: a source video's packets copied as an episode's file (`hdf5_video`), where
//!   the frames are the video's own.
//! - `video_episodes`: one video per episode and camera, copied or encoded (`hdf5_video`, the
//!   LeRobot v2.1 export).
//! - `video_info`: the codec and pixel format of an mp4 written (LeRobot's `info` block).
//! - `video_encode`: camera frames as mp4 video (SVT-AV1/x264), what `lerobot` stores with
//!   `image_encoding = "video"` and `chunkc synth --format lerobot` writes.
//! - `robomimic`: robomimic's `data.hdf5` with `data/demo_<i>` (raw values).
//! - `documents`: `meta.json` and `stats.json`.
//! - `shapes`: a channel's per-step shape in the documents (normalization tables, statistics).
//! - `meta_sources`: a training mixture's fields of `meta.json` (each episode's source, the
//!   sampling probabilities, each source's split, widths and normalization).
//! - `encoder_record`: the frame encoder (library, version, settings) `chunkc.lock` records.
//! - `frames`: one episode's frames of a camera as a sink takes them, in the encoding it asked
//!   for, with the video packets they are the decode of.
//! - `dump`: canonical text dumps of written files (golden tests).

pub mod act_episodes;
pub mod documents;
pub mod dump;
pub mod encoder_record;
mod frames;
mod groot;
pub mod hdf5;
mod hdf5_chunks;
mod hdf5_jpeg;
mod hdf5_lossy;
mod hdf5_native;
mod hdf5_rows;
pub mod hdf5_video;
pub mod jpeg;
pub mod lerobot;
mod lerobot_cameras;
mod lerobot_columns;
mod lerobot_episode_stats;
mod lerobot_features;
mod lerobot_files;
mod lerobot_rows;
mod lerobot_spill;
mod lerobot_tasks;
pub mod lerobot_v21;
mod lerobot_v21_data;
pub mod lerobot_v21_meta;
pub mod lerobot_v3_videos;
mod meta_sources;
pub mod png;
pub mod robomimic;
mod shapes;
mod source_marks;
pub mod video_copy;
pub mod video_encode;
mod video_episodes;
pub mod video_info;
pub mod zarr;
mod zarr_store;

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use frames::{encode_frame, FrameEncoding, Frames};

use crate::error::Result;
use crate::plan::ProfilePlan;
use crate::spec::OutputFormat;
use crate::stats::normalize::RowNormalizer;
use crate::store::LowdimStore;

/// What a sink needs to lay out its container.
pub struct SinkContext<'a> {
    pub profile: &'a ProfilePlan,
    /// The profile's staging directory.
    pub dir: &'a Path,
    /// A directory for the sink's temporary files (removed with the staging directory); the
    /// sink names its files after the profile.
    pub scratch: &'a Path,
    /// Exclusive ends of each episode in the stored per-step arrays.
    pub episode_ends: &'a [u64],
    /// Source episode ids, in stored order.
    pub episode_ids: &'a [u64],
    /// A training mixture's: each stored episode's source (its index); empty for one source.
    pub episode_sources: &'a [usize],
    /// A training mixture's sources, in mixture order; empty for one source.
    pub source_parts: &'a [crate::source::SourcePart],
    /// Each episode's task (a language instruction), by source id; episodes without one are
    /// absent (the LeRobot export gives them its default task).
    pub tasks: &'a BTreeMap<u64, String>,
    /// The row store's memory budget, decided by exec (`CHUNKC_SPILL_BYTES`); a sink that
    /// buffers rows of its own keeps within it too.
    pub spill_budget: usize,
}

impl SinkContext<'_> {
    /// Values a stored row of channel `c` holds, on average over the stored rows: the channel's
    /// width, or, for a training mixture's padded channel, its sources' own widths weighted by
    /// their rows (padding is not values). Chunks are sized by it.
    pub fn values_per_row(&self, c: usize) -> usize {
        let width = self.profile.channels[c]
            .shape
            .iter()
            .product::<usize>()
            .max(1);
        let (mut rows, mut values, mut start) = (0u64, 0u64, 0u64);
        for (&end, &s) in self.episode_ends.iter().zip(self.episode_sources) {
            let own = self.source_parts.get(s).map_or(width, |p| p.widths[c]);
            (rows, values) = (rows + end - start, values + (end - start) * own as u64);
            start = end;
        }
        match rows {
            0 => width,
            _ => (values.div_ceil(rows) as usize).clamp(1, width),
        }
    }
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
    /// Whether [`Sink::write_frames`] will store these frames of image channel `channel` as a
    /// copy of their video packets, reading none of their pixels (a sharded build's partial then
    /// leaves the pixels behind). Reads the packets to check them; false by default.
    fn copies_frames(&self, channel: usize, frames: &Frames) -> Result<bool> {
        let _ = (channel, frames);
        Ok(false)
    }
    /// Encoded frames of image channel `channel` for one episode, from stored row `row`.
    fn write_frames(&mut self, channel: usize, row: usize, frames: &Frames) -> Result<()>;
    /// A whole low-dimensional channel in raw units, and the profile's normalizer for it: the
    /// sink decides whether it stores normalized or raw values. The store may be on disk: read it
    /// a block of rows at a time, and keep the `Arc` (not a copy) to read it again in `finish`.
    fn write_lowdim(
        &mut self,
        channel: usize,
        raw: &Arc<LowdimStore>,
        normalizer: &RowNormalizer,
    ) -> Result<()>;
    /// The window index of both splits: rows of (episode position, t, limit, sub), read a block
    /// at a time (or whole, by sinks that need it whole).
    fn write_index(&mut self, index: &dyn WindowIndex) -> Result<()>;
    /// Completes the container, and says what only its writing could know.
    fn finish(self: Box<Self>) -> Result<Finished>;
}

/// What a sink found out while writing, for the documents beside the container.
#[derive(Debug, Default)]
pub struct Finished {
    /// Per camera stored as one video per episode (chunkc's HDF5 `image_compression =
    /// "video"`), what its files hold.
    pub videos: BTreeMap<String, video_info::StoredVideo>,
    /// The BLAKE3 of files the sink took from the bytes as it wrote them, by path: the build
    /// records these in the lock without reading the files back.
    pub written: HashMap<PathBuf, blake3::Hash>,
}

/// Which split of the window index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Split {
    Train,
    Val,
}

/// The window index of a profile, produced on demand so that it need not be in memory whole.
pub trait WindowIndex: Sync {
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
        OutputFormat::Parquet if ctx.profile.writes_lerobot_v21() => {
            Ok(Box::new(lerobot_v21::LerobotV21Writer::create(ctx)?))
        }
        OutputFormat::Parquet => Ok(Box::new(lerobot::LerobotWriter::create(ctx)?)),
        OutputFormat::RobomimicHdf5 => Ok(Box::new(robomimic::RobomimicWriter::create(ctx)?)),
    }
}
