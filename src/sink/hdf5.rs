// Long file: one writer: its three layouts share every dataset but `/chunks`.
//! The HDF5 writer for chunkc's own layouts (`index`, and `materialized` / `virtual`, which add
//! `/chunks`: see `hdf5_chunks`). Cameras stored as JPEG or video: see `hdf5_lossy`.
//!
//! ```text
//! /data/<channel>      (N, ...) float32 (normalized low-dim) or uint8 (images, HWC)
//! /meta/episode_ends   (E,) int64  exclusive ends of each episode in /data
//! /meta/episode_ids    (E,) int64  source episode ids, in stored order
//! /meta/episode_sources (E,) int64 a training mixture's: each episode's source index
//! /index/train         (S, 4) int64 rows of (episode position, current step t, limit, sub)
//! /index/val           (S, 4) int64
//! ```
//! Attributes on `/` name the window parameters. Object time tracking is off everywhere, and
//! data is written in a fixed order, so the file's bytes depend only on its contents.

use std::sync::Arc;

use hdf5::dataset::{AllocTime, FillTime};
use hdf5::types::VarLenUnicode;
use hdf5::{Dataset, File, Group};
use ndarray::{ArrayViewD, IxDyn};

use super::hdf5_chunks::{self, Stored, Windows};
use super::hdf5_lossy::LossyFrames;
use super::hdf5_rows::write_rows;
use super::{FrameEncoding, Frames, Sink, SinkContext, Split, WindowIndex};
use crate::bytes::f32_bytes;
use crate::error::{Error, Result};
use crate::source::block_map::{self, BlockMap};
use crate::source::ChannelKind;
use crate::spec::{Compression, ImageCompression, Layout, Padding};
use crate::stats::normalize::RowNormalizer;
use crate::store::LowdimStore;
use crate::window::{EpisodeEnds, Window};

/// chunkc's own container, where the format says.
const DATA_FILE: &str = crate::spec::OutputFormat::Hdf5.files().data;
/// Chunks of low-dimensional data hold about this many bytes (a few windows' worth).
const LOWDIM_CHUNK_BYTES: usize = 64 * 1024;
/// `image_compression = "gzip"` compresses frames at this level unless the spec gives one.
const DEFAULT_IMAGE_GZIP_LEVEL: u32 = 1;

/// Low-dim channels are normalized and written about this many bytes at a time.
const NORMALIZE_BLOCK_BYTES: usize = 4 << 20;
/// Window index rows generated and written at once.
const INDEX_BLOCK_BYTES: usize = 4 << 20;

/// gzip's level when the spec gives none.
const DEFAULT_GZIP_LEVEL: u32 = 4;

pub struct Hdf5Writer {
    file: File,
    /// How frames are handed over and stored.
    frames: FrameEncoding,
    /// The same file opened with std, for frames written with `pwrite` (uncompressed frames).
    raw: Option<std::fs::File>,
    /// Per channel: where each frame's chunk lies, for uncompressed image channels.
    block_maps: Vec<Option<BlockMap>>,
    data: Vec<Dataset>,
    shapes: Vec<Vec<usize>>,
    names: Vec<String>,
    layout: Layout,
    window: Window,
    padding: Padding,
    episode_ends: EpisodeEnds,
    /// Normalized low-dim values and normalizers, kept for `/chunks` (not for `index`).
    kept: Vec<Option<(Vec<f32>, RowNormalizer)>>,
    /// The row store's memory budget (exec's), which bounds the index blocks too.
    spill_budget: usize,
    /// Cameras stored as JPEG or video (`image_compression`).
    lossy: LossyFrames,
}

fn group(parent: &Group, name: &str) -> Result<Group> {
    Ok(parent
        .create_group_builder()
        .obj_track_times(false)
        .create(name)?)
}

/// HDF5 stores frames raw or deflated; it never asks for PNGs, and JPEGs go to `hdf5_lossy`.
fn no_png() -> Error {
    Error::Internal("HDF5 frames are never PNG-encoded, nor JPEGs outside hdf5_lossy".into())
}

fn text(s: &str) -> Result<VarLenUnicode> {
    s.parse::<VarLenUnicode>()
        .map_err(|e| Error::Internal(format!("attribute text {s:?}: {e}")))
}

/// Asks the kernel to start writing these bytes to disk now (without waiting): the frames are
/// most of the output, and the build ends with an fsync of every file, which otherwise waits
/// for all of them at once. Only a hint: the fsync still makes the data durable.
fn start_writeback(file: &std::fs::File, offset: u64, len: usize) {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        // SAFETY: the descriptor is open while `file` lives; the call reads no memory of ours.
        unsafe {
            libc::sync_file_range(
                file.as_raw_fd(),
                offset as libc::off64_t,
                len as libc::off64_t,
                libc::SYNC_FILE_RANGE_WRITE,
            );
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (file, offset, len);
}

impl Hdf5Writer {
    // Long function: one dataset per layout element, created in file order.
    pub fn create(ctx: &SinkContext) -> Result<Self> {
        let path = &ctx.dir.join(DATA_FILE);
        let (plan, episode_ends, ids) = (ctx.profile, ctx.episode_ends, ctx.episode_ids);
        let file = File::with_options()
            .with_fcpl(|p| p.obj_track_times(false))
            .create(path)
            .map_err(|e| Error::output(format!("cannot create {}: {e}", path.display())))?;
        let steps = *episode_ends.last().unwrap_or(&0) as usize;

        let v = &plan.values;
        let root: &Group = &file;
        root.new_attr::<i64>()
            .create("chunk_size")?
            .write_scalar(&i64::from(v.chunk))?;
        root.new_attr::<i64>()
            .create("obs_history")?
            .write_scalar(&i64::from(v.obs_history))?;
        root.new_attr::<i64>()
            .create("stride")?
            .write_scalar(&i64::from(v.stride))?;
        root.new_attr::<f64>()
            .create("fps")?
            .write_scalar(&plan.fps)?;
        root.new_attr::<VarLenUnicode>()
            .create("padding")?
            .write_scalar(&text(v.padding.name())?)?;
        root.new_attr::<VarLenUnicode>()
            .create("alignment")?
            .write_scalar(&text(v.alignment.name())?)?;
        root.new_attr::<VarLenUnicode>()
            .create("layout")?
            .write_scalar(&text(v.layout.name())?)?;

        let frames = match v.image_compression {
            ImageCompression::None | ImageCompression::Video => FrameEncoding::Raw,
            ImageCompression::Jpeg => FrameEncoding::Jpeg(LossyFrames::quality(ctx)),
            ImageCompression::Gzip => FrameEncoding::Zlib(
                v.image_compression_level
                    .unwrap_or(DEFAULT_IMAGE_GZIP_LEVEL)
                    .min(9) as u8,
            ),
        };
        let data_group = group(root, "data")?;
        let (mut lossy, lossy_frames) = (LossyFrames::new(ctx), LossyFrames::wanted(ctx));
        let mut block_maps = Vec::new();
        let mut data = Vec::new();
        let mut shapes = Vec::new();
        for ch in &plan.channels {
            let mut shape = vec![steps];
            shape.extend(&ch.shape);
            let ds = match ch.kind {
                ChannelKind::Lowdim => {
                    let row_bytes = 4 * ch.shape.iter().product::<usize>().max(1);
                    let rows = (LOWDIM_CHUNK_BYTES / row_bytes).clamp(1, steps.max(1));
                    let mut chunk = vec![rows];
                    chunk.extend(&ch.shape);
                    let b = data_group
                        .new_dataset::<f32>()
                        .shape(shape.clone())
                        .chunk(chunk)
                        .obj_track_times(false);
                    let b = match v.compression {
                        Compression::Gzip => {
                            b.deflate(v.compression_level.unwrap_or(DEFAULT_GZIP_LEVEL) as u8)
                        }
                        Compression::Lzf => b.lzf(),
                        // Unfiltered: every chunk allocated now and never filled, then written
                        // straight into (`write_raw_rows`), as uncompressed frames are.
                        _ => b
                            .alloc_time(Some(AllocTime::Early))
                            .fill_time(FillTime::Never),
                    };
                    b.create(ch.name.as_str())?
                }
                ChannelKind::Image if lossy_frames => lossy.add(ctx, root, &ch.name, &ch.shape)?,
                ChannelKind::Image => {
                    // One frame per chunk: a sample reads only the frames it needs.
                    let mut chunk = vec![1];
                    chunk.extend(&ch.shape);
                    let b = data_group
                        .new_dataset::<u8>()
                        .shape(shape.clone())
                        .chunk(chunk)
                        .obj_track_times(false);
                    match frames {
                        FrameEncoding::Zlib(level) => b.deflate(level).create(ch.name.as_str())?,
                        // Every chunk allocated now, in row order, and never filled: the frames
                        // are then written straight into their chunks (`write_raw_frames`).
                        FrameEncoding::Raw => b
                            .alloc_time(Some(AllocTime::Early))
                            .fill_time(FillTime::Never)
                            .create(ch.name.as_str())?,
                        FrameEncoding::Png | FrameEncoding::Jpeg(_) => return Err(no_png()),
                    }
                }
            };
            if ch.kind == ChannelKind::Lowdim || !lossy_frames {
                lossy.skip();
            }
            block_maps.push(match (ch.kind, frames) {
                // Low-dim channels whose chunks cannot be located go through HDF5.
                (ChannelKind::Lowdim, _) => block_map::locate(&ds),
                (ChannelKind::Image, _) if lossy_frames => None,
                (ChannelKind::Image, FrameEncoding::Raw) => {
                    Some(block_map::locate(&ds).ok_or_else(|| {
                        Error::Internal(format!(
                            "{}: the frames' chunks of `{}` cannot be located",
                            path.display(),
                            ch.name
                        ))
                    })?)
                }
                _ => None,
            });
            data.push(ds);
            shapes.push(ch.shape.clone());
        }

        let meta = group(root, "meta")?;
        let ends: Vec<i64> = episode_ends.iter().map(|&e| e as i64).collect();
        let ids: Vec<i64> = ids.iter().map(|&e| e as i64).collect();
        let sources: Vec<i64> = ctx.episode_sources.iter().map(|&s| s as i64).collect();
        let mut meta_arrays = vec![("episode_ends", &ends), ("episode_ids", &ids)];
        if !sources.is_empty() {
            meta_arrays.push(("episode_sources", &sources));
        }
        for (name, values) in meta_arrays {
            meta.new_dataset::<i64>()
                .shape([values.len()])
                .obj_track_times(false)
                .create(name)?
                .write_raw(values)?;
        }
        group(root, "index")?;
        let raw = if block_maps.iter().any(Option::is_some) {
            // Metadata goes through HDF5 (it flushes it on close); uncompressed rows through
            // this handle, into chunks HDF5 allocated and never touches again.
            Some(
                std::fs::OpenOptions::new()
                    .write(true)
                    .open(path)
                    .map_err(|e| Error::output(format!("cannot open {}: {e}", path.display())))?,
            )
        } else {
            None
        };
        Ok(Hdf5Writer {
            file,
            frames,
            raw,
            block_maps,
            data,
            shapes,
            names: plan.channels.iter().map(|c| c.name.clone()).collect(),
            layout: v.layout,
            window: *plan.window(),
            padding: v.padding,
            episode_ends: episode_ends.into(),
            kept: plan.channels.iter().map(|_| None).collect(),
            spill_budget: ctx.spill_budget,
            lossy,
        })
    }

    /// Writes frames already compressed as HDF5's deflate filter stores a chunk, directly as
    /// chunks: HDF5 would compress them on one thread under its global lock.
    fn write_chunks(&self, channel: usize, row: usize, frames: &Frames) -> Result<()> {
        let ds = &self.data[channel];
        let rank = 1 + self.shapes[channel].len();
        for (i, frame) in frames.iter().enumerate() {
            let mut offset = vec![0 as hdf5_sys::h5::hsize_t; rank];
            offset[0] = (row + i) as hdf5_sys::h5::hsize_t;
            // SAFETY: the dataset id is valid while `ds` lives; `offset` has one entry per
            // dimension and `frame` outlives the call. The global HDF5 lock is held by `sync`.
            let status = hdf5::sync::sync(|| unsafe {
                hdf5_sys::h5d::H5Dwrite_chunk(
                    ds.id(),
                    hdf5_sys::h5p::H5P_DEFAULT,
                    0,
                    offset.as_ptr(),
                    frame.len(),
                    frame.as_ptr().cast(),
                )
            });
            if status < 0 {
                return Err(Error::output(format!(
                    "HDF5: writing frame {} of {} failed",
                    row + i,
                    ds.name()
                )));
            }
        }
        Ok(())
    }

    /// Writes uncompressed frames straight into their chunks, allocated when the dataset was
    /// created: plain `pwrite`s, outside HDF5 and its global lock.
    fn write_raw_frames(&self, channel: usize, row: usize, frames: &Frames) -> Result<()> {
        if frames.bytes().len() != frames.len() * self.row_bytes(channel) {
            return Err(Error::Internal(format!(
                "channel {channel}: {} bytes for {} frames of {} bytes",
                frames.bytes().len(),
                frames.len(),
                self.row_bytes(channel)
            )));
        }
        self.write_raw_rows(channel, row, frames.bytes())
    }

    fn row_bytes(&self, channel: usize) -> usize {
        self.block_maps[channel].as_ref().map_or(0, |m| m.row_bytes)
    }

    /// Writes whole rows from `row` (`bytes`, as stored) into the chunks of a channel that has
    /// a chunk map: one `pwrite` per run of chunks that follow one another in the file (usually
    /// all of them). Not spread over threads: the kernel serializes buffered writes to one file
    /// anyway (the inode lock).
    fn write_raw_rows(&self, channel: usize, row: usize, bytes: &[u8]) -> Result<()> {
        use std::os::unix::fs::FileExt;
        let (Some(map), Some(file)) = (&self.block_maps[channel], &self.raw) else {
            return Err(Error::Internal(format!(
                "channel {channel}: no chunk map to write rows into"
            )));
        };
        let rows = bytes.len() / map.row_bytes.max(1);
        if rows * map.row_bytes != bytes.len() {
            return Err(Error::Internal(format!(
                "channel {channel}: {} bytes are not whole rows of {} bytes",
                bytes.len(),
                map.row_bytes
            )));
        }
        let extents = map.extents(row, row + rows);
        let written: usize = extents.iter().map(|e| e.rows).sum();
        if written != rows {
            return Err(Error::Internal(format!(
                "channel {channel}: rows {row}..{} are outside the dataset",
                row + rows
            )));
        }
        for e in &extents {
            let from = (e.row - row) * map.row_bytes;
            let part = &bytes[from..from + e.rows * map.row_bytes];
            file.write_all_at(part, e.offset).map_err(|err| {
                Error::output(format!(
                    "writing rows {}..{} of {}: {err}",
                    e.row,
                    e.row + e.rows,
                    self.names[channel]
                ))
            })?;
            start_writeback(file, e.offset, part.len());
        }
        Ok(())
    }

    /// Writes rows of a low-dimensional channel from `row`: into its chunks directly when they
    /// are mapped, through HDF5 otherwise.
    fn write_lowdim_rows(&self, channel: usize, row: usize, values: &[f32]) -> Result<()> {
        if self.block_maps[channel].is_some() {
            return self.write_raw_rows(channel, row, f32_bytes(values));
        }
        write_rows(&self.data[channel], row, values)
    }

    /// Writes one split's window index: rows of (episode position, current step, limit, sub);
    /// see `chunk::Sample`.
    /// Written a block of rows at a time: the index need not be in memory whole.
    fn write_index_of(&self, name: &str, index: &dyn WindowIndex, split: Split) -> Result<()> {
        let n = index.count(split);
        let ds = self
            .file
            .group("index")?
            .new_dataset::<i64>()
            .shape([n, 4])
            .obj_track_times(false)
            .create(name)?;
        // Within the low-dim memory budget too: a tiny `CHUNKC_SPILL_BYTES` (the tests) makes
        // blocks of a few rows, which start and end inside episodes.
        let block = (INDEX_BLOCK_BYTES.min(self.spill_budget) / 32).max(1);
        let starts: Vec<usize> = (0..n).step_by(block).collect();
        let generate = |lo: usize| index.rows(split, lo, (lo + block).min(n));
        // The next block is generated while this one is written.
        let mut next = starts.first().map(|&lo| generate(lo));
        for (i, &lo) in starts.iter().enumerate() {
            let rows = next.take().expect("generated")?;
            let hi = lo + rows.len();
            let (written, following) = rayon::join(
                || -> Result<()> {
                    let view = ArrayViewD::from_shape(IxDyn(&[hi - lo, 4]), rows.as_flattened())
                        .map_err(|err| Error::Internal(format!("index/{name}: {err}")))?;
                    ds.write_slice(view, (lo..hi, 0..4))?;
                    Ok(())
                },
                || starts.get(i + 1).map(|&lo| generate(lo)),
            );
            written?;
            next = following;
        }
        Ok(())
    }
}

impl Sink for Hdf5Writer {
    fn data_file(&self) -> &str {
        DATA_FILE
    }

    fn frame_encoding(&self) -> FrameEncoding {
        self.frames
    }

    fn copies_frames(&self, channel: usize, frames: &Frames) -> Result<bool> {
        self.lossy.copies(channel, frames)
    }

    fn write_frames(&mut self, channel: usize, row: usize, frames: &Frames) -> Result<()> {
        if self.lossy.write(channel, row, frames)? {
            return Ok(());
        }
        match self.frames {
            FrameEncoding::Raw => self.write_raw_frames(channel, row, frames),
            FrameEncoding::Zlib(_) => self.write_chunks(channel, row, frames),
            FrameEncoding::Png | FrameEncoding::Jpeg(_) => Err(no_png()),
        }
    }

    /// chunkc's own layout stores normalized values; the loader inverts them.
    fn write_lowdim(
        &mut self,
        channel: usize,
        raw: &Arc<LowdimStore>,
        normalizer: &RowNormalizer,
    ) -> Result<()> {
        let wanted = match self.layout {
            Layout::Index => false,
            Layout::Materialized => true,
            Layout::Virtual => self.names[channel] == "action",
        };
        if !wanted {
            // Normalized and written a block of whole chunks at a time: no second copy of the
            // whole channel in memory.
            let width = self.shapes[channel].iter().product::<usize>().max(1);
            let chunk_rows = self.data[channel]
                .chunk()
                .and_then(|c| c.first().copied())
                .unwrap_or(1)
                .max(1);
            let block_rows = chunk_rows * (NORMALIZE_BLOCK_BYTES / (4 * width * chunk_rows)).max(1);
            let starts: Vec<usize> = (0..raw.len()).step_by(block_rows).collect();
            // A block is read back and normalized in pieces on every thread.
            let piece_rows = chunk_rows * (block_rows / chunk_rows / 8).max(1);
            let prepare = |lo: usize| -> Result<Vec<f32>> {
                use rayon::prelude::*;
                let hi = (lo + block_rows).min(raw.len());
                let mut block = vec![0f32; (hi - lo) * width];
                block
                    .par_chunks_mut(piece_rows * width)
                    .enumerate()
                    .try_for_each(|(i, piece)| -> Result<()> {
                        raw.rows_into(lo + i * piece_rows, piece)?;
                        normalizer.apply_rows(lo + i * piece_rows, piece);
                        Ok(())
                    })?;
                Ok(block)
            };
            // The next block is prepared while this one is written (one thread at a time
            // writes); a thread done writing helps prepare.
            let mut next = starts.first().map(|&lo| prepare(lo));
            for (i, &lo) in starts.iter().enumerate() {
                let block = next.take().expect("prepared")?;
                let this = &*self;
                let (written, following) = rayon::join(
                    || this.write_lowdim_rows(channel, lo, &block),
                    || starts.get(i + 1).map(|&lo| prepare(lo)),
                );
                written?;
                next = following;
            }
            return Ok(());
        }
        // The windows of these layouts are materialized from the whole channel in memory.
        let mut values = raw.rows(0, raw.len())?.into_owned();
        normalizer.apply_rows(0, &mut values);
        self.write_lowdim_rows(channel, 0, &values)?;
        // Kept for `/chunks` (materialized or virtual layouts).
        self.kept[channel] = Some((values, normalizer.clone()));
        Ok(())
    }

    fn write_index(&mut self, index: &dyn WindowIndex) -> Result<()> {
        self.write_index_of("train", index, Split::Train)?;
        self.write_index_of("val", index, Split::Val)?;
        if self.layout == Layout::Index {
            return Ok(());
        }
        // The materialized and virtual layouts walk every window.
        let (train, val) = (index.all(Split::Train)?, index.all(Split::Val)?);
        let windows = Windows {
            window: &self.window,
            padding: self.padding,
            episode_ends: &self.episode_ends,
            rows: train.iter().chain(&val).copied().collect(),
            num_train: train.len(),
        };
        let stored: Vec<Stored> = self
            .kept
            .iter()
            .enumerate()
            .filter_map(|(c, kept)| {
                let (values, normalizer) = kept.as_ref()?;
                Some(Stored {
                    name: &self.names[c],
                    width: self.shapes[c].iter().product::<usize>().max(1),
                    shape: &self.shapes[c],
                    values,
                    normalizer,
                })
            })
            .collect();
        match self.layout {
            Layout::Materialized => hdf5_chunks::materialize(&self.file, &windows, &stored),
            _ => {
                let action = stored.iter().find(|s| s.name == "action").ok_or_else(|| {
                    Error::Internal("the virtual layout needs the action channel".into())
                })?;
                hdf5_chunks::virtual_action(&self.file, &windows, action)
            }
        }
    }

    fn finish(mut self: Box<Self>) -> Result<super::Finished> {
        let videos = self.lossy.finish()?;
        let Hdf5Writer { file, data, .. } = *self;
        drop(data);
        file.close()?;
        Ok(super::Finished {
            videos,
            ..Default::default()
        })
    }
}
