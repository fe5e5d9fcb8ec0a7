//! A training mixture in the plan: the split, per source and seeded by each source's own ids (so
//! a source splits as it would alone), and the probabilities the loader's sampler draws each
//! source with (`[mixture] balance`).

use super::{split, ProfilePlan, Split};
use crate::error::Result;
use crate::source::{Manifest, SourcePart};
use crate::spec::{Balance, LoadedSpec, SplitFrom};

/// Each source's episodes split on their own ids (`[split] from = "source"`: the split the
/// source stores), in mixture ids.
pub(super) fn split(spec: &LoadedSpec, manifest: &Manifest) -> Result<Split> {
    let mut joined = Split {
        train: Vec::new(),
        val: Vec::new(),
    };
    for (s, part) in manifest.parts.iter().enumerate() {
        let local: Vec<u64> = manifest
            .episodes
            .iter()
            .filter(|e| manifest.source_of(e.id) == s)
            .map(|e| e.id - part.id_offset)
            .collect();
        let own = match (spec.spec.split.from, &part.source_split) {
            (SplitFrom::Source, Some(stored)) => Split {
                train: local
                    .iter()
                    .copied()
                    .filter(|id| stored.train.contains(id))
                    .collect(),
                val: local
                    .iter()
                    .copied()
                    .filter(|id| !stored.train.contains(id))
                    .collect(),
            },
            _ => split::split(&local, spec.spec.split.val_fraction, spec.spec.split.seed),
        };
        if own.train.is_empty() {
            return Err(spec.error_at(
                &["split", "val_fraction"],
                format!(
                    "this leaves source `{}` no training episode ({} episodes, {} for validation)",
                    part.name,
                    local.len(),
                    own.val.len()
                ),
                None,
            ));
        }
        joined
            .train
            .extend(own.train.iter().map(|id| id + part.id_offset));
        joined
            .val
            .extend(own.val.iter().map(|id| id + part.id_offset));
    }
    Ok(joined)
}

/// The source format the plan names: the source's, or `mixture`.
pub(super) fn format_name(manifest: &Manifest) -> &'static str {
    match manifest.parts.is_empty() {
        true => manifest.format.name(),
        false => "mixture",
    }
}

/// Each source's windows in one split of a profile (`train`: the training split).
pub fn windows(p: &ProfilePlan, manifest_parts: &[SourcePart], train: bool) -> Vec<usize> {
    let mut out = vec![0; manifest_parts.len()];
    let want = if train { "train" } else { "val" };
    for e in p.episodes.iter().filter(|e| e.split == want) {
        out[SourcePart::index_of(manifest_parts, e.id)] += e.samples.unwrap_or(0);
    }
    out
}

/// The probability of drawing each source, from its `weights` and its `windows` in the split:
/// `weights`: w / Σw; `steps`: w·n / Σ w·n (Octo's `balance_weights`); `uniform`: equal. A source
/// without windows, or without weight, is never drawn; the others share what it leaves.
pub fn balanced(balance: Balance, weights: &[f64], windows: &[usize]) -> Vec<f64> {
    let raw: Vec<f64> = weights
        .iter()
        .zip(windows)
        .map(|(&w, &n)| match (n, balance) {
            (0, _) => 0.0,
            (_, Balance::Weights) => w,
            (_, Balance::Steps) => w * n as f64,
            (_, Balance::Uniform) => f64::from(u8::from(w > 0.0)),
        })
        .collect();
    let total: f64 = raw.iter().sum();
    if total == 0.0 {
        return vec![0.0; raw.len()];
    }
    raw.iter().map(|r| r / total).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn balance_modes() {
        let w = [0.7, 0.3, 1.0];
        let n = [100, 300, 0];
        assert_eq!(balanced(Balance::Weights, &w, &n), vec![0.7, 0.3, 0.0]);
        let steps = balanced(Balance::Steps, &w, &n);
        assert!((steps[0] - 70.0 / 160.0).abs() < 1e-15);
        assert!((steps[1] - 90.0 / 160.0).abs() < 1e-15);
        assert_eq!(balanced(Balance::Uniform, &w, &n), vec![0.5, 0.5, 0.0]);
        assert_eq!(
            balanced(Balance::Uniform, &[0.0, 1.0], &[5, 5]),
            vec![0.0, 1.0]
        );
    }
}
