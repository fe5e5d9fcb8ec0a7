//! Per-dimension count, mean, M2, min and max, mergeable exactly in a fixed order.
//!
//! Partials are built per episode and merged with Chan et al.'s pairwise formula. Merging in the
//! episode order the plan fixes makes the result independent of the thread count.

#[derive(Debug, Clone, PartialEq)]
pub struct Moments {
    pub count: u64,
    pub mean: Vec<f64>,
    pub m2: Vec<f64>,
    pub min: Vec<f64>,
    pub max: Vec<f64>,
}

impl Moments {
    pub fn new(dims: usize) -> Self {
        Moments {
            count: 0,
            mean: vec![0.0; dims],
            m2: vec![0.0; dims],
            min: vec![f64::INFINITY; dims],
            max: vec![f64::NEG_INFINITY; dims],
        }
    }

    /// Partial of a row-major block of `rows × dims` values (two-pass within the block, which is
    /// both exact enough and fast).
    pub fn of_rows(values: &[f32], dims: usize) -> Self {
        Moments::of_narrow_rows(values, values.len() / dims.max(1), dims)
    }

    /// The moments at `width` columns of `rows` rows of `own` values each (`values.len() /
    /// rows`), each followed by `width - own` zeros (a mixture source's padding), equal bit for
    /// bit to [`Moments::of_rows`] of the padded rows: only the `own` columns are summed, and a
    /// padded column's moments are those of zeros (mean, M2, min and max 0).
    pub fn of_narrow_rows(values: &[f32], rows: usize, width: usize) -> Self {
        let mut m = Moments::new(width);
        if width == 0 || rows == 0 {
            return m;
        }
        let own = values.len() / rows;
        debug_assert!(own <= width && own * rows == values.len());
        m.count = rows as u64;
        for d in own..width {
            (m.min[d], m.max[d]) = (0.0, 0.0);
        }
        if own == 0 {
            return m;
        }
        // Zipped slices rather than indices: no bounds checks, and the per-dimension updates
        // of a row vectorize. Each dimension's sums are still taken in row order.
        let (mean, min, max) = (&mut m.mean[..own], &mut m.min[..own], &mut m.max[..own]);
        for row in values.chunks_exact(own) {
            for (((v, s), lo), hi) in row.iter().zip(&mut *mean).zip(&mut *min).zip(&mut *max) {
                let v = f64::from(*v);
                *s += v;
                *lo = lo.min(v);
                *hi = hi.max(v);
            }
        }
        for mean in &mut m.mean[..own] {
            *mean /= rows as f64;
        }
        let (mean, m2) = (&m.mean[..own], &mut m.m2[..own]);
        for row in values.chunks_exact(own) {
            for ((v, mu), acc) in row.iter().zip(mean).zip(&mut *m2) {
                let dv = f64::from(*v) - mu;
                *acc += dv * dv;
            }
        }
        m
    }

    /// Folds `other` into `self` (Chan's parallel update).
    pub fn merge(&mut self, other: &Moments) {
        if other.count == 0 {
            return;
        }
        if self.count == 0 {
            *self = other.clone();
            return;
        }
        let (na, nb) = (self.count as f64, other.count as f64);
        let n = na + nb;
        for d in 0..self.mean.len() {
            let delta = other.mean[d] - self.mean[d];
            self.mean[d] += delta * nb / n;
            self.m2[d] += other.m2[d] + delta * delta * na * nb / n;
            self.min[d] = self.min[d].min(other.min[d]);
            self.max[d] = self.max[d].max(other.max[d]);
        }
        self.count += other.count;
    }

    /// Standard deviation with `ddof` delta degrees of freedom (0: population, 1: sample).
    pub fn std(&self, ddof: u64) -> Vec<f64> {
        self.m2
            .iter()
            .map(|&m2| {
                if self.count > ddof {
                    (m2 / (self.count - ddof) as f64).sqrt()
                } else {
                    0.0
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merge_equals_whole() {
        let data: Vec<f32> = (0..60)
            .map(|i| ((i * 37) % 11) as f32 * 0.5 - 2.0)
            .collect();
        let whole = Moments::of_rows(&data, 3);
        let mut merged = Moments::of_rows(&data[..21], 3);
        merged.merge(&Moments::of_rows(&data[21..45], 3));
        merged.merge(&Moments::of_rows(&data[45..], 3));
        assert_eq!(merged.count, whole.count);
        for d in 0..3 {
            assert!((merged.mean[d] - whole.mean[d]).abs() < 1e-12);
            assert!((merged.m2[d] - whole.m2[d]).abs() < 1e-9);
            assert_eq!(merged.min[d], whole.min[d]);
            assert_eq!(merged.max[d], whole.max[d]);
        }
    }

    #[test]
    fn narrow_rows_are_the_moments_of_their_padding_bit_for_bit() {
        let (width, own, rows) = (5, 2, 8);
        let narrow: Vec<f32> = (0..rows * own)
            .map(|i| ((i * 37) % 11) as f32 * 0.3 - 1.7)
            .collect();
        let padded: Vec<f32> = (narrow.chunks_exact(own))
            .flat_map(|r| r.iter().copied().chain([0.0; 3]))
            .collect();
        let want = Moments::of_rows(&padded, width);
        assert_eq!(Moments::of_narrow_rows(&narrow, rows, width), want);
        // A source without the channel: its rows are all padding.
        let zeros = vec![0.0; rows * width];
        let none = Moments::of_narrow_rows(&[], rows, width);
        assert_eq!(none, Moments::of_rows(&zeros, width));
        assert_eq!(none.count, rows as u64);
    }

    #[test]
    fn std_ddof() {
        let m = Moments::of_rows(&[1.0, 2.0, 3.0, 4.0], 1);
        assert!((m.std(0)[0] - 1.118033988749895).abs() < 1e-12);
        assert!((m.std(1)[0] - 1.2909944487358056).abs() < 1e-12);
    }
}
