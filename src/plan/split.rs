//! The train/validation split: deterministic, keyed by episode id.
//!
//! Each episode gets a key `BLAKE3(seed, id)`; episodes are ranked by key and the
//! `round(val_fraction * n)` lowest go to validation. The rank of two episodes never depends on
//! the others, so adding an episode to a source moves at most one existing episode between sets.

use serde::Serialize;

#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Split {
    /// Source episode ids, ascending.
    pub train: Vec<u64>,
    /// Source episode ids, ascending.
    pub val: Vec<u64>,
}

impl Split {
    pub fn is_train(&self, id: u64) -> bool {
        self.train.binary_search(&id).is_ok()
    }
}

fn key(seed: u64, id: u64) -> [u8; 32] {
    let mut h = blake3::Hasher::new();
    h.update(b"chunkc-split-v1");
    h.update(&seed.to_le_bytes());
    h.update(&id.to_le_bytes());
    *h.finalize().as_bytes()
}

/// Number of validation episodes for `n` episodes.
pub fn val_count(n: usize, val_fraction: f64) -> usize {
    if n == 0 || val_fraction <= 0.0 {
        return 0;
    }
    let k = (val_fraction * n as f64).round() as usize;
    // A positive fraction asks for a validation set: give it at least one episode when that
    // still leaves one to train on.
    k.max(usize::from(n >= 2)).min(n)
}

pub fn split(ids: &[u64], val_fraction: f64, seed: u64) -> Split {
    let mut ranked: Vec<([u8; 32], u64)> = ids.iter().map(|&id| (key(seed, id), id)).collect();
    ranked.sort();
    let n_val = val_count(ids.len(), val_fraction);
    let mut val: Vec<u64> = ranked[..n_val].iter().map(|&(_, id)| id).collect();
    let mut train: Vec<u64> = ranked[n_val..].iter().map(|&(_, id)| id).collect();
    val.sort_unstable();
    train.sort_unstable();
    Split { train, val }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_disjoint() {
        let ids: Vec<u64> = (0..206).collect();
        let s = split(&ids, 0.1, 0);
        assert_eq!(s.val.len(), 21);
        assert_eq!(s.train.len(), 185);
        assert!(s.val.iter().all(|v| !s.is_train(*v)));
    }

    #[test]
    fn adding_an_episode_moves_at_most_one() {
        let ids: Vec<u64> = (0..50).collect();
        let a = split(&ids, 0.2, 7);
        let more: Vec<u64> = (0..51).collect();
        let b = split(&more, 0.2, 7);
        let moved = a.val.iter().filter(|v| !b.val.contains(v)).count();
        assert!(moved <= 1, "{moved} episodes left the validation set");
    }

    #[test]
    fn seed_changes_the_split() {
        let ids: Vec<u64> = (0..100).collect();
        assert_ne!(split(&ids, 0.1, 0).val, split(&ids, 0.1, 1).val);
    }

    #[test]
    fn zero_fraction_keeps_everything_for_training() {
        let s = split(&[3, 1, 2], 0.0, 0);
        assert_eq!((s.train, s.val), (vec![1, 2, 3], vec![]));
    }
}
