//! Signal quality of the action channel, per episode and dimension (the checks lerobot-doctor
//! makes, made robust): frozen dimensions, clipped runs, one-step spikes, and dimensions constant
//! over the whole dataset.
//!
//! - **frozen**: the longest run of one exact value covers at least `frozen_fraction` of the
//!   episode, in a dimension that does not hold still like that in most episodes (a gripper that
//!   never moves in the dataset is `constant`, not frozen), at a value that is not the
//!   dimension's dataset-wide min or max (a hand closed on an object holds its limit).
//! - **clipped**: at least `clip_fraction` of the steps sit exactly at the episode's max (or min)
//!   in runs of two or more that the signal enters and leaves moving (a full step of at least
//!   half the episode's typical step on each side: a hand at rest decelerates into its extreme,
//!   a saturated command runs into it), at a bound inside the range the other episodes reach
//!   (a hand fully closed sits at the dataset's limit by design), in a dimension whose median
//!   episode does not sit at its bounds.
//! - **jump**: a one-step spike: a value off the line through its two neighbours by more than
//!   `jump_threshold` robust standard deviations of the dimension's step changes, whose
//!   neighbours echo it (a step out and straight back) and which stands out from the curvature
//!   two steps away ([`spikes`]). Measured from the line, not from each neighbour, a spike riding
//!   on a fast motion is as visible as one on a still signal. The reference is the median over
//!   episodes of each episode's MAD of step changes, after dividing every episode by its units
//!   factor, so a units-changed episode is not "full of jumps", and a few spikes do not inflate
//!   it. A gripper or hand closing in one step is a step (one neighbour on each side of the
//!   line, no echo), and the turning point of a fast motion (the G1 set's hand joints closing
//!   and opening within a few steps) bends the steps around it: neither is a spike.

/// One episode's per-dimension signal features, compact (kept for every episode until the
/// judgement): the values are the source's own single precision, the shares are counts (the
/// judgement divides them by the steps).
#[derive(Debug, Clone, Copy, Default)]
pub struct DimSignal {
    /// The longest run of one exact value.
    pub run: Run,
    /// Steps at the episode's max (or min) in runs of two or more (see [`dim_signal`]).
    pub clip_steps: u32,
    /// Whether `clip_steps` counts the max (else the min).
    pub clip_max: bool,
    /// Steps equal to the step before.
    pub unchanged: u32,
    /// 1.4826 × MAD of the step changes.
    pub step_sigma: f32,
    /// The largest spikes (the distance from the line through the neighbours), largest first
    /// (size 0: none).
    pub spikes: [Spike; 3],
    pub min: f32,
    pub max: f32,
}

/// A run of one exact value.
#[derive(Debug, Clone, Copy, Default)]
pub struct Run {
    pub len: u32,
    pub start: u32,
    pub value: f32,
}

/// A one-step spike: its size and step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Spike {
    pub size: f32,
    pub step: u32,
}

impl DimSignal {
    /// The clipped share of an episode of `n` steps, the bound, and which (`max` or `min`).
    pub fn clip(&self, n: usize) -> (f64, f64, &'static str) {
        let share = f64::from(self.clip_steps) / n.max(1) as f64;
        if self.clip_max {
            (share, f64::from(self.max), "max")
        } else {
            (share, f64::from(self.min), "min")
        }
    }
}

/// The share of an episode's `n` steps equal to the step before, from their count.
pub fn unchanged_share(unchanged: u32, n: usize) -> f64 {
    f64::from(unchanged) / n.saturating_sub(1).max(1) as f64
}

/// The buffers of one episode's signal features, reused from dimension to dimension.
#[derive(Default)]
pub struct Scratch {
    steps: Vec<f32>,
    keys: Vec<u32>,
    r: Vec<f64>,
    sizes: Vec<f64>,
}

/// The features of one column `x` (finite values).
pub fn dim_signal(x: &[f32], scratch: &mut Scratch) -> DimSignal {
    let n = x.len();
    let (min, max) = bounds(x);
    let mut out = DimSignal {
        min,
        max,
        ..Default::default()
    };
    if n == 0 {
        return out;
    }
    out.run = longest_run(x);
    out.unchanged = unchanged(x);
    let steps = &mut scratch.steps;
    steps.clear();
    steps.extend(x.windows(2).map(|w| w[1] - w[0]));
    out.step_sigma = if steps.is_empty() {
        0.0
    } else {
        (1.4826 * f64::from(super::stats::mad_f32(steps, &mut scratch.keys))) as f32
    };
    if max > min {
        // Steps in runs (two or more) at `bound` that the signal enters and leaves moving: a
        // full step of at least half the episode's typical step on each side (a hand at rest
        // decelerates into its extreme; a saturated command runs into it).
        let half = 0.5 * f64::from(out.step_sigma);
        let brisk = |t: usize, u: usize| (f64::from(x[t]) - f64::from(x[u])).abs() >= half;
        let at = |bound: f32| {
            let mut count = 0;
            let mut t = 0;
            while t < n {
                if x[t] != bound {
                    t += 1;
                    continue;
                }
                let start = t;
                while t < n && x[t] == bound {
                    t += 1;
                }
                let enters = start < 2 || brisk(start - 1, start - 2);
                let leaves = t + 1 >= n || brisk(t + 1, t);
                if t - start >= 2 && enters && leaves {
                    count += t - start;
                }
            }
            count as u32
        };
        // Runs of two or more need two values at the bound: most columns touch theirs once.
        let count = |bound: f32| x.iter().map(|&v| u32::from(v == bound)).sum::<u32>();
        let hi = if count(max) >= 2 { at(max) } else { 0 };
        let lo = if count(min) >= 2 { at(min) } else { 0 };
        (out.clip_steps, out.clip_max) = if hi >= lo { (hi, true) } else { (lo, false) };
    }
    out.spikes = spikes(x, scratch);
    out
}

/// The lowest and highest value (∞ and -∞ when empty).
pub fn bounds(x: &[f32]) -> (f32, f32) {
    x.iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        })
}

/// How a column holds still: its longest run of one exact value (steps) and the number of
/// steps equal to the step before (what `stuck` judges of the state).
pub fn held(x: &[f32]) -> (u32, u32) {
    if x.is_empty() {
        return (0, 0);
    }
    (longest_run(x).len, unchanged(x))
}

/// The longest run of one exact value (the first of the longest); `x` is not empty. A run ends
/// where a value differs from the one before (no chain through the run's first value).
fn longest_run(x: &[f32]) -> Run {
    let (mut start, mut best) = (0usize, (1usize, 0usize));
    for (t, w) in x.windows(2).enumerate() {
        if w[1] != w[0] {
            if t + 1 - start > best.0 {
                best = (t + 1 - start, start);
            }
            start = t + 1;
        }
    }
    if x.len() - start > best.0 {
        best = (x.len() - start, start);
    }
    Run {
        len: best.0 as u32,
        start: best.1 as u32,
        value: x[best.1],
    }
}

/// The steps equal to the step before.
fn unchanged(x: &[f32]) -> u32 {
    x.windows(2).map(|w| u32::from(w[1] == w[0])).sum()
}

/// [`spikes`]' sizes of the steps `2..n - 2` of `x` (`n` at least 5) into `sizes`, from the
/// residuals `r`: equally long slices, one per offset, so that the loop runs without bounds
/// checks (and vectorizes).
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
        let echo = |ru: f64| (ru * rt < 0.0) & (ru.abs() >= 0.25 * size);
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
/// - both neighbours' residuals are the glitch's echo, of the other sign and at least a quarter
///   of it (a single step out and back, not a V: a hand closing and opening has its neighbours
///   on the line through theirs);
/// - it stands out from the curvature around it: three times the residuals two steps away (the
///   turning point of a fast motion bends its surroundings too).
///
/// Every step's size is computed first, without branches (the loop vectorizes), then the three
/// largest picked.
fn spikes(x: &[f32], scratch: &mut Scratch) -> [Spike; 3] {
    let n = x.len();
    let mut top = [Spike::default(); 3];
    if n < 3 {
        return top;
    }
    let r = &mut scratch.r;
    r.clear();
    r.push(0.0);
    r.extend(x.windows(3).map(|w| {
        let (a, b, c) = (f64::from(w[0]), f64::from(w[1]), f64::from(w[2]));
        b - 0.5 * (a + c)
    }));
    r.push(0.0);
    let size_at = |t: usize| -> f64 {
        let rt = r[t];
        let size = rt.abs();
        let echo = |u: usize| r[u] * rt < 0.0 && r[u].abs() >= 0.25 * size;
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
    // The three largest, kept in order as the steps go by (size descending, then step).
    let mut kept = 0;
    for (c, chunk) in sizes[..n - 1].chunks(8).enumerate() {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn of(x: &[f64]) -> DimSignal {
        let x: Vec<f32> = x.iter().map(|&v| v as f32).collect();
        dim_signal(&x, &mut Scratch::default())
    }

    #[test]
    fn runs_bounds_and_spikes() {
        let mut x: Vec<f64> = (0..100).map(|t| (t as f64 * 0.1).sin()).collect();
        x[40] += 5.0;
        let s = of(&x);
        assert_eq!(s.spikes[0].step, 40);
        assert!(s.spikes[0].size > 4.0);
        let step: Vec<f64> = (0..100).map(|t| if t < 50 { 0.0 } else { 1.0 }).collect();
        assert_eq!(of(&step).spikes[0].size, 0.0);
        // A still dimension that closes and opens fast (as G1's hand joints do): a V, not a spike.
        let v: Vec<f64> = (0..100)
            .map(|t| 0.6 - 0.1 * (5.0 - (t as f64 - 50.0).abs()).max(0.0))
            .collect();
        assert_eq!(of(&v).spikes[0].size, 0.0);
        // A spike riding a fast ramp is as big as on a still signal: its distance from the line
        // (to the single precision of the values).
        let mut ramp: Vec<f64> = (0..100).map(|t| 0.3 * t as f64).collect();
        ramp[60] += 1.5;
        let s = of(&ramp);
        assert_eq!(s.spikes[0].step, 60);
        assert!((s.spikes[0].size - 1.5).abs() < 1e-5);
        // Timing artefacts of a motion are not spikes: a held sample, an uneven step.
        let mut hold: Vec<f64> = (0..100).map(|t| 0.3 * t as f64).collect();
        hold[60] = hold[59];
        assert_eq!(of(&hold).spikes[0].size, 0.0);
        let mut uneven: Vec<f64> = (0..100).map(|t| 0.3 * t as f64).collect();
        uneven[60] -= 0.2;
        assert_eq!(of(&uneven).spikes[0].size, 0.0);
        let held: Vec<f64> = (0..100)
            .map(|t| if t < 30 { t as f64 } else { 30.0 })
            .collect();
        let s = of(&held);
        assert_eq!((s.run.len, s.run.start), (70, 30));
        let clipped: Vec<f64> = (0..100).map(|t| (t as f64 * 0.2).sin().min(0.5)).collect();
        let s = of(&clipped);
        assert_eq!(s.clip(100).2, "max");
        assert!(s.clip(100).0 > 0.2);
    }

    /// The three largest spikes, in order, against a plain scan of every step's size.
    #[test]
    fn keeps_the_three_largest_in_order() {
        let mut x: Vec<f64> = (0..200).map(|t| (t as f64 * 0.05).sin()).collect();
        for (t, s) in [(20, 1.0), (50, 3.0), (90, 2.0), (130, 3.0), (170, 0.5)] {
            x[t] += s;
        }
        let got: Vec<(u32, f32)> = of(&x).spikes.iter().map(|s| (s.step, s.size)).collect();
        assert_eq!(
            got.iter().map(|g| g.0).collect::<Vec<_>>(),
            vec![50, 130, 90]
        );
        assert!((got[0].1 - 3.0).abs() < 0.01 && (got[2].1 - 2.0).abs() < 0.01);
        // No spike at all: the first three steps, size 0.
        let flat: Vec<f64> = (0..50).map(|t| t as f64).collect();
        let got: Vec<(u32, f32)> = of(&flat).spikes.iter().map(|s| (s.step, s.size)).collect();
        assert_eq!(got, vec![(1, 0.0), (2, 0.0), (3, 0.0)]);
        // Short columns: a spike at step 1 from three steps on, nothing to panic at.
        for n in 0..8 {
            let x: Vec<f64> = (0..n).map(|t| if t == 1 { 5.0 } else { 0.0 }).collect();
            let s = of(&x);
            assert_eq!(s.spikes[0].size > 0.0, n >= 3, "{n}");
        }
    }
}
