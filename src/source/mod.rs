//! Stage 2, open: one adapter per on-disk layout, all behind the same [`Source`] trait.
//!
//! Everything downstream sees one model: a [`Manifest`] (cheap metadata, known before any data is
//! read) and [`Episode`]s read one at a time. Low-dimensional channels arrive as `f32`, images as
//! `u8` (HWC); the time axis is always first.
//!
//! Adapters, one per `[source] format`:
//! - `dp_zarr`: Diffusion Policy zarr ReplayBuffer (`data/<key>`, `meta/episode_ends`).
//! - `aloha`: ACT / ALOHA, one `episode_<i>.hdf5` per episode, raw or JPEG-compressed images.
//! - `robomimic`: robomimic `data/demo_<i>` groups, and robosuite's older files of that shape.
//! - `lerobot`: LeRobot v2.1 (one parquet per episode) and v3.0 (many per file).
//! - `rlds`: RLDS / Open X-Embodiment, TFDS-prepared TFRecord shards, read without TensorFlow.
//!
//! Shared pieces:
//! - `check`: what every episode must satisfy (lengths, finite values, increasing timestamps).
//! - `mapping`: `[source.channels]` (rename, column slices, concatenation, kind) resolved
//!   against the keys a source offers, and applied to the arrays read.
//! - `h5`: HDF5 reading helpers (key listing, typed reads, clear errors, reads without HDF5).
//! - `h5meta`: where contiguous datasets lie, read from a file's metadata without the HDF5
//!   library (so that the headers of many episode files are read in parallel).
//! - `block_cache`: decoded blocks (a *block* is a storage chunk of a source file: zarr or HDF5
//!   chunk, parquet row group) shared by the episodes that overlap them (each block decoded at
//!   most once per build), and the decode counts the build reports.
//! - `block_map`: where a chunked, unfiltered HDF5 dataset's blocks lie in its file (read and
//!   written with `pread`/`pwrite`, outside HDF5's lock; the HDF5 writer uses it too).
//! - `jpeg`: decoding JPEG frames.
//! - `video`: camera videos (demux, LeRobot's frame selection, decode to RGB as PyAV does),
//!   behind the `video` cargo feature.
//! - `parquet_read`: parquet columns (scalars, fixed- and variable-size lists) as rows of numbers.
//! - `subset`: `[source] episodes = […]`, a view of some episodes of any source.
//! - `fingerprint`: the content hash that tells the plan whether a source changed (`later`: hashed
//!   as the build reads, or beside it, not before it).
//! - `zarr_read_store`: the store a zarr source is read through, hashing each file it reads.
//! - `detect`: which layout a path holds, and the keys a source offers before any is mapped
//!   (`chunkc init`, `chunkc inspect`).

mod aloha;
pub mod block_cache;
pub mod block_map;
pub mod check;
pub mod detect;
mod dp_zarr;
pub mod fingerprint;
mod h5;
mod h5meta;
mod jpeg;
mod lerobot;
pub mod mapping;
mod parquet_read;
mod parts;
pub mod rlds;
mod robomimic;
mod subset;
pub mod video;
mod zarr_read_store;

pub use block_cache::DecodeCounts;
pub use lerobot::Info as LerobotInfo;
pub use parts::SourcePart;
pub use subset::Subset;
pub use video::VideoCheck;

use std::collections::BTreeMap;

use serde::Serialize;

use crate::error::{Error, Result};
use crate::spec::{LoadedSpec, SourceFormat};

/// What a channel holds, decided from its per-step rank: vectors are low-dimensional, arrays of
/// rank 3 (H, W, C) are images.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ChannelKind {
    Lowdim,
    Image,
}

/// A channel as the manifest describes it.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelInfo {
    /// Our name (`action`, `observation.state`).
    pub name: String,
    /// The key in the source.
    pub key: String,
    pub kind: ChannelKind,
    /// Per-step shape (everything after the time axis).
    pub shape: Vec<usize>,
    /// The source's element type, as the source names it.
    pub source_dtype: String,
}

impl ChannelInfo {
    /// Number of values per step.
    pub fn width(&self) -> usize {
        self.shape.iter().product()
    }
}

/// One episode's place in the source.
#[derive(Debug, Clone, Serialize)]
pub struct EpisodeInfo {
    /// The source's own id (the episode number in the source's naming).
    pub id: u64,
    pub len: usize,
}

/// Metadata of a whole source: known before any per-step data is read.
#[derive(Debug, Clone, Serialize)]
pub struct Manifest {
    pub format: SourceFormat,
    /// The source's recording rate in Hz.
    pub fps: f64,
    pub episodes: Vec<EpisodeInfo>,
    /// In the spec's (sorted) channel order; `action` is among them.
    pub channels: Vec<ChannelInfo>,
    /// BLAKE3 over the bytes of everything the adapter reads, with the BLAKE3 of each file it
    /// covers, by path in the source (the lock keeps them, so that a changed source names the
    /// file). Known at open, or completed from the pass's reads when first asked for.
    pub fingerprint: fingerprint::SourcePrint,
    /// Whether episodes carry timestamps read from the source.
    pub timestamps: bool,
    /// The split the source itself stores, if any (used with `[split] from = "source"`).
    pub source_split: Option<SourceSplit>,
    /// Things the user should know that do not stop the build (gaps in ids, skipped keys).
    pub warnings: Vec<String>,
    /// Each episode's task (RLDS: its language instruction), by source id; empty for sources
    /// that store none. Written where the outputs keep tasks (`meta.json`, the dataset card).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub tasks: BTreeMap<u64, String>,
    /// The sources of a training mixture, in index order (empty for one source). Episode ids
    /// are then the mixture's: a part's own id plus its `id_offset`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub parts: Vec<SourcePart>,
}

impl Manifest {
    /// What every adapter's opening ends with: the manifest of one source, its episodes, the
    /// channels `mapped` resolved and the fingerprint of the files read, with no timestamps,
    /// stored split or tasks (an adapter that has them sets them).
    pub fn one_source(
        format: SourceFormat,
        fps: f64,
        episodes: Vec<EpisodeInfo>,
        mapped: &mapping::Mapped,
        fingerprint: impl Into<fingerprint::SourcePrint>,
        warnings: Vec<String>,
    ) -> Manifest {
        Manifest {
            format,
            fps,
            episodes,
            channels: mapped.channels.clone(),
            fingerprint: fingerprint.into(),
            timestamps: false,
            source_split: None,
            warnings,
            tasks: BTreeMap::new(),
            parts: Vec::new(),
        }
    }
}

/// A train/validation split stored in the source, by source episode id.
#[derive(Debug, Clone, Serialize)]
pub struct SourceSplit {
    /// Where it was read from (`mask/train, mask/valid`).
    pub origin: String,
    pub train: Vec<u64>,
    pub val: Vec<u64>,
}

/// One channel's values for one episode, time-major and row-major.
#[derive(Debug, Clone)]
pub enum ChannelData {
    Lowdim(Vec<f32>),
    Image(Vec<u8>),
}

/// One episode's data, channels in manifest order.
#[derive(Debug, Clone)]
pub struct Episode {
    pub id: u64,
    pub len: usize,
    /// Seconds per step, when the source stores them (LeRobot `timestamp`, robosuite sim time).
    pub timestamps: Option<Vec<f64>>,
    pub channels: Vec<ChannelData>,
    /// Per image channel (manifest position) whose frames are a video file's own frames one per
    /// row: which ones. Only sources that decode video fill it; whatever changes the rows (a
    /// repair, a resample, a resize) must not pass it on.
    pub packets: BTreeMap<usize, video::PacketSpan>,
}

impl Episode {
    /// The low-dimensional values of the channels at `channels` (manifest positions), taken out
    /// of the episode; an image channel gives an empty vector.
    pub fn take_lowdim(mut self, channels: &[usize]) -> Vec<Vec<f32>> {
        channels
            .iter()
            .map(|&c| {
                match std::mem::replace(&mut self.channels[c], ChannelData::Image(Vec::new())) {
                    ChannelData::Lowdim(v) => v,
                    ChannelData::Image(_) => Vec::new(),
                }
            })
            .collect()
    }
}

/// A dataset on disk, opened. Implementations must be safe to read from several threads.
pub trait Source: Send + Sync {
    fn manifest(&self) -> &Manifest;
    /// Reads the episode at position `index` of `manifest().episodes`.
    fn read_episode(&self, index: usize) -> Result<Episode>;
    /// The episode at `index` as a build reads it: its low-dim channels at the width
    /// [`Manifest::own_width`] gives, not padded. Only a source whose manifest has `parts` (a
    /// training mixture) pads, and it overrides this; every other source reads as
    /// [`Source::read_episode`] does. The build pads only what it writes.
    fn read_unpadded(&self, index: usize) -> Result<Episode> {
        self.read_episode(index)
    }
    /// The timestamps of the episode at `index`, `None` when the source stores none. The audit
    /// reads these for every episode before the build: adapters that can read them without the
    /// rest of the episode override this.
    fn read_timestamps(&self, index: usize) -> Result<Option<Vec<f64>>> {
        Ok(self.read_episode(index)?.timestamps)
    }
    /// The low-dimensional channels at `channels` (manifest positions) of the episode at `index`,
    /// time-major (the dataset doctor reads only these): adapters that read per key override it.
    fn read_lowdim(&self, index: usize, channels: &[usize]) -> Result<Vec<Vec<f32>>> {
        Ok(self.read_episode(index)?.take_lowdim(channels))
    }
    /// How many times each storage chunk was decoded so far (see [`block_cache`]); empty for
    /// sources that do not count.
    fn decode_counts(&self) -> DecodeCounts {
        DecodeCounts::new()
    }
    /// The episodes at `positions` (sorted, consecutive in storage) are about to be read side by
    /// side: adapters whose storage chunks span episodes decode those chunks now, in parallel,
    /// so that the readers find them ready. Never an error: a chunk that fails here fails again,
    /// with its episode named, when it is read.
    fn prefetch(&self, positions: &[usize]) {
        let _ = positions;
    }
    /// The checks of the episode at `index`'s camera videos, one per video channel (demuxed
    /// packet times against the rows; nothing decoded); empty for sources without video. An
    /// `Err` is a failure to read the source's metadata, not a bad video (that is a check's
    /// `problem`).
    fn video_checks(&self, index: usize) -> Result<Vec<VideoCheck>> {
        let _ = index;
        Ok(Vec::new())
    }
    /// Only the episodes at `positions` (sorted) will be read from now on: adapters that keep a
    /// decoded chunk until every episode overlapping it has been read count only these.
    fn only_reading(&mut self, positions: &[usize]) {
        let _ = positions;
    }
}

/// Opens the source a spec names.
pub fn open(spec: &LoadedSpec) -> Result<Box<dyn Source>> {
    let src = spec.source();
    let path = spec.resolve(&src.path);
    if !path.exists() {
        let message = match std::fs::read_link(&path) {
            Ok(target) => format!(
                "source path {} is a symlink to {}, which does not exist",
                path.display(),
                target.display()
            ),
            Err(_) => format!("source path {} does not exist", path.display()),
        };
        return Err(spec.error_at(&["source", "path"], message, None));
    }
    let source: Box<dyn Source> = match src.format {
        SourceFormat::DiffusionPolicyZarr => Box::new(dp_zarr::DpZarrSource::open(spec, &path)?),
        SourceFormat::AlohaHdf5 => Box::new(aloha::AlohaSource::open(spec, &path)?),
        SourceFormat::RobomimicHdf5 => Box::new(robomimic::RobomimicSource::open(spec, &path)?),
        SourceFormat::Lerobot => Box::new(lerobot::LerobotSource::open(spec, &path)?),
        SourceFormat::Rlds => Box::new(rlds::RldsSource::open(spec, &path)?),
    };
    match &src.episodes {
        Some(ids) => Ok(Box::new(subset::Subset::new(spec, source, ids)?)),
        None => Ok(source),
    }
}

/// The rate of a source that stores timestamps but no rate: one over the median interval,
/// rounded to a thousandth of a Hz (so 0.05 s steps give exactly 20 Hz).
pub fn fps_from_timestamps(episodes: &[Vec<f64>]) -> Option<f64> {
    let mut dts: Vec<f64> = episodes
        .iter()
        .flat_map(|t| t.windows(2).map(|w| w[1] - w[0]))
        .filter(|dt| dt.is_finite() && *dt > 0.0)
        .collect();
    if dts.is_empty() {
        return None;
    }
    dts.sort_by(f64::total_cmp);
    let median = dts[dts.len() / 2];
    Some((1000.0 / median).round() / 1000.0)
}

/// Decides a channel's kind from its per-step shape, or says why it cannot be used.
pub fn kind_for_shape(shape: &[usize]) -> std::result::Result<ChannelKind, String> {
    match shape.len() {
        0..=2 => Ok(ChannelKind::Lowdim),
        3 if shape[2] == 1 || shape[2] == 3 || shape[2] == 4 => Ok(ChannelKind::Image),
        _ => Err(format!(
            "per-step shape {shape:?} is neither a vector nor an (H, W, C) image"
        )),
    }
}

/// Converts image values that arrive as floats holding 0..255 (Push-T stores them so) to `u8`,
/// refusing anything that would not round-trip exactly.
pub fn image_to_u8(values: &[f32], what: impl Fn(usize) -> String) -> Result<Vec<u8>> {
    let mut out = Vec::with_capacity(values.len());
    for (i, &v) in values.iter().enumerate() {
        if !(0.0..=255.0).contains(&v) || v.fract() != 0.0 {
            return Err(Error::source(format!(
                "{}: image value {v} is not an integer in 0..=255",
                what(i)
            )));
        }
        out.push(v as u8);
    }
    Ok(out)
}
