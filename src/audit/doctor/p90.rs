//! The 90th percentile of a column's per-step statistic (the doctor's motion and return
//! scales, the clipped check's entry step): non-negative finite values as their bits, whose
//! integer order is their order, selected in place.

/// The 90th percentile (the lower of the two nearest ranks) of non-negative finite values given
/// as their bits (whose integer order is their order); NaN when there are fewer than `least`.
#[inline(always)]
pub fn p90_of_bits(bits: &mut [u32], least: usize) -> f32 {
    let m = bits.len();
    if m < least.max(1) {
        return f32::NAN;
    }
    let k = (9 * (m - 1)) / 10;
    f32::from_bits(*bits.select_nth_unstable(k).1)
}

/// The 90th percentile of `keys` ([`p90_of_bits`], NaN under `least` values), where
/// `skipped` of the keys are 0 placeholders for values left out and `zeros` more are 0 values
/// counted: those keys are the smallest, so the percentile's rank among the values counted is
/// its rank among all keys past the placeholders.
#[inline(always)]
pub fn p90_skipping(keys: &mut [u32], skipped: usize, zeros: usize, least: usize) -> f32 {
    let m = keys.len() - skipped;
    if m < least.max(1) {
        return f32::NAN;
    }
    let k = (9 * (m - 1)) / 10;
    if k < zeros {
        return 0.0;
    }
    f32::from_bits(*keys.select_nth_unstable(k + skipped).1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The percentile over keys with placeholders equals the lower-rank 90th percentile of the
    /// values kept and the zeros counted, sorted out in full.
    #[test]
    fn placeholders_are_skipped_by_rank() {
        let mut r = 3u64;
        let mut next = move || {
            r = r
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            r >> 33
        };
        for case in 0..400 {
            let n = case % 60;
            // 0: left out, 1: a zero counted, else a value kept.
            let kinds: Vec<u64> = (0..n).map(|_| next() % 4).collect();
            let values: Vec<f32> = (0..n).map(|_| (next() % 50 + 1) as f32 * 0.25).collect();
            let mut keys: Vec<u32> = kinds
                .iter()
                .zip(&values)
                .map(|(&k, &v)| if k >= 2 { v.to_bits() } else { 0 })
                .collect();
            let skipped = kinds.iter().filter(|&&k| k == 0).count();
            let zeros = kinds.iter().filter(|&&k| k == 1).count();
            let mut counted: Vec<f32> = kinds
                .iter()
                .zip(&values)
                .filter(|(&k, _)| k != 0)
                .map(|(&k, &v)| if k == 1 { 0.0 } else { v })
                .collect();
            counted.sort_by(f32::total_cmp);
            let want = if counted.len() < 4 {
                f32::NAN
            } else {
                counted[9 * (counted.len() - 1) / 10]
            };
            let got = p90_skipping(&mut keys, skipped, zeros, 4);
            assert_eq!(got.to_bits(), want.to_bits(), "{kinds:?} {values:?}");
        }
    }
}
