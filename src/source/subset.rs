//! `[source] episodes = […]`: some episodes of any source, in the source's order.

use super::{DecodeCounts, Episode, Manifest, Source};
use crate::error::Result;
use crate::spec::LoadedSpec;

pub struct Subset {
    inner: Box<dyn Source>,
    manifest: Manifest,
    /// Positions in the inner source's episode list.
    positions: Vec<usize>,
}

impl Subset {
    pub fn new(spec: &LoadedSpec, mut inner: Box<dyn Source>, ids: &[u64]) -> Result<Self> {
        let all = &inner.manifest().episodes;
        if let Some(id) = ids.iter().find(|id| !all.iter().any(|e| e.id == **id)) {
            let shown: Vec<String> = all.iter().take(20).map(|e| e.id.to_string()).collect();
            let more = if all.len() > 20 { ", …" } else { "" };
            return Err(spec.error_at(
                &["source", "episodes"],
                format!(
                    "episode {id} is not in the source, which has ids {}{more}",
                    shown.join(", ")
                ),
                None,
            ));
        }
        let positions: Vec<usize> = (0..all.len())
            .filter(|&i| ids.contains(&all[i].id))
            .collect();
        let mut manifest = inner.manifest().clone();
        manifest.episodes = positions.iter().map(|&i| all[i].clone()).collect();
        inner.only_reading(&positions);
        manifest.tasks.retain(|id, _| ids.contains(id));
        if let Some(split) = manifest.source_split.as_mut() {
            split.train.retain(|id| ids.contains(id));
            split.val.retain(|id| ids.contains(id));
        }
        Ok(Subset {
            inner,
            manifest,
            positions,
        })
    }
}

impl Subset {
    /// Every episode of `inner` except those in `excluded` (ids).
    pub fn without(mut inner: Box<dyn Source>, excluded: &[u64]) -> Self {
        let all = &inner.manifest().episodes;
        let positions: Vec<usize> = (0..all.len())
            .filter(|&i| !excluded.contains(&all[i].id))
            .collect();
        let mut manifest = inner.manifest().clone();
        manifest.episodes = positions.iter().map(|&i| all[i].clone()).collect();
        inner.only_reading(&positions);
        manifest.tasks.retain(|id, _| !excluded.contains(id));
        if let Some(split) = manifest.source_split.as_mut() {
            split.train.retain(|id| !excluded.contains(id));
            split.val.retain(|id| !excluded.contains(id));
        }
        Subset {
            inner,
            manifest,
            positions,
        }
    }
}

impl Source for Subset {
    fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn read_episode(&self, index: usize) -> Result<Episode> {
        self.inner.read_episode(self.positions[index])
    }

    fn read_timestamps(&self, index: usize) -> Result<Option<Vec<f64>>> {
        self.inner.read_timestamps(self.positions[index])
    }

    fn read_lowdim(&self, index: usize, channels: &[usize]) -> Result<Vec<Vec<f32>>> {
        self.inner.read_lowdim(self.positions[index], channels)
    }

    fn decode_counts(&self) -> DecodeCounts {
        self.inner.decode_counts()
    }

    fn video_checks(&self, index: usize) -> Result<Vec<crate::source::VideoCheck>> {
        self.inner.video_checks(self.positions[index])
    }

    fn prefetch(&self, positions: &[usize]) {
        let inner: Vec<usize> = positions.iter().map(|&i| self.positions[i]).collect();
        self.inner.prefetch(&inner);
    }

    fn only_reading(&mut self, positions: &[usize]) {
        let inner: Vec<usize> = positions.iter().map(|&i| self.positions[i]).collect();
        self.inner.only_reading(&inner);
    }
}
