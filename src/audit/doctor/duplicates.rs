//! Near-duplicate episodes: the same demonstration stored twice (a re-export, a copy-paste of a
//! recording session), which weighs it double and leaks it across the train/val split.
//!
//! Each episode's action is resampled at [`POINTS`] evenly spaced steps per dimension and divided
//! by the dimension's typical spread (the median over episodes of the per-episode standard
//! deviation). Two episodes of lengths within 5% are near-duplicates when the RMS difference of
//! these signatures is below `duplicate_tolerance`. Sorting by the signatures' means bounds the
//! comparisons (the means of two signatures differ by at most their RMS difference); the later
//! episode of a pair, in source order, is the one flagged.

pub const POINTS: usize = 32;

/// The resampled action of one `(n, width)` episode, `POINTS × width` values.
pub fn signature(a: &[f64], n: usize, width: usize) -> Vec<f64> {
    let mut out = Vec::with_capacity(POINTS * width);
    for p in 0..POINTS {
        let pos = if n > 1 {
            p as f64 * (n - 1) as f64 / (POINTS - 1) as f64
        } else {
            0.0
        };
        let (lo, frac) = (pos.floor() as usize, pos - pos.floor());
        let hi = (lo + 1).min(n.saturating_sub(1));
        for d in 0..width {
            out.push(a[lo * width + d] * (1.0 - frac) + a[hi * width + d] * frac);
        }
    }
    out
}

/// Pairs `(earlier, later, rms)` of positions whose signatures (already divided by the spreads)
/// are within `tolerance`; each later episode appears once, with its closest earlier match.
pub fn pairs(
    signatures: &[Vec<f64>],
    lengths: &[usize],
    tolerance: f64,
) -> Vec<(usize, usize, f64)> {
    let keys: Vec<f64> = signatures
        .iter()
        .map(|s| s.iter().sum::<f64>() / s.len().max(1) as f64)
        .collect();
    let key = |s: usize| keys[s];
    let mut order: Vec<usize> = (0..signatures.len()).collect();
    order.sort_by(|&i, &j| key(i).total_cmp(&key(j)).then(i.cmp(&j)));
    let mut best: std::collections::BTreeMap<usize, (usize, f64)> = Default::default();
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if key(j) - key(i) > tolerance {
                break;
            }
            let (li, lj) = (lengths[i] as f64, lengths[j] as f64);
            if (li - lj).abs() > 0.05 * li.max(lj) || signatures[i].len() != signatures[j].len() {
                continue;
            }
            let n = signatures[i].len().max(1) as f64;
            let rms = (signatures[i]
                .iter()
                .zip(&signatures[j])
                .map(|(p, q)| (p - q) * (p - q))
                .sum::<f64>()
                / n)
                .sqrt();
            if rms < tolerance {
                let (early, late) = (i.min(j), i.max(j));
                let e = best.entry(late).or_insert((early, rms));
                if rms < e.1 || (rms == e.1 && early < e.0) {
                    *e = (early, rms);
                }
            }
        }
    }
    best.into_iter()
        .map(|(late, (early, rms))| (early, late, rms))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_copy_not_the_neighbours() {
        let ep = |phase: f64| {
            signature(
                &(0..50)
                    .map(|t| (t as f64 * 0.1 + phase).sin())
                    .collect::<Vec<_>>(),
                50,
                1,
            )
        };
        let sigs = vec![ep(0.0), ep(1.0), ep(0.0001), ep(2.0)];
        assert_eq!(
            pairs(&sigs, &[50; 4], 0.01)
                .iter()
                .map(|p| (p.0, p.1))
                .collect::<Vec<_>>(),
            vec![(0, 2)]
        );
    }
}
