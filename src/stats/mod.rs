// Long file: the statistics pass (moments, percentiles, histograms per rate) and its results are one step.
//! Statistics over the training split: exact, per dimension, over all timesteps.
//!
//! - `moments`: mergeable count/mean/M2/min/max partials.
//! - `percentile`: exact percentiles (numpy's linear definition).
//! - `normalize`: per-channel normalization parameters derived from the statistics.
//! - `shaped`: per-dimension numbers laid out in a channel's per-step shape (for the files).
//! - `bands`: a channel whose dimensions different populations cover (a padded channel of a
//!   training mixture), reduced band by band and joined.
//!
//! Low-dimensional channels are reduced from the in-memory per-step buffers; image channels are
//! reduced per colour channel from per-episode partials (moments + a 256-bin histogram) built
//! while the images stream through.

pub mod bands;
mod moments;
pub mod normalize;
mod percentile;
pub mod shaped;

pub use moments::Moments;
pub use percentile::{
    percentile, percentile_of_histogram, percentiles, percentiles_counted, percentiles_streamed,
    Definition, HighCounts, SecondPass,
};

use rayon::prelude::*;

use serde::Serialize;

/// The numbers `stats.json` holds for one channel. Vectors have one entry per dimension
/// (per colour channel for images, in stored 0..255 units). `std` is the population standard
/// deviation (ddof = 0); `p001`/`p999` are the 0.1th and 99.9th percentiles, `q01`/`q99` the 1st
/// and 99th (openpi's quantile normalization uses those), `q10`/`q50`/`q90` for LeRobot.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelStats {
    pub mean: Vec<f64>,
    pub std: Vec<f64>,
    pub min: Vec<f64>,
    pub max: Vec<f64>,
    pub p001: Vec<f64>,
    pub p999: Vec<f64>,
    pub q01: Vec<f64>,
    pub q99: Vec<f64>,
    /// 10th, 50th and 90th percentiles (LeRobot's `q10`, `q50`, `q90`).
    pub q10: Vec<f64>,
    pub q50: Vec<f64>,
    pub q90: Vec<f64>,
    /// Number of timesteps the statistics cover.
    pub count: u64,
    /// Per dimension, where dimensions cover different numbers of timesteps (a padded channel of
    /// a training mixture, whose sources have different widths); empty otherwise.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub dim_count: Vec<u64>,
    /// Kept for normalization modes that need another ddof; not serialized.
    #[serde(skip)]
    pub moments: Moments,
}

impl ChannelStats {
    /// The sample standard deviation (ddof = 1) per dimension, each over its own count.
    pub fn unbiased_std(&self) -> Vec<f64> {
        if self.dim_count.is_empty() {
            return self.moments.std(1);
        }
        let m2 = self.moments.m2.iter().zip(&self.dim_count);
        m2.map(|(&m2, &n)| {
            if n > 1 {
                (m2 / (n - 1) as f64).sqrt()
            } else {
                0.0
            }
        })
        .collect()
    }
}

/// Statistics of a low-dimensional channel from row-major per-episode blocks (`dims` values per
/// step), merged in the given order.
pub fn lowdim<'a>(
    blocks: impl Iterator<Item = &'a [f32]> + Clone + Send + Sync,
    dims: usize,
) -> ChannelStats {
    let mut m = Moments::new(dims);
    for block in blocks.clone() {
        m.merge(&Moments::of_rows(block, dims));
    }
    let each = |d: usize, f: &mut dyn FnMut(&[f32])| -> Result<(), std::convert::Infallible> {
        let mut column = Vec::new();
        for block in blocks.clone() {
            column.extend(block.iter().skip(d).step_by(dims));
        }
        f(&column);
        Ok(())
    };
    match lowdim_from(m, dims, each) {
        Ok(s) => s,
        Err(never) => match never {},
    }
}

/// [`lowdim`] from the moments already merged (in episode order) and a reader of one column at
/// a time: `each(d, f)` calls `f` with blocks that together hold dimension `d` of every value the
/// moments cover. Exact percentiles come from two reads of each column
/// ([`percentiles_streamed`]), one column per task: the values are never all in memory, which is
/// what keeps memory flat in the number of values. A build reads its stores' rows with
/// [`lowdim_from_rows`] instead: every column from one read.
pub fn lowdim_from<E: Send>(
    m: Moments,
    dims: usize,
    each: impl Fn(usize, &mut dyn FnMut(&[f32])) -> Result<(), E> + Sync,
) -> Result<ChannelStats, E> {
    let rows = m.count;
    let pct: Vec<Vec<f64>> = crate::error::in_order((0..dims).into_par_iter().map(|d| {
        if rows == 0 {
            Ok(vec![f64::NAN; PERCENTILES.len()])
        } else {
            percentiles_streamed(rows, &PERCENTILES, |f| each(d, f))
        }
    }))?;
    let pct: Vec<Vec<f64>> = (0..PERCENTILES.len())
        .map(|k| pct.iter().map(|p| p[k]).collect())
        .collect();
    Ok(finish(m, pct, rows))
}

/// Columns whose percentile passes [`lowdim_from_rows`] runs side by side: memory is a few
/// 65,536-entry tables per column (more for columns whose values crowd into a few buckets), so
/// wide channels (point clouds) go a group of columns at a time.
pub const COLUMN_GROUP: usize = 16;

/// [`lowdim_from`] for values read as row-major rows: `pass(f)` must call `f` with blocks of
/// whole rows that together hold every value the moments cover, each time it is called.
/// `high`, when given, is every column's first percentile pass, counted ahead. Each block
/// feeds the passes of a group of [`COLUMN_GROUP`] columns side by side, so a channel of up to
/// that many columns is read once (twice without `high`), a wider one once or twice per group;
/// the rows are never all in memory.
pub fn lowdim_from_rows<E>(
    m: Moments,
    dims: usize,
    high: Option<&[HighCounts]>,
    pass: impl FnMut(&mut dyn FnMut(&[f32])) -> Result<(), E>,
) -> Result<ChannelStats, E> {
    lowdim_from_rows_as(m, dims, high, Definition::Linear, pass)
}

/// [`lowdim_from_rows`] with percentiles of another [`Definition`].
pub fn lowdim_from_rows_as<E>(
    m: Moments,
    dims: usize,
    high: Option<&[HighCounts]>,
    definition: Definition,
    mut pass: impl FnMut(&mut dyn FnMut(&[f32])) -> Result<(), E>,
) -> Result<ChannelStats, E> {
    let rows = m.count;
    let mut pct: Vec<Vec<f64>> = Vec::with_capacity(dims);
    if rows == 0 {
        pct.resize(dims, vec![f64::NAN; PERCENTILES.len()]);
    }
    // One read of the rows feeds `passes[i]` with column `columns.start + i` of every block.
    fn feed<P: Send, E>(
        pass: &mut impl FnMut(&mut dyn FnMut(&[f32])) -> Result<(), E>,
        passes: &mut [P],
        columns: &std::ops::Range<usize>,
        dims: usize,
        add: impl Fn(&mut P, &[f32], usize, usize) + Sync,
    ) -> Result<(), E> {
        pass(&mut |block| {
            passes
                .par_iter_mut()
                .zip(columns.clone())
                .for_each(|(p, d)| add(p, block, d, dims));
        })
    }
    for first in (0..dims).step_by(COLUMN_GROUP).filter(|_| rows > 0) {
        let columns = first..dims.min(first + COLUMN_GROUP);
        let counted: Vec<HighCounts>;
        let high: &[HighCounts] = match high {
            Some(high) => &high[columns.clone()],
            None => {
                let mut group: Vec<HighCounts> =
                    columns.clone().map(|_| HighCounts::new()).collect();
                feed(
                    &mut pass,
                    &mut group,
                    &columns,
                    dims,
                    HighCounts::add_strided,
                )?;
                counted = group;
                &counted
            }
        };
        let mut second: Vec<SecondPass> = high
            .iter()
            .map(|h| SecondPass::with(h, rows, &PERCENTILES, definition))
            .collect();
        feed(
            &mut pass,
            &mut second,
            &columns,
            dims,
            SecondPass::add_strided,
        )?;
        pct.extend(
            second
                .into_par_iter()
                .map(SecondPass::finish)
                .collect::<Vec<_>>(),
        );
    }
    let pct: Vec<Vec<f64>> = (0..PERCENTILES.len())
        .map(|k| pct.iter().map(|p| p[k]).collect())
        .collect();
    Ok(finish(m, pct, rows))
}

/// Adds the per-colour histograms of HWC pixels with `C` colours to `hist`. Four pixels at a
/// time into four sets of `u32` tables: consecutive equal values (smooth images) then do not
/// wait on one another's increments, and the tables stay in L1. Exact, whatever the order.
fn histograms<const C: usize>(pixels: &[u8], hist: &mut [[u64; 256]]) {
    const LANES: usize = 4;
    // Pixels counted before the u32 tables are added to `hist` (they cannot overflow).
    const FLUSH: usize = 1 << 30;
    let mut counts = [[[0u32; 256]; C]; LANES];
    for block in pixels.chunks(FLUSH * C) {
        let mut quads = block.chunks_exact(LANES * C);
        for q in &mut quads {
            for (lane, table) in counts.iter_mut().enumerate() {
                for (c, t) in table.iter_mut().enumerate() {
                    t[q[lane * C + c] as usize] += 1;
                }
            }
        }
        for px in quads.remainder().chunks_exact(C) {
            for (c, &v) in px.iter().enumerate() {
                counts[0][c][v as usize] += 1;
            }
        }
        for table in &mut counts {
            for (h, t) in hist.iter_mut().zip(table.iter_mut()) {
                for (x, y) in h.iter_mut().zip(t.iter_mut()) {
                    *x += u64::from(*y);
                    *y = 0;
                }
            }
        }
    }
}

/// Per-episode partial statistics of an image channel (per colour channel).
#[derive(Debug, Clone)]
pub struct ImagePartial {
    pub frames: u64,
    pub moments: Moments,
    pub hist: Vec<[u64; 256]>,
}

impl ImagePartial {
    pub fn new(colors: usize) -> Self {
        ImagePartial {
            frames: 0,
            moments: Moments::new(colors),
            hist: vec![[0; 256]; colors],
        }
    }

    /// Partial of `frames` frames of HWC `u8` pixels with `colors` channels.
    pub fn of_frames(pixels: &[u8], frames: usize, colors: usize) -> Self {
        let mut p = ImagePartial::new(colors);
        p.frames = frames as u64;
        match colors {
            3 => histograms::<3>(pixels, &mut p.hist),
            1 => histograms::<1>(pixels, &mut p.hist),
            4 => histograms::<4>(pixels, &mut p.hist),
            _ => {
                for px in pixels.chunks_exact(colors.max(1)) {
                    for (c, &v) in px.iter().enumerate() {
                        p.hist[c][v as usize] += 1;
                    }
                }
            }
        }
        // Moments follow exactly from the histogram, which avoids a second pass over the pixels.
        let n: u64 = p.hist.first().map(|h| h.iter().sum()).unwrap_or(0);
        p.moments.count = n;
        for c in 0..colors {
            let h = &p.hist[c];
            if n == 0 {
                continue;
            }
            let mean = h
                .iter()
                .enumerate()
                .map(|(v, &k)| v as f64 * k as f64)
                .sum::<f64>()
                / n as f64;
            let m2 = h
                .iter()
                .enumerate()
                .map(|(v, &k)| (v as f64 - mean).powi(2) * k as f64)
                .sum::<f64>();
            p.moments.mean[c] = mean;
            p.moments.m2[c] = m2;
            p.moments.min[c] = h.iter().position(|&k| k > 0).unwrap() as f64;
            p.moments.max[c] = (255 - h.iter().rev().position(|&k| k > 0).unwrap()) as f64;
        }
        p
    }

    pub fn merge(&mut self, other: &ImagePartial) {
        self.frames += other.frames;
        self.moments.merge(&other.moments);
        for (a, b) in self.hist.iter_mut().zip(&other.hist) {
            for (x, y) in a.iter_mut().zip(b.iter()) {
                *x += y;
            }
        }
    }

    pub fn finish(self) -> ChannelStats {
        let has = self.moments.count > 0;
        let pct = PERCENTILES
            .iter()
            .map(|&q| {
                self.hist
                    .iter()
                    .map(|h| {
                        if has {
                            percentile_of_histogram(h, q)
                        } else {
                            f64::NAN
                        }
                    })
                    .collect::<Vec<f64>>()
            })
            .collect();
        finish(self.moments, pct, self.frames)
    }
}

/// The percentiles every channel gets, in the order `finish` expects.
const PERCENTILES: [f64; 7] = [0.1, 99.9, 1.0, 99.0, 10.0, 50.0, 90.0];

fn finish(m: Moments, pct: Vec<Vec<f64>>, count: u64) -> ChannelStats {
    let [p001, p999, q01, q99, q10, q50, q90]: [Vec<f64>; 7] =
        pct.try_into().expect("one vector per percentile");
    let empty = m.count == 0;
    let fix = |v: &Vec<f64>| -> Vec<f64> {
        if empty {
            vec![f64::NAN; v.len()]
        } else {
            v.clone()
        }
    };
    ChannelStats {
        mean: fix(&m.mean),
        std: fix(&m.std(0)),
        min: fix(&m.min),
        max: fix(&m.max),
        p001,
        p999,
        q01,
        q99,
        q10,
        q50,
        q90,
        count,
        dim_count: Vec::new(),
        moments: m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_partial_matches_direct_moments() {
        let pixels: Vec<u8> = (0..2 * 4 * 4 * 3).map(|i| ((i * 53) % 256) as u8).collect();
        let p = ImagePartial::of_frames(&pixels, 2, 3);
        let as_f32: Vec<f32> = pixels.iter().map(|&v| f32::from(v)).collect();
        let direct = Moments::of_rows(&as_f32, 3);
        for c in 0..3 {
            assert!((p.moments.mean[c] - direct.mean[c]).abs() < 1e-9);
            assert!((p.moments.m2[c] - direct.m2[c]).abs() < 1e-6);
            assert_eq!(p.moments.min[c], direct.min[c]);
            assert_eq!(p.moments.max[c], direct.max[c]);
        }
    }

    #[test]
    fn histograms_count_every_pixel() {
        for colors in [1, 2, 3, 4] {
            // 37 pixels: not a multiple of the four lanes.
            let pixels: Vec<u8> = (0..37 * colors)
                .map(|i| ((i * 89 + i / 7) % 251) as u8)
                .collect();
            let p = ImagePartial::of_frames(&pixels, 1, colors);
            let mut naive = vec![[0u64; 256]; colors];
            for (i, &v) in pixels.iter().enumerate() {
                naive[i % colors][v as usize] += 1;
            }
            assert_eq!(p.hist, naive, "{colors} colours");
        }
    }

    #[test]
    fn rows_read_in_blocks_equal_the_whole_columns() {
        // A narrow channel counted ahead, and one wider than a column group counted by the
        // statistics themselves, group by group; blocks of 7 rows, so they end inside rows'
        // natural groupings.
        for (dims, ahead) in [(3usize, true), (COLUMN_GROUP + 5, false), (5, false)] {
            let rows = 300;
            let values: Vec<f32> = (0..rows * dims)
                .map(|i| ((i * 7919 + i / dims * 31) % 1009) as f32 * 0.25 - 40.0)
                .collect();
            let want = lowdim(std::iter::once(&values[..]), dims);
            let mut high: Vec<HighCounts> = (0..dims).map(|_| HighCounts::new()).collect();
            HighCounts::add_rows(&mut high, &values);
            let mut passes = 0;
            let got = lowdim_from_rows::<()>(
                Moments::of_rows(&values, dims),
                dims,
                ahead.then_some(high.as_slice()),
                |f| {
                    passes += 1;
                    values.chunks(7 * dims).for_each(&mut *f);
                    Ok(())
                },
            )
            .unwrap();
            let groups = dims.div_ceil(COLUMN_GROUP);
            assert_eq!(passes, if ahead { groups } else { 2 * groups });
            let pairs = [
                (&want.p001, &got.p001),
                (&want.q01, &got.q01),
                (&want.q10, &got.q10),
                (&want.q50, &got.q50),
                (&want.q90, &got.q90),
                (&want.q99, &got.q99),
                (&want.p999, &got.p999),
            ];
            for (w, g) in pairs {
                assert_eq!(w.len(), dims);
                let same = w
                    .iter()
                    .zip(g.iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(same, "dims {dims}: {w:?} vs {g:?}");
            }
        }
    }

    #[test]
    fn lowdim_blocks_equal_one_block() {
        let a: Vec<f32> = (0..20).map(|i| i as f32).collect();
        let split = lowdim([&a[..8], &a[8..]].into_iter(), 2);
        let whole = lowdim(std::iter::once(&a[..]), 2);
        assert_eq!(split.p001, whole.p001);
        assert_eq!(split.p999, whole.p999);
        assert_eq!(split.count, 10);
    }
}
