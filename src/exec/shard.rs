//! `chunkc build --shard I/N --partials DIR`: the parallel part of the pass for one shard's
//! episodes (read, check, convert to every rate, encode frames for every sink, statistics
//! partials), written as a partial ([`super::partial`]) instead of consumed. Every profile of the
//! plan is built (a shard cannot know which outputs the merge machine holds).
//!
//! The sinks are created in a scratch directory beside the partials only to ask each one how it
//! wants its frames encoded; nothing is ever written to the output directory, so shards may run
//! at the same time on many machines that share the partials directory. A shard run twice (a
//! retried task) writes the same bytes: the records are its episodes in order, and each record
//! depends only on its episode.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicUsize;

use super::partial::{self, Header, Record, Writer, PARTIAL_FORMAT};
use super::process::Prepared;
use super::{progress, read, set_up, Staging};
use crate::error::{IoContext, Result};
use crate::plan::shards::{self, Shard};
use crate::plan::{Plan, ProfilePlan, TOOL_VERSION};
use crate::recycle;
use crate::sink::{FrameEncoding, Sink};
use crate::source::Source;
use crate::spec::LoadedSpec;

/// What a shard did.
#[derive(Debug, Clone)]
pub struct ShardReport {
    pub shard: Shard,
    /// Episode positions (audited manifest order) it read.
    pub episodes: std::ops::Range<usize>,
    /// Episodes `[audit] non_finite = "exclude_episode"` left out (the merge then refuses: the
    /// plan changes).
    pub excluded: Vec<(u64, String)>,
    pub partial: PathBuf,
    pub bytes: u64,
}

/// Runs shard `shard` of `plan` over `source` and writes its partial into `dir`.
pub fn shard(
    spec: &LoadedSpec,
    plan: &Plan,
    source: &dyn Source,
    shard: Shard,
    dir: &Path,
    show_progress: bool,
) -> Result<ShardReport> {
    let manifest = source.manifest();
    let lens: Vec<usize> = manifest.episodes.iter().map(|e| e.len).collect();
    let range = shards::assign(&lens, shard.count)[shard.index].clone();
    std::fs::create_dir_all(dir).at("create partials directory", dir)?;
    // A scratch directory of this shard's own: a retried task finds and replaces its own.
    let work = dir.join(format!(".work-{:05}-of-{:05}", shard.index, shard.count));
    if work.exists() {
        std::fs::remove_dir_all(&work).at("remove", &work)?;
    }
    std::fs::create_dir_all(&work).at("create", &work)?;
    let staging = Staging::new(&work)?;
    let every: Vec<&ProfilePlan> = plan.profiles.iter().collect();
    let setup = set_up(plan, &every, manifest, &staging)?;
    let reads: Vec<AtomicUsize> = (0..manifest.episodes.len())
        .map(|_| AtomicUsize::new(0))
        .collect();
    let paths = spec.source_paths().join(", ");
    let pass = read::Pass {
        plan,
        source,
        non_finite: spec.spec.audit.non_finite,
        source_path: &paths,
        jobs: &setup.jobs,
        reads: &reads,
        progress: show_progress,
        doctor: None,
    };
    let path = partial::path_of(dir, shard.index, shard.count);
    let header = Header {
        format: PARTIAL_FORMAT,
        tool_version: TOOL_VERSION.to_string(),
        plan: shards::plan_id(plan),
        shard: shard.index,
        shards: shard.count,
        episodes: [range.start, range.end],
    };
    let mut writer = Writer::create(&path, &header)?;
    let bar = progress::bar(show_progress, range.len() as u64, "reading episodes");
    let mut excluded = Vec::new();
    for batch in read::batches(manifest, range.clone()) {
        let records = read::read_batch(&pass, batch.clone(), !excluded.is_empty())?;
        for (i, mut record) in batch.zip(records) {
            leave_copied_pixels(&mut record, &setup.sinks)?;
            if let Record::Excluded(reason) = &record {
                excluded.push((manifest.episodes[i].id, reason.clone()));
            }
            writer.record(&record)?;
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    writer.finish()?;
    drop(setup);
    drop(staging);
    std::fs::remove_dir_all(&work).at("remove", &work)?;
    let bytes = std::fs::metadata(&path).at("read", &path)?.len();
    Ok(ShardReport {
        shard,
        episodes: range,
        excluded,
        partial: path,
        bytes,
    })
}

/// Leaves behind the pixels of a record's uncompressed frames that every sink taking them will
/// copy from their video packets: the partial then holds where the packets are, which the merge
/// copies from, instead of the decoded frames (hundreds of times the video's size).
fn leave_copied_pixels(record: &mut Record, sinks: &[(usize, Box<dyn Sink>)]) -> Result<()> {
    let Record::Kept(processed) = record else {
        return Ok(());
    };
    for (r, channels) in processed.data.iter_mut().enumerate() {
        let raw: Vec<&dyn Sink> = (sinks.iter())
            .filter(|(sr, s)| *sr == r && s.frame_encoding() == FrameEncoding::Raw)
            .map(|(_, s)| s.as_ref())
            .collect();
        if raw.is_empty() {
            continue;
        }
        for (c, prepared) in channels.iter_mut().enumerate() {
            let Prepared::Frames(encoded) = prepared else {
                continue;
            };
            for (enc, frames) in encoded.iter_mut() {
                if *enc != FrameEncoding::Raw || frames.packets().is_none() {
                    continue;
                }
                if raw.iter().try_fold(true, |all, s| {
                    Ok::<bool, crate::error::Error>(all && s.copies_frames(c, frames)?)
                })? {
                    let (stripped, pixels) = std::mem::take(frames).without_pixels();
                    *frames = stripped;
                    if let Some(pixels) = pixels {
                        recycle::give(pixels);
                    }
                }
            }
        }
    }
    Ok(())
}
