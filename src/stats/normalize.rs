//! Normalization parameters, in one convention for every mode: stored `y = (x - center) / scale`,
//! recovered `x = y * scale + center`, optionally clipped to [-1, 1] after the forward map.

use serde::Serialize;

use super::ChannelStats;
use crate::spec::NormalizeMode;

/// ACT clips its (unbiased) standard deviation to at least this (`get_norm_stats`).
pub const ZSCORE_STD_FLOOR: f64 = 1e-2;
/// Below this range a dimension is treated as constant and mapped to 0 (Diffusion Policy's
/// `limits` normalizer uses the same threshold when fitting).
pub const MINMAX_RANGE_EPS: f64 = 1e-4;
/// LeRobot adds this to `std` (MEAN_STD) and to `max - min` (MIN_MAX).
pub const LEROBOT_EPS: f64 = 1e-8;
/// openpi adds this to `q99 - q01` (quantile) and to `std` (z-score).
pub const OPENPI_EPS: f64 = 1e-6;
/// Diffusion Policy's `get_range_normalizer_attrs` default `range_eps`, which its abs-action
/// normalizer uses.
pub const DP_ABS_RANGE_EPS: f64 = 1e-7;
/// numpy's `isclose` tolerances, which GR00T's min-max normalization uses to find a constant
/// dimension.
pub const GROOT_ISCLOSE_ATOL: f64 = 1e-8;
pub const GROOT_ISCLOSE_RTOL: f64 = 1e-5;
/// One arm's block of Diffusion Policy's abs-action layout: `[pos3, rotation_6d, gripper1]`.
pub const DP_ABS_ARM: usize = 10;

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Normalizer {
    pub mode: NormalizeMode,
    pub center: Vec<f64>,
    pub scale: Vec<f64>,
    /// Whether normalized values are clipped to [-1, 1].
    pub clip: bool,
}

impl Normalizer {
    fn new(mode: NormalizeMode, center: Vec<f64>, scale: Vec<f64>, clip: bool) -> Self {
        Normalizer {
            mode,
            center,
            scale,
            clip,
        }
    }

    /// Values stored as they are (`dims` per step).
    pub fn identity(dims: usize) -> Self {
        Normalizer::new(NormalizeMode::None, vec![0.0; dims], vec![1.0; dims], false)
    }

    /// Maps `[lo, hi]` per dimension onto [-1, 1] (center and half-width).
    fn range(mode: NormalizeMode, lo: &[f64], hi: &[f64], eps: f64, clip: bool) -> Self {
        let center = lo
            .iter()
            .zip(hi)
            .map(|(l, h)| l + (h - l + eps) / 2.0)
            .collect();
        let scale = lo
            .iter()
            .zip(hi)
            .map(|(l, h)| (h - l + eps) / 2.0)
            .collect();
        Normalizer::new(mode, center, scale, clip)
    }

    pub fn fit(mode: NormalizeMode, stats: &ChannelStats) -> Self {
        let dims = stats.mean.len();
        match mode {
            NormalizeMode::None => Normalizer::new(mode, vec![0.0; dims], vec![1.0; dims], false),
            NormalizeMode::Zscore => {
                let std = stats.unbiased_std();
                let scale = std.into_iter().map(|s| s.max(ZSCORE_STD_FLOOR)).collect();
                Normalizer::new(mode, stats.mean.clone(), scale, false)
            }
            NormalizeMode::LerobotMeanStd => {
                let scale = stats.std.iter().map(|s| s + LEROBOT_EPS).collect();
                Normalizer::new(mode, stats.mean.clone(), scale, false)
            }
            NormalizeMode::LerobotMinMax => {
                Normalizer::range(mode, &stats.min, &stats.max, LEROBOT_EPS, false)
            }
            NormalizeMode::OpenpiZscore => {
                let scale = stats.std.iter().map(|s| s + OPENPI_EPS).collect();
                Normalizer::new(mode, stats.mean.clone(), scale, false)
            }
            NormalizeMode::DpAbsAction => {
                // Per arm: the position by range (a constant one shifted to 0); the rotation
                // and the gripper as they are.
                let mut center = vec![0.0; dims];
                let mut scale = vec![1.0; dims];
                for d in (0..dims).filter(|d| d % DP_ABS_ARM < 3) {
                    let (lo, hi) = (stats.min[d], stats.max[d]);
                    if hi - lo < DP_ABS_RANGE_EPS {
                        center[d] = lo;
                    } else {
                        center[d] = 0.5 * (lo + hi);
                        scale[d] = 0.5 * (hi - lo);
                    }
                }
                Normalizer::new(mode, center, scale, false)
            }
            NormalizeMode::Quantile => {
                Normalizer::range(mode, &stats.q01, &stats.q99, OPENPI_EPS, false)
            }
            NormalizeMode::GrootQuantile => {
                let mut center = Vec::with_capacity(dims);
                let mut scale = Vec::with_capacity(dims);
                for (&lo, &hi) in stats.q01.iter().zip(&stats.q99) {
                    // GR00T's `normalize_values_minmax` maps a dimension to 0 where
                    // `np.isclose(max, min)`; here its q01 maps to 0.
                    if (hi - lo).abs() <= GROOT_ISCLOSE_ATOL + GROOT_ISCLOSE_RTOL * lo.abs() {
                        center.push(lo);
                        scale.push(1.0);
                    } else {
                        center.push(0.5 * (lo + hi));
                        scale.push(0.5 * (hi - lo));
                    }
                }
                Normalizer::new(mode, center, scale, true)
            }
            NormalizeMode::Minmax | NormalizeMode::Limits => {
                let (lo, hi, clip) = if mode == NormalizeMode::Minmax {
                    (&stats.p001, &stats.p999, true)
                } else {
                    (&stats.min, &stats.max, false)
                };
                let mut center = Vec::with_capacity(dims);
                let mut scale = Vec::with_capacity(dims);
                for (&lo, &hi) in lo.iter().zip(hi) {
                    if hi - lo < MINMAX_RANGE_EPS {
                        // Diffusion Policy: scale 1, and the minimum maps to 0.
                        center.push(lo);
                        scale.push(1.0);
                    } else {
                        center.push(0.5 * (lo + hi));
                        scale.push(0.5 * (hi - lo));
                    }
                }
                Normalizer::new(mode, center, scale, clip)
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

impl Normalizer {
    /// This normalizer on the first `own` of `width` dimensions and the identity on the rest, so
    /// that a mixture source's zero padding stays 0 (`self` has at least `own` dimensions).
    pub fn widened(&self, own: usize, width: usize) -> Normalizer {
        let mut center = self.center[..own].to_vec();
        let mut scale = self.scale[..own].to_vec();
        center.resize(width, 0.0);
        scale.resize(width, 1.0);
        Normalizer::new(self.mode, center, scale, self.clip)
    }
}

/// The normalizers of a channel's stored rows, by row range: one for a single source, one per
/// source in a training mixture (each source's rows with its own).
#[derive(Debug, Clone, PartialEq)]
pub struct RowNormalizer {
    /// Each normalizer and the first row it applies to, from row 0, in row order.
    pieces: Vec<(usize, Normalizer)>,
}

impl RowNormalizer {
    /// One normalizer for every row.
    pub fn single(n: Normalizer) -> Self {
        RowNormalizer {
            pieces: vec![(0, n)],
        }
    }

    /// Normalizers from their first rows (sorted, the first 0).
    pub fn pieces(pieces: Vec<(usize, Normalizer)>) -> Self {
        assert!(pieces.first().is_some_and(|p| p.0 == 0), "rows from 0");
        RowNormalizer { pieces }
    }

    /// The normalizer of row 0 (the only one of a single source).
    pub fn first(&self) -> &Normalizer {
        &self.pieces[0].1
    }

    /// The normalizer of stored row `row`.
    pub fn at(&self, row: usize) -> &Normalizer {
        let k = self.pieces.partition_point(|p| p.0 <= row);
        &self.pieces[k.saturating_sub(1)].1
    }

    /// Normalizes, in place, the rows of `values` (whole rows), the first of which is row `first`.
    pub fn apply_rows(&self, first: usize, values: &mut [f32]) {
        let width = self.first().center.len();
        if width == 0 {
            return;
        }
        let rows = values.len() / width;
        for (k, (start, n)) in self.pieces.iter().enumerate() {
            let end = self.pieces.get(k + 1).map_or(usize::MAX, |p| p.0);
            let (lo, hi) = (first.max(*start), (first + rows).min(end));
            if lo < hi {
                n.apply(&mut values[(lo - first) * width..(hi - first) * width]);
            }
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
    fn limits_use_true_min_max_and_map_constant_min_to_zero() {
        let values: Vec<f32> = (0..11).flat_map(|i| [i as f32, 7.0]).collect();
        let stats = lowdim(std::iter::once(&values[..]), 2);
        let n = Normalizer::fit(NormalizeMode::Limits, &stats);
        assert_eq!((n.forward(0, 0.0), n.forward(0, 10.0)), (-1.0, 1.0));
        assert_eq!(n.forward(1, 7.0), 0.0);
        assert!(!n.clip);
    }

    #[test]
    fn quantile_matches_openpi_formula() {
        let values: Vec<f32> = (0..201).map(|i| i as f32).collect();
        let stats = lowdim(std::iter::once(&values[..]), 1);
        let n = Normalizer::fit(NormalizeMode::Quantile, &stats);
        let (q01, q99) = (stats.q01[0], stats.q99[0]);
        for x in [0.0, 17.0, 150.0, 200.0] {
            let want = (x - q01) / (q99 - q01 + OPENPI_EPS) * 2.0 - 1.0;
            assert!((n.forward(0, x) - want).abs() < 1e-12);
        }
    }

    #[test]
    fn groot_quantile_maps_q01_q99_to_unit_range_and_clips() {
        let values: Vec<f32> = (0..201).flat_map(|i| [i as f32, 4.0]).collect();
        let stats = lowdim(std::iter::once(&values[..]), 2);
        let n = Normalizer::fit(NormalizeMode::GrootQuantile, &stats);
        let (q01, q99) = (stats.q01[0], stats.q99[0]);
        assert!((n.forward(0, q01) + 1.0).abs() < 1e-12);
        assert!((n.forward(0, q99) - 1.0).abs() < 1e-12);
        let mid = (n.forward(0, 50.0) - ((50.0 - q01) / (q99 - q01) * 2.0 - 1.0)).abs();
        assert!(mid < 1e-12);
        assert_eq!((n.forward(0, 0.0), n.forward(0, 200.0)), (-1.0, 1.0));
        assert_eq!(n.forward(1, 4.0), 0.0);
    }

    #[test]
    fn row_pieces_normalize_their_own_rows() {
        let a = Normalizer::new(NormalizeMode::Zscore, vec![1.0, 0.0], vec![2.0, 1.0], false);
        let b = Normalizer::new(NormalizeMode::Zscore, vec![10.0], vec![5.0], false).widened(1, 2);
        assert_eq!(b.center, vec![10.0, 0.0]);
        let rows = RowNormalizer::pieces(vec![(0, a.clone()), (2, b)]);
        // Rows 1..4 of [x, pad]: row 1 is a's, rows 2 and 3 b's (its pad dimension stays 0).
        let mut v = vec![3.0, 4.0, 20.0, 0.0, 15.0, 0.0];
        rows.apply_rows(1, &mut v);
        assert_eq!(v, vec![1.0, 4.0, 2.0, 0.0, 1.0, 0.0]);
        let mut one = vec![3.0, 4.0];
        RowNormalizer::single(a.clone()).apply_rows(7, &mut one);
        let mut want = vec![3.0, 4.0];
        a.apply(&mut want);
        assert_eq!(one, want);
    }

    #[test]
    fn zscore_floors_std() {
        let values: Vec<f32> = vec![1.0, 1.0, 1.0, 1.0];
        let stats = lowdim(std::iter::once(&values[..]), 1);
        let n = Normalizer::fit(NormalizeMode::Zscore, &stats);
        assert_eq!(n.scale, vec![ZSCORE_STD_FLOOR]);
    }
}
