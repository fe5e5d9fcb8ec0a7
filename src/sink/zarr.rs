//! The Zarr writer: a Diffusion Policy replay buffer that its `ReplayBuffer` opens directly, plus
//! chunkc's window index.
//!
//! ```text
//! data.zarr/
//!   data/<key>          (N, ...) float32 raw values (low-dim) or uint8 HWC frames (images)
//!   meta/episode_ends   (E,) int64  exclusive ends (Diffusion Policy's key)
//!   meta/episode_ids    (E,) int64  source episode ids, in stored order
//!   meta/episode_sources (E,) int64 a training mixture's: each episode's source index
//!   index/train         (S, 4) int64 rows of (episode position, current step t, limit, sub)
//!   index/val           (S, 4) int64
//! ```
//! `<key>` is the channel's export name (`plan::export`): by default the source key it was read
//! from (`img`, `state`, `action` for Push-T, as `PushTImageDataset` reads them), always one path
//! component, so that `data/` holds arrays only, as `ReplayBuffer` expects.
//! Native consumers normalize in their own code, so every value is raw (the loader normalizes
//! on read with `meta.json`'s parameters). Zarr v2 by default (`.zgroup`/`.zarray`), v3 with
//! `zarr_version = 3`. Low-dim arrays are chunked along time only; images one frame per chunk.
//! Compressor: Blosc lz4 level 5 without shuffle (Diffusion Policy's default) or Blosc zstd with
//! bit-shuffle. Metadata is written with sorted keys and no library stamp, so the bytes depend
//! only on the contents.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde_json::{json, Value};
use zarrs::array::{Array, ArrayMetadataOptions};
use zarrs::metadata::ArrayMetadata;

use super::zarr_store::DirStore;
use super::{FrameEncoding, Frames, Sink, SinkContext, Split, WindowIndex};
use crate::error::{Error, IoContext, Result};
use crate::source::ChannelKind;
use crate::spec::Compression;
use crate::stats::normalize::RowNormalizer;
use crate::store::LowdimStore;

pub const ZARR_DIR: &str = crate::spec::OutputFormat::Zarr.files().data;
/// Low-dim chunks hold about this many bytes of values (a mixture's padding aside).
const LOWDIM_CHUNK_BYTES: usize = 256 * 1024;
const DEFAULT_BLOSC_LEVEL: u32 = 5;

pub struct ZarrWriter {
    root: PathBuf,
    store: Arc<DirStore>,
    version: u32,
    compression: Compression,
    level: u32,
    data: Vec<Array<DirStore>>,
    chunk_rows: Vec<usize>,
    widths: Vec<usize>,
}

fn err(e: impl std::fmt::Display) -> Error {
    Error::output(format!("zarr: {e}"))
}

impl ZarrWriter {
    pub fn create(ctx: &SinkContext) -> Result<Self> {
        let root = ctx.dir.join(ZARR_DIR);
        let v = &ctx.profile.values;
        let store = Arc::new(DirStore::new(root.clone()));
        let mut w = ZarrWriter {
            root,
            store,
            version: v.zarr_version,
            compression: v.compression,
            level: v.compression_level.unwrap_or(DEFAULT_BLOSC_LEVEL),
            data: Vec::new(),
            chunk_rows: Vec::new(),
            widths: Vec::new(),
        };
        for g in ["", "data", "meta", "index"] {
            w.group(g)?;
        }
        let steps = *ctx.episode_ends.last().unwrap_or(&0) as usize;
        for (c, ch) in ctx.profile.channels.iter().enumerate() {
            let width = ch.shape.iter().product::<usize>().max(1);
            // About LOWDIM_CHUNK_BYTES of values a chunk: a mixture's padding is not values.
            let values = ctx.values_per_row(c);
            let (dtype, rows) = match ch.kind {
                ChannelKind::Lowdim => ("float32", (LOWDIM_CHUNK_BYTES / (4 * values)).max(1)),
                ChannelKind::Image => ("uint8", 1),
            };
            let rows = rows.clamp(1, steps.max(1));
            let mut shape = vec![steps];
            shape.extend(&ch.shape);
            let mut chunks = vec![rows];
            chunks.extend(&ch.shape);
            let array = w.array(&ch.array, dtype, &shape, &chunks)?;
            w.data.push(array);
            w.chunk_rows.push(rows);
            w.widths.push(width);
        }
        let ends: Vec<i64> = ctx.episode_ends.iter().map(|&e| e as i64).collect();
        let ids: Vec<i64> = ctx.episode_ids.iter().map(|&e| e as i64).collect();
        w.whole_i64("meta/episode_ends", &ends, &[ends.len()])?;
        w.whole_i64("meta/episode_ids", &ids, &[ids.len()])?;
        if !ctx.episode_sources.is_empty() {
            let sources: Vec<i64> = ctx.episode_sources.iter().map(|&s| s as i64).collect();
            w.whole_i64("meta/episode_sources", &sources, &[sources.len()])?;
        }
        Ok(w)
    }

    fn write_json(&self, rel: &str, value: &Value) -> Result<()> {
        let path = self.root.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).at("create", parent)?;
        }
        let mut text = serde_json::to_string_pretty(value).expect("JSON serializes");
        text.push('\n');
        std::fs::write(&path, text).at("write", &path)
    }

    fn group(&self, path: &str) -> Result<()> {
        let dir = Path::new(path);
        if self.version == 2 {
            self.write_json(
                &dir.join(".zgroup").to_string_lossy(),
                &json!({"zarr_format": 2}),
            )
        } else {
            let doc = json!({"zarr_format": 3, "node_type": "group", "attributes": {}});
            self.write_json(&dir.join("zarr.json").to_string_lossy(), &doc)
        }
    }

    fn blosc(&self, typesize: usize) -> Option<(&'static str, u8)> {
        match self.compression {
            Compression::Zstd => Some(("zstd", 2)),
            Compression::None => None,
            _ => Some(("lz4", 0)),
        }
        .map(|(cname, shuffle)| {
            let _ = typesize;
            (cname, shuffle)
        })
    }

    fn array(
        &self,
        path: &str,
        dtype: &str,
        shape: &[usize],
        chunks: &[usize],
    ) -> Result<Array<DirStore>> {
        let typesize = if dtype == "uint8" {
            1
        } else {
            4 + 4 * (dtype == "int64") as usize
        };
        let metadata: ArrayMetadata = if self.version == 2 {
            let dt = match dtype {
                "float32" => "<f4",
                "int64" => "<i8",
                _ => "|u1",
            };
            let compressor = self.blosc(typesize).map(|(cname, shuffle)| {
                json!({"id": "blosc", "cname": cname, "clevel": self.level, "shuffle": shuffle, "blocksize": 0})
            });
            let doc = json!({
                "zarr_format": 2, "shape": shape, "chunks": chunks, "dtype": dt,
                "compressor": compressor, "fill_value": 0, "order": "C", "filters": null,
            });
            ArrayMetadata::V2(serde_json::from_value(doc).map_err(err)?)
        } else {
            let mut codecs = vec![json!({"name": "bytes", "configuration": {"endian": "little"}})];
            if let Some((cname, shuffle)) = self.blosc(typesize) {
                let shuffle = ["noshuffle", "shuffle", "bitshuffle"][shuffle as usize];
                codecs.push(json!({"name": "blosc", "configuration": {
                    "cname": cname, "clevel": self.level, "shuffle": shuffle,
                    "typesize": typesize, "blocksize": 0}}));
            }
            let doc = json!({
                "zarr_format": 3, "node_type": "array", "shape": shape, "data_type": dtype,
                "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": chunks}},
                "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
                "fill_value": 0, "codecs": codecs, "attributes": {},
            });
            ArrayMetadata::V3(serde_json::from_value(doc).map_err(err)?)
        };
        let array = Array::new_with_metadata(self.store.clone(), &format!("/{path}"), metadata)
            .map_err(err)?;
        array
            .store_metadata_opt(&ArrayMetadataOptions::default().with_include_zarrs_metadata(false))
            .map_err(err)?;
        Ok(array)
    }

    /// Stores `values` of `array` (row-major, `width` per row) chunk by chunk along time.
    fn rows<T: zarrs::array::Element + Copy + Default>(
        array: &Array<DirStore>,
        values: &[T],
        width: usize,
        chunk_rows: usize,
        first_chunk: usize,
    ) -> Result<()> {
        let rank = array.dimensionality();
        let per_chunk = chunk_rows * width;
        for (c, part) in values.chunks(per_chunk.max(1)).enumerate() {
            let mut chunk = part.to_vec();
            chunk.resize(per_chunk, T::default());
            let mut idx = vec![0u64; rank];
            idx[0] = (first_chunk + c) as u64;
            array.store_chunk(&idx, chunk).map_err(err)?;
        }
        Ok(())
    }

    fn whole_i64(&self, path: &str, values: &[i64], shape: &[usize]) -> Result<()> {
        let rows = shape[0].max(1);
        let mut chunks = shape.to_vec();
        chunks[0] = rows;
        let array = self.array(path, "int64", shape, &chunks)?;
        if !values.is_empty() {
            let width = shape[1..].iter().product::<usize>().max(1);
            Self::rows(&array, values, width, rows, 0)?;
        }
        Ok(())
    }
}

impl Sink for ZarrWriter {
    fn data_file(&self) -> &str {
        ZARR_DIR
    }

    fn frame_encoding(&self) -> FrameEncoding {
        FrameEncoding::Raw
    }

    fn stores_normalized(&self) -> bool {
        false
    }

    fn write_frames(&mut self, channel: usize, row: usize, frames: &Frames) -> Result<()> {
        use rayon::prelude::*;
        let array = &self.data[channel];
        let rank = array.dimensionality();
        // One chunk (one file) per frame: compressing and writing them in parallel gives the
        // same files whatever the order.
        (0..frames.len()).into_par_iter().try_for_each(|i| {
            let mut idx = vec![0u64; rank];
            idx[0] = (row + i) as u64;
            array.store_chunk(&idx, frames.get(i)).map_err(err)
        })
    }

    /// Raw values: Diffusion Policy fits its own normalizer on the replay buffer.
    fn write_lowdim(
        &mut self,
        channel: usize,
        raw: &Arc<LowdimStore>,
        _: &RowNormalizer,
    ) -> Result<()> {
        use rayon::prelude::*;
        // One chunk (one file) per task, read from the store (which may be on disk) straight
        // into the chunk's buffer: the files are the same whatever the order, and a padded
        // mixture channel's many values compress on every thread.
        let (width, chunk_rows) = (self.widths[channel], self.chunk_rows[channel].max(1));
        let array = &self.data[channel];
        let rank = array.dimensionality();
        let chunks = raw.len().div_ceil(chunk_rows);
        // Each thread fills one chunk buffer again and again (a fresh one a chunk would fault
        // in and zero its pages every time).
        let buffer = || vec![0f32; chunk_rows * width];
        (0..chunks)
            .into_par_iter()
            .try_for_each_init(buffer, |chunk, c| {
                let lo = c * chunk_rows;
                let hi = (lo + chunk_rows).min(raw.len());
                let (rows, rest) = chunk.split_at_mut((hi - lo) * width);
                raw.rows_into(lo, rows)?;
                rest.fill(0.0);
                let mut idx = vec![0u64; rank];
                idx[0] = c as u64;
                array.store_chunk(&idx, &chunk[..]).map_err(err)
            })
    }

    fn write_index(&mut self, index: &dyn WindowIndex) -> Result<()> {
        for (name, split) in [("index/train", Split::Train), ("index/val", Split::Val)] {
            let rows = index.all(split)?;
            let flat: Vec<i64> = rows.iter().flatten().copied().collect();
            self.whole_i64(name, &flat, &[rows.len(), 4])?;
        }
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<super::Finished> {
        Ok(super::Finished {
            written: self.store.take_written(),
            ..Default::default()
        })
    }
}
