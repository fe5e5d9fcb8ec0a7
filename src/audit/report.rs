//! The audit's result as data: what `chunkc audit` writes to `audit/audit.json`, what the plan
//! applies, and what the HTML report draws. The JSON field names are part of the interface
//! contract (DESIGN.md): `expected_interval`, `episodes[].{id, n_frames, interval_mean,
//! interval_std, interval_min, interval_max, flags, verdict}`, `repaired_fraction`; `video`
//! (one entry per episode and camera) appears only for sources with video.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::spec::DoctorAction;

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
    pub doctor: Option<DoctorSummary>,
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
    pub findings: Vec<Finding>,
}

impl EpisodeAudit {
    /// Why an excluded episode is left out: the timing or video audit's sentence, and the
    /// doctor's findings set to `"exclude"`, never the findings that only warn (they would read
    /// as causes).
    pub fn exclusion_reason(&self) -> String {
        let mut timing = self.detail.clone();
        for f in &self.findings {
            let sentence = format!("{}: {}", f.flag.name(), f.detail);
            for form in [format!("; {sentence}"), format!("{sentence}; "), sentence] {
                if let Some(at) = timing.find(&form) {
                    timing.replace_range(at..at + form.len(), "");
                    break;
                }
            }
        }
        let doctor: Vec<String> = self
            .findings
            .iter()
            .filter(|f| f.action == DoctorAction::Exclude)
            .map(|f| format!("{}: {}", f.flag.name(), f.detail))
            .collect();
        let mut parts = Vec::new();
        if !timing.is_empty() {
            parts.push(format!("audit: {timing}"));
        }
        if !doctor.is_empty() {
            parts.push(format!("dataset doctor: {}", doctor.join("; ")));
        }
        parts.join("; ")
    }
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

/// One doctor flag on one episode, with why and its evidence numbers.
#[derive(Debug, Clone, Serialize)]
pub struct Finding {
    pub flag: Flag,
    pub action: DoctorAction,
    pub detail: String,
    pub evidence: BTreeMap<String, f64>,
}

/// The doctor's dataset-wide results, in `audit.json` under `doctor`.
#[derive(Debug, Clone, Serialize)]
pub struct DoctorSummary {
    pub action_channel: String,
    pub state_channel: Option<String>,
    /// Episodes flagged per flag name.
    pub flagged: BTreeMap<String, u64>,
    /// Action dimensions (shared with the state) the alignment checks used.
    pub tracked_dims: Vec<usize>,
    /// Episodes per lag (steps from an action to the state that first shows it).
    pub lag_histogram: BTreeMap<i32, u64>,
    pub lag_mode: Option<i32>,
    /// (lag, mean R² of the state change over the fitted episodes).
    pub lag_curve: Vec<(i32, f64)>,
    /// The majority convention, `absolute` or `delta`.
    pub convention: Option<String>,
    /// Episodes per convention (`absolute`, `delta`, `unclear`).
    pub conventions: BTreeMap<String, u64>,
    /// Per episode in source order: (id, the action's units factor against the dataset).
    pub units: Vec<(u64, f64)>,
    /// Per action dimension, the reference of the jump check: its motion scale (the median
    /// episode's 90th percentile of a moving step's distance from the line through its
    /// neighbours).
    pub motion_scale: Vec<f64>,
    /// `channel[dim]` constant over the whole dataset, with the value.
    pub constant: Vec<(String, usize, f64)>,
    /// `channel[dim]` holding still in most episodes, with the share of episodes.
    pub stuck: Vec<(String, usize, f64)>,
    /// Every dimension's quarters (in recording order) as robust deviations.
    pub shift: Vec<ShiftDim>,
    /// (earlier id, later id, RMS difference in spreads).
    pub duplicates: Vec<(u64, u64, f64)>,
    /// The thresholds the charts draw (`[audit.doctor]`).
    pub units_ratio: f64,
    pub shift_threshold: f64,
}

/// One channel dimension's quarters, as deviations from the dataset in robust standard
/// deviations.
#[derive(Debug, Clone, Serialize)]
pub struct ShiftDim {
    pub channel: String,
    pub dim: usize,
    pub deviations: Vec<f64>,
}
