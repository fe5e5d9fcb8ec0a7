//! The source as the audit leaves it: excluded episodes gone, every other episode with its
//! repaired length, and `read_episode` applying the repair right after the read, before anything
//! downstream (checks, rate conversion, statistics) sees the episode.

use super::repair;
use super::timing::Repair;
use super::AuditReport;
use crate::error::{Error, Result};
use crate::source::{ChannelData, Episode, Manifest, Source};

pub struct Audited {
    inner: Box<dyn Source>,
    manifest: Manifest,
    /// Positions in the inner source's episode list, and the repair of each.
    positions: Vec<(usize, Repair)>,
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
        let mut manifest = inner.manifest().clone();
        let mut positions = Vec::new();
        let mut episodes = Vec::new();
        let mut excluded = Vec::new();
        for (i, (info, repair)) in manifest.episodes.iter().zip(repairs).enumerate() {
            let repair = if apply { repair } else { Repair::None };
            if repair == Repair::Exclude {
                excluded.push(info.id);
                continue;
            }
            let mut info = info.clone();
            info.len = match &repair {
                Repair::Regrid { steps } | Repair::Resample { steps, .. } => *steps,
                _ => info.len,
            };
            episodes.push(info);
            positions.push((i, repair));
        }
        manifest.episodes = episodes;
        if let Some(split) = manifest.source_split.as_mut() {
            split.train.retain(|id| !excluded.contains(id));
            split.val.retain(|id| !excluded.contains(id));
        }
        Audited {
            inner,
            manifest,
            positions,
            expected: report.expected_interval,
        }
    }
}

impl Source for Audited {
    fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn read_episode(&self, index: usize) -> Result<Episode> {
        let (position, repair) = &self.positions[index];
        let episode = self.inner.read_episode(*position)?;
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
