//! `image_compression = "jpeg"` in chunkc's HDF5 layout: every frame of a camera a JPEG file,
//! back to back.
//!
//! ```text
//! /data/<camera>         (B,) uint8   the JPEGs of every stored step, in row order (chunked,
//!                                     up to 1 MiB per chunk, unfiltered: one or two preads a frame)
//!     attrs: encoding = "jpeg", quality, frame_shape = [H, W, C]
//! /frame_ends/<camera>   (N,) int64   exclusive end of row i's JPEG in /data/<camera>
//! ```
//! Frames arrive one episode at a time in stored order (exec's contract), so the bytes are
//! appended and the ends are a running total: the same file for any `-j`.

use hdf5::types::VarLenUnicode;
use hdf5::{Dataset, Group};

use super::Frames;
use crate::error::{Error, Result};

/// Bytes per chunk of `/data/<camera>`: a few frames, so that a frame rarely spans two; less
/// for small datasets (about a tenth of their raw frames), whose last chunk would be mostly empty.
const CHUNK_BYTES: usize = 1 << 20;
const MIN_CHUNK_BYTES: usize = 16 << 10;

/// One camera's JPEG bytes and their ends, being appended to.
pub(super) struct JpegChannel {
    bytes: Dataset,
    ends: Dataset,
    /// Bytes written so far (the end of the last frame).
    written: u64,
    /// Rows written so far.
    rows: usize,
}

impl JpegChannel {
    /// Creates the camera's datasets for `steps` frames of `shape` at `quality`.
    pub(super) fn create(
        root: &Group,
        name: &str,
        shape: &[usize],
        steps: usize,
        quality: u8,
    ) -> Result<Self> {
        super::jpeg::check_shape(shape)
            .map_err(|e| Error::output(format!("channel `{name}`: {e}")))?;
        let data = root.group("data")?;
        let bytes = data
            .new_dataset::<u8>()
            .shape(0..)
            .chunk(
                (steps * shape.iter().product::<usize>() / 10).clamp(MIN_CHUNK_BYTES, CHUNK_BYTES),
            )
            .obj_track_times(false)
            .create(name)?;
        let text = |s: &str| {
            s.parse::<VarLenUnicode>()
                .map_err(|e| Error::Internal(format!("attribute text {s:?}: {e}")))
        };
        bytes
            .new_attr::<VarLenUnicode>()
            .create("encoding")?
            .write_scalar(&text("jpeg")?)?;
        bytes
            .new_attr::<i64>()
            .create("quality")?
            .write_scalar(&i64::from(quality))?;
        let dims: Vec<i64> = shape.iter().map(|&d| d as i64).collect();
        bytes
            .new_attr::<i64>()
            .shape([dims.len()])
            .create("frame_shape")?
            .write_raw(&dims)?;
        let group = match root.group("frame_ends") {
            Ok(g) => g,
            Err(_) => root
                .create_group_builder()
                .obj_track_times(false)
                .create("frame_ends")?,
        };
        let ends = group
            .new_dataset::<i64>()
            .shape([steps])
            .obj_track_times(false)
            .create(name)?;
        Ok(JpegChannel {
            bytes,
            ends,
            written: 0,
            rows: 0,
        })
    }

    /// The dataset `/data/<camera>`.
    pub(super) fn dataset(&self) -> Dataset {
        self.bytes.clone()
    }

    /// Appends one episode's JPEGs, whose first row is `row`.
    pub(super) fn push(&mut self, row: usize, frames: &Frames) -> Result<()> {
        if row != self.rows {
            return Err(Error::Internal(format!(
                "{}: frames of row {row} arrived after row {}",
                self.bytes.name(),
                self.rows
            )));
        }
        let lo = self.written as usize;
        let hi = lo + frames.bytes().len();
        self.bytes.resize(hi)?;
        if hi > lo {
            self.bytes.write_slice(frames.bytes(), lo..hi)?;
        }
        let ends: Vec<i64> = frames
            .ends()
            .iter()
            .map(|&e| (lo as u64 + e) as i64)
            .collect();
        if !ends.is_empty() {
            self.ends.write_slice(&ends[..], row..row + ends.len())?;
        }
        self.written = hi as u64;
        self.rows += frames.len();
        Ok(())
    }
}
