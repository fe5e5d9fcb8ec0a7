//! What every stream chunkc writes is encoded with: its shape, its pixel format, the encoder's
//! and the muxer's options (LeRobot's settings, with what keeps the bytes the same on every
//! machine and run), and what the documents beside the videos say of them.

use crate::spec::VideoCodec;
#[cfg(feature = "video")]
use crate::spec::VideoSettings;

/// What LeRobot's `get_video_info` reports of a stream chunkc wrote.
pub fn codec_name(codec: VideoCodec) -> &'static str {
    match codec {
        VideoCodec::Libsvtav1 => "av1",
        VideoCodec::Libx264 => "h264",
        VideoCodec::Mpeg4 => "mpeg4",
    }
}

/// The pixel format every stream is encoded in.
pub const PIX_FMT: &str = "yuv420p";

/// SVT-AV1's preset (speed) as LeRobot sets it.
pub const SVTAV1_PRESET: u32 = 12;

/// x264's own options (FFmpeg's `x264-params`): the same algorithms on every CPU, so the bytes
/// depend on neither the machine's instruction sets nor what its heap held before.
pub const X264_PARAMS: &str = "cpu-independent=1";

/// The libavcodec the encoders run in (`major.minor.micro`), or why there is none.
pub fn library_version() -> String {
    #[cfg(feature = "video")]
    {
        let v = ffmpeg_next::codec::version();
        format!("libavcodec {}.{}.{}", v >> 16, (v >> 8) & 0xff, v & 0xff)
    }
    #[cfg(not(feature = "video"))]
    {
        "none (built without the `video` feature)".to_string()
    }
}

/// The geometry and rate of a stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamShape {
    pub height: usize,
    pub width: usize,
    pub fps: f64,
}

impl StreamShape {
    pub(super) fn frame_bytes(&self) -> usize {
        self.height * self.width * 3
    }
}

/// The encoder's options (libavcodec's, in the order they are set): the quality, one thread
/// (the same decisions on every run) and, for x264, [`X264_PARAMS`]; `asm` limits x264 to
/// those instruction sets (its `asm` option; `0`: none), as a machine without the others would.
#[cfg(feature = "video")]
pub(super) fn encoder_options(s: &VideoSettings, asm: Option<&str>) -> Vec<(&'static str, String)> {
    let mut opts = vec![];
    if s.codec != VideoCodec::Mpeg4 {
        opts.push(("crf", s.crf.to_string()));
    }
    match s.codec {
        // A fixed quantizer instead ([`mpeg4_quality`]): MPEG-4 Part 2 has no constant rate factor.
        VideoCodec::Mpeg4 => {}
        VideoCodec::Libsvtav1 => {
            opts.push(("preset", SVTAV1_PRESET.to_string()));
            // One thread, no core pinning: the same decisions on every run.
            opts.push(("svtav1-params", "lp=1".to_string()));
        }
        VideoCodec::Libx264 => {
            opts.push(("threads", "1".to_string()));
            let params = match asm {
                Some(asm) => format!("{X264_PARAMS}:asm={asm}"),
                None => X264_PARAMS.to_string(),
            };
            opts.push(("x264-params", params));
        }
    }
    opts
}

/// libavcodec's `FF_QP2LAMBDA`: a quantizer as the encoder's `quality` (lambda).
#[cfg(feature = "video")]
const QP2LAMBDA: i32 = 118;

/// Every frame's `quality` for the settings, as FFmpeg's own `-q:v` sets it: MPEG-4's fixed
/// quantizer (the settings' `crf`, at least 1) as a lambda; 0 where the encoder decides.
#[cfg(feature = "video")]
pub(super) fn mpeg4_quality(s: &VideoSettings) -> i32 {
    match s.codec {
        VideoCodec::Mpeg4 => QP2LAMBDA * s.crf.max(1) as i32,
        _ => 0,
    }
}

/// The muxer's options: no library version in the file (`+bitexact`), and the index first, so
/// that players (and the Hub's viewer) start without a seek.
#[cfg(feature = "video")]
pub(super) const MUXER_OPTIONS: &[(&str, &str)] =
    &[("fflags", "+bitexact"), ("movflags", "+faststart")];

/// Why an encoder may have refused frames of `shape`: SVT-AV1 before 2.0 (Debian 12 has 1.4)
/// takes nothing under 64x64. Empty when that is not it.
#[cfg(feature = "video")]
pub(super) fn refusal_hint(s: &VideoSettings, shape: StreamShape) -> String {
    let small = s.codec == VideoCodec::Libsvtav1 && (shape.height < 64 || shape.width < 64);
    if !small {
        return String::new();
    }
    let instead = if crate::spec::HAS_X264 {
        "`video_codec = \"libx264\"` takes them"
    } else {
        "resize them with `cameras`, or store them as `jpeg` or `png`"
    };
    format!(
        " ({}x{} frames: this SVT-AV1 may need at least 64x64; {instead})",
        shape.height, shape.width
    )
}
