//! How the LeRobot exports encode a camera stored as video (`image_encoding = "video"`): the
//! profile's encoder settings, whether a source video's packets are copied instead, and the
//! codec of a camera too small for SVT-AV1.
//!
//! - **Copies**: files of one episode each (v2.1; v3.0 with `video_copy = true`) copy the
//!   source's packets where an episode's frames are a source video's own, unchanged (the
//!   source's rate, no resize, whole GOPs from a keyframe: [`super::video_copy`]), of any codec
//!   an mp4 holds, or only of `video_codec`'s when the spec names one; `video_copy = false`
//!   encodes every episode. v2.1 copies by default, v3.0 only when asked (its default is
//!   LeRobot's own layout, one encoded file of every episode).
//! - **Small cameras**: SVT-AV1 1.4 (Debian 12's, the wheel's) refuses frames under 64 pixels
//!   a side. When the spec names no codec, such a camera is encoded with x264 (at x264's default
//!   crf 23, unless `video_crf` says) where this chunkc has it, else (the wheel, whose LGPL
//!   FFmpeg has no x264) with FFmpeg's own MPEG-4 Part 2 encoder at quantizer 3: both are read
//!   by LeRobot's decoders (torchcodec, PyAV) and GR00T's.

use super::lerobot_columns::video_shape;
use super::video_episodes::EpisodeCamera;
use crate::error::Result;
use crate::plan::ProfilePlan;
use crate::spec::{OutputFormat, Profile, StreamCopy, VideoCodec, VideoSettings, HAS_X264};

/// The smallest frames SVT-AV1 1.4 encodes.
const SVTAV1_MIN_SIDE: usize = 64;
/// x264's crf where a camera too small for SVT-AV1 falls back to it (x264's own default).
const X264_FALLBACK_CRF: u32 = 23;
/// MPEG-4's quantizer where a camera too small for SVT-AV1 falls back to it without x264 (2 is
/// the finest that keeps 8-bit rounding; 3 is close to lossless at these sizes).
const MPEG4_FALLBACK_QSCALE: u32 = 3;

/// Whether the profile's videos are one file per episode and may copy the source's packets:
/// LeRobot v2.1 (unless `video_copy = false`), LeRobot v3.0 with `video_copy = true`.
pub(super) fn per_episode_copies(p: &ProfilePlan) -> bool {
    p.values.format == OutputFormat::Parquet
        && (p.writes_lerobot_v21() || p.values.video_copy == Some(true))
}

/// Which source streams a camera's files copy: none unless `copies`, none with
/// `video_copy = false`, those of `video_codec` when the spec names one, else any an mp4 holds.
pub(super) fn copy_mode(values: &Profile, copies: bool) -> StreamCopy {
    match (copies, values.video_copy, values.video_codec) {
        (false, ..) | (_, Some(false), _) => StreamCopy::Never,
        (_, _, Some(_)) => StreamCopy::SameCodec,
        _ => StreamCopy::AnyCodec,
    }
}

/// The encoder of a `height` x `width` camera: the profile's, unless it is SVT-AV1 by default
/// (no `video_codec`) and the frames are too small for it: then x264 where the build has it
/// (`has_x264`), else FFmpeg's own MPEG-4 encoder, each at its own quality unless `video_crf`
/// says.
fn for_size(
    values: &Profile,
    s: VideoSettings,
    (height, width): (usize, usize),
    has_x264: bool,
) -> VideoSettings {
    let small = height < SVTAV1_MIN_SIDE || width < SVTAV1_MIN_SIDE;
    if !small || values.video_codec.is_some() || s.codec != VideoCodec::Libsvtav1 {
        return s;
    }
    let (codec, crf) = match has_x264 {
        true => (VideoCodec::Libx264, X264_FALLBACK_CRF),
        false => (VideoCodec::Mpeg4, MPEG4_FALLBACK_QSCALE),
    };
    VideoSettings {
        codec,
        crf: values.video_crf.map_or(crf, |c| c.min(codec.max_crf())),
        ..s
    }
}

/// Camera `name` (per-step `shape`) at `fps`, encoded with the profile's `settings`;
/// `copies`: whether its files are one episode each and may copy the source's packets
/// (`video_copy` can still turn that off).
pub(super) fn camera(
    values: &Profile,
    (name, shape, fps): (&str, &[usize], f64),
    settings: VideoSettings,
    copies: bool,
) -> Result<EpisodeCamera> {
    let shape = video_shape(name, shape, fps)?;
    let mut s = for_size(values, settings, (shape.height, shape.width), HAS_X264);
    s.copy = copy_mode(values, copies);
    Ok(EpisodeCamera {
        name: name.to_string(),
        shape,
        settings: s,
    })
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::spec::STORAGE_VIDEO;

    fn profile(keys: &str) -> Profile {
        let text = format!(
            "version = 1\n[source]\nformat = \"diffusion_policy_zarr\"\npath = \"x.zarr\"\n\
             fps = 10\n[source.channels]\naction = \"action\"\n[output]\ndir = \"out\"\n\
             [profiles.p]\npreset = \"pi0\"\nformat = \"parquet\"\n\
             image_encoding = \"video\"\n{keys}\n"
        );
        let loaded = crate::spec::LoadedSpec::parse("spec.toml", &text, Path::new(".")).unwrap();
        loaded.profiles.into_iter().next().unwrap()
    }

    #[test]
    fn a_camera_too_small_for_svtav1_gets_a_codec_the_build_has() {
        let svt = VideoSettings {
            codec: VideoCodec::Libsvtav1,
            crf: 30,
            ..STORAGE_VIDEO
        };
        let p = profile("");
        assert_eq!(
            for_size(&p, svt, (96, 96), true).codec,
            VideoCodec::Libsvtav1
        );
        let x = for_size(&p, svt, (32, 96), true);
        assert_eq!((x.codec, x.crf), (VideoCodec::Libx264, 23));
        let m = for_size(&p, svt, (32, 32), false);
        assert_eq!((m.codec, m.crf), (VideoCodec::Mpeg4, 3));
        // A named codec or crf is the spec's.
        let named = profile("video_codec = \"libsvtav1\"");
        assert_eq!(
            for_size(&named, svt, (32, 32), false).codec,
            VideoCodec::Libsvtav1
        );
        let crf = profile("video_crf = 40");
        assert_eq!(for_size(&crf, svt, (32, 32), false).crf, 31);
        assert_eq!(for_size(&crf, svt, (32, 32), true).crf, 40);
    }
}
