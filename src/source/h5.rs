// Long file: one helper set over the HDF5 library (open, list, typed and direct reads), shared by two adapters.
//! HDF5 reading shared by the `aloha` and `robomimic` adapters: opening with a clear error,
//! listing the datasets under a group, and reading one as `f32` or `u8`, through HDF5 or, where
//! the storage allows it, with plain `pread`s ([`direct`]).

use std::path::Path;

use hdf5::types::TypeDescriptor;
use hdf5::{Dataset, File, Group};

use super::block_map::{self, BlockMap, DeflatedMap};
use super::mapping::Raw;
use crate::error::{Error, Result};

/// Opens `path`, turning HDF5's error into one that names the file.
pub fn open(path: &Path) -> Result<File> {
    File::open(path).map_err(|e| {
        Error::source(format!(
            "{}: cannot open as HDF5 (corrupt, truncated, or not an HDF5 file): {e}",
            path.display()
        ))
    })
}

/// The group at `name` under `parent`, or an error naming the file and the group.
pub fn group(parent: &Group, name: &str, file: &Path) -> Result<Group> {
    parent.group(name).map_err(|e| {
        Error::source(format!(
            "{}: no group `{name}` under `{}`: {e}",
            file.display(),
            parent.name()
        ))
    })
}

/// The dataset at `name` under `parent`, or an error naming the file and the key.
pub fn dataset(parent: &Group, name: &str, file: &Path) -> Result<Dataset> {
    parent.dataset(name).map_err(|e| {
        Error::source(format!(
            "{}: cannot open dataset `{}/{name}`: {e}",
            file.display(),
            parent.name().trim_end_matches('/')
        ))
    })
}

/// Every dataset under `group`, recursively, as (path relative to `group`, dataset), sorted.
pub fn datasets(group: &Group, file: &Path) -> Result<Vec<(String, Dataset)>> {
    let mut out = Vec::new();
    let mut stack = vec![(String::new(), group.clone())];
    while let Some((prefix, g)) = stack.pop() {
        let names = g.member_names().map_err(|e| {
            Error::source(format!(
                "{}: cannot list `{}`: {e}",
                file.display(),
                g.name()
            ))
        })?;
        for name in names {
            let rel = if prefix.is_empty() {
                name.clone()
            } else {
                format!("{prefix}/{name}")
            };
            if let Ok(ds) = g.dataset(&name) {
                out.push((rel, ds));
            } else if let Ok(child) = g.group(&name) {
                stack.push((rel, child));
            }
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

/// The element type's name (`float32`, `uint8`, …).
pub fn dtype_name(ds: &Dataset) -> String {
    ds.dtype()
        .and_then(|t| t.to_descriptor())
        .map(|d| d.to_string())
        .unwrap_or_else(|_| "unknown".into())
}

/// Whether values of this element type can be read as numbers.
pub fn is_numeric(ds: &Dataset) -> bool {
    matches!(
        ds.dtype().and_then(|t| t.to_descriptor()),
        Ok(TypeDescriptor::Integer(_) | TypeDescriptor::Unsigned(_) | TypeDescriptor::Float(_))
    )
}

/// A dataset's per-step shape (after the time axis); a 1-D array has `[1]`.
pub fn step_shape(ds: &Dataset) -> Vec<usize> {
    let shape = ds.shape();
    if shape.len() <= 1 {
        vec![1]
    } else {
        shape[1..].to_vec()
    }
}

/// Number of steps (the first axis).
pub fn steps(ds: &Dataset) -> usize {
    ds.shape().first().copied().unwrap_or(0)
}

/// Reads a whole dataset: `uint8` as bytes, any other numeric type converted to `f32`.
pub fn read(ds: &Dataset, what: impl Fn() -> String) -> Result<Raw> {
    let fail = |e: hdf5::Error| Error::source(format!("{}: cannot read: {e}", what()));
    if !is_numeric(ds) {
        return Err(Error::source(format!(
            "{}: element type {} is not numeric",
            what(),
            dtype_name(ds)
        )));
    }
    if dtype_name(ds) == "uint8" {
        ds.read_raw::<u8>().map(Raw::U8).map_err(fail)
    } else {
        ds.read_raw::<f32>().map(Raw::F32).map_err(fail)
    }
}

/// Where a dataset's values lie in its file, so that they can be read with plain `pread`s (and
/// inflated) outside HDF5's global lock (episodes then decode in parallel).
#[derive(Debug, Clone, PartialEq)]
pub struct Direct {
    pub place: Place,
    /// Number of elements.
    pub elements: usize,
    pub dtype: DirectType,
}

/// Contiguous storage, or chunks that are slabs of rows (plain or deflated).
#[derive(Debug, Clone, PartialEq)]
pub enum Place {
    /// Byte offset of the first element in the file.
    Contiguous(u64),
    Chunked(BlockMap),
    /// Deflate-compressed chunks of whole rows.
    Deflated(DeflatedMap),
}

/// The little-endian element types read directly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DirectType {
    F32,
    F64,
    U8,
}

impl DirectType {
    fn size(self) -> usize {
        match self {
            DirectType::F32 => 4,
            DirectType::F64 => 8,
            DirectType::U8 => 1,
        }
    }
}

/// The dataset's location for [`read_direct`], when its layout allows it: f32, f64 or u8
/// little-endian values, either in contiguous storage that is allocated and in the file itself
/// (not external), or chunked as [`block_map::locate`] accepts (no filter, chunks of whole rows,
/// all allocated: ALOHA's one-frame-per-chunk images), or in chunks of whole rows compressed
/// with the deflate filter alone ([`block_map::locate_deflated`]: robomimic's gzip frames).
/// `None` for anything else (other filters, compact, partly allocated, other types): those are
/// read through HDF5.
pub fn direct(ds: &Dataset) -> Option<Direct> {
    use hdf5::types::{FloatSize, IntSize};
    use hdf5_sys::h5t::{H5T_order_t, H5Tget_order};
    let dtype = match ds.dtype().and_then(|t| t.to_descriptor()).ok()? {
        TypeDescriptor::Float(FloatSize::U4) => DirectType::F32,
        TypeDescriptor::Float(FloatSize::U8) => DirectType::F64,
        TypeDescriptor::Unsigned(IntSize::U1) => DirectType::U8,
        _ => return None,
    };
    let elements: usize = ds.shape().iter().product();
    let file_type = ds.dtype().ok()?;
    // SAFETY: both ids are valid while `ds` and `file_type` live; the calls only read metadata,
    // under HDF5's global lock.
    let (offset, storage, order) = hdf5::sync::sync(|| unsafe {
        (
            hdf5_sys::h5d::H5Dget_offset(ds.id()),
            hdf5_sys::h5d::H5Dget_storage_size(ds.id()),
            H5Tget_order(file_type.id()),
        )
    });
    let little = order == H5T_order_t::H5T_ORDER_LE || dtype == DirectType::U8;
    if !little {
        return None;
    }
    // HADDR_UNDEF (all ones): not contiguous, not allocated, or external.
    let place = if offset != u64::MAX && storage == (elements * dtype.size()) as u64 {
        Place::Contiguous(offset)
    } else if ds.is_chunked() {
        match block_map::locate(ds) {
            Some(map) => Place::Chunked(map),
            None => Place::Deflated(block_map::locate_deflated(ds)?),
        }
    } else {
        return None;
    };
    Some(Direct {
        place,
        elements,
        dtype,
    })
}

/// The number of storage chunks of a dataset located by [`direct`] (contiguous storage: one).
pub fn direct_chunks(d: &Direct) -> u64 {
    match &d.place {
        Place::Contiguous(_) => 1,
        Place::Chunked(map) => map.rows.div_ceil(map.rows_per_block.max(1)) as u64,
        Place::Deflated(map) => map.rows.div_ceil(map.rows_per_block.max(1)) as u64,
    }
}

/// The number of storage chunks of `ds` (allocated ones; contiguous or compact storage: one).
pub fn chunks(ds: &Dataset) -> u64 {
    if ds.is_chunked() {
        ds.num_chunks().unwrap_or(1) as u64
    } else {
        1
    }
}

/// Reads a dataset located by [`direct`] from `file` (opened with std, no HDF5 involved):
/// `uint8` as bytes, floats converted to `f32` as [`read`] does.
pub fn read_direct(file: &std::fs::File, d: &Direct) -> std::io::Result<Raw> {
    use std::os::unix::fs::FileExt;
    // Wherever the bytes lie, they are read into `out`.
    let fill = |out: &mut [u8]| -> std::io::Result<()> {
        match &d.place {
            Place::Contiguous(offset) => file.read_exact_at(out, *offset),
            Place::Chunked(map) => block_map::read_rows(file, map, 0, out),
            Place::Deflated(map) => block_map::read_deflated(file, map, out),
        }
    };
    Ok(match d.dtype {
        DirectType::U8 => {
            let mut bytes = vec![0u8; d.elements];
            fill(&mut bytes)?;
            Raw::U8(bytes)
        }
        // Straight into the values: no byte buffer, no second copy.
        DirectType::F32 => {
            let mut values = vec![0f32; d.elements];
            fill(crate::bytes::f32_bytes_mut(&mut values))?;
            crate::bytes::from_le(&mut values);
            Raw::F32(values)
        }
        DirectType::F64 => {
            let mut bytes = vec![0u8; d.elements * d.dtype.size()];
            fill(&mut bytes)?;
            Raw::F32(
                bytes
                    .chunks_exact(8)
                    .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")) as f32)
                    .collect(),
            )
        }
    })
}

/// Reads a 1-D array of strings (fixed- or variable-length), as robomimic's masks are stored.
pub fn read_strings(ds: &Dataset) -> std::result::Result<Vec<String>, String> {
    use hdf5::types::{FixedAscii, VarLenAscii, VarLenUnicode};
    match ds.dtype().and_then(|t| t.to_descriptor()) {
        Ok(TypeDescriptor::FixedAscii(_) | TypeDescriptor::FixedUnicode(_)) => ds
            .read_raw::<FixedAscii<256>>()
            .map(|v| v.iter().map(|s| s.as_str().to_string()).collect())
            .map_err(|e| e.to_string()),
        Ok(TypeDescriptor::VarLenAscii) => ds
            .read_raw::<VarLenAscii>()
            .map(|v| v.iter().map(|s| s.as_str().to_string()).collect())
            .map_err(|e| e.to_string()),
        Ok(TypeDescriptor::VarLenUnicode) => ds
            .read_raw::<VarLenUnicode>()
            .map(|v| v.iter().map(|s| s.as_str().to_string()).collect())
            .map_err(|e| e.to_string()),
        Ok(other) => Err(format!("expected strings, found {other}")),
        Err(e) => Err(e.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames (t, 4, 5, 3) with a distinct value per byte.
    fn frames(t: usize) -> ndarray::Array4<u8> {
        ndarray::Array4::from_shape_fn((t, 4, 5, 3), |(i, y, x, c)| {
            (i * 7 + y * 31 + x * 3 + c * 101) as u8
        })
    }

    fn direct_bytes(path: &Path, ds: &Dataset) -> Option<Vec<u8>> {
        let d = direct(ds)?;
        let file = std::fs::File::open(path).unwrap();
        match read_direct(&file, &d).unwrap() {
            Raw::U8(v) => Some(v),
            Raw::F32(_) => panic!("u8 read as f32"),
        }
    }

    #[test]
    fn chunked_frames_read_directly_equal_hdf5s_reading() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frames.hdf5");
        let data = frames(11);
        {
            let f = File::create(&path).unwrap();
            // One frame per chunk (ALOHA), and 3 rows per chunk with a partial last chunk.
            for (name, rows) in [("one", 1), ("three", 3)] {
                f.new_dataset::<u8>()
                    .shape(data.shape())
                    .chunk([rows, 4, 5, 3])
                    .create(name)
                    .unwrap()
                    .write(&data)
                    .unwrap();
            }
            // Chunks written out of order: the map has several runs.
            let ds = f
                .new_dataset::<u8>()
                .shape(data.shape())
                .chunk([1, 4, 5, 3])
                .create("shuffled")
                .unwrap();
            for t in [5, 0, 10, 3, 1, 2, 4, 9, 6, 8, 7] {
                ds.write_slice(
                    data.slice(ndarray::s![t..t + 1, .., .., ..]),
                    ndarray::s![t..t + 1, .., .., ..],
                )
                .unwrap();
            }
        }
        let f = File::open(&path).unwrap();
        for name in ["one", "three", "shuffled"] {
            let ds = f.dataset(name).unwrap();
            let d = direct(&ds).expect("located");
            assert!(matches!(d.place, Place::Chunked(_)), "{name}");
            let through_hdf5 = ds.read_raw::<u8>().unwrap();
            assert_eq!(direct_bytes(&path, &ds).unwrap(), through_hdf5, "{name}");
            assert_eq!(through_hdf5, data.as_slice().unwrap(), "{name}");
        }
        if let Place::Chunked(map) = direct(&f.dataset("shuffled").unwrap()).unwrap().place {
            assert!(map.runs().len() > 1);
        }
    }

    #[test]
    fn deflated_chunks_read_directly_equal_hdf5s_reading() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frames.hdf5");
        let data = frames(11);
        let lowdim = ndarray::Array2::from_shape_fn((11, 7), |(t, d)| (t as f64).sin() + d as f64);
        {
            let f = File::create(&path).unwrap();
            // One frame per chunk (robomimic), and 3 rows per chunk with a partial last chunk.
            for (name, rows) in [("one", 1), ("three", 3)] {
                f.new_dataset::<u8>()
                    .shape(data.shape())
                    .chunk([rows, 4, 5, 3])
                    .deflate(4)
                    .create(name)
                    .unwrap()
                    .write(&data)
                    .unwrap();
            }
            f.new_dataset::<f64>()
                .shape(lowdim.shape())
                .chunk([4, 7])
                .deflate(9)
                .create("lowdim")
                .unwrap()
                .write(&lowdim)
                .unwrap();
        }
        let f = File::open(&path).unwrap();
        for name in ["one", "three"] {
            let ds = f.dataset(name).unwrap();
            let d = direct(&ds).expect("located");
            assert!(matches!(d.place, Place::Deflated(_)), "{name}");
            let through_hdf5 = ds.read_raw::<u8>().unwrap();
            assert_eq!(direct_bytes(&path, &ds).unwrap(), through_hdf5, "{name}");
            assert_eq!(through_hdf5, data.as_slice().unwrap(), "{name}");
        }
        let ds = f.dataset("lowdim").unwrap();
        let file = std::fs::File::open(&path).unwrap();
        match read_direct(&file, &direct(&ds).expect("located")).unwrap() {
            Raw::F32(v) => {
                let want: Vec<f32> = lowdim.iter().map(|&x| x as f32).collect();
                assert_eq!(v, want);
            }
            Raw::U8(_) => panic!("f64 read as u8"),
        }
    }

    #[test]
    fn a_damaged_deflated_chunk_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frames.hdf5");
        {
            let f = File::create(&path).unwrap();
            f.new_dataset::<u8>()
                .shape([3, 4, 5, 3])
                .chunk([1, 4, 5, 3])
                .deflate(1)
                .create("gzip")
                .unwrap()
                .write(&frames(3))
                .unwrap();
        }
        let d = direct(&File::open(&path).unwrap().dataset("gzip").unwrap()).unwrap();
        let Place::Deflated(map) = &d.place else {
            panic!("not located as deflated chunks");
        };
        // Overwrite the middle of chunk 1's stored bytes.
        let (offset, size) = map.block(1);
        {
            use std::os::unix::fs::FileExt;
            let file = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
            file.write_all_at(&vec![0xA5; size as usize / 2], offset + size / 4)
                .unwrap();
        }
        let file = std::fs::File::open(&path).unwrap();
        let e = read_direct(&file, &d).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidData, "{e}");
        assert!(e.to_string().contains("chunk 1"), "{e}");
    }

    #[test]
    fn other_filters_or_partly_written_chunks_go_through_hdf5() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frames.hdf5");
        let data = frames(6);
        {
            let f = File::create(&path).unwrap();
            f.new_dataset::<u8>()
                .shape(data.shape())
                .chunk([1, 4, 5, 3])
                .shuffle()
                .deflate(1)
                .create("shuffle_gzip")
                .unwrap()
                .write(&data)
                .unwrap();
            f.new_dataset::<u8>()
                .shape(data.shape())
                .chunk([1, 4, 5, 3])
                .lzf()
                .create("lzf")
                .unwrap()
                .write(&data)
                .unwrap();
            // Only frames 0..2 written: the other chunks are not allocated.
            for (name, gzip) in [("partial", false), ("partial_gzip", true)] {
                let b = f
                    .new_dataset::<u8>()
                    .shape(data.shape())
                    .chunk([1, 4, 5, 3]);
                let b = if gzip { b.deflate(1) } else { b };
                b.create(name)
                    .unwrap()
                    .write_slice(
                        data.slice(ndarray::s![0..2, .., .., ..]),
                        ndarray::s![0..2, .., .., ..],
                    )
                    .unwrap();
            }
            // Chunks that split a frame.
            f.new_dataset::<u8>()
                .shape(data.shape())
                .chunk([1, 2, 5, 3])
                .deflate(1)
                .create("split")
                .unwrap()
                .write(&data)
                .unwrap();
        }
        let f = File::open(&path).unwrap();
        for name in ["shuffle_gzip", "lzf", "partial", "partial_gzip", "split"] {
            assert!(direct(&f.dataset(name).unwrap()).is_none(), "{name}");
        }
    }
}
