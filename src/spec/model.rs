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
    /// Only these source episode ids, in the source's order (all when left out).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub episodes: Option<Vec<u64>>,
    /// Channel mapping, `our name = "source key"` or `our name = { key = …, columns = […] }` /
    /// `{ concat = […] }`. Exactly one channel must be called `action`; every other channel is
    /// an observation and must be named `observation.<name>`.
    pub channels: BTreeMap<String, ChannelSpec>,
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
