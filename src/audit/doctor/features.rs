//! What one episode reduces to for the doctor: per-dimension signal features, the alignment fits,
//! moments, the state's ranges and runs, and the duplicate signature. Computed once per episode,
//! in parallel; every check then judges these, never the raw values.

use super::{alignment, duplicates, signal};

/// What one episode reduces to.
pub(super) struct Features {
    pub n: usize,
    pub signal: Vec<signal::DimSignal>,
    pub fits: Vec<Option<Vec<alignment::LagFit>>>,
    pub stds: Vec<f64>,
    pub action_means: Vec<f64>,
    pub state_means: Vec<f64>,
    pub state_range: Vec<(f64, f64)>,
    /// Per state dimension, the longest run of one exact value and the share of unchanged steps.
    pub state_runs: Vec<(usize, f64)>,
    pub signature: Vec<f64>,
}

fn column_stats(x: &[f64], n: usize, width: usize) -> (Vec<f64>, Vec<f64>) {
    let mut means = vec![0.0; width];
    let mut stds = vec![0.0; width];
    if n == 0 {
        return (means, stds);
    }
    for d in 0..width {
        let m = (0..n).map(|t| x[t * width + d]).sum::<f64>() / n as f64;
        let v = (0..n).map(|t| (x[t * width + d] - m).powi(2)).sum::<f64>() / n as f64;
        means[d] = m;
        stds[d] = v.sqrt();
    }
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
        Some(s) => (0..s_dim)
            .map(|d| {
                let sig = signal::dim_signal(s, n, s_dim, d);
                (sig.run.0, sig.unchanged)
            })
            .collect(),
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
        signature: duplicates::signature(a, n, a_dim),
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
