//! Near-duplicate episodes: the same demonstration stored twice (a re-export, a copy-paste of a
//! recording session), which weighs it double and leaks it across the train/val split.
//!
//! Each episode's action is resampled at [`POINTS`] evenly spaced steps per dimension and divided
//! by the dimension's typical spread (the median over episodes of the per-episode standard
//! deviation). Two episodes of lengths within 5% are near-duplicates when the RMS difference of
//! these signatures is below `duplicate_tolerance`. A hash grid over three projections of the
//! signatures bounds the comparisons ([`pairs`]); the later episode of a pair, in source order,
//! is the one flagged.

use rayon::prelude::*;

use super::columns::Columns;

pub const POINTS: usize = 32;

/// The resampled action of one episode (its columns), `POINTS × width` values in single
/// precision, point-major.
#[inline(always)]
pub fn signature(a: &Columns) -> Vec<f32> {
    let (n, width) = (a.n(), a.width());
    let mut out = Vec::with_capacity(POINTS * width);
    if n == 0 {
        out.resize(POINTS * width, 0.0);
        return out;
    }
    for p in 0..POINTS {
        let pos = if n > 1 {
            p as f64 * (n - 1) as f64 / (POINTS - 1) as f64
        } else {
            0.0
        };
        let (lo, frac) = (pos.floor() as usize, pos - pos.floor());
        let hi = (lo + 1).min(n - 1);
        for d in 0..width {
            let x = a.col(d);
            let v = f64::from(x[lo]) * (1.0 - frac) + f64::from(x[hi]) * frac;
            out.push(v as f32);
        }
    }
    out
}

/// Projections of a signature onto `±1/len` patterns ([`PROJECTIONS`] of them: all `+`, then
/// signs alternating every element, then every two): each differs between two signatures by at
/// most their RMS difference (`|Σ±dᵢ|/D ≤ Σ|dᵢ|/D ≤ RMS`), so near-duplicates fall into
/// neighbouring cells of a grid of `tolerance`-wide cells in every projection.
pub const PROJECTIONS: usize = 3;

fn projections(s: &[f32], scale: &[f64]) -> [f64; PROJECTIONS] {
    let mut out = [0.0; PROJECTIONS];
    for (i, v) in scaled(s, scale).enumerate() {
        out[0] += v;
        out[1] += if i % 2 == 0 { v } else { -v };
        out[2] += if (i / 2) % 2 == 0 { v } else { -v };
    }
    let len = s.len().max(1) as f64;
    out.map(|x| x / len)
}

/// A signature's values times `scale` (per dimension, repeating), in double precision.
fn scaled<'a>(s: &'a [f32], scale: &'a [f64]) -> impl Iterator<Item = f64> + 'a {
    s.chunks(scale.len().max(1))
        .flat_map(move |row| row.iter().zip(scale).map(|(v, k)| f64::from(*v) * k))
}

/// The RMS difference of two equally long signatures times `scale`, when below `tolerance`:
/// the sum stops as soon as it is past what the tolerance allows (most pairs a grid cell
/// holds are no duplicates).
fn rms_within(a: &[f32], b: &[f32], scale: &[f64], tolerance: f64) -> Option<f64> {
    let n = a.len().max(1) as f64;
    // Past this sum of squares the RMS is at the tolerance or above (with room for rounding:
    // the verdict is the final comparison's).
    let limit = tolerance * tolerance * n * (1.0 + 1e-9);
    let mut total = 0.0;
    for (p, q) in a
        .chunks(scale.len().max(1))
        .zip(b.chunks(scale.len().max(1)))
    {
        for ((x, y), k) in p.iter().zip(q).zip(scale) {
            let d = f64::from(*x) * k - f64::from(*y) * k;
            total += d * d;
        }
        if total > limit {
            return None;
        }
    }
    let rms = (total / n).sqrt();
    (rms < tolerance).then_some(rms)
}

/// Pairs `(earlier, later, rms)` of positions whose signatures, times `scale` (per dimension: one
/// over the dimension's spread), are within `tolerance`; each later episode appears once, with
/// its closest earlier match. The scaled signatures are never stored (50,000 episodes of 14-D
/// actions would hold 180 MB of them).
///
/// Episodes go into a hash grid by their [`projections`]; each is compared exactly (lengths, then
/// the RMS difference) only with the episodes of its own and the neighbouring cells, so the work
/// grows with the episodes times the crowding of a cell, not with their square, and no pair
/// within `tolerance` is missed. The comparisons run in parallel, each episode's against its
/// later neighbours; the matches are then kept in the order a single thread would meet them,
/// so the pairs do not depend on the threads.
pub fn pairs(
    signatures: &[&[f32]],
    scale: &[f64],
    lengths: &[usize],
    tolerance: f64,
) -> Vec<(usize, usize, f64)> {
    type Cell = [i64; PROJECTIONS];
    let cell_of =
        |s: &[f32]| -> Cell { projections(s, scale).map(|x| (x / tolerance).floor() as i64) };
    let cells: Vec<Cell> = signatures.par_iter().map(|s| cell_of(s)).collect();
    let mut grid: std::collections::HashMap<Cell, Vec<usize>> = Default::default();
    for (i, c) in cells.iter().enumerate() {
        grid.entry(*c).or_default().push(i);
    }
    let offsets: Vec<Cell> = (0..3usize.pow(PROJECTIONS as u32))
        .map(|k| {
            let mut o = [0i64; PROJECTIONS];
            let mut k = k;
            for x in o.iter_mut() {
                *x = (k % 3) as i64 - 1;
                k /= 3;
            }
            o
        })
        .collect();
    // Per episode, its matches among the later episodes of its own and the neighbouring cells.
    let matches: Vec<Vec<(usize, f64)>> = (0..cells.len())
        .into_par_iter()
        .map(|i| {
            let mut found = Vec::new();
            for o in &offsets {
                let mut near = cells[i];
                for (x, d) in near.iter_mut().zip(o) {
                    *x += d;
                }
                // Each pair once: from its earlier episode.
                for &j in grid.get(&near).map_or(&[][..], |v| &v[..]) {
                    let (li, lj) = (lengths[i] as f64, lengths[j] as f64);
                    if j <= i
                        || (li - lj).abs() > 0.05 * li.max(lj)
                        || signatures[i].len() != signatures[j].len()
                    {
                        continue;
                    }
                    if let Some(rms) = rms_within(signatures[i], signatures[j], scale, tolerance) {
                        found.push((j, rms));
                    }
                }
            }
            found
        })
        .collect();
    let mut best: std::collections::BTreeMap<usize, (usize, f64)> = Default::default();
    for (i, found) in matches.into_iter().enumerate() {
        for (j, rms) in found {
            let e = best.entry(j).or_insert((i, rms));
            if rms < e.1 || (rms == e.1 && i < e.0) {
                *e = (i, rms);
            }
        }
    }
    best.into_iter()
        .map(|(late, (early, rms))| (early, late, rms))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_copy_not_the_neighbours() {
        let ep = |phase: f64| {
            let x: Vec<f32> = (0..50)
                .map(|t| (t as f64 * 0.1 + phase).sin() as f32)
                .collect();
            signature(&Columns::of(&x, 50, 1))
        };
        let sigs: Vec<Vec<f32>> = vec![ep(0.0), ep(1.0), ep(0.0001), ep(2.0)];
        let views: Vec<&[f32]> = sigs.iter().map(|s| &s[..]).collect();
        assert_eq!(
            pairs(&views, &[1.0], &[50; 4], 0.01)
                .iter()
                .map(|p| (p.0, p.1))
                .collect::<Vec<_>>(),
            vec![(0, 2)]
        );
    }

    /// The grid finds exactly the pairs every-pair comparison finds, with planted copies at
    /// distances up to the tolerance's edge.
    #[test]
    fn grid_equals_every_pair() {
        let mut seed = 7u64;
        let mut rand = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let tolerance = 0.05;
        let mut sigs: Vec<Vec<f32>> = (0..300)
            .map(|_| (0..24).map(|_| (0.2 * (rand() - 0.5)) as f32).collect())
            .collect();
        for k in 0..60 {
            let scale = tolerance * (0.5 + rand());
            let copy: Vec<f32> = sigs[k]
                .iter()
                .map(|v| (f64::from(*v) + scale * (rand() - 0.5)) as f32)
                .collect();
            sigs.push(copy);
        }
        let lengths: Vec<usize> = (0..sigs.len()).map(|i| 100 + i % 3).collect();
        let mut every = std::collections::BTreeMap::new();
        for j in 0..sigs.len() {
            for i in 0..j {
                let rms = (sigs[i]
                    .iter()
                    .zip(&sigs[j])
                    .map(|(p, q)| (f64::from(*p) - f64::from(*q)).powi(2))
                    .sum::<f64>()
                    / 24.0)
                    .sqrt();
                let e = every.entry(j).or_insert((i, f64::INFINITY));
                if rms < tolerance && rms < e.1 {
                    *e = (i, rms);
                }
            }
        }
        let expected: Vec<(usize, usize, f64)> = every
            .into_iter()
            .filter(|(_, (_, r))| r.is_finite())
            .map(|(j, (i, r))| (i, j, r))
            .collect();
        assert!(expected.len() >= 40, "{}", expected.len());
        let views: Vec<&[f32]> = sigs.iter().map(|s| &s[..]).collect();
        assert_eq!(pairs(&views, &[1.0], &lengths, tolerance), expected);
    }
}
