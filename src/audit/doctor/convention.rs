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
//!   Without tracked dimensions, the factor is the median over dimensions of the action's standard
//!   deviation over the dataset's median, and counts only when at least 80% of the dimensions
//!   agree in direction beyond the threshold (an idle episode moves less, but not in units).

use super::alignment::{lag_of, LagFit};
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

/// `fits[e][d]`: episode e's fits of shared dimension d; `stds[e][d]`: the standard deviation
/// of action dimension d in episode e.
// Long function: tracked dimensions, lags, conventions and units, each from the one before.
pub fn judge(fits: &[Vec<Option<Vec<LagFit>>>], stds: &[Vec<f64>], units_ratio: f64) -> Judged {
    let episodes = fits.len();
    let dims = fits.iter().map(|f| f.len()).max().unwrap_or(0);
    let tracked: Vec<usize> = (0..dims)
        .filter(|&d| {
            let best = fits.iter().filter_map(|f| f.get(d)?.as_ref()).map(|v| {
                1.0 - v
                    .iter()
                    .map(|x| x.unexplained)
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
            let used: Vec<&Vec<LagFit>> =
                tracked.iter().filter_map(|&d| f.get(d)?.as_ref()).collect();
            if used.len() < tracked.len() {
                continue;
            }
            let unexplained: Vec<f64> = (0..shifts)
                .map(|i| used.iter().map(|v| v[i].unexplained).sum::<f64>() / used.len() as f64)
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
            let score = median(used.iter().map(|v| v[best].convention));
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
                        .map(|&d| f[d].as_ref().map_or(f64::NAN, |v| v[l.best].alpha))
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
    } else {
        let a_dims = stds.iter().map(|s| s.len()).max().unwrap_or(0);
        let reference: Vec<f64> = (0..a_dims)
            .map(|d| median(stds.iter().filter_map(|s| s.get(d).copied())))
            .collect();
        for (e, s) in stds.iter().enumerate() {
            let ratios: Vec<f64> = s
                .iter()
                .zip(&reference)
                .filter(|(x, r)| **x > 0.0 && **r > 0.0)
                .map(|(x, r)| x / r)
                .collect();
            if ratios.is_empty() {
                continue;
            }
            let factor = median(ratios.iter().copied());
            let up = ratios.iter().filter(|r| **r > units_ratio).count();
            let down = ratios.iter().filter(|r| **r < 1.0 / units_ratio).count();
            out.units[e] = factor;
            out.units_judged[e] = 5 * up.max(down) >= 4 * ratios.len();
        }
    }
    out
}
