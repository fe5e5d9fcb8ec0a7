//! Diffusion Policy's zarr `ReplayBuffer` (`replay.zarr`, zarr v2), as its `ReplayBuffer`
//! writes it: every episode appended along axis 0.
//!
//! ```text
//! data/action            (N, A) float32, chunks of about 1 MiB along time
//! data/state             (N, S) float32
//! data/cam<c>            (N, H, W, 3) uint8, chunks of about 1 MiB of whole frames
//! meta/episode_ends      (E,) int64, exclusive cumulative ends
//! ```
//! Compressor: Blosc lz4 level 5 without shuffle (the `ReplayBuffer` default). Episodes are
//! buffered until a chunk row is full, so memory stays at one chunk per array. The replay
//! buffer stores no timestamps, so only a `drop` fault leaves a trace (shorter episodes).
//!
//! [`ZarrLayout`] changes the low-dim arrays' chunking (`--zarr-chunk-rows`, and
//! `--zarr-chunk-cols`, which splits the columns as zarr-python's default chunking does) and
//! the format (`--zarr-format 3`: `zarr.json` metadata, the same codecs), so that the
//! benchmarks and tests read the layouts users' files have.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde_json::json;
use zarrs::array::{Array, ArrayMetadataOptions};
use zarrs::filesystem::FilesystemStore;
use zarrs::metadata::ArrayMetadata;

use super::{SynthEpisode, SynthOptions, SynthWriter};
use crate::error::{Error, IoContext, Result};

const CHUNK_BYTES: usize = 1 << 20;

/// How the arrays are chunked and which zarr format describes them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ZarrLayout {
    /// Rows per chunk of the low-dim arrays (`None`: about 1 MiB of rows).
    pub chunk_rows: Option<usize>,
    /// Columns per chunk of the low-dim arrays (`None`: all of them).
    pub chunk_cols: Option<usize>,
    /// 2 or 3.
    pub format: u8,
}

impl Default for ZarrLayout {
    fn default() -> Self {
        ZarrLayout {
            chunk_rows: None,
            chunk_cols: None,
            format: 2,
        }
    }
}

fn err(e: impl std::fmt::Display) -> Error {
    Error::output(format!("zarr: {e}"))
}

/// One growing array: its pending rows, written a whole chunk at a time.
struct Column<T> {
    name: String,
    /// Values per step.
    width: usize,
    /// Per-step shape after the time axis.
    shape: Vec<usize>,
    chunk_rows: usize,
    /// Columns per chunk (the whole width unless the layout splits low-dim columns).
    chunk_cols: usize,
    pending: Vec<T>,
    chunks_written: u64,
    rows: usize,
}

pub struct DpZarrWriter {
    root: PathBuf,
    store: Arc<FilesystemStore>,
    lowdim: Vec<Column<f32>>,
    images: Vec<Column<u8>>,
    ends: Vec<i64>,
    format: u8,
}

impl<T> Column<T> {
    fn new(name: String, shape: Vec<usize>, elem: usize) -> Self {
        let width = shape.iter().product::<usize>().max(1);
        Column {
            name,
            width,
            chunk_rows: (CHUNK_BYTES / (width * elem)).max(1),
            chunk_cols: width,
            shape,
            pending: Vec::new(),
            chunks_written: 0,
            rows: 0,
        }
    }
}

fn write_json(root: &Path, rel: &str, value: &serde_json::Value) -> Result<()> {
    let path = root.join(rel);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).at("create", parent)?;
    }
    let mut text = serde_json::to_string_pretty(value).expect("JSON serializes");
    text.push('\n');
    std::fs::write(&path, text).at("write", &path)
}

impl DpZarrWriter {
    pub fn create(opts: &SynthOptions, root: &Path) -> Result<Self> {
        let store = Arc::new(FilesystemStore::new(root).map_err(err)?);
        let layout = opts.zarr;
        if !matches!(layout.format, 2 | 3) {
            return Err(Error::Spec(format!(
                "chunkc synth: zarr format {} (2 or 3)",
                layout.format
            )));
        }
        for g in ["", "data", "meta"] {
            let (name, doc) = if layout.format == 3 {
                (
                    "zarr.json",
                    json!({"zarr_format": 3, "node_type": "group", "attributes": {}}),
                )
            } else {
                (".zgroup", json!({"zarr_format": 2}))
            };
            write_json(root, format!("{g}/{name}").trim_start_matches('/'), &doc)?;
        }
        let mut lowdim = vec![
            Column::new("action".into(), vec![opts.action_dim], 4),
            Column::new("state".into(), vec![opts.state_dim], 4),
        ];
        for col in &mut lowdim {
            if let Some(rows) = layout.chunk_rows {
                col.chunk_rows = rows.max(1);
            }
            if let Some(cols) = layout.chunk_cols {
                col.chunk_cols = cols.clamp(1, col.width);
            }
        }
        let images = (0..opts.cameras)
            .map(|c| Column::new(format!("cam{c}"), vec![opts.height, opts.width, 3], 1))
            .collect();
        Ok(DpZarrWriter {
            root: root.to_path_buf(),
            store,
            lowdim,
            images,
            ends: Vec::new(),
            format: layout.format,
        })
    }

    fn array(
        &self,
        path: &str,
        dtype: &str,
        shape: &[usize],
        chunks: &[usize],
    ) -> Result<Array<FilesystemStore>> {
        let metadata = if self.format == 3 {
            let (data_type, fill, size) = match dtype {
                "<f4" => ("float32", json!(0.0), 4),
                "|u1" => ("uint8", json!(0), 1),
                "<i8" => ("int64", json!(0), 8),
                other => return Err(err(format!("no zarr v3 name for {other}"))),
            };
            let doc = json!({
                "zarr_format": 3, "node_type": "array", "shape": shape, "data_type": data_type,
                "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": chunks}},
                "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
                "fill_value": fill,
                "codecs": [
                    {"name": "bytes", "configuration": {"endian": "little"}},
                    {"name": "blosc", "configuration": {"cname": "lz4", "clevel": 5,
                        "shuffle": "noshuffle", "typesize": size, "blocksize": 0}},
                ],
                "attributes": {},
            });
            ArrayMetadata::V3(serde_json::from_value(doc).map_err(err)?)
        } else {
            let doc = json!({
                "zarr_format": 2, "shape": shape, "chunks": chunks, "dtype": dtype,
                "compressor": {"id": "blosc", "cname": "lz4", "clevel": 5, "shuffle": 0, "blocksize": 0},
                "fill_value": 0, "order": "C", "filters": null,
            });
            ArrayMetadata::V2(serde_json::from_value(doc).map_err(err)?)
        };
        let array = Array::new_with_metadata(self.store.clone(), &format!("/{path}"), metadata)
            .map_err(err)?;
        array
            .store_metadata_opt(&ArrayMetadataOptions::default().with_include_zarrs_metadata(false))
            .map_err(err)?;
        Ok(array)
    }

    /// Writes the full chunks among `col`'s pending rows (all of them, padded, when `last`).
    fn flush<T: zarrs::array::Element + Copy + Default>(
        &self,
        col: &mut Column<T>,
        dtype: &str,
        last: bool,
    ) -> Result<()> {
        let per_chunk = col.chunk_rows * col.width;
        let mut shape = vec![col.rows];
        shape.extend(&col.shape);
        let mut chunks = vec![col.chunk_rows];
        chunks.extend(&col.shape);
        // Split columns: only low-dim arrays (one axis after time) are split.
        let split = col.chunk_cols < col.width && col.shape.len() == 1;
        if split {
            chunks[1] = col.chunk_cols;
        }
        // The array's shape grows as episodes arrive; its metadata is rewritten at the end.
        let array = self.array(&format!("data/{}", col.name), dtype, &shape, &chunks)?;
        let mut done = 0;
        while col.pending.len() - done >= per_chunk || (last && done < col.pending.len()) {
            let end = (done + per_chunk).min(col.pending.len());
            let mut rows = col.pending[done..end].to_vec();
            rows.resize(per_chunk, T::default());
            let mut idx = vec![0u64; 1 + col.shape.len()];
            idx[0] = col.chunks_written;
            if split {
                let c = col.chunk_cols;
                for j in 0..col.width.div_ceil(c) {
                    let mut chunk = vec![T::default(); col.chunk_rows * c];
                    for (r, row) in rows.chunks_exact(col.width).enumerate() {
                        let cols = &row[j * c..((j + 1) * c).min(col.width)];
                        chunk[r * c..r * c + cols.len()].copy_from_slice(cols);
                    }
                    idx[1] = j as u64;
                    array.store_chunk(&idx, chunk).map_err(err)?;
                }
            } else {
                array.store_chunk(&idx, rows).map_err(err)?;
            }
            col.chunks_written += 1;
            done = end;
        }
        col.pending.drain(..done);
        Ok(())
    }
}

impl SynthWriter for DpZarrWriter {
    fn episode(&mut self, ep: &SynthEpisode) -> Result<()> {
        let mut lowdim = std::mem::take(&mut self.lowdim);
        for (col, values) in lowdim.iter_mut().zip([&ep.action, &ep.state]) {
            col.pending.extend_from_slice(values);
            col.rows += ep.steps;
            self.flush(col, "<f4", false)?;
        }
        self.lowdim = lowdim;
        let mut images = std::mem::take(&mut self.images);
        for (col, values) in images.iter_mut().zip(&ep.frames) {
            col.pending.extend_from_slice(values);
            col.rows += ep.steps;
            self.flush(col, "|u1", false)?;
        }
        self.images = images;
        self.ends
            .push(self.ends.last().copied().unwrap_or(0) + ep.steps as i64);
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        let mut lowdim = std::mem::take(&mut self.lowdim);
        for col in &mut lowdim {
            self.flush(col, "<f4", true)?;
        }
        let mut images = std::mem::take(&mut self.images);
        for col in &mut images {
            self.flush(col, "|u1", true)?;
        }
        let n = self.ends.len();
        let array = self.array("meta/episode_ends", "<i8", &[n], &[n.max(1)])?;
        array.store_chunk(&[0], self.ends.clone()).map_err(err)?;
        let _ = &self.root;
        Ok(())
    }
}
