//! The dataset-wide judgement of the alignment fits ([`super::alignment`]): which dimensions
//! track the state, each episode's lag, convention and units, and the dataset's majority of each.
//!
//! - **Tracked dimensions**: those whose median episode explains more than half of the state
//!   change ([`TRACKED_R2`]); the rest (an action in another space than the state, a gripper)
//!   take no part in the lag, convention and units judgements.
//! - **Lag**: per episode, the shift minimizing the mean unexplained share over the tracked
//!   dimensions (when it explains at least [`MIN_R2`] and is not an end of the range tried,
//!   where the fit has no peak); the dataset's lag is the mode.
//! - **Convention**: the median over tracked dimensions of `|corr(a, s_next)| - |corr(a, Δs)|` at
//!   the episode's lag: above [`CONVENTION_MARGIN`] an absolute target, below its negative a
//!   delta; the majority of the classified episodes is the dataset's convention.
//! - **Units**: the episode's factor is the median over tracked dimensions of the dataset's median
//!   gain α over the episode's (a ×10 units change divides α by 10, whatever the convention).
//!   And in any case from the values: when in at least 80% of the dimensions both the action's
//!   level (RMS) and spread (standard deviation) are beyond the threshold times the dataset's
//!   median, the same way, the factor is the median level ratio ([`levels`]): an episode in
//!   degrees among radians, action and state alike, leaves the gain as it is (an idle episode
//!   moves less, but holds its level).

use super::alignment::{lag_of, DimFits};
use super::stats::median;

pub const TRACKED_R2: f64 = 0.5;
pub const MIN_R2: f64 = 0.3;
pub const CONVENTION_MARGIN: f64 = 0.2;

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Convention {
    Absolute,
    Delta,
}

impl Convention {
    pub fn name(self) -> &'static str {
        match self {
            Convention::Absolute => "absolute",
            Convention::Delta => "delta",
        }
    }
}

/// One episode's lag.
#[derive(Debug, Clone)]
pub struct EpisodeLag {
    pub lag: i32,
    /// Mean unexplained share at every shift.
    pub unexplained: Vec<f64>,
    pub best: usize,
    pub score: f64,
}

#[derive(Debug, Default)]
pub struct Judged {
    pub tracked: Vec<usize>,
    pub lags: Vec<Option<EpisodeLag>>,
    pub mode: Option<i32>,
    /// (lag, mean R² over the fitted episodes).
    pub curve: Vec<(i32, f64)>,
    /// Per episode, the action's units relative to the dataset (1: the same).
    pub units: Vec<f64>,
    /// Per episode, whether `units` is trustworthy enough to flag.
    pub units_judged: Vec<bool>,
    pub conventions: Vec<Option<Convention>>,
    pub majority: Option<Convention>,
}

/// `fits[e][d]`: episode e's fits of shared dimension d; `rms[e][d]` and `stds[e][d]`: the root
/// mean square (about 0) and the standard deviation of action dimension d in episode e.
// Long function: tracked dimensions, lags, conventions and units, each from the one before.
pub fn judge(
    fits: &[&[Option<DimFits>]],
    rms: &[Vec<f64>],
    stds: &[Vec<f64>],
    units_ratio: f64,
) -> Judged {
    let episodes = fits.len();
    let dims = fits.iter().map(|f| f.len()).max().unwrap_or(0);
    let tracked: Vec<usize> = (0..dims)
        .filter(|&d| {
            let best = fits.iter().filter_map(|f| f.get(d)?.as_ref()).map(|v| {
                1.0 - v
                    .unexplained
                    .iter()
                    .map(|&x| f64::from(x))
                    .fold(f64::INFINITY, f64::min)
            });
            median(best) > TRACKED_R2
        })
        .collect();
    let mut out = Judged {
        tracked: tracked.clone(),
        lags: vec![None; episodes],
        units: vec![1.0; episodes],
        units_judged: vec![false; episodes],
        conventions: vec![None; episodes],
        ..Default::default()
    };
    let shifts = (super::alignment::SHIFT_MAX - super::alignment::SHIFT_MIN + 1) as usize;
    if !tracked.is_empty() {
        let mut sums = vec![0.0; shifts];
        let mut fitted = 0usize;
        for (e, f) in fits.iter().enumerate() {
            let used: Vec<&DimFits> = tracked.iter().filter_map(|&d| f.get(d)?.as_ref()).collect();
            if used.len() < tracked.len() {
                continue;
            }
            let unexplained: Vec<f64> = (0..shifts)
                .map(|i| {
                    used.iter()
                        .map(|v| f64::from(v.unexplained[i]))
                        .sum::<f64>()
                        / used.len() as f64
                })
                .collect();
            let best = (0..shifts)
                .min_by(|&i, &j| unexplained[i].total_cmp(&unexplained[j]))
                .unwrap_or(0);
            // A fit that explains too little, or whose best shift is an end of the range (it
            // would keep improving past it: no peak, so no lag), estimates nothing.
            if 1.0 - unexplained[best] < MIN_R2 || best == 0 || best + 1 == shifts {
                continue;
            }
            for (s, u) in sums.iter_mut().zip(&unexplained) {
                *s += 1.0 - u;
            }
            fitted += 1;
            let score = median(used.iter().map(|v| v.convention(best)));
            out.conventions[e] = if score > CONVENTION_MARGIN {
                Some(Convention::Absolute)
            } else if score < -CONVENTION_MARGIN {
                Some(Convention::Delta)
            } else {
                None
            };
            out.lags[e] = Some(EpisodeLag {
                lag: lag_of(best),
                unexplained,
                best,
                score,
            });
        }
        if fitted > 0 {
            out.curve = (0..shifts)
                .map(|i| (lag_of(i), sums[i] / fitted as f64))
                .collect();
        }
        out.mode = super::stats::mode(out.lags.iter().flatten().map(|l| l.lag));
        out.majority = super::stats::mode(out.conventions.iter().flatten().copied());
        // Units: the gain at each episode's own lag against the dataset's median gain.
        let gains: Vec<Option<Vec<f64>>> = fits
            .iter()
            .zip(&out.lags)
            .map(|(f, l)| {
                let l = l.as_ref()?;
                Some(
                    tracked
                        .iter()
                        .map(|&d| {
                            f[d].as_ref()
                                .map_or(f64::NAN, |v| f64::from(v.alpha[l.best]))
                        })
                        .collect(),
                )
            })
            .collect();
        let reference: Vec<f64> = (0..tracked.len())
            .map(|k| median(gains.iter().flatten().map(|g| g[k])))
            .collect();
        for (e, g) in gains.iter().enumerate() {
            let Some(g) = g else { continue };
            let factor = median(
                g.iter()
                    .zip(&reference)
                    .filter(|(x, r)| x.abs() > 0.0 && r.abs() > 0.0)
                    .map(|(x, r)| r / x),
            );
            if factor.is_finite() && factor > 0.0 {
                out.units[e] = factor;
                out.units_judged[e] = true;
            }
        }
    }
    // Units from the values themselves, in either case: an episode recorded in degrees where the
    // rest are radians (action and state alike, so the gain above does not move) has every
    // dimension's level and spread scaled together.
    // The gain, where it already says so, measures the factor more closely (the level compares
    // against the median episode's positions).
    let beyond = |u: f64| u > units_ratio || u < 1.0 / units_ratio;
    for (e, level) in levels(rms, stds, units_ratio).into_iter().enumerate() {
        if let Some(factor) = level {
            if !(out.units_judged[e] && beyond(out.units[e])) {
                out.units[e] = factor;
                out.units_judged[e] = true;
            }
        }
    }
    out
}

/// Per episode, its units factor when the action's values are in other units than the dataset's:
/// in at least 80% of the dimensions both the level (RMS about 0) and the spread (standard
/// deviation) are beyond `units_ratio` times the dataset's median, the same way; the factor is
/// the median over dimensions of the level's ratio. An idle episode moves less, but holds its
/// level; a larger motion spreads more, but about the same positions.
fn levels(rms: &[Vec<f64>], stds: &[Vec<f64>], units_ratio: f64) -> Vec<Option<f64>> {
    let dims = rms.iter().map(Vec::len).max().unwrap_or(0);
    let reference = |of: &[Vec<f64>]| -> Vec<f64> {
        (0..dims)
            .map(|d| median(of.iter().filter_map(|s| s.get(d).copied())))
            .collect()
    };
    let (rms_ref, std_ref) = (reference(rms), reference(stds));
    rms.iter()
        .zip(stds)
        .map(|(r, s)| {
            let ratios: Vec<(f64, f64)> = (0..r.len().min(s.len()))
                .filter(|&d| rms_ref[d] > 0.0 && std_ref[d] > 0.0)
                .map(|d| (r[d] / rms_ref[d], s[d] / std_ref[d]))
                .collect();
            if ratios.is_empty() {
                return None;
            }
            let up = ratios
                .iter()
                .filter(|(l, s)| *l > units_ratio && *s > units_ratio)
                .count();
            let down = ratios
                .iter()
                .filter(|(l, s)| *l < 1.0 / units_ratio && *s < 1.0 / units_ratio)
                .count();
            (5 * up.max(down) >= 4 * ratios.len()).then(|| median(ratios.iter().map(|p| p.0)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_find_degrees_not_idle_episodes() {
        // Joint angles near 0.5 rad moving by 0.2; episode 1 in degrees, episode 2 idle.
        let mut rms = vec![vec![0.55, 0.6, 0.5]; 10];
        let mut stds = vec![vec![0.2, 0.25, 0.2]; 10];
        let deg = 180.0 / std::f64::consts::PI;
        rms[1] = rms[1].iter().map(|x| x * deg).collect();
        stds[1] = stds[1].iter().map(|x| x * deg).collect();
        stds[2] = vec![0.01, 0.01, 0.01];
        let found = levels(&rms, &stds, 3.0);
        assert!((found[1].unwrap() - deg).abs() < 1e-9);
        assert!(found
            .iter()
            .enumerate()
            .all(|(e, f)| f.is_some() == (e == 1)));
    }
}
