//! Signal quality of the action channel, per episode and dimension (the checks lerobot-doctor
//! makes, made robust): frozen dimensions, clipped runs, one-step spikes, and dimensions constant
//! over the whole dataset.
//!
//! Each is measured against the dimension's own motion and range, because real joints sit still
//! for most of an episode, move in quantized steps (servo ticks: the median step is 0) or are
//! not used at all, and a reference taken over every step (the robust std of the step changes)
//! is then the sensor's noise, against which every real motion looks like a fault. Calibrated on
//! real LeRobot datasets of six robots (book: doctor.md, "Calibrated on real data").
//!
//! - **frozen**: the longest run of one exact value covers at least `frozen_fraction` of the
//!   episode and at least twice the dimension's median over the episodes (a joint that rests
//!   for half of most episodes rests), in a dimension where at most a tenth of the other
//!   episodes hold that long (a dimension unused in many episodes is `stuck`, a dataset-wide
//!   warning, not a fault of each), at a value that is not the dimension's dataset-wide min or
//!   max (a hand closed on an object holds its limit).
//! - **clipped**: at least `clip_fraction` of the steps sit exactly at the episode's max (or min)
//!   in two or more runs of two or more steps, each entered and left moving (a step of at least
//!   0.15 times the episode's 90th percentile of its non-zero steps and three quanta, its
//!   smallest non-zero step, on each side: a joint at rest decelerates into its extreme, down
//!   to single servo ticks; a saturated command runs into the same ceiling again and again),
//!   none at the episode's start or end (a rest pose), at a bound inside the range
//!   the other episodes reach, in a dimension whose median episode does not sit at its bounds.
//! - **jump**: a one-step spike: a value off the line through its two neighbours, going out and
//!   straight back ([`spikes::largest`]), by more than `jump_threshold` times the dimension's
//!   motion scale and `jump_range` of its range over the dataset. The motion scale is the median
//!   over episodes of each episode's 90th percentile of that same distance at the steps where
//!   the dimension moves: how much the dimension's real motion bends from one step to the next.
//!   A still or quantized dimension has no step sigma to speak of, but a scale of its motion
//!   all the same; a dimension whose range is its noise (an arm that is not used) has a motion
//!   scale of the size of its range. A spike that fails those tests (its neighbours carry a
//!   fast motion's curvature besides its echo, or the dimension's steps make its motion scale
//!   large) is judged again by its return ([`returns::largest`]): beyond `jump_range` of the
//!   range and three quarters of `jump_threshold` times the dimension's return scale, how far
//!   its real motion goes out and comes back in one step. Episodes in other units are measured
//!   in the dataset's.

use super::p90::{p90_of_bits, p90_skipping};
use super::{returns, spikes};

/// One episode's per-dimension signal features, compact (kept for every episode until the
/// judgement): the values are the source's own single precision, the shares are counts (the
/// judgement divides them by the steps).
#[derive(Debug, Clone, Copy, Default)]
pub struct DimSignal {
    /// The longest run of one exact value.
    pub run: Run,
    /// Steps at the episode's max (or min) in runs of two or more (see [`dim_signal`]).
    pub clip_steps: u32,
    /// How many runs `clip_steps` counts.
    pub clip_runs: u32,
    /// Whether `clip_steps` counts the max (else the min).
    pub clip_max: bool,
    /// Steps equal to the step before.
    pub unchanged: u32,
    /// The 90th percentile of the distance from the line through the neighbours at the steps
    /// where the dimension moves (NaN with fewer than [`MOTION_STEPS`] such steps).
    pub motion: f32,
    /// The largest spikes (the distance from the line through the neighbours), largest first
    /// (size 0: none).
    pub spikes: [spikes::Spike; 3],
    /// The largest returns ([`returns::largest`]), largest first (size 0: none).
    pub returns: [spikes::Spike; 3],
    /// The 90th percentile, at the steps where the dimension moves, of how far it goes out and
    /// comes straight back ([`returns::back`]; NaN with fewer than [`MOTION_STEPS`] such
    /// steps).
    pub return_scale: f32,
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

/// A run at a bound counts as `clipped` when the signal enters and leaves it with a step of at
/// least this share of the episode's 90th percentile of its non-zero steps.
const CLIP_ENTRY: f64 = 0.15;

/// The fewest moving steps an episode's motion scale is taken from.
pub const MOTION_STEPS: usize = 4;

/// The share of an episode's `n` steps equal to the step before, from their count.
pub fn unchanged_share(unchanged: u32, n: usize) -> f64 {
    f64::from(unchanged) / n.saturating_sub(1).max(1) as f64
}

/// The buffers of one episode's signal features, reused from dimension to dimension.
#[derive(Default)]
pub struct Scratch {
    steps: Vec<f32>,
    keys: Vec<u32>,
    back: Vec<u32>,
    backs: Vec<f32>,
    spikes: spikes::Scratch,
}

/// The features of one column `x` (finite values) of an action whose dimensions leave a rest at
/// each step as `onsets` counts ([`returns::onsets`]).
#[inline(always)]
pub fn dim_signal(x: &[f32], onsets: &[u32], scratch: &mut Scratch) -> DimSignal {
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
    out.spikes = spikes::largest(x, &mut scratch.spikes);
    // The residuals the spike search left (of this column: it computes them from 3 steps on).
    let (r, sizes) = scratch.spikes.parts();
    out.returns = returns::largest(x, r, onsets, sizes);
    // The motion scale: the distance from the line through the neighbours at the steps where
    // the dimension moves (either neighbour differs); the return scale: how far it goes out
    // and comes back there ([`returns::back`]), its zeros counted, not kept.
    let (keys, back, backs) = (&mut scratch.keys, &mut scratch.back, &mut scratch.backs);
    returns::backs(r, backs);
    // Written without branches and in place: a step the statistic leaves out holds 0, the
    // smallest key, and the rank skips those.
    let moving = |t: usize| (x[t] != x[t - 1]) | (x[t + 1] != x[t]);
    keys.clear();
    keys.resize(n.saturating_sub(2), 0);
    let mut still = 0;
    for (t, key) in keys.iter_mut().enumerate() {
        let m = moving(t + 1);
        *key = if m {
            (r[t + 1].abs() as f32).to_bits()
        } else {
            0
        };
        still += usize::from(!m);
    }
    out.motion = p90_skipping(keys, still, 0, MOTION_STEPS);
    back.clear();
    back.resize(backs.len(), 0);
    let (mut left_out, mut back_zeros) = (0, 0);
    for (i, (&q, key)) in backs.iter().zip(back.iter_mut()).enumerate() {
        let moving = moving(i + 2);
        *key = if moving & (q > 0.0) { q.to_bits() } else { 0 };
        left_out += usize::from(!moving);
        back_zeros += usize::from(moving & (q <= 0.0));
    }
    out.return_scale = p90_skipping(back, left_out, back_zeros, MOTION_STEPS);
    if max > min {
        (out.clip_steps, out.clip_runs, out.clip_max) = clipped(x, steps, keys, (min, max));
    }
    out
}

/// The steps of `x` (its `steps`, not constant) in runs (two or more) at its max or min (its
/// `bounds`), whichever holds more, that the signal enters and leaves moving: a step of at least
/// 0.15 times the episode's 90th percentile of its non-zero steps, and of three quanta (its
/// smallest non-zero step), on each side (a joint at rest decelerates into its extreme, down to
/// single servo ticks; a saturated command runs into it), away from the episode's ends (a rest
/// pose). Returns the steps, the runs, and whether at the max; `keys` is a buffer.
#[inline(always)]
fn clipped(
    x: &[f32],
    steps: &[f32],
    keys: &mut Vec<u32>,
    (min, max): (f32, f32),
) -> (u32, u32, bool) {
    let n = x.len();
    // A run of two or more needs two steps in a row at the bound: most columns never hold
    // theirs, and then the entry step (a selection over the steps) is not needed.
    let holds = |bound: f32| {
        x.windows(2)
            .map(|w| u32::from((w[0] == bound) & (w[1] == bound)))
            .sum::<u32>()
            > 0
    };
    let (hold_max, hold_min) = (holds(max), holds(min));
    if !hold_max && !hold_min {
        return (0, 0, true);
    }
    keys.clear();
    keys.extend(
        steps
            .iter()
            .filter(|&&d| d != 0.0)
            .map(|d| d.abs().to_bits()),
    );
    let quantum = keys.iter().copied().min().map_or(0.0, f32::from_bits);
    let half = (CLIP_ENTRY * f64::from(p90_of_bits(keys, 1))).max(3.0 * f64::from(quantum));
    let brisk = |t: usize, u: usize| (f64::from(x[t]) - f64::from(x[u])).abs() >= half;
    let at = |bound: f32| {
        let (mut count, mut runs) = (0, 0);
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
            let enters = start >= 2 && brisk(start - 1, start - 2);
            let leaves = t + 1 < n && brisk(t + 1, t);
            if t - start >= 2 && enters && leaves {
                count += t - start;
                runs += 1;
            }
        }
        (count as u32, runs)
    };
    let hi = if hold_max { at(max) } else { (0, 0) };
    let lo = if hold_min { at(min) } else { (0, 0) };
    let (best, is_max) = if hi.0 >= lo.0 {
        (hi, true)
    } else {
        (lo, false)
    };
    (best.0, best.1, is_max)
}

/// The lowest and highest of finite values (∞ and -∞ when empty), eight lanes at a time.
#[inline(always)]
pub fn bounds(x: &[f32]) -> (f32, f32) {
    let (mut lo, mut hi) = ([f32::INFINITY; 8], [f32::NEG_INFINITY; 8]);
    let chunks = x.chunks_exact(8);
    let tail = chunks.remainder();
    // Compare and select (one instruction a lane): the values are finite, so `min`'s and
    // `max`'s NaN handling is not needed.
    for c in chunks {
        for l in 0..8 {
            lo[l] = if c[l] < lo[l] { c[l] } else { lo[l] };
            hi[l] = if c[l] > hi[l] { c[l] } else { hi[l] };
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
    let mut best = (1usize, 0usize);
    if unchanged > 0 {
        // The current run's length, without a branch on the values (a select); the best moves
        // only while a run grows past it, and a later run as long does not replace it.
        let mut len = 1usize;
        for (t, w) in x.windows(2).enumerate() {
            len = if w[1] == w[0] { len + 1 } else { 1 };
            if len > best.0 {
                best = (len, t + 2 - len);
            }
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
        dim_signal(&x, &vec![0; x.len()], &mut Scratch::default())
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
