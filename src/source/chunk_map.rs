//! Where the chunks of a chunked, unfiltered HDF5 dataset lie in its file, so that they can be
//! read (`pread`) or written (`pwrite`) without HDF5 and its global lock.
//!
//! The ALOHA adapter reads source frames stored one frame per chunk this way (episodes then read
//! in parallel), and the HDF5 writer writes uncompressed frames into chunks it allocated at
//! creation. Only datasets whose chunks are plain slabs of rows qualify: no filter, a chunk
//! shape of `(k, rest of the shape)`, every chunk allocated and full-sized; anything else goes
//! through HDF5.
//!
//! The map is compact: chunks that follow one another in the file form one run, so a dataset
//! written in order costs a few dozen bytes however many chunks it has.

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
pub struct ChunkMap {
    /// Rows (first axis) per chunk; the last chunk may hold fewer rows of the dataset, but its
    /// storage is full-sized.
    pub rows_per_chunk: usize,
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

impl ChunkMap {
    /// Builds a map from `(chunk index, file offset)` pairs in any order. `None` unless they
    /// are exactly chunks `0..n` (n chunks covering `rows` rows), each once.
    pub fn from_chunks(
        mut chunks: Vec<(u64, u64)>,
        rows_per_chunk: usize,
        row_bytes: usize,
        rows: usize,
    ) -> Option<ChunkMap> {
        if rows_per_chunk == 0 || row_bytes == 0 {
            return None;
        }
        let expected = rows.div_ceil(rows_per_chunk) as u64;
        if chunks.len() as u64 != expected {
            return None;
        }
        chunks.sort_unstable();
        let chunk_bytes = (rows_per_chunk * row_bytes) as u64;
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
        Some(ChunkMap {
            rows_per_chunk,
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
    pub fn chunk_bytes(&self) -> u64 {
        (self.rows_per_chunk * self.row_bytes) as u64
    }

    /// The file extents holding rows `lo..hi` (clamped to the dataset), in row order; rows
    /// contiguous in the file come as one extent.
    pub fn extents(&self, lo: usize, hi: usize) -> Vec<Extent> {
        let hi = hi.min(self.rows);
        let mut out: Vec<Extent> = Vec::new();
        if lo >= hi {
            return out;
        }
        let k = self.rows_per_chunk;
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

/// The chunk map of `ds`, when it qualifies (see the module documentation): chunked, no
/// filter, chunk shape `(k, rest of the shape)`, every chunk allocated and full-sized.
pub fn locate(ds: &Dataset) -> Option<ChunkMap> {
    let shape = ds.shape();
    let chunk = ds.chunk()?;
    if shape.is_empty() || chunk.len() != shape.len() || chunk[1..] != shape[1..] {
        return None;
    }
    if !ds.filters().is_empty() {
        return None;
    }
    let element = ds.dtype().ok()?.size();
    let row_bytes = shape[1..].iter().product::<usize>() * element;
    let rows_per_chunk = chunk[0];
    let chunk_bytes = (rows_per_chunk * row_bytes) as u64;

    struct Found {
        chunks: Vec<(u64, u64)>,
        rows_per_chunk: u64,
        chunk_bytes: u64,
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
        let first = unsafe { *offset };
        let whole = filter_mask == 0 && size == found.chunk_bytes && addr != haddr_t::MAX;
        if !whole || first % found.rows_per_chunk != 0 {
            found.ok = false;
            return 1; // stop: this dataset goes through HDF5
        }
        found.chunks.push((first / found.rows_per_chunk, addr));
        0
    }
    let mut found = Found {
        chunks: Vec::with_capacity(shape[0].div_ceil(rows_per_chunk.max(1))),
        rows_per_chunk: rows_per_chunk.max(1) as u64,
        chunk_bytes,
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
    if status < 0 || !found.ok {
        return None;
    }
    ChunkMap::from_chunks(found.chunks, rows_per_chunk, row_bytes, shape[0])
}

/// Reads rows `lo..hi` of a dataset mapped by `map` from `file` into `out` (exactly
/// `(hi - lo) * row_bytes` bytes), one `pread` per extent.
pub fn read_rows(
    file: &std::fs::File,
    map: &ChunkMap,
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
        let map = ChunkMap::from_chunks(chunks, 2, 4, 19).unwrap();
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
        let map = ChunkMap::from_chunks(chunks, 2, 4, 8).unwrap();
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
        assert!(ChunkMap::from_chunks(vec![(0, 0), (2, 16)], 2, 4, 6).is_none());
        assert!(ChunkMap::from_chunks(vec![(0, 0), (0, 8), (1, 16)], 2, 4, 6).is_none());
        assert!(ChunkMap::from_chunks(vec![(0, 0), (1, 8)], 2, 4, 6).is_none());
    }
}
