//! Spikes that return (issue 50): the `jump` check's second judgement of a one-step spike, by
//! its return signature rather than its distance from the line through its neighbours.
//!
//! A value that goes out for one step and comes straight back leaves the line of the two steps
//! before it by as much as the line of the two steps after it, the same way:
//! `e_l = x[t] - (2x[t-1] - x[t-2])` and `e_r = x[t] - (2x[t+1] - x[t+2])` (the second
//! differences at `t - 1` and `t + 1`) are both about the spike's size, whatever the motion's
//! speed (a line's second difference is 0). A step of a motion changes one of them only, a fast
//! motion bends both by its curvature, which the second differences two steps away (without
//! `x[t]`) measure too, and a zig-zag of teleoperation noise makes those as large.
//!
//! [`super::spikes`]' judgement asks more of a spike's surroundings: its neighbours must be its
//! exact echo, which a spike on a fast or curving motion is not (the motion's curvature adds to
//! each), and it is measured against the dimension's motion scale, which a joint that rests and
//! then moves in large steps makes as large as its steps. This one measures the excursion
//! against the dimension's own returns: how far its real motion goes out and comes back in one
//! step, which a step, a ramp or a servo's held ticks do not.

use super::spikes::{self, Spike};

/// A return must exceed this many times the calmer side's second difference two steps away ...
const OVER_CALM: f64 = 3.0;

/// ... and the busier side's.
const OVER_BUSY: f64 = 1.0;

/// Each of the two steps, out and back, is at least this share of the excursion (a held or
/// uneven sample of a motion lies on one side of the excursion: a timing artefact, not a glitch
/// of the value).
const STEP_SHARE: f64 = 0.4;

/// A return at a step where this many other action dimensions leave a rest ...
const ONSET_OTHERS: u32 = 2;

/// ... (the same value for this many steps before; a quantized command holds two or three
/// samples as it moves) and do not come back is the start of a teleoperator's input across the
/// action (robosuite's spacemouse, issue 50), not a glitch of one value.
const REST: usize = 4;

/// Per step, how many of the action's dimensions leave a rest there ([`leaves_rest`]).
#[inline(always)]
pub fn onsets(columns: &[&[f32]], n: usize) -> Vec<u32> {
    let mut count = vec![0u32; n];
    if n > REST + 1 {
        // The steps `REST..n - 1`, from equally long slices, one per offset (the loop
        // vectorizes).
        let m = n - 1 - REST;
        for x in columns {
            let (a, b, c, d) = (&x[..m], &x[1..m + 1], &x[2..m + 2], &x[3..m + 3]);
            let (now, next) = (&x[4..m + 4], &x[5..m + 5]);
            for (i, out) in count[REST..n - 1].iter_mut().enumerate() {
                let rest = (a[i] == d[i]) & (b[i] == d[i]) & (c[i] == d[i]);
                *out += u32::from(rest & (now[i] != d[i]) & (next[i] != d[i]));
            }
        }
    }
    count
}

/// Whether `x` leaves a rest at step `t`: `x[t-4] == .. == x[t-1] != x[t]`, and `x[t+1] !=
/// x[t-1]` (it does not come back; false at the first four steps and the last).
#[inline(always)]
fn leaves_rest(x: &[f32], t: usize) -> bool {
    t >= REST
        && t + 1 < x.len()
        && x[t - REST..t].iter().all(|&v| v == x[t - 1])
        && x[t] != x[t - 1]
        && x[t + 1] != x[t - 1]
}

/// The smaller of two finite values (`f64::min` also orders NaN, which costs a blend a step).
#[inline(always)]
fn lesser(a: f64, b: f64) -> f64 {
    if a < b {
        a
    } else {
        b
    }
}

/// The excursion at a step (its value and its neighbours' `x`) when it returns, from the
/// residuals of [`spikes::residuals`] at its neighbours, `rl` and `rr` (`-2 r[u]` is the second
/// difference at `u`), else 0. `calm` and `busy` are the smaller and the larger of the residuals
/// two steps away (0 where a side is missing).
#[inline(always)]
fn excursion(x: [f32; 3], rl: f64, rr: f64, calm: f64, busy: f64) -> f64 {
    let half = lesser(rl.abs(), rr.abs());
    let (before, after) = (
        f64::from(x[1]) - f64::from(x[0]),
        f64::from(x[1]) - f64::from(x[2]),
    );
    let spike = (rl * rr > 0.0)
        & (before * rl < 0.0)
        & (before * after > 0.0)
        & (lesser(before.abs(), after.abs()) >= STEP_SHARE * 2.0 * half)
        & (half > OVER_CALM * calm)
        & (half > OVER_BUSY * busy);
    if spike {
        2.0 * half
    } else {
        0.0
    }
}

/// The three largest returns of `x` (`n` at least 5): (size, step), largest first (size 0:
/// none), from its residuals `r` and the action's [`onsets`]; `sizes` is a buffer.
///
/// A return at step `t` (in `2..n - 2`) is `min(|e_l|, |e_r|)` when the two are of one sign,
/// the value lies beyond both neighbours that way, each of its two steps is at least 0.4 of
/// it, it exceeds three times the calmer of the second differences two steps away and the
/// busier one, and fewer than two other action dimensions leave a rest at `t`.
#[inline(always)]
pub fn largest(x: &[f32], r: &[f64], onsets: &[u32], sizes: &mut Vec<f64>) -> [Spike; 3] {
    let n = x.len();
    sizes.clear();
    sizes.resize(n, 0.0);
    if n < 5 {
        return spikes::top3(sizes);
    }
    // The ends: a side whose second difference two steps away lies outside the episode is
    // missing (the other alone is the calm one, and there is no busy one).
    let side = |u: Option<usize>| u.filter(|&u| u >= 1 && u + 1 < n).map(|u| r[u].abs());
    for t in [2, n - 3] {
        let (calm, busy) = match (side(t.checked_sub(2)), side(Some(t + 2))) {
            (Some(a), Some(b)) => (a.min(b), a.max(b)),
            (Some(s), None) | (None, Some(s)) => (s, 0.0),
            (None, None) => (0.0, 0.0),
        };
        let around = [x[t - 1], x[t], x[t + 1]];
        sizes[t] = excursion(around, r[t - 1], r[t + 1], calm, busy);
    }
    // The steps with both sides inside the episode, without branches (the loop vectorizes).
    if n > 6 {
        interior(x, r, &mut sizes[3..n - 3]);
    }
    // Not at an onset across the action: the three largest are looked at (returns are rare,
    // onsets rarer), and taken again without one that is.
    loop {
        let top = spikes::top3(sizes);
        let at_onset = |s: &&Spike| {
            let t = s.step as usize;
            s.size > 0.0 && onsets[t].saturating_sub(u32::from(leaves_rest(x, t))) >= ONSET_OTHERS
        };
        match top.iter().find(at_onset) {
            Some(s) => sizes[s.step as usize] = 0.0,
            None => return top,
        }
    }
}

/// [`largest`]' sizes of the steps `3..n - 3` of `x` into `sizes`, from the residuals `r`:
/// equally long slices, one per offset, so that the loop runs without bounds checks.
#[inline(always)]
fn interior(x: &[f32], r: &[f64], sizes: &mut [f64]) {
    let m = sizes.len();
    let (r1, r2, r4, r5) = (&r[1..m + 1], &r[2..m + 2], &r[4..m + 4], &r[5..m + 5]);
    let (xb, xt, xa) = (&x[2..m + 2], &x[3..m + 3], &x[4..m + 4]);
    for (i, out) in sizes.iter_mut().enumerate() {
        let (a, b) = (r1[i].abs(), r5[i].abs());
        let (calm, busy) = if a < b { (a, b) } else { (b, a) };
        *out = excursion([xb[i], xt[i], xa[i]], r2[i], r4[i], calm, busy);
    }
}

/// How far a step goes out and comes back, from its neighbours' residuals: `min(|e_l|, |e_r|)`
/// where the two are of one sign, else 0 (what the return scale,
/// [`super::signal::DimSignal::return_scale`], takes the 90th percentile of).
#[inline(always)]
pub fn back(rl: f64, rr: f64) -> f64 {
    if rl * rr > 0.0 {
        2.0 * lesser(rl.abs(), rr.abs())
    } else {
        0.0
    }
}

/// [`back`] of every step `2..n - 2` of a column from its residuals `r` (`n` values), in single
/// precision, into `out` (`n - 4` values; the loop vectorizes).
#[inline(always)]
pub fn backs(r: &[f64], out: &mut Vec<f32>) {
    out.clear();
    let n = r.len();
    if n >= 5 {
        out.extend(
            r[1..n - 3]
                .iter()
                .zip(&r[3..n - 1])
                .map(|(&rl, &rr)| back(rl, rr) as f32),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The largest return of one column (no other dimension), and the column's return scale
    /// (the 90th percentile of its keys).
    fn of(x: &[f64]) -> (Spike, f32) {
        let x: Vec<f32> = x.iter().map(|&v| v as f32).collect();
        let mut r = Vec::new();
        spikes::residuals(&x, &mut r);
        let onsets = onsets(&[&x], x.len());
        let top = largest(&x, &r, &onsets, &mut Vec::new());
        let mut keys: Vec<f64> = (2..x.len() - 2)
            .filter(|&t| x[t] != x[t - 1] || x[t + 1] != x[t])
            .map(|t| back(r[t - 1], r[t + 1]))
            .collect();
        keys.sort_by(f64::total_cmp);
        (top[0], keys[9 * (keys.len() - 1) / 10] as f32)
    }

    /// A fast joint: swings of 100 and back in 30 steps each (minimum jerk), resting 10 steps
    /// between; its steps reach 6.25 at mid-swing, half the spike of 12 planted there.
    fn swings(n: usize) -> Vec<f64> {
        let jerk = |u: f64| u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
        (0..n)
            .map(|t| match t % 80 {
                k if k < 10 => 0.0,
                k if k < 40 => 100.0 * jerk((k - 10) as f64 / 30.0),
                k if k < 50 => 100.0,
                k => 100.0 * (1.0 - jerk((k - 50) as f64 / 30.0)),
            })
            .collect()
    }

    #[test]
    fn a_spike_on_a_fast_joint_returns() {
        let mut x = swings(400);
        let (clean, scale) = of(&x);
        assert_eq!(clean.size, 0.0, "{clean:?}");
        let fastest = 80 + 25;
        assert!((x[fastest + 1] - x[fastest]) > 6.0);
        x[fastest] += 12.0;
        let (spike, _) = of(&x);
        assert_eq!(spike.step, fastest as u32);
        assert!((spike.size - 12.0).abs() < 0.5, "{spike:?}");
        assert!(f64::from(spike.size) > 6.0 * f64::from(scale), "{scale}");
        // The line judgement does not take it: its step back is less than half the spike.
        let xs: Vec<f32> = x.iter().map(|&v| v as f32).collect();
        let line = spikes::largest(&xs, &mut spikes::Scratch::default());
        assert!(line.iter().all(|s| s.size == 0.0), "{line:?}");
    }

    /// A still joint that moves in rare large steps (a hand joint's commands): the steps are not
    /// returns, a spike of less than them is.
    #[test]
    fn a_spike_on_a_still_joint_returns() {
        let mut x = vec![0.0; 200];
        for v in &mut x[60..120] {
            *v = 37.0;
        }
        let (clean, scale) = of(&x);
        assert_eq!((clean.size, scale), (0.0, 0.0));
        x[150] += 61.0;
        x[30] -= 20.0;
        let (spike, _) = of(&x);
        assert_eq!((spike.step, spike.size), (150, 61.0));
    }

    /// A genuine fast step that does not come back, a held sample of a ramp, a zig-zag of
    /// teleoperation noise, a V: none returns.
    #[test]
    fn steps_holds_and_zigzags_do_not_return() {
        let step: Vec<f64> = (0..100).map(|t| if t < 50 { 0.0 } else { 60.0 }).collect();
        assert_eq!(of(&step).0.size, 0.0);
        // A fast step over two samples, overshooting by one and settling.
        let mut fast: Vec<f64> = (0..100).map(|t| if t < 50 { 0.0 } else { 60.0 }).collect();
        fast[50] = 35.0;
        fast[51] = 64.0;
        assert_eq!(of(&fast).0.size, 0.0);
        let mut hold: Vec<f64> = (0..100).map(|t| 3.0 * t as f64).collect();
        hold[60] = hold[59];
        assert_eq!(of(&hold).0.size, 0.0);
        let zigzag: Vec<f64> = (0..100)
            .map(|t| {
                if (40..48).contains(&t) {
                    [1.0, -1.0][t % 2]
                } else {
                    0.0
                }
            })
            .collect();
        assert_eq!(of(&zigzag).0.size, 0.0);
        let v: Vec<f64> = (0..100).map(|t| (t as f64 - 50.0).abs()).collect();
        assert_eq!(of(&v).0.size, 0.0);
    }

    /// A one-step excursion where two other dimensions start to move from rest is the start of
    /// an input.
    #[test]
    fn an_onset_across_the_action_is_not_a_glitch() {
        let n = 60;
        let mut spike = vec![0.0f32; n];
        spike[30] = 0.2;
        let starts = |from: usize| -> Vec<f32> {
            (0..n)
                .map(|t| {
                    if t >= from {
                        0.1 * (t - from + 1) as f32
                    } else {
                        0.0
                    }
                })
                .collect()
        };
        let (a, b) = (starts(30), starts(30));
        let mut r = Vec::new();
        spikes::residuals(&spike, &mut r);
        let alone = onsets(&[&spike, &a], n);
        assert_eq!(largest(&spike, &r, &alone, &mut Vec::new())[0].step, 30);
        let both = onsets(&[&spike, &a, &b], n);
        assert_eq!(largest(&spike, &r, &both, &mut Vec::new())[0].size, 0.0);
        // Quantized commands that move on, each value held for two samples, are no onset.
        let ticks: Vec<f32> = (0..n).map(|t| 0.1 * (t / 2) as f32).collect();
        let moving = onsets(&[&spike, &ticks, &ticks], n);
        assert_eq!(largest(&spike, &r, &moving, &mut Vec::new())[0].step, 30);
    }
}
