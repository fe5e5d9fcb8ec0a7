//! Stage 5, execute: the only place that uses threads.
//!
//! The source is read once, in batches of episodes decoded in parallel (rayon) and consumed in
//! episode order, so memory stays bounded by the batch and every write and every statistics merge
//! happens in the same order whatever the thread count. A panic inside an episode job becomes an
//! error naming the episode.
//!
//! - `finish`: a profile's last writes once the statistics are known.
//! - `location`: where the output may go (never into the source; through a symlink only when
//!   the spec allows it).
//! - `staging`: the staging directory and the final renames.
//! - `progress`: progress bars (hidden when stderr is not a terminal).
//! - `store`: the low-dim values of one channel at one rate, spilled to disk beyond a budget.
//! - `timings`: wall time per phase, printed when `CHUNKC_TIMINGS` is set.

mod finish;
mod location;
mod progress;
mod staging;
mod store;
pub mod timings;

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use rayon::prelude::*;

use crate::audit::{self, AuditReport};
use crate::error::{Error, Result};
use crate::lock::{self, Lock, LockedProfile, SpecLock, LOCK_VERSION};
use crate::plan::{self, Conversion, Plan, ProfilePlan};
use crate::render;
use crate::sink::{self, FrameEncoding, Frames, Sink, SinkContext};
use crate::source::{self, ChannelData, ChannelKind, Episode, Source};
use crate::spec::{LoadedSpec, SplitFrom};
use crate::stats::{self, ChannelStats, ImagePartial};
use crate::window::EpisodeEnds;

pub use staging::{BUILD_LOCK_FILE, STAGING_DIR};
pub use store::{budget_from_env as spill_budget, LowdimStore};

#[derive(Debug, Clone, Default)]
pub struct BuildOptions {
    /// Fail instead of building when anything is out of date (`--locked`).
    pub locked: bool,
    /// Show progress bars (they are hidden anyway when stderr is not a terminal).
    pub progress: bool,
}

#[derive(Debug, Clone)]
pub struct BuildReport {
    pub out_dir: PathBuf,
    pub built: Vec<String>,
    pub up_to_date: Vec<String>,
    /// How many times each source episode was read (manifest order): 1 each when anything was
    /// built, whatever the number of profiles and rates; empty when nothing was.
    pub episode_reads: Vec<usize>,
    /// How many times each storage chunk of the source was decoded (array, then chunk index;
    /// see [`source::block_cache`]): 1 each when anything was built, whatever the source's
    /// chunking; empty when nothing was.
    pub chunk_decodes: source::DecodeCounts,
}

/// Opens the source and audits it: the source as read, the audit, and each episode's repair.
pub fn audit(spec: &LoadedSpec) -> Result<(Box<dyn Source>, AuditReport, Vec<audit::Repair>)> {
    check_output_location(spec, &spec.resolve(&spec.spec.output.dir))?;
    let opened = timings::phase("open source");
    let source = source::open(spec)?;
    drop(opened);
    let _audit = timings::phase("audit");
    let (report, repairs) = audit::run(spec, source.as_ref())?;
    Ok((source, report, repairs))
}

/// Opens the source, audits it, and resolves the plan against the lock (what `chunkc plan`
/// shows). The source returned is the audited one: exclusions gone, repairs applied on read.
pub fn plan(spec: &LoadedSpec) -> Result<(Box<dyn Source>, Plan)> {
    let (raw, report, repairs) = audit(spec)?;
    let applied = spec.spec.audit.repair;
    let source: Box<dyn Source> = Box::new(audit::Audited::new(raw, &report, repairs, applied));
    let manifest = source.manifest();
    if manifest.episodes.is_empty() {
        return Err(Error::source(format!(
            "{}: the audit excluded every episode ({}); see `chunkc audit`, or relax `[audit]`",
            spec.spec.source.path,
            report
                .episodes
                .first()
                .map(|e| format!("episode {}: {}", e.id, e.detail))
                .unwrap_or_default()
        )));
    }
    for warning in &manifest.warnings {
        eprintln!("warning: {warning}");
    }
    if spec.spec.split.from == SplitFrom::Source && manifest.source_split.is_none() {
        eprintln!(
            "warning: `split.from = \"source\"`, but {} stores no split; using `val_fraction` and `seed`",
            spec.spec.source.path
        );
    }
    let out_dir = spec.resolve(&spec.spec.output.dir);
    location::check(spec, &out_dir)?;
    let lock = Lock::read(&lock::path_for(&spec.file))?;
    let entry = lock
        .as_ref()
        .and_then(|l| l.specs.get(&lock::key_for(&spec.file)));
    let mut plan = plan::resolve(spec, source.manifest(), entry, &out_dir)?;
    plan::apply_audit(&mut plan, &report, applied);
    Ok((source, plan))
}

/// Where the output may go (never into the source; through a symlink only when the spec allows
/// it); `analyze` and `audit` write under the output directory too.
pub(crate) fn check_output_location(spec: &LoadedSpec, out_dir: &Path) -> Result<()> {
    location::check(spec, out_dir)
}

pub fn build(spec: &LoadedSpec, opts: &BuildOptions) -> Result<BuildReport> {
    let whole = timings::phase("whole build");
    let out_dir = spec.resolve(&spec.spec.output.dir);
    // Never create anything (not even the lock) inside a source.
    location::check(spec, &out_dir)?;
    let mut build_lock = staging::BuildLock::acquire(&out_dir)?;
    // Repair what an interrupted build left, before the plan compares outputs with the lock.
    staging::Staging::recover(&out_dir)?;
    let (source, plan) = plan(spec)?;
    let stale: Vec<&ProfilePlan> = plan
        .profiles
        .iter()
        .filter(|p| !p.status.is_up_to_date())
        .collect();
    let up_to_date: Vec<String> = plan
        .profiles
        .iter()
        .filter(|p| p.status.is_up_to_date())
        .map(|p| p.name.clone())
        .collect();
    if stale.is_empty() {
        return Ok(BuildReport {
            out_dir,
            built: Vec::new(),
            up_to_date,
            episode_reads: Vec::new(),
            chunk_decodes: Default::default(),
        });
    }
    if opts.locked {
        let reasons: Vec<String> = stale
            .iter()
            .filter_map(|p| Some(format!("  {}: {}", p.name, p.status.reason()?)))
            .collect();
        return Err(Error::Locked(format!(
            "--locked: these profiles would be rebuilt:\n{}",
            reasons.join("\n")
        )));
    }

    let reads: Vec<AtomicUsize> = (0..plan.source.episodes)
        .map(|_| AtomicUsize::new(0))
        .collect();
    let chunk_decodes: source::DecodeCounts;
    let (plan, stale, hashes) =
        match run_staged(spec, &plan, &stale, source.as_ref(), opts, &reads)? {
            Outcome::Built(staging, hashes) => {
                chunk_decodes = source.decode_counts();
                let built: Vec<String> = stale.iter().map(|p| p.name.clone()).collect();
                build_lock.keep();
                let _commit = timings::phase("commit (fsync)");
                staging.commit(&built)?;
                (plan, built, hashes)
            }
            Outcome::Exclude(excluded) => {
                // `[audit] non_finite = "exclude_episode"` found episodes to leave out. Which ones
                // depends only on the data, so the output stays deterministic: plan again without
                // them and build from that plan (this reads the kept episodes a second time).
                let ids: Vec<u64> = excluded.keys().copied().collect();
                let kept: Box<dyn Source> = Box::new(source::Subset::without(source, &ids));
                let lock = Lock::read(&lock::path_for(&spec.file))?;
                let entry = lock
                    .as_ref()
                    .and_then(|l| l.specs.get(&lock::key_for(&spec.file)));
                let mut replan = plan::resolve(spec, kept.manifest(), entry, &out_dir)?;
                replan.audit = plan.audit.clone();
                for (p, before) in replan.profiles.iter_mut().zip(&plan.profiles) {
                    p.excluded = before.excluded.clone();
                    p.excluded
                        .extend(excluded.iter().map(|(&id, reason)| plan::Excluded {
                            id,
                            reason: reason.clone(),
                        }));
                    p.excluded.sort_by_key(|e| e.id);
                    p.repaired = before
                        .repaired
                        .iter()
                        .filter(|r| !excluded.contains_key(&r.id))
                        .cloned()
                        .collect();
                }
                let names: Vec<String> = stale.iter().map(|p| p.name.clone()).collect();
                let restale: Vec<&ProfilePlan> = replan
                    .profiles
                    .iter()
                    .filter(|p| names.contains(&p.name))
                    .collect();
                let again: Vec<AtomicUsize> = (0..replan.source.episodes)
                    .map(|_| AtomicUsize::new(0))
                    .collect();
                match run_staged(spec, &replan, &restale, kept.as_ref(), opts, &again)? {
                    Outcome::Built(staging, hashes) => {
                        chunk_decodes = kept.decode_counts();
                        build_lock.keep();
                        staging.commit(&names)?;
                        (replan, names, hashes)
                    }
                    Outcome::Exclude(more) => {
                        return Err(Error::Internal(format!(
                            "episodes {:?} passed the audit once and failed it the second time",
                            more.keys().collect::<Vec<_>>()
                        )))
                    }
                }
            }
        };
    let built = stale;

    // Re-read the lock: only this spec's entry changes, whatever else it holds.
    let lock_path = lock::path_for(&spec.file);
    let key = lock::key_for(&spec.file);
    let mut all = Lock::read(&lock_path)?.unwrap_or(Lock {
        version: LOCK_VERSION,
        specs: BTreeMap::new(),
    });
    let previous = all.specs.remove(&key).unwrap_or_default();
    let mut profiles = BTreeMap::new();
    for p in &plan.profiles {
        let entry = match hashes.get(&p.name) {
            Some(files) => LockedProfile {
                fingerprint: p.fingerprint.clone(),
                files: files.clone(),
                inputs: p.inputs.clone(),
            },
            None => previous.profiles.get(&p.name).cloned().unwrap_or_default(),
        };
        profiles.insert(p.name.clone(), entry);
    }
    all.specs.insert(
        key,
        SpecLock {
            tool_version: plan::TOOL_VERSION.to_string(),
            spec_hash: plan.spec_hash.clone(),
            source_fingerprint: plan.source.fingerprint.clone(),
            source_files: plan.source.files.clone(),
            profiles,
        },
    );
    all.write(&lock_path)?;
    drop(whole);
    timings::report();
    Ok(BuildReport {
        out_dir,
        built,
        up_to_date,
        episode_reads: reads.into_iter().map(AtomicUsize::into_inner).collect(),
        chunk_decodes,
    })
}

/// BLAKE3 of every output file, by profile, then path.
type FileHashes = BTreeMap<String, BTreeMap<String, String>>;
/// Episodes to leave out: id → reason.
type Excluded = BTreeMap<u64, String>;

enum Outcome {
    Built(staging::Staging, FileHashes),
    /// Nothing was kept of this attempt.
    Exclude(Excluded),
}

fn run_staged(
    spec: &LoadedSpec,
    plan: &Plan,
    stale: &[&ProfilePlan],
    source: &dyn Source,
    opts: &BuildOptions,
    reads: &[AtomicUsize],
) -> Result<Outcome> {
    let out_dir = spec.resolve(&spec.spec.output.dir);
    let staging = staging::Staging::new(&out_dir)?;
    run(spec, plan, stale, source, &staging, opts, reads).map(|r| match r {
        Ok(hashes) => Outcome::Built(staging, hashes),
        Err(excluded) => Outcome::Exclude(excluded),
    })
}

/// Per-rate state: the decimated low-dimensional data of every episode, and the streaming
/// statistics of image channels.
struct RateState {
    conversion: Conversion,
    /// Exclusive ends of each episode in the decimated per-step arrays.
    ends: EpisodeEnds,
    /// Per channel (manifest order): concatenated low-dim values; empty for images. Shared with
    /// the sinks that export episode by episode once reading is over.
    lowdim: Vec<Arc<LowdimStore>>,
    /// Per channel: the statistics partials of the training episodes, merged in episode order.
    partials: Vec<Partial>,
}

/// The part of a channel's statistics reduced while the source is read: moments of low-dim
/// channels (their percentiles need every value, and are taken from the store at the end), and
/// moments + histograms of images.
enum Partial {
    Lowdim(stats::Moments),
    Image(ImagePartial),
}

impl Partial {
    fn merge(&mut self, other: &Partial) {
        match (self, other) {
            (Partial::Lowdim(a), Partial::Lowdim(b)) => a.merge(b),
            (Partial::Image(a), Partial::Image(b)) => a.merge(b),
            _ => unreachable!("partials of one channel have one kind"),
        }
    }
}

/// One episode's channel after the parallel part of the work.
enum Prepared {
    Lowdim(Vec<f32>),
    /// The frames in every encoding a sink at this rate asked for.
    Frames(Vec<(FrameEncoding, Frames)>),
}

/// One episode after the parallel part of the work: decimated per rate, images compressed,
/// statistics partials computed.
struct Processed {
    /// Per rate (in `RateState` order), per channel.
    data: Vec<Vec<Prepared>>,
    /// Per rate, per channel: the statistics partial, if this is a training episode.
    partials: Vec<Vec<Option<Partial>>>,
}

fn decimate<T: Copy>(values: &[T], width: usize, factor: usize) -> Vec<T> {
    if factor == 1 || width == 0 {
        return values.to_vec();
    }
    let mut out = Vec::with_capacity((values.len() / width).div_ceil(factor) * width);
    for row in values.chunks_exact(width).step_by(factor) {
        out.extend_from_slice(row);
    }
    out
}

/// Decimates an episode to every rate, encodes its frames for every sink, and computes the
/// statistics partials of a training episode. Runs in parallel over episodes.
fn process(
    mut episode: Episode,
    source: &dyn Source,
    rates: &[(Conversion, Vec<FrameEncoding>)],
    train: bool,
) -> Processed {
    let channels = &source.manifest().channels;
    let mut data: Vec<Vec<Prepared>> = rates.iter().map(|_| Vec::new()).collect();
    let mut partials: Vec<Vec<Option<Partial>>> = rates.iter().map(|_| Vec::new()).collect();
    // The source's own rate goes last, so that it can take the values once every other rate
    // has been derived from them (no copy of the episode).
    let identity = |r: &usize| rates[*r].0 == Conversion::Decimate { factor: 1 };
    let order: Vec<usize> = (0..rates.len())
        .filter(|r| !identity(r))
        .chain((0..rates.len()).filter(identity))
        .collect();
    for (k, &r) in order.iter().enumerate() {
        let (conversion, encodings) = &rates[r];
        let last = k + 1 == order.len();
        let mut per_channel = Vec::with_capacity(channels.len());
        let mut per_partial = Vec::with_capacity(channels.len());
        for (ch, values) in channels.iter().zip(episode.channels.iter_mut()) {
            let width = ch.width();
            let converted = match *conversion {
                // The source's own rate, last, takes the values (no copy).
                Conversion::Decimate { factor: 1 } if last => match values {
                    ChannelData::Lowdim(v) => ChannelData::Lowdim(std::mem::take(v)),
                    ChannelData::Image(v) => ChannelData::Image(std::mem::take(v)),
                },
                Conversion::Decimate { factor } => match &*values {
                    ChannelData::Lowdim(v) => ChannelData::Lowdim(decimate(v, width, factor)),
                    ChannelData::Image(v) => ChannelData::Image(decimate(v, width, factor)),
                },
                Conversion::Resample { method, .. } => {
                    audit::repair::convert_rate(values, width, conversion.len(episode.len), method)
                }
            };
            match converted {
                ChannelData::Lowdim(v) => {
                    per_partial
                        .push(train.then(|| Partial::Lowdim(stats::Moments::of_rows(&v, width))));
                    per_channel.push(Prepared::Lowdim(v));
                }
                ChannelData::Image(d) => {
                    let frames = d.len() / width.max(1);
                    let colors = *ch.shape.last().unwrap_or(&1);
                    per_partial.push(
                        train.then(|| Partial::Image(ImagePartial::of_frames(&d, frames, colors))),
                    );
                    // Compressed encodings first, then the pixels themselves become the raw frames.
                    let mut encoded: Vec<(FrameEncoding, Frames)> = encodings
                        .iter()
                        .filter(|&&enc| enc != FrameEncoding::Raw)
                        .map(|&enc| (enc, Frames::encode(enc, &d, &ch.shape)))
                        .collect();
                    if encodings.contains(&FrameEncoding::Raw) {
                        encoded.push((FrameEncoding::Raw, Frames::raw(d, width)));
                    }
                    per_channel.push(Prepared::Frames(encoded));
                }
            }
        }
        data[r] = per_channel;
        partials[r] = per_partial;
    }
    Processed { data, partials }
}

/// Bytes of decoded values a batch of episodes may hold, beyond its minimum size.
const BATCH_BYTES: usize = 8 << 20;

/// Episodes decoded at once, in order: at least two per thread (to keep every thread busy), and
/// more while their decoded values stay under [`BATCH_BYTES`] (short low-dim episodes: fewer
/// pauses between batches). Memory stays bounded by the batch.
fn batches(manifest: &source::Manifest) -> Vec<std::ops::Range<usize>> {
    let min = 2 * rayon::current_num_threads();
    let step_bytes: usize = manifest
        .channels
        .iter()
        .map(|c| match c.kind {
            ChannelKind::Lowdim => 4 * c.width(),
            ChannelKind::Image => c.width(),
        })
        .sum();
    let mut out = Vec::new();
    let (mut start, mut bytes) = (0, 0);
    for (i, e) in manifest.episodes.iter().enumerate() {
        bytes += e.len * step_bytes;
        if i + 1 - start >= min && bytes >= BATCH_BYTES {
            out.push(start..i + 1);
            (start, bytes) = (i + 1, 0);
        }
    }
    if start < manifest.episodes.len() {
        out.push(start..manifest.episodes.len());
    }
    out
}

fn run(
    spec: &LoadedSpec,
    plan: &Plan,
    stale: &[&ProfilePlan],
    source: &dyn Source,
    staging: &staging::Staging,
    opts: &BuildOptions,
    reads: &[AtomicUsize],
) -> Result<Result<FileHashes, Excluded>> {
    let manifest = source.manifest();
    let non_finite = spec.spec.audit.non_finite;
    let source_path = spec.spec.source.path.as_str();
    let mut excluded: BTreeMap<u64, String> = BTreeMap::new();
    // Test hook: the tests prove that a panicking episode job becomes an error naming it.
    let panic_on: Option<u64> = std::env::var("CHUNKC_TEST_PANIC_EPISODE")
        .ok()
        .and_then(|v| v.parse().ok());
    let overrides = spec
        .spec
        .output
        .templates
        .as_deref()
        .map(|t| spec.resolve(t));
    let renderer = &render::Renderer::new(overrides.as_deref())?;
    // In plan order (fastest first), once each.
    let conversions: Vec<Conversion> = plan
        .rates
        .iter()
        .map(|r| r.conversion)
        .filter(|c| stale.iter().any(|p| p.conversion == *c))
        .collect();

    let budget = store::budget_from_env();
    let mut rates: Vec<RateState> = conversions
        .iter()
        .enumerate()
        .map(|(r, &conversion)| {
            let mut ends = Vec::with_capacity(manifest.episodes.len());
            let mut total = 0u64;
            for e in &manifest.episodes {
                total += conversion.len(e.len) as u64;
                ends.push(total);
            }
            RateState {
                conversion,
                ends: EpisodeEnds::new(ends),
                lowdim: manifest
                    .channels
                    .iter()
                    .enumerate()
                    .map(|(c, ch)| {
                        let width = match ch.kind {
                            ChannelKind::Lowdim => ch.width(),
                            ChannelKind::Image => 0,
                        };
                        let dir = staging.scratch_dir().join(format!("rate{r}-channel{c}"));
                        Arc::new(LowdimStore::new(width, budget, dir, total as usize))
                    })
                    .collect(),
                partials: manifest
                    .channels
                    .iter()
                    .map(|c| match c.kind {
                        ChannelKind::Lowdim => Partial::Lowdim(stats::Moments::new(c.width())),
                        ChannelKind::Image => {
                            Partial::Image(ImagePartial::new(*c.shape.last().unwrap_or(&1)))
                        }
                    })
                    .collect(),
            }
        })
        .collect();

    let ids: Vec<u64> = manifest.episodes.iter().map(|e| e.id).collect();
    let mut sinks: Vec<(usize, Box<dyn Sink>)> = Vec::with_capacity(stale.len());
    let mut dirs = Vec::with_capacity(stale.len());
    for p in stale {
        let dir = staging.profile_dir(&p.name)?;
        let rate = rates
            .iter()
            .position(|r| r.conversion == p.conversion)
            .unwrap();
        let sink = sink::create(&SinkContext {
            profile: p,
            dir: &dir,
            scratch: &staging.scratch_dir(),
            episode_ends: &rates[rate].ends,
            episode_ids: &ids,
        })?;
        sinks.push((rate, sink));
        dirs.push(dir);
    }
    // Frames are encoded once per rate and encoding, however many sinks share them.
    let jobs: Vec<(Conversion, Vec<FrameEncoding>)> = rates
        .iter()
        .enumerate()
        .map(|(r, rate)| {
            let mut encodings: Vec<FrameEncoding> = sinks
                .iter()
                .filter(|(sr, _)| *sr == r)
                .map(|(_, s)| s.frame_encoding())
                .collect();
            encodings.sort();
            encodings.dedup();
            (rate.conversion, encodings)
        })
        .collect();

    let bar = progress::bar(
        opts.progress,
        manifest.episodes.len() as u64,
        "reading episodes",
    );
    let reading = timings::phase("read episodes");
    let positions: Vec<usize> = (0..manifest.episodes.len()).collect();
    for range in batches(manifest) {
        let batch = &positions[range];
        // Once an episode is excluded this attempt is thrown away: only check the rest.
        let checking_only = !excluded.is_empty();
        let processed: Vec<Option<Processed>> = batch
            .par_iter()
            .map(|&i| {
                let id = manifest.episodes[i].id;
                let train = plan.split.is_train(id);
                reads[i].fetch_add(1, Ordering::Relaxed);
                catch_unwind(AssertUnwindSafe(|| {
                    let ep = source.read_episode(i)?;
                    if panic_on == Some(id) {
                        panic!("CHUNKC_TEST_PANIC_EPISODE={id}");
                    }
                    let place = format!("{source_path}: episode {id}");
                    match source::check::episode(&ep, manifest, non_finite, &place)? {
                        source::check::Verdict::Exclude(reason) => Ok(Err((id, reason))),
                        source::check::Verdict::Keep if checking_only => Ok(Ok(None)),
                        source::check::Verdict::Keep => {
                            Ok(Ok(Some(process(ep, source, &jobs, train))))
                        }
                    }
                }))
                .unwrap_or_else(|panic| {
                    let what = panic
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_default();
                    Err(Error::Internal(format!(
                        "panic while processing episode {id}: {what}"
                    )))
                })
            })
            // Collect every episode's result before looking at any: when several episodes of a
            // batch fail, the error reported is the first in episode order, whatever finished
            // first (rayon's `collect::<Result<_>>` would return whichever failure it met).
            .collect::<Vec<Result<_>>>()
            .into_iter()
            .collect::<Result<Vec<_>>>()?
            .into_iter()
            .map(|r| {
                r.unwrap_or_else(|(id, reason)| {
                    excluded.insert(id, reason);
                    None
                })
            })
            .collect();
        if !excluded.is_empty() {
            bar.inc(batch.len() as u64);
            continue;
        }
        let processed: Vec<Processed> = processed.into_iter().flatten().collect();

        // Low-dim values wait here, per (rate, channel), for one task per store below, each
        // with whether it is a training episode's.
        type Rows = (Vec<f32>, bool);
        let mut pending: Vec<Vec<Vec<Rows>>> = rates
            .iter()
            .map(|r| vec![Vec::new(); r.lowdim.len()])
            .collect();
        for (&i, episode) in batch.iter().zip(processed) {
            for (r, (rate, (data, partials))) in rates
                .iter_mut()
                .zip(episode.data.into_iter().zip(episode.partials))
                .enumerate()
            {
                let row = rate.ends.start(i);
                let train = plan.split.is_train(manifest.episodes[i].id);
                for (c, (values, partial)) in data.into_iter().zip(partials).enumerate() {
                    if let Some(p) = partial {
                        rate.partials[c].merge(&p);
                    }
                    match values {
                        Prepared::Lowdim(v) => pending[r][c].push((v, train)),
                        Prepared::Frames(encoded) => {
                            for (_, sink) in sinks.iter_mut().filter(|(sr, _)| *sr == r) {
                                let enc = sink.frame_encoding();
                                let (_, frames) = encoded
                                    .iter()
                                    .find(|(e, _)| *e == enc)
                                    .expect("frames encoded for every sink");
                                sink.write_frames(c, row, frames)?;
                            }
                        }
                    }
                }
            }
            bar.inc(1);
        }
        // Each store takes its episodes in order; stores are independent, so they fill (and
        // spill) side by side.
        let stores: Vec<&mut Arc<LowdimStore>> =
            rates.iter_mut().flat_map(|r| r.lowdim.iter_mut()).collect();
        let pushed: Vec<Result<()>> = stores
            .into_par_iter()
            .zip(pending.into_iter().flatten().collect::<Vec<_>>())
            .map(|(store, episodes)| {
                let store = Arc::get_mut(store).expect("no reader while the source is read");
                episodes
                    .iter()
                    .try_for_each(|(v, train)| store.push(v, *train))
            })
            .collect();
        pushed.into_iter().collect::<Result<Vec<()>>>()?;
    }
    bar.finish_and_clear();
    drop(reading);
    if !excluded.is_empty() {
        return Ok(Err(excluded));
    }
    // Statistics once per (rate, channel), shared by every profile at that rate; each rate's
    // profiles finish (normalized writes, window index, documents, hashes) as soon as its
    // statistics are known, while other rates still reduce theirs. Profiles' files are
    // independent, and results are gathered in profile order.
    let train_mask: Vec<bool> = ids.iter().map(|&id| plan.split.is_train(id)).collect();
    let shared = finish::Shared {
        spec,
        plan,
        manifest,
        renderer,
    };
    // Per rate: (profile position, its sink, its staging directory).
    type Pending<'d> = Vec<(usize, Box<dyn Sink>, &'d PathBuf)>;
    let mut by_rate: Vec<Pending> = rates.iter().map(|_| Vec::new()).collect();
    for (i, ((r, sink), dir)) in sinks.into_iter().zip(&dirs).enumerate() {
        by_rate[r].push((i, sink, dir));
    }
    type Finished = Vec<(usize, Result<BTreeMap<String, String>>)>;
    let finished: Vec<Finished> = rates
        .par_iter()
        .zip(by_rate)
        .map(|(rate, profiles)| -> Result<Vec<_>> {
            let stats = {
                let _statistics = timings::phase("statistics");
                rate_stats(rate, manifest, &train_mask)?
            };
            Ok(profiles
                .into_par_iter()
                .map(|(i, sink, dir)| {
                    (
                        i,
                        finish::profile(&shared, stale[i], rate, &stats, sink, dir),
                    )
                })
                .collect())
        })
        // The first failing rate in plan order, whatever finished first.
        .collect::<Vec<Result<_>>>()
        .into_iter()
        .collect::<Result<_>>()?;
    let mut finished: Finished = finished.into_iter().flatten().collect();
    finished.sort_by_key(|(i, _)| *i);
    let finished = finished.into_iter().map(|(_, files)| files);
    let mut hashes = BTreeMap::new();
    for (p, files) in stale.iter().zip(finished) {
        hashes.insert(p.name.clone(), files?);
        // `finish::profile` fsynced every file it hashed.
        staging.files_synced(&p.name);
    }
    Ok(Ok(hashes))
}

/// The statistics of every channel at one rate: low-dim percentiles from the store (moments were
/// merged while reading), image statistics from their partials.
fn rate_stats(
    rate: &RateState,
    manifest: &source::Manifest,
    train_mask: &[bool],
) -> Result<BTreeMap<String, ChannelStats>> {
    let mut by_channel = BTreeMap::new();
    for (c, ch) in manifest.channels.iter().enumerate() {
        let s = match (&rate.partials[c], ch.kind) {
            (Partial::Lowdim(m), ChannelKind::Lowdim) => {
                let values = &rate.lowdim[c];
                let ends = &rate.ends;
                let train: Vec<(usize, usize)> = (0..ends.len())
                    .filter(|&e| train_mask[e])
                    .map(|e| {
                        let r = ends.range(e);
                        (r.start, r.end)
                    })
                    .collect();
                // The store counted the first percentile pass as the rows arrived; the second
                // reads the training rows once, for every column.
                stats::lowdim_from_rows(m.clone(), ch.width(), values.high_counts(), |f| {
                    values.for_rows(&train, f)
                })?
            }
            (Partial::Image(p), ChannelKind::Image) => p.clone().finish(),
            _ => unreachable!("a channel's partial has its kind"),
        };
        by_channel.insert(ch.name.clone(), s);
    }
    Ok(by_channel)
}
