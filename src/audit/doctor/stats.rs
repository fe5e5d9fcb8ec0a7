//! Robust statistics the checks share: medians and MAD-based standard deviations, so that the
//! faulty episodes a check looks for do not move the reference they are measured against.

/// The median (mean of the middle two for an even count); NaN when empty. Ignores NaNs.
pub fn median(values: impl IntoIterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = values.into_iter().filter(|x| !x.is_nan()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    // Selection, not a sort: the same order statistics in linear time.
    let n = v.len();
    let (below, &mut upper, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    if n % 2 == 1 {
        upper
    } else {
        let lower = below
            .iter()
            .copied()
            .max_by(f64::total_cmp)
            .unwrap_or(upper);
        0.5 * (lower + upper)
    }
}

/// 1.4826 × the median absolute deviation: the standard deviation of normal data, unmoved by a
/// minority of outliers.
pub fn mad_sigma(values: &[f64]) -> f64 {
    let m = median(values.iter().copied());
    1.4826 * median(values.iter().map(|x| (x - m).abs()))
}

/// The most common value; ties go to the smallest.
pub fn mode<T: Ord + Copy>(values: impl IntoIterator<Item = T>) -> Option<T> {
    let mut counts = std::collections::BTreeMap::new();
    for v in values {
        *counts.entry(v).or_insert(0u64) += 1;
    }
    let best = counts.values().copied().max()?;
    counts.into_iter().find(|(_, c)| *c == best).map(|(v, _)| v)
}

/// The lowest and highest of `(min, max)` pairs.
pub fn range(pairs: impl Iterator<Item = (f64, f64)>) -> (f64, f64) {
    pairs.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (a, b)| {
        (lo.min(a), hi.max(b))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn robust_against_outliers() {
        assert_eq!(median([3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median([4.0, 1.0, 2.0, 3.0]), 2.5);
        let mut v: Vec<f64> = (0..100).map(|i| (i % 10) as f64).collect();
        let clean = mad_sigma(&v);
        v[0] = 1e9;
        assert!((mad_sigma(&v) - clean).abs() < 1.5);
        assert_eq!(mode([3, 1, 3, 1, 2]), Some(1));
    }
}
