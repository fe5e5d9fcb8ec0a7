//! JPEG frames as ALOHA's compressed episodes store them: one zero-padded row of bytes per step.

use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;
use zune_jpeg::JpegDecoder;

/// A decoded frame: (height, width, RGB bytes in HWC order).
pub struct Frame {
    pub height: usize,
    pub width: usize,
    pub rgb: Vec<u8>,
}

fn decoder(bytes: &[u8]) -> JpegDecoder<ZCursor<&[u8]>> {
    let options = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::RGB);
    JpegDecoder::new_with_options(ZCursor::new(bytes), options)
}

/// The (height, width) in a JPEG's header, without decoding the image.
pub fn dimensions(bytes: &[u8]) -> Result<(usize, usize), String> {
    let mut d = decoder(bytes);
    d.decode_headers()
        .map_err(|e| format!("not a JPEG image: {e:?}"))?;
    let info = d.info().ok_or("JPEG header without dimensions")?;
    Ok((usize::from(info.height), usize::from(info.width)))
}

/// Decodes one frame to RGB. Trailing zero padding after the image is ignored.
pub fn decode(bytes: &[u8]) -> Result<Frame, String> {
    let mut d = decoder(bytes);
    let rgb = d
        .decode()
        .map_err(|e| format!("cannot decode JPEG: {e:?}"))?;
    let info = d.info().ok_or("JPEG without dimensions")?;
    let (w, h) = (usize::from(info.width), usize::from(info.height));
    if rgb.len() != w * h * 3 {
        return Err(format!(
            "decoded {} bytes for a {w}x{h} RGB image",
            rgb.len()
        ));
    }
    Ok(Frame {
        height: h,
        width: w,
        rgb,
    })
}
