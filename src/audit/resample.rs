//! Resampling a whole episode from `n` to `num` steps, along the time axis of a row-major
//! `(n, width)` block: the Fourier method (what `scipy.signal.resample` computes for real input)
//! or linear interpolation. Output step `k` sits at source position `k · n / num` (in steps) for
//! both, and images take the nearest source frame at that position.
//!
//! Fourier: the real FFT of each column keeps its `min(n, num) / 2 + 1` lowest frequencies; when
//! that count `m = min(n, num)` is even, the unpaired bin `m / 2` is doubled when shortening and
//! halved when lengthening (scipy's handling of the Nyquist bin); the inverse real FFT of length
//! `num` is scaled by `num / n`. The method treats the episode as one period of a periodic
//! signal: where the last step differs from the first, the result rings near both ends (Gibbs).
//! Linear interpolation has no such edge effect; past the last step it holds the last value
//! (as `numpy.interp`).

use rustfft::num_complex::Complex;
use rustfft::FftPlanner;

use crate::spec::ResampleMethod;

/// Resamples every column of `y` (`n` rows of `width` values) to `num` rows.
pub fn resample(y: &[f64], width: usize, num: usize, method: ResampleMethod) -> Vec<f64> {
    match method {
        ResampleMethod::Fourier => fourier(y, width, num),
        ResampleMethod::Linear => linear(y, width, num),
    }
}

/// Source position (in steps) of output step `k`.
pub fn position(k: usize, n: usize, num: usize) -> f64 {
    k as f64 * n as f64 / num as f64
}

/// The source step nearest to output step `k` (ties go to the earlier step).
pub fn nearest(k: usize, n: usize, num: usize) -> usize {
    let p = position(k, n, num);
    let below = p.floor();
    let i = if p - below > 0.5 { below + 1.0 } else { below };
    (i as usize).min(n - 1)
}

pub fn fourier(y: &[f64], width: usize, num: usize) -> Vec<f64> {
    let n = y.len().checked_div(width).unwrap_or(0);
    let mut out = vec![0.0; num * width];
    if n == 0 || num == 0 || width == 0 {
        return out;
    }
    let mut planner = FftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n);
    let inverse = planner.plan_fft_inverse(num);
    let m = n.min(num);
    let kept = m / 2 + 1;
    let scale = num as f64 / n as f64 / num as f64; // `num / n`, and the inverse FFT's `1 / num`
    let mut column = vec![Complex::new(0.0, 0.0); n];
    let mut spectrum = vec![Complex::new(0.0, 0.0); num];
    for c in 0..width {
        for (i, v) in column.iter_mut().enumerate() {
            *v = Complex::new(y[i * width + c], 0.0);
        }
        forward.process(&mut column);
        // The one-sided spectrum scipy keeps, with its unpaired-bin rule.
        let mut half: Vec<Complex<f64>> = column[..kept.min(n)].to_vec();
        if m.is_multiple_of(2) && num != n {
            half[m / 2] *= if num < n { 2.0 } else { 0.5 };
        }
        // The inverse real FFT of length `num`: a Hermitian spectrum whose bin 0 and (for even
        // `num`) bin `num / 2` count with their real part only.
        spectrum
            .iter_mut()
            .for_each(|v| *v = Complex::new(0.0, 0.0));
        for (k, &v) in half.iter().enumerate() {
            if k > num / 2 {
                break;
            }
            if k == 0 || (num.is_multiple_of(2) && k == num / 2) {
                spectrum[k] = Complex::new(v.re, 0.0);
            } else {
                spectrum[k] = v;
                spectrum[num - k] = v.conj();
            }
        }
        inverse.process(&mut spectrum);
        for (k, v) in spectrum.iter().enumerate() {
            out[k * width + c] = v.re * scale;
        }
    }
    out
}

pub fn linear(y: &[f64], width: usize, num: usize) -> Vec<f64> {
    let n = y.len().checked_div(width).unwrap_or(0);
    let mut out = Vec::with_capacity(num * width);
    if n == 0 {
        return vec![0.0; num * width];
    }
    for k in 0..num {
        let p = position(k, n, num);
        let i = p.floor() as usize;
        if i + 1 >= n {
            out.extend_from_slice(&y[(n - 1) * width..n * width]);
            continue;
        }
        let f = p - i as f64;
        for c in 0..width {
            let (a, b) = (y[i * width + c], y[(i + 1) * width + c]);
            out.push(a + f * (b - a));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn sine(n: usize, cycles: f64, phase: f64) -> Vec<f64> {
        (0..n)
            .map(|i| (2.0 * PI * cycles * i as f64 / n as f64 + phase).sin())
            .collect()
    }

    #[test]
    fn band_limited_sines_resample_exactly() {
        // A periodic sine well below both Nyquist frequencies is reproduced exactly at the new
        // sample positions, shortening and lengthening, even and odd lengths.
        for (n, num) in [(40, 50), (50, 40), (41, 64), (64, 41), (30, 30), (33, 100)] {
            let got = fourier(&sine(n, 3.0, 0.4), 1, num);
            let want = sine(num, 3.0, 0.4);
            for (a, b) in got.iter().zip(&want) {
                assert!((a - b).abs() < 1e-9, "{n} -> {num}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn columns_are_independent_and_constants_stay() {
        let n = 25;
        let y: Vec<f64> = (0..n).flat_map(|i| [2.5, (i as f64 * 0.3).cos()]).collect();
        let both = fourier(&y, 2, 37);
        let single: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).cos()).collect();
        let alone = fourier(&single, 1, 37);
        for k in 0..37 {
            assert!((both[2 * k] - 2.5).abs() < 1e-12);
            assert!((both[2 * k + 1] - alone[k]).abs() < 1e-12);
        }
    }

    #[test]
    fn linear_and_nearest_positions() {
        let y = [0.0, 10.0, 20.0, 30.0];
        // 4 -> 6 steps: positions 0, 2/3, 4/3, 2, 8/3, 10/3 (past the end holds the last value).
        let got = linear(&y, 1, 6);
        let want = [0.0, 20.0 / 3.0, 40.0 / 3.0, 20.0, 80.0 / 3.0, 30.0];
        for (a, b) in got.iter().zip(want) {
            assert!((a - b).abs() < 1e-12);
        }
        assert_eq!(
            (0..6).map(|k| nearest(k, 4, 6)).collect::<Vec<_>>(),
            [0, 1, 1, 2, 3, 3]
        );
        // A tie (position 0.5) goes to the earlier step.
        assert_eq!(nearest(1, 2, 4), 0);
    }
}
