//! The judgement of the signal checks (`frozen`, `clipped`, `jump`) per action dimension,
//! against what the dimension does over the whole dataset (see [`super::signal`]).

use super::features::Features;
use super::found::Found;
use super::spikes::Spike;
use super::{signal, stats};
use crate::audit::report::Flag;
use crate::spec::DoctorSpec;

/// `frozen` needs a run this many times the other episodes' 90th percentile of theirs ...
const FROZEN_OVER_OTHERS: f64 = 1.25;

/// ... and twice their median ...
const FROZEN_OVER_MEDIAN: f64 = 2.0;

/// ... in a dimension where at most this share of the other episodes hold one value as long
/// (else it is `stuck`, a dataset-wide warning, not `frozen` in each).
const FROZEN_OTHERS_LONG: f64 = 0.1;

/// A spike judged by its return ([`super::returns`]) is flagged beyond this share of
/// `jump_threshold` times the dimension's return scale: the return signature is specific (a
/// step, a ramp, a turning point or a zig-zag has none), so it needs less margin than the
/// distance from the line. Calibrated on real data (`bench/doctor_spikes.py`): at 6 the noisiest
/// set's own returns (Bridge's 10-step deltas, up to 5.6 times their scale) stay unflagged.
const RETURN_SHARE: f64 = 0.75;

/// Frozen, clipped and jump, per action dimension against the dataset. Returns the jump check's
/// reference per dimension (the motion scale, in the dataset's units).
pub(super) fn signal_checks(
    cfg: &DoctorSpec,
    feats: &[Features],
    scale: &[f64],
    a_dim: usize,
    found: &mut Found,
) -> Vec<f64> {
    (0..a_dim)
        .map(|d| {
            let dim = DimRefs::of(cfg, feats, scale, d);
            for (e, f) in feats.iter().enumerate() {
                frozen_or_clipped(cfg, &dim, d, e, f, scale[e], found);
                jump(cfg, &dim, d, e, f, scale[e], found);
            }
            dim.motion
        })
        .collect()
}

/// What one action dimension's checks measure against, over the whole dataset.
struct DimRefs {
    /// The lowest and highest value, in the dataset's units.
    lowest: f64,
    highest: f64,
    /// The jump check's motion scale (median of the episodes' [`signal::DimSignal::motion`]).
    motion: f64,
    /// Its return scale (median of the episodes' [`signal::DimSignal::return_scale`]).
    returns: f64,
    /// Every episode's share in its longest run of one value, ascending.
    runs: Vec<f64>,
    /// Their median.
    run_median: f64,
    /// Episodes whose longest run covers `frozen_fraction`.
    long: usize,
    /// The median episode's clipped share.
    clip_median: f64,
}

impl DimRefs {
    fn of(cfg: &DoctorSpec, feats: &[Features], scale: &[f64], d: usize) -> DimRefs {
        let (lowest, highest) = stats::range(feats.iter().zip(scale).map(|(f, u)| {
            let s = &f.signal[d];
            (f64::from(s.min) / u, f64::from(s.max) / u)
        }));
        let median_of = |of: fn(&signal::DimSignal) -> f32| {
            let m = stats::median(
                feats
                    .iter()
                    .zip(scale)
                    .map(|(f, u)| f64::from(of(&f.signal[d])) / u),
            );
            if m.is_nan() {
                0.0
            } else {
                m
            }
        };
        DimRefs {
            lowest,
            highest,
            motion: median_of(|s| s.motion),
            returns: median_of(|s| s.return_scale),
            runs: {
                let mut r: Vec<f64> = feats.iter().map(|f| run_share(f, d)).collect();
                r.sort_by(f64::total_cmp);
                r
            },
            run_median: stats::median(feats.iter().map(|f| run_share(f, d))),
            long: feats.iter().filter(|f| is_long(cfg, f, d)).count(),
            clip_median: stats::median(feats.iter().map(|f| f.signal[d].clip(f.n).0)),
        }
    }

    /// The 90th percentile (lower nearest rank) of the other episodes' run shares, for an
    /// episode whose share is `own` and above it (else `own` is not an outlier: infinity).
    fn others_p90(&self, own: f64) -> f64 {
        let e = self.runs.len();
        if e < 2 {
            return 0.0;
        }
        // Without `own`, which lies above the rank asked for, that rank's value is unchanged.
        let k = 9 * (e - 2) / 10;
        if own > self.runs[k] {
            self.runs[k]
        } else {
            f64::INFINITY
        }
    }
}

/// The share of episode `f` that dimension `d`'s longest run of one value covers.
fn run_share(f: &Features, d: usize) -> f64 {
    f64::from(f.signal[d].run.len) / f.n.max(1) as f64
}

/// Whether dimension `d` of episode `f` holds one value for `frozen_fraction` of it.
fn is_long(cfg: &DoctorSpec, f: &Features, d: usize) -> bool {
    f.n >= 10 && run_share(f, d) >= cfg.frozen_fraction
}

/// `frozen` or else `clipped`, for dimension `d` of episode `e`.
fn frozen_or_clipped(
    cfg: &DoctorSpec,
    dim: &DimRefs,
    d: usize,
    e: usize,
    f: &Features,
    u: f64,
    found: &mut Found,
) {
    let sig = &f.signal[d];
    let long = is_long(cfg, f, d);
    let value = f64::from(sig.run.value);
    let at_limit = value / u <= dim.lowest || value / u >= dim.highest;
    let own = run_share(f, d);
    let others = dim.others_p90(own);
    let others_long = dim.long.saturating_sub(1) as f64 / (dim.runs.len() - 1).max(1) as f64;
    if long
        && own >= FROZEN_OVER_OTHERS * others
        && own >= FROZEN_OVER_MEDIAN * dim.run_median
        && others_long <= FROZEN_OTHERS_LONG
        && !at_limit
    {
        let (len, from) = (sig.run.len, sig.run.start);
        found.add(e, Flag::Frozen, cfg.frozen, format!(
            "action[{d}] holds {value} for {len} of {} steps from step {from}, where 90% of the other episodes hold one value for at most {:.0}% of theirs", f.n, 100.0 * others),
            &[("dim", d as f64), ("steps", len as f64), ("from", from as f64), ("value", value)]);
        return;
    }
    let (share, bound, side) = sig.clip(f.n);
    if share >= cfg.clip_fraction
        && sig.clip_runs >= 2
        && dim.clip_median < cfg.clip_fraction
        && !long
        && bound / u > dim.lowest
        && bound / u < dim.highest
    {
        found.add(
            e,
            Flag::Clipped,
            cfg.clipped,
            format!(
                "action[{d}] runs into its {side} {bound} {} times, sitting there for {:.0}% of the steps",
                sig.clip_runs,
                100.0 * share
            ),
            &[("dim", d as f64), ("share", share), ("bound", bound), ("runs", f64::from(sig.clip_runs))],
        );
    }
}

/// `jump` for dimension `d` of episode `e` (in units `u` of the dataset's): a spike off the line
/// through its neighbours ([`super::spikes`]) or, else, one judged by its return
/// ([`super::returns`]).
fn jump(
    cfg: &DoctorSpec,
    dim: &DimRefs,
    d: usize,
    e: usize,
    f: &Features,
    u: f64,
    found: &mut Found,
) {
    let range = dim.highest - dim.lowest;
    // (NaN: no value.)
    if range.is_nan() || range <= 0.0 {
        return;
    }
    let sig = &f.signal[d];
    let over = |spikes: &[Spike; 3], threshold: f64| {
        let size = |k: usize| f64::from(spikes[k].size) / u;
        let count = (0..3).filter(|&k| size(k) > threshold).count();
        (threshold > 0.0 && size(0) > threshold).then_some((size(0), spikes[0].step, count))
    };
    let times = |s: f64, scale: f64| {
        if scale > 0.0 {
            s / scale
        } else {
            f64::INFINITY
        }
    };
    let line = (cfg.jump_threshold * dim.motion).max(cfg.jump_range * range);
    if let Some((s, step, count)) = over(&sig.spikes, line) {
        let times = times(s, dim.motion);
        found.add(e, Flag::Jump, cfg.jump, format!(
            "action[{d}] spikes at step {step}: out by {s:.4} and straight back, {:.0}% of its range and {times:.0}x its motion scale ({count} such steps)", 100.0 * s / range),
            &[("dim", d as f64), ("step", f64::from(step)), ("size", s), ("range_share", s / range), ("times_motion", times)]);
        return;
    }
    let back = (RETURN_SHARE * cfg.jump_threshold * dim.returns).max(cfg.jump_range * range);
    if let Some((s, step, count)) = over(&sig.returns, back) {
        let times = times(s, dim.returns);
        found.add(e, Flag::Jump, cfg.jump, format!(
            "action[{d}] spikes at step {step}: out by {s:.4} from its motion on both sides and straight back, {:.0}% of its range and {times:.0}x how far it returns in one step elsewhere ({count} such steps)", 100.0 * s / range),
            &[("dim", d as f64), ("step", f64::from(step)), ("size", s), ("range_share", s / range), ("times_return", times)]);
    }
}

#[cfg(test)]
mod tests {
    use super::super::features::{features, Shape};
    use super::*;

    /// Minimum jerk from 0 to 1.
    fn jerk(u: f64) -> f64 {
        u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)
    }

    /// Episode `e` of `n` steps, 3 action dimensions: 0 a fast joint (swings of 100 in 30 steps,
    /// its steps reaching 6.25); 1 a hand joint that rests and moves in steps of 37 (to 245 in
    /// episode 0: its range); 2 a joint that steps by 60 in one step and stays.
    fn episode(e: usize, n: usize) -> Vec<f32> {
        let mut rows = Vec::with_capacity(3 * n);
        for t in 0..n {
            let k = (t + 7 * e) % 80;
            let fast = match k {
                k if k < 10 => 0.0,
                k if k < 40 => 100.0 * jerk((k - 10) as f64 / 30.0),
                k if k < 50 => 100.0,
                k => 100.0 * (1.0 - jerk((k - 50) as f64 / 30.0)),
            };
            let hand = match t {
                40..=79 => 37.0,
                120..=139 if e == 0 => 245.0,
                _ => 0.0,
            };
            let step = if t < 100 + e { 0.0 } else { 60.0 };
            rows.extend([fast as f32, hand, step]);
        }
        rows
    }

    /// The `jump` findings of each episode: (dimension, step).
    fn jumps(episodes: &[Vec<f32>], n: usize) -> Vec<Vec<(usize, u32)>> {
        let shape = Shape {
            n,
            a_dim: 3,
            s_dim: 0,
        };
        let feats: Vec<Features> = episodes.iter().map(|a| features(a, None, shape)).collect();
        let mut found = Found(vec![Vec::new(); feats.len()]);
        let scale = vec![1.0; feats.len()];
        signal_checks(&DoctorSpec::default(), &feats, &scale, 3, &mut found);
        found
            .0
            .iter()
            .map(|list| {
                list.iter()
                    .filter(|f| f.flag == Flag::Jump)
                    .map(|f| (f.evidence["dim"] as usize, f.evidence["step"] as u32))
                    .collect()
            })
            .collect()
    }

    /// Spikes that return are flagged on a fast joint (out by twice its step at mid-swing) and
    /// on a resting hand joint whose steps set its motion scale above the spike (issue 50's two
    /// misses); a genuine fast step, which does not return, is not.
    #[test]
    fn returning_spikes_on_fast_and_still_joints() {
        let n = 240;
        let mut episodes: Vec<Vec<f32>> = (0..10).map(|e| episode(e, n)).collect();
        assert!(jumps(&episodes, n).iter().all(|j| j.is_empty()));
        // Mid-swing of episode 3's fast joint: steps of 6.25 either side.
        let fastest = (50..n).find(|t| (t + 21) % 80 == 25).unwrap();
        episodes[3][3 * fastest] += 12.0;
        // Episode 5's hand joint at rest, +61 (a quarter of its range) and back.
        episodes[5][3 * 150 + 1] += 61.0;
        let got = jumps(&episodes, n);
        assert_eq!(got[3], vec![(0, fastest as u32)]);
        assert_eq!(got[5], vec![(1, 150)]);
        assert!(got
            .iter()
            .enumerate()
            .all(|(e, j)| e == 3 || e == 5 || j.is_empty()));
    }
}
