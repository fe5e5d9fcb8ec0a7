// Long file: the audit's driver (timing, video, doctor) and its summary text share the report.
//! Stage 3, audit: inter-frame intervals per episode → a verdict (ok, interpolate dropped frames,
//! resample, exclude) under the thresholds in `[audit]`, and the repairs `build` applies.
//!
//! - `report`: the result as data ([`AuditReport`]), written as `audit/audit.json`.
//! - `timing`: interval statistics, flags and the verdict rules, per episode.
//! - `histogram`: every episode's intervals together: the histogram and its modes.
//! - `spline`: the not-a-knot cubic spline (as `scipy.interpolate.CubicSpline`).
//! - `resample`: Fourier (as `scipy.signal.resample`) and linear resampling along time.
//! - `repair`: a verdict applied to an [`Episode`](crate::source::Episode).
//! - `doctor`: the dataset doctor, checks of the action and state values (frozen, clipped,
//!   jumps, duplicates, misalignment, mixed conventions, units, shift, short episodes).
//! - `audited`: the source as the audit leaves it ([`Audited`]): exclusions gone, repaired
//!   lengths, repairs applied as episodes are read.
//! - `conversion`: from one rate to another (decimation or resampling), for a profile or a
//!   mixture.
//! - `mixture`: the audited sources of a training mixture joined into one ([`Mixture`]): ids
//!   made unique, every source at the mixture's rate, padded channels zero-filled;
//!   `channel_union` decides its channels and widths; `sources_doctor` runs each source's
//!   dataset doctor on the build's read of it.

mod audited;
mod channel_union;
pub mod conversion;
pub mod doctor;
pub mod histogram;
pub mod joined_report;
pub mod mixture;
pub mod repair;
pub mod report;
pub mod resample;
pub mod sources_doctor;
pub mod spline;
pub mod timing;

pub use audited::Audited;
pub use mixture::Mixture;
pub use report::{
    AuditReport, EpisodeAudit, Flag, Histogram, RepairExample, Thresholds, Verdict, VideoAudit,
};
pub use timing::Repair;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::source::{ChannelKind, Source};
use crate::spec::{BadVideo, LoadedSpec};

/// Above this share of repaired episodes the audit warns.
pub const REPAIR_WARNING: f64 = 0.1;

/// Audits every episode of `source` from its timestamps (no other data is read), then, when
/// `doctor` is set, runs the dataset doctor over the action and state values in a pass of its
/// own (`build` passes false and folds the doctor into its read instead). Sources without
/// timestamps are judged at their declared rate: every episode `ok`.
// Long function: the per-episode loop and the dataset summary share the running totals.
pub fn run(
    spec: &LoadedSpec,
    source: &dyn Source,
    doctor: bool,
) -> Result<(AuditReport, Vec<Repair>)> {
    let cfg = &spec.spec.audit;
    let manifest = source.manifest();
    let fps = manifest.fps;
    let expected = 1.0 / fps;
    let shown = &spec.source().path;
    let mut episodes = Vec::with_capacity(manifest.episodes.len());
    let mut repairs = Vec::with_capacity(manifest.episodes.len());
    let mut intervals = histogram::Intervals::default();
    // Without timestamps every episode of a length is judged alike: judged once per length.
    let mut by_length: std::collections::HashMap<usize, (EpisodeAudit, Repair)> =
        Default::default();
    let mut lengths: std::collections::BTreeMap<usize, u64> = Default::default();
    for (i, info) in manifest.episodes.iter().enumerate() {
        let stamps = if manifest.timestamps {
            source.read_timestamps(i)?
        } else {
            None
        };
        if stamps.is_none() {
            if let Some((audit, repair)) = by_length.get(&info.len) {
                episodes.push(EpisodeAudit {
                    id: info.id,
                    ..audit.clone()
                });
                repairs.push(repair.clone());
                *lengths.entry(info.len).or_insert(0) += 1;
                continue;
            }
        }
        let place = format!("{shown}: episode {}", info.id);
        let t = match stamps {
            Some(t) => {
                if t.len() != info.len {
                    return Err(Error::source(format!(
                        "{place}: {} timestamps for {} steps",
                        t.len(),
                        info.len
                    )));
                }
                if let Some(k) = t.iter().position(|x| !x.is_finite()) {
                    return Err(Error::source(format!(
                        "{place}: timestamp at step {k} is {}",
                        t[k]
                    )));
                }
                t
            }
            // The declared rate: a regular grid.
            None => (0..info.len).map(|k| k as f64 * expected).collect(),
        };
        let (audit, repair) = timing::judge(info.id, &t, fps, cfg)
            .map_err(|msg| Error::source(format!("{place}: {msg}")))?;
        if manifest.timestamps {
            intervals.add_steps(&t, 1);
        } else {
            *lengths.entry(info.len).or_insert(0) += 1;
            by_length.insert(info.len, (audit.clone(), repair.clone()));
        }
        episodes.push(audit);
        repairs.push(repair);
    }
    let video = video_checks(spec, source, &mut episodes, &mut repairs)?;
    for (&len, &count) in &lengths {
        let grid: Vec<f64> = (0..len).map(|k| k as f64 * expected).collect();
        intervals.add_steps(&grid, count);
    }
    let total = episodes.len().max(1) as f64;
    let count = |v: Verdict| episodes.iter().filter(|e| e.verdict == v).count();
    let repaired = count(Verdict::Interpolate) + count(Verdict::Resample);
    let repaired_fraction = repaired as f64 / total;
    let excluded_fraction = count(Verdict::Exclude) as f64 / total;
    let mut warnings = Vec::new();
    let intervals = intervals.runs();
    let modes = histogram::modes_of(&intervals, expected, cfg.jitter_threshold);
    if modes.len() >= 2 {
        let shown: Vec<String> = modes
            .iter()
            .map(|(c, share)| format!("{c:.6} s ({:.0}%)", 100.0 * share))
            .collect();
        warnings.push(format!(
            "the interval histogram is bimodal: {}; the recording alternates between rates",
            shown.join(", ")
        ));
    }
    if repaired_fraction > REPAIR_WARNING {
        warnings.push(format!(
            "{repaired} of {} episodes ({:.0}%) need repair: fix the recording setup",
            episodes.len(),
            100.0 * repaired_fraction
        ));
    }
    // RLDS's step markers (`is_first`/`is_last`/`is_terminal`) checked while the source was
    // opened: reported here with the timing, never acted on.
    if manifest.format == crate::spec::SourceFormat::Rlds {
        warnings.extend(manifest.warnings.iter().cloned());
    }
    if !cfg.repair && episodes.iter().any(|e| e.verdict != Verdict::Ok) {
        warnings.push(
            "`[audit] repair = false`: the verdicts are reported, and `build` uses every episode as recorded".into(),
        );
    }
    let mut report = AuditReport {
        expected_interval: expected,
        source_fps: fps,
        timestamps: manifest.timestamps,
        thresholds: Thresholds {
            jitter: cfg.jitter_threshold,
            gap: cfg.gap_threshold,
            count: cfg.count_threshold,
        },
        episodes,
        repaired_fraction,
        excluded_fraction,
        histogram: histogram::histogram_of(&intervals, expected),
        warnings,
        examples: Vec::new(),
        video,
        doctor: None,
        doctor_seconds: None,
    };
    if !doctor {
        return Ok((report, repairs));
    }
    let started = std::time::Instant::now();
    doctor::run(spec, source, &mut report, &mut repairs)?;
    if report.doctor.is_some() {
        report.doctor_seconds = Some(started.elapsed().as_secs_f64());
    }
    Ok((report, repairs))
}

/// The camera videos of every episode against its rows (demuxed, not decoded; episodes side by
/// side). An episode with a bad video fails the audit, or under `[audit] video =
/// "exclude_episode"` is excluded (flag `video`). The first bad one in episode order is the
/// error, whatever the thread count.
fn video_checks(
    spec: &LoadedSpec,
    source: &dyn Source,
    episodes: &mut [EpisodeAudit],
    repairs: &mut [Repair],
) -> Result<Vec<VideoAudit>> {
    let checks: Vec<Result<Vec<crate::source::VideoCheck>>> = (0..episodes.len())
        .into_par_iter()
        .map(|i| source.video_checks(i))
        .collect();
    let shown = &spec.source().path;
    let mut out = Vec::new();
    for ((e, repair), checks) in episodes.iter_mut().zip(repairs.iter_mut()).zip(checks) {
        for check in checks? {
            if let Some(problem) = &check.problem {
                let place = format!(
                    "{shown}: episode {}, camera `{}` (channel `{}`), file {}",
                    e.id, check.camera, check.channel, check.file
                );
                match spec.spec.audit.video {
                    BadVideo::Error => {
                        return Err(Error::source(format!(
                            "{place}: {problem}; set `[audit] video = \"exclude_episode\"` to leave such episodes out"
                        )))
                    }
                    BadVideo::ExcludeEpisode => {
                        if !e.flags.contains(&Flag::Video) {
                            e.flags.push(Flag::Video);
                            e.detail = format!(
                                "video `{}` ({}): {problem}",
                                check.camera, check.file
                            );
                        }
                        e.verdict = Verdict::Exclude;
                        e.repaired_frames = 0;
                        *repair = Repair::Exclude;
                    }
                }
            }
            out.push(VideoAudit {
                episode: e.id,
                check,
            });
        }
    }
    Ok(out)
}

/// Up to three repaired episodes, one dimension of one channel before and after repair
/// (`observation.state` if there is one, else the first low-dimensional channel; dimension 0).
/// Reads those episodes in full.
pub fn examples(
    source: &dyn Source,
    report: &AuditReport,
    repairs: &[Repair],
) -> Result<Vec<RepairExample>> {
    let manifest = source.manifest();
    let Some(c) = manifest
        .channels
        .iter()
        .position(|c| c.name == "observation.state" && c.kind == ChannelKind::Lowdim)
        .or_else(|| {
            manifest
                .channels
                .iter()
                .position(|c| c.kind == ChannelKind::Lowdim)
        })
    else {
        return Ok(Vec::new());
    };
    let ch = &manifest.channels[c];
    let width = ch.width();
    if width == 0 {
        return Ok(Vec::new());
    }
    let column = |data: &crate::source::ChannelData| -> Vec<f64> {
        match data {
            crate::source::ChannelData::Lowdim(v) => {
                v.iter().step_by(width).map(|&x| f64::from(x)).collect()
            }
            crate::source::ChannelData::Image(_) => Vec::new(),
        }
    };
    let mut out = Vec::new();
    for (i, (audit, repair)) in report.episodes.iter().zip(repairs).enumerate() {
        if out.len() == 3 {
            break;
        }
        if !matches!(audit.verdict, Verdict::Interpolate | Verdict::Resample) {
            continue;
        }
        let episode = source.read_episode(i)?;
        let Some(before_t) = episode.timestamps.clone() else {
            continue;
        };
        let before = column(&episode.channels[c]);
        let after_ep = repair::apply(
            episode,
            repair,
            &manifest.channels,
            report.expected_interval,
        );
        out.push(RepairExample {
            episode: audit.id,
            verdict: audit.verdict,
            channel: ch.name.clone(),
            dim: 0,
            before_t,
            before,
            after_t: after_ep.timestamps.clone().unwrap_or_default(),
            after: column(&after_ep.channels[c]),
        });
    }
    Ok(out)
}

impl AuditReport {
    /// Pretty, deterministic JSON (`audit/audit.json`).
    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("the audit serializes");
        s.push('\n');
        s
    }

    /// Episodes per verdict, in verdict order.
    pub fn verdict_counts(&self) -> Vec<(Verdict, usize)> {
        [
            Verdict::Ok,
            Verdict::Interpolate,
            Verdict::Resample,
            Verdict::Exclude,
        ]
        .into_iter()
        .map(|v| (v, self.episodes.iter().filter(|e| e.verdict == v).count()))
        .collect()
    }

    /// The short text summary `chunkc audit` prints.
    // Long function: one line per part of the audit (timing, video, doctor), printed in order.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "expected interval {} s ({} Hz){}\n",
            self.expected_interval,
            self.source_fps,
            if self.timestamps {
                ""
            } else {
                "; the source stores no timestamps: every episode is judged at the declared rate"
            }
        );
        let counts: Vec<String> = self
            .verdict_counts()
            .into_iter()
            .map(|(v, k)| format!("{} {k}", v.name()))
            .collect();
        s.push_str(&format!(
            "episodes: {} ({})\n",
            self.episodes.len(),
            counts.join(", ")
        ));
        let flagged: Vec<&EpisodeAudit> = self
            .episodes
            .iter()
            .filter(|e| !e.flags.is_empty() || e.verdict != Verdict::Ok)
            .collect();
        if !flagged.is_empty() {
            s.push_str(&format!(
                "\n  {:>8}  {:>7}  {:>10}  {:>10}  {:>10}  {:>10}  {:<28}  {:<11}  detail\n",
                "episode",
                "frames",
                "mean (s)",
                "std (s)",
                "min (s)",
                "max (s)",
                "flags",
                "verdict"
            ));
            for e in flagged {
                let flags: Vec<&str> = e.flags.iter().map(|f| f.name()).collect();
                s.push_str(&format!(
                    "  {:>8}  {:>7}  {:>10.6}  {:>10.6}  {:>10.6}  {:>10.6}  {:<28}  {:<11}  {}\n",
                    e.id,
                    e.n_frames,
                    e.interval_mean,
                    e.interval_std,
                    e.interval_min,
                    e.interval_max,
                    flags.join(","),
                    e.verdict.name(),
                    e.detail
                ));
            }
        }
        if !self.video.is_empty() {
            let bad = self
                .video
                .iter()
                .filter(|v| v.check.problem.is_some())
                .count();
            let worst = self
                .video
                .iter()
                .map(|v| v.check.worst_gap)
                .fold(0.0, f64::max);
            s.push_str(&format!(
                "camera videos: {} checked (episode x camera), {bad} bad; farthest row from its frame {:.6} s (tolerance {} s)\n",
                self.video.len(),
                worst,
                crate::source::video::TOLERANCE_S
            ));
            for v in self.video.iter().filter(|v| v.check.problem.is_some()) {
                s.push_str(&format!(
                    "  episode {}, camera `{}`, file {}: {}\n",
                    v.episode,
                    v.check.camera,
                    v.check.file,
                    v.check.problem.as_deref().unwrap_or("")
                ));
            }
        }
        for w in &self.warnings {
            s.push_str(&format!("warning: {w}\n"));
        }
        s
    }
}

impl Verdict {
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Ok => "ok",
            Verdict::Interpolate => "interpolate",
            Verdict::Resample => "resample",
            Verdict::Exclude => "exclude",
        }
    }
}

impl Flag {
    pub fn name(self) -> &'static str {
        match self {
            Flag::Jitter => "jitter",
            Flag::Gap => "gap",
            Flag::Count => "count",
            Flag::NonMonotonic => "non_monotonic",
            Flag::Video => "video",
            Flag::Frozen => "frozen",
            Flag::Clipped => "clipped",
            Flag::Jump => "jump",
            Flag::Duplicate => "duplicate",
            Flag::Misaligned => "misaligned",
            Flag::MixedConvention => "mixed_convention",
            Flag::Units => "units",
            Flag::Short => "short",
        }
    }
}
