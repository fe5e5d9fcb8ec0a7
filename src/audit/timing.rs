// Long file: the per-episode judgement: interval statistics, flags and verdicts with their thresholds.
//! Per-episode interval statistics, flags and verdicts (the dataset-wide histogram is in
//! `histogram`).
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

use super::report::{EpisodeAudit, Flag, Verdict};
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
    let n = timestamps.len();
    let dt = intervals(timestamps);
    let s = stats(&dt);
    let raw_flags = flags(timestamps, &dt, fps, cfg);
    let audit = EpisodeAudit {
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
        findings: Vec::new(),
    };
    let (t, repeats) = if raw_flags.contains(&Flag::NonMonotonic) {
        match without_repeats(timestamps, &dt, cfg)? {
            Ok(kept) => kept,
            Err(why) => return Ok(settle(audit, Decision::Exclude(why), "", &[], fps)),
        }
    } else {
        (timestamps.to_vec(), 0)
    };
    let prefix = if repeats > 0 {
        format!("dropped {repeats} repeated timestamps; ")
    } else {
        String::new()
    };
    let decision = decide(&t, repeats, fps, cfg);
    Ok(settle(audit, decision, &prefix, &t, fps))
}

fn intervals(t: &[f64]) -> Vec<f64> {
    t.windows(2).map(|w| w[1] - w[0]).collect()
}

/// What the rules decided for an episode, each with the sentence that says why.
enum Decision {
    /// Regular as recorded.
    Keep,
    Regrid(String),
    Resample {
        steps: usize,
        method: ResampleMethod,
        why: String,
    },
    Exclude(String),
}

/// Rule 1, for timestamps that repeat or go back: `Ok` with the timestamps to judge and how many
/// repeats were dropped, `Err` (inside) when the episode is excluded; the outer `Err` is
/// `non_monotonic = "error"`.
#[allow(clippy::type_complexity)]
fn without_repeats(
    timestamps: &[f64],
    dt: &[f64],
    cfg: &AuditSpec,
) -> std::result::Result<std::result::Result<(Vec<f64>, usize), String>, String> {
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
        NonMonotonic::Error => Err(format!(
            "timestamps must increase, but {how}; set `[audit] non_monotonic = \"drop_duplicates\"` or `\"exclude\"` to go on"
        )),
        NonMonotonic::Exclude => Ok(Err(format!("timestamps: {how}"))),
        NonMonotonic::DropDuplicates if back.is_some() => Ok(Err(format!(
            "timestamps go back ({how}); only repeats can be dropped"
        ))),
        NonMonotonic::DropDuplicates => {
            let (t, _) = drop_repeats(timestamps);
            if t.len() < 2 {
                return Ok(Err(format!("all {} timestamps are equal", timestamps.len())));
            }
            let dropped = timestamps.len() - t.len();
            Ok(Ok((t, dropped)))
        }
    }
}

/// How the intervals of increasing timestamps sit around their median.
struct Regularity {
    median: f64,
    /// Intervals within `jitter_threshold` × median of the median.
    close: usize,
    regular: bool,
}

fn regularity(dt: &[f64], cfg: &AuditSpec) -> Regularity {
    let mut sorted = dt.to_vec();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let close = dt
        .iter()
        .filter(|&&d| (d - median).abs() <= cfg.jitter_threshold * median)
        .count();
    Regularity {
        median,
        close,
        regular: close as f64 >= REGULAR_SHARE * dt.len() as f64,
    }
}

/// Rules 2 to 5 on increasing timestamps `t` (`repeats` of them dropped before).
fn decide(t: &[f64], repeats: usize, fps: f64, cfg: &AuditSpec) -> Decision {
    let expected = 1.0 / fps;
    let dt = intervals(t);
    if flags(t, &dt, fps, cfg).is_empty() || t.len() < 2 {
        return if repeats > 0 {
            Decision::Regrid("the rest is regular".into())
        } else {
            Decision::Keep
        };
    }
    let r = regularity(&dt, cfg);
    if r.regular && (r.median / expected - 1.0).abs() > cfg.count_threshold {
        return wrong_rate(t, &dt, r.median, repeats, fps, cfg);
    }
    if r.regular {
        return dropped_frames(&dt, &r, expected, cfg);
    }
    irregular(&dt, &r, expected, cfg)
}

/// Rule 3: regular intervals at another rate than the dataset claims.
fn wrong_rate(
    t: &[f64],
    dt: &[f64],
    median: f64,
    repeats: usize,
    fps: f64,
    cfg: &AuditSpec,
) -> Decision {
    let expected = 1.0 / fps;
    let why = format!(
        "regular intervals of {median:.6} s instead of {expected} s ({:.3} Hz instead of {fps} Hz)",
        1.0 / median
    );
    let gaps: Vec<usize> = (0..dt.len())
        .filter(|&i| dt[i] > cfg.gap_threshold * expected)
        .map(|i| i + 1)
        .collect();
    if !gaps.is_empty() {
        return Decision::Exclude(format!(
            "{why} and gaps before step(s) {}",
            steps_list(&gaps)
        ));
    }
    match cfg.rate_error {
        RateError::Exclude => Decision::Exclude(why),
        // Resampling assumes evenly spaced steps: re-grid the repeats away instead.
        RateError::Resample if repeats > 0 => Decision::Regrid(why),
        RateError::Resample => Decision::Resample {
            steps: ((t.len() as f64) * stats(dt).mean / expected).round() as usize,
            method: cfg.resample,
            why,
        },
    }
}

/// Rule 4: regular intervals with frames missing between some of them.
fn dropped_frames(dt: &[f64], r: &Regularity, expected: f64, cfg: &AuditSpec) -> Decision {
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
        return Decision::Regrid(format!(
            "{} of {} intervals off the median {:.6} s",
            dt.len() - r.close,
            dt.len(),
            r.median
        ));
    }
    let why = format!(
        "{missing} dropped frame(s) (before step(s) {})",
        steps_list(&at)
    );
    if missing as u64 <= u64::from(cfg.max_dropped) {
        return Decision::Regrid(why);
    }
    Decision::Exclude(format!(
        "{why}, more than `[audit] max_dropped = {}`",
        cfg.max_dropped
    ))
}

/// Rule 5: irregular intervals.
fn irregular(dt: &[f64], r: &Regularity, expected: f64, cfg: &AuditSpec) -> Decision {
    let s = stats(dt);
    let hole = (cfg.max_dropped as f64 + 1.0) * expected;
    if s.max > hole * (1.0 + 1e-9) {
        let i = dt.iter().position(|&d| d == s.max).unwrap_or(0);
        return Decision::Exclude(format!(
            "irregular intervals with a hole of {} s before step {} (more than {} missing frames)",
            s.max,
            i + 1,
            cfg.max_dropped
        ));
    }
    let why = format!(
        "irregular intervals (std {:.1}% of the mean {:.6} s, {:.0}% within {:.0}% of the median {:.6} s)",
        100.0 * s.std / s.mean,
        s.mean,
        100.0 * r.close as f64 / dt.len() as f64,
        100.0 * cfg.jitter_threshold,
        r.median
    );
    match cfg.irregular {
        Irregular::Exclude => Decision::Exclude(why),
        Irregular::Interpolate => Decision::Regrid(why),
    }
}

/// Writes `decision` into the episode's audit; every sentence after rule 1 starts with `prefix`
/// (what rule 1 dropped). `t` are the timestamps the decision was made on.
fn settle(
    mut audit: EpisodeAudit,
    decision: Decision,
    prefix: &str,
    t: &[f64],
    fps: f64,
) -> (EpisodeAudit, Repair) {
    let expected = 1.0 / fps;
    match decision {
        Decision::Keep => {
            audit.detail = "regular".into();
            (audit, Repair::None)
        }
        Decision::Regrid(why) => {
            let steps = grid_steps(t[0], t[t.len() - 1], expected);
            audit.verdict = Verdict::Interpolate;
            audit.detail = format!(
                "{prefix}{why}; re-gridded by cubic spline onto {expected} s steps: {} -> {steps} steps",
                audit.n_frames
            );
            audit.repaired_frames = steps;
            (audit, Repair::Regrid { steps })
        }
        Decision::Resample { steps, method, why } => {
            let name = match method {
                ResampleMethod::Fourier => "fourier",
                ResampleMethod::Linear => "linear",
            };
            audit.verdict = Verdict::Resample;
            audit.detail = format!(
                "{prefix}{why}; resampled ({name}): {} -> {steps} steps",
                t.len()
            );
            audit.repaired_frames = steps;
            (audit, Repair::Resample { steps, method })
        }
        Decision::Exclude(why) => {
            audit.verdict = Verdict::Exclude;
            audit.detail = format!("{prefix}{why}");
            audit.repaired_frames = 0;
            (audit, Repair::Exclude)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
