//! Per-episode interval statistics, flags and verdicts, and the dataset-wide histogram.
//!
//! Statistics and flags are computed on the intervals as recorded (`diff(timestamps)`, the
//! population standard deviation), with `T = 1 / source.fps` the expected interval:
//! - `jitter`: std > `jitter_threshold` × mean;
//! - `gap`: some interval > `gap_threshold` × T;
//! - `count`: |n − (duration × fps + 1)| > `count_threshold` × (duration × fps + 1), with
//!   duration = last − first timestamp (a regular recording of n frames spans n − 1 intervals);
//! - `non_monotonic`: some interval ≤ 0.
//!
//! The verdict is decided on the intervals left once repeated timestamps are dropped. Timing is
//! *regular* when at least 90% of them lie within `jitter_threshold` × median of the median
//! (dropped frames leave a recording regular; alternating rates and jitter do not).
//! 1. repeated or decreasing timestamps: `[audit] non_monotonic` (drop the repeats, keeping the
//!    first frame of each run, and go on; decreasing timestamps or fewer than two distinct ones
//!    exclude the episode);
//! 2. nothing flagged: `ok` (`interpolate` when repeats were dropped);
//! 3. regular, with the median off T by more than `count_threshold` (recorded at the wrong
//!    rate): `[audit] rate_error`, by default `resample` to round(n × mean interval / T) steps
//!    (excluded when it also has gaps);
//! 4. regular otherwise (dropped frames): `interpolate` when the frames missing,
//!    Σ max(0, round(interval / T) − 1), are at most `max_dropped`; else exclude;
//! 5. irregular: exclude when one interval exceeds (`max_dropped` + 1) × T (a hole); else
//!    `[audit] irregular`, by default `interpolate`.
//!
//! `interpolate` re-grids onto `first + k T`, k = 0 … floor((last − first) / T), so no step is
//! extrapolated.
//!
//! Bimodality: the sorted intervals are split into groups wherever two neighbours differ by more
//! than `jitter_threshold` × T; the histogram is bimodal when two or more groups each hold at
//! least 5% of all intervals.

use super::report::{EpisodeAudit, Flag, Histogram, Verdict};
use crate::spec::{AuditSpec, Irregular, NonMonotonic, RateError, ResampleMethod};

/// What `build` does to an episode before anything else.
#[derive(Debug, Clone, PartialEq)]
pub enum Repair {
    /// Used as read.
    None,
    /// Repeats dropped, then every channel evaluated at `first + k T`, k < `steps`.
    Regrid {
        steps: usize,
    },
    /// The whole episode resampled to `steps` steps.
    Resample {
        steps: usize,
        method: ResampleMethod,
    },
    Exclude,
}

/// Share of intervals within `jitter_threshold` of the median that makes timing regular.
pub const REGULAR_SHARE: f64 = 0.9;
/// Share of all intervals a group needs to count as a mode.
pub const MODE_SHARE: f64 = 0.05;
/// Bins of the dataset-wide histogram.
pub const HISTOGRAM_BINS: usize = 50;

struct Stats {
    mean: f64,
    std: f64,
    min: f64,
    max: f64,
}

fn stats(dt: &[f64]) -> Stats {
    if dt.is_empty() {
        return Stats {
            mean: 0.0,
            std: 0.0,
            min: 0.0,
            max: 0.0,
        };
    }
    let n = dt.len() as f64;
    let mean = dt.iter().sum::<f64>() / n;
    let var = dt.iter().map(|d| (d - mean) * (d - mean)).sum::<f64>() / n;
    Stats {
        mean,
        std: var.sqrt(),
        min: dt.iter().copied().fold(f64::INFINITY, f64::min),
        max: dt.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    }
}

fn flags(t: &[f64], dt: &[f64], fps: f64, cfg: &AuditSpec) -> Vec<Flag> {
    let mut flags = Vec::new();
    if dt.is_empty() {
        return flags;
    }
    let s = stats(dt);
    let expected = 1.0 / fps;
    if s.mean > 0.0 && s.std > cfg.jitter_threshold * s.mean {
        flags.push(Flag::Jitter);
    }
    if s.max > cfg.gap_threshold * expected {
        flags.push(Flag::Gap);
    }
    let frames = (t[t.len() - 1] - t[0]) * fps + 1.0;
    if (t.len() as f64 - frames).abs() > cfg.count_threshold * frames {
        flags.push(Flag::Count);
    }
    if dt.iter().any(|&d| d <= 0.0) {
        flags.push(Flag::NonMonotonic);
    }
    flags
}

/// Steps of the regular grid from the first to the last timestamp.
pub fn grid_steps(first: f64, last: f64, expected: f64) -> usize {
    ((last - first) / expected + 1e-6).floor() as usize + 1
}

/// The timestamps with repeats dropped (the first frame of each run of equal ones kept), and the
/// positions kept.
pub fn drop_repeats(t: &[f64]) -> (Vec<f64>, Vec<usize>) {
    let mut kept = Vec::with_capacity(t.len());
    let mut times = Vec::with_capacity(t.len());
    for (i, &v) in t.iter().enumerate() {
        if times.last() != Some(&v) {
            times.push(v);
            kept.push(i);
        }
    }
    (times, kept)
}

fn steps_list(steps: &[usize]) -> String {
    let shown: Vec<String> = steps.iter().take(5).map(|s| s.to_string()).collect();
    let more = if steps.len() > 5 { ", …" } else { "" };
    format!("{}{more}", shown.join(", "))
}

/// Judges one episode. `Err` carries the message of `non_monotonic = "error"`.
pub fn judge(
    id: u64,
    timestamps: &[f64],
    fps: f64,
    cfg: &AuditSpec,
) -> std::result::Result<(EpisodeAudit, Repair), String> {
    let expected = 1.0 / fps;
    let n = timestamps.len();
    let dt: Vec<f64> = timestamps.windows(2).map(|w| w[1] - w[0]).collect();
    let s = stats(&dt);
    let raw_flags = flags(timestamps, &dt, fps, cfg);
    let mut audit = EpisodeAudit {
        id,
        n_frames: n,
        interval_mean: s.mean,
        interval_std: s.std,
        interval_min: s.min,
        interval_max: s.max,
        flags: raw_flags.clone(),
        verdict: Verdict::Ok,
        detail: String::new(),
        repaired_frames: n,
    };
    let exclude = |mut audit: EpisodeAudit, why: String| {
        audit.verdict = Verdict::Exclude;
        audit.detail = why;
        audit.repaired_frames = 0;
        Ok((audit, Repair::Exclude))
    };

    let mut prefix = String::new();
    let (t, repeats) = if raw_flags.contains(&Flag::NonMonotonic) {
        let back = dt.iter().position(|&d| d < 0.0);
        let first_repeat = dt.iter().position(|&d| d == 0.0);
        let how = match (back, first_repeat) {
            (Some(i), _) => format!(
                "step {} ({} s) goes back from step {i} ({} s)",
                i + 1,
                timestamps[i + 1],
                timestamps[i]
            ),
            (None, Some(i)) => format!(
                "step {} repeats the timestamp of step {i} ({} s)",
                i + 1,
                timestamps[i]
            ),
            (None, None) => unreachable!("non_monotonic means some interval <= 0"),
        };
        match cfg.non_monotonic {
            NonMonotonic::Error => {
                return Err(format!(
                    "timestamps must increase, but {how}; set `[audit] non_monotonic = \"drop_duplicates\"` or `\"exclude\"` to go on"
                ))
            }
            NonMonotonic::Exclude => return exclude(audit, format!("timestamps: {how}")),
            NonMonotonic::DropDuplicates if back.is_some() => {
                return exclude(
                    audit,
                    format!("timestamps go back ({how}); only repeats can be dropped"),
                )
            }
            NonMonotonic::DropDuplicates => {
                let (t, _) = drop_repeats(timestamps);
                let dropped = n - t.len();
                if t.len() < 2 {
                    return exclude(audit, format!("all {n} timestamps are equal"));
                }
                prefix = format!("dropped {dropped} repeated timestamps; ");
                (t, dropped)
            }
        }
    } else {
        (timestamps.to_vec(), 0)
    };

    let dt: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let s = stats(&dt);
    let fl = flags(&t, &dt, fps, cfg);
    let regrid = |mut audit: EpisodeAudit, why: String| {
        let steps = grid_steps(t[0], t[t.len() - 1], expected);
        audit.verdict = Verdict::Interpolate;
        audit.detail = format!(
            "{prefix}{why}; re-gridded by cubic spline onto {expected} s steps: {n} -> {steps} steps"
        );
        audit.repaired_frames = steps;
        Ok((audit, Repair::Regrid { steps }))
    };
    if fl.is_empty() || t.len() < 2 {
        if repeats > 0 {
            return regrid(audit, "the rest is regular".into());
        }
        audit.detail = "regular".into();
        return Ok((audit, Repair::None));
    }
    // Regular timing: nearly all intervals close to their median.
    let mut sorted = dt.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let close = dt
        .iter()
        .filter(|&&d| (d - median).abs() <= cfg.jitter_threshold * median)
        .count();
    let regular = close as f64 >= REGULAR_SHARE * dt.len() as f64;
    let gaps: Vec<usize> = (0..dt.len())
        .filter(|&i| dt[i] > cfg.gap_threshold * expected)
        .collect();
    if regular && (median / expected - 1.0).abs() > cfg.count_threshold {
        let why = format!(
            "regular intervals of {median:.6} s instead of {expected} s ({:.3} Hz instead of {fps} Hz)",
            1.0 / median
        );
        if !gaps.is_empty() {
            return exclude(
                audit,
                format!(
                    "{prefix}{why} and gaps before step(s) {}",
                    steps_list(&gaps.iter().map(|g| g + 1).collect::<Vec<_>>())
                ),
            );
        }
        return match cfg.rate_error {
            RateError::Exclude => exclude(audit, format!("{prefix}{why}")),
            RateError::Resample if repeats > 0 => {
                // Resampling assumes evenly spaced steps: re-grid the repeats away instead.
                regrid(audit, why)
            }
            RateError::Resample => {
                let steps = ((t.len() as f64) * s.mean / expected).round() as usize;
                let method = cfg.resample;
                let name = match method {
                    ResampleMethod::Fourier => "fourier",
                    ResampleMethod::Linear => "linear",
                };
                audit.verdict = Verdict::Resample;
                audit.detail = format!("{why}; resampled ({name}): {} -> {steps} steps", t.len());
                audit.repaired_frames = steps;
                Ok((audit, Repair::Resample { steps, method }))
            }
        };
    }
    if regular {
        let mut missing = 0usize;
        let mut at = Vec::new();
        for (i, &d) in dt.iter().enumerate() {
            let m = ((d / expected).round() as usize).saturating_sub(1);
            if m > 0 {
                missing += m;
                at.push(i + 1);
            }
        }
        if missing == 0 {
            return regrid(
                audit,
                format!(
                    "{} of {} intervals off the median {median:.6} s",
                    dt.len() - close,
                    dt.len()
                ),
            );
        }
        let why = format!(
            "{missing} dropped frame(s) (before step(s) {})",
            steps_list(&at)
        );
        if missing as u64 <= u64::from(cfg.max_dropped) {
            return regrid(audit, why);
        }
        return exclude(
            audit,
            format!(
                "{prefix}{why}, more than `[audit] max_dropped = {}`",
                cfg.max_dropped
            ),
        );
    }
    let hole = (cfg.max_dropped as f64 + 1.0) * expected;
    if s.max > hole * (1.0 + 1e-9) {
        let i = dt.iter().position(|&d| d == s.max).unwrap_or(0);
        return exclude(
            audit,
            format!(
                "{prefix}irregular intervals with a hole of {} s before step {} (more than {} missing frames)",
                s.max,
                i + 1,
                cfg.max_dropped
            ),
        );
    }
    let why = format!(
        "irregular intervals (std {:.1}% of the mean {:.6} s, {:.0}% within {:.0}% of the median {median:.6} s)",
        100.0 * s.std / s.mean,
        s.mean,
        100.0 * close as f64 / dt.len() as f64,
        100.0 * cfg.jitter_threshold
    );
    match cfg.irregular {
        Irregular::Exclude => exclude(audit, format!("{prefix}{why}")),
        Irregular::Interpolate => regrid(audit, why),
    }
}

/// The step intervals of every episode, as a multiset. Counted per distinct value while there are
/// few (regular recordings, and sources without timestamps, whose nominal grid repeats a handful
/// of values: memory then does not grow with the number of episodes); kept one by one beyond
/// [`Intervals::MAX_DISTINCT`] distinct values.
#[derive(Debug, Default)]
pub struct Intervals {
    counted: std::collections::HashMap<u64, u64>,
    /// Every interval, once there were too many distinct values to count.
    all: Option<Vec<f64>>,
}

impl Intervals {
    pub const MAX_DISTINCT: usize = 1 << 16;

    /// Adds the intervals between consecutive timestamps, `times` times over.
    pub fn add_steps(&mut self, t: &[f64], times: u64) {
        self.add(t.windows(2).map(|w| w[1] - w[0]), times);
    }

    fn add(&mut self, intervals: impl Iterator<Item = f64>, times: u64) {
        for v in intervals {
            if let Some(all) = &mut self.all {
                all.extend(std::iter::repeat_n(v, times as usize));
                continue;
            }
            *self.counted.entry(v.to_bits()).or_insert(0) += times;
            if self.counted.len() > Self::MAX_DISTINCT {
                let mut all = Vec::new();
                for (&bits, &n) in &self.counted {
                    all.extend(std::iter::repeat_n(f64::from_bits(bits), n as usize));
                }
                self.counted = Default::default();
                self.all = Some(all);
            }
        }
    }

    /// The distinct values in increasing order, each with its count.
    pub fn runs(mut self) -> Runs {
        match self.all.take() {
            Some(mut all) => {
                all.sort_by(f64::total_cmp);
                Runs::Sorted(all)
            }
            None => {
                let mut counted: Vec<(f64, u64)> = self
                    .counted
                    .into_iter()
                    .map(|(bits, n)| (f64::from_bits(bits), n))
                    .collect();
                counted.sort_by(|a, b| a.0.total_cmp(&b.0));
                Runs::Counted(counted)
            }
        }
    }
}

/// Sorted intervals, read as (value, count) runs.
pub enum Runs {
    Counted(Vec<(f64, u64)>),
    Sorted(Vec<f64>),
}

impl Runs {
    fn iter(&self) -> Box<dyn Iterator<Item = (f64, u64)> + '_> {
        match self {
            Runs::Counted(v) => Box::new(v.iter().copied()),
            Runs::Sorted(v) => Box::new(v.chunk_by(|a, b| a == b).map(|g| (g[0], g.len() as u64))),
        }
    }

    fn total(&self) -> u64 {
        self.iter().map(|(_, n)| n).sum()
    }
}

/// Equal-width bins from the smallest to the largest interval (given as runs).
pub fn histogram_of(runs: &Runs, expected: f64) -> Histogram {
    let total = runs.total();
    if total == 0 {
        return Histogram {
            edges: vec![expected * 0.99, expected * 1.01],
            counts: vec![0],
        };
    }
    let lo = runs.iter().next().map_or(0.0, |(v, _)| v);
    let hi = runs.iter().last().map_or(0.0, |(v, _)| v);
    if hi - lo <= expected * 1e-9 {
        return Histogram {
            edges: vec![lo - expected * 0.01, lo + expected * 0.01],
            counts: vec![total],
        };
    }
    let width = (hi - lo) / HISTOGRAM_BINS as f64;
    let edges: Vec<f64> = (0..=HISTOGRAM_BINS)
        .map(|i| lo + i as f64 * width)
        .collect();
    let mut counts = vec![0u64; HISTOGRAM_BINS];
    for (v, n) in runs.iter() {
        let b = (((v - lo) / width) as usize).min(HISTOGRAM_BINS - 1);
        counts[b] += n;
    }
    Histogram { edges, counts }
}

/// The modes of the intervals (group centres, in seconds, with their share), largest first:
/// groups of sorted values with no gap wider than
/// `separation * expected` between neighbours.
pub fn modes_of(runs: &Runs, expected: f64, separation: f64) -> Vec<(f64, f64)> {
    let total = runs.total() as f64;
    let mut groups: Vec<(f64, u64)> = Vec::new();
    // The open group: sum (of every value in sorted order, as a plain sum would add them),
    // count, and its largest value.
    let mut open: Option<(f64, u64, f64)> = None;
    for (v, n) in runs.iter() {
        if let Some((sum, count, last)) = open {
            if v - last > separation * expected {
                groups.push((sum / count as f64, count));
                open = None;
            }
        }
        let (mut sum, count, _) = open.unwrap_or((0.0, 0, v));
        for _ in 0..n {
            sum += v;
        }
        open = Some((sum, count + n, v));
    }
    if let Some((sum, count, _)) = open {
        groups.push((sum / count as f64, count));
    }
    let mut modes: Vec<(f64, f64)> = groups
        .into_iter()
        .map(|(c, k)| (c, k as f64 / total))
        .filter(|&(_, share)| share >= MODE_SHARE)
        .collect();
    modes.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.total_cmp(&b.0)));
    modes
}

#[cfg(test)]
mod tests {
    use super::*;

    fn modes(intervals: &[f64], expected: f64, separation: f64) -> Vec<(f64, f64)> {
        let mut set = Intervals::default();
        set.add(intervals.iter().copied(), 1);
        modes_of(&set.runs(), expected, separation)
    }

    fn regular(n: usize, dt: f64) -> Vec<f64> {
        (0..n).map(|i| i as f64 * dt).collect()
    }

    #[test]
    fn verdicts() {
        let cfg = AuditSpec::default();
        let (a, r) = judge(0, &regular(50, 0.1), 10.0, &cfg).unwrap();
        assert_eq!((a.verdict, r), (Verdict::Ok, Repair::None));
        let mut dropped = regular(52, 0.1);
        dropped.remove(30);
        dropped.remove(10);
        let (a, r) = judge(1, &dropped, 10.0, &cfg).unwrap();
        assert_eq!(a.flags, vec![Flag::Jitter, Flag::Gap]);
        assert_eq!(
            (a.verdict, r),
            (Verdict::Interpolate, Repair::Regrid { steps: 52 })
        );
        let (a, r) = judge(2, &regular(40, 0.125), 10.0, &cfg).unwrap();
        assert_eq!(a.flags, vec![Flag::Count]);
        assert_eq!(a.verdict, Verdict::Resample);
        assert_eq!(
            r,
            Repair::Resample {
                steps: 50,
                method: ResampleMethod::Fourier
            }
        );
        let mut rep = regular(20, 0.1);
        rep.insert(5, rep[5]);
        let (a, r) = judge(3, &rep, 10.0, &cfg).unwrap();
        assert!(a.flags.contains(&Flag::NonMonotonic));
        assert_eq!(
            (a.verdict, r),
            (Verdict::Interpolate, Repair::Regrid { steps: 20 })
        );
        let strict = AuditSpec {
            non_monotonic: NonMonotonic::Error,
            ..AuditSpec::default()
        };
        assert!(judge(3, &rep, 10.0, &strict).is_err());
        let (a, _) = judge(4, &[1.0, 1.0, 1.0], 10.0, &cfg).unwrap();
        assert_eq!(a.verdict, Verdict::Exclude);
    }

    #[test]
    fn bimodal_groups() {
        let mut dt = vec![0.010; 60];
        dt.extend(vec![0.012; 40]);
        dt.push(0.03);
        let m = modes(&dt, 0.01, 0.1);
        assert_eq!(m.len(), 2);
        assert!((m[0].0 - 0.010).abs() < 1e-12 && (m[1].0 - 0.012).abs() < 1e-12);
    }
}
