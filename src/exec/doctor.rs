//! The dataset doctor folded into the build's one pass: each episode reduces to its doctor
//! features (in parallel, from the values already decoded, never read again from the source),
//! the features are kept (a fixed size per episode, never the steps), and once every episode is
//! reduced the judgement runs over them in source order, before anything is committed.
//!
//! Where a rate keeps the source's own steps, its row store holds the values as read, and the
//! features are computed from it beside the writes ([`Doctor::take_stored`]): the writes leave
//! cores idle, the pass does not. Otherwise each episode is reduced as the pass reads it
//! ([`Doctor::take`]). A training mixture's sources' doctor does the same per source: a source
//! whose steps the mixture's rate keeps is reduced from the stores, the others as read.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;
use std::time::Instant;

use rayon::prelude::*;

use super::rate::RateState;
use super::Excluded;
use crate::audit::doctor::{Features, Probe};
use crate::audit::sources_doctor::SourcesDoctor;
use crate::error::Result;
use crate::source::Episode;

/// The judgement: the features of every episode the pass read (in its order) to the episodes
/// the doctor excludes.
pub type Judge<'a> = Box<dyn FnMut(&[Features]) -> Result<Excluded> + Send + Sync + 'a>;

/// The doctor riding on a pass: what it reads, the features gathered, and the judgement.
pub struct Doctor<'a> {
    /// `None`: the source reduces its episodes itself as they are read (a training mixture's
    /// sources, each at its own rate; see `audit::sources_doctor`).
    probe: Option<&'a Probe>,
    judge: Judge<'a>,
    slots: Vec<OnceLock<Features>>,
    /// Nanoseconds spent computing features, over all threads.
    busy: AtomicU64,
    /// A training mixture's sources' doctor, which reduces the episodes itself.
    elsewhere: Option<&'a SourcesDoctor>,
    /// The doctor's wall seconds, once judged.
    seconds: Option<f64>,
}

impl<'a> Doctor<'a> {
    pub fn new(probe: &'a Probe, episodes: usize, judge: Judge<'a>) -> Self {
        Doctor {
            probe: Some(probe),
            judge,
            slots: (0..episodes).map(|_| OnceLock::new()).collect(),
            busy: AtomicU64::new(0),
            elsewhere: None,
            seconds: None,
        }
    }

    /// A training mixture's doctor: `sources` reduces each episode as the mixture reads it, or
    /// from the stores beside the writes ([`Doctor::take_stored`]); the pass judges.
    pub fn reading_elsewhere(sources: &'a SourcesDoctor, judge: Judge<'a>) -> Self {
        Doctor {
            probe: None,
            judge,
            slots: Vec::new(),
            busy: AtomicU64::new(0),
            elsewhere: Some(sources),
            seconds: None,
        }
    }

    /// Whether some episodes can be reduced from a rate's stored rows ([`Doctor::take_stored`]).
    pub(super) fn takes_stored(&self) -> bool {
        self.probe.is_some() || self.elsewhere.is_some_and(SourcesDoctor::stores_any)
    }

    /// Says, before the pass reads, whether [`Doctor::take_stored`] will run after it.
    pub(super) fn will_take_stored(&self, yes: bool) {
        if let Some(sources) = self.elsewhere {
            sources.from_stores(yes);
        }
    }

    /// The doctor's wall seconds (its share of the pass at the pass's thread count, plus the
    /// judgement), once judged.
    pub fn seconds(&self) -> Option<f64> {
        self.seconds
    }

    /// Reduces episode `i` (manifest position) to its features, once.
    pub(super) fn take(&self, i: usize, episode: &Episode) {
        if let Some(probe) = self.probe {
            self.keep(i, || probe.features(episode));
        }
    }

    /// Reduces every episode to its features from the rows `rate` stored, in parallel: a rate
    /// that keeps the source's own steps stores the values as read, so the features are those
    /// [`Doctor::take`] computes. The build runs this beside its writes.
    pub(super) fn take_stored(&self, rate: &RateState) -> Result<()> {
        let Some(probe) = self.probe else {
            return match self.elsewhere {
                Some(sources) => sources.take_stored(&rate.lowdim, &|i| rate.ends.range(i)),
                None => Ok(()),
            };
        };
        let action = &rate.lowdim[probe.action_channel()];
        let state = probe.state_channel().map(|c| &rate.lowdim[c]);
        (0..self.slots.len()).into_par_iter().try_for_each(|i| {
            let rows = rate.ends.range(i);
            let a = action.rows(rows.start, rows.end)?;
            let s = match state {
                Some(store) => Some(store.rows(rows.start, rows.end)?),
                None => None,
            };
            self.keep(i, || probe.reduce(&a, s.as_deref()));
            Ok(())
        })
    }

    /// Keeps episode `i`'s features, once, counting the time they took.
    fn keep(&self, i: usize, features: impl FnOnce() -> Features) {
        let started = Instant::now();
        // Kept as an exact-size copy: the vectors built alongside the episode's temporaries
        // would pin the heap they were carved from (measured: 418 MiB peak for 5,000 episodes
        // of 400 steps kept as built, 167 MiB as copies).
        let f = features().clone();
        let _ = self.slots[i].set(f);
        let spent = started.elapsed().as_nanos() as u64;
        self.busy.fetch_add(spent, Ordering::Relaxed);
    }

    /// Judges the features once every episode has been read: the episodes excluded.
    pub(super) fn judge(&mut self) -> Result<Excluded> {
        let started = Instant::now();
        let feats: Vec<Features> = std::mem::take(&mut self.slots)
            .into_iter()
            .map(|s| s.into_inner().expect("the pass reduced every episode"))
            .collect();
        let excluded = (self.judge)(&feats)?;
        let threads = rayon::current_num_threads().max(1) as f64;
        let elsewhere = (self.elsewhere).map_or(0, |s| s.busy().load(Ordering::Relaxed));
        let busy = (self.busy.load(Ordering::Relaxed) + elsewhere) as f64 * 1e-9;
        self.seconds = Some(busy / threads + started.elapsed().as_secs_f64());
        Ok(excluded)
    }
}
