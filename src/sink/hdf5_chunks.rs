//! The `/chunks` group of the `materialized` and `virtual` HDF5 layouts.
//!
//! Rows of `/chunks/<channel>` are the windows of `/index/train` followed by those of
//! `/index/val` (`/chunks` attributes `num_train`, `num_val`).
//!
//! - `materialized`: `/chunks/action` (N, K, A) and `/chunks/action_is_pad` (N, K); every
//!   low-dimensional observation as `/chunks/<name>` (N, obs_history, ...) and `<name>_is_pad`.
//! - `virtual`: `/chunks/action` is an HDF5 virtual dataset. For every split and chunk step k,
//!   one mapping sends the windows whose step k is inside the episode onto rows of
//!   `/data/action`, and one sends the padded ones onto `/chunks/action_pad`, which holds only the
//!   pad rows (in mapping order). Selections are unions of row blocks, so the mapping count is
//!   2 x 2 x K whatever the number of windows.

use std::ffi::CString;

use hdf5::{File, Group};
use hdf5_sys::h5::hsize_t;
use hdf5_sys::h5i::hid_t;

use super::hdf5_rows::write_rows;
use crate::error::{Error, Result};
use crate::spec::Padding;
use crate::stats::normalize::{Normalizer, RowNormalizer};
use crate::window::{EpisodeEnds, Step, Window};

/// A stored low-dimensional channel, normalized as in `/data` (each row with its source's
/// normalizer, in a training mixture).
pub struct Stored<'a> {
    pub name: &'a str,
    pub width: usize,
    pub shape: &'a [usize],
    pub values: &'a [f32],
    pub normalizer: &'a RowNormalizer,
}

pub struct Windows<'a> {
    pub window: &'a Window,
    pub padding: Padding,
    pub episode_ends: &'a EpisodeEnds,
    /// Index rows, train then val.
    pub rows: Vec<[i64; 4]>,
    pub num_train: usize,
}

fn chunks_group(file: &File, w: &Windows) -> Result<Group> {
    let g = file
        .create_group_builder()
        .obj_track_times(false)
        .create("chunks")?;
    for (name, n) in [
        ("num_train", w.num_train),
        ("num_val", w.rows.len() - w.num_train),
    ] {
        g.new_attr::<i64>()
            .create(name)?
            .write_scalar(&(n as i64))?;
    }
    Ok(g)
}

/// A dataset of `shape` chunked about 64 KiB at a time along its first axis (reading one window
/// stays cheap), deflated when `gzip`.
fn dense<T: hdf5::H5Type>(
    g: &Group,
    name: &str,
    shape: Vec<usize>,
    gzip: bool,
) -> Result<(hdf5::Dataset, usize)> {
    let mut chunk = shape.clone();
    let row: usize = shape[1..].iter().product::<usize>().max(1) * std::mem::size_of::<T>();
    chunk[0] = (64 * 1024 / row).clamp(1, shape[0].max(1));
    let rows = chunk[0];
    let b = g
        .new_dataset::<T>()
        .shape(shape)
        .chunk(chunk)
        .obj_track_times(false);
    let b = if gzip { b.deflate(4) } else { b };
    Ok((b.create(name)?, rows))
}

fn write_dense<T: hdf5::H5Type>(
    g: &Group,
    name: &str,
    shape: Vec<usize>,
    values: &[T],
    gzip: bool,
) -> Result<()> {
    let (ds, _) = dense::<T>(g, name, shape, gzip)?;
    if !values.is_empty() {
        ds.write_raw(values)?;
    }
    Ok(())
}

/// Windows materialized and written at once: about this many bytes of values.
const BLOCK_BYTES: usize = 4 << 20;

/// [`BLOCK_BYTES`], or `CHUNKC_CHUNKS_BLOCK_BYTES` when set (the tests make it tiny, so that
/// small datasets are written in many blocks).
fn block_bytes() -> usize {
    std::env::var("CHUNKC_CHUNKS_BLOCK_BYTES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(BLOCK_BYTES)
}

/// `/chunks` of the `materialized` layout, a block of windows at a time (whole chunks of the
/// values; the small deflated `_is_pad` chunks complete in HDF5's chunk cache), so memory holds
/// one block, not K copies of the channel.
pub fn materialize(file: &File, w: &Windows, channels: &[Stored]) -> Result<()> {
    let g = chunks_group(file, w)?;
    let n = w.rows.len();
    for ch in channels {
        let is_action = ch.name == "action";
        let steps = if is_action {
            w.window.chunk
        } else {
            w.window.obs_history
        };
        let mut shape = vec![n, steps];
        shape.extend(ch.shape);
        let (values_ds, chunk_rows) = dense::<f32>(&g, ch.name, shape, false)?;
        let (pads_ds, _) = dense::<bool>(&g, &format!("{}_is_pad", ch.name), vec![n, steps], true)?;
        let row_bytes = steps * ch.width * 4;
        let block = chunk_rows * (block_bytes() / (row_bytes * chunk_rows).max(1)).max(1);
        for lo in (0..n).step_by(block) {
            let hi = (lo + block).min(n);
            let mut values = Vec::with_capacity((hi - lo) * steps * ch.width);
            let mut pads = Vec::with_capacity((hi - lo) * steps);
            for r in &w.rows[lo..hi] {
                let (ep, t, limit) = (r[0] as usize, r[1] as usize, r[2] as usize);
                let start = w.episode_ends.start(ep);
                let row = |i: usize| &ch.values[(start + i) * ch.width..(start + i + 1) * ch.width];
                if is_action {
                    for s in w.window.action_steps(t, limit, w.episode_ends.len_of(ep)) {
                        match s {
                            Step::Row(i) => values.extend_from_slice(row(i)),
                            Step::Pad(i) => {
                                let n = ch.normalizer.at(start + i);
                                values.extend(pad_row(w.padding, n, row(i)));
                            }
                        }
                        pads.push(matches!(s, Step::Pad(_)));
                    }
                } else {
                    for (i, pad) in w.window.obs_steps(t) {
                        values.extend_from_slice(row(i));
                        pads.push(pad);
                    }
                }
            }
            write_rows(&values_ds, lo, &values)?;
            write_rows(&pads_ds, lo, &pads)?;
        }
    }
    Ok(())
}

/// An HDF5 dataspace being built as a union of blocks; closed on drop.
struct Space(hid_t);

impl Space {
    fn new(dims: &[usize]) -> Result<Space> {
        let dims: Vec<hsize_t> = dims.iter().map(|&d| d as hsize_t).collect();
        // SAFETY: `dims` has `dims.len()` entries and outlives the call.
        let id = hdf5::sync::sync(|| unsafe {
            hdf5_sys::h5s::H5Screate_simple(dims.len() as i32, dims.as_ptr(), std::ptr::null())
        });
        if id < 0 {
            return Err(Error::output("HDF5: cannot create a dataspace".to_string()));
        }
        // SAFETY: `id` is a valid dataspace.
        hdf5::sync::sync(|| unsafe { hdf5_sys::h5s::H5Sselect_none(id) });
        Ok(Space(id))
    }

    /// Adds the block at `start` of size `count`.
    fn add(&mut self, start: &[usize], count: &[usize]) -> Result<()> {
        let start: Vec<hsize_t> = start.iter().map(|&d| d as hsize_t).collect();
        let count: Vec<hsize_t> = count.iter().map(|&d| d as hsize_t).collect();
        // SAFETY: both arrays have one entry per dimension of the dataspace.
        let status = hdf5::sync::sync(|| unsafe {
            hdf5_sys::h5s::H5Sselect_hyperslab(
                self.0,
                hdf5_sys::h5s::H5S_SELECT_OR,
                start.as_ptr(),
                std::ptr::null(),
                count.as_ptr(),
                std::ptr::null(),
            )
        });
        if status < 0 {
            return Err(Error::output("HDF5: cannot select a block".to_string()));
        }
        Ok(())
    }
}

impl Drop for Space {
    fn drop(&mut self) {
        // SAFETY: `self.0` is a dataspace this struct created.
        hdf5::sync::sync(|| unsafe { hdf5_sys::h5s::H5Sclose(self.0) });
    }
}

/// `(first window, first source row, length)`: a block of windows whose step maps onto
/// consecutive source rows.
type Run = (usize, usize, usize);

/// Adds `(window i, source row r)` to `runs` of consecutive window positions with consecutive
/// source rows: `(first window, first row, length)`.
fn extend_runs(runs: &mut Vec<Run>, i: usize, r: usize) {
    match runs.last_mut() {
        Some((i0, r0, n)) if *i0 + *n == i && *r0 + *n == r => *n += 1,
        _ => runs.push((i, r, 1)),
    }
}

/// `/chunks` of the `virtual` layout (action only). One pass over the windows builds the
/// mappings' row blocks directly and writes `action_is_pad` a block of windows at a time, so
/// memory holds the blocks and the pad rows, not K entries per window.
// Long function: the one pass over the windows that keeps memory bounded; split, it would be two passes.
pub fn virtual_action(file: &File, w: &Windows, action: &Stored) -> Result<()> {
    let g = chunks_group(file, w)?;
    let (n, k, a) = (w.rows.len(), w.window.chunk, action.width);
    let steps = w.episode_ends.total();
    let (is_pad_ds, _) = dense::<bool>(&g, "action_is_pad", vec![n, k], true)?;
    // Deflated chunks written in part complete in HDF5's chunk cache: no alignment needed.
    let block = (block_bytes() / k.max(1)).max(1);
    let mut is_pad: Vec<bool> = Vec::with_capacity(block.min(n) * k);
    let mut is_pad_lo = 0;
    // Pad rows in mapping order: per split, per step k, in window order.
    let mut pad_values: Vec<f32> = Vec::new();
    // Per (split, k): the row blocks of the valid steps (onto /data/action), then of the padded
    // ones (onto /chunks/action_pad).
    let mut mappings: Vec<(Vec<Run>, bool)> = Vec::new();
    let splits = [(0, w.num_train), (w.num_train, n)];
    for (lo, hi) in splits {
        let mut valid = vec![Vec::new(); k];
        let mut padded = vec![Vec::new(); k];
        // Per k: this split's pad rows, numbered from 0 until they are placed.
        let mut pads: Vec<Vec<f32>> = vec![Vec::new(); k];
        for i in lo..hi {
            let r = w.rows[i];
            let start = w.episode_ends.start(r[0] as usize);
            let resolved = w.window.action_steps(
                r[1] as usize,
                r[2] as usize,
                w.episode_ends.len_of(r[0] as usize),
            );
            for (step, s) in resolved.into_iter().enumerate() {
                match s {
                    Step::Row(row) => {
                        extend_runs(&mut valid[step], i, start + row);
                        is_pad.push(false);
                    }
                    Step::Pad(row) => {
                        extend_runs(&mut padded[step], i, pads[step].len() / a.max(1));
                        let edge = &action.values[(start + row) * a..(start + row + 1) * a];
                        let n = action.normalizer.at(start + row);
                        pads[step].extend(pad_row(w.padding, n, edge));
                        is_pad.push(true);
                    }
                }
            }
            if is_pad.len() == block * k {
                write_rows(&is_pad_ds, is_pad_lo, &is_pad)?;
                is_pad_lo += block;
                is_pad.clear();
            }
        }
        for (step, (valid, padded)) in valid.into_iter().zip(padded).enumerate() {
            let first = pad_values.len() / a.max(1);
            pad_values.extend_from_slice(&pads[step]);
            let padded = padded
                .into_iter()
                .map(|(i, r, len)| (i, first + r, len))
                .collect();
            mappings.push((valid, false));
            mappings.push((padded, true));
        }
    }
    if !is_pad.is_empty() {
        write_rows(&is_pad_ds, is_pad_lo, &is_pad)?;
    }
    let pad_rows = pad_values.len() / a.max(1);
    write_dense(&g, "action_pad", vec![pad_rows, a], &pad_values, false)?;

    // SAFETY (all calls below): ids are created here and closed before returning; strings are
    // NUL-terminated and outlive the calls; the HDF5 lock is held by `sync`.
    let dcpl = hdf5::sync::sync(|| unsafe {
        hdf5_sys::h5p::H5Pcreate(*hdf5_sys::h5p::H5P_CLS_DATASET_CREATE)
    });
    if dcpl < 0 {
        return Err(Error::output(
            "HDF5: cannot create a property list".to_string(),
        ));
    }
    // Modification times would make the bytes depend on the clock.
    hdf5::sync::sync(|| unsafe { hdf5_sys::h5p::H5Pset_obj_track_times(dcpl, 0) });
    let here = CString::new(".").unwrap();
    let data = CString::new("/data/action").unwrap();
    let pads = CString::new("/chunks/action_pad").unwrap();
    let mut result = Ok(());
    for (m, (blocks, is_pad_map)) in mappings.iter().enumerate() {
        if blocks.is_empty() {
            continue;
        }
        let step = (m / 2) % k;
        let source_rows = if *is_pad_map { pad_rows } else { steps };
        let mut vspace = Space::new(&[n, k, a])?;
        let mut sspace = Space::new(&[source_rows, a])?;
        for &(i, r, len) in blocks {
            vspace.add(&[i, step, 0], &[len, 1, a])?;
            sspace.add(&[r, 0], &[len, a])?;
        }
        let name = if *is_pad_map { &pads } else { &data };
        let status = hdf5::sync::sync(|| unsafe {
            hdf5_sys::h5p::H5Pset_virtual(dcpl, vspace.0, here.as_ptr(), name.as_ptr(), sspace.0)
        });
        if status < 0 {
            result = Err(Error::output(
                "HDF5: cannot add a virtual mapping".to_string(),
            ));
            break;
        }
    }
    if result.is_ok() {
        let space = Space::new(&[n, k, a])?;
        let name = CString::new("action").unwrap();
        let id = hdf5::sync::sync(|| unsafe {
            hdf5_sys::h5s::H5Sselect_all(space.0);
            hdf5_sys::h5d::H5Dcreate2(
                g.id(),
                name.as_ptr(),
                *hdf5_sys::h5t::H5T_NATIVE_FLOAT,
                space.0,
                hdf5_sys::h5p::H5P_DEFAULT,
                dcpl,
                hdf5_sys::h5p::H5P_DEFAULT,
            )
        });
        if id < 0 {
            result = Err(Error::output(
                "HDF5: cannot create the virtual dataset".to_string(),
            ));
        } else {
            hdf5::sync::sync(|| unsafe { hdf5_sys::h5d::H5Dclose(id) });
        }
    }
    hdf5::sync::sync(|| unsafe { hdf5_sys::h5p::H5Pclose(dcpl) });
    result
}

/// The stored (normalized) values of a padded step whose edge row is `edge`.
fn pad_row(padding: Padding, normalizer: &Normalizer, edge: &[f32]) -> Vec<f32> {
    match padding {
        Padding::Zero => (0..edge.len())
            .map(|d| normalizer.forward(d, 0.0) as f32)
            .collect(),
        Padding::Mask => vec![0.0; edge.len()],
        Padding::Edge | Padding::Truncate => edge.to_vec(),
    }
}
