//! The one pass over the source: episodes decoded in batches, in parallel (rayon), consumed in
//! episode order, so memory stays bounded by two low-dim batches (one consumed while the next is
//! read) or one of camera frames, and every write and every statistics merge happens in the same order whatever the thread
//! count.

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use rayon::prelude::*;

use super::guard::episode_job;
use super::partial::{self, Record as Read};
use super::process::{process, Job, Prepared, Processed};
use super::rate::RateState;
use super::{progress, Excluded};
use crate::error::Result;
use crate::plan::Plan;
use crate::recycle;
use crate::sink::{FrameEncoding, Sink};
use crate::source::{self, ChannelKind, Manifest, Source};
use crate::spec::NonFinite;
use crate::stats::HighCounts;
use crate::store::LowdimStore;
use crate::timings;

/// Bytes of decoded values a batch of episodes may hold, beyond its minimum size.
const BATCH_BYTES: usize = 8 << 20;

/// What the pass reads and how.
pub(super) struct Pass<'a> {
    pub plan: &'a Plan,
    pub source: &'a dyn Source,
    /// `[audit] non_finite`: what a NaN or infinity in an episode does.
    pub non_finite: NonFinite,
    /// The source as the spec names it, for messages.
    pub source_path: &'a str,
    /// Per rate (in `RateState` order): its conversion, resizes and frame encodings.
    pub jobs: &'a [Job],
    /// How many times each episode was read (the tests check "once").
    pub reads: &'a [AtomicUsize],
    pub progress: bool,
    /// The dataset doctor's features, computed from each episode read (see [`super::doctor`]).
    pub doctor: Option<&'a super::doctor::Doctor<'a>>,
}

/// Where the pass takes its episodes from.
pub(super) enum Feed {
    /// The source: each episode read, checked and processed here.
    Source,
    /// Shards' partials (in shard order), processed already (`chunkc merge`).
    Partials(Vec<partial::Reader>),
}

/// Low-dim rows waiting for their store, with whether they are a training episode's.
/// An episode's rows for one store.
struct Rows {
    values: Vec<f32>,
    train: bool,
    /// Its source (0 for one source), and how many rows `values` holds (a mixture source's
    /// at its own width, unpadded).
    source: usize,
    rows: usize,
}

/// Reads every episode once into `rates` and `sinks` (rate position, sink). Returns the
/// episodes `[audit] non_finite = "exclude_episode"` leaves out: when there are any, nothing
/// this pass wrote is to be kept.
pub(super) fn read_all(
    pass: &Pass,
    rates: &mut [RateState],
    sinks: &mut [(usize, Box<dyn Sink>)],
    feed: &mut Feed,
) -> Result<Excluded> {
    let manifest = pass.source.manifest();
    let mut excluded = Excluded::new();
    let bar = progress::bar(
        pass.progress,
        manifest.episodes.len() as u64,
        "reading episodes",
    );
    let _reading = timings::phase("read episodes");
    // Low-dim batch k is consumed (in order, on one thread) while batch k + 1 is read and
    // processed on the others, so no core waits on the sequential part. Camera episodes are
    // hundreds of megabytes each: their batches take turns, so memory holds one.
    let overlap = manifest
        .channels
        .iter()
        .all(|c| c.kind == ChannelKind::Lowdim);
    let mut ready: Option<(Range<usize>, Vec<Processed>)> = None;
    for batch in batches(manifest, 0..manifest.episodes.len()) {
        let checking_only = !excluded.is_empty();
        let next = |feed: &mut Feed| match feed {
            Feed::Source => read_batch(pass, batch.clone(), checking_only),
            Feed::Partials(readers) => from_partials(readers, batch.clone()),
        };
        let read = match ready.take() {
            Some((previous, kept)) if !overlap => {
                consume(pass, previous, kept, rates, sinks, &bar)?;
                next(feed)?
            }
            Some((previous, kept)) => {
                let (consumed, read) = rayon::join(
                    || consume(pass, previous, kept, rates, sinks, &bar),
                    || next(feed),
                );
                consumed?;
                read?
            }
            None => next(feed)?,
        };
        let mut kept = Vec::with_capacity(read.len());
        for (i, r) in batch.clone().zip(read) {
            match r {
                Read::Kept(p) => kept.push(p),
                Read::Checked => {}
                Read::Excluded(reason) => {
                    excluded.insert(manifest.episodes[i].id, reason);
                }
            }
        }
        if !excluded.is_empty() {
            bar.inc(batch.len() as u64);
            continue;
        }
        ready = Some((batch, kept));
    }
    if let Some((last, kept)) = ready {
        consume(pass, last, kept, rates, sinks, &bar)?;
    }
    bar.finish_and_clear();
    recycle::clear();
    Ok(excluded)
}

/// The records of the episodes `batch` from the partials that hold them.
fn from_partials(readers: &mut [partial::Reader], batch: Range<usize>) -> Result<Vec<Read>> {
    batch
        .map(|i| {
            let reader = readers
                .iter_mut()
                .find(|r| r.episodes().contains(&i))
                .ok_or_else(|| {
                    crate::error::Error::Internal(format!("no partial holds episode {i}"))
                })?;
            reader.record()
        })
        .collect()
}

/// The episodes `range` in batches decoded at once, in order: at least two per thread (to keep
/// every thread busy), and more while their decoded values stay under [`BATCH_BYTES`] (short
/// low-dim episodes: fewer pauses between batches). Episodes with camera frames (hundreds of
/// megabytes each) come one per thread. Memory stays bounded by the batch.
pub(super) fn batches(manifest: &Manifest, range: Range<usize>) -> Vec<Range<usize>> {
    let cameras = manifest
        .channels
        .iter()
        .any(|c| c.kind == ChannelKind::Image);
    let min = if cameras { 1 } else { 2 } * rayon::current_num_threads();
    let step_bytes: usize = manifest
        .channels
        .iter()
        .map(|c| match c.kind {
            ChannelKind::Lowdim => 4 * c.width(),
            ChannelKind::Image => c.width(),
        })
        .sum();
    let mut out = Vec::new();
    let (mut start, mut bytes) = (range.start, 0);
    for i in range.clone() {
        bytes += manifest.episodes[i].len * step_bytes;
        if i + 1 - start >= min && bytes >= BATCH_BYTES {
            out.push(start..i + 1);
            (start, bytes) = (i + 1, 0);
        }
    }
    if start < range.end {
        out.push(start..range.end);
    }
    out
}

/// The parallel part of a batch: read, check and (unless `checking_only`) process each episode.
pub(super) fn read_batch(
    pass: &Pass,
    batch: Range<usize>,
    checking_only: bool,
) -> Result<Vec<Read>> {
    let manifest = pass.source.manifest();
    // Test hook: the tests prove that a panicking episode job becomes an error naming it.
    let panic_on: Option<u64> = std::env::var("CHUNKC_TEST_PANIC_EPISODE")
        .ok()
        .and_then(|v| v.parse().ok());
    let positions: Vec<usize> = batch.collect();
    // Storage chunks the batch's episodes share are decoded side by side first.
    pass.source.prefetch(&positions);
    // When several episodes of a batch fail, the error reported is the first in episode order.
    crate::error::in_order(positions.par_iter().map(|&i| {
        let id = manifest.episodes[i].id;
        let train = pass.plan.split.is_train(id);
        pass.reads[i].fetch_add(1, Ordering::Relaxed);
        episode_job(id, || {
            let ep = pass.source.read_unpadded(i)?;
            if panic_on == Some(id) {
                panic!("CHUNKC_TEST_PANIC_EPISODE={id}");
            }
            let place = manifest.place(id, pass.source_path);
            Ok(
                match source::check::episode(&ep, manifest, pass.non_finite, &place)? {
                    source::check::Verdict::Exclude(reason) => Read::Excluded(reason),
                    source::check::Verdict::Keep if checking_only => Read::Checked,
                    source::check::Verdict::Keep => {
                        if let Some(doctor) = pass.doctor {
                            doctor.take(i, &ep);
                        }
                        Read::Kept(process(ep, pass.source, pass.jobs, train))
                    }
                },
            )
        })
    }))
}

/// The sequential part of a batch, in episode order: statistics partials merged, frames written
/// to every sink of their rate, then the low-dim rows per (rate, channel) pushed ([`push_rows`]).
fn consume(
    pass: &Pass,
    batch: Range<usize>,
    processed: Vec<Processed>,
    rates: &mut [RateState],
    sinks: &mut [(usize, Box<dyn Sink>)],
    bar: &indicatif::ProgressBar,
) -> Result<()> {
    let manifest = pass.source.manifest();
    let mut pending: Vec<Vec<Vec<Rows>>> = rates
        .iter()
        .map(|r| r.lowdim.iter().map(|_| Vec::new()).collect())
        .collect();
    for (i, episode) in batch.zip(processed) {
        let id = manifest.episodes[i].id;
        let train = pass.plan.split.is_train(id);
        let source = manifest.source_of(id);
        for (r, (rate, (data, partials))) in rates
            .iter_mut()
            .zip(episode.data.into_iter().zip(episode.partials))
            .enumerate()
        {
            let row = rate.start(i);
            for (c, (values, partial)) in data.into_iter().zip(partials).enumerate() {
                if let Some(p) = partial {
                    rate.partials[c].merge(&p);
                    rate.source_partials[source][c].merge(&p);
                }
                match values {
                    Prepared::Lowdim(values) => {
                        // As many rows as the values hold; a mixture source without the
                        // channel holds none, and is its episode's rows of padding.
                        let rows = match manifest.own_width(c, id) {
                            0 => rate.ends.range(i).len(),
                            own => values.len() / own,
                        };
                        pending[r][c].push(Rows {
                            values,
                            train,
                            source,
                            rows,
                        })
                    }
                    Prepared::Frames(encoded) => {
                        for (_, sink) in sinks.iter_mut().filter(|(sr, _)| *sr == r) {
                            let enc = sink.frame_encoding();
                            let (_, frames) = encoded
                                .iter()
                                .find(|(e, _)| *e == enc)
                                .expect("frames encoded for every sink");
                            sink.write_frames(c, row, frames)?;
                        }
                        // The uncompressed frames' memory takes the next episode's decode,
                        // unless a sink still holds them (a video encoder: they are freed when
                        // it is done).
                        for (enc, frames) in encoded {
                            if enc == FrameEncoding::Raw {
                                if let Some(bytes) = frames.into_unshared_bytes() {
                                    recycle::give(bytes);
                                }
                            }
                        }
                    }
                }
            }
        }
        bar.inc(1);
    }
    push_rows(rates, pending)
}

/// Each store takes its episodes' rows in order, each source counting the first percentile
/// pass over its training rows (a mixture's on its own dimensions); stores are independent, so
/// they fill (and spill) side by side.
fn push_rows(rates: &mut [RateState], pending: Vec<Vec<Vec<Rows>>>) -> Result<()> {
    type Counts = Option<Vec<HighCounts>>;
    let channels: Vec<(&mut Arc<LowdimStore>, &mut Vec<Counts>)> = rates
        .iter_mut()
        .flat_map(|r| r.lowdim.iter_mut().zip(r.source_high.iter_mut()))
        .collect();
    let pushed: Vec<Result<()>> = channels
        .into_par_iter()
        .zip(pending.into_iter().flatten().collect::<Vec<_>>())
        .map(|((store, sources), episodes)| {
            let store = Arc::get_mut(store).expect("no reader while the source is read");
            let width = store.width();
            // A mixture source's rows come at its own width (unpadded), as its store keeps them.
            episodes.iter().try_for_each(|rows| {
                if rows.train && width > 0 {
                    if let Some(own) = sources[rows.source].as_mut() {
                        HighCounts::add_rows(own, &rows.values);
                    }
                }
                store.push_own(&rows.values, rows.rows)
            })
        })
        .collect();
    pushed.into_iter().collect()
}
