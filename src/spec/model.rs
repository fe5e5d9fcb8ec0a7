// Long file: every TOML table's type in one place, in the order the schema and reference are generated.
//! The spec as written: serde + schemars types and nothing else.
//!
//! These types mirror the TOML one to one. Every optional value stays optional here; presets and
//! defaults are applied later by `spec::preset`, which produces the fully explicit
//! [`crate::spec::Profile`]. Keep this file free of engine dependencies: the JSON Schema and the
//! book's spec reference are generated from it.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub use super::image_storage::ImageCompression;
pub use super::memory::MemorySize;
pub use super::transform::{StatsPopulation, TransformSpec};

/// A chunkc build spec (`chunkc.toml`): one source (or a mixture of several), one split, one
/// output directory, and one profile per target architecture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    /// Spec format version. Must be 1.
    pub version: u32,
    /// The raw demonstration dataset to read. Give either `[source]` or `[sources.<name>]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<SourceSpec>,
    /// A training mixture: several datasets, `[sources.<name>]`, each today's `[source]` plus a
    /// `weight`, built into one output (see `[mixture]`).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub sources: BTreeMap<String, SourceSpec>,
    /// How the sources of `[sources.<name>]` are mixed: sampling balance, statistics, padding.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mixture: Option<MixtureSpec>,
    /// How episodes are divided into training and validation sets.
    #[serde(default)]
    pub split: SplitSpec,
    /// What to do about bad data found while reading.
    #[serde(default, skip_serializing_if = "AuditSpec::is_default")]
    pub audit: AuditSpec,
    /// Where the outputs go.
    pub output: OutputSpec,
    /// How the build runs (outputs never depend on it).
    #[serde(default, skip_serializing_if = "BuildSpec::is_default")]
    pub build: BuildSpec,
    /// One entry per target architecture: `[profiles.<name>]`. Each writes `<output.dir>/<name>/`.
    pub profiles: BTreeMap<String, ProfileSpec>,
}

/// `[source]`: the dataset to read and how its keys map to chunkc channels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SourceSpec {
    /// The on-disk layout of the dataset.
    pub format: SourceFormat,
    /// Path to the dataset, relative to the spec file.
    pub path: String,
    /// Recording rate in Hz. Required when the source stores neither timestamps nor a rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fps: Option<f64>,
    /// Only these source episode ids, in the source's order (all when left out).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub episodes: Option<Vec<u64>>,
    /// Channel mapping, `our name = "source key"` or `our name = { key = …, columns = […] }` /
    /// `{ concat = […] }`. Exactly one channel must be called `action`; every other channel is
    /// an observation and must be named `observation.<name>`.
    pub channels: BTreeMap<String, ChannelSpec>,
    /// Only in `[sources.<name>]`: this source's sampling weight in the mixture (at least 0;
    /// default 1). How weights become sampling probabilities is `[mixture] balance`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weight: Option<f64>,
}

/// `[mixture]`: how the sources of a training mixture are combined.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MixtureSpec {
    /// How the loader's sampler turns weights into source probabilities.
    #[serde(default)]
    pub balance: Balance,
    /// Which statistics normalize each source's values.
    #[serde(default)]
    pub stats: MixtureStats,
    /// Channels zero-padded to a common width after normalizing, `{ action = 32 }`; each gets a
    /// `<channel>_dim_mask` in the loader's samples, true on the source's own dimensions.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub pad_to: BTreeMap<String, usize>,
}

/// `[mixture] balance`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Balance {
    /// Each source drawn with probability weight / sum of weights.
    #[default]
    Weights,
    /// weight × the source's windows in the split, normalized (Octo's `balance_weights`).
    Steps,
    /// Every source with windows equally often, whatever its weight.
    Uniform,
}

/// `[mixture] stats`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum MixtureStats {
    /// Each source normalized with its own statistics (Octo).
    #[default]
    PerSource,
    /// Every source normalized with the statistics of the union (openpi's shared asset).
    Pooled,
}

impl Balance {
    pub fn name(self) -> &'static str {
        match self {
            Balance::Weights => "weights",
            Balance::Steps => "steps",
            Balance::Uniform => "uniform",
        }
    }
}

impl MixtureStats {
    pub fn name(self) -> &'static str {
        match self {
            MixtureStats::PerSource => "per_source",
            MixtureStats::Pooled => "pooled",
        }
    }
}

/// One channel of `[source.channels]`: a source key, or a table that selects columns of a key,
/// concatenates several keys, or declares the kind.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
#[serde(untagged)]
pub enum ChannelSpec {
    /// The source key, read whole.
    Key(String),
    /// `{ key = "state", columns = [1, 8] }`, `{ concat = ["a", "b"] }`, `{ key = …, kind = … }`.
    Table(ChannelTable),
}

/// Untagged by hand: a string or a table, and a table's own error (an unknown field with the
/// list of valid ones) reaches the user instead of serde's "did not match any variant".
impl<'de> Deserialize<'de> for ChannelSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = ChannelSpec;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a source key (string) or a table such as { key = \"state\", columns = [0, 7] }")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<ChannelSpec, E> {
                Ok(ChannelSpec::Key(v.to_string()))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> Result<ChannelSpec, A::Error> {
                ChannelTable::deserialize(serde::de::value::MapAccessDeserializer::new(map))
                    .map(ChannelSpec::Table)
            }
        }
        d.deserialize_any(Visitor)
    }
}

/// The table form of a channel mapping. Give exactly one of `key` and `concat`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ChannelTable {
    /// The source key to read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub key: Option<String>,
    /// Several low-dimensional source keys, joined column-wise in this order.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub concat: Option<Vec<String>>,
    /// `[start, end)`: keep these columns of the (flattened) key, as Python's `x[:, start:end]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub columns: Option<[usize; 2]>,
    /// What the channel holds; decided from its per-step shape when left out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kind: Option<ChannelKindSpec>,
}

/// A declared channel kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ChannelKindSpec {
    /// A vector per step (any per-step shape is flattened).
    Lowdim,
    /// An (H, W, C) uint8 image per step.
    Image,
}

impl ChannelSpec {
    /// The source keys this channel reads, in order.
    pub fn keys(&self) -> Vec<&str> {
        match self {
            ChannelSpec::Key(k) => vec![k.as_str()],
            ChannelSpec::Table(t) => match (&t.key, &t.concat) {
                (Some(k), _) => vec![k.as_str()],
                (None, Some(keys)) => keys.iter().map(String::as_str).collect(),
                (None, None) => Vec::new(),
            },
        }
    }

    /// How the mapping is shown in messages and the plan (`state[1:8]`, `a + b`).
    pub fn describe(&self) -> String {
        let joined = self.keys().join(" + ");
        match self {
            ChannelSpec::Table(ChannelTable {
                columns: Some([a, b]),
                ..
            }) => format!("{joined}[{a}:{b}]"),
            _ => joined,
        }
    }
}

/// The on-disk layouts chunkc reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SourceFormat {
    /// Diffusion Policy zarr ReplayBuffer: `data/<key>` + `meta/episode_ends`.
    DiffusionPolicyZarr,
    /// ACT / ALOHA: one `episode_<i>.hdf5` per episode.
    AlohaHdf5,
    /// robomimic: `data/demo_<i>` groups in one HDF5 file.
    RobomimicHdf5,
    /// LeRobot v2.1 / v3.0: parquet + `meta/info.json`.
    Lerobot,
    /// RLDS / Open X-Embodiment: a TFDS-prepared directory of TFRecord shards
    /// (`dataset_info.json`, `features.json`). Stores no rate: `source.fps` is required.
    Rlds,
}

impl SourceFormat {
    pub fn name(self) -> &'static str {
        match self {
            SourceFormat::DiffusionPolicyZarr => "diffusion_policy_zarr",
            SourceFormat::AlohaHdf5 => "aloha_hdf5",
            SourceFormat::RobomimicHdf5 => "robomimic_hdf5",
            SourceFormat::Lerobot => "lerobot",
            SourceFormat::Rlds => "rlds",
        }
    }
}

/// `[split]`: a deterministic train/validation split keyed by episode id, so that adding an
/// episode to the source never moves the others between sets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SplitSpec {
    /// Fraction of episodes held out for validation, in [0, 1).
    #[serde(default = "default_val_fraction")]
    pub val_fraction: f64,
    /// Seed of the split's hash.
    #[serde(default)]
    pub seed: u64,
    /// Where the split comes from: chunkc's seeded hash (default), or the source's own split
    /// (robomimic `mask/train` / `mask/valid`, LeRobot `info.json` `splits`), falling back to
    /// the hash when the source has none.
    #[serde(default, skip_serializing_if = "SplitFrom::is_hash")]
    pub from: SplitFrom,
}

/// Where the train/validation split comes from.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SplitFrom {
    /// chunkc's deterministic hash of (seed, episode id), with `val_fraction`.
    #[default]
    Hash,
    /// The split stored in the source.
    Source,
}

impl SplitFrom {
    fn is_hash(&self) -> bool {
        *self == SplitFrom::Hash
    }
}

fn default_val_fraction() -> f64 {
    0.1
}

impl Default for SplitSpec {
    fn default() -> Self {
        SplitSpec {
            val_fraction: default_val_fraction(),
            seed: 0,
            from: SplitFrom::Hash,
        }
    }
}

/// `[audit]`: checks of the data itself. The temporal audit (`chunkc audit`) judges every
/// episode's inter-frame intervals against `1 / source.fps` and decides a verdict per episode
/// (`ok`, `interpolate`, `resample`, `exclude`); `build` applies the verdicts when `repair` is on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AuditSpec {
    /// A NaN or infinite value in a low-dimensional channel: stop the build with an error naming
    /// the episode, channel and step (default), or leave the whole episode out (listed under
    /// `excluded` in each profile's `meta.json`).
    #[serde(default)]
    pub non_finite: NonFinite,
    /// A camera video (LeRobot `dtype: "video"`) that cannot give every row its frame: a missing,
    /// truncated or unreadable file, or a row whose nearest frame is `tolerance_s` (1e-4 s) or
    /// more away. Stop with an error naming the episode, camera, file (and row and gap)
    /// (default), or leave the episode out of every profile.
    #[serde(default)]
    pub video: BadVideo,
    /// Apply the audit's verdicts in `build` (re-grid, resample, exclude). When false, episodes
    /// are used as recorded and the verdicts are only reported.
    #[serde(default = "default_true")]
    pub repair: bool,
    /// Flag `jitter` when the standard deviation of an episode's intervals exceeds this fraction
    /// of their mean.
    #[serde(default = "default_jitter")]
    pub jitter_threshold: f64,
    /// Flag `gap` when an interval exceeds this many expected intervals.
    #[serde(default = "default_gap")]
    pub gap_threshold: f64,
    /// Flag `count` when the frame count deviates from `duration × fps + 1` by more than this
    /// fraction.
    #[serde(default = "default_count")]
    pub count_threshold: f64,
    /// Dropped frames an episode may miss and still be repaired by interpolation; an episode
    /// missing more (or, when its timing is irregular, with one hole longer than
    /// `max_dropped + 1` intervals) is excluded.
    #[serde(default = "default_max_dropped")]
    pub max_dropped: u32,
    /// Repeated or decreasing timestamps.
    #[serde(default)]
    pub non_monotonic: NonMonotonic,
    /// Regular intervals at the wrong rate (only `count` flagged): resample the episode to the
    /// source rate, or leave it out.
    #[serde(default)]
    pub rate_error: RateError,
    /// Irregular intervals (`jitter`): re-grid the episode onto regular steps by cubic spline, or
    /// leave it out.
    #[serde(default)]
    pub irregular: Irregular,
    /// How a whole episode changes rate, both for `rate_error = "resample"` and for profiles
    /// whose `fps` does not divide the source's: `fourier` (as `scipy.signal.resample`) or
    /// `linear`.
    #[serde(default)]
    pub resample: ResampleMethod,
    /// `[audit.doctor]`: the data checks (signal quality, alignment, action conventions,
    /// duplicates, shift, short episodes).
    #[serde(default)]
    pub doctor: DoctorSpec,
}

/// `[audit.doctor]`: the dataset doctor's checks of the action and state values (see the book's
/// "Dataset doctor" page). Each per-episode check has an action (`warn`, `exclude` the episode,
/// or fail with an `error`) and its threshold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DoctorSpec {
    /// Run the checks (they read every episode's action and state channels once).
    #[serde(default = "default_true")]
    pub enabled: bool,
    /// An action dimension that holds one exact value for a long run, where the dimension moves
    /// in most other episodes.
    #[serde(default)]
    pub frozen: DoctorAction,
    /// The shortest run flagged `frozen`, as a fraction of the episode.
    #[serde(default = "default_frozen_fraction")]
    pub frozen_fraction: f64,
    /// Runs of an action dimension sitting exactly at its episode's min or max.
    #[serde(default)]
    pub clipped: DoctorAction,
    /// The share of an episode's steps at a bound flagged `clipped`.
    #[serde(default = "default_clip_fraction")]
    pub clip_fraction: f64,
    /// One-step spikes in an action dimension.
    #[serde(default)]
    pub jump: DoctorAction,
    /// Flag `jump` when a value lies off the line through its two neighbours, going out and
    /// straight back, by more than this many times the dimension's motion scale: the median over
    /// episodes of the 90th percentile of that distance at the steps where it moves (how much a
    /// real motion of the dimension bends from step to step).
    #[serde(default = "default_jump_threshold")]
    pub jump_threshold: f64,
    /// ... and by more than this fraction of the dimension's range over the dataset.
    #[serde(default = "default_jump_range")]
    pub jump_range: f64,
    /// Near-copies of an earlier episode (the later one is flagged).
    #[serde(default)]
    pub duplicate: DoctorAction,
    /// Flag `duplicate` below this RMS difference of the resampled actions, in units of each
    /// dimension's typical spread.
    #[serde(default = "default_duplicate_tolerance")]
    pub duplicate_tolerance: f64,
    /// An episode whose action-to-state lag differs from the dataset's most common lag.
    #[serde(default)]
    pub misaligned: DoctorAction,
    /// Steps of lag difference tolerated before flagging `misaligned`.
    #[serde(default = "default_lag_tolerance")]
    pub lag_tolerance: u32,
    /// An episode whose actions behave as deltas where most are absolute targets, or the reverse.
    #[serde(default)]
    pub mixed_convention: DoctorAction,
    /// An episode whose actions are in other units than the rest.
    #[serde(default)]
    pub units: DoctorAction,
    /// Flag `units` when an episode's action scale differs from the dataset's by more than this
    /// factor (either way).
    #[serde(default = "default_units_ratio")]
    pub units_ratio: f64,
    /// An episode shorter than a profile's chunk.
    #[serde(default)]
    pub short: DoctorAction,
    /// Warn of distribution shift when a quarter of the episodes (in recording order) has a
    /// median episode mean this many robust standard deviations from the dataset's.
    #[serde(default = "default_shift_threshold")]
    pub shift_threshold: f64,
}

/// What a doctor check does with an episode it flags.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum DoctorAction {
    /// Report it; `build` uses the episode.
    #[default]
    Warn,
    /// Leave the episode out of every profile (with `repair = true`).
    Exclude,
    /// Fail `audit` and `build` with an error naming the episode.
    Error,
}

fn default_frozen_fraction() -> f64 {
    0.5
}
fn default_clip_fraction() -> f64 {
    0.05
}
fn default_jump_threshold() -> f64 {
    8.0
}
fn default_jump_range() -> f64 {
    0.05
}
fn default_duplicate_tolerance() -> f64 {
    0.01
}
fn default_lag_tolerance() -> u32 {
    1
}
fn default_units_ratio() -> f64 {
    3.0
}
fn default_shift_threshold() -> f64 {
    1.0
}

impl Default for DoctorSpec {
    fn default() -> Self {
        DoctorSpec {
            enabled: true,
            frozen: DoctorAction::Warn,
            frozen_fraction: default_frozen_fraction(),
            clipped: DoctorAction::Warn,
            clip_fraction: default_clip_fraction(),
            jump: DoctorAction::Warn,
            jump_threshold: default_jump_threshold(),
            jump_range: default_jump_range(),
            duplicate: DoctorAction::Warn,
            duplicate_tolerance: default_duplicate_tolerance(),
            misaligned: DoctorAction::Warn,
            lag_tolerance: default_lag_tolerance(),
            mixed_convention: DoctorAction::Warn,
            units: DoctorAction::Warn,
            units_ratio: default_units_ratio(),
            short: DoctorAction::Warn,
            shift_threshold: default_shift_threshold(),
        }
    }
}

fn default_true() -> bool {
    true
}
fn default_jitter() -> f64 {
    0.1
}
fn default_gap() -> f64 {
    2.0
}
fn default_count() -> f64 {
    0.05
}
fn default_max_dropped() -> u32 {
    2
}

impl Default for AuditSpec {
    fn default() -> Self {
        AuditSpec {
            non_finite: NonFinite::default(),
            video: BadVideo::default(),
            repair: true,
            jitter_threshold: default_jitter(),
            gap_threshold: default_gap(),
            count_threshold: default_count(),
            max_dropped: default_max_dropped(),
            non_monotonic: NonMonotonic::default(),
            rate_error: RateError::default(),
            irregular: Irregular::default(),
            resample: ResampleMethod::default(),
            doctor: DoctorSpec::default(),
        }
    }
}

impl AuditSpec {
    fn is_default(&self) -> bool {
        *self == AuditSpec::default()
    }
}

/// What to do with an episode whose timestamps repeat or go back.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum NonMonotonic {
    /// Keep the first frame of every run of equal timestamps, then judge the rest; an episode
    /// whose timestamps go back is excluded.
    #[default]
    DropDuplicates,
    /// Leave the episode out.
    Exclude,
    /// Fail with an error naming the episode and step.
    Error,
}

/// What to do with an episode recorded regularly at the wrong rate.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum RateError {
    /// Resample the whole episode to the source rate (`[audit] resample` says how).
    #[default]
    Resample,
    /// Leave the episode out.
    Exclude,
}

/// What to do with an episode whose intervals are irregular.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Irregular {
    /// Re-grid onto regular steps: cubic spline for numbers, the nearest frame for images.
    #[default]
    Interpolate,
    /// Leave the episode out.
    Exclude,
}

/// How an episode is resampled to another number of steps.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ResampleMethod {
    /// The Fourier method of `scipy.signal.resample` (treats the episode as periodic).
    #[default]
    Fourier,
    /// Linear interpolation between the neighbouring steps (as `numpy.interp`).
    Linear,
}

/// What to do with an episode holding NaN or infinity.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum NonFinite {
    /// Fail the build.
    #[default]
    Error,
    /// Leave the episode out of every profile.
    ExcludeEpisode,
}

/// What to do with an episode whose camera video cannot give every row its frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum BadVideo {
    /// Fail `audit` and `build`, naming the episode, camera and file.
    #[default]
    Error,
    /// Leave the episode out of every profile (its audit verdict is `exclude`).
    ExcludeEpisode,
}

/// `[output]`: where the built datasets are written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Output directory, relative to the spec file. Each profile writes a subdirectory.
    pub dir: String,
    /// A directory of template overrides, relative to the spec file: `<file>.j2` replaces the
    /// built-in template of that generated file (`loader.py.j2`, `README.md.j2`, ...), and
    /// `<file stem>/<part>.j2` one part of it (`loader/dataset.py.j2`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub templates: Option<String>,
    /// Allow `dir` (the part written in the spec) and the entries chunkc writes directly under it
    /// to be symlinks. Off by default: a build refuses an output path that a symlink sends
    /// somewhere else, since a stray link would make it write (and replace) files elsewhere.
    /// Writing into the source is refused either way.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub follow_symlinks: bool,
}

/// `[build]`: how the build runs, on this machine; the outputs are the same bytes whatever it
/// says.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BuildSpec {
    /// The memory the build may keep low-dimensional values in until they are written, with a
    /// unit (`"2GiB"`, `"512MiB"`); what does not fit goes to a file in the staging directory.
    /// Default: a quarter of the memory available when the build starts. `chunkc build
    /// --memory` overrides it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(with = "Option<String>")]
    pub memory: Option<MemorySize>,
}

impl BuildSpec {
    pub fn is_default(&self) -> bool {
        self == &BuildSpec::default()
    }
}

/// `[profiles.<name>]`: one training-ready dataset. Every value left out comes from the profile it
/// `extends`, then from the preset, then from the defaults.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ProfileSpec {
    /// Start from a target architecture's conventions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<Preset>,
    /// Start from another profile of this spec (its values, and its preset); anything set here
    /// overrides it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extends: Option<String>,
    /// Control rate in Hz, at most the source rate. An integer divisor of the source rate keeps
    /// every n-th step; any other rate resamples each episode (`[audit] resample`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fps: Option<f64>,
    /// Action chunk length K, in steps at the profile's rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chunk: Option<u32>,
    /// Number of observation frames per sample, ending at the sample's current step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub obs_history: Option<u32>,
    /// Action steps the policy executes before replanning (Diffusion Policy's `n_action_steps`).
    /// When set, it bounds the padding after the episode end to `executes - 1` steps (Diffusion
    /// Policy's `pad_after`), whatever the alignment.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub executes: Option<u32>,
    /// The simulator the trained policy is rolled out in, a gymnasium id such as
    /// `"gym_pusht/PushT-v0"`: the profile gets a generated `rollout.py` (see the book's
    /// "Validating a dataset" chapter for the environments it supports).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub env: Option<String>,
    /// Where the action chunk starts relative to the observation history.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alignment: Option<Alignment>,
    /// What fills an action chunk that runs past the end of its episode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub padding: Option<Padding>,
    /// Steps between the starts of consecutive samples within an episode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stride: Option<u32>,
    /// Normalization per channel; channels left out get the preset's mode for their kind.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normalize: Option<BTreeMap<String, NormalizeMode>>,
    /// Output container format: chunkc's own (`hdf5`, `zarr`, `parquet`) or a codebase-native
    /// export (`act_episodes`, `robomimic_hdf5`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub format: Option<OutputFormat>,
    /// Names of the arrays of a native export (`zarr`, `robomimic_hdf5`, `act_episodes`), per
    /// channel: `"observation.image" = "camera_0"`. A channel left out keeps the name of the
    /// source key it was read from (its last `/` component), or, when it is built with `concat`
    /// or `columns`, its chunkc name without `observation.`. Fixed by the codebase: robomimic's
    /// `actions`, ACT's `action`, and ACT's state channel is `qpos` unless named here. Merged
    /// along `extends`; a name is one path component (no `/`). `hdf5` and `parquet` keep
    /// chunkc's names and take none (see `formats.md`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub export_keys: Option<BTreeMap<String, String>>,
    /// How `format = "hdf5"` stores the chunks: `index` (default, per-step arrays + window
    /// index), `materialized` (plus `/chunks/<channel>` of shape (N, K, ...): K times the
    /// storage) or `virtual` (plus an HDF5 virtual dataset `/chunks/action` mapped onto the
    /// per-step rows).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layout: Option<Layout>,
    /// Compression of low-dimensional arrays (images: see `formats.md`). HDF5: `none`
    /// (default), `gzip`, `lzf`; Zarr: `lz4` (default, Blosc), `zstd` (Blosc, bit-shuffled),
    /// `none`; Parquet: `zstd` (default), `none`. Native exports keep their codebase's layout.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compression: Option<Compression>,
    /// Compression level: gzip 0-9 (default 4), Blosc 1-9 (default 5), Parquet zstd 1-22
    /// (default 3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compression_level: Option<u32>,
    /// How `format = "hdf5"` stores image frames: `none` (default; uncompressed, one frame per
    /// chunk, as ACT and robomimic store them: the fastest to read), `gzip` (HDF5's deflate
    /// filter: about 1.5x smaller), `jpeg` (a JPEG per frame at `image_quality`, as ALOHA's
    /// compressed episodes: lossy, 10-30x smaller) or `video` (one mp4 per episode and camera in
    /// `videos/`, H.264 with a keyframe every 8 frames by default: lossy, the smallest; needs the
    /// `video` cargo feature). Other formats keep their own convention: Zarr compresses frames
    /// with `compression`, Parquet as `image_encoding` says, native exports store them raw.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_compression: Option<ImageCompression>,
    /// gzip level of `image_compression = "gzip"`, 0-9 (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_compression_level: Option<u32>,
    /// JPEG quality of `image_compression = "jpeg"`, 1-100 (default 90).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_quality: Option<u32>,
    /// How `format = "parquet"` stores image frames: `png` (default; lossless PNGs in the
    /// parquet rows, readable by chunkc's loader with numpy alone and by any build of chunkc) or
    /// `video` (one mp4 per camera, `videos/<channel>/chunk-000/file-000.mp4`, `dtype: "video"`
    /// in `meta/info.json`, as LeRobot records its datasets: lossy, many times smaller; needs a
    /// chunkc built with the `video` cargo feature). See `video-export.md`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_encoding: Option<ImageEncoding>,
    /// Encoder of `image_encoding = "video"`: `libsvtav1` (default; AV1, LeRobot's default) or
    /// `libx264` (H.264; the default of hdf5's `image_compression = "video"`: faster to decode).
    /// The wheel's FFmpeg (LGPL) has no x264: there hdf5's default is `libsvtav1` too, and
    /// `libx264` is refused.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub video_codec: Option<VideoCodec>,
    /// Constant rate factor of the video encoder (lower is better quality and larger): default
    /// 30 (LeRobot's), 23 for hdf5's `image_compression = "video"`; libsvtav1 0-63, libx264 0-51.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub video_crf: Option<u32>,
    /// Keyframe interval (GOP size) of the video encoder, in frames: default 2 for parquet
    /// (LeRobot's: random access to any frame decodes at most one other), 8 for hdf5's
    /// `image_compression = "video"` (see `video-storage.md`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub video_gop: Option<u32>,
    /// Whether a video stored one file per episode copies a source video's packets into an
    /// episode's file instead of encoding its frames again, where the profile keeps the video
    /// as it is: the source's rate, no `cameras` resize, rows that are the video's own frames,
    /// an episode that starts on a keyframe, keyframes at most `video_gop` frames apart, and the
    /// codec of `video_codec` when that is given. hdf5's `image_compression = "video"` and
    /// parquet's `lerobot_version = "v2.1"`: default true (the stored video is the source's
    /// bytes, with no second generation of compression loss); `false` encodes every episode.
    /// Parquet's LeRobot v3.0: default false (one encoded file of every episode per camera, as
    /// LeRobot records); `true` writes one file per episode, copied where it can be.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub video_copy: Option<bool>,
    /// Zarr format version of `format = "zarr"`: 2 (default; what Diffusion Policy's
    /// `ReplayBuffer` opens) or 3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zarr_version: Option<u32>,
    /// LeRobot dataset version of `format = "parquet"`: `"v3.0"` (default; what LeRobot >= 0.4
    /// reads: one data file of every episode) or `"v2.1"` (what openpi's pinned lerobot, PyPI
    /// lerobot <= 0.3.3, GR00T and most VLA repositories read: one parquet file and one mp4 per
    /// episode, `meta/*.jsonl`). A v2.1 profile folder is the dataset root and holds the training
    /// episodes; the validation episodes are a second v2.1 dataset in its `val/` folder. See
    /// `formats.md`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lerobot_version: Option<LerobotVersion>,
    /// GR00T's `meta/modality.json` (`preset = "groot"` only): per low-dimensional channel, its
    /// named parts, `"observation.state" = { arm = [0, 7], gripper = [7, 8] }`, each a `[start,
    /// end)` slice of the channel's vector (GR00T's `start` / `end`). The parts of a channel
    /// tile it: from 0 to its width, without overlap or gap. A channel left out is one part,
    /// named after its last dotted component (`state`, `action`). `action`'s parts are GR00T's
    /// action keys, every other low-dimensional channel's its state keys; cameras are its video
    /// keys (`observation.images.top` as `top`) and the task its
    /// `annotation.human.task_description`. Merged along `extends`, channel by channel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub modality: Option<BTreeMap<String, ModalityParts>>,
    /// The action parts (of `modality`) GR00T fine-tunes as relative actions
    /// (`ActionRepresentation.RELATIVE`; `preset = "groot"` only): `meta/relative_stats.json`
    /// holds their statistics over every action chunk of `chunk` steps that fits in its
    /// episode, each the action minus the state part of the same name at the chunk's first step.
    /// The dataset keeps absolute actions: GR00T makes them relative itself.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub relative_actions: Option<Vec<String>>,
    /// Statistics files in target codebases' own formats, written beside `stats.json`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stats_formats: Option<Vec<StatsFormat>>,
    /// Variable-length chunks cut at natural breakpoints instead of fixed windows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub segment: Option<SegmentSpec>,
    /// Two-level chunks: a coarse chunk of several seconds and fine chunks inside it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hierarchy: Option<HierarchySpec>,
    /// Action representations: an ordered list of `[[profiles.<name>.transforms]]` tables
    /// (`op = "rotation" | "delta" | "relative_pose"`), applied before statistics and
    /// normalization (see the book's "Action representations" page). Not inherited along
    /// `extends` when the profile gives its own list.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transforms: Option<Vec<TransformSpec>>,
    /// Which values the statistics cover: `frames` (every training step once; the default) or
    /// `windows` (every training sample's whole action chunk, as openpi counts them; the `pi0`
    /// presets' choice, and required with `delta` or `relative_pose`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stats_population: Option<StatsPopulation>,
    /// Diffusion Policy's robomimic `abs_action: True` (a `diffusion_policy` profile only):
    /// actions `[pos3, axis_angle3, gripper1]` per arm (7 or 14 wide) become `[pos3,
    /// rotation_6d, gripper1]` (10 or 20), normalized as its `robomimic_abs_action_only`
    /// normalizer does (`normalize.action = "dp_abs_action"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub abs_action: Option<bool>,
    /// Per camera (image channel): the size its frames are stored at,
    /// `[profiles.<name>.cameras."observation.image"] size = [H, W]`. Merged along `extends`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cameras: Option<BTreeMap<String, super::camera::CameraSpec>>,
}

/// One channel's parts in GR00T's `meta/modality.json`: `<part> = [start, end]`, each the
/// slice `[start, end)` of the channel's vector; together they tile it from 0 to its width.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(transparent)]
pub struct ModalityParts(pub BTreeMap<String, [u32; 2]>);

impl std::ops::Deref for ModalityParts {
    type Target = BTreeMap<String, [u32; 2]>;
    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

/// Target-architecture presets (values and sources in the book's presets chapter).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Preset {
    /// ACT: K=100 at 50 Hz, one observation, edge padding + mask, z-score (unbiased std >= 1e-2).
    Act,
    /// Diffusion Policy: K=16 at 10 Hz, two observations, executes 8, its window alignment and
    /// `limits` normalization.
    DiffusionPolicy,
    /// 3D Diffusion Policy: as `diffusion_policy`, point clouds passed through unnormalized.
    Dp3,
    /// High-frequency Diffusion Policy: K=32 at 20 Hz, three observations, zero padding + mask.
    DiffusionPolicyHighfreq,
    /// LeRobot's ACT: K=100 at the dataset rate, indices clamped, MEAN_STD.
    LerobotAct,
    /// LeRobot's Diffusion: horizon 64, two observations, MIN_MAX low-dim, every frame a sample
    /// (its `n_action_steps` 32 is an inference setting that does not shape the dataset).
    LerobotDiffusion,
    /// openpi's pi0: action horizon 50 at the dataset rate, z-score `(x - mean) / (std + 1e-6)`,
    /// statistics over every sample's whole chunk (`stats_population = "windows"`).
    Pi0,
    /// openpi's pi0.5: horizon 50, quantile normalization, windows.
    Pi05,
    /// openpi's pi0-FAST: horizon 32, quantile normalization, windows.
    Pi0Fast,
    /// The name before openpi's models had presets of their own: an alias of `pi05` (quantile
    /// normalization, as openpi normalizes pi0.5 and pi0-FAST; pi0 z-scores: use `pi0`).
    Openpi,
    /// NVIDIA GR00T N1.7: action horizon 16, state and cameras at offset 0, only chunks that fit
    /// in the episode, absolute actions and states; a LeRobot v2.1 dataset (`format =
    /// "parquet"`, `lerobot_version = "v2.1"`) with GR00T's `meta/modality.json` and
    /// `meta/stats.json`, normalized q01/q99 to [-1, 1], clipped.
    Groot,
}

impl Preset {
    pub const ALL: [Preset; 11] = [
        Preset::Act,
        Preset::DiffusionPolicy,
        Preset::Dp3,
        Preset::DiffusionPolicyHighfreq,
        Preset::LerobotAct,
        Preset::LerobotDiffusion,
        Preset::Pi0,
        Preset::Pi05,
        Preset::Pi0Fast,
        Preset::Openpi,
        Preset::Groot,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Preset::Act => "act",
            Preset::DiffusionPolicy => "diffusion_policy",
            Preset::Dp3 => "dp3",
            Preset::DiffusionPolicyHighfreq => "diffusion_policy_highfreq",
            Preset::LerobotAct => "lerobot_act",
            Preset::LerobotDiffusion => "lerobot_diffusion",
            Preset::Pi0 => "pi0",
            Preset::Pi05 => "pi05",
            Preset::Pi0Fast => "pi0_fast",
            Preset::Openpi => "openpi",
            Preset::Groot => "groot",
        }
    }
}

/// Where a sample's action chunk starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Alignment {
    /// Actions start at the current step t (the last observation frame).
    Current,
    /// Diffusion Policy's: one window `[t-(To-1), t-(To-1)+K)` for observations and actions, so
    /// the actions start at the FIRST observation frame.
    DiffusionPolicy,
}

impl Alignment {
    pub fn name(self) -> &'static str {
        match self {
            Alignment::Current => "current",
            Alignment::DiffusionPolicy => "diffusion_policy",
        }
    }
}

/// How an action chunk that runs past either end of its episode is filled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Padding {
    /// Repeat the episode's first/last action (indices clamped to the episode).
    Edge,
    /// Zeros in raw (physical) units, as ACT's original code pads.
    Zero,
    /// Zeros in normalized units, for losses that mask padded steps with `action_is_pad`.
    Mask,
    /// Drop every sample that would need padding (actions past either end, or observation
    /// history before the start).
    Truncate,
}

impl Padding {
    pub fn name(self) -> &'static str {
        match self {
            Padding::Edge => "edge",
            Padding::Zero => "zero",
            Padding::Mask => "mask",
            Padding::Truncate => "truncate",
        }
    }
}

/// Normalization applied to a channel's stored values (and inverted by the loader). Every mode
/// is stored as `y = (x - center) / scale`, optionally clipped to [-1, 1].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum NormalizeMode {
    /// `(x - mean) / max(std, 1e-2)` with the unbiased (ddof = 1) std, as ACT normalizes.
    Zscore,
    /// Maps the 0.1th..99.9th percentile range to [-1, 1], then clips. A dimension whose range is
    /// below 1e-4 maps to 0.
    Minmax,
    /// Diffusion Policy's `limits`: maps [min, max] to [-1, 1]; a dimension whose range is below
    /// 1e-4 gets scale 1 and maps its minimum to 0.
    Limits,
    /// openpi's quantile normalization: `(x - q01) / (q99 - q01 + 1e-6) * 2 - 1`, not clipped.
    Quantile,
    /// openpi's z-score (pi0): `(x - mean) / (std + 1e-6)` with the population std.
    OpenpiZscore,
    /// Diffusion Policy's `robomimic_abs_action_only` normalizer, per 10-wide arm block of
    /// `[pos3, rotation_6d, gripper1]`: the position by range to [-1, 1] (a range below 1e-7
    /// gets scale 1 and offset -min), the rotation and the gripper left as they are.
    DpAbsAction,
    /// LeRobot's MEAN_STD: `(x - mean) / (std + 1e-8)` with the population std.
    LerobotMeanStd,
    /// LeRobot's MIN_MAX: `(x - min) / (max - min + 1e-8) * 2 - 1`.
    LerobotMinMax,
    /// GR00T N1.7's (`use_percentiles`, `clip_outliers`): `(x - q01) / (q99 - q01) * 2 - 1`,
    /// clipped to [-1, 1]; a dimension whose q01 and q99 are close (numpy's `isclose`) maps its
    /// q01 to 0 with scale 1.
    GrootQuantile,
    /// Stored as read.
    None,
}

impl NormalizeMode {
    pub fn name(self) -> &'static str {
        match self {
            NormalizeMode::Zscore => "zscore",
            NormalizeMode::Minmax => "minmax",
            NormalizeMode::Limits => "limits",
            NormalizeMode::Quantile => "quantile",
            NormalizeMode::OpenpiZscore => "openpi_zscore",
            NormalizeMode::DpAbsAction => "dp_abs_action",
            NormalizeMode::LerobotMeanStd => "lerobot_mean_std",
            NormalizeMode::LerobotMinMax => "lerobot_min_max",
            NormalizeMode::GrootQuantile => "groot_quantile",
            NormalizeMode::None => "none",
        }
    }
}

/// `[profiles.<name>.segment]`: cut each episode at natural breakpoints. Each segment becomes one
/// sample whose actions are padded to `max_length` with a mask.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SegmentSpec {
    /// What marks a breakpoint.
    pub method: SegmentMethod,
    /// The channel watched (`action` or `observation.<name>`).
    pub channel: String,
    /// Dimensions of that channel to watch; all when left out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dims: Option<Vec<u32>>,
    /// Trailing moving-average window, in steps, applied before looking for breakpoints.
    #[serde(default = "one")]
    pub smoothing: u32,
    /// Values (or velocities) within ±threshold do not change the sign that is tracked.
    #[serde(default)]
    pub threshold: f64,
    /// Breakpoints closer than this to the previous one are dropped.
    #[serde(default = "one")]
    pub min_length: u32,
    /// Longer segments are split; also the padded length of every sample. Defaults to `chunk`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_length: Option<u32>,
}

fn one() -> u32 {
    1
}

/// Breakpoint detectors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SegmentMethod {
    /// Zero crossings of the velocity (first difference) of the watched dimensions.
    Velocity,
    /// Sign changes of the watched values themselves (a gripper command, a contact flag).
    SignChange,
}

/// `[profiles.<name>.hierarchy]`: coarse chunks of `coarse_seconds`, cut into fine chunks of
/// `chunk` steps. Each sample is one fine chunk with its coarse chunk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct HierarchySpec {
    /// Length of the coarse chunk in seconds (rounded to whole steps at the profile's rate).
    pub coarse_seconds: f64,
}

/// Codebase-specific statistics files.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize, JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum StatsFormat {
    /// ACT's `dataset_stats.pkl` (and `dataset_stats.json`).
    Act,
    /// Diffusion Policy's `LinearNormalizer` parameters (`dp_normalizer.json`, `dp_normalizer.py`).
    DiffusionPolicy,
    /// LeRobot's `meta/stats.json` layout (`lerobot_stats.json`).
    Lerobot,
    /// openpi's `norm_stats.json`.
    Openpi,
    /// robomimic's normalization stats, v0.5 `offset`/`scale` and v0.4 `mean`/`std`
    /// (`robomimic_stats.json`).
    Robomimic,
}

impl StatsFormat {
    pub fn name(self) -> &'static str {
        match self {
            StatsFormat::Act => "act",
            StatsFormat::DiffusionPolicy => "diffusion_policy",
            StatsFormat::Lerobot => "lerobot",
            StatsFormat::Openpi => "openpi",
            StatsFormat::Robomimic => "robomimic",
        }
    }
}

/// Output container formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum OutputFormat {
    /// chunkc's own HDF5 file `data.h5` (see `layout`), read by the generated `loader.py`.
    Hdf5,
    /// A Diffusion Policy replay buffer `data.zarr` (`data/<key>`, `meta/episode_ends`) in
    /// raw units, plus chunkc's window index (`index/train`, `index/val`).
    Zarr,
    /// A LeRobot v3.0 dataset in raw units (`data/chunk-000/file-000.parquet`, `meta/…`), plus
    /// chunkc's window index (`meta/chunkc_index.parquet`).
    Parquet,
    /// ACT's own layout: `episode_<i>.hdf5` files in raw units, plus `dataset_stats.pkl`.
    ActEpisodes,
    /// A robomimic dataset `data.hdf5` in raw units (`data/demo_<i>`, `mask/train`, `mask/valid`).
    RobomimicHdf5,
}

impl OutputFormat {
    pub const ALL: [OutputFormat; 5] = [
        OutputFormat::Hdf5,
        OutputFormat::Zarr,
        OutputFormat::Parquet,
        OutputFormat::ActEpisodes,
        OutputFormat::RobomimicHdf5,
    ];

    pub fn name(self) -> &'static str {
        match self {
            OutputFormat::Hdf5 => "hdf5",
            OutputFormat::Zarr => "zarr",
            OutputFormat::Parquet => "parquet",
            OutputFormat::ActEpisodes => "act_episodes",
            OutputFormat::RobomimicHdf5 => "robomimic_hdf5",
        }
    }

    /// The format's data container, relative to the profile directory: one copy of the names
    /// that the sinks write, `meta.json` names and `chunkc plan` lists.
    pub const fn files(self) -> DataFiles {
        let (data, planned) = match self {
            OutputFormat::Hdf5 => ("data.h5", "data.h5"),
            OutputFormat::Zarr => ("data.zarr", "data.zarr/"),
            OutputFormat::Parquet => ("data/chunk-000/file-000.parquet", "data/"),
            OutputFormat::ActEpisodes => ("episode_0.hdf5", "episode_*.hdf5"),
            OutputFormat::RobomimicHdf5 => ("data.hdf5", "data.hdf5"),
        };
        DataFiles { data, planned }
    }

    /// Whether the output is a codebase's own layout (raw values, no chunkc loader).
    pub fn is_native_export(self) -> bool {
        matches!(
            self,
            OutputFormat::ActEpisodes | OutputFormat::RobomimicHdf5
        )
    }
}

/// Where a format's data lives in a profile directory ([`OutputFormat::files`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DataFiles {
    /// The file (or directory) written first and named by `meta.json` as the data: the whole
    /// container, or its first file (ACT's `episode_0.hdf5`, LeRobot's first parquet file).
    pub data: &'static str,
    /// What `chunkc plan` lists: the container, a directory (`/`-terminated) or a glob.
    pub planned: &'static str,
}

/// How chunkc's HDF5 file stores the chunks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Layout {
    /// Per-step arrays once plus the window index; a chunk is computed on read.
    Index,
    /// Also `/chunks/<channel>` (N, K, ...) and `/chunks/<channel>_is_pad` (N, K) for every
    /// low-dimensional channel (observations: (N, obs_history, ...)).
    Materialized,
    /// Also an HDF5 virtual dataset `/chunks/action` (N, K, A) whose rows map onto stored
    /// rows, and `/chunks/action_is_pad`.
    Virtual,
}

impl Layout {
    pub fn name(self) -> &'static str {
        match self {
            Layout::Index => "index",
            Layout::Materialized => "materialized",
            Layout::Virtual => "virtual",
        }
    }
}

/// Compression codecs (which ones a format accepts: see `compression`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Compression {
    /// Stored uncompressed.
    None,
    /// Deflate (HDF5's gzip filter).
    Gzip,
    /// LZF (HDF5; h5py ships the filter).
    Lzf,
    /// Blosc with LZ4 (Zarr), no shuffle: Diffusion Policy's default.
    Lz4,
    /// Blosc with Zstandard and bit-shuffle (Zarr: Diffusion Policy's "disk" setting), or
    /// Parquet's zstd.
    Zstd,
}

impl Compression {
    pub fn name(self) -> &'static str {
        match self {
            Compression::None => "none",
            Compression::Gzip => "gzip",
            Compression::Lzf => "lzf",
            Compression::Lz4 => "lz4",
            Compression::Zstd => "zstd",
        }
    }

    /// The codecs `format` accepts, its default first.
    pub fn allowed(format: OutputFormat) -> &'static [Compression] {
        match format {
            OutputFormat::Hdf5 => &[Compression::None, Compression::Gzip, Compression::Lzf],
            OutputFormat::Zarr => &[Compression::Lz4, Compression::Zstd, Compression::None],
            OutputFormat::Parquet => &[Compression::Zstd, Compression::None],
            OutputFormat::ActEpisodes | OutputFormat::RobomimicHdf5 => &[Compression::None],
        }
    }
}

/// How `format = "parquet"` stores image frames (see `image_encoding`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ImageEncoding {
    /// A PNG per frame in the parquet rows (`dtype: "image"`).
    Png,
    /// One mp4 video per camera (`dtype: "video"`).
    Video,
}

impl ImageEncoding {
    pub fn name(self) -> &'static str {
        match self {
            ImageEncoding::Png => "png",
            ImageEncoding::Video => "video",
        }
    }
}

/// The LeRobot dataset layout `format = "parquet"` writes (see `lerobot_version`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
pub enum LerobotVersion {
    /// One parquet file and one mp4 per camera per episode, `meta/*.jsonl` (LeRobot <= 0.3.3,
    /// openpi, GR00T).
    #[serde(rename = "v2.1")]
    V21,
    /// Many episodes per file, `meta/episodes/*.parquet` (LeRobot >= 0.4).
    #[default]
    #[serde(rename = "v3.0")]
    V30,
}

impl LerobotVersion {
    /// As written in the spec and in `meta/info.json`'s `codebase_version`.
    pub fn name(self) -> &'static str {
        match self {
            LerobotVersion::V21 => "v2.1",
            LerobotVersion::V30 => "v3.0",
        }
    }
}

/// The video encoder of `image_encoding = "video"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum VideoCodec {
    /// AV1 with SVT-AV1 (LeRobot's default encoder).
    Libsvtav1,
    /// H.264 with x264.
    Libx264,
    /// MPEG-4 Part 2 with FFmpeg's own encoder. Not a value of `video_codec`: chunkc encodes a
    /// LeRobot camera too small for SVT-AV1 with it where it has no x264 (the wheel).
    #[serde(skip)]
    Mpeg4,
}

impl VideoCodec {
    /// FFmpeg's name of the encoder.
    pub fn name(self) -> &'static str {
        match self {
            VideoCodec::Libsvtav1 => "libsvtav1",
            VideoCodec::Libx264 => "libx264",
            VideoCodec::Mpeg4 => "mpeg4",
        }
    }

    /// The largest constant rate factor the encoder takes (MPEG-4's fixed quantizer).
    pub fn max_crf(self) -> u32 {
        match self {
            VideoCodec::Libsvtav1 => 63,
            VideoCodec::Libx264 => 51,
            VideoCodec::Mpeg4 => 31,
        }
    }
}
