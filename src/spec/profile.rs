//! A profile with every value decided ([`Profile`]): what preset expansion ([`super::preset`])
//! gives every later stage, which never looks at presets again.

use std::collections::BTreeMap;

use serde::Serialize;

use super::camera::Camera;
use super::model::{
    Alignment, Compression, HierarchySpec, ImageCompression, ImageEncoding, Layout, LerobotVersion,
    NormalizeMode, OutputFormat, Padding, Preset, SegmentSpec, StatsFormat, StatsPopulation,
    TransformSpec, VideoCodec,
};
use super::video_settings::{
    StreamCopy, VideoSettings, DEFAULT_VIDEO_CRF, DEFAULT_VIDEO_GOP, STORAGE_VIDEO,
};

/// A profile with every value decided. Later stages never look at presets again.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Profile {
    pub name: String,
    pub preset: Option<Preset>,
    pub extends: Option<String>,
    /// Control rate in Hz; `None` means "the source's rate".
    pub fps: Option<f64>,
    pub chunk: u32,
    pub obs_history: u32,
    /// Steps executed per chunk; bounds the padding after the episode end to `executes - 1`.
    pub executes: Option<u32>,
    /// The gymnasium id of the simulator `rollout.py` runs the policy in.
    pub env: Option<String>,
    pub alignment: Alignment,
    pub padding: Padding,
    pub stride: u32,
    /// Mode for low-dimensional channels with one value vector per step, when not in `normalize`.
    pub normalize_lowdim: NormalizeMode,
    /// Mode for low-dimensional channels with a matrix per step (point clouds, keypoints).
    pub normalize_multidim: NormalizeMode,
    /// Explicit per-channel modes from the spec (merged along the `extends` chain).
    pub normalize: BTreeMap<String, NormalizeMode>,
    pub format: OutputFormat,
    /// Array names of the native exports per channel (merged along the `extends` chain); see
    /// `spec::export_keys`.
    pub export_keys: BTreeMap<String, String>,
    pub layout: Layout,
    pub compression: Compression,
    /// `None`: the codec's default level.
    pub compression_level: Option<u32>,
    /// Image frames of the HDF5 layouts (other formats have their own conventions).
    pub image_compression: ImageCompression,
    /// `None`: gzip's default level for frames (1).
    pub image_compression_level: Option<u32>,
    /// `None`: [`super::DEFAULT_IMAGE_QUALITY`] (unset stays out of the serialized profile).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub image_quality: Option<u32>,
    /// Image frames of `format = "parquet"` as written (`None`: PNG); see [`Profile::video`].
    /// Unset keys stay `None` and out of the serialized profile, so that the fingerprint of a
    /// profile that does not use them is the one it had before they existed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub image_encoding: Option<ImageEncoding>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub video_codec: Option<VideoCodec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub video_crf: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub video_gop: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub video_copy: Option<bool>,
    pub zarr_version: u32,
    /// The LeRobot layout `format = "parquet"` writes: the nearest profile of the `extends`
    /// chain that sets `lerobot_version`, else the preset's (`groot`: v2.1), else v3.0. Left out
    /// of the serialized profile when it is v3.0, so that those fingerprints stay.
    #[serde(skip_serializing_if = "is_v30")]
    pub lerobot_version: LerobotVersion,
    /// GR00T's parts of each low-dimensional channel as written (`[start, end)` by part name),
    /// merged along the `extends` chain channel by channel; empty (and left out of the
    /// serialized profile) when none is given.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub modality: BTreeMap<String, super::model::ModalityParts>,
    /// The action parts GR00T makes relative (the nearest list along the `extends` chain).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub relative_actions: Vec<String>,
    pub stats_formats: Vec<StatsFormat>,
    pub segment: Option<SegmentSpec>,
    pub hierarchy: Option<HierarchySpec>,
    /// The action representations, in order (the nearest list along the `extends` chain).
    /// Empty, and left out of the serialized profile (fingerprints stay), when there are none.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub transforms: Vec<TransformSpec>,
    /// Which values the statistics cover: as set, else the preset's, else `windows` when a
    /// transform needs the sample's current step, else `frames` (left out when `frames`).
    #[serde(skip_serializing_if = "is_frames")]
    pub stats_population: StatsPopulation,
    /// Diffusion Policy's `abs_action` (expanded by the plan, which knows the action's width).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub abs_action: bool,
    /// The stored size of each resized camera, by channel (merged along the `extends` chain).
    /// Empty (and left out of the serialized profile, so that fingerprints stay) when no camera
    /// is resized.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub cameras: BTreeMap<String, Camera>,
    /// Where each value came from: `profiles.<name>`, `preset <name>` or `default`.
    pub origins: BTreeMap<&'static str, String>,
}

fn is_frames(p: &StatsPopulation) -> bool {
    *p == StatsPopulation::Frames
}

fn is_v30(v: &LerobotVersion) -> bool {
    *v == LerobotVersion::V30
}

impl Profile {
    /// Whether the profile writes a LeRobot v2.1 dataset (`format = "parquet"`,
    /// `lerobot_version = "v2.1"`).
    pub fn writes_lerobot_v21(&self) -> bool {
        self.format == OutputFormat::Parquet && self.lerobot_version == LerobotVersion::V21
    }

    /// Whether the profile writes GR00T's dataset (`preset = "groot"`, nearest in the chain).
    pub fn is_groot(&self) -> bool {
        self.preset == Some(Preset::Groot)
    }

    /// The encoder settings when frames are stored as video, else `None`: parquet's
    /// `image_encoding = "video"` (LeRobot's defaults) or hdf5's `image_compression = "video"`
    /// ([`STORAGE_VIDEO`]'s).
    pub fn video(&self) -> Option<VideoSettings> {
        let defaults = match self.format {
            OutputFormat::Parquet if self.image_encoding == Some(ImageEncoding::Video) => {
                VideoSettings {
                    codec: VideoCodec::Libsvtav1,
                    crf: DEFAULT_VIDEO_CRF,
                    gop: DEFAULT_VIDEO_GOP,
                    copy: StreamCopy::Never,
                    copy_gop: None,
                    closed_gop: true,
                }
            }
            OutputFormat::Hdf5 if self.image_compression == ImageCompression::Video => {
                STORAGE_VIDEO
            }
            _ => return None,
        };
        Some(VideoSettings {
            codec: self.video_codec.unwrap_or(defaults.codec),
            crf: self.video_crf.unwrap_or(defaults.crf),
            gop: self.video_gop.unwrap_or(defaults.gop),
            copy: match (defaults.copy, self.video_copy, self.video_codec) {
                (StreamCopy::Never, ..) | (_, Some(false), _) => StreamCopy::Never,
                (_, _, Some(_)) => StreamCopy::SameCodec,
                (copy, ..) => copy,
            },
            copy_gop: self.video_gop,
            closed_gop: defaults.closed_gop,
        })
    }
}
