//! The end of a profile's build, once the source has been read and the statistics reduced:
//! normalizers, the window index, the container's last writes, and every document and generated
//! file beside it. Returns the BLAKE3 of each file, for the lock.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::hash_outputs::hash_and_sync;
use super::rate::RateState;
use super::shared::{Shared, Stats};
use super::staging::Staging;
use super::FileHashes;
use crate::error::{IoContext, Result};
use crate::plan::{ProfilePlan, META_FILE, STATS_FILE};
use crate::render;
use crate::sink::video_info::StoredVideo;
use crate::sink::{self, documents, Sink};
use crate::source::{ChannelKind, Manifest};
use crate::stats::normalize::{Normalizer, RowNormalizer};
use crate::stats::ChannelStats;
use crate::timings;
use crate::window::Sampling;

/// A stale profile waiting for its rate's statistics: a position (of its rate when handed in,
/// of the profile once grouped by rate), its sink and its staging directory.
pub(super) type Waiting = (usize, Box<dyn Sink>, PathBuf);

/// Statistics once per (rate, channel), shared by every profile at that rate; each rate's
/// profiles finish (normalized writes, window index, documents, hashes) as soon as its
/// statistics are known, while other rates still reduce theirs. Profiles' files are
/// independent, and results are gathered in profile order.
pub(super) fn all(
    shared: &Shared,
    stale: &[&ProfilePlan],
    rates: &[RateState],
    profiles: Vec<Waiting>,
    staging: &Staging,
) -> Result<FileHashes> {
    let manifest = shared.manifest;
    let train_mask: Vec<bool> = manifest
        .episodes
        .iter()
        .map(|e| shared.plan.split.is_train(e.id))
        .collect();
    let mut by_rate: Vec<Vec<Waiting>> = rates.iter().map(|_| Vec::new()).collect();
    for (i, (r, sink, dir)) in profiles.into_iter().enumerate() {
        by_rate[r].push((i, sink, dir));
    }
    type Finished = Vec<(usize, Result<BTreeMap<String, String>>)>;
    let finished: Vec<Finished> = crate::error::in_order(rates.par_iter().zip(by_rate).map(
        |(rate, profiles)| -> Result<Vec<_>> {
            let (stats, sources) = {
                let _statistics = timings::phase("statistics");
                let sources = super::rate_stats::per_source(rate, manifest, &train_mask)?;
                (
                    super::rate_stats::stats(rate, manifest, &train_mask)?,
                    sources,
                )
            };
            Ok(profiles
                .into_par_iter()
                .map(|(i, sink, dir)| {
                    let p = stale[i];
                    let own = super::window_stats::profile_stats(
                        p,
                        rate,
                        manifest,
                        &stats,
                        &sources,
                        &train_mask,
                    );
                    let own = match own {
                        Ok(own) => own,
                        Err(e) => return (i, Err(e)),
                    };
                    let stats = Stats {
                        own: own.as_ref().map_or(&stats, |o| &o.pooled),
                        stored: &stats,
                        sources: own.as_ref().map_or(&sources, |o| &o.sources),
                    };
                    (i, profile(shared, p, rate, &stats, sink, &dir))
                })
                .collect())
        },
    ))?;
    let mut finished: Finished = finished.into_iter().flatten().collect();
    finished.sort_by_key(|(i, _)| *i);
    let mut hashes = BTreeMap::new();
    for (p, (_, files)) in stale.iter().zip(finished) {
        hashes.insert(p.name.clone(), files?);
        // `profile` fsynced every file it hashed.
        staging.files_synced(&p.name);
    }
    Ok(hashes)
}

/// A profile's last writes, in order: the container (normalized low-dim values, window index),
/// its documents and generated files; returns each file's BLAKE3.
pub(super) fn profile(
    shared: &Shared,
    p: &ProfilePlan,
    rate: &RateState,
    stats: &Stats,
    sink: Box<dyn Sink>,
    dir: &Path,
) -> Result<BTreeMap<String, String>> {
    let data = write_data(shared, p, rate, stats, sink)?;
    let documents = timings::phase("documents");
    write_documents(shared, p, rate, stats, &data, dir)?;
    drop(documents);
    let _hashing = timings::phase("hash outputs");
    hash_and_sync(dir, &data.hashed)
}

/// What the container's writes leave for the documents.
struct Written {
    /// The BLAKE3 of the files the sink hashed as it wrote them, by path.
    hashed: HashMap<PathBuf, blake3::Hash>,
    normalizers: BTreeMap<String, Normalizer>,
    /// A training mixture's, per source: what its rows are normalized with.
    source_normalizers: Vec<BTreeMap<String, Normalizer>>,
    /// Samples per split (train, val).
    counts: [usize; 2],
    /// Per episode, the `[t, t + limit]` of each sample, when the sampling is by segments.
    segments: Vec<Vec<[usize; 2]>>,
    data_file: String,
    normalized: bool,
    /// What each camera stored as one video per episode holds.
    videos: BTreeMap<String, StoredVideo>,
}

/// The normalized low-dim values and the window index, then the sink's last writes.
fn write_data(
    shared: &Shared,
    p: &ProfilePlan,
    rate: &RateState,
    all_stats: &Stats,
    mut sink: Box<dyn Sink>,
) -> Result<Written> {
    let lowdim = timings::phase("write low-dim");
    let stats = all_stats.own;
    let mut normalizers = BTreeMap::new();
    let mixture = super::source_normalizers::Normalizers::new(shared, p, all_stats);
    // With transforms the loader transforms raw values on read and normalizes after: every
    // low-dim channel is stored raw (a reference is read raw too).
    let raw = !p.transforms.is_empty();
    for (c, ch) in p.channels.iter().enumerate() {
        let n = Normalizer::fit(ch.normalize, &stats[&ch.name]);
        if ch.kind == ChannelKind::Lowdim {
            let stored = match (raw, &mixture) {
                (true, _) => RowNormalizer::single(Normalizer::identity(rate.lowdim[c].width())),
                (false, Some(m)) => m.rows(rate, shared.manifest, c),
                (false, None) => RowNormalizer::single(n.clone()),
            };
            sink.write_lowdim(c, &rate.lowdim[c], &stored)?;
        }
        normalizers.insert(ch.name.clone(), n);
    }
    drop(lowdim);
    let _windows = timings::phase("write index");
    // The index is counted here and generated again a block at a time as the sink writes it.
    let mut index = Index {
        p,
        rate,
        manifest: shared.manifest,
        splits: [Vec::new(), Vec::new()],
    };
    let mut segments = Vec::new();
    let mut counts = [0usize; 2];
    // Each episode's samples, counted on every thread (kept only for segments).
    let per_episode: Vec<(usize, Option<Vec<[usize; 2]>>)> = {
        let index = &index;
        crate::error::in_order((0..p.episodes.len()).into_par_iter().map(|e| -> Result<_> {
            let samples = index.samples(e)?;
            let kept = matches!(p.sampling, Sampling::Segment { .. })
                .then(|| samples.iter().map(|s| [s.t, s.t + s.limit]).collect());
            Ok((samples.len(), kept))
        }))?
    };
    for ((ep, (count, kept)), e) in p.episodes.iter().zip(per_episode).zip(0..) {
        segments.extend(kept);
        let split = usize::from(ep.split != "train");
        index.splits[split].push((counts[split], e));
        counts[split] += count;
    }
    for (episodes, &count) in index.splits.iter_mut().zip(&counts) {
        episodes.push((count, usize::MAX));
    }
    sink.write_index(&index)?;
    let data_file = sink.data_file().to_string();
    let normalized = sink.stores_normalized() && !raw;
    let finished = sink.finish()?;
    Ok(Written {
        hashed: finished.written,
        videos: finished.videos,
        normalizers,
        source_normalizers: mixture.map(|m| m.by_source).unwrap_or_default(),
        counts,
        segments,
        data_file,
        normalized,
    })
}

/// `meta.json`, `stats.json`, the codebase statistics files and the generated scripts.
fn write_documents(
    shared: &Shared,
    p: &ProfilePlan,
    rate: &RateState,
    all_stats: &Stats,
    data: &Written,
    dir: &Path,
) -> Result<()> {
    let stats = all_stats.own;
    let (plan, renderer) = (shared.plan, shared.renderer);
    let write = |name: &str, text: String| -> Result<()> {
        let path = dir.join(name);
        std::fs::write(&path, text).at("write", &path)
    };
    write(
        META_FILE,
        documents::meta_json(
            plan,
            p,
            &documents::Built {
                episode_ends: &rate.ends,
                normalizers: &data.normalizers,
                num_samples: data.counts,
                segments: &data.segments,
                source_normalizers: &data.source_normalizers,
                videos: &data.videos,
            },
            &data.data_file,
            data.normalized,
        )?,
    )?;
    write(STATS_FILE, documents::stats_json(p, stats))?;
    super::source_files::write_source_stats(shared, p, all_stats.sources, dir)?;
    if p.values.format == crate::spec::OutputFormat::Parquet && !p.values.is_groot() {
        // LeRobot v3.0 reads its statistics from `meta/stats.json` (a `groot` profile's are
        // GR00T's, written with its datasets).
        let path = dir.join(sink::lerobot::STATS_PATH);
        std::fs::write(&path, render::codebase::lerobot(p, all_stats.stored)).at("write", &path)?;
    }
    codebase_files(shared, p, rate, stats, &data.normalizers, dir)?;
    // The dataset card is written by `commands` once the dataset doctor has judged.
    for (name, text) in render::profile_files(renderer, plan, p)? {
        write(name, text)?;
    }
    for (path, text) in render::groot::configs(renderer, p, &plan.source.parts)? {
        write(&path, text)?;
    }
    Ok(())
}

/// The statistics files the profile's `stats_formats` ask for; returns (name, what) of each.
fn codebase_files(
    shared: &Shared,
    p: &ProfilePlan,
    rate: &RateState,
    stats: &BTreeMap<String, ChannelStats>,
    normalizers: &BTreeMap<String, Normalizer>,
    dir: &Path,
) -> Result<Vec<(String, String)>> {
    let mut stats_files = Vec::new();
    if p.values.stats_formats.is_empty() {
        return Ok(stats_files);
    }
    // ACT's `example_qpos`: the state of the first training episode, in raw units.
    let example_state = p
        .state_channel()
        .and_then(|state| {
            let c = p.channels.iter().position(|ch| ch.name == state.name)?;
            let e = p.episodes.iter().position(|ep| ep.split == "train")?;
            let width = shared.manifest.channels[c].width();
            let (start, end) = (rate.start(e), rate.ends.range(e).end);
            Some(rate.lowdim[c].rows(start, end).map(|v| (v, width)))
        })
        .transpose()?;
    let inputs = render::codebase::Inputs {
        profile: p,
        stats,
        normalizers,
        example_state: example_state.as_ref().map(|(v, w)| (v.as_ref(), *w)),
        renderer: shared.renderer,
    };
    for f in render::codebase::files(&p.values.stats_formats, &inputs)? {
        let path = dir.join(&f.name);
        std::fs::write(&path, f.bytes).at("write", &path)?;
        stats_files.push((f.name, f.what));
    }
    Ok(stats_files)
}

/// A profile's window index, generated on demand from the sampling (see [`sink::WindowIndex`]).
struct Index<'a> {
    p: &'a ProfilePlan,
    rate: &'a RateState,
    manifest: &'a Manifest,
    /// Per split (train, val): (first row, episode position) of each of its episodes, in order,
    /// then (rows, `usize::MAX`).
    splits: [Vec<(usize, usize)>; 2],
}

impl Index<'_> {
    /// The samples of episode `e`.
    fn samples(&self, e: usize) -> Result<Vec<crate::window::Sample>> {
        let ep = &self.p.episodes[e];
        let start = self.rate.start(e);
        Ok(match &self.p.sampling {
            Sampling::Segment { channel, .. } => {
                let width = self.manifest.channels[*channel].width();
                let values = self.rate.lowdim[*channel].rows(start, start + ep.len)?;
                self.p.sampling.samples(ep.len, Some((&values, width)))
            }
            _ => self.p.sampling.samples(ep.len, None),
        })
    }

    fn split(split: sink::Split) -> usize {
        match split {
            sink::Split::Train => 0,
            sink::Split::Val => 1,
        }
    }
}

impl sink::WindowIndex for Index<'_> {
    fn count(&self, split: sink::Split) -> usize {
        self.splits[Self::split(split)]
            .last()
            .map_or(0, |&(n, _)| n)
    }

    fn rows(&self, split: sink::Split, lo: usize, hi: usize) -> Result<Vec<[i64; 4]>> {
        let episodes = &self.splits[Self::split(split)];
        let mut out = Vec::with_capacity(hi.saturating_sub(lo));
        // The last episode starting at or before `lo`.
        let mut i = episodes
            .partition_point(|&(first, _)| first <= lo)
            .saturating_sub(1);
        while out.len() < hi - lo && i + 1 < episodes.len() {
            let (first, e) = episodes[i];
            let samples = self.samples(e)?;
            let from = lo.max(first) - first;
            let to = (hi - first).min(samples.len());
            out.extend(
                samples[from.min(to)..to]
                    .iter()
                    .map(|s| [e as i64, s.t as i64, s.limit as i64, s.sub as i64]),
            );
            i += 1;
        }
        Ok(out)
    }
}
