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
//!   a side. Such a camera is encoded with x264 (at x264's default crf 23, unless `video_crf`
//!   says) where this chunkc has it and the spec names no codec; the wheel, without x264, keeps
//!   SVT-AV1, and its error says to resize the camera or keep PNG.

use super::lerobot_columns::video_shape;
use super::video_episodes::EpisodeCamera;
use crate::error::Result;
use crate::spec::{Profile, StreamCopy, VideoCodec, VideoSettings, HAS_X264};

/// The smallest frames SVT-AV1 1.4 encodes.
const SVTAV1_MIN_SIDE: usize = 64;
/// x264's crf where a camera too small for SVT-AV1 falls back to it (x264's own default).
const X264_FALLBACK_CRF: u32 = 23;

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
    let mut s = settings;
    s.copy = match (copies, values.video_copy, values.video_codec) {
        (false, ..) | (_, Some(false), _) => StreamCopy::Never,
        (_, _, Some(_)) => StreamCopy::SameCodec,
        _ => StreamCopy::AnyCodec,
    };
    let small = shape.height < SVTAV1_MIN_SIDE || shape.width < SVTAV1_MIN_SIDE;
    if small && HAS_X264 && values.video_codec.is_none() && s.codec == VideoCodec::Libsvtav1 {
        s.codec = VideoCodec::Libx264;
        s.crf = values.video_crf.unwrap_or(X264_FALLBACK_CRF);
    }
    Ok(EpisodeCamera {
        name: name.to_string(),
        shape,
        settings: s,
    })
}
