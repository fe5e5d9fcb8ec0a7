//! The not-a-knot cubic spline (what `scipy.interpolate.CubicSpline` computes by default),
//! evaluated for every column of a row-major `(n, width)` block at once.
//!
//! The spline is found through its first derivatives `s_i` at the knots: every interior knot
//! makes the second derivative continuous,
//! `dx_i s_{i-1} + 2 (dx_{i-1} + dx_i) s_i + dx_{i-1} s_{i+1} = 3 (dx_i m_{i-1} + dx_{i-1} m_i)`
//! (`m_i` the slope of interval `i`), and the two end conditions make the third derivative
//! continuous at the second and the second-to-last knot (not-a-knot). The matrix is tridiagonal
//! and the same for every column: it is factored once. Two knots give the straight line and
//! three the parabola through them, as in scipy. Outside the knots the end pieces extrapolate.

/// Interpolates `y` (row-major, `x.len()` rows of `width` values), known at the strictly
/// increasing `x`, at the times `at`. Returns `at.len()` rows of `width` values.
// Long function: one numeric algorithm (the natural cubic spline's tridiagonal solve and evaluation).
pub fn interpolate(x: &[f64], y: &[f64], width: usize, at: &[f64]) -> Vec<f64> {
    let n = x.len();
    assert!(n >= 2, "a spline needs two knots");
    assert_eq!(y.len(), n * width);
    let dx: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    let slope = |i: usize, c: usize| (y[(i + 1) * width + c] - y[i * width + c]) / dx[i];
    // Derivatives at the knots, row-major like `y`.
    let mut s = vec![0.0; n * width];
    if n == 2 {
        for c in 0..width {
            s[c] = slope(0, c);
            s[width + c] = slope(0, c);
        }
    } else if n == 3 {
        // The parabola through three points: s0 + s1 = 2 m0, s1 + s2 = 2 m1, and the interior
        // condition. Solved in closed form per column.
        let (d0, d1) = (dx[0], dx[1]);
        for c in 0..width {
            let (m0, m1) = (slope(0, c), slope(1, c));
            // Substituting s0 = 2 m0 - s1 and s2 = 2 m1 - s1 into the interior row:
            // d1 (2 m0 - s1) + 2 (d0 + d1) s1 + d0 (2 m1 - s1) = 3 (d1 m0 + d0 m1).
            let s1 = (d1 * m0 + d0 * m1) / (d0 + d1);
            s[c] = 2.0 * m0 - s1;
            s[width + c] = s1;
            s[2 * width + c] = 2.0 * m1 - s1;
        }
    } else {
        // Rows: sub[i] s_{i-1} + diag[i] s_i + sup[i] s_{i+1} = rhs_i.
        let mut sub = vec![0.0; n];
        let mut diag = vec![0.0; n];
        let mut sup = vec![0.0; n];
        diag[0] = dx[1];
        sup[0] = x[2] - x[0];
        for i in 1..n - 1 {
            sub[i] = dx[i];
            diag[i] = 2.0 * (dx[i - 1] + dx[i]);
            sup[i] = dx[i - 1];
        }
        sub[n - 1] = x[n - 1] - x[n - 3];
        diag[n - 1] = dx[n - 3];
        let rhs = |i: usize, c: usize| -> f64 {
            if i == 0 {
                let d = x[2] - x[0];
                ((dx[0] + 2.0 * d) * dx[1] * slope(0, c) + dx[0] * dx[0] * slope(1, c)) / d
            } else if i == n - 1 {
                let d = x[n - 1] - x[n - 3];
                (dx[n - 2] * dx[n - 2] * slope(n - 3, c)
                    + (2.0 * d + dx[n - 2]) * dx[n - 3] * slope(n - 2, c))
                    / d
            } else {
                3.0 * (dx[i] * slope(i - 1, c) + dx[i - 1] * slope(i, c))
            }
        };
        // Thomas algorithm: forward elimination of the matrix once ...
        let mut c_prime = vec![0.0; n];
        let mut denom = vec![0.0; n];
        denom[0] = diag[0];
        c_prime[0] = sup[0] / denom[0];
        for i in 1..n {
            denom[i] = diag[i] - sub[i] * c_prime[i - 1];
            c_prime[i] = sup[i] / denom[i];
        }
        // ... then per column.
        let mut d = vec![0.0; n];
        for c in 0..width {
            d[0] = rhs(0, c) / denom[0];
            for i in 1..n {
                d[i] = (rhs(i, c) - sub[i] * d[i - 1]) / denom[i];
            }
            s[(n - 1) * width + c] = d[n - 1];
            for i in (0..n - 1).rev() {
                let next = s[(i + 1) * width + c];
                s[i * width + c] = d[i] - c_prime[i] * next;
            }
        }
    }

    let mut out = Vec::with_capacity(at.len() * width);
    for &t in at {
        // The piece whose interval holds t (x_i <= t < x_{i+1}); the end pieces outside.
        let i = x.partition_point(|&v| v <= t).clamp(1, n - 1) - 1;
        let tau = t - x[i];
        let h = dx[i];
        for c in 0..width {
            let m = slope(i, c);
            let (s0, s1) = (s[i * width + c], s[(i + 1) * width + c]);
            let k = (s0 + s1 - 2.0 * m) / h;
            let c3 = k / h;
            let c2 = (m - s0) / h - k;
            out.push(((c3 * tau + c2) * tau + s0) * tau + y[i * width + c]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::interpolate;

    fn cubic(t: f64) -> [f64; 2] {
        [
            0.5 * t * t * t - 2.0 * t * t + t - 3.0,
            -t * t * t + 0.25 * t + 7.0,
        ]
    }

    #[test]
    fn reproduces_cubics_exactly() {
        // Not-a-knot splines are exact for cubics, on any knots, inside and outside them.
        for n in 4..9 {
            let x: Vec<f64> = (0..n)
                .map(|i| i as f64 * 0.7 + (i * i) as f64 * 0.05)
                .collect();
            let y: Vec<f64> = x.iter().flat_map(|&t| cubic(t)).collect();
            let at: Vec<f64> = (0..40).map(|i| -0.5 + i as f64 * 0.13).collect();
            let got = interpolate(&x, &y, 2, &at);
            for (k, &t) in at.iter().enumerate() {
                let want = cubic(t);
                for c in 0..2 {
                    assert!(
                        (got[2 * k + c] - want[c]).abs() < 1e-9,
                        "n {n}, t {t}: {} vs {}",
                        got[2 * k + c],
                        want[c]
                    );
                }
            }
        }
    }

    #[test]
    fn passes_through_the_knots_and_handles_few_points() {
        let x = [0.0, 0.1, 0.35, 0.4, 0.9];
        let y = [1.0, -2.0, 0.5, 3.0, 2.0];
        assert_eq!(interpolate(&x, &y, 1, &x).len(), 5);
        for (a, b) in interpolate(&x, &y, 1, &x).iter().zip(y) {
            assert!((a - b).abs() < 1e-12);
        }
        // Two knots: the line; three: the parabola through them.
        let line = interpolate(&[0.0, 2.0], &[1.0, 5.0], 1, &[1.0, 3.0]);
        assert!((line[0] - 3.0).abs() < 1e-12 && (line[1] - 7.0).abs() < 1e-12);
        let p = |t: f64| 2.0 * t * t - t + 1.0;
        let xs = [0.0, 0.3, 1.0];
        let ys: Vec<f64> = xs.iter().map(|&t| p(t)).collect();
        for t in [0.1, 0.5, 0.9, 1.5] {
            assert!((interpolate(&xs, &ys, 1, &[t])[0] - p(t)).abs() < 1e-12);
        }
    }
}
