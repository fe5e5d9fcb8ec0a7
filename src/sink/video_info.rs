//! What an mp4 chunkc wrote holds, as LeRobot's `get_video_info` reads it back into
//! `meta/info.json`'s `info` block: the stream's codec and pixel format (a copied stream keeps
//! the source's, an encoded one has the encoder's).

use std::path::Path;

use crate::error::{Error, Result};

/// The codec (FFmpeg's name: `av1`, `h264`) and pixel format (`yuv420p`) of the file's video
/// stream.
pub fn stream_format(path: &Path) -> Result<(String, String)> {
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
mod imp {
    use std::path::Path;

    use ffmpeg_next as ff;

    pub fn stream_format(path: &Path) -> Result<(String, String), String> {
        let _ = ff::init();
        let input = ff::format::input(path).map_err(|e| format!("cannot open the video: {e}"))?;
        let stream = input
            .streams()
            .best(ff::media::Type::Video)
            .ok_or_else(|| "the file holds no video stream".to_string())?;
        let params = stream.parameters();
        let codec = params.id().name().to_string();
        let decoder = ff::codec::context::Context::from_parameters(params)
            .and_then(|c| c.decoder().video())
            .map_err(|e| format!("cannot read the stream's parameters: {e}"))?;
        let pix_fmt = decoder
            .format()
            .descriptor()
            .map_or_else(|| "unknown".to_string(), |d| d.name().to_string());
        Ok((codec, pix_fmt))
    }
}
