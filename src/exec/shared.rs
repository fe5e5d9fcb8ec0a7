//! What every stale profile of a build shares as it finishes (the plan, the manifest, the
//! renderer), and a profile's statistics: the ones it normalizes with, the stored values' and
//! each source's.

use std::collections::BTreeMap;

use crate::plan::Plan;
use crate::render;
use crate::source::Manifest;
use crate::stats::ChannelStats;

/// What every profile of a build shares.
pub(super) struct Shared<'a> {
    pub plan: &'a Plan,
    pub manifest: &'a Manifest,
    pub renderer: &'a render::Renderer,
}

/// A profile's statistics: its own (after its transforms, over its population), which it
/// normalizes with, and the per-frame ones of the stored values (a LeRobot export's
/// `meta/stats.json` describes the stored features).
pub(super) struct Stats<'a> {
    pub own: &'a BTreeMap<String, ChannelStats>,
    pub stored: &'a BTreeMap<String, ChannelStats>,
    /// A training mixture's own, per source (its own width, after its transforms); empty for
    /// one source. `own` and `stored` are then the pooled ones.
    pub sources: &'a [BTreeMap<String, ChannelStats>],
}
