// Long file: one adapter: zarr v2 and v3 metadata, chunk geometry and the reads share the array model.
//! Diffusion Policy's zarr ReplayBuffer: all episodes concatenated along axis 0 of `data/<key>`,
//! with `meta/episode_ends` holding the exclusive cumulative ends.
//!
//! Episodes are read chunk by chunk through a [`BlockCache`]: a chunk that spans several
//! episodes (Diffusion Policy's ~2 MB chunks, or zarr-python's default chunking, which also
//! splits the columns) is decoded once, by the first episode that needs it, and each episode
//! copies its rows out of the decoded chunks.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use zarrs::array::{Array, ArraySubset};
use zarrs::filesystem::FilesystemStore;

use super::block_cache::{self, BlockCache, DecodeCounts};
use super::mapping::{self, KeyInfo, Mapped, Raw};
use super::zarr_read_store::ReadStore;
use super::{fingerprint, Episode, EpisodeInfo, Manifest, Source};
use crate::error::{Error, Result};
use crate::spec::{LoadedSpec, SourceFormat};

type ZArray = Array<ReadStore>;

pub struct DpZarrSource {
    root: PathBuf,
    manifest: Manifest,
    /// Cumulative episode starts (len = episodes + 1).
    bounds: Vec<u64>,
    /// The arrays the channels read, by key, with their chunk grids.
    arrays: BTreeMap<String, Chunked>,
    mapped: Mapped,
    /// Decoded chunks, keyed by (array position in `arrays`, chunk grid index).
    cache: BlockCache<(usize, Vec<u64>), Decoded>,
}

/// One array and where its chunks lie.
struct Chunked {
    array: ZArray,
    /// Its position among the source's arrays (the cache key's first part).
    index: usize,
    shape: Vec<usize>,
    /// Per axis, the (first element, length) of each chunk along it.
    grid: Vec<Vec<(usize, usize)>>,
    /// Per chunk along the time axis: the episode reads that take rows from it.
    users: Vec<u32>,
    dtype: String,
}

/// A decoded chunk, as the channels take it (every numeric type but `uint8` as `f32`).
enum Decoded {
    F32(Vec<f32>),
    U8(Vec<u8>),
}

/// Codec options for decoding one chunk: no parallelism inside the decode (episodes already
/// decode in parallel, and a rayon worker waiting inside a decode could otherwise be handed the
/// read of an episode that waits for that very chunk).
fn one_thread() -> zarrs::array::CodecOptions {
    let mut o = zarrs::array::CodecOptions::default();
    o.set_concurrent_target(1);
    o
}

impl Chunked {
    fn new(array: ZArray, index: usize) -> std::result::Result<Chunked, String> {
        let shape: Vec<usize> = array.shape().iter().map(|&d| d as usize).collect();
        let grid_shape = array.chunk_grid_shape().to_vec();
        let mut grid = Vec::with_capacity(shape.len());
        for (axis, &n) in grid_shape.iter().enumerate() {
            let mut along = Vec::with_capacity(n as usize);
            for i in 0..n {
                let mut idx = vec![0u64; shape.len()];
                idx[axis] = i;
                let sub = array.chunk_subset(&idx).map_err(|e| e.to_string())?;
                along.push((sub.start()[axis] as usize, sub.shape()[axis] as usize));
            }
            grid.push(along);
        }
        let dtype = dtype_name(&array);
        Ok(Chunked {
            array,
            index,
            shape,
            grid,
            users: Vec::new(),
            dtype,
        })
    }

    /// Counts, for each chunk along time, the episodes among `bounds` (positions `reading`)
    /// that overlap it.
    fn count_users(&mut self, bounds: &[u64], reading: &[usize]) {
        let starts: Vec<u64> = self
            .grid
            .first()
            .map_or(Vec::new(), |g| g.iter().map(|&(s, _)| s as u64).collect());
        let episodes: Vec<std::ops::Range<u64>> =
            reading.iter().map(|&i| bounds[i]..bounds[i + 1]).collect();
        let rows = self.shape.first().copied().unwrap_or(0) as u64;
        self.users = block_cache::users_per_block(&episodes, &starts, rows);
    }

    /// Decodes chunk `idx` whole (its full chunk shape, edges included).
    /// Chunk `idx` decoded, or an error naming its file in the store.
    fn decode(&self, idx: &[u64]) -> std::result::Result<(Decoded, usize), String> {
        self.decode_values(idx)
            .map_err(|e| format!("chunk file {}: {e}", self.array.chunk_key(idx)))
    }

    fn decode_values(&self, idx: &[u64]) -> std::result::Result<(Decoded, usize), String> {
        let o = one_thread();
        macro_rules! conv {
            ($t:ty) => {
                self.array
                    .retrieve_chunk_opt::<Vec<$t>>(idx, &o)
                    .map(|v| v.into_iter().map(|x| x as f32).collect::<Vec<f32>>())
                    .map_err(|e| e.to_string())?
            };
        }
        let values = match self.dtype.as_str() {
            "uint8" => {
                let v = self
                    .array
                    .retrieve_chunk_opt::<Vec<u8>>(idx, &o)
                    .map_err(|e| e.to_string())?;
                let n = v.len();
                return Ok((Decoded::U8(v), n));
            }
            "float32" => self
                .array
                .retrieve_chunk_opt::<Vec<f32>>(idx, &o)
                .map_err(|e| e.to_string())?,
            "float64" => conv!(f64),
            "int8" => conv!(i8),
            "int16" => conv!(i16),
            "int32" => conv!(i32),
            "int64" => conv!(i64),
            "uint16" => conv!(u16),
            "uint32" => conv!(u32),
            "uint64" => conv!(u64),
            "bool" => self
                .array
                .retrieve_chunk_opt::<Vec<bool>>(idx, &o)
                .map(|v| v.into_iter().map(|x| x as u8 as f32).collect())
                .map_err(|e| e.to_string())?,
            other => return Err(format!("unsupported element type {other}")),
        };
        let n = values.len() * 4;
        Ok((Decoded::F32(values), n))
    }
}

/// Copies the rows `rows` (array rows) of a decoded chunk into `out`, which holds whole array
/// rows from `out_row` on. The chunk starts at `origin` and has (full) shape `chunk`; the array
/// has shape `shape`, so the chunk's elements past the array's edge are skipped.
fn copy_from_chunk<T: Copy>(
    src: &[T],
    chunk: &[usize],
    origin: &[usize],
    shape: &[usize],
    rows: std::ops::Range<usize>,
    out_row: usize,
    out: &mut [T],
) {
    let n = shape.len();
    if n <= 1 {
        let (a, b) = (rows.start - origin[0], rows.end - origin[0]);
        out[rows.start - out_row..rows.end - out_row].copy_from_slice(&src[a..b]);
        return;
    }
    let chunk_row: usize = chunk[1..].iter().product();
    let array_row: usize = shape[1..].iter().product();
    if chunk[1..] == shape[1..] {
        // Whole rows: one run.
        let (a, b) = (
            (rows.start - origin[0]) * chunk_row,
            (rows.end - origin[0]) * chunk_row,
        );
        let at = (rows.start - out_row) * array_row;
        out[at..at + (b - a)].copy_from_slice(&src[a..b]);
        return;
    }
    // The part of the chunk inside the array along every axis after time.
    let inside: Vec<usize> = (1..n)
        .map(|d| chunk[d].min(shape[d].saturating_sub(origin[d])))
        .collect();
    if inside.contains(&0) {
        return;
    }
    let run = inside[n - 2];
    // Strides (elements) along axes 1..n of the chunk and of the array.
    let stride = |dims: &[usize]| -> Vec<usize> {
        let mut s = vec![1usize; n - 1];
        for d in (0..n - 2).rev() {
            s[d] = s[d + 1] * dims[d + 2];
        }
        s
    };
    let (cs, ss) = (stride(chunk), stride(shape));
    let base: usize = (1..n).map(|d| origin[d] * ss[d - 1]).sum();
    let mut counter = vec![0usize; n.saturating_sub(2)];
    for r in rows {
        let src_row = (r - origin[0]) * chunk_row;
        let dst_row = (r - out_row) * array_row + base;
        counter.iter_mut().for_each(|c| *c = 0);
        loop {
            let (mut s, mut d) = (src_row, dst_row);
            for (k, &c) in counter.iter().enumerate() {
                s += c * cs[k];
                d += c * ss[k];
            }
            out[d..d + run].copy_from_slice(&src[s..s + run]);
            // The next index over axes 1..n-1 (the last axis is the run), odometer-wise.
            let mut k = counter.len();
            let done = loop {
                if k == 0 {
                    break true;
                }
                k -= 1;
                counter[k] += 1;
                if counter[k] < inside[k] {
                    break false;
                }
                counter[k] = 0;
            };
            if done {
                break;
            }
        }
    }
}

fn open_array(store: &Arc<ReadStore>, root: &Path, key: &str) -> Result<ZArray> {
    Array::open(store.clone(), &format!("/{key}")).map_err(|e| {
        Error::source(format!(
            "{}: cannot open zarr array `{key}`: {e}",
            root.display()
        ))
    })
}

/// Names of the arrays under `data/`, for "did you mean" style listings.
fn data_keys(root: &Path) -> Vec<String> {
    let mut keys: Vec<String> = std::fs::read_dir(root.join("data"))
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .filter(|e| {
                    e.path().join(".zarray").exists() || e.path().join("zarr.json").exists()
                })
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    keys.sort();
    keys
}

fn dtype_name(array: &ZArray) -> String {
    let shown = array.data_type().to_string();
    shown.split(" / ").next().unwrap_or(&shown).to_string()
}

impl DpZarrSource {
    /// Opens the store: the episodes (`meta/episode_ends`), the arrays under `data/` mapped to
    /// channels, each as long as the episodes together, and their chunk grids.
    pub fn open(spec: &LoadedSpec, root: &Path) -> Result<Self> {
        let files = FilesystemStore::new(root).map_err(|e| {
            Error::source(format!("{}: cannot open zarr store: {e}", root.display()))
        })?;
        // The fingerprint is completed from the pass's own reads of the chunk files.
        let seen = fingerprint::Seen::default();
        let store = Arc::new(ReadStore::new(files, seen.clone()));
        let fps = spec.source().fps.ok_or_else(|| {
            spec.error_at(
                &["source", "fps"],
                "a diffusion_policy_zarr source stores no rate; set `source.fps`",
                Some("Push-T is recorded at 10 Hz".into()),
            )
        })?;
        let (episodes, bounds) = list_episodes(&store, root)?;
        let (keys, mut arrays) = data_arrays(&store, root)?;
        let place = root.join("data").display().to_string();
        let mapped = mapping::resolve(spec, &place, &keys)?;
        arrays.retain(|k, _| mapped.keys().contains(k));
        let arrays = check_arrays(root, arrays, &bounds)?;
        let fingerprint = fingerprint::SourcePrint::pending(root, read_files(root, &mapped)?, seen);
        let manifest = Manifest::one_source(
            SourceFormat::DiffusionPolicyZarr,
            fps,
            episodes,
            &mapped,
            fingerprint,
            mapped.warnings.clone(),
        );
        Ok(DpZarrSource {
            root: root.to_path_buf(),
            manifest,
            bounds,
            arrays,
            mapped,
            cache: BlockCache::new(block_cache::budget_from_env()),
        })
    }
}

/// The episodes `meta/episode_ends` lists, and their cumulative starts (one more than
/// episodes).
fn list_episodes(store: &Arc<ReadStore>, root: &Path) -> Result<(Vec<EpisodeInfo>, Vec<u64>)> {
    let ends_array = open_array(store, root, "meta/episode_ends")?;
    let n = ends_array.shape().first().copied().unwrap_or(0);
    // Every episode has a step, so there are no more ends than steps in the longest array;
    // checked on the metadata, before a corrupt shape makes the read allocate for it.
    let longest = data_keys(root)
        .iter()
        .filter_map(|key| open_array(store, root, &format!("data/{key}")).ok())
        .map(|array| (array.shape().first().copied().unwrap_or(0), array))
        .max_by_key(|(steps, _)| *steps);
    let longest_steps = longest.as_ref().map_or(0, |(steps, _)| *steps);
    let longest = match &longest {
        Some((steps, array)) => format!(
            "the longest array, {}, has {steps} steps",
            array.path().as_str().trim_start_matches('/')
        ),
        None => "there are no arrays under data/".into(),
    };
    if n > longest_steps {
        return Err(Error::source(format!(
            "{}: meta/episode_ends has {n} entries, but {longest}; every episode has at least one step",
            root.display(),
        )));
    }
    let ends = read_f32_exact_i64(&ends_array, n)
        .map_err(|e| Error::source(format!("{}: meta/episode_ends: {e}", root.display())))?;
    let mut bounds = vec![0u64];
    let mut episodes = Vec::with_capacity(ends.len());
    for (i, &end) in ends.iter().enumerate() {
        let start = *bounds.last().unwrap();
        if end < 0 || (end as u64) <= start {
            return Err(Error::source(format!(
                "{}: meta/episode_ends[{i}] = {end} does not exceed the previous end {start}: episode {i} is empty or the ends are not increasing",
                root.display()
            )));
        }
        episodes.push(EpisodeInfo {
            id: i as u64,
            len: (end as u64 - start) as usize,
        });
        bounds.push(end as u64);
    }
    Ok((episodes, bounds))
}

/// The arrays under `data/`, by key, and the keys they offer.
fn data_arrays(
    store: &Arc<ReadStore>,
    root: &Path,
) -> Result<(Vec<KeyInfo>, BTreeMap<String, ZArray>)> {
    let mut keys = Vec::new();
    let mut arrays = BTreeMap::new();
    for key in data_keys(root) {
        let array = open_array(store, root, &format!("data/{key}"))?;
        let shape: Vec<usize> = array.shape().iter().map(|&d| d as usize).collect();
        keys.push(KeyInfo {
            key: key.clone(),
            shape: if shape.len() <= 1 {
                vec![1]
            } else {
                shape[1..].to_vec()
            },
            dtype: dtype_name(&array),
        });
        arrays.insert(key, array);
    }
    Ok((keys, arrays))
}

/// The mapped arrays, each checked to end where the last episode ends, with their chunk grids
/// and the episodes that read each chunk.
fn check_arrays(
    root: &Path,
    arrays: BTreeMap<String, ZArray>,
    bounds: &[u64],
) -> Result<BTreeMap<String, Chunked>> {
    let total = *bounds.last().unwrap();
    for (key, array) in &arrays {
        let steps = array.shape().first().copied().unwrap_or(0);
        if steps != total {
            return Err(Error::source(format!(
                "{}: data/{key} has {steps} steps but meta/episode_ends ends at {total}",
                root.display(),
            )));
        }
    }
    let everyone: Vec<usize> = (0..bounds.len() - 1).collect();
    let mut chunked = BTreeMap::new();
    for (index, (key, array)) in arrays.into_iter().enumerate() {
        let mut c = Chunked::new(array, index).map_err(|e| {
            Error::source(format!("{}: data/{key}: chunk grid: {e}", root.display()))
        })?;
        c.count_users(bounds, &everyone);
        chunked.insert(key, c);
    }
    Ok(chunked)
}

/// The files the fingerprint covers: everything under `meta/` and under the mapped arrays.
fn read_files(root: &Path, mapped: &Mapped) -> Result<Vec<PathBuf>> {
    let mut files = fingerprint::list_files(&root.join("meta"))?
        .into_iter()
        .map(|p| Path::new("meta").join(p))
        .collect::<Vec<_>>();
    for key in mapped.keys() {
        let dir = Path::new("data").join(key);
        files.extend(
            fingerprint::list_files(&root.join(&dir))?
                .into_iter()
                .map(|p| dir.join(p)),
        );
    }
    files.sort();
    Ok(files)
}

/// `episode_ends` is int64 in every replay buffer seen so far; read it without a float detour.
fn read_f32_exact_i64(array: &ZArray, n: u64) -> std::result::Result<Vec<i64>, String> {
    #[allow(clippy::single_range_in_vec_init)] // one range per dimension, and this array has one
    let subset = ArraySubset::new_with_ranges(&[0..n]);
    match dtype_name(array).as_str() {
        "int64" => array
            .retrieve_array_subset::<Vec<i64>>(&subset)
            .map_err(|e| e.to_string()),
        "int32" => array
            .retrieve_array_subset::<Vec<i32>>(&subset)
            .map(|v| v.into_iter().map(i64::from).collect())
            .map_err(|e| e.to_string()),
        "uint64" => array
            .retrieve_array_subset::<Vec<u64>>(&subset)
            .map(|v| v.into_iter().map(|x| x as i64).collect())
            .map_err(|e| e.to_string()),
        other => Err(format!("expected an integer array, found {other}")),
    }
}

/// One chunk of a [`Chunked`] array that some rows read: its grid index, its first element and
/// its extent along every axis.
struct ChunkAt {
    idx: Vec<u64>,
    origin: Vec<usize>,
    extent: Vec<usize>,
    /// Its position along the time axis.
    time: usize,
}

impl Chunked {
    /// The chunks holding rows `rows` (every column), in storage order.
    fn chunks_of(&self, rows: std::ops::Range<usize>) -> Vec<ChunkAt> {
        let mut out = Vec::new();
        if rows.is_empty() || self.grid.is_empty() {
            return out;
        }
        let time = &self.grid[0];
        let first = time.partition_point(|&(s, n)| s + n <= rows.start);
        // Every combination of chunk positions along the axes after time.
        let others: Vec<usize> = self.grid[1..].iter().map(Vec::len).collect();
        let combos: usize = others.iter().product();
        for (b, &(t0, tn)) in time.iter().enumerate().skip(first) {
            if t0 >= rows.end {
                break;
            }
            for combo in 0..combos {
                let mut rest = combo;
                let mut axis_idx = vec![0usize; others.len()];
                for (k, &n) in others.iter().enumerate().rev() {
                    axis_idx[k] = rest % n;
                    rest /= n;
                }
                let mut at = ChunkAt {
                    idx: vec![b as u64],
                    origin: vec![t0],
                    extent: vec![tn],
                    time: b,
                };
                for (k, &i) in axis_idx.iter().enumerate() {
                    let (s, n) = self.grid[k + 1][i];
                    at.idx.push(i as u64);
                    at.origin.push(s);
                    at.extent.push(n);
                }
                out.push(at);
            }
        }
        out
    }
}

impl DpZarrSource {
    /// Rows `rows` of `c`, every column, from the chunks that hold them (each decoded once, see
    /// the module documentation).
    fn read_rows(
        &self,
        c: &Chunked,
        rows: std::ops::Range<usize>,
    ) -> std::result::Result<Raw, String> {
        let width: usize = c.shape.iter().skip(1).product();
        let mut out = if c.dtype == "uint8" {
            Raw::U8(vec![0; rows.len() * width])
        } else {
            Raw::F32(vec![0.0; rows.len() * width])
        };
        if rows.is_empty() || c.grid.is_empty() {
            return Ok(out);
        }
        for at in c.chunks_of(rows.clone()) {
            let (t0, tn) = (at.origin[0], at.extent[0]);
            let overlap = rows.start.max(t0)..rows.end.min(t0 + tn);
            let users = c.users.get(at.time).copied().unwrap_or(1);
            let decoded = self
                .cache
                .get(&(c.index, at.idx.clone()), users, || c.decode(&at.idx))?;
            match (&*decoded, &mut out) {
                (Decoded::F32(src), Raw::F32(dst)) => copy_from_chunk(
                    src, &at.extent, &at.origin, &c.shape, overlap, rows.start, dst,
                ),
                (Decoded::U8(src), Raw::U8(dst)) => copy_from_chunk(
                    src, &at.extent, &at.origin, &c.shape, overlap, rows.start, dst,
                ),
                _ => return Err("decoded chunk of another type".into()),
            }
        }
        Ok(out)
    }
}

impl Source for DpZarrSource {
    fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn decode_counts(&self) -> DecodeCounts {
        let names: std::collections::BTreeMap<usize, &str> = self
            .arrays
            .iter()
            .map(|(k, c)| (c.index, k.as_str()))
            .collect();
        let mut out = DecodeCounts::new();
        for ((array, chunk), n) in self.cache.decodes() {
            out.entry(format!("data/{}", names[&array]))
                .or_default()
                .insert(chunk, n);
        }
        out
    }

    fn prefetch(&self, positions: &[usize]) {
        use rayon::prelude::*;
        let (Some(&first), Some(&last)) = (positions.first(), positions.last()) else {
            return;
        };
        let rows = self.bounds[first] as usize..self.bounds[last + 1] as usize;
        // Chunks wholly inside one episode gain nothing here (their one reader decodes them).
        let wanted: Vec<(&Chunked, ChunkAt)> = self
            .arrays
            .values()
            .flat_map(|c| c.chunks_of(rows.clone()).into_iter().map(move |at| (c, at)))
            .filter(|(c, at)| c.users.get(at.time).copied().unwrap_or(1) > 1)
            .collect();
        wanted.par_iter().for_each(|(c, at)| {
            let users = c.users.get(at.time).copied().unwrap_or(1);
            self.cache
                .prefill(&(c.index, at.idx.clone()), users, || c.decode(&at.idx));
        });
    }

    fn only_reading(&mut self, positions: &[usize]) {
        for c in self.arrays.values_mut() {
            c.count_users(&self.bounds, positions);
        }
    }

    fn read_episode(&self, index: usize) -> Result<Episode> {
        let info = &self.manifest.episodes[index];
        let (start, end) = (self.bounds[index], self.bounds[index + 1]);
        let place = format!("{}: episode {}", self.root.display(), info.id);
        let channels = mapping::assemble(&self.mapped, info.len, &place, |key| {
            self.read_rows(&self.arrays[key], start as usize..end as usize)
                .map_err(|e| Error::source(format!("{place}: data/{key}: {e}")))
        })?;
        Ok(Episode {
            id: info.id,
            len: info.len,
            timestamps: None,
            channels,
            packets: Default::default(),
        })
    }
}
