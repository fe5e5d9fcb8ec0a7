// Long file: each preset's values are a table of defaults; the expansion walks them key by key.
//! Preset expansion: turns a [`ProfileSpec`] as written (and the chain of profiles it `extends`)
//! into a fully explicit [`Profile`], remembering where every value came from.
//!
//! Precedence, highest first: the profile's own keys, the profiles it extends (nearest first),
//! the preset (the nearest one in that chain), the defaults. The values and their sources are
//! documented in the book's presets chapter and in `TARGETS.md`.

use std::collections::BTreeMap;

use serde::Serialize;

use super::camera::{self, Camera};
use super::model::{
    Alignment, Compression, HierarchySpec, ImageCompression, ImageEncoding, Layout, NormalizeMode,
    OutputFormat, Padding, Preset, ProfileSpec, SegmentSpec, StatsFormat, StatsPopulation,
    TransformSpec, VideoCodec,
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

/// The encoder settings of a profile that stores frames as video (`image_encoding = "video"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VideoSettings {
    pub codec: VideoCodec,
    pub crf: u32,
    /// The keyframe interval the encoder writes.
    pub gop: u32,
    pub copy: StreamCopy,
    /// The longest keyframe interval a copied stream may have: `video_gop` when the spec sets
    /// it, else none (a copy keeps the source's keyframes: refusing a source whose keyframes
    /// are 12 apart because the encoder would write 8 re-encoded every episode of a real set).
    pub copy_gop: Option<u32>,
    /// Every `gop`-th frame a keyframe (closed GOPs), as in LeRobot's own files: libavcodec's
    /// SVT-AV1 wrapper otherwise asks for open GOPs, whose intra frames are not keyframes, and
    /// a LeRobot reader seeking to a frame of a file shared by every episode would decode from
    /// its first frame. On for every stream chunkc encodes: libavcodec's x264 wrapper, too, asks
    /// for open GOPs unless told, and a reader that starts at an open GOP's keyframe gets
    /// errors (and broken frames) for the frames shown before it, which refer to the GOP before.
    pub closed_gop: bool,
}

/// Which source streams a video storage copies packet for packet instead of encoding
/// (`video_copy`; the other conditions are the sink's: same rate and size, whole GOPs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StreamCopy {
    /// Always encode: parquet's LeRobot videos (one file of every episode), or `video_copy =
    /// false`.
    Never,
    /// A stream of any codec (hdf5, no `video_codec` given: the source's codec is kept).
    AnyCodec,
    /// Only a stream in the codec of `video_codec`, which the spec names.
    SameCodec,
}

/// LeRobot's `encode_video_frames` defaults (`g=2`, `crf=30`).
pub const DEFAULT_VIDEO_CRF: u32 = 30;
pub const DEFAULT_VIDEO_GOP: u32 = 2;

/// Whether this chunkc's FFmpeg has x264. The wheel's does not (`static-ffmpeg`: an LGPL FFmpeg
/// linked into the binary, with SVT-AV1 as its only encoder; x264 is GPL); a developer build links
/// the system FFmpeg, which has it (Debian's). A spec that names `libx264` in a build without it
/// is refused at `video_codec`.
pub const HAS_X264: bool = !cfg!(feature = "static-ffmpeg");

/// The encoder of hdf5's `image_compression = "video"` when the spec names none: H.264 (about
/// twice as fast to decode on a data-loader CPU as AV1) at x264's own default quality, with a
/// keyframe every 8 frames (closed GOPs, each a random-access point): a random frame decodes at
/// most 8 (4.5 on average). Without x264 ([`HAS_X264`]), SVT-AV1 at LeRobot's quality, with the
/// same keyframes.
pub const STORAGE_VIDEO: VideoSettings = VideoSettings {
    codec: if HAS_X264 {
        VideoCodec::Libx264
    } else {
        VideoCodec::Libsvtav1
    },
    crf: if HAS_X264 { 23 } else { DEFAULT_VIDEO_CRF },
    gop: 8,
    copy: StreamCopy::AnyCodec,
    copy_gop: None,
    closed_gop: true,
};

impl Profile {
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

/// The values a preset supplies (see TARGETS.md, "Default chunk parameters").
struct PresetValues {
    fps: Option<f64>,
    chunk: Option<u32>,
    obs_history: u32,
    executes: Option<u32>,
    alignment: Alignment,
    padding: Padding,
    normalize_lowdim: NormalizeMode,
    normalize_multidim: NormalizeMode,
    stats_formats: &'static [StatsFormat],
    stats_population: Option<StatsPopulation>,
}

// Long function: one table of values per preset, each with where it comes from.
fn preset_values(preset: Preset) -> PresetValues {
    use NormalizeMode as N;
    let base = PresetValues {
        fps: None,
        chunk: None,
        obs_history: 1,
        executes: None,
        alignment: Alignment::Current,
        padding: Padding::Edge,
        normalize_lowdim: N::None,
        normalize_multidim: N::None,
        stats_formats: &[],
        stats_population: None,
    };
    // openpi: the action horizon at the dataset rate, statistics over every sample's chunk
    // (`compute_norm_stats`), quantiles for every model but pi0 (`use_quantile_norm`).
    let openpi = PresetValues {
        chunk: Some(50),
        normalize_lowdim: N::Quantile,
        normalize_multidim: N::Quantile,
        stats_formats: &[StatsFormat::Openpi],
        stats_population: Some(StatsPopulation::Windows),
        ..base
    };
    let dp = PresetValues {
        fps: Some(10.0),
        chunk: Some(16),
        obs_history: 2,
        executes: Some(8),
        alignment: Alignment::DiffusionPolicy,
        normalize_lowdim: N::Limits,
        normalize_multidim: N::Limits,
        stats_formats: &[StatsFormat::DiffusionPolicy],
        ..base
    };
    match preset {
        // ACT: K=100 at 50 Hz, the current observation only, z-score (get_norm_stats).
        Preset::Act => PresetValues {
            fps: Some(50.0),
            chunk: Some(100),
            normalize_lowdim: N::Zscore,
            normalize_multidim: N::Zscore,
            stats_formats: &[StatsFormat::Act],
            ..base
        },
        // Diffusion Policy: horizon 16, n_obs_steps 2, n_action_steps 8, LinearNormalizer limits.
        Preset::DiffusionPolicy => dp,
        // 3D Diffusion Policy: the same, with point clouds (matrix-valued channels) unnormalized.
        Preset::Dp3 => PresetValues {
            normalize_multidim: N::None,
            ..dp
        },
        // High-frequency Diffusion Policy: K=32 at 20 Hz, three observations, zero + mask.
        Preset::DiffusionPolicyHighfreq => PresetValues {
            fps: Some(20.0),
            chunk: Some(32),
            obs_history: 3,
            executes: Some(16),
            padding: Padding::Zero,
            ..dp
        },
        // LeRobot ACT: chunk_size 100, n_obs_steps 1, MEAN_STD, every frame a sample.
        Preset::LerobotAct => PresetValues {
            chunk: Some(100),
            normalize_lowdim: N::LerobotMeanStd,
            normalize_multidim: N::LerobotMeanStd,
            stats_formats: &[StatsFormat::Lerobot],
            ..base
        },
        // LeRobot Diffusion: horizon 64, n_obs_steps 2, actions from the first observation
        // frame (delta indices start at 1 - n_obs_steps), MIN_MAX, every frame a sample.
        Preset::LerobotDiffusion => PresetValues {
            chunk: Some(64),
            obs_history: 2,
            alignment: Alignment::DiffusionPolicy,
            normalize_lowdim: N::LerobotMinMax,
            normalize_multidim: N::LerobotMinMax,
            stats_formats: &[StatsFormat::Lerobot],
            ..base
        },
        // pi0 (Pi0Config: action_horizon 50): z-score with openpi's epsilon.
        Preset::Pi0 => PresetValues {
            normalize_lowdim: N::OpenpiZscore,
            normalize_multidim: N::OpenpiZscore,
            ..openpi
        },
        // pi0.5 (Pi0Config(pi05=True): action_horizon 50), and `openpi`, its alias.
        Preset::Pi05 | Preset::Openpi => openpi,
        // pi0-FAST (Pi0FASTConfig: action_horizon 32).
        Preset::Pi0Fast => PresetValues {
            chunk: Some(32),
            ..openpi
        },
    }
}

/// Why a profile cannot be expanded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ExpandError {
    /// A value with no default that neither the chain nor the preset gives.
    Missing(&'static str),
    /// `extends` names a profile that does not exist.
    UnknownParent(String),
    /// `extends` goes round in a circle (the names in order).
    Cycle(Vec<String>),
}

/// The profile and the profiles it extends, nearest first.
fn chain<'a>(
    name: &'a str,
    profiles: &'a BTreeMap<String, ProfileSpec>,
) -> Result<Vec<(&'a str, &'a ProfileSpec)>, ExpandError> {
    let mut out: Vec<(&str, &ProfileSpec)> = Vec::new();
    let mut current = name;
    loop {
        if out.iter().any(|(n, _)| *n == current) {
            let mut names: Vec<String> = out.iter().map(|(n, _)| n.to_string()).collect();
            names.push(current.to_string());
            return Err(ExpandError::Cycle(names));
        }
        let spec = profiles
            .get(current)
            .ok_or_else(|| ExpandError::UnknownParent(current.to_string()))?;
        out.push((current, spec));
        match &spec.extends {
            Some(parent) => current = parent,
            None => return Ok(out),
        }
    }
}

/// Expands the profile `name` of `profiles`.
// Long function: one field per profile key, resolved in a fixed order: long, not deep.
pub fn expand(
    name: &str,
    profiles: &BTreeMap<String, ProfileSpec>,
) -> Result<Profile, ExpandError> {
    let chain = chain(name, profiles)?;
    let mut origins = BTreeMap::new();

    // The nearest profile in the chain that sets a key wins.
    macro_rules! pick {
        ($field:ident) => {{
            let found = chain
                .iter()
                .find_map(|(n, p)| p.$field.clone().map(|v| (v, format!("profiles.{n}"))));
            if let Some((_, from)) = &found {
                origins.insert(stringify!($field), from.clone());
            }
            found.map(|(v, _)| v)
        }};
    }

    let preset = pick!(preset);
    let from_preset = preset.map(|p| format!("preset {}", p.name()));
    let base = preset.map(preset_values);

    // A value from the chain, else from the preset, else a default.
    macro_rules! resolve {
        ($field:ident, $preset_value:expr, $default:expr, $wrap:expr) => {{
            match pick!($field) {
                Some(v) => $wrap(v),
                None => match base.as_ref().and_then($preset_value) {
                    Some(v) => {
                        origins.insert(stringify!($field), from_preset.clone().unwrap());
                        v
                    }
                    None => {
                        origins.insert(stringify!($field), "default".to_string());
                        $default
                    }
                },
            }
        }};
    }

    let fps = resolve!(fps, |b: &PresetValues| b.fps.map(Some), None, Some);
    let chunk = match resolve!(chunk, |b: &PresetValues| b.chunk.map(Some), None, Some) {
        Some(c) => c,
        None => return Err(ExpandError::Missing("chunk")),
    };
    let obs_history = resolve!(
        obs_history,
        |b: &PresetValues| Some(b.obs_history),
        1,
        std::convert::identity
    );
    let executes = resolve!(
        executes,
        |b: &PresetValues| b.executes.map(Some),
        None,
        Some
    );
    let env = pick!(env);
    let alignment = resolve!(
        alignment,
        |b: &PresetValues| Some(b.alignment),
        Alignment::Current,
        std::convert::identity
    );
    let padding = resolve!(
        padding,
        |b: &PresetValues| Some(b.padding),
        Padding::Edge,
        std::convert::identity
    );
    let stride = resolve!(stride, |_: &PresetValues| None, 1, std::convert::identity);
    let format = resolve!(
        format,
        |_: &PresetValues| None,
        OutputFormat::Hdf5,
        std::convert::identity
    );
    let layout = resolve!(
        layout,
        |_: &PresetValues| None,
        Layout::Index,
        std::convert::identity
    );
    let compression = resolve!(
        compression,
        |_: &PresetValues| None,
        Compression::allowed(format)[0],
        std::convert::identity
    );
    let compression_level = resolve!(compression_level, |_: &PresetValues| None, None, Some);
    let image_compression = resolve!(
        image_compression,
        |_: &PresetValues| None,
        ImageCompression::None,
        std::convert::identity
    );
    let image_compression_level =
        resolve!(image_compression_level, |_: &PresetValues| None, None, Some);
    let image_quality = pick!(image_quality);
    let image_encoding = pick!(image_encoding);
    let video_codec = pick!(video_codec);
    let video_crf = pick!(video_crf);
    let video_gop = pick!(video_gop);
    let video_copy = pick!(video_copy);
    let zarr_version = resolve!(
        zarr_version,
        |_: &PresetValues| None,
        2,
        std::convert::identity
    );
    let stats_formats = resolve!(
        stats_formats,
        |b: &PresetValues| Some(b.stats_formats.to_vec()),
        Vec::new(),
        std::convert::identity
    );
    // A native export carries its codebase's statistics file.
    let mut stats_formats = stats_formats;
    if format == OutputFormat::ActEpisodes && !stats_formats.contains(&StatsFormat::Act) {
        stats_formats.push(StatsFormat::Act);
        stats_formats.sort();
    }
    let transforms = pick!(transforms).unwrap_or_default();
    let abs_action = pick!(abs_action).unwrap_or(false);
    let windowed = transforms.iter().any(TransformSpec::per_window);
    let stats_population = resolve!(
        stats_population,
        |b: &PresetValues| b.stats_population,
        if windowed {
            StatsPopulation::Windows
        } else {
            StatsPopulation::Frames
        },
        std::convert::identity
    );
    let segment = pick!(segment);
    let hierarchy = pick!(hierarchy);
    let extends = profiles[name].extends.clone();

    // Per-channel modes merge along the chain: farthest first, so nearer profiles override.
    let mut normalize = BTreeMap::new();
    for (_, p) in chain.iter().rev() {
        if let Some(map) = &p.normalize {
            normalize.extend(map.iter().map(|(k, v)| (k.clone(), *v)));
        }
    }
    let mut export_keys = BTreeMap::new();
    for (_, p) in chain.iter().rev() {
        if let Some(map) = &p.export_keys {
            export_keys.extend(map.iter().map(|(k, v)| (k.clone(), v.clone())));
        }
    }
    let cameras = camera::merged(chain.iter().map(|(_, p)| &p.cameras));
    let (normalize_lowdim, normalize_multidim) = base
        .as_ref()
        .map(|b| (b.normalize_lowdim, b.normalize_multidim))
        .unwrap_or((NormalizeMode::None, NormalizeMode::None));
    origins.insert(
        "normalize",
        from_preset.clone().unwrap_or_else(|| "default".into()),
    );

    Ok(Profile {
        name: name.to_string(),
        preset,
        extends,
        fps,
        chunk,
        obs_history,
        executes,
        env,
        alignment,
        padding,
        stride,
        normalize_lowdim,
        normalize_multidim,
        normalize,
        format,
        export_keys,
        layout,
        compression,
        compression_level,
        image_compression,
        image_compression_level,
        image_quality,
        image_encoding,
        video_codec,
        video_crf,
        video_gop,
        video_copy,
        zarr_version,
        stats_formats,
        segment,
        hierarchy,
        transforms,
        stats_population,
        abs_action,
        cameras,
        origins,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn profiles(items: &[(&str, ProfileSpec)]) -> BTreeMap<String, ProfileSpec> {
        items
            .iter()
            .map(|(n, p)| (n.to_string(), p.clone()))
            .collect()
    }

    #[test]
    fn override_wins_over_preset() {
        let spec = ProfileSpec {
            preset: Some(Preset::Act),
            fps: Some(10.0),
            chunk: Some(20),
            ..Default::default()
        };
        let p = expand("act", &profiles(&[("act", spec)])).unwrap();
        assert_eq!((p.fps, p.chunk, p.obs_history), (Some(10.0), 20, 1));
        assert_eq!(p.normalize_lowdim, NormalizeMode::Zscore);
        assert_eq!(p.origins["chunk"], "profiles.act");
        assert_eq!(p.origins["obs_history"], "preset act");
        assert_eq!(p.origins["stride"], "default");
    }

    #[test]
    fn no_preset_needs_chunk() {
        let all = profiles(&[("x", ProfileSpec::default())]);
        assert_eq!(expand("x", &all), Err(ExpandError::Missing("chunk")));
    }

    #[test]
    fn extends_inherits_and_overrides() {
        let base = ProfileSpec {
            preset: Some(Preset::DiffusionPolicy),
            chunk: Some(24),
            normalize: Some([("action".to_string(), NormalizeMode::Minmax)].into()),
            ..Default::default()
        };
        let child = ProfileSpec {
            extends: Some("base".into()),
            stride: Some(4),
            ..Default::default()
        };
        let all = profiles(&[("base", base), ("child", child)]);
        let p = expand("child", &all).unwrap();
        assert_eq!((p.chunk, p.stride, p.obs_history), (24, 4, 2));
        assert_eq!(p.preset, Some(Preset::DiffusionPolicy));
        assert_eq!(p.alignment, Alignment::DiffusionPolicy);
        assert_eq!(p.normalize["action"], NormalizeMode::Minmax);
        assert_eq!(p.origins["chunk"], "profiles.base");
        assert_eq!(p.origins["stride"], "profiles.child");
        assert_eq!(p.origins["obs_history"], "preset diffusion_policy");
    }

    #[test]
    fn export_keys_merge_along_extends() {
        let map = |pairs: &[(&str, &str)]| {
            Some(
                pairs
                    .iter()
                    .map(|(k, v)| (k.to_string(), v.to_string()))
                    .collect(),
            )
        };
        let base = ProfileSpec {
            preset: Some(Preset::DiffusionPolicy),
            format: Some(OutputFormat::Zarr),
            export_keys: map(&[("observation.image", "camera_0"), ("action", "act")]),
            ..Default::default()
        };
        let child = ProfileSpec {
            extends: Some("base".into()),
            export_keys: map(&[("action", "action")]),
            ..Default::default()
        };
        let all = profiles(&[("base", base), ("child", child)]);
        let p = expand("child", &all).unwrap();
        assert_eq!(p.export_keys["observation.image"], "camera_0");
        assert_eq!(p.export_keys["action"], "action");
        assert_eq!(p.export_keys.len(), 2);
    }

    #[test]
    fn extends_cycles_and_unknown_parents_are_errors() {
        let a = ProfileSpec {
            extends: Some("b".into()),
            ..Default::default()
        };
        let b = ProfileSpec {
            extends: Some("a".into()),
            ..Default::default()
        };
        let all = profiles(&[("a", a), ("b", b)]);
        assert_eq!(
            expand("a", &all),
            Err(ExpandError::Cycle(vec!["a".into(), "b".into(), "a".into()]))
        );
        let orphan = ProfileSpec {
            extends: Some("nope".into()),
            ..Default::default()
        };
        let all = profiles(&[("x", orphan)]);
        assert_eq!(
            expand("x", &all),
            Err(ExpandError::UnknownParent("nope".into()))
        );
    }
}
