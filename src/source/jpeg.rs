//! JPEG frames as ALOHA's compressed episodes store them: one zero-padded row of bytes per step.
//!
//! Decoded with libjpeg-turbo (built from source, without SIMD so the bytes do not depend on the
//! CPU), the library behind Pillow and OpenCV: the frames chunkc stores are exactly the ones the
//! users' own Python pipelines decode.

/// A decoded frame: (height, width, RGB bytes in HWC order).
pub struct Frame {
    pub height: usize,
    pub width: usize,
    pub rgb: Vec<u8>,
}

/// The (height, width) in a JPEG's header, without decoding the image.
pub fn dimensions(bytes: &[u8]) -> Result<(usize, usize), String> {
    let header = turbojpeg::read_header(bytes).map_err(|e| format!("not a JPEG image: {e}"))?;
    Ok((header.height, header.width))
}

/// Decodes one frame to RGB. Trailing zero padding after the image is ignored.
pub fn decode(bytes: &[u8]) -> Result<Frame, String> {
    let image = turbojpeg::decompress(bytes, turbojpeg::PixelFormat::RGB)
        .map_err(|e| format!("cannot decode JPEG: {e}"))?;
    let (w, h) = (image.width, image.height);
    if image.pitch != w * 3 || image.pixels.len() != w * h * 3 {
        return Err(format!(
            "decoded {} bytes for a {w}x{h} RGB image",
            image.pixels.len()
        ));
    }
    Ok(Frame {
        height: h,
        width: w,
        rgb: image.pixels,
    })
}
