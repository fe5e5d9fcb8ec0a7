//! The sample autocorrelation of one series, as `statsmodels.tsa.stattools.acf` computes it with
//! its defaults (`adjusted=False`, `demean=True`; its FFT path gives the same numbers):
//!
//! `acf[k] = Σ_{t < n-k} (x_t - x̄)(x_{t+k} - x̄) / Σ_t (x_t - x̄)²`
//!
//! The sums run directly (O(n · lags)), in f64, in a fixed order, so the result is the same on
//! every machine.

/// `acf[0..=max_lag]` of `x`, stopping early at lag `n - 1`; `None` when `x` has fewer than two
/// values or does not vary (the formula divides by zero there; statsmodels returns NaN).
pub fn acf(x: &[f64], max_lag: usize) -> Option<Vec<f64>> {
    let n = x.len();
    if n < 2 {
        return None;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let d: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let denom: f64 = d.iter().map(|v| v * v).sum();
    if denom == 0.0 {
        return None;
    }
    let lags = max_lag.min(n - 1);
    Some(
        (0..=lags)
            .map(|k| {
                d[..n - k]
                    .iter()
                    .zip(&d[k..])
                    .map(|(a, b)| a * b)
                    .sum::<f64>()
                    / denom
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::acf;

    #[test]
    fn lag_zero_is_one_and_alternating_series_is_negative_at_lag_one() {
        let x = [1.0, -1.0, 1.0, -1.0, 1.0, -1.0];
        let r = acf(&x, 10).unwrap();
        assert_eq!(r.len(), 6, "capped at n - 1");
        assert!((r[0] - 1.0).abs() < 1e-15);
        // Σ_{t<5} x_t x_{t+1} = -5, Σ x² = 6.
        assert!((r[1] + 5.0 / 6.0).abs() < 1e-15);
    }

    #[test]
    fn hand_computed_values() {
        // x = 1..=4: mean 2.5, d = -1.5 -0.5 0.5 1.5, Σd² = 5.
        let r = acf(&[1.0, 2.0, 3.0, 4.0], 3).unwrap();
        let expected = [
            1.0,
            (0.75 - 0.25 + 0.75) / 5.0,
            (-0.75 - 0.75) / 5.0,
            -2.25 / 5.0,
        ];
        for (a, b) in r.iter().zip(expected) {
            assert!((a - b).abs() < 1e-15, "{r:?}");
        }
    }

    #[test]
    fn constant_and_too_short_series_have_none() {
        assert!(acf(&[3.0; 10], 5).is_none());
        assert!(acf(&[3.0], 5).is_none());
        assert!(acf(&[], 5).is_none());
    }
}
