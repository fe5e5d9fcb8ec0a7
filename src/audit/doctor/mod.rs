//! The dataset doctor: checks of the action and state values that catch what silently ruins a
//! policy (a frozen or clipped actuator, spikes, actions misaligned with the observations or in
//! another convention or units than the rest, duplicated episodes, shift across the recording,
//! episodes shorter than a chunk), run by `chunkc audit`, `plan` and `check`, and inside every
//! `build`'s one read.
//!
//! Each episode's action and state reduce to features of a fixed size ([`Features`]), in
//! parallel: `build` computes them from the values it reads anyway (as it reads each episode,
//! [`Probe::features`], or from its row store beside the writes, [`Probe::reduce`]); `audit`,
//! `plan` and `check` read the two channels in a pass of their own ([`run`]). The judgement
//! ([`judge`]) then runs over all features in source order, so the result depends neither on the
//! thread count nor on the pass. Precision first: an episode's convention and units are judged
//! before anything else ([`convention`]), every other check measures against robust dataset-wide
//! references (medians, MADs), and so one fault does not set off another check.
//!
//! - `features`: what one episode reduces to (read once, in parallel).
//! - `judge`: every check over the features, one function each; the findings into the report
//!   (`found`); `judge_signal`: the signal checks' judgement; `warnings`: the dataset-wide
//!   warnings, one line per kind.
//! - `stats`: medians, MAD, mode.
//! - `signal`: frozen, clipped, jump (and the constant dimensions); `spikes`: jump's search;
//!   `p90`: the percentiles their scales take.
//! - `columns`: an episode's channel by column, and the sums the features share.
//! - `alignment`: the per-episode lag fits; `lanes`: their inner loop.
//! - `convention`: tracked dimensions, lag mode, conventions, units.
//! - `duplicates`, `shift`, `short`.

mod alignment;
mod columns;
mod convention;
mod duplicates;
mod features;
mod found;
mod judge;
mod judge_signal;
mod lanes;
mod p90;
mod returns;
mod shift;
mod short;
mod signal;
mod spikes;
mod stats;
mod warnings;

use rayon::prelude::*;

use super::report::AuditReport;
use super::timing::Repair;
pub use crate::audit::report::{DoctorSummary, Finding, ShiftDim};
use crate::error::Result;
use crate::source::{ChannelData, ChannelKind, Episode, Manifest, Source};
use crate::spec::LoadedSpec;
use features::features;
pub use features::Features;

/// `misaligned` needs the dataset's lag to leave at least this many times the unexplained share
/// of the episode's own lag.
pub const MISALIGNED_GAIN: f64 = 2.0;

/// A dimension unchanged from step to step in this share of an episode's steps holds still.
pub const STUCK_UNCHANGED: f64 = 0.8;

/// What the doctor reads of every episode: the positions and widths of the `action` and
/// `observation.state` channels. None when `[audit.doctor] enabled = false`, or the source has
/// no low-dimensional `action` channel (or no episodes).
#[derive(Debug, Clone)]
pub struct Probe {
    action: usize,
    state: Option<usize>,
    a_dim: usize,
    s_dim: usize,
}

impl Probe {
    pub fn of(spec: &LoadedSpec, manifest: &Manifest) -> Option<Probe> {
        let lowdim = |name: &str| {
            manifest
                .channels
                .iter()
                .position(|c| c.name == name && c.kind == ChannelKind::Lowdim)
        };
        let action = lowdim("action")?;
        if !spec.spec.audit.doctor.enabled || manifest.episodes.is_empty() {
            return None;
        }
        let state = lowdim("observation.state");
        let a_dim = manifest.channels[action].width();
        let s_dim = state.map_or(0, |c| manifest.channels[c].width());
        (a_dim > 0).then_some(Probe {
            action,
            state,
            a_dim,
            s_dim,
        })
    }

    /// The channels the doctor reads (manifest positions): the action, then the state.
    fn channels(&self) -> Vec<usize> {
        std::iter::once(self.action).chain(self.state).collect()
    }

    /// The manifest position of the action channel.
    pub fn action_channel(&self) -> usize {
        self.action
    }

    /// The manifest position of the state channel, when the source has one.
    pub fn state_channel(&self) -> Option<usize> {
        self.state
    }

    /// What an episode reduces to, from its action (and state) rows, row-major.
    pub fn reduce(&self, action: &[f32], state: Option<&[f32]>) -> Features {
        let n = action.len() / self.a_dim;
        let shape = features::Shape {
            n,
            a_dim: self.a_dim,
            s_dim: self.s_dim,
        };
        features(action, state, shape)
    }

    /// What an episode the build has read reduces to (its channels in manifest order).
    pub fn features(&self, episode: &Episode) -> Features {
        let lowdim = |c: usize| match &episode.channels[c] {
            ChannelData::Lowdim(v) => &v[..],
            ChannelData::Image(_) => &[],
        };
        self.reduce(lowdim(self.action), self.state.map(lowdim))
    }

    /// Judges the features of the episodes `ids` (in that order) into `report` (see
    /// [`judge::judge`]); returns the ids excluded, with why.
    pub fn judge(
        &self,
        spec: &LoadedSpec,
        fps: f64,
        ids: &[u64],
        feats: &[Features],
        report: &mut AuditReport,
    ) -> Result<Vec<(u64, String)>> {
        let cx = judge::Context {
            spec,
            fps,
            ids,
            a_dim: self.a_dim,
            s_dim: self.s_dim,
            has_state: self.state.is_some(),
        };
        judge::judge(&cx, feats, report)
    }
}

/// Runs the checks in a pass of their own (`chunkc audit`, `plan`, `check`; `build` computes
/// the features as it reads the episodes, see [`Probe::features`]) and adds their flags,
/// findings, verdicts and summary to `report` (and the exclusions to `repairs`). Does nothing
/// without a [`Probe`].
pub fn run(
    spec: &LoadedSpec,
    source: &dyn Source,
    report: &mut AuditReport,
    repairs: &mut [Repair],
) -> Result<()> {
    let manifest = source.manifest();
    let Some(probe) = Probe::of(spec, manifest) else {
        return Ok(());
    };
    let wanted = probe.channels();
    // The episodes the build reads: not those the timing or video audit already excluded, so
    // that `plan`, `audit` and `build` judge the same episodes and count the same.
    let judged: Vec<usize> = (0..manifest.episodes.len())
        .filter(|&k| repairs[k] != Repair::Exclude)
        .collect();
    let feats: Vec<Features> =
        crate::error::in_order(judged.par_iter().map(|&i| -> Result<Features> {
            let data = source.read_lowdim(i, &wanted)?;
            Ok(probe.reduce(&data[0], probe.state.map(|_| &data[1][..])))
        }))?;
    let ids: Vec<u64> = judged.iter().map(|&k| manifest.episodes[k].id).collect();
    let excluded = probe.judge(spec, manifest.fps, &ids, &feats, report)?;
    for (id, _) in excluded {
        if let Some(k) = manifest.episodes.iter().position(|e| e.id == id) {
            repairs[k] = Repair::Exclude;
        }
    }
    Ok(())
}
