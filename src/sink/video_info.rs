//! What an mp4 chunkc wrote holds, as FFmpeg's demuxer reads it back (what `ffprobe` and PyAV
//! report, and what LeRobot's `get_video_info` writes into `meta/info.json`'s `info` block): the
//! stream's codec, profile and pixel format. A copied stream keeps the source's, an encoded one
//! has the encoder's.

use std::path::Path;

use serde::Serialize;

use crate::error::{Error, Result};

/// The format of a stored video stream, in FFmpeg's names.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub struct StreamFormat {
    /// The codec (`av1`, `h264`, `mpeg4`): `codec_name` in `ffprobe`, `codec_context.name` in
    /// PyAV.
    pub codec: String,
    /// The codec's profile (`Main`, `High`, `Simple Profile`), where the stream names one.
    pub profile: Option<String>,
    /// The pixel format (`yuv420p`).
    pub pix_fmt: String,
}

/// The format of the video stream of the mp4 at `path`.
pub fn stream_format(path: &Path) -> Result<StreamFormat> {
    #[cfg(feature = "video")]
    {
        imp::stream_format(path).map_err(|m| Error::output(format!("{}: {m}", path.display())))
    }
    #[cfg(not(feature = "video"))]
    {
        Err(Error::output(format!(
            "{}: reading video needs a chunkc built with the `video` cargo feature",
            path.display()
        )))
    }
}

#[cfg(feature = "video")]
pub(super) use imp::{of_parameters, profile_name};

#[cfg(feature = "video")]
mod imp {
    use std::ffi::CStr;
    use std::path::Path;

    use ffmpeg_next as ff;

    use super::StreamFormat;

    pub fn stream_format(path: &Path) -> Result<StreamFormat, String> {
        let _ = ff::init();
        let input = ff::format::input(path).map_err(|e| format!("cannot open the video: {e}"))?;
        let stream = input
            .streams()
            .best(ff::media::Type::Video)
            .ok_or_else(|| "the file holds no video stream".to_string())?;
        Ok(of_parameters(&stream.parameters()))
    }

    /// FFmpeg's name of profile `profile` of codec `id` (none where it has no name).
    pub fn profile_name(id: ff::codec::Id, profile: i32) -> Option<String> {
        // SAFETY: FFmpeg's profile names are static strings (null when it has none).
        unsafe {
            let name = ff::ffi::avcodec_profile_name(id.into(), profile);
            (!name.is_null()).then(|| CStr::from_ptr(name).to_string_lossy().into_owned())
        }
    }

    /// The format a demuxed stream's parameters describe (those of a stream copied as they are
    /// describe the copy).
    pub fn of_parameters(params: &ff::codec::Parameters) -> StreamFormat {
        let id = params.id();
        // SAFETY: the parameters are valid for the borrow.
        let profile = profile_name(id, unsafe { (*params.as_ptr()).profile });
        let pix_fmt = ff::codec::context::Context::from_parameters(params.clone())
            .and_then(|c| c.decoder().video())
            .ok()
            .and_then(|d| d.format().descriptor())
            .map_or_else(|| "unknown".to_string(), |d| d.name().to_string());
        StreamFormat {
            codec: id.name().to_string(),
            profile,
            pix_fmt,
        }
    }
}

/// What a camera stored as one video per episode holds: how many of its episodes' files were
/// copied from the source's streams, of how many, and the formats of the files, each with how
/// many files hold it (in order).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StoredVideo {
    pub copied: usize,
    pub episodes: usize,
    pub formats: Vec<(StreamFormat, usize)>,
}

impl StoredVideo {
    /// `copied` (every file), `encoded` (none) or `mixed`.
    pub fn stored(&self) -> &'static str {
        match self.copied {
            0 => "encoded",
            c if c == self.episodes => "copied",
            _ => "mixed",
        }
    }

    /// `field` of the files' format when every file has the same, else `None`.
    pub fn shared<T: PartialEq>(&self, field: impl Fn(&StreamFormat) -> T) -> Option<T> {
        let mut values = self.formats.iter().map(|(f, _)| field(f));
        let first = values.next()?;
        values.all(|v| v == first).then_some(first)
    }
}
