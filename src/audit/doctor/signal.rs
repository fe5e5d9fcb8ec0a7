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
//!   two steps away ([`spikes::largest`]). Measured from the line, not from each neighbour, a spike riding
//!   on a fast motion is as visible as one on a still signal. The reference is the median over
//!   episodes of each episode's MAD of step changes, after dividing every episode by its units
//!   factor, so a units-changed episode is not "full of jumps", and a few spikes do not inflate
//!   it. A gripper or hand closing in one step is a step (one neighbour on each side of the
//!   line, no echo), and the turning point of a fast motion (the G1 set's hand joints closing
//!   and opening within a few steps) bends the steps around it: neither is a spike.

use super::spikes;

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
    pub spikes: [spikes::Spike; 3],
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
    spikes: spikes::Scratch,
}

/// The features of one column `x` (finite values).
#[inline(always)]
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
    let steps = &mut scratch.steps;
    steps.clear();
    steps.extend(x[1..].iter().zip(x).map(|(b, a)| b - a));
    // A step of 0 is a value equal to the one before (finite values).
    out.unchanged = steps.iter().map(|&d| u32::from(d == 0.0)).sum();
    out.run = longest_run(x, out.unchanged);
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
    out.spikes = spikes::largest(x, &mut scratch.spikes);
    out
}

/// The lowest and highest value (∞ and -∞ when empty), eight lanes at a time.
#[inline(always)]
pub fn bounds(x: &[f32]) -> (f32, f32) {
    let (mut lo, mut hi) = ([f32::INFINITY; 8], [f32::NEG_INFINITY; 8]);
    let chunks = x.chunks_exact(8);
    let tail = chunks.remainder();
    for c in chunks {
        for l in 0..8 {
            lo[l] = lo[l].min(c[l]);
            hi[l] = hi[l].max(c[l]);
        }
    }
    for (l, &v) in tail.iter().enumerate() {
        lo[l] = lo[l].min(v);
        hi[l] = hi[l].max(v);
    }
    (
        lo.into_iter().fold(f32::INFINITY, f32::min),
        hi.into_iter().fold(f32::NEG_INFINITY, f32::max),
    )
}

/// How a column holds still: its longest run of one exact value (steps) and the number of
/// steps equal to the step before (what `stuck` judges of the state).
#[inline(always)]
pub fn held(x: &[f32]) -> (u32, u32) {
    if x.is_empty() {
        return (0, 0);
    }
    let unchanged = x[1..].iter().zip(x).map(|(b, a)| u32::from(b == a)).sum();
    (longest_run(x, unchanged).len, unchanged)
}

/// The longest run of one exact value (the first of the longest) of `x` (not empty), whose
/// `unchanged` steps equal the one before: none, and every run is one step long.
#[inline(always)]
fn longest_run(x: &[f32], unchanged: u32) -> Run {
    let (mut start, mut best) = (0usize, (1usize, 0usize));
    if unchanged > 0 {
        // A run ends where a value differs from the one before.
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
    }
    Run {
        len: best.0 as u32,
        start: best.1 as u32,
        value: x[best.1],
    }
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
}
