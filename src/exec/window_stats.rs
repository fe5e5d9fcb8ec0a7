//! The statistics a profile keeps for itself: channels it transforms (a rotation, openpi's
//! delta, UMI's relative pose) and profiles whose statistics cover every sample's window
//! (`stats_population = "windows"`, as openpi's `compute_norm_stats` counts them). They are
//! computed from the rate's row stores after reading, over the exact values the generated
//! loader returns (before normalizing), and replace the rate's shared statistics of those
//! channels for this profile only.
//!
//! The rows are generated again for each pass (moments, then the two exact-percentile passes),
//! a group of episodes at a time in parallel and fed in episode order: memory is a group's
//! windows, flat in the number of episodes, and the result does not depend on the threads.

use std::collections::BTreeMap;
use std::ops::Range;

use rayon::prelude::*;

use super::rate::RateState;
use crate::error::{Error, Result};
use crate::plan::ProfilePlan;
use crate::source::{ChannelKind, Manifest};
use crate::spec::StatsPopulation;
use crate::stats::{self, bands, ChannelStats, Moments};
use crate::transform::{self, Transform};
use crate::window::{Sampling, Step};

/// Episodes whose rows are generated side by side, per thread.
const EPISODES_PER_THREAD: usize = 2;

/// A profile's own statistics: `pooled` (a mixture's union, or one source's) and per source
/// (empty for one source), each the shared statistics with the profile's own in place of the
/// channels it transforms or counts by windows.
pub(super) struct Own {
    pub pooled: BTreeMap<String, ChannelStats>,
    pub sources: Vec<BTreeMap<String, ChannelStats>>,
}

/// The profile's own statistics, or `None` when it has none of its own (the default: nothing
/// is copied). `shared` and `shared_sources` are the rate's. Every episode's rows (training or
/// not) are checked to hold rotations first.
pub(super) fn profile_stats(
    p: &ProfilePlan,
    rate: &RateState,
    manifest: &Manifest,
    shared: &BTreeMap<String, ChannelStats>,
    shared_sources: &[BTreeMap<String, ChannelStats>],
    train_mask: &[bool],
) -> Result<Option<Own>> {
    if p.transforms.is_empty() && p.values.stats_population == StatsPopulation::Frames {
        return Ok(None);
    }
    let mut out = Own {
        pooled: shared.clone(),
        sources: shared_sources.to_vec(),
    };
    check_rotations(p, rate, manifest)?;
    let train: Vec<usize> = (0..p.episodes.len()).filter(|&e| train_mask[e]).collect();
    let source_of = |e: usize| manifest.source_of(p.episodes[e].id);
    for (c, ch) in manifest.channels.iter().enumerate() {
        if ch.kind != ChannelKind::Lowdim || !p.windowed_stats(c) {
            continue;
        }
        let widths = &p.widths[c];
        let rows = |sources: &[usize], dims: Range<usize>| Rows {
            p,
            rate,
            manifest,
            channel: c,
            train: train
                .iter()
                .copied()
                .filter(|&e| sources.contains(&source_of(e)))
                .collect(),
            dims,
        };
        // Each source's own (one for a single source), then the union's per band of the sources
        // that cover it; a band one source covers is that source's own, its dimensions `dims`.
        let mut own_stats = Vec::new();
        for (s, &own) in widths.own_after.iter().enumerate() {
            if widths.own[s] == 0 {
                own_stats.push((Moments::new(0), None));
                continue;
            }
            let (m, stats) = rows(&[s], 0..own).stats()?;
            // A mixture's per-source statistics (a single source has only the union's).
            if let Some(kept) = out.sources.get_mut(s) {
                kept.insert(ch.name.clone(), stats.clone());
            }
            own_stats.push((m, Some(stats)));
        }
        let mut parts = Vec::new();
        for (dims, sources) in bands::bands(&widths.own_after, widths.after) {
            if sources.is_empty() {
                parts.push(bands::uncovered(dims.len()));
                continue;
            }
            if let [s] = sources[..] {
                if let (_, Some(stats)) = &own_stats[s] {
                    parts.push(stats.columns(dims));
                    continue;
                }
            }
            let mut m = Moments::new(dims.len());
            for &s in &sources {
                m.merge(&own_stats[s].0.columns(dims.clone()));
            }
            parts.push(rows(&sources, dims).percentiles(m)?);
        }
        out.pooled.insert(ch.name.clone(), bands::concat(parts));
    }
    Ok(Some(out))
}

/// The rows one channel's statistics cover: each training episode's of the sources read,
/// transformed by its own source's transforms on its own dimensions, then the dimensions `dims`.
struct Rows<'a> {
    p: &'a ProfilePlan,
    rate: &'a RateState,
    manifest: &'a Manifest,
    channel: usize,
    /// Training episodes (positions), in order.
    train: Vec<usize>,
    /// The dimensions kept of each transformed row.
    dims: Range<usize>,
}

impl Rows<'_> {
    /// Moments (merged in episode order) and the statistics of the rows.
    fn stats(&self) -> Result<(Moments, ChannelStats)> {
        let width = self.dims.len();
        let mut m = Moments::new(width);
        self.each_block(&mut |block| m.merge(&Moments::of_rows(block, width)))?;
        Ok((m.clone(), self.percentiles(m)?))
    }

    /// The statistics of the rows, whose moments are `m`.
    fn percentiles(&self, m: Moments) -> Result<ChannelStats> {
        // Over windows, openpi's population, the percentiles are the data values openpi's
        // histogram quantiles approximate (within one of its bins).
        let definition = match self.p.values.stats_population {
            StatsPopulation::Windows => stats::Definition::InvertedCdf,
            StatsPopulation::Frames => stats::Definition::Linear,
        };
        stats::lowdim_from_rows_as(m, self.dims.len(), None, definition, |f| self.each_block(f))
    }

    /// Calls `f` with each training episode's block of rows, in episode order.
    fn each_block(&self, f: &mut dyn FnMut(&[f32])) -> Result<()> {
        let group = rayon::current_num_threads() * EPISODES_PER_THREAD;
        for episodes in self.train.chunks(group.max(1)) {
            let blocks: Vec<Vec<f32>> =
                crate::error::in_order(episodes.par_iter().map(|&e| self.episode(e)))?;
            for b in &blocks {
                f(b);
            }
        }
        Ok(())
    }

    /// Episode `e`'s rows: per sample, its action chunk (edge rows repeated) or observation
    /// history under `windows`, else each step once; each transformed with the reference at
    /// the sample's current step.
    fn episode(&self, e: usize) -> Result<Vec<f32>> {
        let (start, end) = (self.rate.start(e), self.rate.ends.range(e).end);
        let len = end - start;
        let c = self.channel;
        let width = self.manifest.channels[c].width();
        let s = self.manifest.source_of(self.p.episodes[e].id);
        let own = self.p.widths[c].own[s];
        let transforms: Vec<&Transform> = self.p.transforms_for(c, s).collect();
        let values = self.rate.lowdim[c].rows(start, end)?;
        let references = references(self.rate, &transforms, start, end)?;
        let is_action = self.manifest.channels[c].name == "action";
        // (current step, row) pairs.
        let pairs: Vec<(usize, usize)> = match self.p.values.stats_population {
            StatsPopulation::Frames => (0..len).map(|r| (r, r)).collect(),
            StatsPopulation::Windows => {
                let Sampling::Window { window } = &self.p.sampling else {
                    unreachable!("the plan allows windows only with fixed windows")
                };
                window
                    .samples(len)
                    .into_iter()
                    .flat_map(|s| {
                        let rows: Vec<usize> = if is_action {
                            window
                                .action_steps(s.t, s.limit, len)
                                .into_iter()
                                .map(|step| match step {
                                    Step::Row(r) | Step::Pad(r) => r,
                                })
                                .collect()
                        } else {
                            window.obs_steps(s.t).into_iter().map(|(r, _)| r).collect()
                        };
                        rows.into_iter().map(move |r| (s.t, r))
                    })
                    .collect()
            }
        };
        let mut out = Vec::with_capacity(pairs.len() * self.dims.len());
        let mut row = Vec::with_capacity(self.dims.end);
        for (t, r) in pairs {
            row.clear();
            row.extend(
                values[r * width..r * width + own]
                    .iter()
                    .map(|&v| f64::from(v)),
            );
            for tr in &transforms {
                let reference = reference_row(&references, tr, t);
                tr.apply(&mut row, reference)
                    .map_err(|why| not_rotation(self.p, e, r, tr, &why))?;
            }
            out.extend(row[self.dims.clone()].iter().map(|&v| v as f32));
        }
        Ok(out)
    }
}

/// Each reference channel's raw rows of one episode, as f64, by channel position.
fn references(
    rate: &RateState,
    transforms: &[&Transform],
    start: usize,
    end: usize,
) -> Result<BTreeMap<usize, (usize, Vec<f64>)>> {
    let mut out = BTreeMap::new();
    for c in transforms.iter().filter_map(|t| t.reference()) {
        if let std::collections::btree_map::Entry::Vacant(slot) = out.entry(c) {
            let store = &rate.lowdim[c];
            let rows = store.rows(start, end)?;
            slot.insert((store.width(), rows.iter().map(|&v| f64::from(v)).collect()));
        }
    }
    Ok(out)
}

/// The reference channel's row at step `t`, or nothing for a rotation.
fn reference_row<'r>(
    references: &'r BTreeMap<usize, (usize, Vec<f64>)>,
    t: &Transform,
    step: usize,
) -> &'r [f64] {
    match t.reference() {
        Some(c) => {
            let (w, rows) = &references[&c];
            &rows[step * w..(step + 1) * w]
        }
        None => &[],
    }
}

fn not_rotation(p: &ProfilePlan, e: usize, step: usize, t: &Transform, why: &str) -> Error {
    Error::source(format!(
        "episode {}, step {step} (at {} Hz), channel `{}`: profile `{}`'s {} transform finds {why}; check the transform's dims and rotation kind",
        p.episodes[e].id,
        p.fps,
        t.channel,
        p.name,
        match t.op {
            transform::Op::Rotation { .. } => "rotation",
            transform::Op::Delta { .. } => "delta",
            transform::Op::RelativePose { .. } => "relative_pose",
        }
    ))
}

/// Every episode's every row through its channel's transforms (its source's, on its own
/// dimensions; the reference at the same step), so that a slice holding no rotation is named by
/// episode and step, whatever its split.
fn check_rotations(p: &ProfilePlan, rate: &RateState, manifest: &Manifest) -> Result<()> {
    let channels: Vec<usize> = (0..manifest.channels.len())
        .filter(|&c| p.transforms_of(c).next().is_some())
        .collect();
    crate::error::in_order(
        (0..p.episodes.len())
            .into_par_iter()
            .map(|e| -> Result<()> {
                let (start, end) = (rate.start(e), rate.ends.range(e).end);
                let s = manifest.source_of(p.episodes[e].id);
                for &c in &channels {
                    let transforms: Vec<&Transform> = p.transforms_for(c, s).collect();
                    if transforms.is_empty() {
                        continue;
                    }
                    let width = manifest.channels[c].width();
                    let own = p.widths[c].own[s];
                    let values = rate.lowdim[c].rows(start, end)?;
                    let references = references(rate, &transforms, start, end)?;
                    let mut row = Vec::new();
                    for r in 0..end - start {
                        row.clear();
                        row.extend(
                            values[r * width..r * width + own]
                                .iter()
                                .map(|&v| f64::from(v)),
                        );
                        for t in &transforms {
                            t.apply(&mut row, reference_row(&references, t, r))
                                .map_err(|why| not_rotation(p, e, r, t, &why))?;
                        }
                    }
                }
                Ok(())
            }),
    )?;
    Ok(())
}
