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

/// One episode's per-dimension signal features.
#[derive(Debug, Clone, Default)]
pub struct DimSignal {
    /// The longest run of one exact value: (steps, first step, value).
    pub run: (usize, usize, f64),
    /// The share of steps at the episode's max or min in runs of two or more, that bound, and
    /// which (`max` or `min`).
    pub clip: (f64, f64, &'static str),
    /// The share of steps equal to the step before.
    pub unchanged: f64,
    /// 1.4826 × MAD of the step changes.
    pub step_sigma: f64,
    /// The largest spikes (the distance from the line through the neighbours), largest first:
    /// (size, step).
    pub spikes: Vec<(f64, usize)>,
    pub min: f64,
    pub max: f64,
}

/// The features of dimension `d` of a `(n, width)` array.
pub fn dim_signal(a: &[f64], n: usize, width: usize, d: usize) -> DimSignal {
    let x: Vec<f64> = (0..n).map(|t| a[t * width + d]).collect();
    let mut out = DimSignal {
        min: x.iter().copied().fold(f64::INFINITY, f64::min),
        max: x.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ..Default::default()
    };
    if n == 0 {
        return out;
    }
    out.run = longest_run(&x);
    let steps: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    out.unchanged = unchanged_share(&x);
    out.step_sigma = if steps.is_empty() {
        0.0
    } else {
        super::stats::mad_sigma(&steps)
    };
    if out.max > out.min {
        // Steps in runs (two or more) at `bound` that the signal enters and leaves moving: a
        // full step of at least half the episode's typical step on each side (a hand at rest
        // decelerates into its extreme; a saturated command runs into it).
        let brisk = |t: usize, u: usize| (x[t] - x[u]).abs() >= 0.5 * out.step_sigma;
        let at = |bound: f64| {
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
            count
        };
        let (hi, lo) = (at(out.max), at(out.min));
        out.clip = if hi >= lo {
            (hi as f64 / n as f64, out.max, "max")
        } else {
            (lo as f64 / n as f64, out.min, "min")
        };
    }
    out.spikes = spikes(&x);
    out
}

/// How dimension `d` of a `(n, width)` array holds still: its longest run of one exact value
/// (steps) and the share of steps equal to the step before (what `stuck` judges of the state).
pub fn held(a: &[f64], n: usize, width: usize, d: usize) -> (usize, f64) {
    if n == 0 {
        return (0, 0.0);
    }
    let x: Vec<f64> = (0..n).map(|t| a[t * width + d]).collect();
    (longest_run(&x).0, unchanged_share(&x))
}

/// The longest run of one exact value: (steps, first step, value); `x` is not empty.
fn longest_run(x: &[f64]) -> (usize, usize, f64) {
    let n = x.len();
    let (mut start, mut best) = (0usize, (1usize, 0usize, x[0]));
    for t in 1..=n {
        if t == n || x[t] != x[start] {
            if t - start > best.0 {
                best = (t - start, start, x[start]);
            }
            start = t;
        }
    }
    best
}

/// The share of steps equal to the step before.
fn unchanged_share(x: &[f64]) -> f64 {
    let same = x.windows(2).filter(|w| w[1] == w[0]).count();
    same as f64 / x.len().saturating_sub(1).max(1) as f64
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
fn spikes(x: &[f64]) -> Vec<(f64, usize)> {
    let n = x.len();
    let r = |t: usize| {
        if t == 0 || t + 1 >= n {
            0.0
        } else {
            x[t] - 0.5 * (x[t - 1] + x[t + 1])
        }
    };
    // The three largest, kept in order as the steps go by (size descending, then step).
    let mut top: Vec<(f64, usize)> = Vec::with_capacity(4);
    for t in 1..n.saturating_sub(1) {
        let rt = r(t);
        let size = rt.abs();
        let echo = |u: usize| {
            let ru = r(u);
            ru * rt < 0.0 && ru.abs() >= 0.25 * size
        };
        let around = |u: Option<usize>| u.filter(|&u| u < n).map_or(0.0, |u| r(u).abs());
        // Out and back: above (or below) both neighbours, by at least half its size on each
        // side. A held sample (one flank flat) or an uneven step of a motion (between its
        // neighbours) is a timing artefact, not a glitch of the value.
        let (before, after) = (x[t] - x[t - 1], x[t] - x[t + 1]);
        let spike = size > 0.0
            && before * after > 0.0
            && before.abs().min(after.abs()) >= 0.5 * size
            && (t < 2 || echo(t - 1))
            && (t + 2 >= n || echo(t + 1))
            && 3.0 * around(t.checked_sub(2)).max(around(Some(t + 2))) < size;
        let size = if spike { size } else { 0.0 };
        if top.len() == 3 && size <= top[2].0 {
            continue;
        }
        let at = top.iter().position(|p| size > p.0).unwrap_or(top.len());
        top.insert(at, (size, t));
        top.truncate(3);
    }
    top
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_bounds_and_spikes() {
        let mut x: Vec<f64> = (0..100).map(|t| (t as f64 * 0.1).sin()).collect();
        x[40] += 5.0;
        let s = dim_signal(&x, 100, 1, 0);
        assert_eq!(s.spikes[0].1, 40);
        assert!(s.spikes[0].0 > 4.0);
        let step: Vec<f64> = (0..100).map(|t| if t < 50 { 0.0 } else { 1.0 }).collect();
        assert_eq!(dim_signal(&step, 100, 1, 0).spikes[0].0, 0.0);
        // A still dimension that closes and opens fast (as G1's hand joints do): a V, not a spike.
        let v: Vec<f64> = (0..100)
            .map(|t| 0.6 - 0.1 * (5.0 - (t as f64 - 50.0).abs()).max(0.0))
            .collect();
        assert_eq!(dim_signal(&v, 100, 1, 0).spikes[0].0, 0.0);
        // A spike riding a fast ramp is as big as on a still signal: its distance from the line.
        let mut ramp: Vec<f64> = (0..100).map(|t| 0.3 * t as f64).collect();
        ramp[60] += 1.5;
        let s = dim_signal(&ramp, 100, 1, 0);
        assert_eq!(s.spikes[0].1, 60);
        assert!((s.spikes[0].0 - 1.5).abs() < 1e-9);
        // Timing artefacts of a motion are not spikes: a held sample, an uneven step.
        let mut hold: Vec<f64> = (0..100).map(|t| 0.3 * t as f64).collect();
        hold[60] = hold[59];
        assert_eq!(dim_signal(&hold, 100, 1, 0).spikes[0].0, 0.0);
        let mut uneven: Vec<f64> = (0..100).map(|t| 0.3 * t as f64).collect();
        uneven[60] -= 0.2;
        assert_eq!(dim_signal(&uneven, 100, 1, 0).spikes[0].0, 0.0);
        let held: Vec<f64> = (0..100)
            .map(|t| if t < 30 { t as f64 } else { 30.0 })
            .collect();
        let s = dim_signal(&held, 100, 1, 0);
        assert_eq!((s.run.0, s.run.1), (70, 30));
        let clipped: Vec<f64> = (0..100).map(|t| (t as f64 * 0.2).sin().min(0.5)).collect();
        let s = dim_signal(&clipped, 100, 1, 0);
        assert_eq!(s.clip.2, "max");
        assert!(s.clip.0 > 0.2);
    }
}
