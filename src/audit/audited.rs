//! The source as the audit leaves it: excluded episodes gone, every other episode with its
//! repaired length, and `read_episode` applying the repair right after the read, before anything
//! downstream (checks, rate conversion, statistics) sees the episode.

use super::repair;
use super::timing::Repair;
use super::{AuditReport, Flag};
use crate::error::{Error, Result};
use crate::source::{ChannelData, Episode, Manifest, Source, Subset};

pub struct Audited {
    /// The source without the excluded episodes.
    inner: Subset,
    manifest: Manifest,
    /// The repair of each episode of `inner`.
    repairs: Vec<Repair>,
    expected: f64,
}

impl Audited {
    /// `repairs` are in the inner manifest's order. With `apply` false the source is unchanged
    /// (`[audit] repair = false`).
    pub fn new(
        inner: Box<dyn Source>,
        report: &AuditReport,
        repairs: Vec<Repair>,
        apply: bool,
    ) -> Self {
        // Without repairs an episode left out for its video (`[audit] video`) still goes: it
        // cannot be read.
        let repairs = if apply {
            repairs
        } else {
            report
                .episodes
                .iter()
                .map(|e| match e.flags.contains(&Flag::Video) {
                    true => Repair::Exclude,
                    false => Repair::None,
                })
                .collect()
        };
        let excluded: Vec<u64> = inner
            .manifest()
            .episodes
            .iter()
            .zip(&repairs)
            .filter(|(_, repair)| **repair == Repair::Exclude)
            .map(|(info, _)| info.id)
            .collect();
        let repairs: Vec<Repair> = repairs
            .into_iter()
            .filter(|repair| *repair != Repair::Exclude)
            .collect();
        let inner = Subset::without(inner, &excluded);
        let mut manifest = inner.manifest().clone();
        for (info, repair) in manifest.episodes.iter_mut().zip(&repairs) {
            if let Repair::Regrid { steps } | Repair::Resample { steps, .. } = repair {
                info.len = *steps;
            }
        }
        Audited {
            inner,
            manifest,
            repairs,
            expected: report.expected_interval,
        }
    }
}

impl Source for Audited {
    fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn decode_counts(&self) -> crate::source::DecodeCounts {
        self.inner.decode_counts()
    }

    fn only_reading(&mut self, positions: &[usize]) {
        self.inner.only_reading(positions);
    }

    fn prefetch(&self, positions: &[usize]) {
        self.inner.prefetch(positions);
    }

    fn read_episode(&self, index: usize) -> Result<Episode> {
        let repair = &self.repairs[index];
        let episode = self.inner.read_episode(index)?;
        if *repair == Repair::None {
            return Ok(episode);
        }
        // A non-finite value would spread over the whole repaired channel: leave the episode
        // as read, so that the check names the step it is at.
        let non_finite = episode.channels.iter().any(|c| match c {
            ChannelData::Lowdim(v) => v.iter().any(|x| !x.is_finite()),
            ChannelData::Image(_) => false,
        });
        if non_finite {
            return Ok(episode);
        }
        let id = episode.id;
        let repaired = repair::apply(episode, repair, &self.manifest.channels, self.expected);
        if repaired.len != self.manifest.episodes[index].len {
            return Err(Error::Internal(format!(
                "episode {id}: the repair gave {} steps, the audit planned {}",
                repaired.len, self.manifest.episodes[index].len
            )));
        }
        Ok(repaired)
    }
}
