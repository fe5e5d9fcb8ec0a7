//! What one episode reduces to for the doctor: per-dimension signal features, the alignment fits,
//! moments, the state's ranges and runs, and the duplicate signature. Computed once per episode,
//! in parallel; every check then judges these, never the raw values.

use super::{alignment, duplicates, signal};

/// What one episode reduces to: a fixed size per channel dimension, whatever the episode's
/// length (about 12 KB for 14-D action and state).
#[derive(Debug, Clone)]
pub struct Features {
    pub(super) n: usize,
    pub(super) signal: Vec<signal::DimSignal>,
    pub(super) fits: Vec<Option<Vec<alignment::LagFit>>>,
    pub(super) stds: Vec<f64>,
    pub(super) action_means: Vec<f64>,
    pub(super) state_means: Vec<f64>,
    pub(super) state_range: Vec<(f64, f64)>,
    /// Per state dimension, the longest run of one exact value and the share of unchanged steps.
    pub(super) state_runs: Vec<(usize, f64)>,
    /// The duplicate signature ([`duplicates::signature`]), in single precision: the
    /// tolerance it is compared at is far above its rounding.
    pub(super) signature: Vec<f32>,
}

/// Per column of a `(n, width)` array: the mean and the (population) standard deviation, in
/// two passes over the rows (the array's own order).
fn column_stats(x: &[f64], n: usize, width: usize) -> (Vec<f64>, Vec<f64>) {
    let mut means = vec![0.0; width];
    let mut stds = vec![0.0; width];
    if n == 0 || width == 0 {
        return (means, stds);
    }
    for row in x.chunks_exact(width).take(n) {
        for (m, v) in means.iter_mut().zip(row) {
            *m += v;
        }
    }
    means.iter_mut().for_each(|m| *m /= n as f64);
    for row in x.chunks_exact(width).take(n) {
        for ((s, m), v) in stds.iter_mut().zip(&means).zip(row) {
            *s += (v - m) * (v - m);
        }
    }
    stds.iter_mut().for_each(|s| *s = (*s / n as f64).sqrt());
    (means, stds)
}

pub(super) fn features(
    a: &[f64],
    s: Option<&[f64]>,
    n: usize,
    a_dim: usize,
    s_dim: usize,
) -> Features {
    let signal = (0..a_dim)
        .map(|d| signal::dim_signal(a, n, a_dim, d))
        .collect();
    let shared = if s.is_some() { a_dim.min(s_dim) } else { 0 };
    let fits = (0..shared)
        .map(|d| alignment::fit_dim(a, s.unwrap_or(&[]), n, a_dim, s_dim, d))
        .collect();
    let (action_means, stds) = column_stats(a, n, a_dim);
    let state_runs = match s {
        Some(s) => (0..s_dim).map(|d| signal::held(s, n, s_dim, d)).collect(),
        None => Vec::new(),
    };
    let (state_means, state_range) = match s {
        Some(s) => {
            let (m, _) = column_stats(s, n, s_dim);
            let r = (0..s_dim)
                .map(|d| {
                    (0..n)
                        .map(|t| s[t * s_dim + d])
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                            (lo.min(v), hi.max(v))
                        })
                })
                .collect();
            (m, r)
        }
        None => (Vec::new(), Vec::new()),
    };
    Features {
        n,
        signal,
        fits,
        stds,
        action_means,
        state_means,
        state_range,
        state_runs,
        signature: duplicates::signature(a, n, a_dim)
            .into_iter()
            .map(|v| v as f32)
            .collect(),
    }
}

/// Replaces each non-finite value of a `(n, width)` array by the last finite value of its column
/// (0 before the first).
pub(super) fn hold_finite(x: &mut [f64], width: usize) {
    if width == 0 || x.iter().all(|v| v.is_finite()) {
        return;
    }
    for d in 0..width {
        let mut last = 0.0;
        for v in x.iter_mut().skip(d).step_by(width) {
            if v.is_finite() {
                last = *v;
            } else {
                *v = last;
            }
        }
    }
}
