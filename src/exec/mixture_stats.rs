//! A training mixture's statistics at one rate: each source's own, over its training rows at its
//! own width, and the pooled ones over the union of the sources' training rows, per dimension
//! over the sources that have it ([`stats::bands`]): padding never enters a statistic, and every
//! percentile is exact over the rows it covers. Moments come from the partials merged in episode
//! order; percentiles from two passes over the rows of the store.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

use super::finish::{Shared, Stats};
use super::rate::{Partial, RateState};
use crate::error::{IoContext, Result};
use crate::plan::{ProfilePlan, STATS_FILE};
use crate::render;
use crate::sink::documents;
use crate::source::{ChannelKind, Manifest};
use crate::spec::MixtureStats;
use crate::stats::normalize::{Normalizer, RowNormalizer};
use crate::stats::{self, bands, ChannelStats, Moments};
use crate::store::LowdimStore;

/// A mixture's sources' own statistics beside the pooled ones: `sources/<name>/stats.json`,
/// LeRobot's `lerobot_stats.json`, and the files of the profile's `stats_formats`, each from the
/// source's statistics alone (its own channels, at its own widths).
pub(super) fn write_source_stats(
    shared: &Shared,
    p: &ProfilePlan,
    sources: &[BTreeMap<String, ChannelStats>],
    dir: &Path,
) -> Result<()> {
    for (part, own) in shared.manifest.parts.iter().zip(sources) {
        let sub = dir.join("sources").join(&part.name);
        std::fs::create_dir_all(&sub).at("create", &sub)?;
        let mut narrowed = p.clone();
        narrowed.channels.retain(|ch| own.contains_key(&ch.name));
        for ch in &mut narrowed.channels {
            if ch.kind == ChannelKind::Lowdim && ch.shape.len() == 1 {
                ch.shape = vec![own[&ch.name].mean.len()];
            }
        }
        let normalizers: BTreeMap<String, Normalizer> = narrowed
            .channels
            .iter()
            .map(|ch| {
                (
                    ch.name.clone(),
                    Normalizer::fit(ch.normalize, &own[&ch.name]),
                )
            })
            .collect();
        let inputs = render::codebase::Inputs {
            profile: &narrowed,
            stats: own,
            normalizers: &normalizers,
            example_state: None,
            renderer: shared.renderer,
        };
        let mut files = vec![
            (
                STATS_FILE.to_string(),
                documents::stats_json(&narrowed, own).into_bytes(),
            ),
            (
                "lerobot_stats.json".into(),
                render::codebase::lerobot(&narrowed, own),
            ),
        ];
        for f in render::codebase::files(&p.values.stats_formats, &inputs)? {
            files.push((f.name, f.bytes));
        }
        for (name, bytes) in files {
            let path = sub.join(name);
            std::fs::write(&path, bytes).at("write", &path)?;
        }
    }
    Ok(())
}

/// Per source (mixture order), every channel it has: its own statistics, at its own width
/// (none for one source).
pub(super) fn per_source(
    rate: &RateState,
    manifest: &Manifest,
    train_mask: &[bool],
) -> Result<Vec<BTreeMap<String, ChannelStats>>> {
    let mut out = Vec::new();
    for (s, part) in manifest.parts.iter().enumerate() {
        let mut own = BTreeMap::new();
        for (c, ch) in manifest.channels.iter().enumerate() {
            let width = part.widths[c];
            if width == 0 {
                continue;
            }
            let s_stats = match &rate.source_partials[s][c] {
                Partial::Image(p) => p.clone().finish(),
                Partial::Lowdim(m) => {
                    let rows = train_rows(rate, manifest, train_mask, &[s]);
                    band(&rate.lowdim[c], &rows, m.columns(0..width), 0..width)?
                }
            };
            own.insert(ch.name.clone(), s_stats);
        }
        out.push(own);
    }
    Ok(out)
}

/// Every channel's statistics over the union of the sources' training rows, at the channel's
/// width (dimensions no source has are zeros counting nothing).
pub(super) fn pooled(
    rate: &RateState,
    manifest: &Manifest,
    train_mask: &[bool],
) -> Result<BTreeMap<String, ChannelStats>> {
    let mut out = BTreeMap::new();
    for (c, ch) in manifest.channels.iter().enumerate() {
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
                    parts.push(band(&rate.lowdim[c], &rows, m, dims)?);
                }
                bands::concat(parts)
            }
        };
        out.insert(ch.name.clone(), s);
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

/// The statistics of dimensions `dims` of the store's `rows`, whose moments are `m`.
fn band(
    store: &LowdimStore,
    rows: &[(usize, usize)],
    m: Moments,
    dims: Range<usize>,
) -> Result<ChannelStats> {
    let width = store.width();
    let narrow = dims.len();
    let mut buffer = Vec::new();
    stats::lowdim_from_rows(m, narrow, None, |f| {
        if dims == (0..width) {
            return store.for_rows(rows, f);
        }
        store.for_rows(rows, &mut |block| {
            buffer.clear();
            for row in block.chunks_exact(width) {
                buffer.extend_from_slice(&row[dims.clone()]);
            }
            f(&buffer);
        })
    })
}

/// A mixture profile's normalizers, per source, at each channel's width: fitted on the source's
/// own statistics (`[mixture] stats = "per_source"`) or on the pooled ones (`"pooled"`), on the
/// source's own dimensions; the identity on the rest, so that its padding stays 0.
pub(super) struct Normalizers {
    /// Per source, per channel.
    pub by_source: Vec<BTreeMap<String, Normalizer>>,
}

impl Normalizers {
    /// `None` for one source.
    pub fn new(shared: &Shared, p: &ProfilePlan, stats: &Stats) -> Option<Normalizers> {
        let manifest = shared.manifest;
        let mode = shared.plan.mixture.as_ref()?.stats;
        let mut by_source = Vec::new();
        for (s, part) in manifest.parts.iter().enumerate() {
            let mut own = BTreeMap::new();
            for (c, ch) in p.channels.iter().enumerate() {
                // After the transforms: each source's own dimensions, then its padding.
                let width = p.widths[c].after;
                let fitted = |stats: &ChannelStats| Normalizer::fit(ch.normalize, stats);
                let own_width = match part.widths[c] {
                    0 => 0,
                    _ => p.widths[c].own_after[s],
                };
                let n = match (ch.kind, own_width, mode) {
                    (ChannelKind::Image, _, _) => fitted(&stats.own[&ch.name]),
                    (ChannelKind::Lowdim, 0, _) => Normalizer::identity(width),
                    (ChannelKind::Lowdim, w, MixtureStats::PerSource) => {
                        fitted(&stats.sources[s][&ch.name]).widened(w, width)
                    }
                    (ChannelKind::Lowdim, w, MixtureStats::Pooled) => {
                        fitted(&stats.own[&ch.name]).widened(w, width)
                    }
                };
                own.insert(ch.name.clone(), n);
            }
            by_source.push(own);
        }
        Some(Normalizers { by_source })
    }

    /// Channel `c`'s normalizers by stored row: each source's from its first row.
    pub fn rows(&self, rate: &RateState, manifest: &Manifest, c: usize) -> RowNormalizer {
        let name = &manifest.channels[c].name;
        let mut pieces: Vec<(usize, Normalizer)> = Vec::new();
        for (s, own) in self.by_source.iter().enumerate() {
            let first = manifest
                .episodes
                .iter()
                .position(|e| manifest.source_of(e.id) == s);
            if let Some(e) = first {
                let start = if pieces.is_empty() { 0 } else { rate.start(e) };
                pieces.push((start, own[name].clone()));
            }
        }
        RowNormalizer::pieces(pieces)
    }
}
