//! The statistics of every channel at one rate, shared by every profile at that rate: low-dim
//! percentiles from the row store (moments were merged while reading), image statistics from
//! their partials. A training mixture's sources each get their own, over their training rows at
//! their own width, and the pooled ones are over the union of the sources' training rows, per
//! dimension over the sources that have it ([`stats::bands`]): padding never enters a
//! statistic, and every percentile is exact over the rows it covers.

use std::collections::BTreeMap;
use std::ops::Range;

use rayon::prelude::*;

use super::rate::{Partial, RateState};
use crate::error::Result;
use crate::source::{ChannelKind, Manifest};
use crate::stats::{self, bands, ChannelStats, HighCounts, Moments};
use crate::store::LowdimStore;

/// The statistics of every channel at this rate: low-dim percentiles from the store (moments
/// were merged while reading), image statistics from their partials; a mixture's pooled over
/// its sources.
pub(super) fn stats(
    rate: &RateState,
    manifest: &Manifest,
    train_mask: &[bool],
) -> Result<BTreeMap<String, ChannelStats>> {
    if !manifest.parts.is_empty() {
        return pooled(rate, manifest, train_mask);
    }
    let mut by_channel = BTreeMap::new();
    for (c, ch) in manifest.channels.iter().enumerate() {
        let s = match (&rate.partials[c], ch.kind) {
            (Partial::Lowdim(m), ChannelKind::Lowdim) => {
                let values = &rate.lowdim[c];
                let train: Vec<(usize, usize)> = (0..rate.ends.len())
                    .filter(|&e| train_mask[e])
                    .map(|e| (rate.ends.start(e), rate.ends.range(e).end))
                    .collect();
                // The first percentile pass was counted as the rows arrived; the second
                // reads the training rows once, for every column.
                let high = rate.high[c].as_deref();
                stats::lowdim_from_rows(m.clone(), ch.width(), high, |f| {
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

/// Per source (mixture order), every channel it has: its own statistics, at its own width
/// (none for one source).
pub(super) fn per_source(
    rate: &RateState,
    manifest: &Manifest,
    train_mask: &[bool],
) -> Result<Vec<BTreeMap<String, ChannelStats>>> {
    // Every (source, channel) on its own thread; each statistic reads only its own rows.
    let pairs: Vec<(usize, usize)> = (0..manifest.parts.len())
        .flat_map(|s| (0..manifest.channels.len()).map(move |c| (s, c)))
        .filter(|&(s, c)| manifest.parts[s].widths[c] > 0)
        .collect();
    let each = pairs.par_iter().map(|&(s, c)| -> Result<ChannelStats> {
        let width = manifest.parts[s].widths[c];
        Ok(match &rate.source_partials[s][c] {
            Partial::Image(p) => p.clone().finish(),
            Partial::Lowdim(m) => {
                let rows = train_rows(rate, manifest, train_mask, &[s]);
                let high = rate.source_high[c][s].as_deref();
                band(&rate.lowdim[c], &rows, m.columns(0..width), 0..width, high)?
            }
        })
    });
    let each: Vec<ChannelStats> = crate::error::in_order(each)?;
    let mut out: Vec<BTreeMap<String, ChannelStats>> =
        manifest.parts.iter().map(|_| BTreeMap::new()).collect();
    for ((s, c), stats) in pairs.into_iter().zip(each) {
        out[s].insert(manifest.channels[c].name.clone(), stats);
    }
    Ok(out)
}

/// Every channel's statistics over the union of the sources' training rows, at the channel's
/// width (dimensions no source has are zeros counting nothing).
fn pooled(
    rate: &RateState,
    manifest: &Manifest,
    train_mask: &[bool],
) -> Result<BTreeMap<String, ChannelStats>> {
    let each = manifest
        .channels
        .par_iter()
        .enumerate()
        .map(|(c, ch)| -> Result<_> {
            let s = match &rate.partials[c] {
                // Frames are never padded: the partials of every training episode are the union's.
                Partial::Image(p) => p.clone().finish(),
                Partial::Lowdim(_) => {
                    let widths: Vec<usize> = manifest.parts.iter().map(|p| p.widths[c]).collect();
                    let mut parts = Vec::new();
                    for (dims, sources) in bands::bands(&widths, ch.width()) {
                        if sources.is_empty() {
                            parts.push(bands::uncovered(dims.len()));
                            continue;
                        }
                        let mut m = Moments::new(dims.len());
                        for &s in &sources {
                            match &rate.source_partials[s][c] {
                                Partial::Lowdim(own) => m.merge(&own.columns(dims.clone())),
                                Partial::Image(_) => unreachable!("a low-dim channel's partial"),
                            }
                        }
                        let rows = train_rows(rate, manifest, train_mask, &sources);
                        let high = merged_counts(&rate.source_high[c], &sources, &dims);
                        parts.push(band(&rate.lowdim[c], &rows, m, dims, high.as_deref())?);
                    }
                    bands::concat(parts)
                }
            };
            Ok((ch.name.clone(), s))
        });
    Ok(crate::error::in_order(each)?.into_iter().collect())
}

/// The training rows of the episodes of `sources`, in storage order.
fn train_rows(
    rate: &RateState,
    manifest: &Manifest,
    train_mask: &[bool],
    sources: &[usize],
) -> Vec<(usize, usize)> {
    (0..rate.ends.len())
        .filter(|&e| {
            train_mask[e] && sources.contains(&manifest.source_of(manifest.episodes[e].id))
        })
        .map(|e| (rate.ends.start(e), rate.ends.range(e).end))
        .collect()
}

/// The first percentile pass over dimensions `dims` of the training rows of `sources`: the sum
/// of what each source counted as its rows were pushed (`None` when one did not count).
fn merged_counts(
    counted: &[Option<Vec<HighCounts>>],
    sources: &[usize],
    dims: &Range<usize>,
) -> Option<Vec<HighCounts>> {
    let mut merged: Vec<HighCounts> = dims.clone().map(|_| HighCounts::new()).collect();
    for &s in sources {
        let own = counted[s].as_ref()?;
        for (m, d) in merged.iter_mut().zip(dims.clone()) {
            m.merge(&own[d]);
        }
    }
    Some(merged)
}

/// The statistics of dimensions `dims` of the store's `rows`, whose moments are `m`; `high`:
/// their first percentile pass, when it was counted as the rows were pushed.
fn band(
    store: &LowdimStore,
    rows: &[(usize, usize)],
    m: Moments,
    dims: Range<usize>,
    high: Option<&[HighCounts]>,
) -> Result<ChannelStats> {
    let narrow = dims.len();
    stats::lowdim_from_rows(m, narrow, high, |f| {
        if dims == (0..store.width()) {
            return store.for_rows(rows, f);
        }
        store.for_columns(rows, dims.clone(), f)
    })
}
