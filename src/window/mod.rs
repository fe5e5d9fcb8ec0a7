//! The window index: which samples an episode yields, and which stored rows each sample reads.
//!
//! A sample is `(t, limit, sub)` within an episode of `len` steps: `t` is its current step (the
//! last observation frame), observations are rows `t-H+1 ..= t` with the first frame repeated
//! before the episode start, and actions are rows `t - lead + k` for `k < K` where `lead` is 0
//! (alignment `current`) or `H-1` (Diffusion Policy's alignment: actions start at the first
//! observation frame). Action rows outside the episode, or at `k >= limit`, are padding.
//! Segments and hierarchical chunks reuse the same row rules (`segment`, `hierarchy`).
//!
//! Every row index stays inside its episode: this module decides it ([`Window::action_steps`],
//! [`Window::obs_steps`]: the layouts that materialize windows use them, so their chunks equal the
//! loader's bit for bit), and the loader template mirrors it. [`EpisodeEnds`] holds where each
//! episode's rows lie in the stored arrays.

mod ends;
pub mod hierarchy;
pub mod segment;

pub use ends::{Ends, EpisodeEnds};

use crate::spec::Padding;

/// One sample of an episode: the row of the window index (`episode` is added by the caller).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sample {
    /// Current step: the last observation frame.
    pub t: usize,
    /// Action steps that belong to the sample (K for plain windows; the segment length for
    /// segments; the coarse length for hierarchical samples).
    pub limit: usize,
    /// Fine-chunk index within the coarse chunk (hierarchical samples), else 0.
    pub sub: usize,
}

/// The parameters that shape fixed windows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Window {
    pub chunk: usize,
    pub obs_history: usize,
    /// Steps the action chunk starts before the current step.
    pub lead: usize,
    pub padding: Padding,
    pub stride: usize,
    /// At most this many padded action steps after the episode end (Diffusion Policy's
    /// `pad_after = n_action_steps - 1`); unbounded when `None`.
    pub max_pad_after: Option<usize>,
}

impl Window {
    /// The range of current steps `[first, end)` an episode of `len` steps allows.
    fn t_range(&self, len: usize) -> (usize, usize) {
        let (k, lead) = (self.chunk, self.lead);
        if self.padding == Padding::Truncate {
            // No padding anywhere: t-H+1 >= 0, t-lead >= 0 and t-lead+K <= len.
            let first = (self.obs_history - 1).max(lead);
            return (first, (len + lead + 1).saturating_sub(k).min(len));
        }
        let end = match self.max_pad_after {
            // t - lead + K - 1 <= len - 1 + pad_after
            Some(p) => (len + p + lead + 1).saturating_sub(k).min(len),
            None => len,
        };
        (0, end)
    }

    /// The samples an episode of `len` steps yields, in increasing `t`.
    pub fn samples(&self, len: usize) -> Vec<Sample> {
        let (first, end) = self.t_range(len);
        (first..end.max(first))
            .step_by(self.stride)
            .map(|t| Sample {
                t,
                limit: self.chunk,
                sub: 0,
            })
            .collect()
    }

    /// Number of samples an episode of `len` steps yields.
    pub fn count(&self, len: usize) -> usize {
        let (first, end) = self.t_range(len);
        if end <= first {
            0
        } else {
            (end - first).div_ceil(self.stride)
        }
    }

    /// The K action steps of the sample `(t, limit)` in an episode of `len` steps, as the
    /// generated loader's `_actions` resolves them: at least one valid row, padding before the
    /// episode start and after its end (or after `limit` steps).
    pub fn action_steps(&self, t: usize, limit: usize, len: usize) -> Vec<Step> {
        let k = self.chunk as i64;
        let first = t as i64 - self.lead as i64;
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

    /// Observation rows (episode-relative, oldest first) of the sample at `t`, each with whether
    /// it is padding: the first observation repeats before the episode start.
    pub fn obs_steps(&self, t: usize) -> Vec<(usize, bool)> {
        let h = self.obs_history as i64;
        (0..h)
            .map(|j| {
                let p = t as i64 - h + 1 + j;
                (p.max(0) as usize, p < 0)
            })
            .collect()
    }
}

/// Where one action step of a window comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// An episode-relative row.
    Row(usize),
    /// Padding; the episode-relative edge row it repeats (`edge`) or sits next to.
    Pad(usize),
}

/// How a profile turns an episode into samples.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "mode", rename_all = "snake_case")]
pub enum Sampling {
    /// Fixed windows of `window.chunk` actions.
    Window { window: Window },
    /// One sample per segment, padded to `window.chunk` (= the maximum segment length).
    Segment {
        window: Window,
        params: segment::SegmentParams,
        /// Index of the watched channel in the manifest, and the dimensions watched.
        channel: usize,
        dims: Vec<usize>,
    },
    /// Fine chunks of `window.chunk` inside coarse chunks of `coarse` steps.
    Hierarchy { window: Window, coarse: usize },
}

impl Sampling {
    pub fn window(&self) -> &Window {
        match self {
            Sampling::Window { window }
            | Sampling::Segment { window, .. }
            | Sampling::Hierarchy { window, .. } => window,
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Sampling::Window { .. } => "window",
            Sampling::Segment { .. } => "segment",
            Sampling::Hierarchy { .. } => "hierarchy",
        }
    }

    /// Samples of an episode of `len` steps; `watched` is the segmented channel's raw values
    /// (row-major, with its width), needed only by `Segment`.
    pub fn samples(&self, len: usize, watched: Option<(&[f32], usize)>) -> Vec<Sample> {
        match self {
            Sampling::Window { window } => window.samples(len),
            Sampling::Hierarchy { window, coarse } => {
                hierarchy::samples(len, *coarse, window.chunk, window.stride, window.padding)
            }
            Sampling::Segment { params, dims, .. } => {
                let (values, width) = watched.expect("segmenting needs the watched channel");
                let cuts = segment::breakpoints(values, width, dims, params);
                segment::segments(len, &cuts, params)
                    .into_iter()
                    .map(|(t, limit)| Sample { t, limit, sub: 0 })
                    .collect()
            }
        }
    }

    /// Number of samples, when it follows from the length alone.
    pub fn count(&self, len: usize) -> Option<usize> {
        match self {
            Sampling::Window { window } => Some(window.count(len)),
            Sampling::Hierarchy { .. } => Some(self.samples(len, None).len()),
            Sampling::Segment { .. } => None,
        }
    }
}

/// Steps kept when converting from the source rate to a profile's rate by an integer factor:
/// steps 0, f, 2f, ... of each episode.
pub fn decimated_len(len: usize, factor: usize) -> usize {
    len.div_ceil(factor)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn w(chunk: usize, obs: usize, padding: Padding, stride: usize) -> Window {
        Window {
            chunk,
            obs_history: obs,
            lead: 0,
            padding,
            stride,
            max_pad_after: None,
        }
    }

    #[test]
    fn samples_match_count_and_stay_inside_for_every_mode() {
        for padding in [
            Padding::Edge,
            Padding::Zero,
            Padding::Mask,
            Padding::Truncate,
        ] {
            for len in 0..30 {
                for chunk in 1..10 {
                    for obs in 1..4 {
                        for stride in 1..4 {
                            for (lead, pad_after) in [(0, None), (obs - 1, Some(chunk / 2))] {
                                let win = Window {
                                    lead,
                                    max_pad_after: pad_after,
                                    ..w(chunk, obs, padding, stride)
                                };
                                let samples = win.samples(len);
                                assert_eq!(samples.len(), win.count(len), "{win:?} len {len}");
                                for s in &samples {
                                    assert!(s.t < len);
                                    let steps = win.action_steps(s.t, s.limit, len);
                                    assert_eq!(steps.len(), chunk);
                                    let row = |s: &Step| match *s {
                                        Step::Row(r) | Step::Pad(r) => r,
                                    };
                                    assert!(steps.iter().all(|s| row(s) < len));
                                    assert!(win.obs_steps(s.t).iter().all(|&(r, _)| r <= s.t));
                                    if padding == Padding::Truncate {
                                        assert!(steps.iter().all(|s| matches!(s, Step::Row(_))));
                                        assert!(s.t + 1 >= obs);
                                    }
                                    if let Some(p) = pad_after {
                                        let after =
                                            (0..chunk).filter(|k| s.t + k >= len + lead).count();
                                        assert!(after <= p, "{win:?} len {len} t {}", s.t);
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn diffusion_policy_window_count() {
        // Diffusion Policy: L - horizon + pad_before + pad_after + 1 windows per episode.
        let win = Window {
            lead: 1,
            max_pad_after: Some(7),
            ..w(16, 2, Padding::Edge, 1)
        };
        for len in [8, 9, 50, 161] {
            assert_eq!(win.count(len), len - 16 + 1 + 7 + 1, "len {len}");
        }
        assert_eq!(win.count(7), 0);
        let steps = win.action_steps(0, 16, 50);
        assert_eq!(steps[..2], [Step::Pad(0), Step::Row(0)]);
    }

    #[test]
    fn truncate_drops_short_episodes() {
        assert_eq!(w(16, 2, Padding::Truncate, 1).count(16), 0);
        assert_eq!(w(16, 2, Padding::Truncate, 1).samples(17)[0].t, 1);
    }

    #[test]
    fn obs_history_repeats_first_frame() {
        let win = w(4, 3, Padding::Edge, 1);
        let rows = |t| {
            win.obs_steps(t)
                .into_iter()
                .map(|(r, _)| r)
                .collect::<Vec<_>>()
        };
        assert_eq!(rows(0), vec![0, 0, 0]);
        assert_eq!(rows(1), vec![0, 0, 1]);
        assert_eq!(rows(5), vec![3, 4, 5]);
        assert_eq!(win.obs_steps(1), vec![(0, true), (0, false), (1, false)]);
    }

    #[test]
    fn pads_before_and_after() {
        let win = Window {
            lead: 1,
            ..w(4, 2, Padding::Edge, 1)
        };
        assert_eq!(
            win.action_steps(0, 4, 3),
            vec![Step::Pad(0), Step::Row(0), Step::Row(1), Step::Row(2)]
        );
        assert_eq!(
            win.action_steps(2, 4, 3),
            vec![Step::Row(1), Step::Row(2), Step::Pad(2), Step::Pad(2)]
        );
        assert_eq!(win.obs_steps(0), vec![(0, true), (0, false)]);
    }

    #[test]
    fn decimation_keeps_first_step() {
        assert_eq!(decimated_len(10, 5), 2);
        assert_eq!(decimated_len(11, 5), 3);
        assert_eq!(decimated_len(7, 1), 7);
    }
}
