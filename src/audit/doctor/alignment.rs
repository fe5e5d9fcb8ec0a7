//! Observation/action alignment, per episode: at which lag the commanded action best predicts
//! the next change of the state.
//!
//! A tracking system moves its state toward the command: `s[t+1] - s[t] ≈ α·a[t-ℓ] + β·s[t] + c`.
//! For every shift ℓ in `LAGS` and every dimension the action and state share, an ordinary
//! least-squares fit of the state change on the shifted action and the current state; the shift
//! with the smallest residual is the episode's alignment, reported as the lag `ℓ + 1`: the step
//! at which the action first shows in the state (1 for a log where `action[t]` is what the robot
//! was told at the observation of step t). The same fit covers both conventions: an absolute
//! target gives `β ≈ -α`, a delta `β ≈ 0`; α is the gain in the action's units, so its ratio to
//! the dataset's median is the episode's units factor ([`super::convention`]).

/// The shifts ℓ tried (reported lags -5..=10).
pub const SHIFT_MIN: i64 = -6;
pub const SHIFT_MAX: i64 = 9;
/// Episodes shorter than this get no fit.
pub const MIN_STEPS: usize = 40;

/// One dimension's fit at one shift, in single precision: kept for every episode, dimension and
/// shift (the judgement's inputs, far coarser than its rounding).
#[derive(Debug, Clone, Copy, Default)]
pub struct LagFit {
    /// Residual over total sum of squares of the state change (1 - R²).
    pub unexplained: f32,
    /// The action's coefficient.
    pub alpha: f32,
    /// |corr(a[t-ℓ], s[t+1])| - |corr(a[t-ℓ], s[t+1] - s[t])|: positive for an absolute target,
    /// negative for a delta.
    pub convention: f32,
}

/// The fits of dimension `d` at every shift (`SHIFT_MIN..=SHIFT_MAX`), or None when the episode
/// is too short or the state does not move.
///
/// The action column is centred once (by its episode mean), so that each shift's sums are its
/// window's sliding sums and two dot products over contiguous slices (with the state and the
/// state change; the next state's follows from them): one fused pass per shift.
pub fn fit_dim(
    a: &[f64],
    s: &[f64],
    n: usize,
    a_dim: usize,
    s_dim: usize,
    d: usize,
) -> Option<Vec<LagFit>> {
    if n < MIN_STEPS {
        return None;
    }
    let (t0, t1) = ((SHIFT_MAX) as usize, n - (-SHIFT_MIN) as usize);
    let len = t1 - t0;
    let centred = |v: Vec<f64>| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        v.into_iter().map(|x| x - m).collect::<Vec<f64>>()
    };
    let yc = centred(
        (t0..t1)
            .map(|t| s[(t + 1) * s_dim + d] - s[t * s_dim + d])
            .collect(),
    );
    let x2c = centred((t0..t1).map(|t| s[t * s_dim + d]).collect());
    let nextc = centred((t0..t1).map(|t| s[(t + 1) * s_dim + d]).collect());
    let dot = |p: &[f64], q: &[f64]| p.iter().zip(q).map(|(a, b)| a * b).sum::<f64>();
    let syy = dot(&yc, &yc);
    if syy.is_nan() || syy <= 0.0 {
        return None;
    }
    let s22 = dot(&x2c, &x2c);
    let s2y = dot(&x2c, &yc);
    let snn = dot(&nextc, &nextc);
    let corr = |sxy: f64, sxx: f64, syy: f64| {
        if sxx <= 0.0 || syy <= 0.0 {
            0.0
        } else {
            sxy / (sxx * syy).sqrt()
        }
    };
    let col = centred((0..n).map(|t| a[t * a_dim + d]).collect());
    let mut out = Vec::with_capacity((SHIFT_MAX - SHIFT_MIN + 1) as usize);
    // The window's sums of the action and its square, slid one row earlier per shift.
    let first = (t0 as i64 - SHIFT_MIN) as usize;
    let (mut sx, mut sxx) = col[first..first + len]
        .iter()
        .fold((0.0, 0.0), |(s, q), x| (s + x, q + x * x));
    for shift in SHIFT_MIN..=SHIFT_MAX {
        // The action shifted by `shift`, in place: rows t0 - shift .. t1 - shift.
        let start = (t0 as i64 - shift) as usize;
        if start != first {
            let (come, go) = (col[start], col[start + len]);
            sx += come - go;
            sxx += come * come - go * go;
        }
        let (s12, s1y) = lane_dots(&col[start..start + len], &x2c, &yc);
        // The next state is the current one plus the change (all centred): its sum with the
        // action is the sum of theirs.
        let s1n = s12 + s1y;
        // Against the shifted action's own mean: the other series are centred already.
        let s11 = (sxx - sx * sx / len as f64).max(0.0);
        let det = s11 * s22 - s12 * s12;
        let (alpha, explained) = if s11 <= 0.0 {
            (0.0, if s22 > 0.0 { s2y * s2y / s22 } else { 0.0 })
        } else if det > 1e-12 * s11 * s22 {
            let alpha = (s22 * s1y - s12 * s2y) / det;
            let beta = (s11 * s2y - s12 * s1y) / det;
            (alpha, alpha * s1y + beta * s2y)
        } else {
            (s1y / s11, s1y * s1y / s11)
        };
        let convention = corr(s1n, s11, snn).abs() - corr(s1y, s11, syy).abs();
        out.push(LagFit {
            unexplained: ((syy - explained) / syy).clamp(0.0, 1.0) as f32,
            alpha: alpha as f32,
            convention: convention as f32,
        });
    }
    Some(out)
}

/// `(Σx·p, Σx·q)` over equally long slices, four lanes at a time (the compiler turns them into
/// vector instructions).
fn lane_dots(x: &[f64], p: &[f64], q: &[f64]) -> (f64, f64) {
    let (mut xp, mut xq) = ([0.0f64; 4], [0.0f64; 4]);
    let (xc, pc, qc) = (x.chunks_exact(4), p.chunks_exact(4), q.chunks_exact(4));
    let tail = xc.remainder().len();
    for ((x, p), q) in xc.zip(pc).zip(qc) {
        for k in 0..4 {
            xp[k] += x[k] * p[k];
            xq[k] += x[k] * q[k];
        }
    }
    let sum = |a: [f64; 4]| (a[0] + a[1]) + (a[2] + a[3]);
    let (mut a, mut b) = (sum(xp), sum(xq));
    for i in x.len() - tail..x.len() {
        a += x[i] * p[i];
        b += x[i] * q[i];
    }
    (a, b)
}

/// The reported lag of shift index `i` (into a fit vector).
pub fn lag_of(i: usize) -> i32 {
    (SHIFT_MIN + i as i64 + 1) as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tracking(n: usize, late: usize) -> (Vec<f64>, Vec<f64>) {
        let cmd: Vec<f64> = (0..n + late)
            .map(|t| (t as f64 * 0.07).sin() + 0.4 * (t as f64 * 0.19).cos())
            .collect();
        let mut s = vec![0.0; n];
        let mut x = cmd[0];
        for t in 0..n {
            s[t] = x;
            x += 0.3 * (cmd[t + late] - x);
        }
        // The recorded action is `late` steps behind what drove the state.
        let a: Vec<f64> = cmd[..n].to_vec();
        (a, s)
    }

    #[test]
    fn finds_the_lag_of_a_first_order_tracker() {
        for late in [0usize, 3] {
            let (a, s) = tracking(200, late);
            let fits = fit_dim(&a, &s, 200, 1, 1, 0).unwrap();
            let best = (0..fits.len())
                .min_by(|&i, &j| fits[i].unexplained.total_cmp(&fits[j].unexplained))
                .unwrap();
            assert_eq!(lag_of(best), 1 - late as i32, "late {late}");
            assert!(fits[best].convention > 0.3);
            assert!((fits[best].alpha - 0.3).abs() < 0.01);
        }
    }
}
