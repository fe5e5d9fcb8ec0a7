//! The window index: which samples an episode yields, and which stored rows each sample reads.
//!
//! Alignment `current`: the sample at step `t` takes actions `t .. t+K` and observations
//! `t-H+1 ..= t` (H = obs_history). Rows before the episode start repeat the first observation;
//! rows past the end are padded according to [`Padding`]. Every row index stays inside its
//! episode: this module is the only place that decides it, and the loader template mirrors it.

use crate::spec::Padding;

/// The parameters that shape windows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    pub chunk: usize,
    pub obs_history: usize,
    pub padding: Padding,
    pub stride: usize,
}

impl Window {
    /// The steps `t` (within an episode of `len` steps) at which samples start.
    pub fn starts(&self, len: usize) -> Vec<usize> {
        let (first, last_exclusive) = match self.padding {
            Padding::Truncate => {
                let first = self.obs_history - 1;
                // t + K <= len, so t < len - K + 1.
                let end = (len + 1).saturating_sub(self.chunk);
                (first, end)
            }
            _ => (0, len),
        };
        (first..last_exclusive.max(first))
            .step_by(self.stride)
            .collect()
    }

    /// Number of samples an episode of `len` steps yields.
    pub fn count(&self, len: usize) -> usize {
        let (first, end) = match self.padding {
            Padding::Truncate => (self.obs_history - 1, (len + 1).saturating_sub(self.chunk)),
            _ => (0, len),
        };
        if end <= first {
            0
        } else {
            (end - first).div_ceil(self.stride)
        }
    }

    /// Action rows (episode-relative) for the sample at `t`, with `None` where the chunk runs past
    /// the episode (what fills it depends on the padding mode; `action_is_pad` is true there).
    pub fn action_rows(&self, t: usize, len: usize) -> impl Iterator<Item = Option<usize>> + '_ {
        (t..t + self.chunk).map(move |r| (r < len).then_some(r))
    }

    /// Observation rows (episode-relative) for the sample at `t`, oldest first; the first
    /// observation repeats before the episode start.
    pub fn obs_rows(&self, t: usize) -> impl Iterator<Item = usize> + '_ {
        let h = self.obs_history;
        (0..h).map(move |j| (t + j).saturating_sub(h - 1))
    }
}

/// Row indices kept when converting from the source rate to a profile's rate by an integer
/// factor: steps 0, f, 2f, ... of each episode.
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
            padding,
            stride,
        }
    }

    #[test]
    fn starts_match_count_for_every_mode() {
        for padding in [
            Padding::Edge,
            Padding::Zero,
            Padding::Mask,
            Padding::Truncate,
        ] {
            for len in 0..40 {
                for chunk in 1..12 {
                    for obs in 1..4 {
                        for stride in 1..5 {
                            let win = w(chunk, obs, padding, stride);
                            let starts = win.starts(len);
                            assert_eq!(starts.len(), win.count(len), "{win:?} len {len}");
                            for &t in &starts {
                                assert!(t < len);
                                if padding == Padding::Truncate {
                                    assert!(t + chunk <= len && t + 1 >= obs);
                                }
                                assert!(win.obs_rows(t).all(|r| r <= t));
                                assert!(win.action_rows(t, len).flatten().all(|r| r < len));
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn truncate_drops_short_episodes() {
        assert_eq!(w(16, 2, Padding::Truncate, 1).count(16), 0);
        assert_eq!(w(16, 2, Padding::Truncate, 1).starts(17), vec![1]);
    }

    #[test]
    fn obs_history_repeats_first_frame() {
        let win = w(4, 3, Padding::Edge, 1);
        assert_eq!(win.obs_rows(0).collect::<Vec<_>>(), vec![0, 0, 0]);
        assert_eq!(win.obs_rows(1).collect::<Vec<_>>(), vec![0, 0, 1]);
        assert_eq!(win.obs_rows(5).collect::<Vec<_>>(), vec![3, 4, 5]);
    }

    #[test]
    fn decimation_keeps_first_step() {
        assert_eq!(decimated_len(10, 5), 2);
        assert_eq!(decimated_len(11, 5), 3);
        assert_eq!(decimated_len(7, 1), 7);
    }
}
