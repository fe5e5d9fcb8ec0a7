//! The plan's data: what `chunkc plan --format json` prints and `build` executes. Plain,
//! serializable types, sorted wherever they are collections; [`super::resolve`] fills them.

use std::collections::BTreeMap;

use serde::Serialize;

use super::{CameraResize, Conversion, Split, Status};
use crate::audit::Verdict;
use crate::source::{ChannelInfo, ChannelKind, SourcePart};
use crate::spec::{LerobotVersion, MixtureSpec, NormalizeMode, Profile};
use crate::window::{Sampling, Window};

#[derive(Debug, Clone, Serialize)]
pub struct Plan {
    pub version: u32,
    pub tool_version: &'static str,
    pub spec_hash: String,
    pub source: SourcePlan,
    /// A training mixture's `[mixture]` (absent for one source).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mixture: Option<MixtureSpec>,
    pub split: Split,
    /// One job per distinct profile rate: the source is read once and decimated per rate.
    pub rates: Vec<RateJob>,
    /// One job per (rate, channel): statistics over the training split, shared by the profiles
    /// listed.
    pub statistics: Vec<StatsJob>,
    /// The temporal audit, summed up (`chunkc audit` writes the whole of it).
    pub audit: AuditSummary,
    pub profiles: Vec<ProfilePlan>,
    /// The size of each generated script, from its template (the embedded one or the user's).
    #[serde(skip)]
    pub scripts: BTreeMap<String, super::estimate::ScriptSize>,
    /// The memory the build may keep values in, in bytes (`[build] memory`, or `chunkc build
    /// --memory` once the command sets it); `None`: exec's default.
    #[serde(skip)]
    pub memory: Option<u64>,
}

/// What the temporal audit found and what `build` does about it.
#[derive(Debug, Clone, Default, Serialize)]
pub struct AuditSummary {
    /// Seconds per step the episodes should have: `1 / source.fps`.
    pub expected_interval: f64,
    /// Whether the source stores timestamps (without them every episode is `ok`).
    pub timestamps: bool,
    /// Whether `build` applies the verdicts (`[audit] repair`).
    pub applied: bool,
    /// Episodes per verdict.
    pub verdicts: BTreeMap<&'static str, usize>,
    pub repaired_fraction: f64,
    pub excluded_fraction: f64,
    pub warnings: Vec<String>,
    /// Wall seconds the dataset doctor took, when it ran (not in the plan's JSON, which depends
    /// only on the spec, the source and the lock).
    #[serde(skip)]
    pub doctor_seconds: Option<f64>,
}

/// An episode the audit repaired before anything else happens to it.
#[derive(Debug, Clone, Serialize)]
pub struct RepairedEpisode {
    pub id: u64,
    pub verdict: Verdict,
    /// Steps as recorded.
    pub recorded_len: usize,
    /// Steps after repair, at the source rate.
    pub len: usize,
    pub detail: String,
}

#[derive(Debug, Clone, Serialize)]
pub struct SourcePlan {
    pub format: &'static str,
    /// As written in the spec (relative to the spec file).
    pub path: String,
    pub fps: f64,
    pub episodes: usize,
    pub steps: usize,
    /// With the BLAKE3 of every file it covers, by path in the source (kept in the lock).
    pub fingerprint: crate::source::fingerprint::SourcePrint,
    pub channels: Vec<ChannelInfo>,
    /// A training mixture's sources (empty for one source).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub parts: Vec<SourcePart>,
    /// Each episode's task, by source id (RLDS language instructions); empty when the source
    /// stores none. Not part of the plan's text or JSON: `meta.json` and the card show it.
    #[serde(skip)]
    pub tasks: BTreeMap<u64, String>,
}

/// One pass's worth of converted episodes: a rate, and the stored size of every resized camera
/// (profiles at one rate that store a camera at different sizes get a job each).
#[derive(Debug, Clone, Serialize)]
pub struct RateJob {
    pub fps: f64,
    pub conversion: Conversion,
    pub steps: usize,
    /// `[H, W]` of each resized camera, by channel.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub cameras: BTreeMap<String, [usize; 2]>,
    pub profiles: Vec<String>,
}

#[derive(Debug, Clone, Serialize)]
pub struct StatsJob {
    pub fps: f64,
    pub channel: String,
    /// `[H, W]` of a resized camera's stored frames (its statistics describe those).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub size: Option<[usize; 2]>,
    pub split: &'static str,
    pub profiles: Vec<String>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ProfilePlan {
    pub name: String,
    /// Every value, fully resolved.
    pub values: Profile,
    pub fps: f64,
    pub conversion: Conversion,
    pub rate: String,
    /// How episodes become samples (window parameters included).
    pub sampling: Sampling,
    pub channels: Vec<ProfileChannel>,
    /// The action representations, bound to the channels (`abs_action`'s first), in order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub transforms: Vec<crate::transform::Transform>,
    /// Per channel (manifest order): its widths through the transforms, per source.
    #[serde(skip)]
    pub widths: Vec<crate::transform::Widths>,
    /// A `groot` profile's GR00T modality, per dataset (one per source, in mixture order);
    /// empty (and left out of the plan's JSON) for other profiles.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub groot: Vec<super::groot::GrootModality>,
    pub episodes: Vec<ProfileEpisode>,
    pub excluded: Vec<Excluded>,
    /// Episodes the audit repaired (re-gridded or resampled) before they were used.
    pub repaired: Vec<RepairedEpisode>,
    pub warnings: Vec<String>,
    pub num_samples: SplitCounts,
    pub steps: usize,
    pub files: Vec<PlannedFile>,
    pub fingerprint: super::freshness::ProfilePrint,
    /// The spec values the fingerprint covers, by dotted key (kept in the lock, so that the next
    /// plan can name the value that changed).
    #[serde(skip)]
    pub inputs: BTreeMap<String, String>,
    pub status: Status,
}

#[derive(Debug, Clone, Serialize)]
pub struct ProfileChannel {
    pub name: String,
    pub kind: ChannelKind,
    pub shape: Vec<usize>,
    pub normalize: NormalizeMode,
    /// The name a native export gives the channel (`None`: the format keeps chunkc's names).
    pub export: Option<String>,
    /// The channel's per-step array in the data container (see [`export`]): `data/img`,
    /// `data/demo_<i>/obs/state`, `observations/qpos`; `<i>` is the stored episode position.
    pub array: String,
    /// How a resized camera's frames are resized (`[profiles.<name>.cameras.<channel>]`);
    /// `shape` is then the stored shape.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resize: Option<CameraResize>,
}

impl ProfileChannel {
    /// [`ProfileChannel::array`] of the episode stored at position `i`.
    pub fn array_of(&self, i: usize) -> String {
        self.array.replace("<i>", &i.to_string())
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct ProfileEpisode {
    pub id: u64,
    pub split: &'static str,
    pub source_len: usize,
    /// Steps at the profile's rate.
    pub len: usize,
    /// `None` when it depends on the data (segments).
    pub samples: Option<usize>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Excluded {
    pub id: u64,
    pub reason: String,
}

/// Sample counts per split; `None` when they depend on the data (segments).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct SplitCounts {
    pub train: Option<usize>,
    pub val: Option<usize>,
}

/// A file the profile writes (a path ending in `/` is a directory, one with `*` a set of files),
/// with its size as known before the build.
#[derive(Debug, Clone, Serialize)]
pub struct PlannedFile {
    pub path: String,
    pub estimated_bytes: u64,
    /// Whether `estimated_bytes` is an upper bound of what the build writes (`<=`); otherwise an
    /// estimate (`~`): frames stored lossily, a template of the user's.
    pub bound: bool,
    /// How many files a directory holds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub files: Option<usize>,
    /// How an estimate was made (the source's video files, sample frames encoded, a guess).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub basis: Option<String>,
}

/// One resolved profile value and where it came from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ResolvedValue {
    pub key: &'static str,
    pub value: String,
    /// `profiles.<name>`, `preset <name>`, `spec` or `default`.
    pub origin: String,
}

impl ProfilePlan {
    /// Whether the profile writes a LeRobot v2.1 dataset (`format = "parquet"`,
    /// `lerobot_version = "v2.1"`).
    pub fn writes_lerobot_v21(&self) -> bool {
        self.values.writes_lerobot_v21()
    }

    /// The transforms of channel `c` (a manifest position), in order.
    pub fn transforms_of(&self, c: usize) -> impl Iterator<Item = &crate::transform::Transform> {
        self.transforms.iter().filter(move |t| t.channel_index == c)
    }

    /// The transforms of channel `c` that apply to source `s` (a mixture position; 0 for one
    /// source), in order.
    pub fn transforms_for(
        &self,
        c: usize,
        s: usize,
    ) -> impl Iterator<Item = &crate::transform::Transform> {
        self.transforms_of(c).filter(move |t| t.applies_to(s))
    }

    /// Whether channel `c`'s statistics are not the per-frame ones of its stored values: it is
    /// transformed, or the statistics cover windows.
    pub fn windowed_stats(&self, c: usize) -> bool {
        self.values.stats_population == crate::spec::StatsPopulation::Windows
            || self.transforms_of(c).next().is_some()
    }

    pub fn window(&self) -> &Window {
        self.sampling.window()
    }

    /// `[H, W]` of each camera this profile resizes, by channel.
    pub fn cameras(&self) -> BTreeMap<String, [usize; 2]> {
        self.channels
            .iter()
            .filter_map(|c| Some((c.name.clone(), c.resize?.size)))
            .collect()
    }

    /// Whether `job` converts episodes as this profile stores them.
    pub fn uses(&self, job: &RateJob) -> bool {
        job.conversion == self.conversion && job.cameras == self.cameras()
    }

    /// The values that shape the dataset, as `chunkc plan` and the dataset card show them.
    pub fn resolved_values(&self) -> Vec<ResolvedValue> {
        let v = &self.values;
        let opt = |x: Option<String>| x.unwrap_or_else(|| "none".into());
        [
            ("preset", opt(v.preset.map(|p| p.name().to_string()))),
            ("fps", self.fps.to_string()),
            ("chunk", self.window().chunk.to_string()),
            ("obs_history", v.obs_history.to_string()),
            ("executes", opt(v.executes.map(|e| e.to_string()))),
            ("alignment", v.alignment.name().to_string()),
            ("padding", v.padding.name().to_string()),
            ("stride", v.stride.to_string()),
            ("format", v.format.name().to_string()),
            ("sampling", self.sampling.name().to_string()),
        ]
        .into_iter()
        .chain(
            // Only where it is not the default, so that other profiles' lines stay.
            (v.lerobot_version != LerobotVersion::V30)
                .then(|| ("lerobot_version", v.lerobot_version.name().to_string())),
        )
        .map(|(key, value)| {
            let origin = v.origins.get(key).cloned().unwrap_or_else(|| {
                let from_spec = key == "sampling" && (v.segment.is_some() || v.hierarchy.is_some());
                if from_spec { "spec" } else { "default" }.to_string()
            });
            ResolvedValue { key, value, origin }
        })
        .collect()
    }
}

impl Plan {
    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("plan serializes");
        s.push('\n');
        s
    }

    pub fn up_to_date(&self) -> bool {
        self.profiles.iter().all(|p| p.status.is_up_to_date())
    }
}
