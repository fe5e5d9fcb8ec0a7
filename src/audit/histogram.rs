//! The dataset-wide picture of the step intervals: every episode's intervals as one multiset,
//! its histogram (the audit page's first chart) and its modes (a bimodal recording is flagged).
//!
//! Bimodality: the sorted intervals are split into groups wherever two neighbours differ by more
//! than `jitter_threshold` × T; the histogram is bimodal when two or more groups each hold at
//! least 5% of all intervals.

use super::report::Histogram;

/// Share of all intervals a group needs to count as a mode.
pub const MODE_SHARE: f64 = 0.05;
/// Bins of the dataset-wide histogram.
pub const HISTOGRAM_BINS: usize = 50;

/// The step intervals of every episode, as a multiset. Counted per distinct value while there are
/// few (regular recordings, and sources without timestamps, whose nominal grid repeats a handful
/// of values: memory then does not grow with the number of episodes); kept one by one beyond
/// [`Intervals::MAX_DISTINCT`] distinct values.
#[derive(Debug, Default)]
pub struct Intervals {
    counted: std::collections::HashMap<u64, u64>,
    /// Every interval, once there were too many distinct values to count.
    all: Option<Vec<f64>>,
}

impl Intervals {
    pub const MAX_DISTINCT: usize = 1 << 16;

    /// Adds the intervals between consecutive timestamps, `times` times over.
    pub fn add_steps(&mut self, t: &[f64], times: u64) {
        self.add(t.windows(2).map(|w| w[1] - w[0]), times);
    }

    fn add(&mut self, intervals: impl Iterator<Item = f64>, times: u64) {
        for v in intervals {
            if let Some(all) = &mut self.all {
                all.extend(std::iter::repeat_n(v, times as usize));
                continue;
            }
            *self.counted.entry(v.to_bits()).or_insert(0) += times;
            if self.counted.len() > Self::MAX_DISTINCT {
                let mut all = Vec::new();
                for (&bits, &n) in &self.counted {
                    all.extend(std::iter::repeat_n(f64::from_bits(bits), n as usize));
                }
                self.counted = Default::default();
                self.all = Some(all);
            }
        }
    }

    /// The distinct values in increasing order, each with its count.
    pub fn runs(mut self) -> Runs {
        match self.all.take() {
            Some(mut all) => {
                all.sort_by(f64::total_cmp);
                Runs::Sorted(all)
            }
            None => {
                let mut counted: Vec<(f64, u64)> = self
                    .counted
                    .into_iter()
                    .map(|(bits, n)| (f64::from_bits(bits), n))
                    .collect();
                counted.sort_by(|a, b| a.0.total_cmp(&b.0));
                Runs::Counted(counted)
            }
        }
    }
}

/// Sorted intervals, read as (value, count) runs.
pub enum Runs {
    Counted(Vec<(f64, u64)>),
    Sorted(Vec<f64>),
}

impl Runs {
    fn iter(&self) -> Box<dyn Iterator<Item = (f64, u64)> + '_> {
        match self {
            Runs::Counted(v) => Box::new(v.iter().copied()),
            Runs::Sorted(v) => Box::new(v.chunk_by(|a, b| a == b).map(|g| (g[0], g.len() as u64))),
        }
    }

    fn total(&self) -> u64 {
        self.iter().map(|(_, n)| n).sum()
    }
}

/// Equal-width bins from the smallest to the largest interval (given as runs).
pub fn histogram_of(runs: &Runs, expected: f64) -> Histogram {
    let total = runs.total();
    if total == 0 {
        return Histogram {
            edges: vec![expected * 0.99, expected * 1.01],
            counts: vec![0],
        };
    }
    let lo = runs.iter().next().map_or(0.0, |(v, _)| v);
    let hi = runs.iter().last().map_or(0.0, |(v, _)| v);
    if hi - lo <= expected * 1e-9 {
        return Histogram {
            edges: vec![lo - expected * 0.01, lo + expected * 0.01],
            counts: vec![total],
        };
    }
    let width = (hi - lo) / HISTOGRAM_BINS as f64;
    let edges: Vec<f64> = (0..=HISTOGRAM_BINS)
        .map(|i| lo + i as f64 * width)
        .collect();
    let mut counts = vec![0u64; HISTOGRAM_BINS];
    for (v, n) in runs.iter() {
        let b = (((v - lo) / width) as usize).min(HISTOGRAM_BINS - 1);
        counts[b] += n;
    }
    Histogram { edges, counts }
}

/// The modes of the intervals (group centres, in seconds, with their share), largest first:
/// groups of sorted values with no gap wider than
/// `separation * expected` between neighbours.
pub fn modes_of(runs: &Runs, expected: f64, separation: f64) -> Vec<(f64, f64)> {
    let total = runs.total() as f64;
    let mut groups: Vec<(f64, u64)> = Vec::new();
    // The open group: sum (of every value in sorted order, as a plain sum would add them),
    // count, and its largest value.
    let mut open: Option<(f64, u64, f64)> = None;
    for (v, n) in runs.iter() {
        if let Some((sum, count, last)) = open {
            if v - last > separation * expected {
                groups.push((sum / count as f64, count));
                open = None;
            }
        }
        let (mut sum, count, _) = open.unwrap_or((0.0, 0, v));
        for _ in 0..n {
            sum += v;
        }
        open = Some((sum, count + n, v));
    }
    if let Some((sum, count, _)) = open {
        groups.push((sum / count as f64, count));
    }
    let mut modes: Vec<(f64, f64)> = groups
        .into_iter()
        .map(|(c, k)| (c, k as f64 / total))
        .filter(|&(_, share)| share >= MODE_SHARE)
        .collect();
    modes.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.total_cmp(&b.0)));
    modes
}

#[cfg(test)]
mod tests {
    use super::*;

    fn modes(intervals: &[f64], expected: f64, separation: f64) -> Vec<(f64, f64)> {
        let mut set = Intervals::default();
        set.add(intervals.iter().copied(), 1);
        modes_of(&set.runs(), expected, separation)
    }

    #[test]
    fn bimodal_groups() {
        let mut dt = vec![0.010; 60];
        dt.extend(vec![0.012; 40]);
        dt.push(0.03);
        let m = modes(&dt, 0.01, 0.1);
        assert_eq!(m.len(), 2);
        assert!((m[0].0 - 0.010).abs() < 1e-12 && (m[1].0 - 0.012).abs() < 1e-12);
    }
}
