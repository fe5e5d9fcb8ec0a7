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

use super::{columns, lanes};

/// The shifts tried.
pub const SHIFTS: usize = (SHIFT_MAX - SHIFT_MIN + 1) as usize;

/// One dimension's fits at every shift (`SHIFT_MIN..=SHIFT_MAX`), in single precision: kept
/// for every episode and dimension (the judgement's inputs, far coarser than its rounding).
#[derive(Debug, Clone, Copy)]
pub struct DimFits {
    /// Residual over total sum of squares of the state change (1 - R²).
    pub unexplained: [f32; SHIFTS],
    /// The action's coefficient.
    pub alpha: [f32; SHIFTS],
    /// The convention score in units of `1 / CONVENTION_STEPS` (see [`DimFits::convention`]):
    /// it lies in [-1, 1] and is judged against margins of tenths.
    convention: [i16; SHIFTS],
}

/// The convention score's resolution: steps per unit.
const CONVENTION_STEPS: f64 = 16384.0;

impl DimFits {
    /// |corr(a[t-ℓ], s[t+1])| - |corr(a[t-ℓ], s[t+1] - s[t])| at shift index `i`: positive for
    /// an absolute target, negative for a delta.
    pub fn convention(&self, i: usize) -> f64 {
        f64::from(self.convention[i]) / CONVENTION_STEPS
    }
}

/// The buffers of one episode's fits, reused from dimension to dimension.
#[derive(Default)]
pub struct Scratch {
    col: Vec<f32>,
    x2: Vec<f32>,
    y: Vec<f32>,
}

/// The fits of one dimension, from its action column `a` and state column `s` (equally long),
/// at every shift, or None when the episode is too short or the state does not move.
///
/// The series are centred first (the action by its episode mean, the state and its change by
/// their window's), so that each shift's sums are its window's sliding sums and two dot
/// products over contiguous slices, with the state and with the state change (the next state's
/// follows from them): all sixteen shifts' in one sweep ([`lanes::shifted_dots`]).
#[inline(always)]
pub fn fit_dim(a: &[f32], s: &[f32], scratch: &mut Scratch) -> Option<DimFits> {
    let n = a.len().min(s.len());
    if n < MIN_STEPS {
        return None;
    }
    let (t0, t1) = ((SHIFT_MAX) as usize, n - (-SHIFT_MIN) as usize);
    let len = t1 - t0;
    let padded = len.div_ceil(lanes::LANES) * lanes::LANES;
    let w = state_window(&s[t0..t1 + 1], padded, scratch);
    let syy = w.syy;
    if syy.is_nan() || syy <= 0.0 {
        return None;
    }
    let (s22, s2y) = (w.s22, w.s2y);
    // The action column, centred, with room for the last shift's padded rows.
    let col = &mut scratch.col;
    col.clear();
    col.extend_from_slice(&a[..n]);
    let mean = (columns::sum(col) / n as f64) as f32;
    col.iter_mut().for_each(|x| *x -= mean);
    col.resize(padded + lanes::SHIFTS - 1, 0.0);
    // Shift `shift` reads the action's rows `t0 - shift..t1 - shift`: window `k = t0 - shift`.
    let (dots2, dotsy) = lanes::shifted_dots(col, &scratch.x2, &scratch.y);
    let first = (t0 as i64 - SHIFT_MIN) as usize;
    // The window's sums of the action and its square, slid one row earlier per shift.
    let (mut sx, mut sxx) = sum_and_squares(&col[first..first + len]);
    // One over the square roots of the state's and the next state's sums of squares, for the
    // correlations (0 where there is no spread: the correlation is 0).
    let inverse_root = |v: f64| if v > 0.0 { 1.0 / v.sqrt() } else { 0.0 };
    let (ryy, rnn) = (inverse_root(syy), inverse_root(w.snn));
    let mut out = DimFits {
        unexplained: [0.0; SHIFTS],
        alpha: [0.0; SHIFTS],
        convention: [0; SHIFTS],
    };
    for i in 0..SHIFTS {
        let k = first - i;
        if k != first {
            let (come, go) = (f64::from(col[k]), f64::from(col[k + len]));
            sx += come - go;
            sxx += come * come - go * go;
        }
        // The state and its change were centred at single precision: the rest of their means,
        // times the window's sum, is what their dot products miss.
        let s12 = dots2[k] + w.rest2 * sx;
        let s1y = dotsy[k] + w.resty * sx;
        // The next state is the current one plus the change (all centred): its sum with the
        // action is the sum of theirs.
        let s1n = s12 + s1y;
        // Against the shifted action's own mean: the other series are centred already.
        let s11 = (sxx - sx * sx / len as f64).max(0.0);
        let det = s11 * s22 - s12 * s12;
        let (alpha, explained) = if s11 <= 0.0 {
            (0.0, if s22 > 0.0 { s2y * s2y / s22 } else { 0.0 })
        } else if det > COLLINEAR * s11 * s22 {
            let inv = 1.0 / det;
            let alpha = (s22 * s1y - s12 * s2y) * inv;
            let beta = (s11 * s2y - s12 * s1y) * inv;
            (alpha, alpha * s1y + beta * s2y)
        } else {
            (s1y / s11, s1y * s1y / s11)
        };
        let r11 = inverse_root(s11);
        let convention = (s1n * r11 * rnn).abs() - (s1y * r11 * ryy).abs();
        out.unexplained[i] = ((syy - explained) / syy).clamp(0.0, 1.0) as f32;
        out.alpha[i] = alpha as f32;
        // Rounded half away from zero (`as` truncates).
        let steps = convention.clamp(-1.0, 1.0) * CONVENTION_STEPS;
        out.convention[i] = (steps + 0.5f64.copysign(steps)) as i16;
    }
    Some(out)
}

/// Below this share of `s11·s22` left by their product, the shifted action and the state are
/// collinear at the sums' single-precision resolution: the action alone is fitted.
const COLLINEAR: f64 = 1e-6;

/// The state's sums over the fit's window.
struct Window {
    /// Sums of squares about the mean: the state, its change, the next state.
    s22: f64,
    syy: f64,
    snn: f64,
    /// The state's and its change's sum of products about their means.
    s2y: f64,
    /// What the single-precision centring left of the state's and the change's means.
    rest2: f64,
    resty: f64,
}

/// The window `s` (its rows and the next one) into `scratch.x2` (the state) and `scratch.y`
/// (its change), centred and padded with zeros to `padded`, and their sums.
///
/// One pass takes the state relative to its first value and the change (both exact in single
/// precision for neighbouring values) and sums them, their squares and their product in
/// double precision (four lanes each, a fixed order); the sums about the means follow, and a
/// second pass centres both series.
#[inline(always)]
fn state_window(s: &[f32], padded: usize, scratch: &mut Scratch) -> Window {
    let len = s.len() - 1;
    let p = s[0];
    let (x2, y) = (&mut scratch.x2, &mut scratch.y);
    x2.clear();
    x2.resize(padded, 0.0);
    y.clear();
    y.resize(padded, 0.0);
    let mut acc = [[0.0f64; 4]; 5];
    let add = |acc: &mut [[f64; 4]; 5], l: usize, u: f32, d: f32| {
        let (u, d) = (f64::from(u), f64::from(d));
        acc[0][l] += u;
        acc[1][l] += u * u;
        acc[2][l] += d;
        acc[3][l] += d * d;
        acc[4][l] += u * d;
    };
    let whole = len / 4 * 4;
    for (((sc, nc), xc), yc) in s[..whole]
        .chunks_exact(4)
        .zip(s[1..whole + 1].chunks_exact(4))
        .zip(x2.chunks_exact_mut(4))
        .zip(y.chunks_exact_mut(4))
    {
        for l in 0..4 {
            xc[l] = sc[l] - p;
            yc[l] = nc[l] - sc[l];
            add(&mut acc, l, xc[l], yc[l]);
        }
    }
    for t in whole..len {
        x2[t] = s[t] - p;
        y[t] = s[t + 1] - s[t];
        add(&mut acc, 0, x2[t], y[t]);
    }
    let [su, suu, sy, syy, suy] = acc.map(|a| (a[0] + a[1]) + (a[2] + a[3]));
    let n = len as f64;
    let (mu, my) = (su / n, sy / n);
    let (mu32, my32) = (mu as f32, my as f32);
    x2[..len].iter_mut().for_each(|v| *v -= mu32);
    y[..len].iter_mut().for_each(|v| *v -= my32);
    // The next state is the state plus its change.
    let (sv, svv) = (su + sy, suu + 2.0 * suy + syy);
    Window {
        s22: suu - su * mu,
        syy: syy - sy * my,
        snn: svv - sv * (sv / n),
        s2y: suy - su * my,
        rest2: f64::from(mu32) - mu,
        resty: f64::from(my32) - my,
    }
}

/// `(Σ f64(x), Σ f64(x)²)`, four lanes each, a fixed order.
#[inline(always)]
fn sum_and_squares(x: &[f32]) -> (f64, f64) {
    let (mut s, mut q) = ([0.0f64; 4], [0.0f64; 4]);
    let chunks = x.chunks_exact(4);
    let tail = chunks.remainder();
    for c in chunks {
        for l in 0..4 {
            let v = f64::from(c[l]);
            s[l] += v;
            q[l] += v * v;
        }
    }
    let (mut s, mut q) = ((s[0] + s[1]) + (s[2] + s[3]), (q[0] + q[1]) + (q[2] + q[3]));
    for &v in tail {
        let v = f64::from(v);
        s += v;
        q += v * v;
    }
    (s, q)
}

/// The reported lag of shift index `i` (into a fit vector).
pub fn lag_of(i: usize) -> i32 {
    (SHIFT_MIN + i as i64 + 1) as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tracking(n: usize, late: usize) -> (Vec<f32>, Vec<f32>) {
        let cmd: Vec<f32> = (0..n + late)
            .map(|t| (t as f32 * 0.07).sin() + 0.4 * (t as f32 * 0.19).cos())
            .collect();
        let mut s = vec![0.0; n];
        let mut x = cmd[0];
        for t in 0..n {
            s[t] = x;
            x += 0.3 * (cmd[t + late] - x);
        }
        // The recorded action is `late` steps behind what drove the state.
        let a: Vec<f32> = cmd[..n].to_vec();
        (a, s)
    }

    #[test]
    fn finds_the_lag_of_a_first_order_tracker() {
        for late in [0usize, 3] {
            let (a, s) = tracking(200, late);
            let fits = fit_dim(&a, &s, &mut Scratch::default()).unwrap();
            let best = (0..SHIFTS)
                .min_by(|&i, &j| fits.unexplained[i].total_cmp(&fits.unexplained[j]))
                .unwrap();
            assert_eq!(lag_of(best), 1 - late as i32, "late {late}");
            assert!(fits.convention(best) > 0.3);
            assert!((fits.alpha[best] - 0.3).abs() < 0.01);
        }
    }
}
