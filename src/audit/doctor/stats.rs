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

/// The median absolute deviation of single-precision values, none of them NaN ([`mad_sigma`]
/// without its 1.4826): what every episode's step sigmas are made of. The selections run on
/// integer keys (the same order as the values) in `keys`, a buffer reused across calls.
#[inline(always)]
pub fn mad_f32(values: &[f32], keys: &mut Vec<u32>) -> f32 {
    if values.is_empty() {
        return f32::NAN;
    }
    keys.clear();
    keys.extend(values.iter().map(|&v| key(v)));
    let m = median_of_keys(keys);
    keys.clear();
    keys.extend(values.iter().map(|&v| key((f64::from(v) - m).abs() as f32)));
    median_of_keys(keys) as f32
}

/// An integer whose order is the order of the (not NaN) `f32` `x`.
fn key(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// The `f32` of a [`key`].
fn value_of(k: u32) -> f32 {
    f32::from_bits(if k >> 31 == 1 { k & 0x7fff_ffff } else { !k })
}

/// The median of the values whose [`key`]s are `keys` (not empty; reordered), as [`median`].
fn median_of_keys(keys: &mut [u32]) -> f64 {
    let n = keys.len();
    let (below, &mut upper, _) = keys.select_nth_unstable(n / 2);
    let upper = f64::from(value_of(upper));
    if n % 2 == 1 {
        upper
    } else {
        let lower = below
            .iter()
            .copied()
            .max()
            .map_or(upper, |k| f64::from(value_of(k)));
        0.5 * (lower + upper)
    }
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
        // The single-precision MAD is the double-precision one's, rounded.
        let w: Vec<f32> = (0..101)
            .map(|i| ((i * 37) % 101) as f32 * 0.1 - 3.0)
            .collect();
        let wide: Vec<f64> = w.iter().map(|&x| f64::from(x)).collect();
        let mad = mad_sigma(&wide) / 1.4826;
        let mut keys = Vec::new();
        assert!((f64::from(mad_f32(&w, &mut keys)) - mad).abs() < 1e-6);
        assert!(
            (f64::from(mad_f32(&w[..100], &mut keys)) - mad_sigma(&wide[..100]) / 1.4826).abs()
                < 1e-6
        );
        assert_eq!(key(-1.0) < key(-0.5), key(-0.5) < key(0.0));
        assert_eq!(value_of(key(-2.5)), -2.5);
    }
}
