//! The frame encoder of a profile as `chunkc.lock` records it: which library wrote the lossy
//! bytes (JPEG or video), its version, and every setting that changes them. Same spec + same
//! source + same encoder → the same bytes; the lock says which encoder that was.

use std::collections::BTreeMap;

use super::{jpeg, video_encode};
use crate::lock::LockedEncoder;
use crate::plan::ProfilePlan;
use crate::spec::{ImageCompression, OutputFormat, StreamCopy, VideoCodec, DEFAULT_IMAGE_QUALITY};

/// The encoder of the profile's frames, or `None` when it stores them losslessly.
pub fn of(plan: &ProfilePlan) -> Option<LockedEncoder> {
    let profile = &plan.values;
    let settings = |pairs: &[(&str, String)]| -> BTreeMap<String, String> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect()
    };
    if profile.format == OutputFormat::Hdf5 && profile.image_compression == ImageCompression::Jpeg {
        let quality = profile.image_quality.unwrap_or(DEFAULT_IMAGE_QUALITY);
        return Some(LockedEncoder {
            name: jpeg::ENCODER.into(),
            version: jpeg::ENCODER_VERSION.into(),
            settings: settings(&[
                ("quality", quality.to_string()),
                ("subsampling", jpeg::SUBSAMPLING.into()),
                ("simd", "off".into()),
            ]),
        });
    }
    let video = profile.video()?;
    let mut pairs = vec![
        ("crf", video.crf.to_string()),
        ("gop", video.gop.to_string()),
        ("pix_fmt", video_encode::PIX_FMT.to_string()),
        ("threads", "1".to_string()),
        ("closed_gop", u8::from(video.closed_gop).to_string()),
    ];
    match video.codec {
        VideoCodec::Libsvtav1 => pairs.push(("preset", video_encode::SVTAV1_PRESET.to_string())),
        VideoCodec::Libx264 => pairs.push(("x264_params", video_encode::X264_PARAMS.to_string())),
        VideoCodec::Mpeg4 => pairs.push(("qscale", video.crf.to_string())),
    }
    // Which source streams are copied instead of encoded (their bytes are the source's): the
    // LeRobot exports' per-episode videos decide it apart from `Profile::video`.
    let copy = match profile.format {
        OutputFormat::Parquet => super::lerobot_cameras::copy_mode(
            profile,
            super::lerobot_cameras::per_episode_copies(plan),
        ),
        _ => video.copy,
    };
    match copy {
        StreamCopy::Never => {}
        StreamCopy::AnyCodec => pairs.push(("stream_copy", "any codec".into())),
        StreamCopy::SameCodec => pairs.push((
            "stream_copy",
            video_encode::codec_name(video.codec).to_string(),
        )),
    }
    Some(LockedEncoder {
        name: video.codec.name().into(),
        version: video_encode::library_version(),
        settings: settings(&pairs),
    })
}
