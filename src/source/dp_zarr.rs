//! Diffusion Policy's zarr ReplayBuffer: all episodes concatenated along axis 0 of `data/<key>`,
//! with `meta/episode_ends` holding the exclusive cumulative ends.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use zarrs::array::{Array, ArraySubset};
use zarrs::filesystem::FilesystemStore;

use super::mapping::{self, KeyInfo, Mapped, Raw};
use super::{fingerprint, Episode, EpisodeInfo, Manifest, Source};
use crate::error::{Error, Result};
use crate::spec::{LoadedSpec, SourceFormat};

type ZArray = Array<FilesystemStore>;

pub struct DpZarrSource {
    root: PathBuf,
    manifest: Manifest,
    /// Cumulative episode starts (len = episodes + 1).
    bounds: Vec<u64>,
    /// The arrays the channels read, by key.
    arrays: std::collections::BTreeMap<String, ZArray>,
    mapped: Mapped,
}

fn open_array(store: &Arc<FilesystemStore>, root: &Path, key: &str) -> Result<ZArray> {
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

/// Reads `subset` of `array` and converts it to `f32`, whatever the stored numeric type.
fn read_f32(array: &ZArray, subset: &ArraySubset) -> std::result::Result<Vec<f32>, String> {
    let dtype = dtype_name(array);
    macro_rules! conv {
        ($t:ty) => {
            array
                .retrieve_array_subset::<Vec<$t>>(subset)
                .map(|v| v.into_iter().map(|x| x as f32).collect())
                .map_err(|e| e.to_string())
        };
    }
    match dtype.as_str() {
        "float32" => array
            .retrieve_array_subset::<Vec<f32>>(subset)
            .map_err(|e| e.to_string()),
        "float64" => conv!(f64),
        "int8" => conv!(i8),
        "int16" => conv!(i16),
        "int32" => conv!(i32),
        "int64" => conv!(i64),
        "uint8" => conv!(u8),
        "uint16" => conv!(u16),
        "uint32" => conv!(u32),
        "uint64" => conv!(u64),
        "bool" => array
            .retrieve_array_subset::<Vec<bool>>(subset)
            .map(|v| v.into_iter().map(|x| x as u8 as f32).collect())
            .map_err(|e| e.to_string()),
        other => Err(format!("unsupported element type {other}")),
    }
}

fn dtype_name(array: &ZArray) -> String {
    let shown = array.data_type().to_string();
    shown.split(" / ").next().unwrap_or(&shown).to_string()
}

impl DpZarrSource {
    pub fn open(spec: &LoadedSpec, root: &Path) -> Result<Self> {
        let store = Arc::new(FilesystemStore::new(root).map_err(|e| {
            Error::source(format!("{}: cannot open zarr store: {e}", root.display()))
        })?);
        let fps = spec.spec.source.fps.ok_or_else(|| {
            spec.error_at(
                &["source", "fps"],
                "a diffusion_policy_zarr source stores no rate; set `source.fps`",
                Some("Push-T is recorded at 10 Hz".into()),
            )
        })?;

        let ends_array = open_array(&store, root, "meta/episode_ends")?;
        let n = ends_array.shape().first().copied().unwrap_or(0);
        // Every episode has a step, so there are no more ends than steps in the longest array;
        // checked on the metadata, before a corrupt shape makes the read allocate for it.
        let longest = data_keys(root)
            .iter()
            .filter_map(|key| open_array(&store, root, &format!("data/{key}")).ok())
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
        let total = *bounds.last().unwrap();

        let mut keys = Vec::new();
        let mut arrays = std::collections::BTreeMap::new();
        for key in data_keys(root) {
            let array = open_array(&store, root, &format!("data/{key}"))?;
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
        let place = root.join("data").display().to_string();
        let mapped = mapping::resolve(spec, &place, &keys)?;
        for key in mapped.keys() {
            let steps = arrays[&key].shape().first().copied().unwrap_or(0);
            if steps != total {
                return Err(Error::source(format!(
                    "{}: data/{key} has {steps} steps but meta/episode_ends ends at {total}",
                    root.display(),
                )));
            }
        }
        arrays.retain(|k, _| mapped.keys().contains(k));

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
        let fingerprint = fingerprint::of_files(root, &files)?;

        Ok(DpZarrSource {
            root: root.to_path_buf(),
            manifest: Manifest {
                format: SourceFormat::DiffusionPolicyZarr,
                fps,
                episodes,
                channels: mapped.channels.clone(),
                fingerprint,
                timestamps: false,
                source_split: None,
                warnings: mapped.warnings.clone(),
            },
            bounds,
            arrays,
            mapped,
        })
    }
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

impl Source for DpZarrSource {
    fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn read_episode(&self, index: usize) -> Result<Episode> {
        let info = &self.manifest.episodes[index];
        let (start, end) = (self.bounds[index], self.bounds[index + 1]);
        let place = format!("{}: episode {}", self.root.display(), info.id);
        let channels = mapping::assemble(&self.mapped, info.len, &place, |key| {
            let array = &self.arrays[key];
            // One range per dimension: time first, then the whole of every other axis.
            let mut ranges = Vec::with_capacity(array.shape().len());
            ranges.push(start..end);
            ranges.extend(array.shape()[1..].iter().map(|&d| 0..d));
            let subset = ArraySubset::new_with_ranges(&ranges);
            let fail = |e: String| Error::source(format!("{place}: data/{key}: {e}"));
            if dtype_name(array) == "uint8" {
                array
                    .retrieve_array_subset::<Vec<u8>>(&subset)
                    .map(Raw::U8)
                    .map_err(|e| fail(e.to_string()))
            } else {
                read_f32(array, &subset).map(Raw::F32).map_err(fail)
            }
        })?;
        Ok(Episode {
            id: info.id,
            len: info.len,
            timestamps: None,
            channels,
        })
    }
}
