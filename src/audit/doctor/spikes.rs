//! One-step spikes of an action dimension (the `jump` check's evidence, see [`super::signal`]):
//! every step's distance from the line through its neighbours, the conditions that tell a
//! glitch from a motion, and the three largest. [`super::returns`] judges the same residuals a
//! second way.

/// A one-step spike: its size and step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Spike {
    pub size: f32,
    pub step: u32,
}

/// The buffers of the search, reused from dimension to dimension.
#[derive(Default)]
pub struct Scratch {
    r: Vec<f64>,
    sizes: Vec<f64>,
}

impl Scratch {
    /// The residuals of the last column searched ([`residuals`]), and the sizes' buffer.
    pub fn parts(&mut self) -> (&[f64], &mut Vec<f64>) {
        (&self.r, &mut self.sizes)
    }
}

/// [`largest`]' sizes of the steps `2..n - 2` of `x` (`n` at least 5) into `sizes`, from the
/// residuals `r`: equally long slices, one per offset, so that the loop runs without bounds
/// checks (and vectorizes).
#[inline(always)]
fn interior_sizes(x: &[f32], r: &[f64], sizes: &mut [f64]) {
    let m = sizes.len();
    let (r0, r1, r2, r3, r4) = (
        &r[..m],
        &r[1..m + 1],
        &r[2..m + 2],
        &r[3..m + 3],
        &r[4..m + 4],
    );
    let (xb, xt, xa) = (&x[1..m + 1], &x[2..m + 2], &x[3..m + 3]);
    for (i, out) in sizes.iter_mut().enumerate() {
        let rt = r2[i];
        let size = rt.abs();
        let (xt, xb, xa) = (f64::from(xt[i]), f64::from(xb[i]), f64::from(xa[i]));
        let (before, after) = (xt - xb, xt - xa);
        let echo =
            |ru: f64| (ru * rt < 0.0) & (ru.abs() >= 0.25 * size) & (ru.abs() <= 0.75 * size);
        let spike = (size > 0.0)
            & (before * after > 0.0)
            & (before.abs().min(after.abs()) >= 0.5 * size)
            & echo(r1[i])
            & echo(r3[i])
            & (3.0 * r0[i].abs().max(r4[i].abs()) < size);
        *out = if spike { size } else { 0.0 };
    }
}

/// The three largest one-step spikes of `x`: (size, step), largest first (size 0: none).
///
/// A spike is judged on the residual `r[t] = x[t] - (x[t-1] + x[t+1]) / 2`, the value's distance
/// from the line through its neighbours: a smooth motion, however fast, keeps it small (it is
/// the curvature), a one-step glitch of size s makes it s. The size is `|r[t]|`, when
/// - it goes out and back: above (or below) both neighbours by at least half its size on each
///   side (a held sample has one flat flank, an uneven step of a motion lies between its
///   neighbours: timing artefacts, not glitches of the value);
/// - both neighbours' residuals are the glitch's echo, of the other sign, at least a quarter of
///   it and at most three quarters (a single step out and back makes them half of it; a V, where
///   a hand closes and opens, keeps its neighbours on the line through theirs; a zig-zag of
///   teleoperation noise, each step out and back, makes them as large as it);
/// - it stands out from the curvature around it: three times the residuals two steps away (the
///   turning point of a fast motion bends its surroundings too).
///
/// Every step's size is computed first, without branches (the loop vectorizes), then the three
/// largest picked.
#[inline(always)]
pub fn largest(x: &[f32], scratch: &mut Scratch) -> [Spike; 3] {
    let n = x.len();
    if n < 3 {
        return [Spike::default(); 3];
    }
    residuals(x, &mut scratch.r);
    let r = &scratch.r;
    let size_at = |t: usize| -> f64 {
        let rt = r[t];
        let size = rt.abs();
        let echo =
            |u: usize| r[u] * rt < 0.0 && r[u].abs() >= 0.25 * size && r[u].abs() <= 0.75 * size;
        let around = |u: Option<usize>| u.filter(|&u| u < n).map_or(0.0, |u| r[u].abs());
        let (xt, xb, xa) = (f64::from(x[t]), f64::from(x[t - 1]), f64::from(x[t + 1]));
        let (before, after) = (xt - xb, xt - xa);
        let spike = size > 0.0
            && before * after > 0.0
            && before.abs().min(after.abs()) >= 0.5 * size
            && (t < 2 || echo(t - 1))
            && (t + 2 >= n || echo(t + 1))
            && 3.0 * around(t.checked_sub(2)).max(around(Some(t + 2))) < size;
        if spike {
            size
        } else {
            0.0
        }
    };
    let sizes = &mut scratch.sizes;
    sizes.clear();
    sizes.resize(n, 0.0);
    sizes[1] = size_at(1);
    sizes[n - 2] = size_at(n - 2);
    // The steps with both neighbours' neighbours inside the episode: every condition applies.
    if n >= 5 {
        interior_sizes(x, r, &mut sizes[2..n - 2]);
    }
    top3(&sizes[..n - 1])
}

/// Every step's distance from the line through its neighbours,
/// `r[t] = x[t] - (x[t-1] + x[t+1]) / 2`, into `r` (`n` values; 0 at the two ends). `-2 r[t]`
/// is the second difference at `t`.
#[inline(always)]
pub fn residuals(x: &[f32], r: &mut Vec<f64>) {
    let n = x.len();
    r.clear();
    if n < 3 {
        r.resize(n, 0.0);
        return;
    }
    r.push(0.0);
    r.extend(
        x[..n - 2]
            .iter()
            .zip(&x[1..n - 1])
            .zip(&x[2..])
            .map(|((&a, &b), &c)| f64::from(b) - 0.5 * (f64::from(a) + f64::from(c))),
    );
    r.push(0.0);
}

/// The three largest of every step's `sizes` but the first: (size, step), largest first (of
/// equal sizes the earlier step; size 0: none).
#[inline(always)]
pub fn top3(sizes: &[f64]) -> [Spike; 3] {
    // Most columns have no candidate at all: with every size 0 the search below keeps the
    // first three steps, found here in one pass that vectorizes.
    if sizes.len() > 3 && largest_size(sizes) <= 0.0 {
        return std::array::from_fn(|k| Spike {
            size: 0.0,
            step: k as u32 + 1,
        });
    }
    let mut top = [Spike::default(); 3];
    // Kept in order as the steps go by (size descending, then step).
    let mut kept = 0;
    for (c, chunk) in sizes.chunks(8).enumerate() {
        // Most steps are no spike (size 0): a chunk below the third largest is skipped whole.
        let most = chunk.iter().fold(0.0f64, |m, &v| m.max(v));
        if kept == 3 && most as f32 <= top[2].size {
            continue;
        }
        for (i, &size) in chunk.iter().enumerate() {
            let t = 8 * c + i;
            if t == 0 {
                continue;
            }
            let size = size as f32;
            if kept == 3 && size <= top[2].size {
                continue;
            }
            let at = top[..kept]
                .iter()
                .position(|p| size > p.size)
                .unwrap_or(kept);
            if kept < 3 {
                kept += 1;
            }
            top.copy_within(at..kept - 1, at + 1);
            top[at] = Spike {
                size,
                step: t as u32,
            };
        }
    }
    top
}

/// The largest of `sizes` (non-negative), four lanes at a time.
#[inline(always)]
fn largest_size(sizes: &[f64]) -> f64 {
    let mut lanes = [0.0f64; 4];
    let chunks = sizes.chunks_exact(4);
    let tail = chunks.remainder();
    for c in chunks {
        for l in 0..4 {
            lanes[l] = lanes[l].max(c[l]);
        }
    }
    tail.iter().chain(&lanes).fold(0.0, |m, &v| m.max(v))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn of(x: &[f64]) -> [Spike; 3] {
        let x: Vec<f32> = x.iter().map(|&v| v as f32).collect();
        largest(&x, &mut Scratch::default())
    }

    /// The three largest spikes, largest first (of equal sizes, the earlier step first).
    #[test]
    fn keeps_the_three_largest_in_order() {
        let mut x: Vec<f64> = (0..200).map(|t| (t as f64 * 0.05).sin()).collect();
        for (t, s) in [(20, 1.0), (50, 3.0), (90, 2.0), (130, 3.0), (170, 0.5)] {
            x[t] += s;
        }
        let got: Vec<(u32, f32)> = of(&x).iter().map(|s| (s.step, s.size)).collect();
        assert_eq!(
            got.iter().map(|g| g.0).collect::<Vec<_>>(),
            vec![50, 130, 90]
        );
        assert!((got[0].1 - 3.0).abs() < 0.01 && (got[2].1 - 2.0).abs() < 0.01);
        // No spike at all: the first three steps, size 0.
        let flat: Vec<f64> = (0..50).map(|t| t as f64).collect();
        let got: Vec<(u32, f32)> = of(&flat).iter().map(|s| (s.step, s.size)).collect();
        assert_eq!(got, vec![(1, 0.0), (2, 0.0), (3, 0.0)]);
        // Against sorting every step but the first by size (then step): sparse sizes, ties,
        // none at all, and short columns.
        let mut r = 7u64;
        for case in 0..300 {
            let n = case % 40;
            let sizes: Vec<f64> = (0..n)
                .map(|_| {
                    r = r
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let u = (r >> 40) % 16;
                    if u < 12 || case % 3 == 0 {
                        0.0
                    } else {
                        (u % 3) as f64 * 0.5
                    }
                })
                .collect();
            let mut want: Vec<(u32, f32)> = (1..n).map(|t| (t as u32, sizes[t] as f32)).collect();
            want.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
            want.resize(3, (0, 0.0));
            let got: Vec<(u32, f32)> = top3(&sizes).iter().map(|s| (s.step, s.size)).collect();
            assert_eq!(got, want, "{sizes:?}");
        }
        // Short columns: a spike at step 1 from three steps on, nothing to panic at.
        for n in 0..8 {
            let x: Vec<f64> = (0..n).map(|t| if t == 1 { 5.0 } else { 0.0 }).collect();
            let s = of(&x);
            assert_eq!(s[0].size > 0.0, n >= 3, "{n}");
        }
    }
}
