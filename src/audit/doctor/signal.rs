//! Signal quality of the action channel, per episode and dimension (the checks lerobot-doctor
//! makes, made robust): frozen dimensions, clipped runs, one-step spikes, and dimensions constant
//! over the whole dataset.
//!
//! - **frozen**: the longest run of one exact value covers at least `frozen_fraction` of the
//!   episode, in a dimension that does not hold still like that in most episodes (a gripper that
//!   never moves in the dataset is `constant`, not frozen).
//! - **clipped**: at least `clip_fraction` of the steps sit exactly at the episode's max (or min)
//!   in runs of two or more, in a dimension whose median episode does not (binary grippers sit
//!   at their bounds by design).
//! - **jump**: a step departs from the midpoint of its neighbours by more than `jump_threshold`
//!   robust standard deviations of the dimension's step changes. The reference is the median over
//!   episodes of each episode's MAD of step changes, after dividing every episode by its units
//!   factor, so a units-changed episode is not "full of jumps", and a few spikes do not inflate
//!   it. A midpoint departure catches spikes and leaves steady ramps alone.

/// One episode's per-dimension signal features.
#[derive(Debug, Clone, Default)]
pub struct DimSignal {
    /// The longest run of one exact value: (steps, first step, value).
    pub run: (usize, usize, f64),
    /// The share of steps at the episode's max or min in runs of two or more, that bound, and
    /// which (`max` or `min`).
    pub clip: (f64, f64, &'static str),
    /// 1.4826 × MAD of the step changes.
    pub step_sigma: f64,
    /// The largest departures from the neighbours' midpoint: (|departure|, step), largest first.
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
    if out.max > out.min {
        let at = |bound: f64| {
            (0..n)
                .filter(|&t| {
                    x[t] == bound
                        && ((t > 0 && x[t - 1] == bound) || (t + 1 < n && x[t + 1] == bound))
                })
                .count()
        };
        let (hi, lo) = (at(out.max), at(out.min));
        out.clip = if hi >= lo {
            (hi as f64 / n as f64, out.max, "max")
        } else {
            (lo as f64 / n as f64, out.min, "min")
        };
    }
    let steps: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    out.step_sigma = if steps.is_empty() {
        0.0
    } else {
        super::stats::mad_sigma(&steps)
    };
    let mut spikes: Vec<(f64, usize)> = (1..n.saturating_sub(1))
        .map(|t| ((x[t] - 0.5 * (x[t - 1] + x[t + 1])).abs(), t))
        .collect();
    spikes.sort_by(|p, q| q.0.total_cmp(&p.0).then(p.1.cmp(&q.1)));
    spikes.truncate(3);
    out.spikes = spikes;
    out
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
