//! Which decoded frame each parquet row gets: LeRobot's rule, decided while frames stream by.
//!
//! LeRobot (`decode_video_frames_torchvision`, pyav backend) gives a row with timestamp `ts` the
//! frame whose `pts × time_base` is nearest to `from_timestamp + ts` (v3.0; `ts` in v2.x). Its
//! arithmetic is torch's: query and frame times as `float32`, the distance `|q − p|` in
//! `float32`, the first minimum on a tie, and a row fails (`FrameTimestampError`) unless the
//! distance is below `tolerance_s` (1e-4, compared in `float32`). The same arithmetic is kept
//! here, so that the frame chosen is the one LeRobot chooses even at a tie.
//!
//! Frames arrive in presentation order, so a row's nearest frame is known as soon as a frame at
//! or after its time arrives: it is that frame or the one before. The decoder keeps two frames,
//! never the video; the audit drives the same rule over the demuxed packet times.

/// LeRobot's default `tolerance_s`.
pub const TOLERANCE_S: f64 = 1e-4;

/// Which of the two frames held a row gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pick {
    /// The frame before the one just pushed.
    Previous,
    /// The frame just pushed.
    Current,
}

/// A row whose nearest frame is too far away.
#[derive(Debug, Clone, PartialEq)]
pub struct Miss {
    /// The row in its episode.
    pub row: usize,
    /// The time looked for (`from_timestamp + ts`), seconds.
    pub target: f64,
    /// The nearest frame's time, `None` when the stream gave no frame at all.
    pub nearest: Option<f64>,
    /// `|target − nearest|` as LeRobot computes it (float32), seconds.
    pub gap: f64,
}

/// The streaming selection for one episode and camera.
pub struct Selector {
    /// Target times as float32 (torch's `torch.tensor(list_of_floats)`), with their rows,
    /// sorted by time (stable: rows in order at equal times).
    targets: Vec<(f32, usize, f64)>,
    next: usize,
    previous: Option<f32>,
    /// Per row: the distance to its frame (float32) and that frame's time.
    chosen: Vec<Option<(f32, f64)>>,
    previous_time: f64,
}

impl Selector {
    /// `targets[row]` is the time row `row` looks for, in seconds.
    pub fn new(targets: &[f64]) -> Selector {
        let mut sorted: Vec<(f32, usize, f64)> = targets
            .iter()
            .enumerate()
            .map(|(row, &t)| (t as f32, row, t))
            .collect();
        sorted.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        Selector {
            targets: sorted,
            next: 0,
            previous: None,
            chosen: vec![None; targets.len()],
            previous_time: 0.0,
        }
    }

    /// The earliest target time (where a decoder seeks to), `None` without rows.
    pub fn first_target(&self) -> Option<f64> {
        self.targets.first().map(|t| t.2)
    }

    /// Whether every row has its frame: nothing after this point can change a choice.
    pub fn done(&self) -> bool {
        self.next == self.targets.len()
    }

    /// The next frame, at `time` seconds (presentation order). Calls `take(row, pick)` for every
    /// row decided by it: those whose time is at or before `time`.
    pub fn push(&mut self, time: f64, mut take: impl FnMut(usize, Pick)) {
        let p = time as f32;
        while let Some(&(q, row, _)) = self.targets.get(self.next) {
            if q > p {
                break;
            }
            let current = (q - p).abs();
            let pick = match self.previous {
                // The earlier frame wins a tie (torch's argmin takes the first minimum).
                Some(prev) if (q - prev).abs() <= current => Pick::Previous,
                _ => Pick::Current,
            };
            self.chosen[row] = Some(match pick {
                Pick::Previous => ((q - self.previous.unwrap_or(p)).abs(), self.previous_time),
                Pick::Current => (current, time),
            });
            take(row, pick);
            self.next += 1;
        }
        self.previous = Some(p);
        self.previous_time = time;
    }

    /// The stream ended: rows still open get the last frame (`take(row)`), if there was one.
    pub fn finish(&mut self, mut take: impl FnMut(usize)) {
        let Some(prev) = self.previous else { return };
        while let Some(&(q, row, _)) = self.targets.get(self.next) {
            self.chosen[row] = Some(((q - prev).abs(), self.previous_time));
            take(row);
            self.next += 1;
        }
    }

    /// The first row (in row order) whose frame is `tolerance_s` or more away, or that got no
    /// frame. Call after [`Selector::finish`].
    pub fn first_miss(&self) -> Option<Miss> {
        let tolerance = TOLERANCE_S as f32;
        let target_of = |row: usize| {
            self.targets
                .iter()
                .find(|t| t.1 == row)
                .map(|t| t.2)
                .unwrap_or(f64::NAN)
        };
        self.chosen.iter().enumerate().find_map(|(row, c)| match c {
            Some((d, _)) if *d < tolerance => None,
            Some((d, at)) => Some(Miss {
                row,
                target: target_of(row),
                nearest: Some(*at),
                gap: f64::from(*d),
            }),
            None => Some(Miss {
                row,
                target: target_of(row),
                nearest: None,
                gap: f64::INFINITY,
            }),
        })
    }

    /// The largest distance between a row and its frame, seconds (0 without rows).
    pub fn worst_gap(&self) -> f64 {
        self.chosen
            .iter()
            .map(|c| c.map_or(f64::INFINITY, |(d, _)| f64::from(d)))
            .fold(0.0, f64::max)
    }
}

/// Runs the selection over known frame times (the audit's demuxed packet times, sorted):
/// per row the index of its frame, and the selector (for its misses).
pub fn over_times(times: &[f64], targets: &[f64]) -> (Vec<Option<usize>>, Selector) {
    let mut s = Selector::new(targets);
    let mut out = vec![None; targets.len()];
    for (i, &t) in times.iter().enumerate() {
        if s.done() {
            break;
        }
        s.push(t, |row, pick| {
            out[row] = Some(match pick {
                Pick::Previous => i - 1,
                Pick::Current => i,
            })
        });
    }
    let last = times.len().checked_sub(1);
    s.finish(|row| out[row] = last);
    (out, s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The oracle: LeRobot's rule written plainly (all frames, float32, first minimum).
    fn nearest(times: &[f64], q: f64) -> (usize, f32) {
        let q = q as f32;
        let mut best = (0, f32::INFINITY);
        for (i, &t) in times.iter().enumerate() {
            let d = (q - t as f32).abs();
            if d < best.1 {
                best = (i, d);
            }
        }
        best
    }

    #[test]
    fn matches_the_plain_rule() {
        let times: Vec<f64> = (0..50).map(|k| k as f64 / 30.0).collect();
        let mut targets: Vec<f64> = (0..40).map(|k| 0.2 + k as f64 / 30.0).collect();
        targets.extend([0.0, 10.0, -1.0, 0.5 / 30.0, 1.5 / 30.0]);
        let (got, _) = over_times(&times, &targets);
        for (row, &q) in targets.iter().enumerate() {
            assert_eq!(got[row], Some(nearest(&times, q).0), "row {row} at {q}");
        }
    }

    #[test]
    fn a_frame_short_misses_the_last_row() {
        let times: Vec<f64> = (0..9).map(|k| k as f64 * 0.1).collect();
        let targets: Vec<f64> = (0..10).map(|k| k as f64 * 0.1).collect();
        let (_, s) = over_times(&times, &targets);
        let miss = s.first_miss().expect("row 9 has no frame within tolerance");
        assert_eq!(miss.row, 9);
        assert!((miss.gap - 0.1).abs() < 1e-6, "{miss:?}");
        assert!((miss.nearest.unwrap() - 0.8).abs() < 1e-12);
    }

    #[test]
    fn within_tolerance_passes() {
        let times: Vec<f64> = (0..10).map(|k| k as f64 * 0.1 + 5e-5).collect();
        let targets: Vec<f64> = (0..10).map(|k| k as f64 * 0.1).collect();
        let (got, s) = over_times(&times, &targets);
        assert_eq!(s.first_miss(), None);
        assert_eq!(got, (0..10).map(Some).collect::<Vec<_>>());
        assert!(s.worst_gap() < 1e-4);
    }

    #[test]
    fn no_frames_misses_row_zero() {
        let (got, s) = over_times(&[], &[0.0, 0.1]);
        assert_eq!(got, vec![None, None]);
        assert_eq!(s.first_miss().unwrap().row, 0);
    }
}
