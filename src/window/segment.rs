//! Variable-length chunks: episodes cut at natural breakpoints.
//!
//! A watched series is first smoothed with a trailing moving average of `smoothing` steps. The
//! tracked signal is its first difference (`velocity`) or the smoothed values themselves
//! (`sign_change`, for a gripper command or a contact flag). A sign is tracked with hysteresis:
//! only values beyond ±threshold set it. A breakpoint is a step where the tracked sign flips. The
//! breakpoints of all watched dimensions are merged; segments shorter than `min_length` are
//! merged into the one before, and segments longer than `max_length` are split.

use crate::spec::SegmentMethod;

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SegmentParams {
    pub method: SegmentMethod,
    pub smoothing: usize,
    pub threshold: f64,
    pub min_length: usize,
    pub max_length: usize,
}

/// Steps (in `1..len`) where a new segment starts, from row-major `values` with `width` values
/// per step, watching the dimensions `dims`.
pub fn breakpoints(values: &[f32], width: usize, dims: &[usize], p: &SegmentParams) -> Vec<usize> {
    let len = values.len().checked_div(width).unwrap_or(0);
    let mut out = Vec::new();
    for &d in dims {
        let series: Vec<f64> = (0..len).map(|t| f64::from(values[t * width + d])).collect();
        let smooth = trailing_mean(&series, p.smoothing.max(1));
        let mut state = 0i8;
        for t in 0..len {
            let signal = match p.method {
                SegmentMethod::Velocity if t == 0 => continue,
                SegmentMethod::Velocity => smooth[t] - smooth[t - 1],
                SegmentMethod::SignChange => smooth[t],
            };
            let sign = if signal > p.threshold {
                1
            } else if signal < -p.threshold {
                -1
            } else {
                continue;
            };
            if state != 0 && sign != state && t > 0 {
                out.push(t);
            }
            state = sign;
        }
    }
    out.sort_unstable();
    out.dedup();
    out
}

fn trailing_mean(x: &[f64], window: usize) -> Vec<f64> {
    let mut out = Vec::with_capacity(x.len());
    let mut sum = 0.0;
    for t in 0..x.len() {
        sum += x[t];
        if t >= window {
            sum -= x[t - window];
        }
        out.push(sum / (t + 1).min(window) as f64);
    }
    out
}

/// Segments `(start, length)` covering `0..len`, from breakpoints, after the length rules.
pub fn segments(len: usize, breakpoints: &[usize], p: &SegmentParams) -> Vec<(usize, usize)> {
    if len == 0 {
        return Vec::new();
    }
    let min = p.min_length.max(1);
    let mut starts = vec![0];
    for &b in breakpoints {
        if b < len && b - starts.last().unwrap() >= min {
            starts.push(b);
        }
    }
    // A too-short last segment joins the one before it.
    while starts.len() > 1 && len - starts.last().unwrap() < min {
        starts.pop();
    }
    let mut out = Vec::new();
    for (i, &a) in starts.iter().enumerate() {
        let b = starts.get(i + 1).copied().unwrap_or(len);
        let mut s = a;
        while s < b {
            let n = (b - s).min(p.max_length.max(1));
            out.push((s, n));
            s += n;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(method: SegmentMethod) -> SegmentParams {
        SegmentParams {
            method,
            smoothing: 1,
            threshold: 0.0,
            min_length: 1,
            max_length: 1000,
        }
    }

    #[test]
    fn velocity_zero_crossings_of_a_triangle_wave() {
        // Up for 10 steps, down for 10, up again: the first steps moving the other way are 11
        // and 21.
        let x: Vec<f32> = (0..30)
            .map(|t| match t {
                0..=10 => t as f32,
                11..=20 => (20 - t) as f32,
                _ => (t - 20) as f32,
            })
            .collect();
        let b = breakpoints(&x, 1, &[0], &params(SegmentMethod::Velocity));
        assert_eq!(b, vec![11, 21]);
        let segs = segments(30, &b, &params(SegmentMethod::Velocity));
        assert_eq!(segs, vec![(0, 11), (11, 10), (21, 9)]);
    }

    #[test]
    fn threshold_ignores_noise_and_lengths_are_enforced() {
        // A gripper command: -1 (open) then +1 (closed), with small chatter around zero.
        let x: Vec<f32> = (0..40)
            .map(|t| match t {
                0..=14 => -1.0,
                15..=16 => 0.01,
                17..=29 => 1.0,
                _ => -1.0,
            })
            .collect();
        let mut p = params(SegmentMethod::SignChange);
        p.threshold = 0.1;
        assert_eq!(breakpoints(&x, 1, &[0], &p), vec![17, 30]);
        p.min_length = 12;
        assert_eq!(segments(40, &[17, 30], &p), vec![(0, 17), (17, 23)]);
        p.min_length = 1;
        p.max_length = 8;
        let segs = segments(40, &[17, 30], &p);
        assert!(segs.iter().all(|&(_, n)| n <= 8));
        assert_eq!(segs.iter().map(|&(_, n)| n).sum::<usize>(), 40);
    }

    #[test]
    fn smoothing_is_a_trailing_mean() {
        assert_eq!(
            trailing_mean(&[2.0, 4.0, 6.0, 8.0], 2),
            vec![2.0, 3.0, 5.0, 7.0]
        );
    }
}
