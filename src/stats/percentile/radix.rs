// Long file: one algorithm: the two-pass radix selection and its tests.
//! Exact percentiles of a column read in blocks, twice, in memory independent of its length:
//! the first pass counts values by the high 16 bits of an order-preserving key, the second the
//! low 16 bits within the buckets the needed ranks fall in.

use super::{lerp, position, Definition};

/// `numpy.percentile` of a column too large to hold, read twice: `pass` must call its argument
/// with every value of the column, in blocks, each time it is called (the order does not
/// matter). The first pass counts the values by the high 16 bits of an order-preserving key
/// (the bits of [`f32::total_cmp`]'s order), which tells each needed rank's bucket; the second
/// counts, within those buckets only, the low 16 bits, which gives each rank's exact value.
/// Memory is a few 65,536-entry tables whatever the column's length; the result is the same as
/// [`percentiles`]'s.
pub fn percentiles_streamed<E>(
    n: u64,
    qs: &[f64],
    mut pass: impl FnMut(&mut dyn FnMut(&[f32])) -> Result<(), E>,
) -> Result<Vec<f64>, E> {
    let mut high = HighCounts::new();
    pass(&mut |block| high.add(block))?;
    percentiles_counted(&high, n, qs, pass)
}

/// The first pass of [`percentiles_streamed`], kept by whoever sees the values first (a build's
/// low-dim stores count them as they are pushed), so that [`percentiles_counted`] needs only
/// the second. Counts are `u32` (256 KiB a table), folded into a `u64` table before any could
/// overflow, so any number of values can be counted.
#[derive(Debug, Clone)]
pub struct HighCounts {
    counts: Vec<u32>,
    /// Counts folded out of `counts` (empty until `u32::MAX` values were counted).
    wide: Vec<u64>,
    /// Values counted in `counts` since the last fold.
    pending: u64,
    /// Values `counts` may take before a fold (`u32::MAX`; the tests lower it).
    limit: u64,
    total: u64,
}

impl Default for HighCounts {
    fn default() -> Self {
        Self::new()
    }
}

impl HighCounts {
    pub fn new() -> Self {
        HighCounts {
            counts: vec![0; 1 << 16],
            wide: Vec::new(),
            pending: 0,
            limit: u64::from(u32::MAX),
            total: 0,
        }
    }

    /// Counts `values`.
    pub fn add(&mut self, mut values: &[f32]) {
        while !values.is_empty() {
            let room = self.limit - self.pending;
            if room == 0 {
                self.fold();
                continue;
            }
            let (now, rest) = values.split_at(values.len().min(room as usize));
            for &v in now {
                self.counts[(key(v) >> 16) as usize] += 1;
            }
            self.pending += now.len() as u64;
            self.total += now.len() as u64;
            values = rest;
        }
    }

    /// Counts every `stride`-th value of `values` from `first` (one column of row-major rows).
    pub fn add_strided(&mut self, values: &[f32], first: usize, stride: usize) {
        let n = values.len().saturating_sub(first).div_ceil(stride.max(1));
        if self.pending + n as u64 > self.limit {
            let column: Vec<f32> = values.iter().skip(first).step_by(stride).copied().collect();
            return self.add(&column);
        }
        for &v in values.iter().skip(first).step_by(stride.max(1)) {
            self.counts[(key(v) >> 16) as usize] += 1;
        }
        self.pending += n as u64;
        self.total += n as u64;
    }

    /// Counts row-major rows: `highs[d]` counts column `d` of each row of `values`. One pass
    /// over the rows; consecutive increments go to different tables, so none waits for the
    /// previous one's store.
    pub fn add_rows(highs: &mut [HighCounts], values: &[f32]) {
        HighCounts::add_row_starts(highs, values, highs.len());
    }

    /// [`HighCounts::add_rows`] over rows of `width` values of which `highs` count the first
    /// `highs.len()` (a mixture source's own dimensions, before its padding).
    pub fn add_row_starts(highs: &mut [HighCounts], values: &[f32], width: usize) {
        if highs.is_empty() || width == 0 {
            return;
        }
        debug_assert!(highs.len() <= width);
        let rows = values.len() / width;
        if highs.iter().any(|h| h.pending + rows as u64 > h.limit) {
            // Near a fold: column by column, each folding where it must.
            for (d, high) in highs.iter_mut().enumerate() {
                high.add_strided(values, d, width);
            }
            return;
        }
        for row in values.chunks_exact(width) {
            for (high, &v) in highs.iter_mut().zip(row) {
                high.counts[(key(v) >> 16) as usize] += 1;
            }
        }
        for high in highs {
            high.pending += rows as u64;
            high.total += rows as u64;
        }
    }

    /// Adds what `other` counted: the first pass over both sets of values (a mixture's pooled
    /// band, from its sources' counts).
    pub fn merge(&mut self, other: &HighCounts) {
        if self.pending + other.pending > self.limit {
            self.fold();
        }
        if !other.wide.is_empty() {
            if self.wide.is_empty() {
                self.wide = vec![0; 1 << 16];
            }
            for (w, o) in self.wide.iter_mut().zip(&other.wide) {
                *w += o;
            }
        }
        for (c, o) in self.counts.iter_mut().zip(&other.counts) {
            *c += o;
        }
        self.pending += other.pending;
        self.total += other.total;
    }

    fn fold(&mut self) {
        if self.wide.is_empty() {
            self.wide = vec![0; 1 << 16];
        }
        for (w, c) in self.wide.iter_mut().zip(self.counts.iter_mut()) {
            *w += u64::from(*c);
            *c = 0;
        }
        self.pending = 0;
    }

    /// Values in bucket `b`.
    fn bucket(&self, b: usize) -> u64 {
        u64::from(self.counts[b]) + self.wide.get(b).copied().unwrap_or(0)
    }

    /// How many values were counted.
    pub fn total(&self) -> u64 {
        self.total
    }
}

/// [`percentiles_streamed`] with its first pass already done: `high` counted the `n` values that
/// `pass` (called once) passes again.
pub fn percentiles_counted<E>(
    high: &HighCounts,
    n: u64,
    qs: &[f64],
    mut pass: impl FnMut(&mut dyn FnMut(&[f32])) -> Result<(), E>,
) -> Result<Vec<f64>, E> {
    let mut second = SecondPass::new(high, n, qs);
    pass(&mut |block| second.add(block))?;
    Ok(second.finish())
}

/// The second pass of [`percentiles_streamed`] as a value: fed every value again (in any order
/// and blocks, [`SecondPass::add`] or [`SecondPass::add_strided`]), then [`SecondPass::finish`]
/// gives the percentiles. Lets one read of row-major rows feed every column's second pass.
#[derive(Debug)]
pub struct SecondPass {
    n: u64,
    qs: Vec<f64>,
    definition: Definition,
    /// Each needed rank: (rank, its bucket, its rank within the bucket).
    located: Vec<(u64, usize, u64)>,
    /// The needed buckets, in order.
    buckets: Vec<usize>,
    /// Per bucket (high 16 bits), its position in `buckets`, or `u8::MAX`.
    slot: Vec<u8>,
    low: Vec<Low>,
}

impl SecondPass {
    /// `high` counted the `n` values the pass will be fed.
    pub fn new(high: &HighCounts, n: u64, qs: &[f64]) -> Self {
        SecondPass::with(high, n, qs, Definition::Linear)
    }

    /// [`SecondPass::new`] with another definition of the percentile.
    pub fn with(high: &HighCounts, n: u64, qs: &[f64], definition: Definition) -> Self {
        assert!(n > 0, "percentile of no values");
        assert_eq!(high.total, n, "the first pass counted every value");
        // Each rank's bucket and its rank among the bucket's values.
        let mut ranks: Vec<u64> = Vec::with_capacity(2 * qs.len());
        for &q in qs {
            let (lo, frac) = position(n, q, definition);
            ranks.push(lo);
            if frac != 0.0 && lo + 1 < n {
                ranks.push(lo + 1);
            }
        }
        ranks.sort_unstable();
        ranks.dedup();
        let mut located: Vec<(u64, usize, u64)> = Vec::with_capacity(ranks.len());
        let (mut bucket, mut below) = (0usize, 0u64);
        for &r in &ranks {
            while below + high.bucket(bucket) <= r {
                below += high.bucket(bucket);
                bucket += 1;
            }
            located.push((r, bucket, r - below));
        }
        // The second read keeps, per needed bucket, its values' low 16 bits: as a list when the
        // bucket is small (the usual case: a few values around each percentile), as a table of
        // counts when it is large (values concentrated on a few keys).
        let mut buckets: Vec<usize> = located.iter().map(|&(_, b, _)| b).collect();
        buckets.dedup();
        let mut slot = vec![u8::MAX; 1 << 16];
        let mut low: Vec<Low> = Vec::with_capacity(buckets.len());
        for (i, &b) in buckets.iter().enumerate() {
            slot[b] = i as u8;
            low.push(if high.bucket(b) <= SMALL_BUCKET {
                Low::Keys(Vec::with_capacity(high.bucket(b) as usize))
            } else {
                Low::Counts(vec![0u64; 1 << 16])
            });
        }
        SecondPass {
            n,
            qs: qs.to_vec(),
            definition,
            located,
            buckets,
            slot,
            low,
        }
    }

    #[inline]
    fn add_one(&mut self, v: f32) {
        let k = key(v);
        let s = self.slot[(k >> 16) as usize];
        if s != u8::MAX {
            match &mut self.low[s as usize] {
                Low::Keys(keys) => keys.push(k as u16),
                Low::Counts(counts) => counts[(k & 0xFFFF) as usize] += 1,
            }
        }
    }

    /// Feeds `values`.
    pub fn add(&mut self, values: &[f32]) {
        for &v in values {
            self.add_one(v);
        }
    }

    /// Feeds every `stride`-th value of `values` from `first` (one column of row-major rows).
    pub fn add_strided(&mut self, values: &[f32], first: usize, stride: usize) {
        for &v in values.iter().skip(first).step_by(stride.max(1)) {
            self.add_one(v);
        }
    }

    /// The percentiles of `qs`, in order.
    pub fn finish(mut self) -> Vec<f64> {
        for l in &mut self.low {
            if let Low::Keys(keys) = l {
                keys.sort_unstable();
            }
        }
        let value_at = |rank: u64| -> f64 {
            let &(_, b, within) = self
                .located
                .iter()
                .find(|&&(r, _, _)| r == rank)
                .expect("located");
            let position = self.buckets.iter().position(|&x| x == b).expect("bucket");
            let l = match &self.low[position] {
                Low::Keys(keys) => keys[within as usize],
                Low::Counts(counts) => {
                    let (mut l, mut within) = (0usize, within);
                    while counts[l] <= within {
                        within -= counts[l];
                        l += 1;
                    }
                    l as u16
                }
            };
            f64::from(from_key(((b as u32) << 16) | u32::from(l)))
        };
        let n = self.n;
        self.qs
            .iter()
            .map(|&q| {
                let (lo, frac) = position(n, q, self.definition);
                let a = value_at(lo);
                if frac == 0.0 || lo + 1 >= n {
                    a
                } else {
                    lerp(a, value_at(lo + 1), frac)
                }
            })
            .collect()
    }
}

/// Buckets of at most this many values keep their values' low bits as a list (sorted at the
/// end); larger ones count them in a table.
const SMALL_BUCKET: u64 = 1 << 15;

/// The low 16 bits of the keys of one needed bucket.
#[derive(Debug)]
enum Low {
    Keys(Vec<u16>),
    Counts(Vec<u64>),
}

/// An unsigned key whose order is [`f32::total_cmp`]'s.
fn key(v: f32) -> u32 {
    let b = v.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

fn from_key(k: u32) -> f32 {
    f32::from_bits(if k & 0x8000_0000 != 0 {
        k & 0x7FFF_FFFF
    } else {
        !k
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::percentile::percentiles;

    #[test]
    fn streamed_equals_selection() {
        let qs = [0.1, 99.9, 1.0, 99.0, 10.0, 50.0, 90.0, 0.0, 100.0, 37.5];
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for n in [1usize, 2, 3, 10, 1000, 65_537, 200_000] {
            // Wide-ranging values, repeats, both zeros and infinities: every bucket shape.
            let values: Vec<f32> = (0..n)
                .map(|i| match next() % 10 {
                    0 => 0.0,
                    1 => -0.0,
                    2 => {
                        f32::from_bits(next() as u32 & 0x7F7F_FFFF)
                            * if i % 2 == 0 { 1.0 } else { -1.0 }
                    }
                    3 if i % 97 == 0 => f32::INFINITY,
                    4 if i % 89 == 0 => f32::NEG_INFINITY,
                    5 => 1.5,
                    _ => (next() % 20_000) as f32 * 0.001 - 10.0,
                })
                .collect();
            // And a column mostly of one value (its bucket is counted in a table).
            let heavy: Vec<f32> = values
                .iter()
                .enumerate()
                .map(|(i, &v)| if i % 5 == 0 { v } else { 2.5 })
                .collect();
            check(&values, &qs);
            check(&heavy, &qs);
        }
        for v in [0.0f32, -0.0, 1.0, -1.0, f32::MIN, f32::MAX, f32::INFINITY] {
            assert_eq!(from_key(key(v)).to_bits(), v.to_bits());
        }
    }

    /// `percentiles_streamed` against the selection, bit for bit, whatever the block size.
    fn check(values: &[f32], qs: &[f64]) {
        let n = values.len();
        let want = percentiles(&mut values.to_vec(), qs);
        // The first pass counted ahead: whole blocks, and as the second column of two-wide
        // rows; a low fold limit makes the u32 counts fold into the u64 table many times.
        for limit in [u64::from(u32::MAX), 5] {
            let mut whole = HighCounts::new();
            whole.limit = limit;
            values.chunks(13).for_each(|b| whole.add(b));
            let rows: Vec<f32> = values.iter().flat_map(|&v| [f32::NAN, v]).collect();
            let mut pair = [HighCounts::new(), HighCounts::new()];
            pair[1].limit = limit;
            rows.chunks(2 * 11)
                .for_each(|b| HighCounts::add_rows(&mut pair, b));
            let [_, strided] = pair;
            // Counted in two parts, the second as the first of three-wide rows, then merged.
            let half = n / 2;
            let mut merged = HighCounts::new();
            merged.limit = limit;
            merged.add(&values[..half]);
            let wide: Vec<f32> = values[half..]
                .iter()
                .flat_map(|&v| [v, f32::NAN, 0.0])
                .collect();
            let mut part = [HighCounts::new()];
            part[0].limit = limit;
            HighCounts::add_row_starts(&mut part, &wide, 3);
            merged.merge(&part[0]);
            for high in [&whole, &strided, &merged] {
                assert_eq!(high.total(), n as u64);
                let got = percentiles_counted::<()>(high, n as u64, qs, |f| {
                    values.chunks(64).for_each(&mut *f);
                    Ok(())
                })
                .unwrap();
                let same = want
                    .iter()
                    .zip(&got)
                    .all(|(w, g)| w.to_bits() == g.to_bits());
                assert!(same, "n={n} limit={limit}: {want:?} vs {got:?}");
            }
        }
        for block in [1usize, 7, 4096] {
            let got = percentiles_streamed::<()>(n as u64, qs, |f| {
                values.chunks(block).for_each(&mut *f);
                Ok(())
            })
            .unwrap();
            for ((q, w), g) in qs.iter().zip(&want).zip(&got) {
                assert_eq!(
                    w.to_bits(),
                    g.to_bits(),
                    "n={n} block={block} q={q}: {w} vs {g}"
                );
            }
        }
    }
}

#[cfg(test)]
mod inverted_cdf {
    use super::*;

    /// numpy's `inverted_cdf`: the smallest value with at least `q n / 100` values at or below.
    #[test]
    fn is_the_order_statistic_numpy_names() {
        let values: Vec<f32> = (1..=10).rev().map(|v| v as f32).collect();
        let mut high = HighCounts::new();
        high.add(&values);
        let mut second =
            SecondPass::with(&high, 10, &[1.0, 50.0, 55.0, 99.0], Definition::InvertedCdf);
        second.add(&values);
        assert_eq!(second.finish(), [1.0, 5.0, 6.0, 10.0]);
    }
}
