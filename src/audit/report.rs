//! The audit's result as data: what `chunkc audit` writes to `audit/audit.json`, what the plan
//! applies, and what the HTML report draws. The JSON field names are part of the interface
//! contract (DESIGN.md): `expected_interval`, `episodes[].{id, n_frames, interval_mean,
//! interval_std, interval_min, interval_max, flags, verdict}`, `repaired_fraction`; `video`
//! (one entry per episode and camera) appears only for sources with video.

use serde::Serialize;

/// The whole audit of one source.
#[derive(Debug, Clone, Serialize)]
pub struct AuditReport {
    /// Seconds per step the episodes should have: `1 / source.fps`.
    pub expected_interval: f64,
    /// The rate the audit judged against, in Hz.
    pub source_fps: f64,
    /// Whether the source stores timestamps; without them every interval is the declared one.
    pub timestamps: bool,
    pub thresholds: Thresholds,
    /// In source order.
    pub episodes: Vec<EpisodeAudit>,
    /// Episodes whose verdict is `interpolate` or `resample`, over all episodes.
    pub repaired_fraction: f64,
    /// Episodes whose verdict is `exclude`, over all episodes.
    pub excluded_fraction: f64,
    /// All inter-frame intervals of all episodes, binned.
    pub histogram: Histogram,
    /// Dataset-wide findings (a bimodal interval histogram, too many repairs).
    pub warnings: Vec<String>,
    /// A few repaired episodes, one channel dimension each, before and after repair.
    pub examples: Vec<RepairExample>,
    /// Per episode and camera video: its frames against the rows (sources with video only).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub video: Vec<VideoAudit>,
    /// The dataset doctor's dataset-wide results (`[audit.doctor]`); absent when it did not run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doctor: Option<super::doctor::DoctorSummary>,
    /// Wall seconds the doctor took (`None`: it did not run). Printed by `build` and `audit`,
    /// kept out of `audit.json`, whose bytes depend only on the source and the spec.
    #[serde(skip)]
    pub doctor_seconds: Option<f64>,
}

/// One episode's camera video checked against its rows: the frame count and pts regularity
/// against the rows and `fps`, and the farthest a row is from its frame (LeRobot's
/// `tolerance_s` rule).
#[derive(Debug, Clone, Serialize)]
pub struct VideoAudit {
    pub episode: u64,
    #[serde(flatten)]
    pub check: crate::source::VideoCheck,
}

/// The thresholds the flags were decided with (`[audit]`).
#[derive(Debug, Clone, Serialize)]
pub struct Thresholds {
    /// Flag `jitter` when the interval std exceeds this fraction of the mean interval.
    pub jitter: f64,
    /// Flag `gap` when an interval exceeds this many expected intervals.
    pub gap: f64,
    /// Flag `count` when the frame count deviates from duration × rate by more than this fraction.
    pub count: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct EpisodeAudit {
    pub id: u64,
    pub n_frames: usize,
    pub interval_mean: f64,
    pub interval_std: f64,
    pub interval_min: f64,
    pub interval_max: f64,
    pub flags: Vec<Flag>,
    pub verdict: Verdict,
    /// One sentence saying why (`2 dropped frames at steps 17, 40`).
    pub detail: String,
    /// Steps after repair (equal to `n_frames` when nothing is repaired; 0 when excluded).
    pub repaired_frames: usize,
    /// The dataset doctor's findings, one per flag it added, with their evidence.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub findings: Vec<super::doctor::Finding>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Flag {
    Jitter,
    Gap,
    Count,
    NonMonotonic,
    /// A camera video cannot give every row its frame (`[audit] video`).
    Video,
    /// The dataset doctor's flags (`audit::doctor`).
    Frozen,
    Clipped,
    Jump,
    Duplicate,
    Misaligned,
    MixedConvention,
    Units,
    Short,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    Ok,
    Interpolate,
    Resample,
    Exclude,
}

/// Equal-width bins: `counts[i]` intervals fall in `[edges[i], edges[i + 1])`.
#[derive(Debug, Clone, Serialize)]
pub struct Histogram {
    pub edges: Vec<f64>,
    pub counts: Vec<u64>,
}

/// One channel dimension of a repaired episode, before and after, for the report's plot.
#[derive(Debug, Clone, Serialize)]
pub struct RepairExample {
    pub episode: u64,
    pub verdict: Verdict,
    pub channel: String,
    pub dim: usize,
    pub before_t: Vec<f64>,
    pub before: Vec<f64>,
    pub after_t: Vec<f64>,
    pub after: Vec<f64>,
}
