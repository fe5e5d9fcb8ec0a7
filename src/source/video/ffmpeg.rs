//! The FFmpeg side (feature `video`): demuxing, decoding and RGB conversion through
//! `ffmpeg-next` and the system libraries.
//!
//! What LeRobot's pyav backend does, and so what this does:
//! - **Seek**: `container.seek(round(t / time_base), backward=True, any_frame=False, stream)`,
//!   i.e. `av_seek_frame(…, AVSEEK_FLAG_BACKWARD)` to the keyframe at or before the first row's
//!   time; then decode forward. Here: one seek per episode (only when its first row is not at
//!   the file's start, as in v3.0 files shared by many episodes), then sequential decoding to
//!   the episode's last row, never a seek per frame.
//! - **Frame time**: `frame.pts × time_base` (`AVFrame.pts`; the best-effort timestamp when a
//!   decoder leaves `pts` unset).
//! - **RGB**: `frame.to_rgb()` → `VideoReformatter.reformat(format="rgb24")`, which calls
//!   `sws_getCachedContext(w, h, src, w, h, RGB24, SWS_BILINEAR, NULL, NULL, NULL)` and, since
//!   source and destination colorspace and range are both left unset, never
//!   `sws_setColorspaceDetails`: libswscale's defaults, BT.601 matrix, range from the pixel
//!   format (`yuvj*` full, else limited), whatever the stream's colour tags say. Here: the same
//!   `sws_getContext` call.
//! - **Threads**: one decoder thread per file; files and cameras are decoded side by side by
//!   the caller (decoders are bit-exact, so this changes no value).

use std::path::Path;
use std::sync::Once;

use ff::format::Pixel;
use ff::packet::Ref as _;
use ff::software::scaling;
use ffmpeg_next as ff;

use super::select::{Pick, Selector};
use super::{DecodeFailure, Probe, Timeline};

fn init() {
    static INIT: Once = Once::new();
    INIT.call_once(|| {
        let _ = ff::init();
        // Our messages name the file and the episode; FFmpeg's own log would interleave
        // across threads.
        ff::util::log::set_level(ff::util::log::Level::Quiet);
    });
}

struct Opened {
    input: ff::format::context::Input,
    stream: usize,
    time_base: (i32, i32),
    declared: i64,
    params: ff::codec::Parameters,
    probe: Probe,
}

fn open(path: &Path) -> Result<Opened, String> {
    init();
    let input = ff::format::input(path).map_err(|e| match e {
        ff::Error::InvalidData => {
            format!("not a readable video file ({e}): truncated before its index, or not a video")
        }
        e => format!("the file cannot be opened as a video: {e}"),
    })?;
    let stream = input
        .streams()
        .best(ff::media::Type::Video)
        .ok_or_else(|| "the file holds no video stream".to_string())?;
    let tb = stream.time_base();
    let params = stream.parameters();
    let (width, height) = unsafe {
        let p = params.as_ptr();
        ((*p).width.max(0) as usize, (*p).height.max(0) as usize)
    };
    let probe = Probe {
        codec: params.id().name().to_string(),
        width,
        height,
    };
    Ok(Opened {
        stream: stream.index(),
        time_base: (tb.numerator(), tb.denominator()),
        declared: stream.frames(),
        params,
        probe,
        input,
    })
}

fn seconds(pts: i64, (num, den): (i32, i32)) -> f64 {
    pts as f64 * f64::from(num) / f64::from(den)
}

/// Whether libavformat marked the packet to be dropped (an edit list's lead-in).
fn discarded(packet: &ff::Packet) -> bool {
    unsafe { (*packet.as_ptr()).flags & ff::ffi::AV_PKT_FLAG_DISCARD != 0 }
}

pub fn probe(path: &Path) -> Result<Probe, String> {
    Ok(open(path)?.probe)
}

pub fn timeline(path: &Path) -> Result<Timeline, String> {
    let mut o = open(path)?;
    let mut times = Vec::new();
    let mut read = 0i64;
    let mut cut = None;
    loop {
        let mut packet = ff::Packet::empty();
        match packet.read(&mut o.input) {
            Ok(()) => {}
            Err(ff::Error::Eof) => break,
            Err(e) => {
                cut = Some(format!(
                    "reading stopped after {read} frames ({e}): the file is truncated or damaged"
                ));
                break;
            }
        }
        if packet.stream() != o.stream {
            continue;
        }
        read += 1;
        if discarded(&packet) {
            continue;
        }
        if let Some(pts) = packet.pts().or(packet.dts()) {
            times.push(seconds(pts, o.time_base));
        }
    }
    if cut.is_none() && o.declared > 0 && read < o.declared {
        cut = Some(format!(
            "only {read} of the {} frames its header lists are readable: the file is truncated",
            o.declared
        ));
    }
    times.sort_by(f64::total_cmp);
    Ok(Timeline {
        probe: o.probe,
        times,
        cut,
    })
}

/// Decodes the frames rows `targets` (seconds, one per row) select into `out`
/// (`rows × h × w × 3` bytes), streaming: two RGB frames held at a time.
pub fn decode_rows(
    path: &Path,
    targets: &[f64],
    [h, w, c]: [usize; 3],
    out: &mut [u8],
) -> Result<(), DecodeFailure> {
    let bad = DecodeFailure::Unreadable;
    if c != 3 {
        return Err(bad(format!(
            "info.json gives {c} channels; chunkc decodes videos to RGB (3)"
        )));
    }
    let frame_bytes = h * w * 3;
    debug_assert_eq!(out.len(), targets.len() * frame_bytes);
    let mut o = open(path).map_err(bad)?;
    if (o.probe.width, o.probe.height) != (w, h) && o.probe.width > 0 {
        return Err(bad(format!(
            "frames are {}x{} (width x height), info.json says {w}x{h}",
            o.probe.width, o.probe.height
        )));
    }
    let mut decoder = open_decoder(&o).map_err(bad)?;
    let mut selector = Selector::new(targets);
    if let Some(first) = selector.first_target().filter(|&t| t > 0.0) {
        seek(&mut o, first).map_err(bad)?;
    }
    let mut state = Convert::new(w, h);
    let mut packets = 0usize;
    let mut ended = false;
    while !selector.done() {
        if !ended {
            match feed(&mut o, &mut decoder, &mut packets).map_err(bad)? {
                Fed::Packet => {}
                Fed::OtherStream => continue,
                Fed::End => ended = true,
            }
        }
        let mut rows = Rows {
            selector: &mut selector,
            out: &mut *out,
            time_base: o.time_base,
        };
        let got = rows.take(&mut decoder, &mut state, packets).map_err(bad)?;
        if ended && !got {
            break;
        }
    }
    let prev = &state.previous;
    selector.finish(|row| {
        out[row * frame_bytes..(row + 1) * frame_bytes].copy_from_slice(prev);
    });
    match selector.first_miss() {
        Some(miss) => Err(DecodeFailure::Miss(miss)),
        None => Ok(()),
    }
}

/// The stream's decoder, on one thread.
fn open_decoder(o: &Opened) -> Result<ff::codec::decoder::Video, String> {
    let mut ctx = ff::codec::context::Context::from_parameters(o.params.clone())
        .map_err(|e| format!("no decoder for codec `{}`: {e}", o.probe.codec))?;
    ctx.set_threading(ff::codec::threading::Config {
        kind: ff::codec::threading::Type::Frame,
        count: 1,
        ..Default::default()
    });
    ctx.decoder()
        .video()
        .map_err(|e| format!("cannot open the `{}` decoder: {e}", o.probe.codec))
}

/// Seeks to the keyframe at or before `first` seconds, as PyAV's `container.seek` does.
fn seek(o: &mut Opened, first: f64) -> Result<(), String> {
    seek_back(&mut o.input, o.stream, o.time_base, first)
}

/// Seeks `input` to the keyframe of `stream` (time base `num/den`) at or before `first`
/// seconds (`av_seek_frame` with `AVSEEK_FLAG_BACKWARD`): reading then starts there, not at the
/// file's start.
pub fn seek_back(
    input: &mut ff::format::context::Input,
    stream: usize,
    (num, den): (i32, i32),
    first: f64,
) -> Result<(), String> {
    let offset = (first * f64::from(den) / f64::from(num)).round_ties_even() as i64;
    let ret = unsafe {
        ff::ffi::av_seek_frame(
            input.as_mut_ptr(),
            stream as i32,
            offset,
            ff::ffi::AVSEEK_FLAG_BACKWARD,
        )
    };
    if ret < 0 {
        return Err(format!(
            "seeking to {first} s failed: {}",
            ff::Error::from(ret)
        ));
    }
    Ok(())
}

/// What [`feed`] did with the next packet of the file.
enum Fed {
    /// A packet of the video stream went to the decoder.
    Packet,
    /// A packet of another stream, skipped.
    OtherStream,
    /// The file ended: the decoder was told to give back what it holds.
    End,
}

/// Reads the next packet and sends it to the decoder when it is the video stream's; `packets`
/// counts those sent.
fn feed(
    o: &mut Opened,
    decoder: &mut ff::codec::decoder::Video,
    packets: &mut usize,
) -> Result<Fed, String> {
    let mut packet = ff::Packet::empty();
    match packet.read(&mut o.input) {
        Ok(()) if packet.stream() != o.stream => Ok(Fed::OtherStream),
        Ok(()) => {
            *packets += 1;
            decoder
                .send_packet(&packet)
                .map_err(|e| format!("decoding failed at packet {packets}: {e}"))?;
            Ok(Fed::Packet)
        }
        Err(ff::Error::Eof) => {
            let _ = decoder.send_eof();
            Ok(Fed::End)
        }
        Err(e) => Err(format!(
            "reading stopped after {packets} packets ({e}): the file is truncated or damaged"
        )),
    }
}

/// The rows being filled: each decoded frame, converted, goes to the rows LeRobot's frame
/// selection gives it.
struct Rows<'a> {
    selector: &'a mut Selector,
    out: &'a mut [u8],
    time_base: (i32, i32),
}

impl Rows<'_> {
    /// Takes every frame the decoder has ready (until the selection is done); whether there was
    /// one. `packets` (sent so far) is for messages.
    fn take(
        &mut self,
        decoder: &mut ff::codec::decoder::Video,
        state: &mut Convert,
        packets: usize,
    ) -> Result<bool, String> {
        let mut got = false;
        loop {
            match decoder.receive_frame(&mut state.frame) {
                Ok(()) => {
                    got = true;
                    let pts = state.frame.pts().or(state.frame.timestamp());
                    let Some(pts) = pts else { continue };
                    let time = seconds(pts, self.time_base);
                    state.convert()?;
                    let frame_bytes = state.current.len();
                    let (prev, cur) = (&state.previous, &state.current);
                    let out = &mut *self.out;
                    self.selector.push(time, |row, pick| {
                        let src = match pick {
                            Pick::Previous => prev,
                            Pick::Current => cur,
                        };
                        out[row * frame_bytes..(row + 1) * frame_bytes].copy_from_slice(src);
                    });
                    std::mem::swap(&mut state.previous, &mut state.current);
                    if self.selector.done() {
                        break;
                    }
                }
                Err(ff::Error::Other { errno }) if errno == ff::util::error::EAGAIN => break,
                Err(ff::Error::Eof) => break,
                Err(e) => return Err(format!("decoding failed after packet {packets}: {e}")),
            }
        }
        Ok(got)
    }
}

/// The decoded frame and its RGB conversion (as PyAV makes it).
struct Convert {
    scaler: Option<(scaling::Context, Pixel, u32, u32)>,
    /// RGB rows of the previous frame and of the one just decoded, packed (`w × 3` a row).
    previous: Vec<u8>,
    current: Vec<u8>,
    rgb: ff::frame::Video,
    frame: ff::frame::Video,
    shape: (usize, usize),
}

impl Convert {
    fn new(w: usize, h: usize) -> Convert {
        Convert {
            scaler: None,
            previous: vec![0u8; w * h * 3],
            current: vec![0u8; w * h * 3],
            rgb: ff::frame::Video::empty(),
            frame: ff::frame::Video::empty(),
            shape: (w, h),
        }
    }

    fn convert(&mut self) -> Result<(), String> {
        let (fmt, fw, fh) = (self.frame.format(), self.frame.width(), self.frame.height());
        if (fw as usize, fh as usize) != self.shape {
            return Err(format!(
                "a frame is {fw}x{fh}, info.json says {}x{}",
                self.shape.0, self.shape.1
            ));
        }
        // sws_getCachedContext: a new context only when the input changes.
        if !matches!(&self.scaler, Some((_, f, w, h)) if (*f, *w, *h) == (fmt, fw, fh)) {
            let ctx =
                scaling::Context::get(fmt, fw, fh, Pixel::RGB24, fw, fh, scaling::Flags::BILINEAR)
                    .map_err(|e| format!("no conversion from {fmt:?} to rgb24: {e}"))?;
            self.scaler = Some((ctx, fmt, fw, fh));
            self.rgb = ff::frame::Video::empty();
        }
        let (scaler, ..) = self.scaler.as_mut().expect("made above");
        scaler
            .run(&self.frame, &mut self.rgb)
            .map_err(|e| format!("converting a frame to rgb24 failed: {e}"))?;
        let (w, h) = self.shape;
        let stride = self.rgb.stride(0);
        let data = self.rgb.data(0);
        for y in 0..h {
            self.current[y * w * 3..(y + 1) * w * 3]
                .copy_from_slice(&data[y * stride..y * stride + w * 3]);
        }
        Ok(())
    }
}
