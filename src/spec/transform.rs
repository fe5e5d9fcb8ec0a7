//! `[[profiles.<name>.transforms]]` as written: the action representations the codebases'
//! headline setups train on (rotation conversions, openpi's delta actions, UMI's relative
//! poses), and `stats_population`. Checked against the source's channels by the plan.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub use crate::rotation::{Layout6d, RotationKind};

/// One transform of a channel, applied in list order before statistics and normalization.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "op", rename_all = "snake_case")]
pub enum TransformSpec {
    /// Converts a slice of a channel's last axis from one rotation representation to another
    /// (the channel's width changes: axis-angle 3 -> rotation_6d 6). Per step.
    Rotation(RotationSpec),
    /// openpi's `DeltaActions`: `x[t+k, d] - reference[t, d]` where the mask is true, with `t`
    /// the sample's current step. Per window: applied by the loader on read.
    Delta(DeltaSpec),
    /// UMI's `relative` pose: `inv(T_ref[t]) @ T[t+k]` for a position + rotation slice, then
    /// position + the rotation in `to`. Per window: applied by the loader on read.
    RelativePose(RelativePoseSpec),
}

/// `op = "rotation"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RotationSpec {
    /// The channel (`action` or `observation.<name>`).
    pub channel: String,
    /// `[start, end)` of the channel's last axis, as the transforms before this one leave it.
    pub dims: [usize; 2],
    /// The stored representation; its width must be the slice's.
    pub from: RotationKind,
    /// The representation to train on (not `euler`).
    pub to: RotationKind,
    /// Euler axis sequence as scipy names it (`"xyz"` extrinsic, `"XYZ"` intrinsic); required
    /// with `euler`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub convention: Option<String>,
    /// The 6D representation's rows (default, pytorch3d) or columns (Zhou et al.).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layout: Option<Layout6d>,
    /// The mixture's sources (`[sources.<name>]`) this transform applies to, for a transform
    /// that fits one robot only (its mask, dims or reference); every source when left out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sources: Option<Vec<String>>,
}

/// `op = "delta"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DeltaSpec {
    /// The channel made relative (usually `action`).
    pub channel: String,
    /// The channel whose value at the current step is subtracted (usually
    /// `observation.state`), read raw.
    pub reference: String,
    /// openpi's `make_bool_mask` notation: `6` is six dimensions made relative, `-1` one left
    /// as it is; dimensions past the mask are left as they are.
    pub mask: Vec<i64>,
    /// The mixture's sources (`[sources.<name>]`) this transform applies to, for a transform
    /// that fits one robot only (its mask, dims or reference); every source when left out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sources: Option<Vec<String>>,
}

/// `op = "relative_pose"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RelativePoseSpec {
    /// The channel holding the poses (an action, or an observation whose history is made
    /// relative too).
    pub channel: String,
    /// `[start, end)`: position (3) then the rotation in `rotation`.
    pub dims: [usize; 2],
    /// How the slice stores its rotation.
    pub rotation: RotationKind,
    /// The channel holding the current pose, read raw at the sample's current step.
    pub reference: String,
    /// `[start, end)` of the reference's position + rotation.
    pub reference_dims: [usize; 2],
    /// How the reference stores its rotation (default: `rotation`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_rotation: Option<RotationKind>,
    /// The output rotation (default: `rotation`); UMI trains on `rotation_6d`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub to: Option<RotationKind>,
    /// Euler axis sequence (scipy's), required when a rotation is `euler`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub convention: Option<String>,
    /// The 6D representation's rows (default) or columns.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layout: Option<Layout6d>,
    /// The mixture's sources (`[sources.<name>]`) this transform applies to, for a transform
    /// that fits one robot only (its mask, dims or reference); every source when left out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sources: Option<Vec<String>>,
}

impl TransformSpec {
    pub fn op(&self) -> &'static str {
        match self {
            TransformSpec::Rotation(_) => "rotation",
            TransformSpec::Delta(_) => "delta",
            TransformSpec::RelativePose(_) => "relative_pose",
        }
    }

    pub fn channel(&self) -> &str {
        match self {
            TransformSpec::Rotation(r) => &r.channel,
            TransformSpec::Delta(d) => &d.channel,
            TransformSpec::RelativePose(r) => &r.channel,
        }
    }

    /// Whether the transform needs the sample's current step (the loader applies it on read).
    /// `sources = [...]`, when given.
    pub fn sources(&self) -> Option<&[String]> {
        match self {
            TransformSpec::Rotation(r) => r.sources.as_deref(),
            TransformSpec::Delta(d) => d.sources.as_deref(),
            TransformSpec::RelativePose(r) => r.sources.as_deref(),
        }
    }

    pub fn per_window(&self) -> bool {
        !matches!(self, TransformSpec::Rotation(_))
    }
}

/// Which values a channel's statistics cover.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum StatsPopulation {
    /// Every training step once.
    #[default]
    Frames,
    /// Every training sample's whole action chunk (edge rows repeated at the episode end, as
    /// LeRobot's clamping gives them) and observation history, as openpi's `compute_norm_stats`
    /// counts them: a step counts about K times.
    Windows,
}

impl StatsPopulation {
    pub fn name(self) -> &'static str {
        match self {
            StatsPopulation::Frames => "frames",
            StatsPopulation::Windows => "windows",
        }
    }
}
