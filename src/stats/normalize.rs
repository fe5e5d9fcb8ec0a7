//! Normalization parameters, in one convention for every mode: stored `y = (x - center) / scale`,
//! recovered `x = y * scale + center`, optionally clipped to [-1, 1] after the forward map.

use serde::Serialize;

use super::ChannelStats;
use crate::spec::NormalizeMode;

/// ACT clips its (unbiased) standard deviation to at least this (`get_norm_stats`).
pub const ZSCORE_STD_FLOOR: f64 = 1e-2;
/// Below this percentile range a dimension is treated as constant and mapped to 0 (Diffusion
/// Policy's `limits` normalizer uses the same threshold when fitting).
pub const MINMAX_RANGE_EPS: f64 = 1e-4;

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Normalizer {
    pub mode: NormalizeMode,
    pub center: Vec<f64>,
    pub scale: Vec<f64>,
    /// Whether normalized values are clipped to [-1, 1].
    pub clip: bool,
}

impl Normalizer {
    pub fn fit(mode: NormalizeMode, stats: &ChannelStats) -> Self {
        let dims = stats.mean.len();
        match mode {
            NormalizeMode::None => Normalizer {
                mode,
                center: vec![0.0; dims],
                scale: vec![1.0; dims],
                clip: false,
            },
            NormalizeMode::Zscore => Normalizer {
                mode,
                center: stats.mean.clone(),
                scale: stats
                    .moments
                    .std(1)
                    .into_iter()
                    .map(|s| s.max(ZSCORE_STD_FLOOR))
                    .collect(),
                clip: false,
            },
            NormalizeMode::Minmax => {
                let mut center = Vec::with_capacity(dims);
                let mut scale = Vec::with_capacity(dims);
                for (&lo, &hi) in stats.p001.iter().zip(&stats.p999) {
                    if hi - lo < MINMAX_RANGE_EPS {
                        center.push(0.5 * (lo + hi));
                        scale.push(1.0);
                    } else {
                        center.push(0.5 * (lo + hi));
                        scale.push(0.5 * (hi - lo));
                    }
                }
                Normalizer {
                    mode,
                    center,
                    scale,
                    clip: true,
                }
            }
        }
    }

    /// Normalizes row-major values with `center.len()` values per step, in place.
    pub fn apply(&self, values: &mut [f32]) {
        if self.mode == NormalizeMode::None {
            return;
        }
        let dims = self.center.len();
        for row in values.chunks_exact_mut(dims) {
            for (d, v) in row.iter_mut().enumerate() {
                let mut y = (f64::from(*v) - self.center[d]) / self.scale[d];
                if self.clip {
                    y = y.clamp(-1.0, 1.0);
                }
                *v = y as f32;
            }
        }
    }

    /// The normalized value of raw `x` in dimension `d` (used for zero padding in raw units).
    pub fn forward(&self, d: usize, x: f64) -> f64 {
        let y = (x - self.center[d]) / self.scale[d];
        if self.clip {
            y.clamp(-1.0, 1.0)
        } else {
            y
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::lowdim;

    #[test]
    fn minmax_maps_percentiles_to_unit_range_and_constant_to_zero() {
        let values: Vec<f32> = (0..1001).flat_map(|i| [i as f32, 3.0]).collect();
        let stats = lowdim(std::iter::once(&values[..]), 2);
        let n = Normalizer::fit(NormalizeMode::Minmax, &stats);
        assert!((n.forward(0, stats.p001[0]) + 1.0).abs() < 1e-12);
        assert!((n.forward(0, stats.p999[0]) - 1.0).abs() < 1e-12);
        assert_eq!(n.forward(1, 3.0), 0.0);
    }

    #[test]
    fn zscore_floors_std() {
        let values: Vec<f32> = vec![1.0, 1.0, 1.0, 1.0];
        let stats = lowdim(std::iter::once(&values[..]), 1);
        let n = Normalizer::fit(NormalizeMode::Zscore, &stats);
        assert_eq!(n.scale, vec![ZSCORE_STD_FLOOR]);
    }
}
