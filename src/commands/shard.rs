//! The sharded build: `chunkc build SPEC --shard I/N --partials DIR` on each worker, then
//! `chunkc merge SPEC --partials DIR` once. Engine-agnostic: a Ray task, a Slurm array job or a
//! shell loop runs the same two commands (`scripts/chunkc_ray.py` is the Ray driver).
//!
//! Every shard and the merge plan the same spec over the same source and so compute the same
//! plan and the same assignment ([`plan::shards`]); each partial records the plan's id, and the
//! merge refuses a missing, damaged or stale one before it writes anything. The merge runs the
//! sequential half of the single-machine pass over the partials' records in episode order
//! (statistics merged, rows stored, two-pass exact percentiles over the stored rows, frames
//! written, files finished), so its outputs are the single-machine build's bytes.

use std::path::{Path, PathBuf};

use super::build::{update_lock, BuildOptions, BuildReport};
use crate::error::{Error, Result};
use crate::exec::{self, partial, BuildLock, Input, Outcome, ShardReport, Staging};
use crate::plan::shards::{self, Shard};
use crate::plan::{self, ProfilePlan};
use crate::spec::{self, LoadedSpec};

/// `build --shard I/N --partials DIR`: this shard's episodes processed into its partial.
pub fn build_shard(
    spec: &LoadedSpec,
    shard: Shard,
    partials: &Path,
    opts: &BuildOptions,
) -> Result<ShardReport> {
    let (source, plan) = super::plan(spec)?;
    exec::shard(spec, &plan, source.as_ref(), shard, partials, opts.progress)
}

/// The partial files in `dir` and the shard count they name: every shard `0..N` must be there,
/// of one N.
fn find_partials(dir: &Path) -> Result<(usize, Vec<PathBuf>)> {
    let entries = std::fs::read_dir(dir)
        .map_err(|e| Error::source(format!("--partials {}: cannot read: {e}", dir.display())))?;
    let mut counts = std::collections::BTreeSet::new();
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let count = name
            .strip_prefix("shard-")
            .and_then(|n| n.strip_suffix(".partial"))
            .and_then(|n| n.split_once("-of-"))
            .and_then(|(_, n)| n.parse::<usize>().ok());
        if let Some(n) = count {
            counts.insert(n);
        }
    }
    let count = match counts.len() {
        0 => {
            return Err(Error::source(format!(
                "--partials {}: no shard partials (shard-*-of-*.partial); run `chunkc build SPEC --shard I/N --partials {}` for every I first",
                dir.display(),
                dir.display()
            )))
        }
        1 => *counts.first().expect("one"),
        _ => {
            return Err(Error::source(format!(
                "--partials {}: partials of different shard counts ({}): keep one run's",
                dir.display(),
                counts.iter().map(|n| n.to_string()).collect::<Vec<_>>().join(", ")
            )))
        }
    };
    let paths: Vec<PathBuf> = (0..count)
        .map(|i| partial::path_of(dir, i, count))
        .collect();
    if let Some(i) = paths.iter().position(|p| !p.exists()) {
        return Err(Error::source(format!(
            "shard {i}/{count} is missing: {} does not exist; run `chunkc build SPEC --shard {i}/{count} --partials {}`",
            paths[i].display(),
            dir.display()
        )));
    }
    Ok((count, paths))
}

/// `merge --partials DIR`: every profile built from the shards' partials, committed and locked.
// Long function: the build's sequence (plan, every partial checked, executed from them, commit, lock), each step with its own error.
pub fn merge(spec: &LoadedSpec, partials: &Path, opts: &BuildOptions) -> Result<BuildReport> {
    let started = std::time::Instant::now();
    let out_dir = spec.resolve(&spec.spec.output.dir);
    spec::check_output_location(spec, &out_dir)?;
    let (count, paths) = find_partials(partials)?;
    let mut build_lock = BuildLock::acquire(&out_dir)?;
    Staging::recover(&out_dir)?;
    let (source, mut plan, report) = super::plan::plan_reported(spec)?;
    plan.memory = opts.memory.or(plan.memory);
    let id = shards::plan_id(&plan);
    let lens: Vec<usize> = source.manifest().episodes.iter().map(|e| e.len).collect();
    let assignment = shards::assign(&lens, count);
    // Every partial checked (checksum, tool, plan, episodes) before anything is written.
    for (i, path) in paths.iter().enumerate() {
        let header = partial::verify(path)?;
        let stale = |why: String| {
            Error::source(format!(
                "shard {i}/{count} ({}) is stale: {why}; run `chunkc build SPEC --shard {i}/{count} --partials {}` again",
                path.display(),
                partials.display()
            ))
        };
        if header.format != partial::PARTIAL_FORMAT || header.tool_version != plan::TOOL_VERSION {
            return Err(stale(format!(
                "written by chunkc {} (partial format {}), this is chunkc {}",
                header.tool_version,
                header.format,
                plan::TOOL_VERSION
            )));
        }
        if header.plan != id {
            return Err(stale(
                "its plan differs from this one (the spec, the source or the audit changed since it ran)"
                    .into(),
            ));
        }
        let want = &assignment[i];
        if header.shard != i || header.episodes != [want.start, want.end] {
            return Err(stale(format!(
                "it holds episodes {}..{}, shard {i} is {}..{}",
                header.episodes[0], header.episodes[1], want.start, want.end
            )));
        }
    }
    let every: Vec<&ProfilePlan> = plan.profiles.iter().collect();
    let names: Vec<String> = every.iter().map(|p| p.name.clone()).collect();
    let outcome = exec::execute(
        spec,
        &plan,
        &every,
        source.as_ref(),
        opts.progress,
        &[],
        Input::Partials(&paths),
    )?;
    let hashes = match outcome {
        Outcome::Built(staging, mut hashes) => {
            super::card::write_cards(spec, &plan, &names, &staging, &mut hashes, &report)?;
            build_lock.keep();
            staging.commit(&names)?;
            hashes
        }
        Outcome::Exclude(excluded) => {
            let shown: Vec<String> = excluded
                .iter()
                .map(|(id, why)| format!("episode {id}: {why}"))
                .collect();
            return Err(Error::source(format!(
                "the shards left out episodes under `[audit] non_finite = \"exclude_episode\"` ({}); a sharded build cannot plan again without them: list the others in `[source] episodes`, or build on one machine",
                shown.join("; ")
            )));
        }
    };
    update_lock(spec, &plan, &hashes)?;
    let video_notes = super::build::video_notes(&out_dir, &plan, &names)?;
    Ok(BuildReport {
        out_dir,
        built: names,
        up_to_date: Vec::new(),
        episode_reads: Vec::new(),
        block_decodes: Default::default(),
        doctor_seconds: plan.audit.doctor_seconds,
        doctor_warnings: Vec::new(),
        video_notes,
        seconds: started.elapsed().as_secs_f64(),
    })
}
