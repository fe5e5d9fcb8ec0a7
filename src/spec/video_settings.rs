//! The encoder settings of a profile that stores frames as video, and their defaults
//! (LeRobot's for parquet, [`STORAGE_VIDEO`] for hdf5); [`super::profile::Profile::video`] picks
//! them for a profile.

use super::model::VideoCodec;

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
