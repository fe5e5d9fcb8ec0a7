//! Frames as JPEG files, what `image_compression = "jpeg"` stores (as ALOHA's compressed
//! episodes do: one JPEG per frame).
//!
//! Encoded with libjpeg-turbo built without SIMD (the same library and build that
//! [`crate::source::jpeg`] decodes with): one frame is one single-threaded call, so the bytes
//! depend only on the pixels, the quality and this library version, never on `-j` or the CPU.
//! Colour frames are 4:2:0 (what Pillow and OpenCV write by default), grey frames one component.

/// The encoder as `chunkc.lock` records it: the library and how it was built.
pub const ENCODER: &str = "libjpeg-turbo";
/// The libjpeg-turbo that `turbojpeg-sys` builds from its vendored source.
pub const ENCODER_VERSION: &str = "3.1.0";
/// Chroma subsampling of colour frames, as the lock records it.
pub const SUBSAMPLING: &str = "4:2:0";

/// Whether frames of `shape` (HWC) can be stored as JPEG: grey or RGB, at most 65535 pixels a
/// side. The reason when not.
pub fn check_shape(shape: &[usize]) -> Result<(), String> {
    match shape {
        [h, w, c] if (*c == 1 || *c == 3) && *h > 0 && *w > 0 && *h <= 65535 && *w <= 65535 => {
            Ok(())
        }
        _ => Err(format!(
            "JPEG stores (height, width, 1 or 3) frames of at most 65535 pixels a side, and \
             these are {shape:?}"
        )),
    }
}

/// Encodes one frame of `shape` (HWC, checked by [`check_shape`]) at `quality` (1..=100).
pub fn encode(frame: &[u8], shape: &[usize], quality: u8) -> Vec<u8> {
    let (height, width, colors) = (shape[0], shape[1], shape[2]);
    let (format, subsamp) = if colors == 1 {
        (turbojpeg::PixelFormat::GRAY, turbojpeg::Subsamp::Gray)
    } else {
        (turbojpeg::PixelFormat::RGB, turbojpeg::Subsamp::Sub2x2)
    };
    let image = turbojpeg::Image {
        pixels: frame,
        width,
        pitch: width * colors,
        height,
        format,
    };
    turbojpeg::compress(image, i32::from(quality), subsamp)
        .expect("frames of a checked shape encode")
        .to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_round_trip_through_the_decoder_and_encode_the_same_twice() {
        let shape = [24, 32, 3];
        let frame: Vec<u8> = (0..24 * 32 * 3).map(|i| (i * 7 % 251) as u8).collect();
        let a = encode(&frame, &shape, 90);
        assert_eq!(a, encode(&frame, &shape, 90));
        let decoded = turbojpeg::decompress(&a, turbojpeg::PixelFormat::RGB).unwrap();
        assert_eq!((decoded.height, decoded.width), (24, 32));
        assert!(encode(&frame, &shape, 30).len() < a.len());
        let grey = encode(&frame[..24 * 32], &[24, 32, 1], 90);
        let header = turbojpeg::read_header(&grey).unwrap();
        assert_eq!((header.height, header.width), (24, 32));
        assert!(check_shape(&[24, 32, 4]).is_err());
    }
}
