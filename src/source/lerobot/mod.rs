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
    /// Opens the dataset: `meta/info.json` (its rate, its features mapped to channels), the
    /// layout's episodes, the mapped cameras' videos checked, the stored split, and where each
    /// episode's rows are.
    pub fn open(spec: &LoadedSpec, root: &Path) -> Result<Self> {
        let (info, info_path) = read_info(root)?;
        let fps = rate(spec, &info, &info_path)?;
        let mapped = mapping::resolve(spec, &info_path, &info.features)?;
        let media = media(&mapped, &info.features);
        let mut listing = match info.version {
            Version::V2 => v2::list(root, &info, &media)?,
            Version::V3 => v3::list(root, &info, &media)?,
        };
        listing.read_files.push(PathBuf::from("meta/info.json"));
        check_episodes(root, &listing.episodes)?;
        let cameras = Cameras {
            spec,
            root,
            info: &info,
            info_path: &info_path,
            mapped: &mapped,
            media: &media,
        };
        let files = cameras.files(&listing)?;
        let mut warnings = mapped.warnings.clone();
        warnings.extend(cameras.codec_warnings(&files));
        listing.read_files.extend(files.into_keys());
        let video_channels = cameras.channels();
        let Listing {
            mut read_files,
            episodes,
            locations,
            mut video_files,
            tasks,
        } = listing;
        for videos in &mut video_files {
            videos.retain(|k, _| video_channels.contains_key(k));
        }
        let source_split = stored_split(&info, &episodes, &info_path);
        read_files.sort();
        read_files.dedup();
        let fingerprint = fingerprint::SourcePrint::beside(root, read_files);
        let has_timestamp = info.features.iter().any(|k| k.key == "timestamp");
        let footers = row_groups(root, &locations)?;
        let manifest = Manifest {
            timestamps: has_timestamp,
            source_split,
            tasks,
            ..Manifest::one_source(
                SourceFormat::Lerobot,
                fps,
                episodes,
                &mapped,
                fingerprint,
                warnings,
            )
        };
        Ok(LerobotSource {
            root: root.to_path_buf(),
            manifest,
            mapped,
            stamps: (0..locations.len()).map(|_| OnceLock::new()).collect(),
            locations,
            has_timestamp,
            footers,
            cache: BlockCache::new(block_cache::budget_from_env()),
            videos: video::Videos::new(root, video_files, video_channels, fps),
        })
    }
}

/// `meta/info.json`, parsed, and its path as messages show it.
fn read_info(root: &Path) -> Result<(Info, String)> {
    let info_path = root.join("meta/info.json");
    if !info_path.exists() {
        return Err(Error::source(format!(
            "{}: no meta/info.json; a LeRobot dataset has one",
            root.display()
        )));
    }
    let bytes = std::fs::read(&info_path)
        .map_err(|e| Error::source(format!("{}: cannot read: {e}", info_path.display())))?;
    let shown = info_path.display().to_string();
    Ok((Info::parse(&bytes, &shown)?, shown))
}

/// The rate info.json stores, which `source.fps` may repeat but not contradict (`source.fps`
/// only when info.json has none).
fn rate(spec: &LoadedSpec, info: &Info, info_path: &str) -> Result<f64> {
    match (info.fps, spec.source().fps) {
        (Some(stored), Some(given)) if (stored - given).abs() > 1e-9 => Err(spec.error_at(
            &["source", "fps"],
            format!("`source.fps` is {given}, but {info_path} says {stored}"),
            Some("leave `source.fps` out: LeRobot datasets store their rate".into()),
        )),
        (Some(stored), _) => Ok(stored),
        (None, Some(given)) => Ok(given),
        (None, None) => Err(Error::source(format!("{info_path}: no `fps`"))),
    }
}

/// The mapped features stored beside the parquet files (videos, images).
fn media<'a>(mapped: &Mapped, features: &'a [KeyInfo]) -> Vec<&'a KeyInfo> {
    mapped
        .keys()
        .iter()
        .filter_map(|k| features.iter().find(|i| &i.key == k))
        .filter(|k| k.dtype == "video" || k.dtype == "image")
        .collect()
}

/// The layout lists episodes, none of them empty.
fn check_episodes(root: &Path, episodes: &[EpisodeInfo]) -> Result<()> {
    let shown = root.display();
    if episodes.is_empty() {
        return Err(Error::source(format!(
            "{shown}: the dataset lists no episodes"
        )));
    }
    if let Some(e) = episodes.iter().find(|e| e.len == 0) {
        return Err(Error::source(format!("{shown}: episode {} is empty", e.id)));
    }
    Ok(())
}

/// The split info.json's `splits` store: the episodes in `train`'s ranges train, those in
/// another split's validate (`None` without `splits`).
fn stored_split(info: &Info, episodes: &[EpisodeInfo], info_path: &str) -> Option<SourceSplit> {
    let ranges = info.splits.as_ref()?;
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
    Some(SourceSplit {
        origin: format!("{info_path}: splits"),
        train,
        val,
    })
}

/// Per episode, v3.0's data file footer and how many episodes take rows from each of its row
/// groups (read once per file); `None` for v2's files of one episode.
fn row_groups(
    root: &Path,
    locations: &[(PathBuf, Option<Range<usize>>)],
) -> Result<Vec<Option<Arc<FileRowGroups>>>> {
    let mut by_file: BTreeMap<&PathBuf, Vec<Range<u64>>> = BTreeMap::new();
    for (rel, rows) in locations {
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
    Ok(locations
        .iter()
        .map(|(rel, rows)| rows.as_ref().and_then(|_| shared.get(rel).cloned()))
        .collect())
}

/// The mapped video and image features (`media`), and what opening checks of them.
struct Cameras<'a> {
    spec: &'a LoadedSpec,
    root: &'a Path,
    info: &'a Info,
    info_path: &'a str,
    mapped: &'a Mapped,
    media: &'a [&'a KeyInfo],
}

impl Cameras<'_> {
    /// The channel feature `key` is mapped to.
    fn channel_of(&self, key: &str) -> String {
        let channels = &self.mapped.channels;
        let channel = channels.iter().find(|c| c.key == key);
        channel.map(|c| c.name.clone()).unwrap_or_default()
    }

    /// Each mapped video feature's channel.
    fn channels(&self) -> BTreeMap<String, String> {
        let channel = |m: &&KeyInfo| (m.key.clone(), self.channel_of(&m.key));
        self.media.iter().map(channel).collect()
    }

    /// The video files the selected episodes read, each with its feature. Video and image
    /// features are not in the parquet files: images stored in parquet are not read yet; videos
    /// need the `video` cargo feature, info.json's template and (unless the audit may exclude
    /// the episode) every file.
    fn files(&self, listing: &Listing) -> Result<BTreeMap<PathBuf, String>> {
        let shown = self.root.display();
        if let Some(m) = self.media.iter().find(|m| m.dtype != "video") {
            return Err(Error::source(format!(
                "{shown}: channel `{}` maps to `{}`, a {} feature; reading LeRobot {}s is not supported yet",
                self.channel_of(&m.key),
                m.key,
                m.dtype,
                m.dtype
            )));
        }
        if let Some(m) = self
            .media
            .first()
            .filter(|_| self.info.video_path.is_none())
        {
            return Err(Error::source(format!(
                "{}: no `video_path`, but `{}` is a video feature",
                self.info_path, m.key
            )));
        }
        let excluding = self.spec.spec.audit.video == BadVideo::ExcludeEpisode;
        // `[source] episodes` is applied after the opening (`source::Subset`), but an episode
        // left out there is never read: its videos need not exist.
        let ids = self.spec.source().episodes.as_ref();
        let selected = |id: u64| ids.is_none_or(|ids| ids.contains(&id));
        let mut files: BTreeMap<PathBuf, String> = BTreeMap::new();
        for m in self.media {
            for (e, videos) in listing.episodes.iter().zip(&listing.video_files) {
                let Some(r) = videos.get(&m.key).filter(|_| selected(e.id)) else {
                    continue;
                };
                if self.root.join(&r.file).exists() {
                    files.entry(r.file.clone()).or_insert_with(|| m.key.clone());
                } else if !excluding {
                    return Err(Error::source(format!(
                        "{shown}: episode {}, camera `{}` (channel `{}`), file {}: the file is missing; set `[audit] video = \"exclude_episode\"` to leave such episodes out",
                        e.id,
                        m.key,
                        self.channel_of(&m.key),
                        r.file.display()
                    )));
                }
            }
        }
        // A missing file first (the same message with or without the feature), then the feature.
        if let Some(m) = self.media.first().filter(|_| !codec::ENABLED) {
            return Err(Error::source(format!(
                "{shown}: channel `{}` maps to the video feature `{}`; {}",
                self.channel_of(&m.key),
                m.key,
                codec::DISABLED
            )));
        }
        Ok(files)
    }

    /// Trust the stream over info.json's `video.codec`, and say so: a warning per feature and
    /// pair of codecs that disagree, counting the files.
    fn codec_warnings(&self, files: &BTreeMap<PathBuf, String>) -> Vec<String> {
        let probed: Vec<(PathBuf, String, std::result::Result<codec::Probe, String>)> = files
            .par_iter()
            .map(|(f, key)| (f.clone(), key.clone(), codec::probe(&self.root.join(f))))
            .collect();
        let mut disagree: BTreeMap<(String, String, String), Vec<PathBuf>> = BTreeMap::new();
        for (file, key, probe) in probed {
            let claimed = self.info.video_codecs.iter().find(|(k, _)| *k == key);
            if let (Ok(p), Some((_, claimed))) = (probe, claimed) {
                if codec::codec_family(claimed) != codec::codec_family(&p.codec) {
                    let k = (key, claimed.clone(), p.codec);
                    disagree.entry(k).or_default().push(file);
                }
            }
        }
        let warning = |((key, claimed, found), files): ((String, String, String), Vec<PathBuf>)| {
            format!(
                "{}: `{key}` says `video.codec` is `{claimed}`, but {} file(s) hold {found} (first: {}); decoding what the stream holds",
                self.info_path,
                files.len(),
                files[0].display()
            )
        };
        disagree.into_iter().map(warning).collect()
    }
}
