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
//! info.json's `fps`. Video features live in mp4 files: a channel mapped to one is decoded from
//! them (feature `video`), each row given the frame LeRobot would give it.
//!
//! - `info`: parsing `meta/info.json` (version, rate, features, path templates, splits).
//! - `v2`, `v3`: each layout's episode listing and where each episode's rows are.
//! - `video`: each episode's camera files and spans, their audit checks and their decoding.
//! - `read`: reading an episode (its parquet columns, timestamps and frames): the `Source`.
//! - here: opening (the checks common to both layouts).

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use super::block_cache::{self, BlockCache};
use super::mapping::{self, KeyInfo, Mapped};
use super::parquet_read;
use super::video as codec;
use super::{fingerprint, EpisodeInfo, Manifest, SourceSplit};
use crate::error::{Error, Result};
use crate::spec::{BadVideo, LoadedSpec, SourceFormat};
use rayon::prelude::*;

mod info;
mod read;
mod v2;
mod v3;
mod video;

pub use info::Info;
use info::Version;
#[cfg(test)]
use info::{fill, split_range};

/// What a layout's episode listing finds: the episodes, where each one's rows are, its videos,
/// and the files read for the fingerprint.
#[derive(Default)]
struct Listing {
    episodes: Vec<EpisodeInfo>,
    /// Per episode: the data file (relative to the root) and its rows there (`None`: all).
    locations: Vec<(PathBuf, Option<Range<usize>>)>,
    /// Per episode, the video file of each media feature.
    video_files: Vec<BTreeMap<String, VideoRef>>,
    read_files: Vec<PathBuf>,
    /// Each episode's task (the first of its `tasks`), by id; absent when the layout lists none.
    tasks: BTreeMap<u64, String>,
}

/// Where one episode's camera is: its file (relative to the root) and, in v3.0's shared files,
/// its span (`from_timestamp`, `to_timestamp`); v2: from 0, to the end.
#[derive(Debug, Clone)]
struct VideoRef {
    file: PathBuf,
    from: f64,
    to: Option<f64>,
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
    /// The mapped video features' files per episode.
    videos: video::Videos,
}

/// A v3.0 data file's footer, and the episodes that take rows from each of its row groups.
type FileRowGroups = (parquet_read::Footer, Vec<u32>);

impl LerobotSource {
    // Long function: opening is one sequence of checks (info.json, features, mapping, episodes, videos), each with its own message, read top to bottom.
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
        let fps = match (info.fps, spec.source().fps) {
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

        let listing = match version {
            Version::V2 => v2::list(root, &info, &media)?,
            Version::V3 => v3::list(root, &info, &media)?,
        };
        let Listing {
            mut read_files,
            episodes,
            locations,
            video_files,
            tasks,
        } = listing;
        read_files.push(PathBuf::from("meta/info.json"));
        if episodes.is_empty() {
            return Err(Error::source(format!(
                "{shown}: the dataset lists no episodes"
            )));
        }
        if let Some(e) = episodes.iter().find(|e| e.len == 0) {
            return Err(Error::source(format!("{shown}: episode {} is empty", e.id)));
        }

        // Video and image features are not in the parquet files. Images stored in parquet are
        // not read yet; videos need the feature, the template and (unless the audit may
        // exclude the episode) every file.
        let channel_of = |key: &str| {
            mapped
                .channels
                .iter()
                .find(|c| c.key == key)
                .map(|c| c.name.clone())
                .unwrap_or_default()
        };
        if let Some(m) = media.iter().find(|m| m.dtype != "video") {
            return Err(Error::source(format!(
                "{shown}: channel `{}` maps to `{}`, a {} feature; reading LeRobot {}s is not supported yet",
                channel_of(&m.key),
                m.key,
                m.dtype,
                m.dtype
            )));
        }
        let mut warnings = mapped.warnings.clone();
        if let Some(m) = media.first() {
            if info.video_path.is_none() {
                return Err(Error::source(format!(
                    "{}: no `video_path`, but `{}` is a video feature",
                    info_path.display(),
                    m.key
                )));
            }
        }
        let excluding = spec.spec.audit.video == BadVideo::ExcludeEpisode;
        // `[source] episodes` is applied after the opening (`source::Subset`), but an episode
        // left out there is never read: its videos need not exist.
        let selected = |id: u64| {
            spec.source()
                .episodes
                .as_ref()
                .is_none_or(|ids| ids.contains(&id))
        };
        let mut files: BTreeMap<PathBuf, String> = BTreeMap::new();
        for m in &media {
            for (e, videos) in episodes.iter().zip(&video_files) {
                if !selected(e.id) {
                    continue;
                }
                let Some(r) = videos.get(&m.key) else {
                    continue;
                };
                if root.join(&r.file).exists() {
                    files.entry(r.file.clone()).or_insert_with(|| m.key.clone());
                } else if !excluding {
                    return Err(Error::source(format!(
                        "{shown}: episode {}, camera `{}` (channel `{}`), file {}: the file is missing; set `[audit] video = \"exclude_episode\"` to leave such episodes out",
                        e.id,
                        m.key,
                        channel_of(&m.key),
                        r.file.display()
                    )));
                }
            }
        }
        // A missing file first (the same message with or without the feature), then the feature.
        if let Some(m) = media.first().filter(|_| !codec::ENABLED) {
            return Err(Error::source(format!(
                "{shown}: channel `{}` maps to the video feature `{}`; {}",
                channel_of(&m.key),
                m.key,
                codec::DISABLED
            )));
        }
        // Trust the stream over info.json's `video.codec`, and say so.
        let probed: Vec<(PathBuf, String, std::result::Result<codec::Probe, String>)> = files
            .par_iter()
            .map(|(f, key)| (f.clone(), key.clone(), codec::probe(&root.join(f))))
            .collect();
        let mut disagree: BTreeMap<(String, String, String), Vec<PathBuf>> = BTreeMap::new();
        for (file, key, probe) in probed {
            let claimed = info.video_codecs.iter().find(|(k, _)| *k == key);
            if let (Ok(p), Some((_, claimed))) = (probe, claimed) {
                if codec::codec_family(claimed) != codec::codec_family(&p.codec) {
                    let k = (key, claimed.clone(), p.codec);
                    disagree.entry(k).or_default().push(file);
                }
            }
        }
        for ((key, claimed, found), files) in disagree {
            warnings.push(format!(
                "{}: `{key}` says `video.codec` is `{claimed}`, but {} file(s) hold {found} (first: {}); decoding what the stream holds",
                info_path.display(),
                files.len(),
                files[0].display()
            ));
        }
        read_files.extend(files.keys().cloned());
        let video_channels: BTreeMap<String, String> = media
            .iter()
            .map(|m| (m.key.clone(), channel_of(&m.key)))
            .collect();
        let video_refs: Vec<BTreeMap<String, VideoRef>> = video_files
            .into_iter()
            .map(|mut v| {
                v.retain(|k, _| video_channels.contains_key(k));
                v
            })
            .collect();

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
                parts: Vec::new(),
                format: SourceFormat::Lerobot,
                fps,
                episodes,
                channels: mapped.channels.clone(),
                fingerprint: fingerprint.hash,
                files: fingerprint.files,
                timestamps: has_timestamp,
                source_split,
                warnings,
                tasks,
            },
            mapped,
            locations,
            has_timestamp,
            footers,
            cache: BlockCache::new(block_cache::budget_from_env()),
            stamps,
            videos: video::Videos::new(root, video_refs, video_channels, fps),
        })
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
        // A v2.1 template naming the chunk `chunk_index` (as a real SO-101 set's does).
        let t = "data/chunk-{chunk_index:03d}/episode_{episode_index:06d}.parquet";
        let v = [
            ("episode_chunk", "0".into()),
            ("chunk_index", "0".into()),
            ("episode_index", "7".into()),
        ];
        assert_eq!(fill(t, &v), "data/chunk-000/episode_000007.parquet");
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
