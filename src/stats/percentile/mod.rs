//! Exact percentiles with numpy's default ("linear") definition.
//!
//! For sorted values `x[0..n]` the q-th percentile sits at position `p = q/100 * (n-1)`, linearly
//! interpolated between `x[floor(p)]` and `x[floor(p)+1]`. Three ways to get there, one per
//! kind of data, all giving numpy's numbers:
//! - values held in memory: selection ([`percentile`], [`percentiles`]);
//! - a column too large to hold (a build's low-dim values, which live in row stores that may
//!   spill to disk): two counting passes over it (`radix`);
//! - `u8` images: a 256-bin histogram, which is exact ([`percentile_of_histogram`]).

mod radix;

pub use radix::{percentiles_counted, percentiles_streamed, HighCounts, SecondPass};

/// Which value of the sorted data a percentile is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Definition {
    /// numpy's default: interpolated at `q/100 * (n-1)`.
    #[default]
    Linear,
    /// The smallest value with at least `q/100 * n` values at or below it (numpy's
    /// `inverted_cdf`): a value of the data, the one openpi's histogram quantiles approximate by
    /// the left edge of its bin (`RunningStats`: the first bin whose cumulative count reaches
    /// `q * n`).
    InvertedCdf,
}

/// `numpy.percentile(values, q)` for an unsorted slice (reorders it).
pub fn percentile(values: &mut [f32], q: f64) -> f64 {
    assert!(!values.is_empty(), "percentile of no values");
    let (lo, frac) = position(values.len() as u64, q, Definition::Linear);
    let cmp = |a: &f32, b: &f32| a.total_cmp(b);
    let (_, &mut a, upper) = values.select_nth_unstable_by(lo as usize, cmp);
    if frac == 0.0 || upper.is_empty() {
        return f64::from(a);
    }
    let b = upper.iter().copied().min_by(cmp).unwrap();
    lerp(f64::from(a), f64::from(b), frac)
}

/// `numpy.percentile(values, qs)` for an unsorted slice (reorders it), every percentile at once:
/// the ranks are selected in a divide-and-conquer order (the middle rank first, then each half's
/// ranks only within its half of the slice), so k percentiles cost about `n log k` comparisons
/// instead of `k n`. The result is the same as calling [`percentile`] once per `q`.
pub fn percentiles(values: &mut [f32], qs: &[f64]) -> Vec<f64> {
    assert!(!values.is_empty(), "percentile of no values");
    let n = values.len() as u64;
    // Every rank any percentile reads: floor(p), and floor(p) + 1 when it interpolates.
    let mut ranks: Vec<usize> = Vec::with_capacity(2 * qs.len());
    for &q in qs {
        let (lo, frac) = position(n, q, Definition::Linear);
        ranks.push(lo as usize);
        if frac != 0.0 && lo + 1 < n {
            ranks.push(lo as usize + 1);
        }
    }
    ranks.sort_unstable();
    ranks.dedup();
    select_ranks(values, 0, &ranks);
    qs.iter()
        .map(|&q| {
            let (lo, frac) = position(n, q, Definition::Linear);
            let a = f64::from(values[lo as usize]);
            if frac == 0.0 || lo + 1 >= n {
                a
            } else {
                lerp(a, f64::from(values[lo as usize + 1]), frac)
            }
        })
        .collect()
}
/// Puts the value of every rank in `ranks` (sorted, relative to the whole slice; `offset` is
/// where `values` starts in it) at its sorted position.
fn select_ranks(values: &mut [f32], offset: usize, ranks: &[usize]) {
    if ranks.is_empty() || values.is_empty() {
        return;
    }
    let mid = ranks.len() / 2;
    let k = ranks[mid] - offset;
    let (left, _, right) = values.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    select_ranks(left, offset, &ranks[..mid]);
    select_ranks(right, offset + k + 1, &ranks[mid + 1..]);
}

/// The percentile of the values a 256-bin histogram counts.
pub fn percentile_of_histogram(hist: &[u64; 256], q: f64) -> f64 {
    let n: u64 = hist.iter().sum();
    assert!(n > 0, "percentile of no values");
    let (lo, frac) = position(n, q, Definition::Linear);
    let a = nth_in_histogram(hist, lo);
    if frac == 0.0 || lo + 1 >= n {
        return a;
    }
    lerp(a, nth_in_histogram(hist, lo + 1), frac)
}

fn nth_in_histogram(hist: &[u64; 256], k: u64) -> f64 {
    let mut seen = 0;
    for (value, &c) in hist.iter().enumerate() {
        seen += c;
        if seen > k {
            return value as f64;
        }
    }
    unreachable!("k < total count")
}

fn position(n: u64, q: f64, definition: Definition) -> (u64, f64) {
    if definition == Definition::InvertedCdf {
        let rank = (q / 100.0 * n as f64).ceil().max(1.0) as u64 - 1;
        return (rank.min(n - 1), 0.0);
    }
    let p = q / 100.0 * (n - 1) as f64;
    let lo = p.floor();
    (lo as u64, p - lo)
}

/// numpy's `_lerp`: exact at both ends and monotonic.
fn lerp(a: f64, b: f64, t: f64) -> f64 {
    let diff = b - a;
    if t < 0.5 {
        a + diff * t
    } else {
        b - diff * (1.0 - t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_numpy_linear() {
        // np.percentile([5, 1, 4, 2, 3], [0, 0.1, 50, 99.9, 100])
        let mut v = [5.0f32, 1.0, 4.0, 2.0, 3.0];
        let want = [1.0, 1.004, 3.0, 4.996, 5.0];
        for (q, w) in [0.0, 0.1, 50.0, 99.9, 100.0].iter().zip(want) {
            assert!((percentile(&mut v, *q) - w).abs() < 1e-12, "q={q}");
        }
    }

    #[test]
    fn all_at_once_equals_one_by_one() {
        for n in [1usize, 2, 3, 7, 100, 1001] {
            let values: Vec<f32> = (0..n as u32)
                .map(|i| ((i * 7919) % 1009) as f32 * 0.37 - 50.0)
                .collect();
            let qs = [0.1, 1.0, 10.0, 50.0, 90.0, 99.0, 99.9, 0.0, 100.0];
            let mut a = values.clone();
            let all = percentiles(&mut a, &qs);
            for (q, got) in qs.iter().zip(all) {
                let mut b = values.clone();
                assert_eq!(got, percentile(&mut b, *q), "n={n} q={q}");
            }
        }
    }

    #[test]
    fn histogram_agrees_with_values() {
        let values: Vec<u8> = (0..1000u32).map(|i| ((i * 7919) % 251) as u8).collect();
        let mut hist = [0u64; 256];
        for &v in &values {
            hist[v as usize] += 1;
        }
        let mut as_f32: Vec<f32> = values.iter().map(|&v| f32::from(v)).collect();
        for q in [0.1, 25.0, 50.0, 99.9] {
            let a = percentile_of_histogram(&hist, q);
            let b = percentile(&mut as_f32, q);
            assert!((a - b).abs() < 1e-12, "q={q}: {a} vs {b}");
        }
    }
}
