//! `chunkc build`: every stale profile built from one pass over the source, the staging
//! directory renamed into place, `chunkc.lock` updated.
//!
//! The dataset doctor rides on the same pass: each episode is reduced to its doctor features
//! from the values read (beside the writes, from the row store of the rate that keeps the
//! source's steps, or else as it is read), and the features are judged before anything is
//! committed (an `= "error"` finding fails the build with nothing kept).
//!
//! When `[audit] non_finite = "exclude_episode"` or a doctor check `= "exclude"` finds episodes
//! to leave out, which ones depends only on the data, so the output stays deterministic: the
//! build plans again without them and builds from that plan (reading the kept episodes a second
//! time; the doctor judges in whichever pass reads every kept episode first).

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::AtomicUsize;

use crate::audit::doctor::Probe;
use crate::audit::sources_doctor::SourcesDoctor;
use crate::audit::AuditReport;
use crate::error::{Error, Result};
use crate::exec::{self, BuildLock, Excluded, FileHashes, Outcome, Staging};
use crate::lock::{self, Lock, LockedProfile, SpecLock, LOCK_VERSION};
use crate::plan::{self, Plan, ProfilePlan};
use crate::source::{self, Source};
use crate::spec::{self, LoadedSpec};
use crate::timings;

#[derive(Debug, Clone, Default)]
pub struct BuildOptions {
    /// Fail instead of building when anything is out of date (`--locked`).
    pub locked: bool,
    /// Show progress bars (they are hidden anyway when stderr is not a terminal).
    pub progress: bool,
    /// The memory the build may keep values in, in bytes (`--memory`; over `[build] memory`).
    pub memory: Option<u64>,
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
    pub block_decodes: source::DecodeCounts,
    /// Wall seconds of the dataset doctor (on by default), when it ran: `build` says what it cost.
    pub doctor_seconds: Option<f64>,
    /// The doctor's dataset-wide warnings (flag counts, constant, stuck, shift, lag), when it
    /// ran: `build` prints them; `chunkc audit` writes which episodes and why.
    pub doctor_warnings: Vec<String>,
    /// Per built profile with video storage, per camera: episodes copied, and why copies were
    /// refused.
    pub video_notes: Vec<String>,
    /// Wall seconds of the whole command.
    pub seconds: f64,
}

/// A build that committed: the plan it followed, the profiles it built and their files' hashes.
struct Committed {
    plan: Plan,
    built: Vec<String>,
    hashes: FileHashes,
    block_decodes: source::DecodeCounts,
}

// Long function: the plan, the one pass with its doctor, the rebuild and the commit share the lock.
pub fn build(spec: &LoadedSpec, opts: &BuildOptions) -> Result<BuildReport> {
    let whole = timings::phase("whole build");
    let started = std::time::Instant::now();
    let out_dir = spec.resolve(&spec.spec.output.dir);
    // Never create anything (not even the lock) inside a source.
    spec::check_output_location(spec, &out_dir)?;
    let mut build_lock = BuildLock::acquire(&out_dir)?;
    // Repair what an interrupted build left, before the plan compares outputs with the lock.
    Staging::recover(&out_dir)?;
    let (source, mut plan, report, riding) = super::plan::plan_audited(spec, false)?;
    plan.memory = opts.memory.or(plan.memory);
    let (stale, up_to_date): (Vec<&ProfilePlan>, Vec<&ProfilePlan>) = plan
        .profiles
        .iter()
        .partition(|p| !p.status.is_up_to_date());
    let up_to_date: Vec<String> = up_to_date.iter().map(|p| p.name.clone()).collect();
    if stale.is_empty() {
        return Ok(BuildReport {
            out_dir,
            built: Vec::new(),
            up_to_date,
            episode_reads: Vec::new(),
            block_decodes: Default::default(),
            doctor_seconds: None,
            doctor_warnings: Vec::new(),
            video_notes: Vec::new(),
            seconds: started.elapsed().as_secs_f64(),
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
    let names: Vec<String> = stale.iter().map(|p| p.name.clone()).collect();
    // A mixture's sources each have their own doctor, fed by the mixture as it is read.
    let probe = match spec.is_mixture() {
        true => None,
        false => Probe::of(spec, source.manifest()),
    };
    let judging = match (&probe, &riding) {
        (Some(p), _) => Some(Judging::Probe(p)),
        (None, Some(d)) => Some(Judging::Sources(d)),
        (None, None) => None,
    };
    let mut judged = report.clone();
    let mut doctor = judging.map(|j| doctor_for(spec, j, source.manifest(), &mut judged));
    let outcome = exec::execute(
        spec,
        &plan,
        &stale,
        source.as_ref(),
        opts.progress,
        &reads,
        exec::Input::Source(doctor.as_mut()),
    )?;
    let mut doctor_seconds = doctor.as_ref().and_then(exec::Doctor::seconds);
    drop(doctor);
    let committed = match outcome {
        Outcome::Built(staging, mut hashes) => {
            let block_decodes = source.decode_counts();
            super::card::write_cards(spec, &plan, &names, &staging, &mut hashes, &judged)?;
            build_lock.keep();
            let _commit = timings::phase("commit (fsync)");
            staging.commit(&names)?;
            Committed {
                plan,
                built: names,
                hashes,
                block_decodes,
            }
        }
        Outcome::Exclude(excluded) => {
            // The doctor has not judged when the pass stopped at a non-finite value.
            let pending = judging.filter(|_| doctor_seconds.is_none());
            let again = (spec, &plan, names, opts);
            let (committed, seconds) = rebuild_without(
                again,
                source,
                excluded,
                &mut build_lock,
                (pending, &mut judged),
            )?;
            doctor_seconds = doctor_seconds.or(seconds);
            committed
        }
    };
    update_lock(spec, &committed.plan, &committed.hashes)?;
    drop(whole);
    timings::report();
    let video_notes = video_notes(&out_dir, &committed.plan, &committed.built)?;
    Ok(BuildReport {
        out_dir,
        built: committed.built,
        up_to_date,
        episode_reads: reads.into_iter().map(AtomicUsize::into_inner).collect(),
        block_decodes: committed.block_decodes,
        doctor_seconds,
        doctor_warnings: doctor_warnings(&report, &judged, doctor_seconds.is_some()),
        video_notes,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// What the built profiles' video storage did: copied or encoded, and why.
pub(super) fn video_notes(
    out_dir: &std::path::Path,
    plan: &Plan,
    built: &[String],
) -> Result<Vec<String>> {
    let mut notes = Vec::new();
    for p in plan.profiles.iter().filter(|p| built.contains(&p.name)) {
        if p.values.format != crate::spec::OutputFormat::Hdf5
            || p.values.image_compression != crate::spec::ImageCompression::Video
        {
            continue;
        }
        let data = out_dir.join(&p.name).join(p.values.format.files().data);
        for r in crate::sink::hdf5_video::copy_records(&data)? {
            let mut line = format!(
                "{}: videos `{}`: {} of {} episodes copied from the source's stream",
                p.name, r.camera, r.copied, r.episodes
            );
            if let Some(why) = r.refused {
                line.push_str(&format!("; encoded where the copy was refused: {why}"));
            }
            notes.push(line);
        }
    }
    Ok(notes)
}

/// The warnings the doctor added to the timing audit's.
fn doctor_warnings(timing: &AuditReport, judged: &AuditReport, ran: bool) -> Vec<String> {
    if !ran {
        return Vec::new();
    }
    judged
        .warnings
        .iter()
        .filter(|w| !timing.warnings.contains(w))
        .cloned()
        .collect()
}

/// Who judges a build's episodes: the source's doctor, or a mixture's sources' doctors.
#[derive(Clone, Copy)]
enum Judging<'a> {
    Probe(&'a Probe),
    Sources(&'a SourcesDoctor),
}

/// The dataset doctor of a pass over the episodes of `manifest`, judging into `report`.
fn doctor_for<'a>(
    spec: &'a LoadedSpec,
    judging: Judging<'a>,
    manifest: &source::Manifest,
    report: &'a mut AuditReport,
) -> exec::Doctor<'a> {
    let ids: Vec<u64> = manifest.episodes.iter().map(|e| e.id).collect();
    let fps = manifest.fps;
    match judging {
        Judging::Probe(probe) => exec::Doctor::new(
            probe,
            ids.len(),
            Box::new(move |feats| {
                let excluded = probe.judge(spec, fps, &ids, feats, report)?;
                Ok(excluded.into_iter().collect())
            }),
        ),
        Judging::Sources(sources) => exec::Doctor::reading_elsewhere(
            sources,
            Box::new(move |_| {
                let (joined, excluded) = sources.judge(&ids)?;
                *report = joined;
                Ok(excluded.into_iter().collect())
            }),
        ),
    }
}

/// Plans again without the `excluded` episodes and builds the profiles `names` from that plan
/// (see the module docs); commits the result, with the cards of `judged`. `doctor`: the doctor
/// still to judge (the first pass stopped at a non-finite value), in this pass, into `judged`;
/// its exclusions make one more. Returns the doctor's seconds when it ran here.
fn rebuild_without(
    (spec, plan, names, opts): (&LoadedSpec, &Plan, Vec<String>, &BuildOptions),
    source: Box<dyn Source>,
    excluded: Excluded,
    build_lock: &mut BuildLock,
    (mut doctor, judged): (Option<Judging>, &mut AuditReport),
) -> Result<(Committed, Option<f64>)> {
    let mut kept = source;
    let mut before = plan.clone();
    let mut excluded = excluded;
    let mut seconds = None;
    loop {
        let ids: Vec<u64> = excluded.keys().copied().collect();
        kept = Box::new(source::Subset::without(kept, &ids));
        let replan = replan(spec, &before, kept.as_ref(), &excluded)?;
        let restale: Vec<&ProfilePlan> = replan
            .profiles
            .iter()
            .filter(|p| names.contains(&p.name))
            .collect();
        let again: Vec<AtomicUsize> = (0..replan.source.episodes)
            .map(|_| AtomicUsize::new(0))
            .collect();
        let judging = doctor.take();
        let mut pass_doctor = judging.map(|p| doctor_for(spec, p, kept.manifest(), &mut *judged));
        let outcome = exec::execute(
            spec,
            &replan,
            &restale,
            kept.as_ref(),
            opts.progress,
            &again,
            exec::Input::Source(pass_doctor.as_mut()),
        )?;
        let judged_here = pass_doctor.as_ref().and_then(exec::Doctor::seconds);
        drop(pass_doctor);
        seconds = seconds.or(judged_here);
        match outcome {
            Outcome::Built(staging, mut hashes) => {
                let block_decodes = kept.decode_counts();
                super::card::write_cards(spec, &replan, &names, &staging, &mut hashes, judged)?;
                build_lock.keep();
                staging.commit(&names)?;
                let committed = Committed {
                    plan: replan,
                    built: names,
                    hashes,
                    block_decodes,
                };
                return Ok((committed, seconds));
            }
            // The doctor, judging in this pass, left more out: once more without them.
            Outcome::Exclude(more) if judged_here.is_some() => {
                excluded = more;
                before = replan;
            }
            Outcome::Exclude(more) => {
                return Err(Error::Internal(format!(
                    "episodes {:?} passed the audit once and failed it the second time",
                    more.keys().collect::<Vec<_>>()
                )))
            }
        }
    }
}

/// The plan of `kept` (the source less the excluded episodes), carrying over the first plan's
/// audit, exclusions and repairs, with the new exclusions added.
fn replan(spec: &LoadedSpec, plan: &Plan, kept: &dyn Source, excluded: &Excluded) -> Result<Plan> {
    let out_dir = spec.resolve(&spec.spec.output.dir);
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
    Ok(replan)
}

/// Records the build in `chunkc.lock`: re-read, so that only this spec's entry changes whatever
/// else it holds; profiles not built keep their previous entries.
pub(super) fn update_lock(spec: &LoadedSpec, plan: &Plan, hashes: &FileHashes) -> Result<()> {
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
                fingerprint: p.fingerprint.get()?,
                files: files.clone(),
                inputs: p.inputs.clone(),
                encoder: crate::sink::encoder_record::of(p),
            },
            None => previous.profiles.get(&p.name).cloned().unwrap_or_default(),
        };
        profiles.insert(p.name.clone(), entry);
    }
    let source = plan.source.fingerprint.get()?;
    all.specs.insert(
        key,
        SpecLock {
            tool_version: plan::TOOL_VERSION.to_string(),
            spec_hash: plan.spec_hash.clone(),
            source_fingerprint: source.hash.clone(),
            source_files: source.files.clone(),
            profiles,
        },
    );
    all.write(&lock_path)
}
