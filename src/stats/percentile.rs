//! Exact percentiles with numpy's default ("linear") definition.
//!
//! For sorted values `x[0..n]` the q-th percentile sits at position `p = q/100 * (n-1)`, linearly
//! interpolated between `x[floor(p)]` and `x[floor(p)+1]`. Low-dimensional channels keep all
//! training values (they fit in memory); `u8` images use a 256-bin histogram, which is exact.

/// `numpy.percentile(values, q)` for an unsorted slice (reorders it).
pub fn percentile(values: &mut [f32], q: f64) -> f64 {
    assert!(!values.is_empty(), "percentile of no values");
    let (lo, frac) = position(values.len() as u64, q);
    let cmp = |a: &f32, b: &f32| a.total_cmp(b);
    let (_, &mut a, upper) = values.select_nth_unstable_by(lo as usize, cmp);
    if frac == 0.0 || upper.is_empty() {
        return f64::from(a);
    }
    let b = upper.iter().copied().min_by(cmp).unwrap();
    lerp(f64::from(a), f64::from(b), frac)
}

/// The percentile of the values a 256-bin histogram counts.
pub fn percentile_of_histogram(hist: &[u64; 256], q: f64) -> f64 {
    let n: u64 = hist.iter().sum();
    assert!(n > 0, "percentile of no values");
    let (lo, frac) = position(n, q);
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

fn position(n: u64, q: f64) -> (u64, f64) {
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
