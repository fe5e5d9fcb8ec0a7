//! The spec as written: serde + schemars types and nothing else.
//!
//! These types mirror the TOML one to one. Every optional value stays optional here; presets and
//! defaults are applied later by `spec::preset`, which produces the fully explicit
//! [`crate::spec::Profile`]. Keep this file free of engine dependencies: the JSON Schema and the
//! book's spec reference are generated from it.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A chunkc build spec (`chunkc.toml`): one source, one split, one output directory, and one
/// profile per target architecture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    /// Spec format version. Must be 1.
    pub version: u32,
    /// The raw demonstration dataset to read.
    pub source: SourceSpec,
    /// How episodes are divided into training and validation sets.
    #[serde(default)]
    pub split: SplitSpec,
    /// Where the outputs go.
    pub output: OutputSpec,
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
    /// Channel mapping, `our name = "source key"`. Exactly one channel must be called `action`;
    /// every other channel is an observation and must be named `observation.<name>`.
    pub channels: BTreeMap<String, String>,
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
}

impl SourceFormat {
    pub fn name(self) -> &'static str {
        match self {
            SourceFormat::DiffusionPolicyZarr => "diffusion_policy_zarr",
            SourceFormat::AlohaHdf5 => "aloha_hdf5",
            SourceFormat::RobomimicHdf5 => "robomimic_hdf5",
            SourceFormat::Lerobot => "lerobot",
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
}

fn default_val_fraction() -> f64 {
    0.1
}

impl Default for SplitSpec {
    fn default() -> Self {
        SplitSpec {
            val_fraction: default_val_fraction(),
            seed: 0,
        }
    }
}

/// `[output]`: where the built datasets are written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Output directory, relative to the spec file. Each profile writes a subdirectory.
    pub dir: String,
}

/// `[profiles.<name>]`: one training-ready dataset. Every value left out comes from the preset
/// (or the defaults when there is no preset).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ProfileSpec {
    /// Start from a target architecture's conventions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<Preset>,
    /// Control rate in Hz. Must divide the source rate by an integer (every n-th step is kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fps: Option<f64>,
    /// Action chunk length K, in steps at the profile's rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chunk: Option<u32>,
    /// Number of observation frames per sample, ending at the chunk's first step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub obs_history: Option<u32>,
    /// What fills an action chunk that runs past the end of its episode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub padding: Option<Padding>,
    /// Steps between the starts of consecutive samples within an episode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stride: Option<u32>,
    /// Normalization per channel; channels left out get the preset's mode for their kind.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normalize: Option<BTreeMap<String, NormalizeMode>>,
    /// Output container format.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub format: Option<OutputFormat>,
}

/// Target-architecture presets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Preset {
    /// ACT: K=100 at 50 Hz, one observation, edge padding, z-score.
    Act,
    /// Diffusion Policy: K=16 at 10 Hz, two observations, edge padding, percentile min-max.
    DiffusionPolicy,
}

impl Preset {
    pub fn name(self) -> &'static str {
        match self {
            Preset::Act => "act",
            Preset::DiffusionPolicy => "diffusion_policy",
        }
    }
}

/// How an action chunk that runs past its episode's last step is filled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Padding {
    /// Repeat the episode's last action.
    Edge,
    /// Zeros in raw (physical) units, as ACT's original code pads.
    Zero,
    /// Zeros in normalized units, for losses that mask padded steps with `action_is_pad`.
    Mask,
    /// Drop every sample that would need padding (actions past the end, or observation history
    /// before the start).
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

/// Normalization applied to a channel's stored values (and inverted by the loader).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum NormalizeMode {
    /// `(x - mean) / max(std, 1e-2)` with the unbiased (ddof = 1) std, as ACT normalizes.
    Zscore,
    /// Maps the 0.1th..99.9th percentile range to [-1, 1], then clips. A dimension whose range is
    /// below 1e-4 maps to 0.
    Minmax,
    /// Stored as read.
    None,
}

impl NormalizeMode {
    pub fn name(self) -> &'static str {
        match self {
            NormalizeMode::Zscore => "zscore",
            NormalizeMode::Minmax => "minmax",
            NormalizeMode::None => "none",
        }
    }
}

/// Output container formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum OutputFormat {
    Hdf5,
    Zarr,
    Parquet,
}

impl OutputFormat {
    pub fn name(self) -> &'static str {
        match self {
            OutputFormat::Hdf5 => "hdf5",
            OutputFormat::Zarr => "zarr",
            OutputFormat::Parquet => "parquet",
        }
    }
}
