//! Camera videos (LeRobot's `dtype: "video"` features): demuxing, decoding, frame selection and
//! RGB conversion, kept apart from the LeRobot layouts that say which file and which times.
//!
//! - `select`: which frame each row gets (LeRobot's nearest-pts rule and `tolerance_s`), decided
//!   while frames stream by; no FFmpeg in it, so it is tested in every build.
//! - `ffmpeg` (feature `video`): the FFmpeg libraries through `ffmpeg-next`: a file's packet
//!   times (the audit: demuxing only, no decoding) and the decode of one episode's rows, frames
//!   converted to RGB exactly as PyAV's `frame.to_ndarray(format="rgb24")`.
//! - `span`: when an episode's rows are a file's own frames one by one, which ones (a sink can
//!   then copy their packets instead of encoding the frames again).
//! - `disabled` (without the feature): the same functions, failing with a message that names
//!   the feature.
//!
//! Why a feature: Debian's libavcodec is built with x264/x265, so a chunkc binary linked with it
//! must be distributed under the GPL (book/src/video.md). A build without it reads everything
//! but videos.
//!
//! Errors are plain sentences about the file; the caller adds the episode, camera and file.

pub mod select;
mod span;

#[cfg(not(feature = "video"))]
mod disabled;
#[cfg(feature = "video")]
mod ffmpeg;

#[cfg(not(feature = "video"))]
pub use disabled::{decode_rows, probe, timeline};
#[cfg(feature = "video")]
pub use ffmpeg::{decode_rows, probe, seek_back, timeline};

pub use select::{Miss, TOLERANCE_S};
pub use span::{consecutive, PacketSpan};

/// Whether this binary can decode video (built with the `video` feature).
pub const ENABLED: bool = cfg!(feature = "video");

/// The message for a video source read by a binary built without the feature.
pub const DISABLED: &str = "this chunkc was built without the `video` feature, so it cannot decode video; \
     rebuild with `cargo build --release --features video` (needs the FFmpeg libraries: scripts/setup.sh installs them)";

/// A video file's stream, from its header only.
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    /// FFmpeg's name of the stream's codec (`av1`, `h264`, `hevc`, `mpeg4`).
    pub codec: String,
    pub width: usize,
    pub height: usize,
}

/// A video file's frame times, from its packets (demuxed, not decoded).
#[derive(Debug, Clone, PartialEq)]
pub struct Timeline {
    pub probe: Probe,
    /// Presentation times (`pts × time_base`, seconds) of every packet read, sorted.
    pub times: Vec<f64>,
    /// When reading stopped early: the frames the header promises and why reading stopped
    /// (a truncated file).
    pub cut: Option<String>,
}

/// Why an episode's rows could not all be given their frames.
#[derive(Debug, Clone, PartialEq)]
pub enum DecodeFailure {
    /// The file could not be opened, demuxed or decoded (the sentence says which).
    Unreadable(String),
    /// A row's nearest frame is too far away.
    Miss(Miss),
}

/// The codec name info.json's `video.codec` means, in FFmpeg's terms (LeRobot writes encoder
/// names too: `libsvtav1` is AV1).
pub fn codec_family(name: &str) -> String {
    let lower = name.to_ascii_lowercase();
    match lower.as_str() {
        "libsvtav1" | "libaom-av1" | "libdav1d" | "av01" => "av1".into(),
        "libx264" | "avc" | "avc1" | "h.264" => "h264".into(),
        "libx265" | "h265" | "hvc1" | "hev1" | "h.265" => "hevc".into(),
        "mp4v" | "xvid" | "divx" => "mpeg4".into(),
        _ => lower,
    }
}

/// One episode's camera video against its rows, as the audit reports it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct VideoCheck {
    /// Our channel name and the feature it maps (`observation.images.top`).
    pub channel: String,
    pub camera: String,
    /// The file, relative to the source root.
    pub file: String,
    /// The stream's codec (empty when the file could not be read).
    pub codec: String,
    /// Parquet rows of the episode.
    pub rows: usize,
    /// Frames in the episode's span of the file (v3.0: `from_timestamp ≤ t < to_timestamp`;
    /// v2: the whole file).
    pub frames: usize,
    /// Smallest and largest interval between those frames, seconds (0 with fewer than two).
    pub interval_min: f64,
    pub interval_max: f64,
    /// The largest distance between a row's time and its frame's, seconds.
    pub worst_gap: f64,
    /// Why some row cannot have its frame (missing, unreadable, truncated file, or a row beyond
    /// tolerance with its row and gap); `None` when every row has it.
    pub problem: Option<String>,
}
