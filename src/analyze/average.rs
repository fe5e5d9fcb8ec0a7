//! Averaging per-episode ACFs: per dimension over the episodes in which it varies, then over
//! dimensions. Episodes are added in source order and the sums run in that order, so the result
//! does not depend on anything but the data.

use super::acf::acf;
use super::report::DimAcf;

/// Running sums of per-episode ACFs, one row per dimension.
pub struct Accumulator {
    max_lag: usize,
    sums: Vec<Vec<f64>>,
    counts: Vec<Vec<usize>>,
    constant: Vec<Vec<u64>>,
    /// Per lag, episodes with length > lag.
    episodes_at_lag: Vec<usize>,
}

impl Accumulator {
    pub fn new(width: usize, max_lag: usize) -> Self {
        Accumulator {
            max_lag,
            sums: vec![vec![0.0; max_lag + 1]; width],
            counts: vec![vec![0; max_lag + 1]; width],
            constant: vec![Vec::new(); width],
            episodes_at_lag: vec![0; max_lag + 1],
        }
    }

    /// Adds one episode's values (time-major, `width` values per step).
    pub fn add(&mut self, id: u64, values: &[f32], width: usize) {
        let len = values.len() / width.max(1);
        for count in self.episodes_at_lag.iter_mut().take(len) {
            *count += 1;
        }
        let mut series = vec![0.0f64; len];
        for d in 0..width {
            for (t, v) in series.iter_mut().enumerate() {
                *v = values[t * width + d] as f64;
            }
            match acf(&series, self.max_lag) {
                Some(r) => {
                    for (k, value) in r.into_iter().enumerate() {
                        self.sums[d][k] += value;
                        self.counts[d][k] += 1;
                    }
                }
                None => self.constant[d].push(id),
            }
        }
    }

    /// Per-dimension means, the mean over dimensions, and the episode count per lag.
    pub fn finish(self) -> (Vec<DimAcf>, Vec<f64>, Vec<usize>) {
        let dims: Vec<DimAcf> = self
            .sums
            .iter()
            .zip(&self.counts)
            .zip(self.constant)
            .enumerate()
            .map(|(dim, ((sums, counts), constant_episodes))| DimAcf {
                dim,
                acf: sums
                    .iter()
                    .zip(counts)
                    .take_while(|(_, &n)| n > 0)
                    .map(|(s, &n)| s / n as f64)
                    .collect(),
                constant_episodes,
            })
            .collect();
        let mut mean = Vec::new();
        for k in 0..=self.max_lag {
            let values: Vec<f64> = dims.iter().filter_map(|d| d.acf.get(k).copied()).collect();
            if values.is_empty() {
                break;
            }
            mean.push(values.iter().sum::<f64>() / values.len() as f64);
        }
        let last = self.episodes_at_lag.iter().rposition(|&n| n > 0);
        let mut episodes_at_lag = self.episodes_at_lag;
        episodes_at_lag.truncate(last.map_or(0, |i| i + 1));
        (dims, mean, episodes_at_lag)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn averages_over_long_enough_varying_episodes_only() {
        let mut acc = Accumulator::new(2, 5);
        // Episode 7: dim 0 = 1,2,3,4 (acf known), dim 1 constant.
        acc.add(7, &[1.0, 5.0, 2.0, 5.0, 3.0, 5.0, 4.0, 5.0], 2);
        // Episode 9: dim 0 alternating over 6 steps, dim 1 = 0,1,0,1,0,1.
        acc.add(
            9,
            &[
                1.0, 0.0, -1.0, 1.0, 1.0, 0.0, -1.0, 1.0, 1.0, 0.0, -1.0, 1.0,
            ],
            2,
        );
        let (dims, mean, at_lag) = acc.finish();
        assert_eq!(at_lag, vec![2, 2, 2, 2, 1, 1]);
        assert_eq!(dims[1].constant_episodes, vec![7]);
        assert!(dims[0].constant_episodes.is_empty());
        let a = acf(&[1.0, 2.0, 3.0, 4.0], 5).unwrap();
        let b = acf(&[1.0, -1.0, 1.0, -1.0, 1.0, -1.0], 5).unwrap();
        let c = acf(&[0.0, 1.0, 0.0, 1.0, 0.0, 1.0], 5).unwrap();
        assert_eq!(dims[0].acf.len(), 6);
        for k in 0..6 {
            let want = if k < 4 { (a[k] + b[k]) / 2.0 } else { b[k] };
            assert!((dims[0].acf[k] - want).abs() < 1e-15);
            assert!((dims[1].acf[k] - c[k]).abs() < 1e-15);
            assert!((mean[k] - (dims[0].acf[k] + dims[1].acf[k]) / 2.0).abs() < 1e-15);
        }
    }

    #[test]
    fn a_dimension_constant_everywhere_is_empty_and_left_out_of_the_mean() {
        let mut acc = Accumulator::new(2, 3);
        acc.add(0, &[1.0, 2.0, 2.0, 2.0, 3.0, 2.0], 2);
        let (dims, mean, _) = acc.finish();
        assert!(dims[1].acf.is_empty());
        assert_eq!(dims[1].constant_episodes, vec![0]);
        assert_eq!(mean, dims[0].acf);
    }
}
