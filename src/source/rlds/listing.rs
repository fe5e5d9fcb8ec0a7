//! The episodes of an RLDS dataset assembled from the scanned shards, in shard order (an
//! episode's id is its position): where each is stored, its task and split, and the warnings
//! about them all.

use std::collections::BTreeMap;

use super::features::Feature;
use super::scan::Scanned;
use super::tfrecord::Record;
use super::Shard;
use crate::error::{Error, Result};
use crate::source::mapping::KeyInfo;
use crate::source::EpisodeInfo;

/// Where one episode is stored.
#[derive(Debug, Clone, Copy)]
pub(super) struct Place {
    pub(super) shard: usize,
    /// Record number within the shard.
    pub(super) record: usize,
    pub(super) at: Record,
}

/// The episodes, in shard order (an episode's id is its position), where each is stored, its
/// task and split, and what the warnings count.
#[derive(Default)]
pub(super) struct Listed {
    pub(super) episodes: Vec<EpisodeInfo>,
    pub(super) places: Vec<Place>,
    pub(super) tasks: Vec<Option<String>>,
    pub(super) train: Vec<u64>,
    pub(super) val: Vec<u64>,
    /// Per marker problem: the episodes that have it, and the first.
    markers: BTreeMap<&'static str, (usize, u64)>,
    /// Episodes whose language instruction changes.
    varying: Vec<u64>,
    /// Splits that are neither train nor val/test.
    other_splits: Vec<String>,
}

impl Listed {
    /// The episodes of the shards (`scanned`: each shard's records), each ragged channel
    /// checked to keep its row length.
    pub(super) fn assemble(
        scanned: &[(Vec<Record>, Vec<Scanned>)],
        shards: &[Shard],
        read: &BTreeMap<String, Feature>,
        keys: &[KeyInfo],
    ) -> Result<Listed> {
        let mut l = Listed::default();
        for (s, ((records, eps), shard)) in scanned.iter().zip(shards).enumerate() {
            let role = split_role(&shard.split);
            if role.is_none() && !l.other_splits.contains(&shard.split) {
                l.other_splits.push(shard.split.clone());
            }
            for (r, (record, ep)) in records.iter().zip(eps).enumerate() {
                let id = l.episodes.len() as u64;
                let place = format!("{}: record {r} (episode {id})", shard.shown);
                if ep.len == 0 {
                    return Err(Error::source(format!("{place} has no steps")));
                }
                ep.check_ragged(read, keys, &place)?;
                let at = Place {
                    shard: s,
                    record: r,
                    at: *record,
                };
                l.add(id, at, ep, role.unwrap_or(true));
            }
        }
        Ok(l)
    }

    /// Episode `id`, stored `at`, in training (`train`) or validation.
    fn add(&mut self, id: u64, at: Place, ep: &Scanned, train: bool) {
        self.episodes.push(EpisodeInfo { id, len: ep.len });
        self.places.push(at);
        self.tasks.push(ep.task.clone());
        if train {
            self.train.push(id);
        } else {
            self.val.push(id);
        }
        for m in &ep.markers {
            let e = self.markers.entry(m).or_insert((0, id));
            e.0 += 1;
        }
        if ep.task_varies {
            self.varying.push(id);
        }
    }

    /// What the manifest's warnings say of the episodes: markers, varying tasks, other splits.
    pub(super) fn warnings(&self) -> Vec<String> {
        let n = self.episodes.len();
        let mut out = Vec::new();
        for (what, (count, first)) in &self.markers {
            out.push(format!(
                "{what} in {count} of {n} episodes (first: episode {first}); RLDS markers are only reported, never used"
            ));
        }
        if let Some(first) = self.varying.first() {
            out.push(format!(
                "the language instruction changes within {} episodes (first: episode {first}); each episode's task is its first step's",
                self.varying.len()
            ));
        }
        if !self.other_splits.is_empty() {
            out.push(format!(
                "TFDS splits {} are neither train nor val/test; `[split] from = \"source\"` counts them as training",
                self.other_splits.join(", ")
            ));
        }
        out
    }
}

/// The task of a TFDS split in chunkc's terms: `Some(true)` training, `Some(false)` validation.
fn split_role(name: &str) -> Option<bool> {
    match name {
        "train" => Some(true),
        "val" | "validation" | "test" => Some(false),
        _ => None,
    }
}
