//! The rows of one window, resolved the way the generated loader resolves them: which stored row
//! each action step reads, and what fills the padded steps. The `materialized` and `virtual`
//! HDF5 layouts use it, so their chunks equal the loader's bit for bit.

use crate::spec::Padding;
use crate::stats::normalize::Normalizer;
use crate::window::Window;

/// Where one action step of a window comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// An episode-relative row.
    Row(usize),
    /// Padding; the episode-relative edge row it repeats (`edge`) or sits next to.
    Pad(usize),
}

/// The K action steps of the sample `(t, limit)` in an episode of `len` steps (the loader's
/// `_actions`: at least one valid row, padding before and after).
pub fn action_steps(window: &Window, t: usize, limit: usize, len: usize) -> Vec<Step> {
    let k = window.chunk as i64;
    let first = t as i64 - window.lead as i64;
    let stop = first + limit as i64;
    let len = len as i64;
    let lo = first.clamp(0, (len - 1).max(0));
    let hi = stop.min(len).max(lo + 1);
    let n_before = (lo - first).min(k);
    let n_valid = (hi - lo).min(k - n_before);
    let mut steps = Vec::with_capacity(k as usize);
    steps.extend((0..n_before).map(|_| Step::Pad(lo as usize)));
    steps.extend((lo..lo + n_valid).map(|r| Step::Row(r as usize)));
    let last = (lo + n_valid - 1).max(lo) as usize;
    steps.extend((steps.len() as i64..k).map(|_| Step::Pad(last)));
    steps
}

/// The observation rows (episode-relative, oldest first) and their pad flags for the sample at
/// current step `t`.
pub fn obs_steps(window: &Window, t: usize) -> Vec<(usize, bool)> {
    let h = window.obs_history as i64;
    (0..h)
        .map(|j| {
            let p = t as i64 - h + 1 + j;
            (p.max(0) as usize, p < 0)
        })
        .collect()
}

/// The stored (normalized) values of a padded step whose edge row is `edge`.
pub fn pad_row(padding: Padding, normalizer: &Normalizer, edge: &[f32]) -> Vec<f32> {
    match padding {
        Padding::Zero => (0..edge.len())
            .map(|d| normalizer.forward(d, 0.0) as f32)
            .collect(),
        Padding::Mask => vec![0.0; edge.len()],
        Padding::Edge | Padding::Truncate => edge.to_vec(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn window(chunk: usize, lead: usize) -> Window {
        Window {
            chunk,
            obs_history: 2,
            lead,
            padding: Padding::Edge,
            stride: 1,
            max_pad_after: None,
        }
    }

    #[test]
    fn pads_before_and_after() {
        let w = window(4, 1);
        assert_eq!(
            action_steps(&w, 0, 4, 3),
            vec![Step::Pad(0), Step::Row(0), Step::Row(1), Step::Row(2)]
        );
        assert_eq!(
            action_steps(&w, 2, 4, 3),
            vec![Step::Row(1), Step::Row(2), Step::Pad(2), Step::Pad(2)]
        );
        assert_eq!(obs_steps(&w, 0), vec![(0, true), (0, false)]);
    }
}
