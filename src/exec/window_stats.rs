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

use rayon::prelude::*;

use super::rate::RateState;
use crate::error::{Error, Result};
use crate::plan::ProfilePlan;
use crate::source::{ChannelKind, Manifest};
use crate::spec::StatsPopulation;
use crate::stats::{self, ChannelStats, Moments};
use crate::transform::{self, Transform};
use crate::window::{Sampling, Step};

/// Episodes whose rows are generated side by side, per thread.
const EPISODES_PER_THREAD: usize = 2;

/// `shared` with the profile's own statistics in place of the channels it transforms or counts
/// by windows, or `None` when it has none of its own (the default: nothing is copied). Every
/// episode's rows (training or not) are checked to hold rotations first.
pub(super) fn profile_stats(
    p: &ProfilePlan,
    rate: &RateState,
    manifest: &Manifest,
    shared: &BTreeMap<String, ChannelStats>,
    train_mask: &[bool],
) -> Result<Option<BTreeMap<String, ChannelStats>>> {
    if p.transforms.is_empty() && p.values.stats_population == StatsPopulation::Frames {
        return Ok(None);
    }
    let mut out = shared.clone();
    check_rotations(p, rate, manifest)?;
    for (c, ch) in manifest.channels.iter().enumerate() {
        if ch.kind != ChannelKind::Lowdim || !p.windowed_stats(c) {
            continue;
        }
        let rows = Rows {
            p,
            rate,
            manifest,
            channel: c,
            transforms: p.transforms_of(c).collect(),
            width: transform::width_after(p.transforms_of(c), ch.width()),
            train: (0..p.episodes.len()).filter(|&e| train_mask[e]).collect(),
        };
        let mut m = Moments::new(rows.width);
        rows.each_block(&mut |block| m.merge(&Moments::of_rows(block, rows.width)))?;
        // Over windows, openpi's population, the percentiles are the data values openpi's
        // histogram quantiles approximate (within one of its bins).
        let definition = match p.values.stats_population {
            StatsPopulation::Windows => stats::Definition::InvertedCdf,
            StatsPopulation::Frames => stats::Definition::Linear,
        };
        let s =
            stats::lowdim_from_rows_as(m, rows.width, None, definition, |f| rows.each_block(f))?;
        out.insert(ch.name.clone(), s);
    }
    Ok(Some(out))
}

/// The rows one channel's statistics cover.
struct Rows<'a> {
    p: &'a ProfilePlan,
    rate: &'a RateState,
    manifest: &'a Manifest,
    channel: usize,
    transforms: Vec<&'a Transform>,
    /// Values per row after the transforms.
    width: usize,
    /// Training episodes (positions), in order.
    train: Vec<usize>,
}

impl Rows<'_> {
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
        let width = self.manifest.channels[self.channel].width();
        let values = self.rate.lowdim[self.channel].rows(start, end)?;
        let references = references(self.rate, &self.transforms, start, end)?;
        let is_action = self.manifest.channels[self.channel].name == "action";
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
        let mut out = Vec::with_capacity(pairs.len() * self.width);
        let mut row = Vec::with_capacity(self.width);
        for (t, r) in pairs {
            row.clear();
            row.extend(
                values[r * width..(r + 1) * width]
                    .iter()
                    .map(|&v| f64::from(v)),
            );
            for tr in &self.transforms {
                let reference = reference_row(&references, tr, t);
                tr.apply(&mut row, reference)
                    .map_err(|why| not_rotation(self.p, e, r, tr, &why))?;
            }
            out.extend(row.iter().map(|&v| v as f32));
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

/// Every episode's every row through its channel's transforms (the reference at the same
/// step), so that a slice holding no rotation is named by episode and step, whatever its split.
fn check_rotations(p: &ProfilePlan, rate: &RateState, manifest: &Manifest) -> Result<()> {
    let channels: Vec<usize> = (0..manifest.channels.len())
        .filter(|&c| p.transforms_of(c).next().is_some())
        .collect();
    crate::error::in_order(
        (0..p.episodes.len())
            .into_par_iter()
            .map(|e| -> Result<()> {
                let (start, end) = (rate.start(e), rate.ends.range(e).end);
                for &c in &channels {
                    let transforms: Vec<&Transform> = p.transforms_of(c).collect();
                    let width = manifest.channels[c].width();
                    let values = rate.lowdim[c].rows(start, end)?;
                    let references = references(rate, &transforms, start, end)?;
                    let mut row = Vec::new();
                    for r in 0..end - start {
                        row.clear();
                        row.extend(
                            values[r * width..(r + 1) * width]
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
