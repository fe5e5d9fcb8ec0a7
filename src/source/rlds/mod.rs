// Long file: one adapter's opening, scan and episode reads over the shards; framing, protos, features, images are in their own files.
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
//! - `image`: JPEG frames decoded as `tf.image.decode_jpeg` does.
//! - here: the adapter (open, check, read).

use std::collections::BTreeMap;
use std::fs::File;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::mapping::{self, KeyInfo, Mapped, Raw};
use super::{fingerprint, Episode, EpisodeInfo, Manifest, Source, SourceSplit};
use crate::error::{Error, Result};
use crate::spec::{LoadedSpec, SourceFormat};

pub mod example;
pub mod features;
mod image;
pub mod info;
pub mod tfrecord;

use example::Values;
use features::{Feature, Kind};

/// Where one episode is stored.
#[derive(Debug, Clone, Copy)]
struct Place {
    shard: usize,
    /// Record number within the shard.
    record: usize,
    at: tfrecord::Record,
}

/// What the opening scan learns about one episode.
#[derive(Debug, Clone, Default)]
struct Scanned {
    len: usize,
    task: Option<String>,
    /// Problems with the step markers, for the warnings.
    markers: Vec<&'static str>,
    /// Whether the language instruction changes within the episode.
    task_varies: bool,
    /// Per ragged feature: the constant row length, if every step has the same.
    row_lengths: BTreeMap<String, Option<i64>>,
}

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

/// The task of a TFDS split in chunkc's terms: `Some(true)` training, `Some(false)` validation.
fn split_role(name: &str) -> Option<bool> {
    match name {
        "train" => Some(true),
        "val" | "validation" | "test" => Some(false),
        _ => None,
    }
}

impl RldsSource {
    // Long function: opening is one sequence of checks (version dir, dataset_info, features, shards scanned, mapping, split, rate), each with its own message.
    pub fn open(spec: &LoadedSpec, path: &Path) -> Result<Self> {
        let dir = version_dir(path)?;
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

        // Every shard dataset_info.json names must be there, before anything is read.
        let mut shards = Vec::new();
        for split in &info.splits {
            for shard in &split.shards {
                let p = dir.join(&shard.file);
                let file = File::open(&p).map_err(|e| {
                    Error::source(format!(
                        "{}: split `{}` shard {} (named by {info_shown}): {}",
                        dir.display(),
                        split.name,
                        shard.file,
                        if e.kind() == std::io::ErrorKind::NotFound {
                            "missing".to_string()
                        } else {
                            format!("cannot open: {e}")
                        }
                    ))
                })?;
                shards.push((
                    p.display().to_string(),
                    file,
                    split.name.clone(),
                    shard.episodes,
                ));
            }
        }

        // The channels: first the paths features.json does not declare at all.
        check_paths(spec, &declared, &features_shown)?;

        // Shapes the feature spec leaves open (image sizes, ragged rows) come from the data;
        // the first episode gives them before the mapping is checked, the scan checks the rest.
        let first = shards
            .iter()
            .find(|s| s.3 > 0)
            .map(|(shown, file, ..)| first_record(file, shown))
            .transpose()?;
        let keys = key_infos(&declared, first.as_deref(), &features_shown)?;
        let mapped = mapping::resolve(spec, &features_shown, &keys)?;
        let read: BTreeMap<String, Feature> = mapped
            .keys()
            .iter()
            .map(|k| {
                let f = declared.iter().find(|f| &f.key == k).expect("resolved");
                (k.clone(), f.clone())
            })
            .collect();
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

        // The scan: every record of every shard, shards side by side.
        let scanned: Vec<(Vec<tfrecord::Record>, Vec<Scanned>)> = crate::error::in_order(shards
            .par_iter()
            .map(|(shown, _, _, expected)| -> Result<_> {
                let mut eps = Vec::new();
                let records = tfrecord::scan(Path::new(shown), shown, |i, r, data| {
                    let place = format!("{shown}: record {i} at byte offset {}", r.offset);
                    eps.push(scan_record(data, &declared, &place)?);
                    Ok(())
                })?;
                if records.len() as u64 != *expected {
                    return Err(Error::source(format!(
                        "{shown}: holds {} records, but {info_shown} says {expected}; the shard is truncated or the info is stale",
                        records.len()
                    )));
                }
                Ok((records, eps))
            }))?;

        let mut episodes = Vec::new();
        let mut places = Vec::new();
        let mut tasks = Vec::new();
        let mut train = Vec::new();
        let mut val = Vec::new();
        let mut warnings = mapped.warnings.clone();
        let mut marker_counts: BTreeMap<&'static str, (usize, u64)> = BTreeMap::new();
        let mut varying = Vec::new();
        let mut other_splits = Vec::new();
        for (s, ((records, eps), (shown, _, split, _))) in scanned.iter().zip(&shards).enumerate() {
            let role = split_role(split);
            if role.is_none() && !other_splits.contains(split) {
                other_splits.push(split.clone());
            }
            for (r, (record, ep)) in records.iter().zip(eps).enumerate() {
                let id = episodes.len() as u64;
                if ep.len == 0 {
                    return Err(Error::source(format!(
                        "{shown}: record {r} (episode {id}) has no steps"
                    )));
                }
                for (key, f) in &read {
                    if f.kind == Kind::Ragged {
                        let width = keys.iter().find(|k| &k.key == key).map(KeyInfo::width);
                        match ep.row_lengths.get(key).copied().flatten() {
                            Some(n) if Some(n as usize * inner_width(f)) == width => {}
                            _ => {
                                return Err(Error::source(format!(
                                    "{shown}: record {r} (episode {id}): `{key}` is ragged with rows of another length than the first episode's; a channel needs the same width every step"
                                )))
                            }
                        }
                    }
                }
                episodes.push(EpisodeInfo { id, len: ep.len });
                places.push(Place {
                    shard: s,
                    record: r,
                    at: *record,
                });
                tasks.push(ep.task.clone());
                if role.unwrap_or(true) {
                    train.push(id);
                } else {
                    val.push(id);
                }
                for m in &ep.markers {
                    let e = marker_counts.entry(m).or_insert((0, id));
                    e.0 += 1;
                }
                if ep.task_varies {
                    varying.push(id);
                }
            }
        }
        if episodes.is_empty() {
            return Err(Error::source(format!(
                "{}: the dataset holds no episodes",
                dir.display()
            )));
        }
        let n = episodes.len();
        for (what, (count, first)) in &marker_counts {
            warnings.push(format!(
                "{what} in {count} of {n} episodes (first: episode {first}); RLDS markers are only reported, never used"
            ));
        }
        if let Some(first) = varying.first() {
            warnings.push(format!(
                "the language instruction changes within {} episodes (first: episode {first}); each episode's task is its first step's",
                varying.len()
            ));
        }
        if !other_splits.is_empty() {
            warnings.push(format!(
                "TFDS splits {} are neither train nor val/test; `[split] from = \"source\"` counts them as training",
                other_splits.join(", ")
            ));
        }

        let mut files: Vec<PathBuf> = vec!["dataset_info.json".into(), "features.json".into()];
        for split in &info.splits {
            files.extend(split.shards.iter().map(|s| PathBuf::from(&s.file)));
        }
        files.sort();
        let fingerprint = fingerprint::of_files(&dir, &files)?;
        let fps = spec.source().fps.ok_or_else(|| {
            spec.error_at(
                &["source", "fps"],
                "`source.fps` is required for `format = \"rlds\"`: RLDS stores no rate",
                None,
            )
        })?;
        Ok(RldsSource {
            manifest: Manifest {
                parts: Vec::new(),
                format: SourceFormat::Rlds,
                fps,
                episodes,
                channels: mapped.channels.clone(),
                fingerprint: fingerprint.hash,
                files: fingerprint.files,
                timestamps: false,
                source_split: Some(SourceSplit {
                    origin: format!("{info_shown}: splits"),
                    train,
                    val,
                }),
                warnings,
                tasks: episodes_tasks(&tasks),
            },
            dir,
            mapped,
            read,
            shards: shards
                .into_iter()
                .map(|(shown, f, ..)| (shown, f))
                .collect(),
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

/// The tasks by episode id (ids are positions here), episodes without one left out.
fn episodes_tasks(tasks: &[Option<String>]) -> BTreeMap<u64, String> {
    tasks
        .iter()
        .enumerate()
        .filter_map(|(i, t)| t.clone().map(|t| (i as u64, t)))
        .collect()
}

/// A spec error for a channel path `features.json` does not declare, listing those it does.
fn check_paths(spec: &LoadedSpec, declared: &[Feature], shown: &str) -> Result<()> {
    let names: Vec<&str> = declared.iter().map(|f| f.key.as_str()).collect();
    for (name, channel) in &spec.source().channels {
        for key in channel.keys() {
            let at = ["source", "channels", name.as_str()];
            match declared.iter().find(|f| f.key == key) {
                None => {
                    let close = crate::spec::suggest_name(key, &names)
                        .map(|s| format!("did you mean `{s}`?"));
                    return Err(spec.error_at(
                        &at,
                        format!(
                            "channel `{name}` maps to `{key}`, which {shown} does not declare; it declares: {}",
                            names.join(", ")
                        ),
                        close,
                    ));
                }
                Some(f) => {
                    let why = match &f.kind {
                        _ if !f.per_step => Some(
                            "a per-episode feature (not under `steps`); channels are per step"
                                .to_string(),
                        ),
                        Kind::Text => Some(
                            "text; a language instruction is kept as the episode's task".into(),
                        ),
                        Kind::Other(what) => Some(format!("a {what}, which chunkc cannot read")),
                        _ => None,
                    };
                    if let Some(why) = why {
                        return Err(spec.error_at(
                            &at,
                            format!("channel `{name}` maps to `{key}`, which is {why}"),
                            None,
                        ));
                    }
                }
            }
        }
    }
    Ok(())
}

fn first_record(file: &File, shown: &str) -> Result<Vec<u8>> {
    let mut header = [0u8; 12];
    use std::os::unix::fs::FileExt;
    file.read_exact_at(&mut header, 0)
        .map_err(|_| Error::source(format!("{shown}: truncated: record 0 at byte offset 0")))?;
    let len = u64::from_le_bytes(header[..8].try_into().expect("8 bytes"));
    let size = file.metadata().map(|m| m.len()).unwrap_or(0);
    if len.saturating_add(16) > size {
        return Err(Error::source(format!(
            "{shown}: truncated: record 0 at byte offset 0 needs {} bytes, but the file ends after {size}",
            len.saturating_add(16)
        )));
    }
    tfrecord::read_at(file, tfrecord::Record { offset: 0, len }, shown, 0)
}

/// Values per row of a ragged feature (the product of its known dimensions).
fn inner_width(f: &Feature) -> usize {
    f.shape.iter().skip(1).map(|d| d.unwrap_or(1)).product()
}

/// The keys the channels may read: per-step numbers and images, with their per-step shapes
/// (open dimensions from the first episode).
fn key_infos(declared: &[Feature], first: Option<&[u8]>, shown: &str) -> Result<Vec<KeyInfo>> {
    let example = first.map(example::parse).transpose().map_err(|e| {
        Error::source(format!(
            "{shown}: the first record is not a tf.train.Example: {e}"
        ))
    })?;
    let mut out = Vec::new();
    for f in declared.iter().filter(|f| f.per_step) {
        let shape = match &f.kind {
            Kind::Tensor if f.shape.is_empty() => vec![1],
            Kind::Tensor => f.shape.iter().map(|d| d.unwrap_or(0)).collect(),
            Kind::Image { format } => {
                let mut dims: Vec<Option<usize>> = f.shape.clone();
                if dims.len() != 3 {
                    dims = vec![None, None, Some(3)];
                }
                if dims[0].is_none() || dims[1].is_none() {
                    let frame = example.as_ref().and_then(|e| match e.get(&f.key) {
                        Some(Values::Bytes(b)) => b.first().copied(),
                        _ => None,
                    });
                    if let (Some(frame), "jpeg") = (frame, format.as_str()) {
                        let (h, w) = super::jpeg::dimensions(frame).map_err(|e| {
                            Error::source(format!("{shown}: `{}` in the first episode: {e}", f.key))
                        })?;
                        dims[0] = Some(h);
                        dims[1] = Some(w);
                    }
                }
                dims.iter().map(|d| d.unwrap_or(0)).collect()
            }
            Kind::Ragged => {
                let rows = example.as_ref().and_then(|e| {
                    match e.get(&format!("{}/ragged_row_lengths_0", f.key)) {
                        Some(Values::Int64(v)) => v.first().copied(),
                        _ => None,
                    }
                });
                let inner: Vec<usize> = f.shape.iter().skip(1).map(|d| d.unwrap_or(1)).collect();
                let mut shape = vec![rows.unwrap_or(0).max(0) as usize];
                shape.extend(inner);
                if shape.len() > 1 {
                    vec![shape.iter().product()]
                } else {
                    shape
                }
            }
            _ => continue,
        };
        out.push(KeyInfo {
            key: f.key.clone(),
            shape,
            dtype: match &f.kind {
                Kind::Image { format } => format.clone(),
                _ => f.dtype.clone(),
            },
        });
    }
    Ok(out)
}

fn disagrees(place: &str, message: String) -> Error {
    Error::source(format!(
        "{place}: the record disagrees with features.json: {message}"
    ))
}

/// Checks one record against the feature spec and learns what the manifest needs.
// Long function: one pass over a record's features, checking each against features.json and keeping what the manifest needs.
fn scan_record(data: &[u8], declared: &[Feature], place: &str) -> Result<Scanned> {
    let ex = example::parse(data)
        .map_err(|e| Error::source(format!("{place}: not a tf.train.Example: {e}")))?;
    let mut out = Scanned::default();
    let mut steps: Option<(usize, &str)> = None;
    let mut stored = 0;
    for f in declared {
        for key in f.stored_keys() {
            let Some(values) = ex.get(&key) else {
                return Err(disagrees(
                    place,
                    format!("`{key}` is declared but not stored"),
                ));
            };
            stored += 1;
            let list = if key.ends_with("/ragged_row_lengths_0") {
                "int64_list"
            } else {
                f.list()
            };
            // An empty list carries no kind: TFDS writes empty episodes' lists that way.
            if !values.is_empty() && values.kind() != list {
                return Err(disagrees(
                    place,
                    format!(
                        "`{key}` is a {} {}, which TFDS stores as a {list}, but the record has a {}",
                        f.dtype,
                        match &f.kind {
                            Kind::Image { .. } => "image",
                            Kind::Text => "text",
                            _ => "tensor",
                        },
                        values.kind()
                    ),
                ));
            }
        }
        let n = ex[&f.stored_keys()[0]].len();
        if !f.per_step {
            let want = match f.kind {
                Kind::Tensor => f.width(),
                Kind::Text | Kind::Image { .. } => 1,
                _ => continue,
            };
            if n != want {
                return Err(disagrees(
                    place,
                    format!(
                        "`{}` holds {n} values, but its shape {:?} needs {want}",
                        f.key, f.shape
                    ),
                ));
            }
            continue;
        }
        let this = match f.kind {
            Kind::Tensor => {
                let w = f.width().max(if f.shape.is_empty() { 1 } else { 0 });
                if w == 0 {
                    continue;
                }
                if n % w != 0 {
                    return Err(disagrees(
                        place,
                        format!(
                            "`{}` holds {n} values, not a multiple of its per-step shape {:?}",
                            f.key, f.shape
                        ),
                    ));
                }
                n / w
            }
            Kind::Image { .. } | Kind::Text => n,
            Kind::Ragged => {
                let rows = match &ex[&format!("{}/ragged_row_lengths_0", f.key)] {
                    Values::Int64(v) => v.clone(),
                    _ => Vec::new(),
                };
                let total: i64 = rows.iter().sum();
                let flat = ex[&format!("{}/ragged_flat_values", f.key)].len();
                if rows.iter().any(|&r| r < 0) || total as usize * inner_width(f) != flat {
                    return Err(disagrees(
                        place,
                        format!(
                            "`{}`: the row lengths add up to {total} rows, but {flat} values are stored",
                            f.key
                        ),
                    ));
                }
                let constant = rows
                    .first()
                    .copied()
                    .filter(|r| rows.iter().all(|x| x == r));
                out.row_lengths.insert(f.key.clone(), constant);
                rows.len()
            }
            Kind::Other(_) => continue,
        };
        match steps {
            None => steps = Some((this, f.key.as_str())),
            Some((s, other)) if s != this => {
                return Err(disagrees(
                    place,
                    format!("`{}` has {this} steps, but `{other}` has {s}", f.key),
                ))
            }
            _ => {}
        }
        if f.kind == Kind::Text && f.key.ends_with("language_instruction") {
            if let Values::Bytes(v) = &ex[&f.key] {
                let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
                out.task = v.first().map(|b| text(b));
                out.task_varies = v.iter().any(|b| Some(text(b)) != out.task);
            }
        }
    }
    if stored != ex.len() {
        let wanted: Vec<String> = declared.iter().flat_map(Feature::stored_keys).collect();
        let extra: Vec<&String> = ex.keys().filter(|k| !wanted.contains(k)).collect();
        return Err(disagrees(
            place,
            format!(
                "it stores {}, which features.json does not declare",
                extra
                    .iter()
                    .map(|k| format!("`{k}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    out.len = steps.map_or(0, |s| s.0);
    // The RLDS step markers: first step first, last step last, terminal only at the end.
    let flags = |name: &str| match ex.get(&format!("steps/{name}")) {
        Some(Values::Int64(v)) if v.len() == out.len => Some(v.clone()),
        _ => None,
    };
    if let Some(v) = flags("is_first") {
        if v.first() != Some(&1) || v.iter().skip(1).any(|&x| x != 0) {
            out.markers
                .push("`steps/is_first` is not set on exactly the first step");
        }
    }
    if let Some(v) = flags("is_last") {
        if v.last() != Some(&1) || v.iter().rev().skip(1).any(|&x| x != 0) {
            out.markers
                .push("`steps/is_last` is not set on exactly the last step");
        }
    }
    if let Some(v) = flags("is_terminal") {
        if v.iter().rev().skip(1).any(|&x| x != 0) {
            out.markers
                .push("`steps/is_terminal` is set before the last step");
        }
    }
    Ok(out)
}

impl Source for RldsSource {
    fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn read_episode(&self, index: usize) -> Result<Episode> {
        self.read(index, true)
    }

    /// The low-dim channels only: no JPEG is decoded (the doctor reads every episode's low-dim
    /// values before the build).
    fn read_lowdim(&self, index: usize, channels: &[usize]) -> Result<Vec<Vec<f32>>> {
        Ok(self.read(index, false)?.take_lowdim(channels))
    }
}

impl RldsSource {
    /// The episode at `index`; without `decode_images`, its frames are zeros of the right size
    /// (for a caller that keeps only the low-dim values).
    fn read(&self, index: usize, decode_images: bool) -> Result<Episode> {
        let info = &self.manifest.episodes[index];
        let p = self.places[index];
        let (shown, file) = &self.shards[p.shard];
        let place = format!("{shown}: record {} (episode {})", p.record, info.id);
        let data = tfrecord::read_at(file, p.at, shown, p.record)?;
        let ex = example::parse(&data)
            .map_err(|e| Error::source(format!("{place}: not a tf.train.Example: {e}")))?;
        let len = info.len;
        let channels = mapping::assemble(&self.mapped, len, &place, |key| {
            let f = &self.read[key];
            let stored = match f.kind {
                Kind::Ragged => format!("{key}/ragged_flat_values"),
                _ => key.to_string(),
            };
            match (&f.kind, ex.get(&stored)) {
                (Kind::Image { .. }, Some(Values::Bytes(_))) if !decode_images => {
                    let shape = self.manifest_shape(key);
                    Ok(Raw::U8(vec![0u8; len * shape.iter().product::<usize>()]))
                }
                (Kind::Image { .. }, Some(Values::Bytes(frames))) => {
                    let info = self.manifest_shape(key);
                    let (h, w, c) = (info[0], info[1], info[2]);
                    let mut out = Vec::with_capacity(len * h * w * c);
                    for (t, frame) in frames.iter().enumerate() {
                        let (fh, fw) = image::decode_jpeg_tf(frame, c, &mut out).map_err(|e| {
                            Error::source(format!("{place}: `{key}` step {t}: {e}"))
                        })?;
                        if (fh, fw) != (h, w) {
                            return Err(Error::source(format!(
                                "{place}: `{key}` step {t} is {fh}x{fw}, but the channel's frames are {h}x{w}"
                            )));
                        }
                    }
                    Ok(Raw::U8(out))
                }
                (_, Some(Values::Float(v))) => Ok(Raw::F32(v.clone())),
                (_, Some(Values::Int64(v))) => Ok(Raw::F32(v.iter().map(|&x| x as f32).collect())),
                (_, Some(Values::Bytes(v))) if v.is_empty() => Ok(Raw::F32(Vec::new())),
                _ => Err(Error::source(format!(
                    "{place}: `{key}` changed since the dataset was opened"
                ))),
            }
        })?;
        Ok(Episode {
            id: info.id,
            len,
            timestamps: None,
            channels,
            packets: Default::default(),
        })
    }

    /// The per-step shape of an image key, as the mapping resolved it.
    fn manifest_shape(&self, key: &str) -> Vec<usize> {
        self.manifest
            .channels
            .iter()
            .find(|c| c.key == key)
            .map(|c| c.shape.clone())
            .unwrap_or_else(|| {
                let f = &self.read[key];
                f.shape.iter().map(|d| d.unwrap_or(0)).collect()
            })
    }
}
