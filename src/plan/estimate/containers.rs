//! The data container of each output format: an upper bound of its bytes, as a sum over what it
//! holds, each part at its largest (a partly filled last chunk allocated whole, compression
//! that gains nothing and adds its headers), plus each container's own overheads. Frames stored
//! lossily (JPEG, video) cannot be bounded before they are encoded: their parts are estimates
//! ([`Frames`]), and a container holding them is labelled an estimate.

use crate::plan::{PlannedFile, ProfilePlan};
use crate::source::ChannelKind;
use crate::spec::{Compression, ImageCompression, ImageEncoding, Layout, OutputFormat};

/// An HDF5 file's superblock, root group, groups and attributes.
const HDF5_FILE: u64 = 32 * 1024;
/// A dataset's object header, attributes and chunk index root.
const HDF5_DATASET: u64 = 4 * 1024;
/// One chunk's entry in its dataset's B-tree (version 1 nodes, allocated whole).
const HDF5_CHUNK: u64 = 128;
/// The largest low-dim chunk the HDF5 layouts allocate (`sink::hdf5`: 64 KiB): the last one,
/// partly filled, is allocated whole.
const HDF5_LOWDIM_CHUNK: u64 = 64 * 1024;
/// The largest chunk of a camera's JPEG bytes (`sink::hdf5_jpeg`: 1 MiB), and the smallest.
const JPEG_CHUNK: u64 = 1 << 20;
const JPEG_MIN_CHUNK: u64 = 16 << 10;
/// The largest low-dim chunk of the Zarr layout (`sink::zarr`: 256 KiB), padded whole.
const ZARR_LOWDIM_CHUNK: u64 = 256 * 1024;
/// A Zarr array's or group's metadata files.
const ZARR_ARRAY: u64 = 2 * 1024;
/// A compressed chunk's headers (Blosc's 16 bytes, zstd's frame).
const CODEC_HEADER: u64 = 64;
/// A Parquet file's footer and schema, and each page's header.
const PARQUET_FILE: u64 = 16 * 1024;
const PARQUET_PAGE: u64 = 96;
/// An mp4's container (`ftyp`, `moov` headers) and per frame its sample table entries.
pub const MP4_FILE: u64 = 1024;
pub const MP4_FRAME: u64 = 24;

/// Bytes of one stored frame of a camera.
fn frame(shape: &[usize]) -> u64 {
    shape.iter().product::<usize>() as u64
}

/// The worst a general-purpose compressor (deflate, LZF, Blosc, zstd) adds to `bytes` that it
/// cannot shrink: stored blocks and their headers.
fn incompressible(bytes: u64) -> u64 {
    bytes + bytes / 512 + CODEC_HEADER
}

/// A PNG of a frame of `shape` at its largest: every row's filter byte, deflate's stored blocks,
/// the chunks' headers.
fn png(shape: &[usize]) -> u64 {
    let rows = *shape.first().unwrap_or(&1) as u64;
    incompressible(frame(shape) + rows) + 256
}

/// Samples of both splits; with segments (counted by the data) at most one per step.
pub(super) fn samples(p: &ProfilePlan) -> u64 {
    match (p.num_samples.train, p.num_samples.val) {
        (Some(t), Some(v)) => (t + v) as u64,
        _ => p.steps as u64,
    }
}

/// What a container holds, summed: bytes, and how many datasets and chunks carry them.
#[derive(Default)]
struct Tally {
    bytes: u64,
    datasets: u64,
    chunks: u64,
    /// How the bytes that are estimates (lossy frames) were estimated: with any, the total is
    /// not a bound.
    estimated: Vec<String>,
}

impl Tally {
    fn add(&mut self, bytes: u64, datasets: u64, chunks: u64) {
        self.bytes += bytes;
        self.datasets += datasets;
        self.chunks += chunks;
    }

    fn hdf5(&self) -> u64 {
        HDF5_FILE + self.bytes + self.datasets * HDF5_DATASET + self.chunks * HDF5_CHUNK
    }
}

/// `rows` of `row` bytes in chunks of about `chunk` bytes, the last one allocated whole:
/// (bytes, chunks).
fn chunked(rows: u64, row: u64, chunk: u64, compression: Compression) -> (u64, u64) {
    let per_chunk = (chunk / row.max(1)).clamp(1, rows.max(1));
    let chunks = rows.div_ceil(per_chunk).max(1);
    let bytes = chunks * per_chunk * row;
    match compression {
        Compression::None => (bytes, chunks),
        _ => (incompressible(bytes) + chunks * CODEC_HEADER, chunks),
    }
}

/// The bytes of a camera's lossily stored frames (see `super::Lossy`).
pub(super) trait Frames {
    /// Bytes of `frames` frames of `channel` (JPEG) or of its video stream.
    fn lossy(&self, channel: &str, frames: u64) -> u64;
    /// How they are estimated.
    fn basis(&self, channel: &str) -> String;
}

/// chunkc's HDF5 layouts (`data.h5`): per-step arrays, the window index and the episode table.
fn hdf5(p: &ProfilePlan, frames: &dyn Frames) -> Tally {
    let v = &p.values;
    let (steps, episodes) = (p.steps as u64, p.episodes.len() as u64);
    let mut t = Tally::default();
    for ch in &p.channels {
        let row = frame(&ch.shape);
        match ch.kind {
            ChannelKind::Lowdim => {
                let (bytes, chunks) = chunked(steps, 4 * row, HDF5_LOWDIM_CHUNK, v.compression);
                t.add(bytes, 1, chunks);
            }
            ChannelKind::Image => match v.image_compression {
                ImageCompression::None => t.add(steps * row, 1, steps),
                ImageCompression::Gzip => t.add(steps * incompressible(row), 1, steps),
                ImageCompression::Jpeg => {
                    // An estimate: the frames' bytes, and half the last chunk.
                    let bytes = frames.lossy(&ch.name, steps);
                    let chunk = (steps * row / 10).clamp(JPEG_MIN_CHUNK, JPEG_CHUNK);
                    t.add(bytes + chunk / 2 + 8 * steps, 2, bytes / JPEG_MIN_CHUNK + 2);
                    t.estimated.push(frames.basis(&ch.name));
                }
                // `/videos/<camera>/{path, frames, copied}`; the files are listed apart.
                ImageCompression::Video => t.add(128 * episodes, 3, 0),
            },
        }
    }
    let samples = samples(p);
    t.add(16 * episodes + 32 * samples, 4, 0);
    let (bytes, datasets) = chunks(p, samples);
    // `/chunks` datasets hold chunks of about 64 KiB (a few rows when rows are larger).
    t.add(bytes, datasets, bytes / (16 * 1024) + datasets);
    t
}

/// `/chunks` of the `materialized` and `virtual` layouts: K (or obs_history) rows per window
/// (64 KiB chunks), or the virtual mappings and the pad rows they point at. Returns (bytes,
/// datasets).
fn chunks(p: &ProfilePlan, windows: u64) -> (u64, u64) {
    let v = &p.values;
    let (k, h) = (u64::from(v.chunk), u64::from(v.obs_history));
    let lowdim = || p.channels.iter().filter(|c| c.kind == ChannelKind::Lowdim);
    match v.layout {
        Layout::Index => (0, 0),
        Layout::Materialized => {
            let bytes = lowdim()
                .map(|c| {
                    let steps = if c.name == "action" { k } else { h };
                    let row = steps * 4 * frame(&c.shape);
                    let values = chunked(windows, row, HDF5_LOWDIM_CHUNK, v.compression);
                    let pads = chunked(windows, steps, HDF5_LOWDIM_CHUNK, v.compression);
                    values.0 + pads.0
                })
                .sum();
            (bytes, 2 * lowdim().count() as u64)
        }
        Layout::Virtual => {
            let action = p.channels.iter().find(|c| c.name == "action");
            let row = 4 * action.map_or(1, |c| frame(&c.shape));
            let episodes = p.episodes.len() as u64;
            // Pad rows: at most K per window, and only in the last K windows of an episode
            // and the first obs_history; the mappings: 2 x 2 x K selections of row blocks.
            let pad_rows = (windows * k).min(episodes * k * (k + h));
            let bytes = pad_rows * row + windows * k + 4 * k * (512 + 64 * episodes);
            (bytes, 3)
        }
    }
}

/// The Zarr replay buffer (`data.zarr/`): raw per-step arrays, one frame per chunk.
fn zarr(p: &ProfilePlan) -> u64 {
    let v = &p.values;
    let steps = p.steps as u64;
    let mut bytes = 4 * ZARR_ARRAY;
    for ch in &p.channels {
        let row = frame(&ch.shape);
        bytes += ZARR_ARRAY
            + match ch.kind {
                ChannelKind::Lowdim => chunked(steps, 4 * row, ZARR_LOWDIM_CHUNK, v.compression).0,
                ChannelKind::Image => steps * (incompressible(row) + CODEC_HEADER),
            };
    }
    let whole = |b: u64| ZARR_ARRAY + incompressible(b) + CODEC_HEADER;
    let episodes = p.episodes.len() as u64;
    bytes + 2 * whole(8 * episodes) + 2 * whole(32 * samples(p))
}

/// LeRobot v3.0's data file (`data/`): a row per step (low-dim lists, PNG frames, the index
/// columns), a row group per episode.
fn parquet(p: &ProfilePlan) -> u64 {
    let video = p.values.image_encoding == Some(ImageEncoding::Video);
    let steps = p.steps as u64;
    let mut row = 4 * 8 + 4;
    let mut columns = 5;
    for ch in &p.channels {
        match ch.kind {
            ChannelKind::Lowdim => {
                row += 4 * frame(&ch.shape) + 2;
                columns += 1;
            }
            ChannelKind::Image if video => {}
            ChannelKind::Image => {
                row += png(&ch.shape) + 8;
                columns += 2;
            }
        }
    }
    let episodes = p.episodes.len() as u64;
    let pages = columns * episodes + incompressible(steps * row) / (1 << 20);
    PARQUET_FILE + incompressible(steps * row) + pages * (PARQUET_PAGE + 2 * CODEC_HEADER + 256)
}

/// ACT's episode files (`episode_*.hdf5`): raw float32 arrays, `qvel` (zeros when no channel is
/// exported as it), frames one per chunk.
fn act_episodes(p: &ProfilePlan) -> u64 {
    let mut t = Tally::default();
    let widest = p
        .channels
        .iter()
        .filter(|c| c.kind == ChannelKind::Lowdim)
        .map(|c| frame(&c.shape))
        .max()
        .unwrap_or(0);
    for e in &p.episodes {
        let steps = e.len as u64;
        let mut file = Tally::default();
        for ch in &p.channels {
            match ch.kind {
                ChannelKind::Lowdim => file.add(4 * steps * frame(&ch.shape), 1, 0),
                ChannelKind::Image => file.add(steps * frame(&ch.shape), 1, steps),
            }
        }
        file.add(4 * steps * widest, 1, 0);
        t.bytes += file.hdf5();
    }
    t.bytes
}

/// robomimic's `data.hdf5`: per demo float64 actions, `obs` and `next_obs` (frames twice),
/// `dones` and `rewards`, and the split masks.
fn robomimic(p: &ProfilePlan) -> u64 {
    let mut t = Tally::default();
    for e in &p.episodes {
        let steps = e.len as u64;
        // The demo's groups (demo, obs, next_obs) and attributes.
        t.add(9 * steps, 3 + 2, 0);
        for ch in &p.channels {
            let copies = if ch.name == "action" { 1 } else { 2 };
            match ch.kind {
                ChannelKind::Lowdim => t.add(copies * 8 * steps * frame(&ch.shape), copies, 0),
                ChannelKind::Image => {
                    t.add(copies * steps * frame(&ch.shape), copies, copies * steps)
                }
            }
        }
    }
    t.add(64 * p.episodes.len() as u64, 2, 0);
    t.hdf5()
}

/// The data container's path as `chunkc plan` lists it, and its size.
pub(super) fn data(p: &ProfilePlan, frames: &dyn Frames) -> PlannedFile {
    let path = p.values.format.files().planned.to_string();
    let (bytes, estimated) = match p.values.format {
        OutputFormat::Hdf5 => {
            let t = hdf5(p, frames);
            (t.hdf5(), t.estimated)
        }
        OutputFormat::Zarr => (zarr(p), Vec::new()),
        OutputFormat::Parquet => (parquet(p), Vec::new()),
        OutputFormat::ActEpisodes => (act_episodes(p), Vec::new()),
        OutputFormat::RobomimicHdf5 => (robomimic(p), Vec::new()),
    };
    PlannedFile {
        path,
        estimated_bytes: bytes,
        bound: estimated.is_empty(),
        files: None,
        basis: (!estimated.is_empty()).then(|| format!("JPEG frames: {}", estimated.join("; "))),
    }
}
