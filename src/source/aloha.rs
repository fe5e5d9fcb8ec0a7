//! ACT / ALOHA: a directory of `episode_<i>.hdf5`, one episode per file, ordered by the number
//! (gaps are allowed and reported).
//!
//! `/action`, `/observations/qpos`, `/observations/qvel`, `/observations/effort`, and
//! `/observations/images/<cam>`: either raw frames (T, H, W, 3) uint8 or, in the compressed
//! variant, JPEG bytes (T, max_len) zero-padded. Which one is decided by the dataset's rank, never
//! by the `compress` attribute (some forks set it and store gzip'd 4-D frames). The files store no
//! timestamps; the rate is 50 Hz unless the spec says otherwise.

use std::path::{Path, PathBuf};

use hdf5::Dataset;
use rayon::prelude::*;

use super::block_cache::{self, BlockCache, DecodeCounts};
use super::check::same_length;
use super::mapping::{self, KeyInfo, Mapped, Raw};
use super::{fingerprint, h5, h5meta, jpeg, Episode, EpisodeInfo, Manifest, Source};
use crate::error::{Error, Result};
use crate::spec::{LoadedSpec, SourceFormat};

/// ALOHA records at 50 Hz and stores no rate.
const DEFAULT_FPS: f64 = 50.0;

pub struct AlohaSource {
    files: Vec<PathBuf>,
    manifest: Manifest,
    mapped: Mapped,
    jpeg: JpegKeys,
    /// Per episode: where each mapped key's values lie in the file, when every one of them is
    /// stored contiguously or in unfiltered chunks of whole rows (see [`h5::direct`]); such an
    /// episode is read without HDF5.
    direct: Vec<Located>,
    /// Counts the datasets read (each belongs to one episode and is read whole, once), keyed
    /// by (file name/key, number of chunks).
    decodes: BlockCache<(String, u64), ()>,
}

/// `episode_12.hdf5` → 12.
fn episode_id(name: &str) -> Option<u64> {
    name.strip_prefix("episode_")?
        .strip_suffix(".hdf5")
        .or_else(|| name.strip_prefix("episode_")?.strip_suffix(".h5"))?
        .parse()
        .ok()
}

/// A 2-D uint8 array of images holds one encoded frame per row.
fn is_jpeg_rows(key: &str, ds: &Dataset) -> bool {
    key.starts_with("observations/images/") && ds.ndim() == 2 && h5::dtype_name(ds) == "uint8"
}

/// The (height, width) of the JPEG in row `t`.
fn jpeg_size(ds: &Dataset, t: usize, what: &str) -> Result<(usize, usize)> {
    let row = ds
        .read_slice_1d::<u8, _>(ndarray::s![t, ..])
        .map_err(|e| Error::source(format!("{what} step {t}: cannot read: {e}")))?;
    jpeg::dimensions(row.as_slice().unwrap_or(&row.to_vec()))
        .map_err(|e| Error::source(format!("{what} step {t}: {e}")))
}

/// Keys stored as JPEG rows, with the decoded frame's (height, width).
type JpegKeys = Vec<(String, (usize, usize))>;

/// Where each mapped key's values lie in an episode file, when every one can be read directly.
type Located = Option<Vec<(String, h5::Direct)>>;

impl AlohaSource {
    /// Opens the directory: its episode files, the first one's keys mapped to channels, and
    /// every file's header checked against the first.
    pub fn open(spec: &LoadedSpec, dir: &Path) -> Result<Self> {
        if !dir.is_dir() {
            return Err(spec.error_at(
                &["source", "path"],
                format!("an aloha_hdf5 source is a directory of episode_<i>.hdf5 files; {} is not a directory", dir.display()),
                None,
            ));
        }
        let found = episode_files(dir)?;
        let mut warnings: Vec<String> = missing_ids(&found, dir).into_iter().collect();
        let files: Vec<PathBuf> = found.iter().map(|(_, n)| dir.join(n)).collect();
        let (keys, mut jpeg) = first_file_keys(&files[0])?;
        let mapped = mapping::resolve(spec, &files[0].display().to_string(), &keys)?;
        warnings.extend(mapped.warnings.iter().cloned());
        let wanted = mapped.keys();
        jpeg.retain(|(k, _)| wanted.contains(k));
        let headers = Headers {
            files: &files,
            keys: &keys,
            jpeg: &jpeg,
            wanted: &wanted,
        };
        // The content hashes of the fingerprint run on a thread of their own from now on, while
        // each file's header is read through HDF5 and then while the build reads the episodes.
        let names: Vec<PathBuf> = found.iter().map(|(_, n)| PathBuf::from(n)).collect();
        let fingerprint = fingerprint::SourcePrint::beside(dir, names);
        let (episodes, direct) = headers.read(&found)?;
        let fps = spec.source().fps.unwrap_or(DEFAULT_FPS);
        let format = SourceFormat::AlohaHdf5;
        let manifest = Manifest::one_source(format, fps, episodes, &mapped, fingerprint, warnings);
        Ok(AlohaSource {
            files,
            manifest,
            mapped,
            jpeg,
            direct,
            decodes: BlockCache::new(0),
        })
    }
}

/// The directory's `episode_<i>.hdf5` files, by id: at least one, no id twice.
fn episode_files(dir: &Path) -> Result<Vec<(u64, String)>> {
    let shown = dir.display().to_string();
    let mut found: Vec<(u64, String)> = std::fs::read_dir(dir)
        .map_err(|e| Error::source(format!("{shown}: cannot list: {e}")))?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            episode_id(&name).map(|id| (id, name))
        })
        .collect();
    found.sort();
    if found.is_empty() {
        return Err(Error::source(format!("{shown}: no episode_<i>.hdf5 files")));
    }
    if let Some(w) = found.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(Error::source(format!(
            "{shown}: {} and {} have the same episode number",
            w[0].1, w[1].1
        )));
    }
    Ok(found)
}

/// The warning for ids without a file (the original ACT code needs contiguous ids from 0).
fn missing_ids(found: &[(u64, String)], dir: &Path) -> Option<String> {
    let mut gaps: Vec<String> = found
        .windows(2)
        .filter(|w| w[1].0 > w[0].0 + 1)
        .map(|w| {
            if w[1].0 == w[0].0 + 2 {
                format!("{}", w[0].0 + 1)
            } else {
                format!("{}..={}", w[0].0 + 1, w[1].0 - 1)
            }
        })
        .collect();
    if found[0].0 != 0 {
        gaps.insert(0, format!("0..={}", found[0].0 - 1));
    }
    (!gaps.is_empty()).then(|| {
        format!(
            "{}: no episode file for ids {} (the original ACT code needs contiguous ids from 0)",
            dir.display(),
            gaps.join(", ")
        )
    })
}

/// The keys of the first episode file, and those that hold JPEG rows with their frame size.
fn first_file_keys(path: &Path) -> Result<(Vec<KeyInfo>, JpegKeys)> {
    let first = h5::open(path)?;
    let mut keys = Vec::new();
    let mut jpeg = Vec::new();
    for (key, ds) in h5::datasets(&first, path)? {
        if !h5::is_numeric(&ds) || ds.ndim() == 0 {
            continue;
        }
        if is_jpeg_rows(&key, &ds) {
            let what = format!("{}: {key}", path.display());
            let (h, w) = jpeg_size(&ds, 0, &what)?;
            keys.push(KeyInfo {
                key: key.clone(),
                shape: vec![h, w, 3],
                dtype: "jpeg".into(),
            });
            jpeg.push((key, (h, w)));
        } else {
            keys.push(KeyInfo {
                key,
                shape: h5::step_shape(&ds),
                dtype: h5::dtype_name(&ds),
            });
        }
    }
    Ok((keys, jpeg))
}

/// What every episode file's header is checked against: the first file's keys, the mapped ones
/// (`wanted`) and those of them that hold JPEG rows.
struct Headers<'a> {
    files: &'a [PathBuf],
    keys: &'a [KeyInfo],
    jpeg: &'a JpegKeys,
    wanted: &'a [String],
}

impl Headers<'_> {
    /// Each file's episode (`found`'s id, the length its datasets agree on) and where its
    /// datasets lie, when every one can be read directly.
    fn read(&self, found: &[(u64, String)]) -> Result<(Vec<EpisodeInfo>, Vec<Located>)> {
        let _headers = crate::timings::phase("episode headers");
        // Files whose datasets are all contiguous are understood without HDF5 (and so in
        // parallel); the others are read through it.
        let fast: Vec<Option<Vec<h5meta::Located>>> = if self.jpeg.is_empty() {
            let files = self.files.par_iter();
            files.map(|p| h5meta::locate(p, self.wanted)).collect()
        } else {
            vec![None; self.files.len()]
        };
        let mut episodes = Vec::with_capacity(self.files.len());
        let mut direct = Vec::with_capacity(self.files.len());
        for (((id, _), path), fast) in found.iter().zip(self.files).zip(fast) {
            let (len, located) = match fast {
                Some(found) => self.located(path, found)?,
                None => self.through_hdf5(path)?,
            };
            if len == 0 {
                let here = path.display();
                return Err(Error::source(format!("{here}: the episode is empty")));
            }
            episodes.push(EpisodeInfo { id: *id, len });
            direct.push(located);
        }
        Ok((episodes, direct))
    }

    /// A file whose mapped datasets lie where `found` says: their shapes checked, the length.
    fn located(&self, path: &Path, found: Vec<h5meta::Located>) -> Result<(usize, Located)> {
        let here = path.display().to_string();
        let mut located = Vec::with_capacity(self.wanted.len());
        let mut len = None;
        for (key, l) in self.wanted.iter().zip(found) {
            let step: Vec<usize> = if l.shape.len() <= 1 {
                vec![1]
            } else {
                l.shape[1..].to_vec()
            };
            if step != self.reference(key).shape {
                return Err(self.unlike(&here, key, &l.shape));
            }
            let steps = l.shape.first().copied().unwrap_or(0);
            same_length(&mut len, &here, key, steps)?;
            located.push((key.clone(), l.direct));
        }
        Ok((len.map_or(0, |(n, _)| n), Some(located)))
    }

    /// A file read through HDF5: its mapped datasets' shapes checked, the length, and where
    /// they lie when every one can be read directly.
    fn through_hdf5(&self, path: &Path) -> Result<(usize, Located)> {
        let here = path.display().to_string();
        let file = h5::open(path)?;
        let mut len = None;
        let mut located = Some(Vec::with_capacity(self.wanted.len()));
        for key in self.wanted {
            let ds = h5::dataset(&file, key, path)?;
            let is_jpeg = self.jpeg.iter().any(|(k, _)| k == key);
            located = match (located, h5::direct(&ds)) {
                (Some(mut v), Some(d)) if !is_jpeg => {
                    v.push((key.clone(), d));
                    Some(v)
                }
                _ => None,
            };
            let shape_ok = if is_jpeg {
                is_jpeg_rows(key, &ds)
            } else {
                h5::step_shape(&ds) == self.reference(key).shape
            };
            if !shape_ok {
                return Err(self.unlike(&here, key, &ds.shape()));
            }
            same_length(&mut len, &here, key, h5::steps(&ds))?;
        }
        Ok((len.map_or(0, |(n, _)| n), located))
    }

    /// The first file's `key`.
    fn reference(&self, key: &str) -> &KeyInfo {
        self.keys.iter().find(|k| k.key == key).expect("resolved")
    }

    /// `here`'s `key` has `shape`, unlike the first file's.
    fn unlike(&self, here: &str, key: &str, shape: &[usize]) -> Error {
        let reference = self.reference(key);
        Error::source(format!(
            "{here}: `{key}` has shape {shape:?}, unlike {} ({:?} per step, {})",
            self.files[0].display(),
            reference.shape,
            reference.dtype
        ))
    }
}

/// Decodes every row of a (T, max_len) JPEG array into (T, H, W, 3) frames.
fn decode_rows(ds: &Dataset, size: (usize, usize), what: &str) -> Result<Vec<u8>> {
    let shape = ds.shape();
    let (steps, row_len) = (shape[0], shape[1]);
    let bytes = ds
        .read_raw::<u8>()
        .map_err(|e| Error::source(format!("{what}: cannot read: {e}")))?;
    let mut out = Vec::with_capacity(steps * size.0 * size.1 * 3);
    for (t, row) in bytes.chunks_exact(row_len.max(1)).enumerate() {
        let frame =
            jpeg::decode(row).map_err(|e| Error::source(format!("{what} step {t}: {e}")))?;
        if (frame.height, frame.width) != size {
            return Err(Error::source(format!(
                "{what} step {t}: the frame is {}x{}, but the camera's first frame is {}x{}",
                frame.height, frame.width, size.0, size.1
            )));
        }
        out.extend_from_slice(&frame.rgb);
    }
    Ok(out)
}

impl AlohaSource {
    /// `episode_3.hdf5/action`: how the decode counts name a dataset.
    fn dataset_name(&self, index: usize, key: &str) -> String {
        let file = self.files[index].file_name().unwrap_or_default();
        format!("{}/{key}", file.to_string_lossy())
    }
}

impl Source for AlohaSource {
    fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn decode_counts(&self) -> DecodeCounts {
        block_cache::whole_datasets(self.decodes.decodes())
    }

    fn read_episode(&self, index: usize) -> Result<Episode> {
        let info = &self.manifest.episodes[index];
        let path = &self.files[index];
        let place = path.display().to_string();
        if let Some(located) = &self.direct[index] {
            let file = std::fs::File::open(path)
                .map_err(|e| Error::source(format!("{place}: cannot open: {e}")))?;
            let channels = mapping::assemble(&self.mapped, info.len, &place, |key| {
                let (_, d) = located
                    .iter()
                    .find(|(k, _)| k == key)
                    .expect("every mapped key located");
                self.decodes
                    .count(&(self.dataset_name(index, key), h5::direct_chunks(d)));
                h5::read_direct(&file, d)
                    .map_err(|e| Error::source(format!("{place}: {key}: cannot read: {e}")))
            })?;
            return Ok(Episode {
                id: info.id,
                len: info.len,
                timestamps: None,
                channels,
                packets: Default::default(),
            });
        }
        let file = h5::open(path)?;
        let channels = mapping::assemble(&self.mapped, info.len, &place, |key| {
            let ds = h5::dataset(&file, key, path)?;
            self.decodes
                .count(&(self.dataset_name(index, key), h5::chunks(&ds)));
            let what = format!("{place}: {key}");
            match self.jpeg.iter().find(|(k, _)| k == key) {
                Some((_, size)) => decode_rows(&ds, *size, &what).map(Raw::U8),
                None => h5::read(&ds, || what.clone()),
            }
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
