//! The dataset doctor of each source of a training mixture, riding on the build's one read: as
//! the build reads an episode through the [`Mixture`](super::Mixture), the episode, still at its
//! source's own rate and width, is reduced to its doctor features (what that source's own audit
//! reduces it to); once the pass is over, each source's features are judged as its own audit
//! judges them (its `[audit.doctor]`, its rate, its own ids), and the sources' reports are
//! joined again. The sources' values are read once, by the build.
//!
//! A source whose steps the mixture's rate keeps (its own rate) is stored by the build as read,
//! at its own width: when the build says it will reduce from its stores
//! ([`SourcesDoctor::from_stores`]), such a source's episodes are reduced beside the writes
//! ([`SourcesDoctor::take_stored`]), as a single source's are, and the read only converts.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Instant;

use rayon::prelude::*;

use super::doctor::{Features, Probe};
use super::joined_report::joined_report;
use super::AuditReport;
use crate::error::Result;
use crate::source::{Episode, Manifest};
use crate::spec::SourceView;
use crate::store::LowdimStore;

/// One source's doctor.
pub struct SourceDoctor {
    pub view: SourceView,
    /// `None`: the doctor is off for this source, or it has no action channel.
    pub probe: Option<Probe>,
    /// Its own rate (the doctor's time scale).
    pub fps: f64,
    /// Its first mixture id.
    pub id_offset: u64,
    /// Its audit before the doctor (its own ids).
    pub report: AuditReport,
    /// Where the mixture's rate keeps its steps: the mixture's channels (positions) holding the
    /// probe's action and state, from which its stored rows are reduced.
    pub stored: Option<(usize, Option<usize>)>,
}

/// Every source's doctor, and the features of each episode the build has read.
pub struct SourcesDoctor {
    sources: Vec<SourceDoctor>,
    /// The mixture's episode ids, in its order (ascending).
    ids: Vec<u64>,
    /// Per mixture position: its features, once read.
    slots: Vec<OnceLock<Features>>,
    /// Nanoseconds spent computing features, over all threads.
    busy: AtomicU64,
    /// Per mixture position: its source.
    source_at: Vec<usize>,
    /// Whether this pass reduces the stored sources from the build's stores.
    from_stores: AtomicBool,
}

impl SourcesDoctor {
    /// `manifest`: the mixture's.
    pub fn new(sources: Vec<SourceDoctor>, manifest: &Manifest) -> SourcesDoctor {
        SourcesDoctor {
            sources,
            ids: manifest.episodes.iter().map(|e| e.id).collect(),
            slots: manifest.episodes.iter().map(|_| OnceLock::new()).collect(),
            busy: AtomicU64::new(0),
            source_at: (manifest.episodes.iter())
                .map(|e| manifest.source_of(e.id))
                .collect(),
            from_stores: AtomicBool::new(false),
        }
    }

    /// Whether any source can be reduced from the build's stores.
    pub fn stores_any(&self) -> bool {
        self.sources
            .iter()
            .any(|s| s.probe.is_some() && s.stored.is_some())
    }

    /// Says, before a pass reads, whether it will call [`SourcesDoctor::take_stored`]: then
    /// the read leaves the sources the stores hold to it.
    pub fn from_stores(&self, yes: bool) {
        self.from_stores.store(yes, Ordering::Relaxed);
    }

    /// Reduces mixture position `position`, read from source `s` as `own` (its own channels,
    /// rate and width), once; a source the pass reduces from its stores is left to it.
    pub fn take(&self, position: usize, s: usize, own: &Episode) {
        let source = &self.sources[s];
        let Some(probe) = &source.probe else {
            return;
        };
        if source.stored.is_some() && self.from_stores.load(Ordering::Relaxed) {
            return;
        }
        self.keep(position, || probe.features(own));
    }

    /// Reduces every episode of the sources whose steps the mixture's rate keeps from the rows
    /// `stores` (the mixture's channels at its rate, position `i`'s episode at `rows(i)`) hold:
    /// their own values, as read, so the features are those [`SourcesDoctor::take`] computes.
    pub fn take_stored(
        &self,
        stores: &[Arc<LowdimStore>],
        rows: &(dyn Fn(usize) -> std::ops::Range<usize> + Sync),
    ) -> Result<()> {
        (0..self.slots.len()).into_par_iter().try_for_each(|i| {
            let source = &self.sources[self.source_at[i]];
            let (Some(probe), Some((action, state))) = (&source.probe, source.stored) else {
                return Ok(());
            };
            let rows = rows(i);
            let a = stores[action].own_rows(rows.start, rows.end)?;
            let s = match state {
                Some(c) => Some(stores[c].own_rows(rows.start, rows.end)?),
                None => None,
            };
            self.keep(i, || probe.reduce(&a, s.as_deref()));
            Ok(())
        })
    }

    /// Keeps position `i`'s features, once, counting the time they took.
    fn keep(&self, i: usize, features: impl FnOnce() -> Features) {
        if self.slots[i].get().is_some() {
            return;
        }
        let started = Instant::now();
        // An exact-size copy, as the single source's doctor keeps it (see `exec::doctor`).
        let _ = self.slots[i].set(features().clone());
        let spent = started.elapsed().as_nanos() as u64;
        self.busy.fetch_add(spent, Ordering::Relaxed);
    }

    /// Nanoseconds spent computing features so far, over all threads.
    pub fn busy(&self) -> &AtomicU64 {
        &self.busy
    }

    /// Judges each source's episodes among `ids` (mixture ids, every one read) as its own audit
    /// would: the joined report, and the mixture ids the doctor excludes, with why.
    pub fn judge(&self, ids: &[u64]) -> Result<(AuditReport, Vec<(u64, String)>)> {
        let mut excluded = Vec::new();
        let mut reports = Vec::new();
        for (s, source) in self.sources.iter().enumerate() {
            let mut report = source.report.clone();
            if let Some(probe) = &source.probe {
                let mut own_ids = Vec::new();
                let mut feats = Vec::new();
                for &id in ids.iter().filter(|&&id| self.source_of(id) == s) {
                    own_ids.push(id - source.id_offset);
                    let at = self.ids.binary_search(&id).expect("an id of the mixture");
                    let f = self.slots[at].get().expect("the build read every episode");
                    feats.push(f.clone());
                }
                let started = Instant::now();
                let spec = &source.view.spec;
                let own = probe.judge(spec, source.fps, &own_ids, &feats, &mut report)?;
                let busy = self.busy.load(Ordering::Relaxed) as f64 * 1e-9;
                let threads = rayon::current_num_threads().max(1) as f64;
                let share = busy / threads / self.sources.len() as f64;
                report.doctor_seconds = Some(share + started.elapsed().as_secs_f64());
                excluded.extend(
                    own.into_iter()
                        .map(|(id, why)| (id + source.id_offset, why)),
                );
            }
            reports.push((source.view.name.clone(), source.id_offset, report));
        }
        Ok((joined_report(reports), excluded))
    }

    /// The source mixture id `id` belongs to.
    fn source_of(&self, id: u64) -> usize {
        let after = self.sources.partition_point(|s| s.id_offset <= id);
        after.saturating_sub(1)
    }
}
