//! What a build keeps per output rate while the source is read: each episode's end in the
//! converted per-step arrays, every low-dim value (in a [`LowdimStore`]), and the statistics
//! partials of the training episodes, merged in episode order (`rate_stats` reduces them to
//! the statistics every profile at that rate shares).

use std::sync::Arc;

use super::staging::Staging;
use crate::plan::Conversion;
use crate::source::{ChannelKind, Manifest};
use crate::stats::{self, HighCounts, ImagePartial};
use crate::store::LowdimStore;
use crate::window::EpisodeEnds;

/// Channels up to this wide count their first percentile pass as rows are pushed (a 256 KiB
/// table per column, 16 MiB at most a channel); wider ones (point clouds) leave both passes to
/// the statistics, a group of columns at a time.
pub(super) const COUNT_AHEAD_COLUMNS: usize = 64;

/// Per-rate state: the converted low-dimensional data of every episode, and the streaming
/// statistics of every channel.
pub(super) struct RateState {
    /// Exclusive ends of each episode in the converted per-step arrays.
    pub ends: EpisodeEnds,
    /// Per channel (manifest order): concatenated low-dim values; empty for images. Shared with
    /// the sinks that export episode by episode once reading is over.
    pub lowdim: Vec<Arc<LowdimStore>>,
    /// Per channel, per source (one for a single source): the first pass of the exact
    /// percentiles over that source's training rows, on its own dimensions (a mixture's padding
    /// is not a value), counted as they are pushed (see [`stats::SecondPass`] for the second);
    /// the statistics' bands merge them. `None` for channels wider than
    /// [`COUNT_AHEAD_COLUMNS`]; empty tables for images.
    pub source_high: Vec<Vec<Option<Vec<HighCounts>>>>,
    /// Per channel: the statistics partials of the training episodes, merged in episode order.
    pub partials: Vec<Partial>,
    /// Per source (one for a single source), per channel: the same, of that source's episodes.
    pub source_partials: Vec<Vec<Partial>>,
}

impl RateState {
    /// The empty state of rate number `r`; channel `c`'s store keeps its values in memory when
    /// they fit in `budgets[c]`, and spills under the staging directory's scratch space
    /// otherwise (see [`store_values`]).
    pub fn new(
        r: usize,
        conversion: Conversion,
        manifest: &Manifest,
        staging: &Staging,
        budgets: &[usize],
    ) -> RateState {
        let mut ends = EpisodeEnds::default();
        for e in &manifest.episodes {
            ends.push(conversion.len(e.len));
        }
        let width = |ch: &crate::source::ChannelInfo| match ch.kind {
            ChannelKind::Lowdim => ch.width(),
            ChannelKind::Image => 0,
        };
        let channels = &manifest.channels;
        let partials = || -> Vec<Partial> {
            channels
                .iter()
                .map(|c| match c.kind {
                    ChannelKind::Lowdim => Partial::Lowdim(stats::Moments::new(c.width())),
                    ChannelKind::Image => {
                        Partial::Image(ImagePartial::new(*c.shape.last().unwrap_or(&1)))
                    }
                })
                .collect()
        };
        // Each source counts its own dimensions (a mixture's padding is zeros no statistic
        // counts), and the statistics' bands merge them (`rate_stats`).
        let counts = |w: usize| {
            (w <= COUNT_AHEAD_COLUMNS).then(|| (0..w).map(|_| HighCounts::new()).collect())
        };
        RateState {
            ends,
            lowdim: channels
                .iter()
                .enumerate()
                .map(|(c, ch)| {
                    let dir = staging.scratch_dir().join(format!("rate{r}-channel{c}"));
                    let values = store_values(conversion, manifest)[c];
                    Arc::new(LowdimStore::with_values(width(ch), budgets[c], dir, values))
                })
                .collect(),
            source_high: channels
                .iter()
                .enumerate()
                .map(|(c, ch)| {
                    let own = |w: usize| if width(ch) == 0 { 0 } else { w };
                    (manifest.source_widths(c).into_iter())
                        .map(|w| counts(own(w)))
                        .collect()
                })
                .collect(),
            partials: partials(),
            source_partials: (0..manifest.parts.len().max(1))
                .map(|_| partials())
                .collect(),
        }
    }

    /// Where episode `e`'s rows start in the converted per-step arrays.
    pub fn start(&self, e: usize) -> usize {
        self.ends.start(e)
    }
}

/// The values each channel's store will hold at this rate (0 for cameras): every episode's
/// converted rows, a mixture source's at its own width.
pub(super) fn store_values(conversion: Conversion, manifest: &Manifest) -> Vec<usize> {
    (manifest.channels.iter().enumerate())
        .map(|(c, ch)| match ch.kind {
            ChannelKind::Image => 0,
            ChannelKind::Lowdim => (manifest.episodes.iter())
                .map(|ep| conversion.len(ep.len) * manifest.own_width(c, ep.id))
                .sum(),
        })
        .collect()
}

/// The part of a channel's statistics reduced while the source is read: moments of low-dim
/// channels (their percentiles need every value, and are taken from the store at the end), and
/// moments + histograms of images.
pub(super) enum Partial {
    Lowdim(stats::Moments),
    Image(ImagePartial),
}

impl Partial {
    pub fn merge(&mut self, other: &Partial) {
        match (self, other) {
            (Partial::Lowdim(a), Partial::Lowdim(b)) => a.merge(b),
            (Partial::Image(a), Partial::Image(b)) => a.merge(b),
            _ => unreachable!("partials of one channel have one kind"),
        }
    }
}
