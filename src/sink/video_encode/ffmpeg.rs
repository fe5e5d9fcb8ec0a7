//! The encode loop on FFmpeg's side: one output context, one encoder, one scaler per stream;
//! frames converted and encoded as they come, packets written as the encoder gives them back.

use std::path::Path;
use std::sync::Once;

use ff::{codec, encoder, format, frame, software::scaling, Dictionary, Packet, Rational};
use ffmpeg_next as ff;

use super::settings::{encoder_options, mpeg4_quality, refusal_hint, StreamShape, MUXER_OPTIONS};
use crate::sink::video_info::{self, StreamFormat};
use crate::spec::VideoSettings;

pub struct Inner {
    /// Every frame's `quality` (a fixed quantizer's lambda; 0: the encoder decides).
    quality: i32,
    octx: format::context::Output,
    encoder: encoder::Video,
    scaler: scaling::Context,
    rgb: frame::Video,
    yuv: frame::Video,
    time_base: Rational,
    stream_time_base: Rational,
}

// The contexts are used by one thread at a time (moved into the encoder thread whole).
unsafe impl Send for Inner {}

fn init() -> Result<(), String> {
    static INIT: Once = Once::new();
    let mut failed = None;
    INIT.call_once(|| {
        // SVT-AV1 prints a banner per encoder unless told to keep to warnings.
        if std::env::var_os("SVT_LOG").is_none() {
            std::env::set_var("SVT_LOG", "2");
        }
        if let Err(e) = ff::init() {
            failed = Some(e.to_string());
        }
        ff::log::set_level(ff::log::Level::Error);
    });
    failed.map_or(Ok(()), Err)
}

fn rate(fps: f64) -> Rational {
    let r = Rational::from(fps);
    if r.numerator() > 0 && r.denominator() > 0 {
        r
    } else {
        Rational(fps.round().max(1.0) as i32, 1)
    }
}

impl Inner {
    /// Creates the mp4, its encoder and its RGB24 → yuv420p scaler, and writes the header.
    pub fn create(
        path: &Path,
        shape: StreamShape,
        s: VideoSettings,
        asm: Option<&str>,
    ) -> Result<Self, String> {
        init()?;
        let mut octx = format::output_as(path, "mp4").map_err(e("cannot create the mp4"))?;
        let global_header = octx.format().flags().contains(format::Flags::GLOBAL_HEADER);
        let name = s.codec.name();
        let codec = encoder::find_by_name(name).ok_or_else(|| {
            format!("this FFmpeg has no `{name}` encoder (`ffmpeg -encoders` lists them)")
        })?;
        let frame_rate = rate(shape.fps);
        let time_base = frame_rate.invert();
        let encoder = open_encoder(codec, shape, &s, asm, global_header)?;
        {
            let mut ost = octx.add_stream(codec).map_err(e("cannot add the stream"))?;
            ost.set_parameters(&encoder);
            ost.set_time_base(time_base);
            ost.set_rate(frame_rate);
            ost.set_avg_frame_rate(frame_rate);
        }
        let mut header = Dictionary::new();
        for (key, value) in MUXER_OPTIONS {
            header.set(key, value);
        }
        octx.write_header_with(header)
            .map_err(e("cannot write the mp4 header"))?;
        let stream_time_base = octx.stream(0).expect("added").time_base();
        let (w, h) = (shape.width as u32, shape.height as u32);
        let scaler = rgb_to_yuv(w, h)?;
        Ok(Inner {
            quality: mpeg4_quality(&s),
            octx,
            encoder,
            scaler,
            rgb: frame::Video::new(format::Pixel::RGB24, w, h),
            yuv: frame::Video::new(format::Pixel::YUV420P, w, h),
            time_base,
            stream_time_base,
        })
    }

    pub fn push(&mut self, pixels: &[u8], pts: i64) -> Result<(), String> {
        convert(&mut self.scaler, pixels, &mut self.rgb, &mut self.yuv)?;
        self.send(pts)
    }

    /// Encodes one frame already converted ([`to_yuv420p`]: its Y, U and V planes).
    pub fn push_yuv(&mut self, planes: &[u8], pts: i64) -> Result<(), String> {
        let mut at = 0;
        for plane in 0..3 {
            let (w, h) = plane_size(&self.yuv, plane);
            let stride = self.yuv.stride(plane);
            let data = self.yuv.data_mut(plane);
            for y in 0..h {
                data[y * stride..y * stride + w].copy_from_slice(&planes[at..at + w]);
                at += w;
            }
        }
        self.send(pts)
    }

    fn send(&mut self, pts: i64) -> Result<(), String> {
        self.yuv.set_pts(Some(pts));
        if self.quality > 0 {
            // As FFmpeg's own `-q:v` does: the quantizer of every frame.
            unsafe { (*self.yuv.as_mut_ptr()).quality = self.quality };
        }
        self.encoder
            .send_frame(&self.yuv)
            .map_err(|e| format!("encoding frame {pts}: {e}"))?;
        self.drain()
    }

    fn drain(&mut self) -> Result<(), String> {
        let mut packet = Packet::empty();
        while self.encoder.receive_packet(&mut packet).is_ok() {
            packet.set_stream(0);
            packet.rescale_ts(self.time_base, self.stream_time_base);
            packet
                .write_interleaved(&mut self.octx)
                .map_err(|e| format!("writing a packet: {e}"))?;
        }
        Ok(())
    }

    /// What the stream holds, from the encoder's own stream configuration (its extradata: the
    /// `avcC` / `av1C` record the mp4 carries), as a decoder reads it back: no file is read.
    pub fn format(&self) -> StreamFormat {
        let id = self.encoder.id();
        // SAFETY: the opened encoder's extradata is `extradata_size` bytes (or null).
        let extradata: &[u8] = unsafe {
            let c = self.encoder.as_ptr();
            match (*c).extradata.is_null() {
                true => &[],
                false => std::slice::from_raw_parts((*c).extradata, (*c).extradata_size as usize),
            }
        };
        let profile = profile_of(id, extradata).and_then(|p| video_info::profile_name(id, p));
        StreamFormat {
            codec: id.name().to_string(),
            profile,
            pix_fmt: super::PIX_FMT.to_string(),
        }
    }

    pub fn finish(mut self) -> Result<(), String> {
        self.encoder
            .send_eof()
            .map_err(|e| format!("flushing the encoder: {e}"))?;
        self.drain()?;
        self.octx
            .write_trailer()
            .map_err(|e| format!("writing the mp4 index: {e}"))
    }
}

/// RGB24 `pixels` (one frame, rows back to back) into `yuv` through `rgb`, as every stream
/// converts its frames.
fn convert(
    scaler: &mut scaling::Context,
    pixels: &[u8],
    rgb: &mut frame::Video,
    yuv: &mut frame::Video,
) -> Result<(), String> {
    let row = rgb.width() as usize * 3;
    let stride = rgb.stride(0);
    let data = rgb.data_mut(0);
    for (y, src) in pixels.chunks(row).enumerate() {
        data[y * stride..y * stride + row].copy_from_slice(src);
    }
    scaler
        .run(rgb, yuv)
        .map_err(|e| format!("converting a frame to yuv420p: {e}"))
}

/// (width, height) of plane `plane` of a yuv420p frame.
fn plane_size(f: &frame::Video, plane: usize) -> (usize, usize) {
    let (w, h) = (f.width() as usize, f.height() as usize);
    match plane {
        0 => (w, h),
        _ => (w / 2, h / 2),
    }
}

fn rgb_to_yuv(w: u32, h: u32) -> Result<scaling::Context, String> {
    scaling::Context::get(
        format::Pixel::RGB24,
        w,
        h,
        format::Pixel::YUV420P,
        w,
        h,
        scaling::Flags::BILINEAR,
    )
    .map_err(e("cannot convert RGB24 to yuv420p"))
}

/// RGB24 frames of `w` x `h` (back to back) into `out`: each frame's yuv420p planes (Y, U, V,
/// without padding), back to back, converted exactly as a stream converts the frames it is
/// pushed.
pub fn to_yuv420p(frames: &[u8], w: u32, h: u32, out: &mut [u8]) -> Result<(), String> {
    init()?;
    let mut scaler = rgb_to_yuv(w, h)?;
    let mut rgb = frame::Video::new(format::Pixel::RGB24, w, h);
    let mut yuv = frame::Video::new(format::Pixel::YUV420P, w, h);
    let frame_bytes = w as usize * h as usize * 3;
    let mut at = 0;
    for pixels in frames.chunks(frame_bytes.max(1)) {
        convert(&mut scaler, pixels, &mut rgb, &mut yuv)?;
        for plane in 0..3 {
            let (pw, ph) = plane_size(&yuv, plane);
            let stride = yuv.stride(plane);
            let data = yuv.data(plane);
            for y in 0..ph {
                out[at..at + pw].copy_from_slice(&data[y * stride..y * stride + pw]);
                at += pw;
            }
        }
    }
    Ok(())
}

/// FFmpeg's flags on an H.264 profile (`AV_PROFILE_H264_CONSTRAINED`, `_INTRA`; named
/// `FF_PROFILE_…` before FFmpeg 6.1, the same values).
const H264_CONSTRAINED: i32 = 1 << 9;
const H264_INTRA: i32 = 1 << 11;

/// The profile a decoder reports for a stream whose configuration is `extradata`, in either
/// form an encoder leaves it: H.264's `avcC` record or its SPS in Annex B (profile_idc, with
/// FFmpeg's constrained and intra flags from the constraint bits, as `ff_h264_get_profile` sets
/// them); AV1's `av1C` record or its sequence header OBU (seq_profile).
fn profile_of(id: codec::Id, extradata: &[u8]) -> Option<i32> {
    match id {
        codec::Id::H264 => {
            let sps = match extradata.first()? {
                // avcC: version 1, then profile_idc and the constraint flags.
                1 => extradata.get(1..3)?,
                // Annex B: the bytes after the SPS NAL unit's header.
                _ => {
                    let at = (3..extradata.len())
                        .find(|&i| extradata[i - 3..i] == [0, 0, 1] && extradata[i] & 0x1f == 7)?;
                    extradata.get(at + 1..at + 3)?
                }
            };
            let (idc, flags) = (i32::from(sps[0]), sps[1]);
            let (set1, set3) = (flags & 0x40 != 0, flags & 0x10 != 0);
            Some(match idc {
                66 if set1 => idc | H264_CONSTRAINED,
                110 | 122 | 244 if set3 => idc | H264_INTRA,
                _ => idc,
            })
        }
        codec::Id::AV1 => {
            let first = *extradata.first()?;
            if first & 0x80 != 0 {
                // av1C: marker and version, then seq_profile in the top 3 bits.
                return extradata.get(1).map(|b| i32::from(b >> 5));
            }
            // A sequence header OBU: its header (type 1), an optional extension byte, its
            // size (leb128) when flagged, then seq_profile in the top 3 bits.
            if (first >> 3) & 0x0f != 1 {
                return None;
            }
            let mut at = 1 + usize::from(first & 0x04 != 0);
            if first & 0x02 != 0 {
                while *extradata.get(at)? & 0x80 != 0 {
                    at += 1;
                }
                at += 1;
            }
            extradata.get(at).map(|b| i32::from(b >> 5))
        }
        _ => None,
    }
}

/// An FFmpeg error as a message that says what failed.
fn e(what: &str) -> impl Fn(ff::Error) -> String + '_ {
    move |err| format!("{what}: {err}")
}

/// The encoder of one stream, opened: one thread, yuv420p in `tv` range, the settings' GOP and
/// options ([`encoder_options`]), bit-exact.
fn open_encoder(
    codec: ff::Codec,
    shape: StreamShape,
    s: &VideoSettings,
    asm: Option<&str>,
    global_header: bool,
) -> Result<encoder::Video, String> {
    let frame_rate = rate(shape.fps);
    let mut ctx = codec::context::Context::new_with_codec(codec);
    ctx.set_threading(codec::threading::Config {
        kind: codec::threading::Type::None,
        count: 1,
        ..Default::default()
    });
    let mut enc = ctx.encoder().video().map_err(e("video encoder"))?;
    enc.set_width(shape.width as u32);
    enc.set_height(shape.height as u32);
    enc.set_format(format::Pixel::YUV420P);
    enc.set_time_base(frame_rate.invert());
    enc.set_frame_rate(Some(frame_rate));
    enc.set_gop(s.gop);
    enc.set_color_range(ff::color::Range::MPEG);
    let mut flags = codec::Flags::BITEXACT;
    if global_header {
        flags |= codec::Flags::GLOBAL_HEADER;
    }
    // Closed GOPs when asked: libavcodec's SVT-AV1 and x264 wrappers otherwise ask for open ones
    // (SVT-AV1's intra frames are then not keyframes: a file's only random-access point is its
    // first frame; x264's frames shown before a keyframe refer to the GOP before it, so decoding
    // from there reports missing references).
    if s.closed_gop {
        flags |= codec::Flags::CLOSED_GOP;
    }
    let quality = mpeg4_quality(s);
    if quality > 0 {
        flags |= codec::Flags::QSCALE;
        enc.set_global_quality(quality);
    }
    enc.set_flags(flags);
    let mut opts = Dictionary::new();
    for (key, value) in encoder_options(s, asm) {
        opts.set(key, &value);
    }
    let name = s.codec.name();
    enc.open_with(opts).map_err(|err| {
        let hint = refusal_hint(s, shape);
        format!("cannot open the {name} encoder: {err}{hint}")
    })
}
