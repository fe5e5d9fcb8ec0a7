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
//! - **jump**: a one-step spike, a value above (or below) both neighbours by more than
//!   `jump_threshold` robust standard deviations of the dimension's step changes on both sides.
//!   The reference is the median over episodes of each episode's MAD of step changes, after
//!   dividing every episode by its units factor, so a units-changed episode is not "full of
//!   jumps", and a few spikes do not inflate it. Both flanks must be steep: a gripper or hand
//!   closing in one step is a step, not a glitch. And both must be over twice the steps that
//!   lead into and out of them: the turning point of a fast motion (the G1 set's hand joints
//!   closing and opening within a few steps, in a dimension that is otherwise still) is not one.

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
    /// The largest spikes (the smaller flank of a step above or below both neighbours), largest
    /// first: (size, step).
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
    let (mut start, mut best) = (0usize, (1usize, 0usize, x[0]));
    for t in 1..=n {
        if t == n || x[t] != x[start] {
            if t - start > best.0 {
                best = (t - start, start, x[start]);
            }
            start = t;
        }
    }
    out.run = best;
    let steps: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    out.unchanged = steps.iter().filter(|s| **s == 0.0).count() as f64 / steps.len().max(1) as f64;
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

/// The three largest one-step spikes of `x`: (size, step), largest first (size 0: none).
fn spikes(x: &[f64]) -> Vec<(f64, usize)> {
    let n = x.len();
    // A spike leaves both neighbours on the same side: its size is the smaller flank (a step,
    // a gripper closing, has one flank only).
    let mut spikes: Vec<(f64, usize)> = (1..n.saturating_sub(1))
        .map(|t| {
            let (before, after) = (x[t] - x[t - 1], x[t] - x[t + 1]);
            let flank = before.abs().min(after.abs());
            // ... and its neighbours agree with each other (a glitch returns to the signal) ...
            let returns = (x[t + 1] - x[t - 1]).abs() <= 0.5 * flank;
            // ... and it stands out from the motion around it: the turning point of a fast
            // motion (a hand closing and opening again) has flanks no steeper than the steps
            // that lead into and out of it.
            let lead_in = if t >= 2 {
                (x[t - 1] - x[t - 2]).abs()
            } else {
                0.0
            };
            let lead_out = if t + 2 < n {
                (x[t + 2] - x[t + 1]).abs()
            } else {
                0.0
            };
            let stands_out = flank > 2.0 * lead_in.max(lead_out);
            let size = if before * after > 0.0 && returns && stands_out {
                flank
            } else {
                0.0
            };
            (size, t)
        })
        .collect();
    spikes.sort_by(|p, q| q.0.total_cmp(&p.0).then(p.1.cmp(&q.1)));
    spikes.truncate(3);
    spikes
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
