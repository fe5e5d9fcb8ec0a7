//! Stage 5, execute: one pass over the source, then every stale profile's files, in a staging
//! directory.
//!
//! The source is read once ([`read`]), in batches of episodes decoded in parallel (rayon) and
//! consumed in episode order, so memory stays bounded by the batch and every write and every
//! statistics merge happens in the same order whatever the thread count. Low-dim values wait in
//! the row store ([`crate::store`]) until the statistics are known; then each rate's profiles
//! finish side by side ([`finish`]). A panic inside an episode job becomes an error naming the
//! episode ([`guard`]). The command drivers ([`crate::commands`]) decide what is stale, commit
//! the staging directory and update the lock.
//!
//! - `memory`: how much memory the row stores may keep values in, and which stores do.
//! - `rate`: what is kept per output rate while reading.
//! - `rate_stats`: the statistics of every channel at a rate (a training mixture's per source,
//!   and pooled over the union).
//! - `process`: an episode converted to every rate and encoded for every sink (parallel).
//! - `read`: the batched pass over the source.
//! - `guard`: the panic-to-error wrapper of a per-episode job.
//! - `finish`: a profile's last writes once the statistics are known.
//! - `shared`: what every profile shares as it finishes, and a profile's statistics.
//! - `window_stats`: a profile's own statistics (its transforms, windows), per source too.
//! - `source_normalizers`: a training mixture's normalizers, per source.
//! - `source_files`: a training mixture's statistics files per source.
//! - `partial`: a shard's processed episodes on disk, and reading them back for the merge.
//! - `shard`: one shard's part of the pass (`build --shard I/N`), written as a partial.
//! - `staging`: the staging directory, the build lock and the final renames.
//! - `progress`: progress bars (hidden when stderr is not a terminal).

mod doctor;
mod finish;
mod guard;
mod hash_outputs;
pub mod memory;
pub mod partial;
mod process;
mod progress;
mod rate;
mod rate_stats;
mod read;
mod shard;
mod shared;
mod source_files;
mod source_normalizers;
pub mod staging;
mod window_stats;

use std::collections::BTreeMap;
use std::sync::atomic::AtomicUsize;

use crate::error::Result;
use crate::plan::{Conversion, Plan, ProfilePlan, RateJob};
use crate::render;
use crate::resize::Resize;
use crate::sink::{self, FrameEncoding, Sink, SinkContext};
use crate::source::Source;
use crate::spec::LoadedSpec;

pub use crate::files::{BUILD_LOCK_FILE, STAGING_DIR};
pub use doctor::{Doctor, Judge};
pub use shard::{shard, ShardReport};
pub use staging::{BuildLock, Staging};

/// BLAKE3 of every output file, by profile, then path.
pub type FileHashes = BTreeMap<String, BTreeMap<String, String>>;
/// Episodes to leave out: id → reason.
pub type Excluded = BTreeMap<u64, String>;

/// How one attempt at building the stale profiles ended (errors aside).
pub enum Outcome {
    /// Every stale profile's files are in the staging directory, fsynced and hashed.
    Built(Staging, FileHashes),
    /// `[audit] non_finite = "exclude_episode"`, or the dataset doctor (a check `= "exclude"`),
    /// found episodes to leave out; nothing was kept of this attempt.
    Exclude(Excluded),
}

/// Where a build's episodes come from.
pub enum Input<'a, 'd> {
    /// Read from the source; the dataset doctor, when given, computes its features from the
    /// values read (as they are read, or from the stored rows beside the writes) and judges
    /// them before anything is committed.
    Source(Option<&'a mut Doctor<'d>>),
    /// Processed already, by the shards whose partials these are (in shard order, verified:
    /// see [`partial::verify`]), for `chunkc merge`.
    Partials(&'a [std::path::PathBuf]),
}

/// What a pass sets up before it reads: the state of each rate, the sinks (rate position,
/// sink) and their directories, and per rate how episodes are converted and frames encoded.
struct Setup {
    rates: Vec<rate::RateState>,
    sinks: Vec<(usize, Box<dyn Sink>)>,
    dirs: Vec<std::path::PathBuf>,
    jobs: Vec<process::Job>,
}

fn set_up(
    plan: &Plan,
    stale: &[&ProfilePlan],
    manifest: &crate::source::Manifest,
    staging: &Staging,
) -> Result<Setup> {
    // In plan order (fastest first), once each.
    let used: Vec<&RateJob> = plan
        .rates
        .iter()
        .filter(|r| stale.iter().any(|p| p.uses(r)))
        .collect();
    let budget = memory::budget(plan.memory);
    let values: Vec<Vec<usize>> = (used.iter())
        .map(|job| rate::store_values(job.conversion, manifest))
        .collect();
    let budgets = memory::share(budget, &values);
    let rates: Vec<rate::RateState> = (used.iter().zip(&budgets).enumerate())
        .map(|(r, (job, b))| rate::RateState::new(r, job.conversion, manifest, staging, b))
        .collect();
    let ids: Vec<u64> = manifest.episodes.iter().map(|e| e.id).collect();
    let sources: Vec<usize> = match manifest.parts.is_empty() {
        true => Vec::new(),
        false => ids.iter().map(|&id| manifest.source_of(id)).collect(),
    };
    let mut sinks: Vec<(usize, Box<dyn Sink>)> = Vec::with_capacity(stale.len());
    let mut dirs = Vec::with_capacity(stale.len());
    for p in stale {
        let dir = staging.profile_dir(&p.name)?;
        let rate = used.iter().position(|job| p.uses(job));
        let rate = rate.expect("every stale profile's rate is built");
        let sink = sink::create(&SinkContext {
            profile: p,
            dir: &dir,
            scratch: &staging.scratch_dir(),
            episode_ends: &rates[rate].ends,
            episode_ids: &ids,
            episode_sources: &sources,
            source_parts: &manifest.parts,
            tasks: &manifest.tasks,
            spill_budget: budget,
        })?;
        sinks.push((rate, sink));
        dirs.push(dir);
    }
    let jobs = jobs(&used, manifest, &sinks);
    Ok(Setup {
        rates,
        sinks,
        dirs,
        jobs,
    })
}

/// Builds the `stale` profiles of `plan` from `input` (the source, or shards' partials) into a
/// new staging directory under the output directory. `reads` counts each episode's reads;
/// `progress` shows progress bars.
pub fn execute(
    spec: &LoadedSpec,
    plan: &Plan,
    stale: &[&ProfilePlan],
    source: &dyn Source,
    progress: bool,
    reads: &[AtomicUsize],
    input: Input,
) -> Result<Outcome> {
    let manifest = source.manifest();
    let staging = Staging::new(&spec.resolve(&spec.spec.output.dir))?;
    let overrides = spec
        .spec
        .output
        .templates
        .as_deref()
        .map(|t| spec.resolve(t));
    let renderer = render::Renderer::new(overrides.as_deref())?;
    let Setup {
        mut rates,
        mut sinks,
        dirs,
        jobs,
    } = set_up(plan, stale, manifest, &staging)?;
    let (mut feed, mut doctor) = match input {
        Input::Source(doctor) => (read::Feed::Source, doctor),
        Input::Partials(paths) => (
            read::Feed::Partials(
                paths
                    .iter()
                    .map(|p| partial::Reader::open(p))
                    .collect::<Result<_>>()?,
            ),
            None,
        ),
    };
    // The rate whose store holds the source's own steps: the doctor reads it beside the writes.
    let stored = doctor.as_ref().filter(|d| d.takes_stored()).and_then(|_| {
        jobs.iter()
            .position(|j| j.conversion == Conversion::Decimate { factor: 1 })
    });
    if let Some(doctor) = &doctor {
        doctor.will_take_stored(stored.is_some());
    }
    let paths = spec.source_paths().join(", ");
    let pass = read::Pass {
        plan,
        source,
        non_finite: spec.spec.audit.non_finite,
        source_path: &paths,
        jobs: &jobs,
        reads,
        progress,
        doctor: doctor.as_deref().filter(|_| stored.is_none()),
    };
    let excluded = read::read_all(&pass, &mut rates, &mut sinks, &mut feed)?;
    if !excluded.is_empty() {
        return Ok(Outcome::Exclude(excluded));
    }
    if stored.is_none() {
        if let Some(excluded) = judge(doctor.as_deref_mut())? {
            return Ok(Outcome::Exclude(excluded));
        }
    }
    let shared = shared::Shared {
        plan,
        manifest,
        renderer: &renderer,
    };
    let profiles = sinks.into_iter().zip(dirs).map(|((r, s), d)| (r, s, d));
    let finish = || finish::all(&shared, stale, &rates, profiles.collect(), &staging);
    let hashes = match finish_beside(finish, doctor, stored.map(|r| &rates[r]))? {
        Ok(hashes) => hashes,
        Err(excluded) => return Ok(Outcome::Exclude(excluded)),
    };
    Ok(Outcome::Built(staging, hashes))
}

/// Finishes the profiles (`finish`). With a doctor and `stored` (the rate that keeps the
/// source's steps), the doctor reduces every episode from that rate's rows beside the writes,
/// then judges, while the last writes and their hashing go on: the episodes it leaves out, if
/// any, in place of the hashes.
fn finish_beside(
    finish: impl FnOnce() -> Result<FileHashes> + Send,
    doctor: Option<&mut Doctor>,
    stored: Option<&rate::RateState>,
) -> Result<std::result::Result<FileHashes, Excluded>> {
    let (Some(doctor), Some(rate)) = (doctor, stored) else {
        return finish().map(Ok);
    };
    let (hashes, judged) = rayon::join(finish, || {
        {
            let _features = crate::timings::phase("dataset doctor (beside the writes)");
            doctor.take_stored(rate)?;
        }
        judge(Some(doctor))
    });
    let hashes = hashes?;
    Ok(match judged? {
        Some(excluded) => Err(excluded),
        None => Ok(hashes),
    })
}

/// The doctor's judgement, when there is a doctor: the episodes it leaves out, if any.
fn judge(doctor: Option<&mut Doctor>) -> Result<Option<Excluded>> {
    let Some(doctor) = doctor else {
        return Ok(None);
    };
    let _judging = crate::timings::phase("dataset doctor (judgement)");
    let excluded = doctor.judge()?;
    Ok((!excluded.is_empty()).then_some(excluded))
}

/// Per rate: its conversion, the resize of each camera it stores resized, and the frame
/// encodings its sinks use, each once (frames are encoded once per rate and encoding, however
/// many sinks share them).
fn jobs(
    used: &[&RateJob],
    manifest: &crate::source::Manifest,
    sinks: &[(usize, Box<dyn Sink>)],
) -> Vec<process::Job> {
    used.iter()
        .enumerate()
        .map(|(r, job)| {
            let mut encodings: Vec<FrameEncoding> = sinks
                .iter()
                .filter(|(sr, _)| *sr == r)
                .map(|(_, s)| s.frame_encoding())
                .collect();
            encodings.sort();
            encodings.dedup();
            let resize = manifest
                .channels
                .iter()
                .map(|ch| {
                    let &[h, w, colors] = ch.shape.as_slice() else {
                        return None;
                    };
                    let size = job.cameras.get(&ch.name)?;
                    Some(Resize::cover([h, w], *size, colors)).filter(|r| !r.is_identity())
                })
                .collect();
            process::Job {
                conversion: job.conversion,
                encodings,
                resize,
            }
        })
        .collect()
}
