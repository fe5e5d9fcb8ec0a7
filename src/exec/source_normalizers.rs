//! A training mixture's normalizers, per source: each source's stored rows normalized with its
//! own table, on its own dimensions, the padding left as it is.

use std::collections::BTreeMap;

use super::rate::RateState;
use super::shared::{Shared, Stats};
use crate::plan::ProfilePlan;
use crate::source::{ChannelKind, Manifest};
use crate::spec::MixtureStats;
use crate::stats::normalize::{Normalizer, RowNormalizer};
use crate::stats::ChannelStats;

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
