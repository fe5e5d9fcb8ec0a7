//! The statistics of every channel at one rate, shared by every profile at that rate: low-dim
//! percentiles from the row store (moments were merged while reading), image statistics from
//! their partials. They are over the union of the sources' training rows, per dimension over
//! the sources that have it ([`stats::bands`]); a single source is one source whose one band is
//! the whole channel. A training mixture's sources each get their own too, over their training
//! rows at their own width: padding never enters a statistic, and every percentile is exact
//! over the rows it covers.

use std::collections::BTreeMap;
use std::ops::Range;

use rayon::prelude::*;

use super::rate::{Partial, RateState};
use crate::error::Result;
use crate::source::Manifest;
use crate::stats::{self, bands, ChannelStats, HighCounts, Moments};
use crate::store::LowdimStore;

/// The statistics of every channel at this rate: low-dim percentiles from the store (moments
/// were merged while reading), image statistics from their partials. A low-dim channel's are
/// over the union of its sources' training rows, per dimension over the sources that have it
/// ([`stats::bands`]): one band of one source for a single source, and a mixture's padding
/// never enters a statistic.
pub(super) fn stats(
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
                    let mut parts = Vec::new();
                    for (dims, sources) in bands::bands(&manifest.source_widths(c), ch.width()) {
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
        store.for_columns(rows, dims.clone(), f)
    })
}
