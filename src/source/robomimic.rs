//! robomimic's one-file layout, and robosuite's older files it grew out of.
//!
//! `data/demo_<int>` groups, ordered by the integer (not lexically). robomimic stores the length
//! as the `num_samples` attribute (checked against every array), `actions`, `rewards`, `dones`,
//! `states` and `obs/<key>`; `mask/train` and `mask/valid` list demo names. robosuite's files have
//! no `obs` group and no `num_samples`; column 0 of their `states` is simulation time, which
//! becomes the episode's timestamps.

use std::path::{Path, PathBuf};

use hdf5::{Dataset, File, Group};

use super::block_cache::{self, BlockCache, DecodeCounts};
use super::check::same_length;
use super::mapping::{self, KeyInfo, Mapped, Raw};
use super::{
    fingerprint, fps_from_timestamps, h5, Episode, EpisodeInfo, Manifest, Source, SourceSplit,
};
use crate::error::{Error, Result};
use crate::spec::{LoadedSpec, SourceFormat};

pub struct RobomimicSource {
    path: PathBuf,
    file: File,
    /// The same file opened with std, for datasets read outside HDF5 ([`h5::direct`]).
    raw: std::fs::File,
    manifest: Manifest,
    /// Group names under `data/`, in episode order.
    demos: Vec<String>,
    mapped: Mapped,
    /// Per episode: simulation time from `states[:, 0]` (robosuite files only).
    timestamps: Option<Vec<Vec<f64>>>,
    /// Datasets read, keyed by (path in the file, number of chunks). A robosuite `states`
    /// decoded at open for the timestamps waits here for the episode read (when it fits the
    /// budget), so that it is decoded once.
    cache: BlockCache<(String, u64), Raw>,
}

/// `demo_12` → 12.
fn demo_id(name: &str) -> Option<u64> {
    name.strip_prefix("demo_")?.parse().ok()
}

impl RobomimicSource {
    /// Opens the file: its demos, the first demo's keys mapped to channels, every demo checked
    /// against them (a robosuite file's clock read for its timestamps), the rate and the stored
    /// split.
    pub fn open(spec: &LoadedSpec, path: &Path) -> Result<Self> {
        let shown = path.display().to_string();
        let file = h5::open(path)?;
        let data = h5::group(&file, "data", path)?;
        let demos = list_demos(&data, &shown)?;
        let keys = demo_keys(&data, &demos[0].1, path)?;
        let place = format!("{shown} (data/{})", demos[0].1);
        let mapped = mapping::resolve(spec, &place, &keys)?;
        let cache = BlockCache::new(block_cache::budget_from_env());
        let scan = Demos {
            data: &data,
            path,
            first: &demos[0].1,
            keys: &keys,
            wanted: mapped.keys(),
            cache: &cache,
        };
        let (episodes, timestamps) = scan.episodes(&demos)?;
        let fps = match spec.source().fps {
            Some(fps) => fps,
            None => timestamps
                .as_deref()
                .and_then(fps_from_timestamps)
                .ok_or_else(|| {
                    spec.error_at(
                        &["source", "fps"],
                        format!("{shown} stores no rate and no timestamps; set `source.fps`"),
                        Some("robomimic's datasets are recorded at 20 Hz".into()),
                    )
                })?,
        };
        let mut warnings = mapped.warnings.clone();
        let source_split = read_masks(&file, &demos, &shown, &mut warnings)?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let name = PathBuf::from(path.file_name().unwrap_or_default());
        let fingerprint = fingerprint::SourcePrint::beside(dir, vec![name]);
        let raw = std::fs::File::open(path)
            .map_err(|e| Error::source(format!("{shown}: cannot open: {e}")))?;
        let format = SourceFormat::RobomimicHdf5;
        let manifest = Manifest {
            timestamps: timestamps.is_some(),
            source_split,
            ..Manifest::one_source(format, fps, episodes, &mapped, fingerprint, warnings)
        };
        Ok(RobomimicSource {
            path: path.to_path_buf(),
            file,
            raw,
            manifest,
            demos: demos.into_iter().map(|(_, n)| n).collect(),
            mapped,
            timestamps,
            cache,
        })
    }
}

/// The `data/demo_<n>` groups, by number: at least one, no number twice.
fn list_demos(data: &Group, shown: &str) -> Result<Vec<(u64, String)>> {
    let names = data
        .member_names()
        .map_err(|e| Error::source(format!("{shown}: cannot list `data`: {e}")))?;
    let mut demos: Vec<(u64, String)> = names
        .into_iter()
        .filter_map(|n| demo_id(&n).map(|id| (id, n)))
        .collect();
    demos.sort();
    if demos.is_empty() {
        return Err(Error::source(format!(
            "{shown}: no `data/demo_<n>` groups; is this a robomimic or robosuite file?"
        )));
    }
    if let Some(w) = demos.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(Error::source(format!(
            "{shown}: `data/{}` and `data/{}` have the same number",
            w[0].1, w[1].1
        )));
    }
    Ok(demos)
}

/// The numeric datasets of demo `name`, as keys.
fn demo_keys(data: &Group, name: &str, path: &Path) -> Result<Vec<KeyInfo>> {
    let first = h5::group(data, name, path)?;
    Ok(h5::datasets(&first, path)?
        .iter()
        .filter(|(_, ds)| h5::is_numeric(ds))
        .map(|(key, ds)| KeyInfo {
            key: key.clone(),
            shape: h5::step_shape(ds),
            dtype: h5::dtype_name(ds),
        })
        .collect())
}

/// What every demo is checked against: the `first` demo's keys and the mapped ones (`wanted`).
/// A robosuite `states` decoded for its clock waits in `cache` for the episode read.
struct Demos<'a> {
    data: &'a Group,
    path: &'a Path,
    first: &'a str,
    keys: &'a [KeyInfo],
    wanted: Vec<String>,
    cache: &'a BlockCache<(String, u64), Raw>,
}

impl Demos<'_> {
    /// Each demo's episode, checked, and every demo's timestamps when all of them are
    /// robosuite's.
    fn episodes(&self, demos: &[(u64, String)]) -> Result<(Vec<EpisodeInfo>, Timestamps)> {
        let mut episodes = Vec::with_capacity(demos.len());
        let mut timestamps = Vec::new();
        let mut has_timestamps = true;
        for (id, name) in demos {
            let g = h5::group(self.data, name, self.path)?;
            let here = format!("{}: data/{name}", self.path.display());
            let arrays = h5::datasets(&g, self.path)?;
            let len = self.length(&g, &here, &arrays)?;
            self.check_keys(&here, &arrays)?;
            if len == 0 {
                return Err(Error::source(format!("{here}: the episode is empty")));
            }
            match self.robosuite_clock(&g, name, &here, &arrays, len)? {
                Some(t) => timestamps.push(t),
                None => has_timestamps = false,
            }
            episodes.push(EpisodeInfo { id: *id, len });
        }
        Ok((episodes, has_timestamps.then_some(timestamps)))
    }

    /// The demo's length: `num_samples`, which every array must agree with (robomimic's), else
    /// the length the mapped arrays agree on (robosuite's).
    fn length(&self, g: &Group, here: &str, arrays: &[(String, Dataset)]) -> Result<usize> {
        let num_samples = match g.attr("num_samples") {
            Ok(attr) => Some(attr.read_scalar::<i64>().map_err(|e| {
                Error::source(format!("{here}: cannot read attribute `num_samples`: {e}"))
            })?),
            Err(_) => None,
        };
        let Some(n) = num_samples else {
            let mut len = None;
            for (key, ds) in arrays.iter().filter(|(k, _)| self.wanted.contains(k)) {
                same_length(&mut len, here, key, h5::steps(ds))?;
            }
            return len.map(|(n, _)| n).ok_or_else(|| {
                Error::source(format!("{here}: none of the mapped keys is present"))
            });
        };
        if n < 0 {
            return Err(Error::source(format!("{here}: num_samples is {n}")));
        }
        for (key, ds) in arrays {
            if h5::steps(ds) as i64 != n {
                return Err(Error::source(format!(
                    "{here}: num_samples is {n} but `{key}` has {} steps",
                    h5::steps(ds)
                )));
            }
        }
        Ok(n as usize)
    }

    /// Every mapped key is in the demo, with the first demo's per-step shape.
    fn check_keys(&self, here: &str, arrays: &[(String, Dataset)]) -> Result<()> {
        for key in &self.wanted {
            let reference = self.keys.iter().find(|k| &k.key == key).expect("resolved");
            let first = self.first;
            match arrays.iter().find(|(k, _)| k == key) {
                None => {
                    return Err(Error::source(format!(
                        "{here}: no `{key}` (it is in data/{first})"
                    )))
                }
                Some((_, ds)) if h5::step_shape(ds) != reference.shape => {
                    return Err(Error::source(format!(
                        "{here}: `{key}` has per-step shape {:?}, but {:?} in data/{first}",
                        h5::step_shape(ds),
                        reference.shape,
                    )))
                }
                Some(_) => {}
            }
        }
        Ok(())
    }

    /// robosuite's layout (no `obs` group, simulation time in `states[:, 0]`): the demo's
    /// timestamps; `None` for any other. A mapped `states` so decoded is kept for the episode
    /// read.
    fn robosuite_clock(
        &self,
        g: &Group,
        name: &str,
        here: &str,
        arrays: &[(String, Dataset)],
        len: usize,
    ) -> Result<Option<Vec<f64>>> {
        let states = arrays.iter().find(|(k, _)| k == "states");
        let ds = match (g.group("obs").is_ok(), states) {
            (false, Some((_, ds))) if h5::steps(ds) == len && ds.ndim() == 2 => ds,
            _ => return Ok(None),
        };
        let all = ds
            .read_raw::<f64>()
            .map_err(|e| Error::source(format!("{here}: cannot read `states`: {e}")))?;
        let cols = ds.shape()[1].max(1);
        let timestamps = all.iter().step_by(cols).copied().collect();
        // The episode read converts to f32 as `h5::read_direct` does: keep the values so
        // converted for it instead of decoding `states` again.
        let key = (format!("data/{name}/states"), h5::chunks(ds));
        match h5::direct(ds) {
            Some(_) if self.wanted.iter().any(|k| k == "states") => {
                let values: Vec<f32> = all.iter().map(|&x| x as f32).collect();
                let bytes = values.len() * 4;
                let kept = || Ok::<_, Error>((Raw::F32(values), bytes));
                self.cache.get(&key, 2, kept)?;
            }
            _ => self.cache.count(&key),
        }
        Ok(Some(timestamps))
    }
}

/// Per episode, simulation time from `states[:, 0]` (robosuite files only).
type Timestamps = Option<Vec<Vec<f64>>>;

/// `mask/valid` (and `mask/train`) as a split: the validation demos are those in `mask/valid`,
/// everything else trains.
fn read_masks(
    file: &File,
    demos: &[(u64, String)],
    shown: &str,
    warnings: &mut Vec<String>,
) -> Result<Option<SourceSplit>> {
    let Ok(mask) = file.group("mask") else {
        return Ok(None);
    };
    let read = |name: &str| -> Result<Option<Vec<u64>>> {
        let Ok(ds) = mask.dataset(name) else {
            return Ok(None);
        };
        let names = h5::read_strings(&ds)
            .map_err(|e| Error::source(format!("{shown}: mask/{name}: {e}")))?;
        let mut ids = Vec::with_capacity(names.len());
        for n in names {
            match demos.iter().find(|(_, d)| *d == n) {
                Some((id, _)) => ids.push(*id),
                None => {
                    return Err(Error::source(format!(
                        "{shown}: mask/{name} lists `{n}`, which is not a group in `data`"
                    )))
                }
            }
        }
        ids.sort_unstable();
        Ok(Some(ids))
    };
    let (train, valid) = (read("train")?, read("valid")?);
    let Some(val) = valid else {
        return Ok(None);
    };
    let rest: Vec<u64> = demos
        .iter()
        .map(|(id, _)| *id)
        .filter(|id| val.binary_search(id).is_err())
        .collect();
    if let Some(train) = &train {
        let neither: Vec<String> = rest
            .iter()
            .filter(|id| train.binary_search(id).is_err())
            .map(|id| format!("demo_{id}"))
            .collect();
        if !neither.is_empty() {
            warnings.push(format!(
                "{shown}: {} in neither mask/train nor mask/valid; used for training",
                neither.join(", ")
            ));
        }
    }
    Ok(Some(SourceSplit {
        origin: format!("{shown}: mask/valid"),
        train: rest,
        val,
    }))
}

impl Source for RobomimicSource {
    fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn read_timestamps(&self, index: usize) -> Result<Option<Vec<f64>>> {
        Ok(self.timestamps.as_ref().map(|t| t[index].clone()))
    }

    fn decode_counts(&self) -> DecodeCounts {
        block_cache::whole_datasets(self.cache.decodes())
    }

    fn read_episode(&self, index: usize) -> Result<Episode> {
        let info = &self.manifest.episodes[index];
        let demo = &self.demos[index];
        let place = format!("{}: data/{demo}", self.path.display());
        let group = h5::group(&self.file, &format!("data/{demo}"), &self.path)?;
        let channels = mapping::assemble(&self.mapped, info.len, &place, |key| {
            let ds = h5::dataset(&group, key, &self.path)?;
            let id = (format!("data/{demo}/{key}"), h5::chunks(&ds));
            // One user: a `states` kept at open is taken (and dropped from the cache); anything
            // else is decoded here and not kept.
            let raw = self.cache.get(&id, 1, || {
                // Located under HDF5's lock, then read (and inflated) outside it, so that
                // episodes decode in parallel.
                let raw = match h5::direct(&ds) {
                    Some(d) => h5::read_direct(&self.raw, &d)
                        .map_err(|e| Error::source(format!("{place}/{key}: cannot read: {e}"))),
                    None => h5::read(&ds, || format!("{place}/{key}")),
                }?;
                Ok::<_, Error>((raw, 0))
            })?;
            // Each dataset has one reader in the build: the value is this episode's alone.
            Ok(std::sync::Arc::try_unwrap(raw).unwrap_or_else(|shared| (*shared).clone()))
        })?;
        Ok(Episode {
            id: info.id,
            len: info.len,
            timestamps: self.timestamps.as_ref().map(|t| t[index].clone()),
            channels,
            packets: Default::default(),
        })
    }
}
