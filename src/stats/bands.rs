//! Statistics of a channel whose dimensions different populations cover: a padded channel of a
//! training mixture, whose sources have different widths. The dimensions are cut into bands that
//! one set of sources covers whole; each band is reduced over the rows of its sources only (so
//! padding never enters a statistic, and percentiles are exact over that union), and the bands
//! are joined.

use std::ops::Range;

use super::{ChannelStats, Moments};

/// The bands of a channel of `width` dimensions whose sources have `widths` (0: the source lacks
/// it): each `[a, b)` with the sources whose width reaches `b`, in dimension order. Dimensions no
/// source has form a last band with no source.
pub fn bands(widths: &[usize], width: usize) -> Vec<(Range<usize>, Vec<usize>)> {
    let mut cuts: Vec<usize> = widths.iter().copied().filter(|&w| w > 0).collect();
    cuts.push(width);
    cuts.sort_unstable();
    cuts.dedup();
    let mut out = Vec::new();
    let mut start = 0;
    for end in cuts {
        let sources = (0..widths.len()).filter(|&s| widths[s] >= end).collect();
        out.push((start..end, sources));
        start = end;
    }
    out
}

impl Moments {
    /// The moments of dimensions `columns` only.
    pub fn columns(&self, columns: Range<usize>) -> Moments {
        Moments {
            count: self.count,
            mean: self.mean[columns.clone()].to_vec(),
            m2: self.m2[columns.clone()].to_vec(),
            min: self.min[columns.clone()].to_vec(),
            max: self.max[columns].to_vec(),
        }
    }
}

impl ChannelStats {
    /// The statistics of dimensions `columns` only: each dimension's are its own, over the
    /// same rows (a band of a channel that one source covers).
    pub fn columns(&self, columns: Range<usize>) -> ChannelStats {
        let pick = |v: &Vec<f64>| v[columns.clone()].to_vec();
        ChannelStats {
            mean: pick(&self.mean),
            std: pick(&self.std),
            min: pick(&self.min),
            max: pick(&self.max),
            p001: pick(&self.p001),
            p999: pick(&self.p999),
            q01: pick(&self.q01),
            q99: pick(&self.q99),
            q10: pick(&self.q10),
            q50: pick(&self.q50),
            q90: pick(&self.q90),
            count: self.count,
            dim_count: match self.dim_count.is_empty() {
                true => Vec::new(),
                false => self.dim_count[columns.clone()].to_vec(),
            },
            moments: self.moments.columns(columns),
        }
    }
}

/// Statistics of `width` dimensions that no value covers: zeros, counting nothing.
pub fn uncovered(width: usize) -> ChannelStats {
    let zeros = vec![0.0; width];
    let mut moments = Moments::new(width);
    moments.min = zeros.clone();
    moments.max = zeros.clone();
    ChannelStats {
        mean: zeros.clone(),
        std: zeros.clone(),
        min: zeros.clone(),
        max: zeros.clone(),
        p001: zeros.clone(),
        p999: zeros.clone(),
        q01: zeros.clone(),
        q99: zeros.clone(),
        q10: zeros.clone(),
        q50: zeros.clone(),
        q90: zeros,
        count: 0,
        dim_count: Vec::new(),
        moments,
    }
}

/// Bands' statistics joined in dimension order. `count` is the first band's (the rows of every
/// source that has the channel); `dim_count` says each dimension's when they differ.
pub fn concat(parts: Vec<ChannelStats>) -> ChannelStats {
    let mut dim_count = Vec::new();
    for p in &parts {
        dim_count.extend(std::iter::repeat_n(p.count, p.mean.len()));
    }
    let mut parts = parts.into_iter();
    let mut out = parts.next().expect("a channel has a band");
    for p in parts {
        let vectors = [
            (&mut out.mean, p.mean),
            (&mut out.std, p.std),
            (&mut out.min, p.min),
            (&mut out.max, p.max),
            (&mut out.p001, p.p001),
            (&mut out.p999, p.p999),
            (&mut out.q01, p.q01),
            (&mut out.q99, p.q99),
            (&mut out.q10, p.q10),
            (&mut out.q50, p.q50),
            (&mut out.q90, p.q90),
        ];
        for (a, b) in vectors {
            a.extend(b);
        }
        let m = &mut out.moments;
        m.mean.extend(p.moments.mean);
        m.m2.extend(p.moments.m2);
        m.min.extend(p.moments.min);
        m.max.extend(p.moments.max);
    }
    if dim_count.iter().any(|&n| n != out.count) {
        out.dim_count = dim_count;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::lowdim;

    #[test]
    fn bands_cut_at_every_width() {
        let b = bands(&[2, 26, 0], 32);
        assert_eq!(
            b,
            vec![(0..2, vec![0, 1]), (2..26, vec![1]), (26..32, vec![])]
        );
        assert_eq!(bands(&[3, 3], 3), vec![(0..3, vec![0, 1])]);
    }

    #[test]
    fn joined_bands_equal_each_band_alone() {
        // Source a: 2 dims, 5 rows; source b: 3 dims, 4 rows.
        let a: Vec<f32> = (0..10).map(|i| i as f32).collect();
        let b: Vec<f32> = (0..12).map(|i| (i * 7 % 5) as f32 - 1.0).collect();
        let b_first: Vec<f32> = b.chunks(3).flat_map(|r| r[..2].to_vec()).collect();
        let b_last: Vec<f32> = b.chunks(3).map(|r| r[2]).collect();
        let first = lowdim([&a[..], &b_first[..]].into_iter(), 2);
        let last = lowdim(std::iter::once(&b_last[..]), 1);
        let joined = concat(vec![first.clone(), last.clone()]);
        assert_eq!(joined.count, 9);
        assert_eq!(joined.dim_count, vec![9, 9, 4]);
        assert_eq!(joined.q50, [first.q50, last.q50].concat());
        let want = last.moments.std(1)[0];
        assert!((joined.unbiased_std()[2] - want).abs() < 1e-12);
    }

    #[test]
    fn a_statistics_columns_are_those_columns_statistics_bit_for_bit() {
        let rows: Vec<f32> = (0..60)
            .map(|i| ((i * 37) % 23) as f32 * 0.7 - 3.1)
            .collect();
        let whole = lowdim(std::iter::once(&rows[..]), 4);
        let middle: Vec<f32> = rows.chunks(4).flat_map(|r| r[1..3].to_vec()).collect();
        let alone = lowdim(std::iter::once(&middle[..]), 2);
        let cut = whole.columns(1..3);
        let json = |s: &ChannelStats| serde_json::to_string(s).unwrap();
        assert_eq!(json(&cut), json(&alone));
        assert_eq!(cut.moments, alone.moments);
    }
}
