//! Where the blocks of a chunked HDF5 dataset lie in its file, so that they can be read
//! (`pread`) or written (`pwrite`) without HDF5 and its global lock.
//!
//! A *block* is one storage chunk of a file (what HDF5 and zarr call a chunk, what parquet calls
//! a row group); chunkc keeps the word *chunk* for the action chunk. Below, "chunk" appears only
//! where HDF5's own API is meant.
//!
//! The ALOHA and robomimic adapters read source frames stored one frame per block this way
//! (episodes then read in parallel), and the HDF5 writer writes uncompressed frames into blocks
//! it allocated at creation. Only datasets whose blocks are slabs of whole rows (a chunk shape
//! of `(k, rest of the shape)`), every one allocated, qualify: either unfiltered and full-sized
//! ([`BlockMap`]), or compressed with the deflate filter alone ([`DeflatedMap`], inflated here
//! with zlib); anything else goes through HDF5.
//!
//! The map is compact: blocks that follow one another in the file form one run, so a dataset
//! written in order costs a few dozen bytes however many blocks it has.

use hdf5::Dataset;
use hdf5_sys::h5::{haddr_t, hsize_t};

/// Chunks stored one after another in the file: chunk `first + i` starts at
/// `offset + i * chunk_bytes`, for `i < count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Run {
    pub first: u64,
    pub offset: u64,
    pub count: u64,
}

/// The chunk locations of one dataset.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BlockMap {
    /// Rows (first axis) per chunk; the last chunk may hold fewer rows of the dataset, but its
    /// storage is full-sized.
    pub rows_per_block: usize,
    /// Bytes of one row (one step).
    pub row_bytes: usize,
    /// Rows of the dataset.
    pub rows: usize,
    /// In chunk order, covering every chunk.
    runs: Vec<Run>,
}

/// One piece of a read or write: `rows` dataset rows from `row`, at file offset `offset`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Extent {
    pub row: usize,
    pub rows: usize,
    pub offset: u64,
}

impl BlockMap {
    /// Builds a map from `(chunk index, file offset)` pairs in any order. `None` unless they
    /// are exactly chunks `0..n` (n chunks covering `rows` rows), each once.
    pub fn from_blocks(
        mut chunks: Vec<(u64, u64)>,
        rows_per_block: usize,
        row_bytes: usize,
        rows: usize,
    ) -> Option<BlockMap> {
        if rows_per_block == 0 || row_bytes == 0 {
            return None;
        }
        let expected = rows.div_ceil(rows_per_block) as u64;
        if chunks.len() as u64 != expected {
            return None;
        }
        chunks.sort_unstable();
        let chunk_bytes = (rows_per_block * row_bytes) as u64;
        let mut runs: Vec<Run> = Vec::new();
        for (i, &(index, offset)) in chunks.iter().enumerate() {
            if index != i as u64 {
                return None;
            }
            match runs.last_mut() {
                Some(r) if r.offset + r.count * chunk_bytes == offset => r.count += 1,
                _ => runs.push(Run {
                    first: index,
                    offset,
                    count: 1,
                }),
            }
        }
        Some(BlockMap {
            rows_per_block,
            row_bytes,
            rows,
            runs,
        })
    }

    /// The runs of chunks (a handful for a dataset written in order).
    pub fn runs(&self) -> &[Run] {
        &self.runs
    }

    /// Bytes of one chunk's storage.
    pub fn block_bytes(&self) -> u64 {
        (self.rows_per_block * self.row_bytes) as u64
    }

    /// The file extents holding rows `lo..hi` (clamped to the dataset), in row order; rows
    /// contiguous in the file come as one extent.
    pub fn extents(&self, lo: usize, hi: usize) -> Vec<Extent> {
        let hi = hi.min(self.rows);
        let mut out: Vec<Extent> = Vec::new();
        if lo >= hi {
            return out;
        }
        let k = self.rows_per_block;
        // The first run that may hold chunk `lo / k`.
        let start = self
            .runs
            .partition_point(|r| r.first + r.count <= (lo / k) as u64);
        for r in &self.runs[start..] {
            let run_lo = r.first as usize * k;
            if run_lo >= hi {
                break;
            }
            let run_hi = (r.first + r.count) as usize * k;
            let (a, b) = (lo.max(run_lo), hi.min(run_hi));
            if a < b {
                out.push(Extent {
                    row: a,
                    rows: b - a,
                    offset: r.offset + ((a - run_lo) * self.row_bytes) as u64,
                });
            }
        }
        out
    }
}

/// One allocated chunk as HDF5 reports it.
struct Chunk {
    /// Its first row.
    first_row: u64,
    filter_mask: u32,
    addr: u64,
    size: u64,
}

/// Every chunk of `ds` (through `H5Dchunk_iter`, under HDF5's global lock), or `None` when one
/// is unallocated or HDF5 cannot list them.
fn chunks(ds: &Dataset, expected: usize) -> Option<Vec<Chunk>> {
    struct Found {
        chunks: Vec<Chunk>,
        ok: bool,
    }
    unsafe extern "C" fn each(
        offset: *const hsize_t,
        filter_mask: std::ffi::c_uint,
        addr: haddr_t,
        size: hsize_t,
        data: *mut std::ffi::c_void,
    ) -> std::ffi::c_int {
        // SAFETY: `data` is the `Found` passed to `H5Dchunk_iter` below, alive for the call;
        // `offset` has one entry per dimension (the first is the one read here).
        let found = unsafe { &mut *data.cast::<Found>() };
        if addr == haddr_t::MAX {
            found.ok = false;
            return 1; // stop: this dataset goes through HDF5
        }
        found.chunks.push(Chunk {
            first_row: unsafe { *offset },
            filter_mask,
            addr,
            size,
        });
        0
    }
    let mut found = Found {
        chunks: Vec::with_capacity(expected),
        ok: true,
    };
    // SAFETY: the dataset id is valid while `ds` lives; the callback only touches `found`,
    // which outlives the call; HDF5's global lock is held by `sync`.
    let status = hdf5::sync::sync(|| unsafe {
        hdf5_sys::h5d::H5Dchunk_iter(
            ds.id(),
            hdf5_sys::h5p::H5P_DEFAULT,
            Some(each),
            (&mut found as *mut Found).cast(),
        )
    });
    (status >= 0 && found.ok).then_some(found.chunks)
}

/// Rows per chunk and bytes per row of a chunked dataset whose chunks are slabs of whole rows
/// (chunk shape `(k, rest of the shape)`).
fn row_slabs(ds: &Dataset) -> Option<(usize, usize)> {
    let shape = ds.shape();
    let chunk = ds.chunk()?;
    if shape.is_empty() || chunk.len() != shape.len() || chunk[1..] != shape[1..] || chunk[0] == 0 {
        return None;
    }
    let element = ds.dtype().ok()?.size();
    Some((chunk[0], shape[1..].iter().product::<usize>() * element))
}

/// The chunk map of `ds`, when it qualifies (see the module documentation): chunked, no
/// filter, chunk shape `(k, rest of the shape)`, every chunk allocated and full-sized.
pub fn locate(ds: &Dataset) -> Option<BlockMap> {
    if !ds.filters().is_empty() {
        return None;
    }
    let (rows_per_block, row_bytes) = row_slabs(ds)?;
    let rows = ds.shape()[0];
    let chunk_bytes = (rows_per_block * row_bytes) as u64;
    let all = chunks(ds, rows.div_ceil(rows_per_block))?;
    let mut pairs = Vec::with_capacity(all.len());
    for c in all {
        if c.filter_mask != 0 || c.size != chunk_bytes || c.first_row % rows_per_block as u64 != 0 {
            return None;
        }
        pairs.push((c.first_row / rows_per_block as u64, c.addr));
    }
    BlockMap::from_blocks(pairs, rows_per_block, row_bytes, rows)
}

/// Where the chunks of a deflate-compressed dataset lie (robomimic's and compressed ALOHA
/// recordings' frames: one gzip-filtered chunk per frame): each chunk's offset and stored size,
/// in row order, so that they can be read and inflated on any thread.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeflatedMap {
    pub rows_per_block: usize,
    pub row_bytes: usize,
    pub rows: usize,
    /// (file offset, stored bytes) of chunk `i`.
    chunks: Vec<(u64, u64)>,
}

impl DeflatedMap {
    /// (file offset, stored bytes) of chunk `i`.
    pub fn block(&self, i: usize) -> (u64, u64) {
        self.chunks[i]
    }
}

/// The deflated map of `ds`: chunks of whole rows, the deflate filter alone (no shuffle, no
/// checksum), every chunk allocated and filtered. `None` for anything else.
pub fn locate_deflated(ds: &Dataset) -> Option<DeflatedMap> {
    if !matches!(ds.filters().as_slice(), [hdf5::filters::Filter::Deflate(_)]) {
        return None;
    }
    let (rows_per_block, row_bytes) = row_slabs(ds)?;
    let rows = ds.shape()[0];
    let n = rows.div_ceil(rows_per_block);
    let mut slots: Vec<Option<(u64, u64)>> = vec![None; n];
    for c in chunks(ds, n)? {
        let i = c.first_row / rows_per_block as u64;
        let slot = slots.get_mut(i as usize)?;
        if c.filter_mask != 0 || c.first_row % rows_per_block as u64 != 0 || slot.is_some() {
            return None;
        }
        *slot = Some((c.addr, c.size));
    }
    Some(DeflatedMap {
        rows_per_block,
        row_bytes,
        rows,
        chunks: slots.into_iter().collect::<Option<_>>()?,
    })
}

/// Reads every row of a dataset mapped by `map` from `file` into `out` (`rows * row_bytes`
/// bytes): one `pread` and one inflate per chunk, straight into `out` but for a last chunk that
/// reaches past the dataset's rows.
pub fn read_deflated(
    file: &std::fs::File,
    map: &DeflatedMap,
    out: &mut [u8],
) -> std::io::Result<()> {
    use std::os::unix::fs::FileExt;
    let chunk_bytes = map.rows_per_block * map.row_bytes;
    let bad = |what: String| std::io::Error::new(std::io::ErrorKind::InvalidData, what);
    if out.len() != map.rows * map.row_bytes {
        return Err(bad(format!(
            "{} bytes asked for a dataset of {}",
            out.len(),
            map.rows * map.row_bytes
        )));
    }
    let mut stored = Vec::new();
    let mut tail = Vec::new();
    let mut z = flate2::Decompress::new(true);
    for (i, &(offset, size)) in map.chunks.iter().enumerate() {
        stored.resize(size as usize, 0);
        file.read_exact_at(&mut stored, offset)?;
        let lo = i * chunk_bytes;
        let hi = (lo + chunk_bytes).min(out.len());
        // The last chunk's storage holds a whole chunk: inflate it aside, keep the rows.
        let target: &mut [u8] = if hi - lo == chunk_bytes {
            &mut out[lo..hi]
        } else {
            tail.resize(chunk_bytes, 0);
            &mut tail
        };
        z.reset(true);
        let status = z
            .decompress(&stored, target, flate2::FlushDecompress::Finish)
            .map_err(|e| bad(format!("chunk {i}: {e}")))?;
        if status != flate2::Status::StreamEnd || z.total_out() != chunk_bytes as u64 {
            return Err(bad(format!(
                "chunk {i}: inflates to {} bytes, expected {chunk_bytes}",
                z.total_out()
            )));
        }
        if hi - lo != chunk_bytes {
            out[lo..hi].copy_from_slice(&tail[..hi - lo]);
        }
    }
    Ok(())
}

/// Reads rows `lo..hi` of a dataset mapped by `map` from `file` into `out` (exactly
/// `(hi - lo) * row_bytes` bytes), one `pread` per extent.
pub fn read_rows(
    file: &std::fs::File,
    map: &BlockMap,
    lo: usize,
    out: &mut [u8],
) -> std::io::Result<()> {
    use std::os::unix::fs::FileExt;
    let hi = lo + out.len() / map.row_bytes.max(1);
    for e in map.extents(lo, hi) {
        let at = (e.row - lo) * map.row_bytes;
        file.read_exact_at(&mut out[at..at + e.rows * map.row_bytes], e.offset)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adjacent_chunks_form_one_run() {
        let chunks = (0..10u64).rev().map(|i| (i, 1000 + i * 8)).collect();
        let map = BlockMap::from_blocks(chunks, 2, 4, 19).unwrap();
        assert_eq!(map.runs().len(), 1);
        assert_eq!(
            map.extents(3, 19),
            vec![Extent {
                row: 3,
                rows: 16,
                offset: 1000 + 12
            }]
        );
    }

    #[test]
    fn gaps_split_runs_and_extents() {
        // Chunk 2 lies elsewhere: rows 4..6.
        let chunks = vec![(0, 0), (1, 8), (2, 500), (3, 24)];
        let map = BlockMap::from_blocks(chunks, 2, 4, 8).unwrap();
        assert_eq!(map.runs().len(), 3);
        let e = map.extents(1, 8);
        assert_eq!(
            e,
            vec![
                Extent {
                    row: 1,
                    rows: 3,
                    offset: 4
                },
                Extent {
                    row: 4,
                    rows: 2,
                    offset: 500
                },
                Extent {
                    row: 6,
                    rows: 2,
                    offset: 24
                },
            ]
        );
        assert!(map.extents(8, 9).is_empty());
    }

    #[test]
    fn missing_or_repeated_chunks_are_refused() {
        assert!(BlockMap::from_blocks(vec![(0, 0), (2, 16)], 2, 4, 6).is_none());
        assert!(BlockMap::from_blocks(vec![(0, 0), (0, 8), (1, 16)], 2, 4, 6).is_none());
        assert!(BlockMap::from_blocks(vec![(0, 0), (1, 8)], 2, 4, 6).is_none());
    }
}
