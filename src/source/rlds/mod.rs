//! RLDS / Open X-Embodiment: TFDS-prepared directories read without TensorFlow.
//!
//! The largest public robot-learning corpus is published this way: a version directory with
//! `dataset_info.json` (splits, shard lengths, file template), `features.json` (the nested
//! feature spec) and `<name>-<split>.tfrecord-XXXXX-of-YYYYY` shards holding one
//! `tf.train.Example` per episode. Channels map feature paths (`steps/observation/image_0`,
//! `steps/action/world_vector`) with the usual `[source.channels]` (`concat`, `columns`).
//!
//! Opening scans every shard once, shards in parallel, one record in memory per shard: both
//! checksums of every record, every record against `features.json`, the episode lengths, the
//! language instruction (the episode's task) and the `is_first`/`is_last`/`is_terminal`
//! markers. Reading an episode reads its one record again by offset; images are decoded then,
//! with TensorFlow's settings ([`image`]). RLDS stores no rate (`source.fps` is required, which
//! the spec check enforces) and no timestamps.
//!
//! - `tfrecord`: the record framing and its crc32c checks.
//! - `example`: `tf.train.Example` decoding.
//! - `features`: `features.json`, flattened to the stored keys.
//! - `info`: `dataset_info.json`, the splits and shard files.
//! - `keys`: the channels' paths checked against `features.json`, and the keys they may read.
//! - `scan`: one record checked against `features.json`, and what the manifest needs of it.
//! - `listing`: the episodes assembled from the scanned shards, in shard order.
//! - `read`: an episode read (the `Source`).
//! - `image`: JPEG frames decoded as `tf.image.decode_jpeg` does.
//! - here: opening (the metadata, the shards, the channels, the scan).

use std::collections::BTreeMap;
use std::fs::File;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::mapping::{self, KeyInfo, Mapped};
use super::{fingerprint, Manifest, SourceSplit};
use crate::error::{Error, Result};
use crate::spec::{LoadedSpec, SourceFormat};

pub mod example;
pub mod features;
mod image;
pub mod info;
mod keys;
mod listing;
mod read;
mod scan;
pub mod tfrecord;

use features::{Feature, Kind};
use keys::{check_paths, first_record, key_infos};
use listing::{Listed, Place};
use scan::{scan_record, Scanned};
use tfrecord::Record;

pub struct RldsSource {
    dir: PathBuf,
    manifest: Manifest,
    mapped: Mapped,
    /// The declared features the channels read, by key.
    read: BTreeMap<String, Feature>,
    shards: Vec<(String, File)>,
    places: Vec<Place>,
    tasks: Vec<Option<String>>,
}

/// The version directory: `path` itself, or the one version inside a dataset directory.
fn version_dir(path: &Path) -> Result<PathBuf> {
    if path.join("dataset_info.json").is_file() {
        return Ok(path.to_path_buf());
    }
    let mut found = Vec::new();
    if let Ok(entries) = std::fs::read_dir(path) {
        for e in entries.flatten() {
            if e.path().join("dataset_info.json").is_file() {
                found.push(e.path());
            }
        }
    }
    found.sort();
    match found.len() {
        1 => Ok(found.remove(0)),
        0 => Err(Error::source(format!(
            "{}: no dataset_info.json, here or in a version directory below; an RLDS (TFDS) dataset has one",
            path.display()
        ))),
        _ => Err(Error::source(format!(
            "{}: several versions ({}); point `source.path` at one of them",
            path.display(),
            found
                .iter()
                .map(|p| p.file_name().unwrap_or_default().to_string_lossy().into_owned())
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}

fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::source(format!("{}: cannot read: {e}", path.display())))
}

impl RldsSource {
    /// Opens the version directory: its metadata, every shard it names, the channels mapped to
    /// the declared features, every record scanned and checked, and the episodes in shard order
    /// with their splits and tasks.
    pub fn open(spec: &LoadedSpec, path: &Path) -> Result<Self> {
        let dir = version_dir(path)?;
        let meta = Metadata::read(&dir)?;
        let shards = open_shards(&dir, &meta)?;
        let (keys, mapped, read) = map_channels(spec, &meta, &shards)?;
        let scanned = scan_shards(&shards, &meta)?;
        let listed = Listed::assemble(&scanned, &shards, &read, &keys)?;
        if listed.episodes.is_empty() {
            return Err(Error::source(format!(
                "{}: the dataset holds no episodes",
                dir.display()
            )));
        }
        let mut warnings = mapped.warnings.clone();
        warnings.extend(listed.warnings());
        let fingerprint = fingerprint::SourcePrint::beside(&dir, meta.files());
        let fps = spec.source().fps.ok_or_else(|| {
            spec.error_at(
                &["source", "fps"],
                "`source.fps` is required for `format = \"rlds\"`: RLDS stores no rate",
                None,
            )
        })?;
        let Listed {
            episodes,
            places,
            tasks,
            train,
            val,
            ..
        } = listed;
        let source_split = Some(SourceSplit {
            origin: format!("{}: splits", meta.info_shown),
            train,
            val,
        });
        let manifest = Manifest {
            source_split,
            tasks: episodes_tasks(&tasks),
            ..Manifest::one_source(
                SourceFormat::Rlds,
                fps,
                episodes,
                &mapped,
                fingerprint,
                warnings,
            )
        };
        Ok(RldsSource {
            manifest,
            dir,
            mapped,
            read,
            shards: shards.into_iter().map(|s| (s.shown, s.file)).collect(),
            places,
            tasks,
        })
    }

    /// Each episode's task (its language instruction), in manifest order.
    pub fn tasks(&self) -> &[Option<String>] {
        &self.tasks
    }

    /// The version directory read.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

/// A version directory's `dataset_info.json` and `features.json`, with their paths as
/// messages show them.
struct Metadata {
    info: info::DatasetInfo,
    declared: Vec<Feature>,
    info_shown: String,
    features_shown: String,
}

impl Metadata {
    fn read(dir: &Path) -> Result<Metadata> {
        let info_path = dir.join("dataset_info.json");
        let features_path = dir.join("features.json");
        let info_shown = info_path.display().to_string();
        let features_shown = features_path.display().to_string();
        let info = info::parse(&read_file(&info_path)?, &info_shown).map_err(Error::source)?;
        if !features_path.is_file() {
            return Err(Error::source(format!(
                "{}: no features.json; TFDS writes one beside dataset_info.json",
                dir.display()
            )));
        }
        let declared =
            features::parse(&read_file(&features_path)?, &features_shown).map_err(Error::source)?;
        Ok(Metadata {
            info,
            declared,
            info_shown,
            features_shown,
        })
    }

    /// The files the fingerprint covers: both documents and every shard they name.
    fn files(&self) -> Vec<PathBuf> {
        let mut files: Vec<PathBuf> = vec!["dataset_info.json".into(), "features.json".into()];
        for split in &self.info.splits {
            files.extend(split.shards.iter().map(|s| PathBuf::from(&s.file)));
        }
        files.sort();
        files
    }
}

/// One shard file, open, with its split and the episodes `dataset_info.json` says it holds.
struct Shard {
    shown: String,
    file: File,
    split: String,
    expected: u64,
}

/// Every shard `dataset_info.json` names, opened before anything is read.
fn open_shards(dir: &Path, meta: &Metadata) -> Result<Vec<Shard>> {
    let mut shards = Vec::new();
    for split in &meta.info.splits {
        for shard in &split.shards {
            let p = dir.join(&shard.file);
            let file = File::open(&p).map_err(|e| {
                Error::source(format!(
                    "{}: split `{}` shard {} (named by {}): {}",
                    dir.display(),
                    split.name,
                    shard.file,
                    meta.info_shown,
                    if e.kind() == std::io::ErrorKind::NotFound {
                        "missing".to_string()
                    } else {
                        format!("cannot open: {e}")
                    }
                ))
            })?;
            shards.push(Shard {
                shown: p.display().to_string(),
                file,
                split: split.name.clone(),
                expected: shard.episodes,
            });
        }
    }
    Ok(shards)
}

/// The channels mapped to the declared features, with the keys they were checked against and
/// the features they read (JPEG frames only, so far).
fn map_channels(
    spec: &LoadedSpec,
    meta: &Metadata,
    shards: &[Shard],
) -> Result<(Vec<KeyInfo>, Mapped, BTreeMap<String, Feature>)> {
    // First the paths features.json does not declare at all.
    check_paths(spec, &meta.declared, &meta.features_shown)?;
    // Shapes the feature spec leaves open (image sizes, ragged rows) come from the data; the
    // first episode gives them before the mapping is checked, the scan checks the rest.
    let first = shards
        .iter()
        .find(|s| s.expected > 0)
        .map(|s| first_record(&s.file, &s.shown))
        .transpose()?;
    let keys = key_infos(&meta.declared, first.as_deref(), &meta.features_shown)?;
    let mapped = mapping::resolve(spec, &meta.features_shown, &keys)?;
    let feature = |k: &String| {
        let f = meta
            .declared
            .iter()
            .find(|f| &f.key == k)
            .expect("resolved");
        (k.clone(), f.clone())
    };
    let read: BTreeMap<String, Feature> = mapped.keys().iter().map(feature).collect();
    for f in read.values() {
        if let Kind::Image { format } = &f.kind {
            if format != "jpeg" {
                return Err(spec.error_at(
                    &["source", "channels"],
                    format!(
                        "`{}` holds {format} frames; chunkc reads RLDS JPEG frames only so far",
                        f.key
                    ),
                    None,
                ));
            }
        }
    }
    Ok((keys, mapped, read))
}

/// Every record of every shard, scanned ([`scan_record`]), shards side by side; each shard
/// holds as many as `dataset_info.json` says.
fn scan_shards(shards: &[Shard], meta: &Metadata) -> Result<Vec<(Vec<Record>, Vec<Scanned>)>> {
    crate::error::in_order(shards.par_iter().map(|shard| -> Result<_> {
        let shown = &shard.shown;
        let mut eps = Vec::new();
        let records = tfrecord::scan(Path::new(shown), shown, |i, r, data| {
            let place = format!("{shown}: record {i} at byte offset {}", r.offset);
            eps.push(scan_record(data, &meta.declared, &place)?);
            Ok(())
        })?;
        if records.len() as u64 != shard.expected {
            return Err(Error::source(format!(
                "{shown}: holds {} records, but {} says {}; the shard is truncated or the info is stale",
                records.len(),
                meta.info_shown,
                shard.expected
            )));
        }
        Ok((records, eps))
    }))
}

/// The tasks by episode id (ids are positions here), episodes without one left out.
fn episodes_tasks(tasks: &[Option<String>]) -> BTreeMap<u64, String> {
    tasks
        .iter()
        .enumerate()
        .filter_map(|(i, t)| t.clone().map(|t| (i as u64, t)))
        .collect()
}
