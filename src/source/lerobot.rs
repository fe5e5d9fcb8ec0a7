//! LeRobot datasets: parquet frames plus `meta/info.json`, in two layouts told apart by
//! `codebase_version`.
//!
//! - v2.0 / v2.1: one parquet file per episode (`data_path` in info.json), episodes listed in
//!   `meta/episodes.jsonl` (`episode_index`, `length`).
//! - v3.0: many episodes per `data/chunk-XXX/file-XXX.parquet`; `meta/episodes/**.parquet` has
//!   one row per episode with its `length` and data file (`data/chunk_index`, `data/file_index`).
//!   An episode's rows are found from the data file's `episode_index` column, and must be
//!   contiguous.
//!
//! Every frame row has `timestamp` (seconds), which becomes the episode's timestamps; the rate is
//! info.json's `fps`. Video features live in mp4 files: a channel mapped to one needs the files
//! to exist (decoding them comes later).

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use arrow_array::cast::AsArray;
use arrow_array::types::Int64Type;
use arrow_array::Array;
use serde_json::Value;

use super::block_cache::{self, BlockCache, DecodeCounts};
use super::mapping::{self, KeyInfo, Mapped, Raw};
use super::parquet_read::{self, num_rows, read_columns};
use super::{fingerprint, Episode, EpisodeInfo, Manifest, Source, SourceSplit};
use crate::error::{Error, Result};
use crate::spec::{LoadedSpec, SourceFormat};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Version {
    /// v2.0 and v2.1: one file per episode.
    V2,
    /// v3.0: many episodes per file.
    V3,
}

pub struct LerobotSource {
    root: PathBuf,
    manifest: Manifest,
    mapped: Mapped,
    /// Per episode: the data file (relative to the root) and the episode's rows in it.
    /// (`None`: the whole file, as in v2).
    locations: Vec<(PathBuf, Option<Range<usize>>)>,
    /// Whether frames have a `timestamp` column.
    has_timestamp: bool,
    /// Per episode: its data file's footer and each row group's users (v3.0: read at open,
    /// the episodes that overlap each row group; v2: `None`, the file is the episode's alone).
    footers: Vec<Option<Arc<FileRowGroups>>>,
    /// Decoded column chunks, keyed by (data file, row group, column), each decoded once.
    cache: BlockCache<(PathBuf, usize, String), Vec<f64>>,
    /// Per episode: timestamps the audit read, kept for the episode read (8 bytes a step), so
    /// that the `timestamp` column is decoded once.
    stamps: Vec<OnceLock<Vec<f64>>>,
}

/// A v3.0 data file's footer, and the episodes that take rows from each of its row groups.
type FileRowGroups = (parquet_read::Footer, Vec<u32>);

/// One row of v3.0's `meta/episodes`: the episode, its length, its data file and its videos.
struct EpisodeRow {
    id: u64,
    len: usize,
    chunk: u64,
    file: u64,
    videos: BTreeMap<String, PathBuf>,
}

/// The widest zero-padded field a path template may ask for: a `u64` has 20 digits.
const MAX_WIDTH: usize = 20;

/// The `{name}` / `{name:spec}` fields of a path template: each one's byte range, name and spec.
fn fields(template: &str) -> Vec<(Range<usize>, &str, &str)> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(open) = template[from..].find('{').map(|i| from + i) {
        let Some(close) = template[open..].find('}').map(|i| open + i) else {
            break;
        };
        let inner = &template[open + 1..close];
        let (name, spec) = inner.split_once(':').unwrap_or((inner, ""));
        out.push((open..close + 1, name, spec));
        from = close + 1;
    }
    out
}

/// The zero-padded width a field's spec asks for (`03d` → 3; `` → 0).
fn width(spec: &str) -> usize {
    spec.trim_start_matches('0')
        .trim_end_matches('d')
        .parse()
        .unwrap_or(0)
}

/// Python-style `{name}` / `{name:03d}` formatting of info.json's path templates, in one pass
/// (a value is never searched for fields again). A field whose name is not among `values` stays
/// as written. Widths are at most [`MAX_WIDTH`] ([`Info::parse`] refuses wider ones).
fn fill(template: &str, values: &[(&str, String)]) -> String {
    let mut out = String::with_capacity(template.len());
    let mut from = 0;
    for (range, name, spec) in fields(template) {
        let Some((_, value)) = values.iter().find(|(n, _)| *n == name) else {
            continue;
        };
        out.push_str(&template[from..range.start]);
        let width = width(spec).min(MAX_WIDTH);
        out.push_str(&format!("{value:0>width$}"));
        from = range.end;
    }
    out.push_str(&template[from..]);
    out
}

/// One feature's per-step shape from info.json (`[]` and `[1]` both mean one value).
fn feature_shape(feature: &Value) -> Vec<usize> {
    let shape: Vec<usize> = feature["shape"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|d| d.as_u64())
                .map(|d| d as usize)
                .collect()
        })
        .unwrap_or_default();
    if shape.is_empty() {
        vec![1]
    } else {
        shape
    }
}

/// `"0:100"` → 0..100 (info.json's `splits` values).
fn split_range(text: &str) -> Option<Range<u64>> {
    let (a, b) = text.split_once(':')?;
    Some(a.trim().parse().ok()?..b.trim().parse().ok()?)
}

/// What chunkc reads from `meta/info.json`, before any other file is looked at.
#[derive(Debug, Clone)]
pub struct Info {
    version: Version,
    /// `fps`, when the file stores it.
    pub fps: Option<f64>,
    /// Every feature, in the file's order, with its per-step shape and dtype.
    pub features: Vec<KeyInfo>,
    /// How many episodes share a `chunk-XXX` directory (v2 paths); at least 1.
    pub chunks_size: u64,
    /// The data file template (`data_path`, or the version's default).
    pub data_path: String,
    /// The video file template, when there is one.
    pub video_path: Option<String>,
    /// `splits` as (name, episode range) pairs; `None` when the file has no `splits` table.
    /// Values that are not `"a:b"` are left out.
    pub splits: Option<Vec<(String, Range<u64>)>>,
}

impl Info {
    /// Parses the bytes of an `info.json`; `shown` names the file in errors. Only the metadata is
    /// checked here: whether the files the templates name exist is the adapter's business.
    pub fn parse(bytes: &[u8], shown: &str) -> Result<Info> {
        let info: Value = serde_json::from_slice(bytes)
            .map_err(|e| Error::source(format!("{shown}: invalid JSON: {e}")))?;
        let at_info = |what: &str| Error::source(format!("{shown}: {what}"));
        let version = match info["codebase_version"].as_str() {
            Some("v2.0" | "v2.1") => Version::V2,
            Some("v3.0") => Version::V3,
            Some(other) => {
                return Err(at_info(&format!(
                    "codebase_version `{other}` is not one chunkc reads (v2.0, v2.1, v3.0)"
                )))
            }
            None => return Err(at_info("no `codebase_version`")),
        };
        let features = info["features"]
            .as_object()
            .ok_or_else(|| at_info("no `features` table"))?
            .iter()
            .map(|(key, f)| KeyInfo {
                key: key.clone(),
                shape: feature_shape(f),
                dtype: f["dtype"].as_str().unwrap_or("unknown").to_string(),
            })
            .collect();
        let data_path = info["data_path"].as_str().unwrap_or(match version {
            Version::V2 => "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet",
            Version::V3 => "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        });
        let video_path = info["video_path"].as_str();
        for (key, template) in [("data_path", Some(data_path)), ("video_path", video_path)] {
            let fields = template.map(fields).unwrap_or_default();
            if let Some((_, name, spec)) = fields.iter().find(|(_, _, s)| width(s) > MAX_WIDTH) {
                return Err(at_info(&format!(
                    "`{key}` pads `{{{name}:{spec}}}` to {} digits; at most {MAX_WIDTH} make sense",
                    width(spec)
                )));
            }
        }
        let splits = info["splits"].as_object().map(|splits| {
            splits
                .iter()
                .filter_map(|(k, v)| Some((k.clone(), split_range(v.as_str()?)?)))
                .collect()
        });
        Ok(Info {
            version,
            fps: info["fps"].as_f64(),
            features,
            chunks_size: info["chunks_size"].as_u64().unwrap_or(1000).max(1),
            data_path: data_path.to_string(),
            video_path: video_path.map(str::to_string),
            splits,
        })
    }
}

impl LerobotSource {
    pub fn open(spec: &LoadedSpec, root: &Path) -> Result<Self> {
        let shown = root.display().to_string();
        let info_path = root.join("meta/info.json");
        if !info_path.exists() {
            return Err(Error::source(format!(
                "{shown}: no meta/info.json; a LeRobot dataset has one"
            )));
        }
        let bytes = std::fs::read(&info_path)
            .map_err(|e| Error::source(format!("{}: cannot read: {e}", info_path.display())))?;
        let info = Info::parse(&bytes, &info_path.display().to_string())?;
        let version = info.version;
        let fps = match (info.fps, spec.spec.source.fps) {
            (Some(stored), Some(given)) if (stored - given).abs() > 1e-9 => {
                return Err(spec.error_at(
                    &["source", "fps"],
                    format!(
                        "`source.fps` is {given}, but {} says {stored}",
                        info_path.display()
                    ),
                    Some("leave `source.fps` out: LeRobot datasets store their rate".into()),
                ))
            }
            (Some(stored), _) => stored,
            (None, Some(given)) => given,
            (None, None) => {
                return Err(Error::source(format!("{}: no `fps`", info_path.display())))
            }
        };
        let keys = &info.features;
        let mapped = mapping::resolve(spec, &info_path.display().to_string(), keys)?;
        let media: Vec<&KeyInfo> = mapped
            .keys()
            .iter()
            .filter_map(|k| keys.iter().find(|i| &i.key == k))
            .filter(|k| k.dtype == "video" || k.dtype == "image")
            .collect();

        let mut read_files = vec![PathBuf::from("meta/info.json")];
        let (chunks_size, data_path) = (info.chunks_size, info.data_path.as_str());
        let mut episodes = Vec::new();
        let mut locations = Vec::new();
        // Per episode, the values a video path template needs.
        let mut video_files: Vec<BTreeMap<String, PathBuf>> = Vec::new();
        match version {
            Version::V2 => {
                let list = root.join("meta/episodes.jsonl");
                read_files.push(PathBuf::from("meta/episodes.jsonl"));
                let text = std::fs::read_to_string(&list)
                    .map_err(|e| Error::source(format!("{}: cannot read: {e}", list.display())))?;
                let mut rows: Vec<(u64, usize)> = Vec::new();
                for (n, line) in text
                    .lines()
                    .enumerate()
                    .filter(|(_, l)| !l.trim().is_empty())
                {
                    let v: Value = serde_json::from_str(line).map_err(|e| {
                        Error::source(format!("{}:{}: invalid JSON: {e}", list.display(), n + 1))
                    })?;
                    match (v["episode_index"].as_u64(), v["length"].as_u64()) {
                        (Some(e), Some(len)) => rows.push((e, len as usize)),
                        _ => {
                            return Err(Error::source(format!(
                                "{}:{}: needs `episode_index` and `length`",
                                list.display(),
                                n + 1
                            )))
                        }
                    }
                }
                rows.sort();
                for (e, len) in rows {
                    let values = [
                        ("episode_chunk", (e / chunks_size).to_string()),
                        ("episode_index", e.to_string()),
                    ];
                    let rel = PathBuf::from(fill(data_path, &values));
                    let file = root.join(&rel);
                    if !file.exists() {
                        return Err(Error::source(format!(
                            "{shown}: episode {e}: data file {} is missing",
                            rel.display()
                        )));
                    }
                    let n = num_rows(&file)?;
                    if n != len {
                        return Err(Error::source(format!(
                            "{}: {n} rows, but meta/episodes.jsonl gives episode {e} length {len}",
                            file.display()
                        )));
                    }
                    let mut videos = BTreeMap::new();
                    if let Some(template) = &info.video_path {
                        for m in &media {
                            let mut v = values.to_vec();
                            v.push(("video_key", m.key.clone()));
                            videos.insert(m.key.clone(), PathBuf::from(fill(template, &v)));
                        }
                    }
                    video_files.push(videos);
                    read_files.push(rel.clone());
                    episodes.push(EpisodeInfo { id: e, len });
                    locations.push((rel, None));
                }
            }
            Version::V3 => {
                let meta_dir = root.join("meta/episodes");
                let metas: Vec<PathBuf> = fingerprint::list_files(&meta_dir)?
                    .into_iter()
                    .filter(|p| p.extension().is_some_and(|e| e == "parquet"))
                    .collect();
                if metas.is_empty() {
                    return Err(Error::source(format!(
                        "{}: no parquet files; a v3.0 dataset lists its episodes there",
                        meta_dir.display()
                    )));
                }
                let mut rows: Vec<EpisodeRow> = Vec::new();
                for rel in &metas {
                    let path = meta_dir.join(rel);
                    read_files.push(Path::new("meta/episodes").join(rel));
                    let mut names = vec![
                        "episode_index",
                        "length",
                        "data/chunk_index",
                        "data/file_index",
                    ];
                    let video_cols: Vec<(String, String, String)> = media
                        .iter()
                        .map(|m| {
                            (
                                m.key.clone(),
                                format!("videos/{}/chunk_index", m.key),
                                format!("videos/{}/file_index", m.key),
                            )
                        })
                        .collect();
                    for (_, c, f) in &video_cols {
                        names.push(c);
                        names.push(f);
                    }
                    let cols = read_columns(&path, &names, None)?;
                    let ints = |i: usize| -> Result<Vec<u64>> {
                        parquet_read::to_f64_rows(
                            &cols[i],
                            1,
                            &format!("{}: `{}`", path.display(), names[i]),
                        )
                        .map(|v| v.into_iter().map(|x| x as u64).collect())
                    };
                    let (ids, lens, chunk, file) = (ints(0)?, ints(1)?, ints(2)?, ints(3)?);
                    let video_ints: Vec<(Vec<u64>, Vec<u64>)> = (0..video_cols.len())
                        .map(|j| Ok((ints(4 + 2 * j)?, ints(5 + 2 * j)?)))
                        .collect::<Result<_>>()?;
                    for r in 0..ids.len() {
                        let mut videos = BTreeMap::new();
                        if let Some(template) = &info.video_path {
                            for (j, (key, _, _)) in video_cols.iter().enumerate() {
                                let v = [
                                    ("video_key", key.clone()),
                                    ("chunk_index", video_ints[j].0[r].to_string()),
                                    ("file_index", video_ints[j].1[r].to_string()),
                                ];
                                videos.insert(key.clone(), PathBuf::from(fill(template, &v)));
                            }
                        }
                        rows.push(EpisodeRow {
                            id: ids[r],
                            len: lens[r] as usize,
                            chunk: chunk[r],
                            file: file[r],
                            videos,
                        });
                    }
                }
                rows.sort_by_key(|r| r.id);
                if let Some(w) = rows.windows(2).find(|w| w[0].id == w[1].id) {
                    return Err(Error::source(format!(
                        "{}: episode {} is listed twice",
                        meta_dir.display(),
                        w[0].id
                    )));
                }
                // Each data file once: where each episode's rows are in it.
                let mut ranges: BTreeMap<PathBuf, BTreeMap<u64, Range<usize>>> = BTreeMap::new();
                for EpisodeRow {
                    id: e,
                    len,
                    chunk,
                    file,
                    videos,
                } in rows
                {
                    let values = [
                        ("chunk_index", chunk.to_string()),
                        ("file_index", file.to_string()),
                    ];
                    let rel = PathBuf::from(fill(data_path, &values));
                    if !ranges.contains_key(&rel) {
                        let path = root.join(&rel);
                        if !path.exists() {
                            return Err(Error::source(format!(
                                "{shown}: episode {e}: data file {} is missing",
                                rel.display()
                            )));
                        }
                        ranges.insert(rel.clone(), episode_ranges(&path)?);
                        read_files.push(rel.clone());
                    }
                    let range = ranges[&rel].get(&e).cloned().ok_or_else(|| {
                        Error::source(format!(
                            "{}: no rows of episode {e}, which meta/episodes places there",
                            root.join(&rel).display()
                        ))
                    })?;
                    if range.len() != len {
                        return Err(Error::source(format!(
                            "{}: episode {e} has {} rows, but meta/episodes gives length {len}",
                            root.join(&rel).display(),
                            range.len()
                        )));
                    }
                    video_files.push(videos);
                    episodes.push(EpisodeInfo { id: e, len });
                    locations.push((rel, Some(range)));
                }
            }
        }
        if episodes.is_empty() {
            return Err(Error::source(format!(
                "{shown}: the dataset lists no episodes"
            )));
        }
        if let Some(e) = episodes.iter().find(|e| e.len == 0) {
            return Err(Error::source(format!("{shown}: episode {} is empty", e.id)));
        }

        // Video and image features are not in the parquet files: first a missing file, which the
        // user can fix, then the decoding that is not there yet.
        let channel_of = |key: &str| {
            mapped
                .channels
                .iter()
                .find(|c| c.key == key)
                .map(|c| c.name.clone())
                .unwrap_or_default()
        };
        for m in &media {
            for (e, videos) in episodes.iter().zip(&video_files) {
                if let Some(rel) = videos.get(&m.key).filter(|rel| !root.join(rel).exists()) {
                    return Err(Error::source(format!(
                        "{shown}: channel `{}` maps to the video feature `{}`, but episode {}'s video {} is missing",
                        channel_of(&m.key),
                        m.key,
                        e.id,
                        rel.display()
                    )));
                }
            }
        }
        if let Some(m) = media.first() {
            return Err(Error::source(format!(
                "{shown}: channel `{}` maps to `{}`, a {} feature; reading LeRobot {}s is not supported yet",
                channel_of(&m.key),
                m.key,
                m.dtype,
                m.dtype
            )));
        }

        let source_split = info.splits.as_ref().map(|ranges| {
            let in_split = |name: &str, id: u64| {
                ranges
                    .iter()
                    .any(|(k, r)| k.as_str() == name && r.contains(&id))
            };
            let ids: Vec<u64> = episodes.iter().map(|e| e.id).collect();
            let val: Vec<u64> = ids
                .iter()
                .copied()
                .filter(|&id| !in_split("train", id) && ranges.iter().any(|(_, r)| r.contains(&id)))
                .collect();
            let train = ids.into_iter().filter(|id| !val.contains(id)).collect();
            SourceSplit {
                origin: format!("{}: splits", info_path.display()),
                train,
                val,
            }
        });

        read_files.sort();
        read_files.dedup();
        let fingerprint = fingerprint::of_files(root, &read_files)?;
        let has_timestamp = keys.iter().any(|k| k.key == "timestamp");
        // v3.0: each data file's footer, and how many episodes take rows from each row group.
        let mut by_file: BTreeMap<&PathBuf, Vec<Range<u64>>> = BTreeMap::new();
        for (rel, rows) in &locations {
            if let Some(r) = rows {
                by_file
                    .entry(rel)
                    .or_default()
                    .push(r.start as u64..r.end as u64);
            }
        }
        let mut shared: BTreeMap<&PathBuf, Arc<FileRowGroups>> = BTreeMap::new();
        for (rel, mut ranges) in by_file {
            let footer = parquet_read::footer(&root.join(rel))?;
            ranges.sort_by_key(|r| r.start);
            let users = block_cache::users_per_block(&ranges, &footer.starts, footer.rows);
            shared.insert(rel, Arc::new((footer, users)));
        }
        let footers = locations
            .iter()
            .map(|(rel, rows)| rows.as_ref().and_then(|_| shared.get(rel).cloned()))
            .collect();
        let stamps = (0..locations.len()).map(|_| OnceLock::new()).collect();
        Ok(LerobotSource {
            root: root.to_path_buf(),
            manifest: Manifest {
                format: SourceFormat::Lerobot,
                fps,
                episodes,
                channels: mapped.channels.clone(),
                fingerprint: fingerprint.hash,
                files: fingerprint.files,
                timestamps: has_timestamp,
                source_split,
                warnings: mapped.warnings.clone(),
            },
            mapped,
            locations,
            has_timestamp,
            footers,
            cache: BlockCache::new(block_cache::budget_from_env()),
            stamps,
        })
    }
}

/// Where each episode's rows are in a v3.0 data file, from its `episode_index` column. An
/// episode whose rows are not contiguous is an error.
fn episode_ranges(path: &Path) -> Result<BTreeMap<u64, Range<usize>>> {
    let cols = read_columns(path, &["episode_index"], None)?;
    let mut out: BTreeMap<u64, Range<usize>> = BTreeMap::new();
    let mut row = 0usize;
    let mut previous: Option<u64> = None;
    for batch in &cols[0] {
        let values: Vec<u64> = match batch.data_type() {
            arrow_schema::DataType::Int64 => batch
                .as_primitive::<Int64Type>()
                .values()
                .iter()
                .map(|&v| v as u64)
                .collect(),
            _ => parquet_read::to_f64_rows(std::slice::from_ref(batch), 1, "episode_index")?
                .into_iter()
                .map(|v| v as u64)
                .collect(),
        };
        for e in values {
            if previous != Some(e) {
                if out.contains_key(&e) {
                    return Err(Error::source(format!(
                        "{}: the rows of episode {e} are not contiguous (again at row {row})",
                        path.display()
                    )));
                }
                out.insert(e, row..row);
            }
            out.get_mut(&e).expect("inserted").end = row + 1;
            previous = Some(e);
            row += 1;
        }
    }
    Ok(out)
}

impl Source for LerobotSource {
    fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn read_timestamps(&self, index: usize) -> Result<Option<Vec<f64>>> {
        if !self.has_timestamp {
            return Ok(None);
        }
        if let Some(t) = self.stamps[index].get() {
            return Ok(Some(t.clone()));
        }
        let info = &self.manifest.episodes[index];
        let path = self.root.join(&self.locations[index].0);
        let place = format!("{}: episode {}", path.display(), info.id);
        let t = match self.columns(index, &[("timestamp", 1)]) {
            Ok(mut cols) => cols.pop().expect("timestamp was asked for"),
            Err(_) => self
                .columns_of_episode(index, &[("timestamp", 1)], &place)?
                .remove(0),
        };
        Ok(Some(self.stamps[index].get_or_init(|| t).clone()))
    }

    fn read_episode(&self, index: usize) -> Result<Episode> {
        let info = &self.manifest.episodes[index];
        let (rel, _) = &self.locations[index];
        let path = self.root.join(rel);
        let place = format!("{}: episode {}", path.display(), info.id);
        let keys = self.mapped.keys();
        let widths: BTreeMap<&str, usize> = self
            .mapped
            .recipes
            .iter()
            .flat_map(|r| r.parts.iter().map(|p| (p.key.as_str(), p.width)))
            .collect();
        let mut wanted: Vec<(&str, usize)> = keys
            .iter()
            .map(|k| (k.as_str(), widths[k.as_str()]))
            .collect();
        let kept = self.stamps[index].get();
        if self.has_timestamp && kept.is_none() {
            wanted.push(("timestamp", 1));
        }
        // Through the decoded row groups; on a bad value, read the episode's own rows again the
        // plain way, so that the message names the step in this episode (or, when the bad row
        // is another episode's, this one reads fine).
        let mut cols = match self.columns(index, &wanted) {
            Ok(cols) => cols,
            Err(_) => self.columns_of_episode(index, &wanted, &place)?,
        };
        let timestamps = match kept {
            Some(t) => Some(t.clone()),
            None if self.has_timestamp => cols.pop(),
            None => None,
        };
        let mut by_key: BTreeMap<&str, Vec<f64>> =
            keys.iter().map(String::as_str).zip(cols).collect();
        let channels = mapping::assemble(&self.mapped, info.len, &place, |key| {
            let values = by_key.remove(key).expect("every mapped key was read");
            Ok(Raw::F32(values.into_iter().map(|v| v as f32).collect()))
        })?;
        Ok(Episode {
            id: info.id,
            len: info.len,
            timestamps,
            channels,
        })
    }

    fn decode_counts(&self) -> DecodeCounts {
        let mut out = DecodeCounts::new();
        for ((file, rg, column), n) in self.cache.decodes() {
            out.entry(format!("{}/{column}", file.display()))
                .or_default()
                .insert(vec![rg as u64], n);
        }
        out
    }

    fn only_reading(&mut self, positions: &[usize]) {
        let mut by_file: BTreeMap<PathBuf, Vec<Range<u64>>> = BTreeMap::new();
        for &i in positions {
            if let (rel, Some(r)) = &self.locations[i] {
                by_file
                    .entry(rel.clone())
                    .or_default()
                    .push(r.start as u64..r.end as u64);
            }
        }
        let mut done: BTreeMap<PathBuf, Arc<FileRowGroups>> = BTreeMap::new();
        for i in 0..self.locations.len() {
            let (rel, _) = &self.locations[i];
            let Some(f) = &self.footers[i] else { continue };
            let updated = done.entry(rel.clone()).or_insert_with(|| {
                let mut ranges = by_file.remove(rel).unwrap_or_default();
                ranges.sort_by_key(|r| r.start);
                let users = block_cache::users_per_block(&ranges, &f.0.starts, f.0.rows);
                Arc::new((f.0.clone(), users))
            });
            self.footers[i] = Some(updated.clone());
        }
    }
}

impl LerobotSource {
    /// The columns `wanted` (name, values per step) of episode `index`, as `rows × width`
    /// values each, from its data file's row groups: each row group's column decoded once
    /// (through the cache), however many episodes it holds.
    fn columns(&self, index: usize, wanted: &[(&str, usize)]) -> Result<Vec<Vec<f64>>> {
        let (rel, rows) = &self.locations[index];
        let path = self.root.join(rel);
        let loaded;
        let (footer, users): (&parquet_read::Footer, Option<&[u32]>) = match &self.footers[index] {
            Some(f) => (&f.0, Some(&f.1)),
            None => {
                loaded = parquet_read::footer(&path)?;
                (&loaded, None)
            }
        };
        let rows = match rows {
            Some(r) => r.start as u64..r.end as u64,
            None => 0..footer.rows,
        };
        let mut out = Vec::with_capacity(wanted.len());
        for &(name, width) in wanted {
            let mut values = vec![0f64; (rows.end - rows.start) as usize * width];
            let first = footer
                .starts
                .partition_point(|&s| s <= rows.start)
                .saturating_sub(1);
            for rg in first..footer.starts.len() {
                let lo = footer.starts[rg];
                if lo >= rows.end {
                    break;
                }
                let hi = footer.starts.get(rg + 1).copied().unwrap_or(footer.rows);
                let n = users.and_then(|u| u.get(rg).copied()).unwrap_or(1);
                let what = format!("{}: `{name}`", path.display());
                let decoded = self
                    .cache
                    .get(&(rel.clone(), rg, name.to_string()), n, || {
                        let v =
                            parquet_read::row_group_column(&path, footer, rg, name, width, &what)?;
                        let bytes = v.len() * 8;
                        Ok::<_, Error>((v, bytes))
                    })?;
                let (a, b) = (rows.start.max(lo), rows.end.min(hi));
                if a < b {
                    let src = &decoded[(a - lo) as usize * width..(b - lo) as usize * width];
                    let at = (a - rows.start) as usize * width;
                    values[at..at + src.len()].copy_from_slice(src);
                }
            }
            out.push(values);
        }
        Ok(out)
    }

    /// The columns `wanted` of episode `index` read from its own rows alone (not cached): the
    /// way to a message that names the bad step within the episode.
    fn columns_of_episode(
        &self,
        index: usize,
        wanted: &[(&str, usize)],
        place: &str,
    ) -> Result<Vec<Vec<f64>>> {
        let (rel, rows) = &self.locations[index];
        let names: Vec<&str> = wanted.iter().map(|(n, _)| *n).collect();
        let cols = read_columns(&self.root.join(rel), &names, rows.clone())?;
        cols.iter()
            .zip(wanted)
            .map(|(batches, (name, width))| {
                parquet_read::to_f64_rows(batches, *width, &format!("{place}: `{name}`"))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fills_python_templates() {
        let t = "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet";
        let v = [
            ("episode_chunk", "0".into()),
            ("episode_index", "42".into()),
        ];
        assert_eq!(fill(t, &v), "data/chunk-000/episode_000042.parquet");
        let t = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4";
        let v = [
            ("video_key", "observation.images.top".into()),
            ("chunk_index", "1".into()),
            ("file_index", "12".into()),
        ];
        assert_eq!(
            fill(t, &v),
            "videos/observation.images.top/chunk-001/file-012.mp4"
        );
    }

    #[test]
    fn fills_in_one_pass() {
        // A value that looks like a field is not filled again (this looped forever).
        let v = [("video_key", "{video_key:3}".into())];
        assert_eq!(fill("v/{video_key:3}/x", &v), "v/{video_key:3}/x");
        // Unknown fields and a lone brace stay as written.
        let v = [("episode_index", "7".into())];
        assert_eq!(fill("{other}/{episode_index:03d}/{", &v), "{other}/007/{");
    }

    #[test]
    fn refuses_absurd_widths() {
        // Found while writing the `lerobot_info` fuzz target: a 12-digit width made `fill`
        // build a 100 GB path.
        let json = br#"{"codebase_version": "v2.1", "features": {},
            "data_path": "data/episode_{episode_index:999999999999d}.parquet"}"#;
        let err = Info::parse(json, "info.json").unwrap_err().to_string();
        assert!(
            err.contains("`data_path` pads `{episode_index:999999999999d}`"),
            "{err}"
        );
        let json = br#"{"codebase_version": "v2.1", "features": {},
            "data_path": "data/episode_{episode_index:020d}.parquet"}"#;
        assert!(Info::parse(json, "info.json").is_ok());
    }

    #[test]
    fn split_ranges() {
        assert_eq!(split_range("0:100"), Some(0..100));
        assert_eq!(split_range("x"), None);
    }
}
