//! The judgement of the signal checks (`frozen`, `clipped`, `jump`) per action dimension,
//! against what the dimension does over the whole dataset (see [`super::signal`]).

use super::features::Features;
use super::found::Found;
use super::stats;
use crate::audit::report::Flag;
use crate::spec::DoctorSpec;

/// `frozen` needs a run this many times the other episodes' 90th percentile of theirs ...
const FROZEN_OVER_OTHERS: f64 = 1.25;

/// ... and twice their median ...
const FROZEN_OVER_MEDIAN: f64 = 2.0;

/// ... in a dimension where at most this share of the other episodes hold one value as long
/// (else it is `stuck`, a dataset-wide warning, not `frozen` in each).
const FROZEN_OTHERS_LONG: f64 = 0.1;

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
        let motion = stats::median(
            feats
                .iter()
                .zip(scale)
                .map(|(f, u)| f64::from(f.signal[d].motion) / u),
        );
        DimRefs {
            lowest,
            highest,
            motion: if motion.is_nan() { 0.0 } else { motion },
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

/// `jump` for dimension `d` of episode `e` (in units `u` of the dataset's).
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
    let threshold = (cfg.jump_threshold * dim.motion).max(cfg.jump_range * range);
    if !(range > 0.0 && threshold > 0.0) {
        return;
    }
    let sig = &f.signal[d];
    let size = |k: usize| f64::from(sig.spikes[k].size) / u;
    if size(0) <= threshold {
        return;
    }
    let count = (0..3).filter(|&k| size(k) > threshold).count();
    let (s, step) = (size(0), sig.spikes[0].step);
    let times = if dim.motion > 0.0 {
        s / dim.motion
    } else {
        f64::INFINITY
    };
    found.add(e, Flag::Jump, cfg.jump, format!(
        "action[{d}] spikes at step {step}: out by {s:.4} and straight back, {:.0}% of its range and {times:.0}x its motion scale ({count} such steps)", 100.0 * s / range),
        &[("dim", d as f64), ("step", f64::from(step)), ("size", s), ("range_share", s / range), ("times_motion", times)]);
}
