//! Images decoded as TensorFlow decodes them for TFDS.
//!
//! TFDS's `Image` feature decodes with `tf.image.decode_image`, i.e. `decode_jpeg` with its
//! defaults: `dct_method = ""`, which TensorFlow maps to libjpeg's `JDCT_IFAST` (the fast
//! integer IDCT), and fancy upsampling on. Pillow and OpenCV use the accurate IDCT
//! (`JDCT_ISLOW`), whose frames differ by up to 17 levels on Bridge: a model trained on
//! TFDS's frames should be fed those. `turbojpeg`'s safe API has no switch for the DCT, so this
//! sets `TJPARAM_FASTDCT` through its raw bindings.

use std::cell::RefCell;

use turbojpeg::raw;

/// One decompressor per thread, set up once.
struct Handle(raw::tjhandle);

impl Handle {
    fn new() -> Result<Self, String> {
        // SAFETY: tj3Init returns a handle or null; the handle is only used on this thread.
        let h = unsafe { raw::tj3Init(raw::TJINIT_TJINIT_DECOMPRESS as libc::c_int) };
        if h.is_null() {
            return Err("cannot initialise libjpeg-turbo".into());
        }
        // SAFETY: a valid handle and a valid parameter.
        let ok = unsafe { raw::tj3Set(h, raw::TJPARAM_TJPARAM_FASTDCT as libc::c_int, 1) };
        if ok != 0 {
            return Err("libjpeg-turbo refuses the fast DCT".into());
        }
        Ok(Handle(h))
    }

    fn error(&self) -> String {
        // SAFETY: the handle is valid; the string is owned by it and copied at once.
        unsafe {
            std::ffi::CStr::from_ptr(raw::tj3GetErrorStr(self.0))
                .to_string_lossy()
                .into_owned()
        }
    }
}

impl Drop for Handle {
    fn drop(&mut self) {
        // SAFETY: the handle was created by tj3Init and is destroyed once.
        unsafe { raw::tj3Destroy(self.0) }
    }
}

thread_local! {
    static HANDLE: RefCell<Option<Handle>> = const { RefCell::new(None) };
}

/// Decodes one JPEG to `channels` (1 or 3) interleaved samples per pixel with TensorFlow's
/// settings, appending them to `out`; returns (height, width).
pub fn decode_jpeg_tf(
    bytes: &[u8],
    channels: usize,
    out: &mut Vec<u8>,
) -> Result<(usize, usize), String> {
    if !bytes.starts_with(&[0xff, 0xd8]) {
        return Err("not a JPEG image (no SOI marker)".into());
    }
    HANDLE.with(|cell| {
        let mut slot = cell.borrow_mut();
        if slot.is_none() {
            *slot = Some(Handle::new()?);
        }
        let h = slot.as_ref().expect("just set");
        // SAFETY: valid handle and buffer.
        if unsafe { raw::tj3DecompressHeader(h.0, bytes.as_ptr(), bytes.len() as _) } != 0 {
            return Err(format!("cannot read the JPEG header: {}", h.error()));
        }
        // SAFETY: valid handle.
        let (w, hgt) = unsafe {
            (
                raw::tj3Get(h.0, raw::TJPARAM_TJPARAM_JPEGWIDTH as libc::c_int),
                raw::tj3Get(h.0, raw::TJPARAM_TJPARAM_JPEGHEIGHT as libc::c_int),
            )
        };
        if w <= 0 || hgt <= 0 {
            return Err(format!("JPEG header gives a {w}x{hgt} image"));
        }
        let (w, hgt) = (w as usize, hgt as usize);
        let format = match channels {
            1 => raw::TJPF_TJPF_GRAY,
            3 => raw::TJPF_TJPF_RGB,
            c => return Err(format!("{c} channels: JPEG frames are read as 1 or 3")),
        };
        let start = out.len();
        out.resize(start + w * hgt * channels, 0);
        // SAFETY: the destination holds exactly height × pitch bytes.
        let rc = unsafe {
            raw::tj3Decompress8(
                h.0,
                bytes.as_ptr(),
                bytes.len() as _,
                out[start..].as_mut_ptr(),
                (w * channels) as libc::c_int,
                format,
            )
        };
        if rc != 0 {
            out.truncate(start);
            return Err(format!("cannot decode JPEG: {}", h.error()));
        }
        Ok((hgt, w))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_dct_differs_from_the_accurate_one() {
        // A busy 4:2:0 picture: the two IDCTs round differently somewhere.
        let (w, h) = (32usize, 32usize);
        let pixels: Vec<u8> = (0..w * h * 3).map(|i| ((i * 7919) % 251) as u8).collect();
        let image = turbojpeg::Image {
            pixels: pixels.as_slice(),
            width: w,
            pitch: w * 3,
            height: h,
            format: turbojpeg::PixelFormat::RGB,
        };
        let jpeg = turbojpeg::compress(image, 90, turbojpeg::Subsamp::Sub2x2).unwrap();
        let mut fast = Vec::new();
        assert_eq!(decode_jpeg_tf(&jpeg, 3, &mut fast).unwrap(), (h, w));
        let accurate = turbojpeg::decompress(&jpeg, turbojpeg::PixelFormat::RGB).unwrap();
        assert_eq!(fast.len(), accurate.pixels.len());
        assert_ne!(fast, accurate.pixels);
        assert!(decode_jpeg_tf(b"\xff\xd8garbage", 3, &mut Vec::new()).is_err());
    }
}
