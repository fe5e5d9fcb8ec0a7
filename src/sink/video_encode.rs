// Long file: one encoder: FFmpeg's set-up, the frame conversion and the muxer, behind the feature and its stub.
//! Video encoding of camera frames: RGB24 frames → yuv420p (libswscale) → AV1 (SVT-AV1) or
//! H.264 (x264) in an mp4 (libavformat), one file per camera, as LeRobot records its datasets.
//!
//! Why it looks the way it does:
//!
//! - **LeRobot's settings**: `encode_video_frames` in lerobot 0.4.4 uses libsvtav1, yuv420p,
//!   `g=2`, `crf=30`, `preset=12`; chunkc uses the same by default ([`crate::spec::VideoSettings`]).
//!   The pixels go through libswscale's bilinear RGB → BT.601 limited-range conversion, what
//!   PyAV's `VideoFrame.reformat` does for LeRobot, and the stream is tagged `tv` range.
//! - **Deterministic bytes**: an encoder that splits its work over threads may make different
//!   decisions on different runs. Each stream is encoded with one thread (`thread_count = 1`,
//!   SVT-AV1's `lp=1`, x264's `threads=1`); parallelism comes from encoding the cameras side by
//!   side ([`Background`]), so the bytes are the same for any `-j`. x264 is also told
//!   `cpu-independent=1` ([`X264_PARAMS`]): its macroblock-tree rate control then runs its
//!   portable code, not the code chosen for this CPU. Without it, x264 r3095's AVX-512 path
//!   makes decisions from heap memory it never wrote: the same frames, encoded in threads whose
//!   heaps held different leftovers, gave 2 to 4 different files of 32, and builds varied run to
//!   run whenever an encoder ran beside other work; and x264 with its assembly turned off
//!   wrote other bytes than with it, so which code a CPU gets changed the file. The
//!   container carries no wall clock and no library version: libavformat's and libavcodec's
//!   `bitexact` flags drop the `encoder` tags, and mp4's `creation_time` stays unset (0).
//! - **Streaming**: frames are converted and encoded as they arrive, packets are written as the
//!   encoder gives them back; memory holds a few frames and the encoder's look-ahead, never an
//!   episode's video. [`Background`] bounds the frames queued for its thread.
//!
//! Frame `i` of a file has presentation time `i / fps`: a LeRobot v3.0 file holding many
//! episodes locates episode `e` at `from_timestamp = first row of e / fps`.
//!
//! Without the `video` cargo feature, creating a stream is an error that names the feature.

use std::path::{Path, PathBuf};
use std::sync::mpsc;

use crate::error::{Error, Result};
use crate::spec::{VideoCodec, VideoSettings};

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

/// Frames (episodes) queued for a [`Background`] encoder before `push` waits.
const QUEUE: usize = 2;

/// The geometry and rate of a stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamShape {
    pub height: usize,
    pub width: usize,
    pub fps: f64,
}

impl StreamShape {
    fn frame_bytes(&self) -> usize {
        self.height * self.width * 3
    }
}

/// One mp4 being written, frame by frame, on the calling thread.
pub struct VideoStream {
    path: PathBuf,
    shape: StreamShape,
    frames: u64,
    #[cfg(feature = "video")]
    inner: imp::Inner,
}

impl VideoStream {
    /// Creates `path` (its directory must exist) for RGB24 frames of `shape`.
    pub fn create(path: &Path, shape: StreamShape, settings: VideoSettings) -> Result<Self> {
        Self::create_on(path, shape, settings, None)
    }

    /// [`Self::create`] with x264 limited to the instruction sets `asm` names (x264's `asm`
    /// option; `0`: none), as a machine without the others would encode.
    #[cfg(all(test, feature = "video"))]
    fn create_with_asm(
        path: &Path,
        shape: StreamShape,
        settings: VideoSettings,
        asm: &str,
    ) -> Result<Self> {
        Self::create_on(path, shape, settings, Some(asm))
    }

    fn create_on(
        path: &Path,
        shape: StreamShape,
        settings: VideoSettings,
        asm: Option<&str>,
    ) -> Result<Self> {
        let fail = |m: String| Error::output(format!("{}: {m}", path.display()));
        if shape.height < 2
            || shape.width < 2
            || !shape.height.is_multiple_of(2)
            || !shape.width.is_multiple_of(2)
        {
            return Err(fail(format!(
                "cannot encode {}x{} frames as {PIX_FMT} video: height and width must be even \
                 and at least 2",
                shape.height, shape.width
            )));
        }
        #[cfg(feature = "video")]
        {
            let inner = imp::Inner::create(path, shape, settings, asm).map_err(fail)?;
            Ok(VideoStream {
                path: path.to_path_buf(),
                shape,
                frames: 0,
                inner,
            })
        }
        #[cfg(not(feature = "video"))]
        {
            let _ = (settings, asm);
            Err(fail(
                "writing video needs a chunkc built with the `video` cargo feature".into(),
            ))
        }
    }

    /// Encodes one frame (`height * width * 3` bytes, HWC).
    pub fn push(&mut self, frame: &[u8]) -> Result<()> {
        if frame.len() != self.shape.frame_bytes() {
            return Err(Error::Internal(format!(
                "{}: a frame of {} bytes, expected {}",
                self.path.display(),
                frame.len(),
                self.shape.frame_bytes()
            )));
        }
        #[cfg(feature = "video")]
        self.inner
            .push(frame, self.frames as i64)
            .map_err(|e| Error::output(format!("{}: {e}", self.path.display())))?;
        self.frames += 1;
        Ok(())
    }

    /// Encodes `frames` (back to back) in order.
    pub fn push_all(&mut self, frames: &[u8]) -> Result<()> {
        for f in frames.chunks(self.shape.frame_bytes().max(1)) {
            self.push(f)?;
        }
        Ok(())
    }

    /// Drains the encoder and completes the file; returns the number of frames.
    pub fn finish(self) -> Result<u64> {
        #[cfg(feature = "video")]
        self.inner
            .finish()
            .map_err(|e| Error::output(format!("{}: {e}", self.path.display())))?;
        Ok(self.frames)
    }
}

/// A [`VideoStream`] encoded on a thread of its own, so that several cameras encode side by
/// side while the caller goes on; at most [`QUEUE`] batches of frames wait for it.
///
/// Dropped without [`Background::finish`] (the build failed elsewhere), the stream is abandoned,
/// neither flushed nor closed: its file is in the staging directory, which goes, and SVT-AV1 1.4
/// never returns from a flush of an encoder that was sent no frame, nor from the deinit of an
/// encoder that was not flushed.
pub struct Background {
    send: Option<mpsc::SyncSender<Vec<u8>>>,
    thread: Option<std::thread::JoinHandle<Result<u64>>>,
    abandoned: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl Background {
    pub fn spawn(path: &Path, shape: StreamShape, settings: VideoSettings) -> Result<Self> {
        use std::sync::atomic::Ordering;
        let mut stream = VideoStream::create(path, shape, settings)?;
        let (send, recv) = mpsc::sync_channel::<Vec<u8>>(QUEUE);
        let abandoned = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let flag = abandoned.clone();
        let thread = std::thread::Builder::new()
            .name("chunkc-video".into())
            .spawn(move || {
                for frames in recv {
                    stream.push_all(&frames)?;
                }
                if flag.load(Ordering::SeqCst) {
                    // Leaked: SVT-AV1 1.4 hangs in its flush of an encoder sent no frame, and
                    // in its deinit of one never flushed. The process is about to report the
                    // build's error and exit.
                    std::mem::forget(stream);
                    return Err(Error::Internal("video stream abandoned".into()));
                }
                stream.finish()
            })
            .map_err(|e| Error::Internal(format!("cannot start a video encoder thread: {e}")))?;
        Ok(Background {
            send: Some(send),
            thread: Some(thread),
            abandoned,
        })
    }

    /// Queues frames (back to back) for encoding; waits while the queue is full. An encoder
    /// that failed reports its error here.
    pub fn push(&mut self, frames: Vec<u8>) -> Result<()> {
        let sent = self.send.as_ref().map(|s| s.send(frames).is_ok());
        if sent == Some(true) {
            return Ok(());
        }
        // The thread stopped: it failed; its error says why.
        self.finish().map(|_| ())?;
        Err(Error::Internal("video encoder stopped early".into()))
    }

    /// Waits for every queued frame to be encoded and the file completed.
    pub fn finish(&mut self) -> Result<u64> {
        drop(self.send.take());
        match self.thread.take() {
            Some(t) => t
                .join()
                .map_err(|_| Error::Internal("a video encoder thread panicked".into()))?,
            None => Err(Error::Internal("video encoder already finished".into())),
        }
    }
}

impl Drop for Background {
    fn drop(&mut self) {
        (self.abandoned).store(true, std::sync::atomic::Ordering::SeqCst);
        drop(self.send.take());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(feature = "video")]
mod imp {
    //! The FFmpeg side: one output context, one encoder, one scaler per stream.

    use std::path::Path;
    use std::sync::Once;

    use ff::{codec, encoder, format, frame, software::scaling, Dictionary, Packet, Rational};
    use ffmpeg_next as ff;

    use super::StreamShape;
    use crate::spec::{VideoCodec, VideoSettings};

    use super::{SVTAV1_PRESET, X264_PARAMS};

    /// libavcodec's `FF_QP2LAMBDA`: a quantizer as the encoder's `quality` (lambda).
    const QP2LAMBDA: i32 = 118;

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
        // Long function: FFmpeg's set-up sequence (format, stream, codec options, scaler), each step with its own error.
        pub fn create(
            path: &Path,
            shape: StreamShape,
            s: VideoSettings,
            asm: Option<&str>,
        ) -> Result<Self, String> {
            init()?;
            fn e(what: &str) -> impl Fn(ff::Error) -> String + '_ {
                move |err| format!("{what}: {err}")
            }
            let mut octx = format::output_as(path, "mp4").map_err(e("cannot create the mp4"))?;
            let global_header = octx.format().flags().contains(format::Flags::GLOBAL_HEADER);
            let name = s.codec.name();
            let codec = encoder::find_by_name(name).ok_or_else(|| {
                format!("this FFmpeg has no `{name}` encoder (`ffmpeg -encoders` lists them)")
            })?;
            let frame_rate = rate(shape.fps);
            let time_base = frame_rate.invert();
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
            enc.set_time_base(time_base);
            enc.set_frame_rate(Some(frame_rate));
            enc.set_gop(s.gop);
            enc.set_color_range(ff::color::Range::MPEG);
            let mut flags = codec::Flags::BITEXACT;
            if global_header {
                flags |= codec::Flags::GLOBAL_HEADER;
            }
            // Closed GOPs when asked: libavcodec's SVT-AV1 and x264 wrappers otherwise ask for
            // open ones (SVT-AV1's intra frames are then not keyframes: a file's only
            // random-access point is its first frame; x264's frames shown before a keyframe
            // refer to the GOP before it, so decoding from there reports missing references).
            if s.closed_gop {
                flags |= codec::Flags::CLOSED_GOP;
            }
            enc.set_flags(flags);
            let mut opts = Dictionary::new();
            let mut quality = 0;
            match s.codec {
                VideoCodec::Libsvtav1 => {
                    opts.set("crf", &s.crf.to_string());
                    opts.set("preset", &SVTAV1_PRESET.to_string());
                    // One thread, no core pinning: the same decisions on every run.
                    opts.set("svtav1-params", "lp=1");
                }
                // A fixed quantizer (`-q:v`): MPEG-4 Part 2 has no constant rate factor.
                VideoCodec::Mpeg4 => {
                    quality = QP2LAMBDA * s.crf.max(1) as i32;
                    enc.set_flags(flags | codec::Flags::QSCALE);
                    enc.set_global_quality(quality);
                }
                VideoCodec::Libx264 => {
                    opts.set("crf", &s.crf.to_string());
                    opts.set("threads", "1");
                    let params = match asm {
                        Some(asm) => format!("{X264_PARAMS}:asm={asm}"),
                        None => X264_PARAMS.to_string(),
                    };
                    opts.set("x264-params", &params);
                }
            }
            let encoder = enc.open_with(opts).map_err(|err| {
                // SVT-AV1 before 2.0 (Debian 12 has 1.4) takes nothing under 64x64.
                let small =
                    s.codec == VideoCodec::Libsvtav1 && (shape.height < 64 || shape.width < 64);
                let hint = if small {
                    let instead = if crate::spec::HAS_X264 {
                        "`video_codec = \"libx264\"` takes them"
                    } else {
                        "resize them with `cameras`, or store them as `jpeg` or `png`"
                    };
                    format!(
                        " ({}x{} frames: this SVT-AV1 may need at least 64x64; {instead})",
                        shape.height, shape.width
                    )
                } else {
                    String::new()
                };
                format!("cannot open the {name} encoder: {err}{hint}")
            })?;
            {
                let mut ost = octx.add_stream(codec).map_err(e("cannot add the stream"))?;
                ost.set_parameters(&encoder);
                ost.set_time_base(time_base);
                ost.set_rate(frame_rate);
                ost.set_avg_frame_rate(frame_rate);
            }
            let mut header = Dictionary::new();
            header.set("fflags", "+bitexact");
            // The index first, so that players (and the Hub's viewer) start without a seek.
            header.set("movflags", "+faststart");
            octx.write_header_with(header)
                .map_err(e("cannot write the mp4 header"))?;
            let stream_time_base = octx.stream(0).expect("added").time_base();
            let (w, h) = (shape.width as u32, shape.height as u32);
            let scaler = scaling::Context::get(
                format::Pixel::RGB24,
                w,
                h,
                format::Pixel::YUV420P,
                w,
                h,
                scaling::Flags::BILINEAR,
            )
            .map_err(e("cannot convert RGB24 to yuv420p"))?;
            Ok(Inner {
                quality,
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
            let row = self.rgb.width() as usize * 3;
            let stride = self.rgb.stride(0);
            let data = self.rgb.data_mut(0);
            for (y, src) in pixels.chunks(row).enumerate() {
                data[y * stride..y * stride + row].copy_from_slice(src);
            }
            self.scaler
                .run(&self.rgb, &mut self.yuv)
                .map_err(|e| format!("converting a frame to yuv420p: {e}"))?;
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
}

#[cfg(all(test, feature = "video"))]
mod tests {
    use super::*;

    fn settings() -> VideoSettings {
        VideoSettings {
            codec: VideoCodec::Libsvtav1,
            crf: 30,
            gop: 2,
            copy: crate::spec::StreamCopy::Never,
            copy_gop: None,
            closed_gop: false,
        }
    }

    fn write(path: &Path, n: usize) -> u64 {
        let shape = StreamShape {
            height: 64,
            width: 96,
            fps: 10.0,
        };
        let mut s = VideoStream::create(path, shape, settings()).unwrap();
        for i in 0..n {
            let frame: Vec<u8> = (0..64 * 96 * 3)
                .map(|p| ((p / 3 % 96 + i * 4) % 256) as u8)
                .collect();
            s.push(&frame).unwrap();
        }
        s.finish().unwrap()
    }

    #[test]
    fn the_same_frames_give_the_same_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.mp4"), dir.path().join("b.mp4"));
        assert_eq!(write(&a, 7), 7);
        // In the background, while another stream is written here.
        let mut bg = Background::spawn(
            &b,
            StreamShape {
                height: 64,
                width: 96,
                fps: 10.0,
            },
            settings(),
        )
        .unwrap();
        let frames: Vec<u8> = (0..7)
            .flat_map(|i| (0..64 * 96 * 3).map(move |p| ((p / 3 % 96 + i * 4) % 256) as u8))
            .collect();
        bg.push(frames).unwrap();
        write(&dir.path().join("c.mp4"), 3);
        assert_eq!(bg.finish().unwrap(), 7);
        let (a, b) = (std::fs::read(a).unwrap(), std::fs::read(b).unwrap());
        assert!(a.len() > 100);
        assert!(a == b, "two encodes of the same frames differ");
        // No library version in the container.
        assert!(!a.windows(4).any(|w| w == b"Lavf"));
    }

    /// hdf5 `video` storage's encoder, on frames with detail and motion.
    fn x264_file(path: &Path, asm: Option<&str>) -> Vec<u8> {
        let shape = StreamShape {
            height: 64,
            width: 96,
            fps: 50.0,
        };
        let settings = crate::spec::STORAGE_VIDEO;
        let mut s = match asm {
            None => VideoStream::create(path, shape, settings),
            Some(asm) => VideoStream::create_with_asm(path, shape, settings, asm),
        }
        .unwrap();
        let mut state = 1u64;
        for i in 0..38 {
            let frame: Vec<u8> = (0..64 * 96 * 3)
                .map(|p| {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    ((p / 3 % 96) * 3 + i * 5 + (state >> 60) as usize) as u8
                })
                .collect();
            s.push(&frame).unwrap();
        }
        s.finish().unwrap();
        std::fs::read(path).unwrap()
    }

    #[test]
    fn x264_bytes_do_not_depend_on_what_the_heap_held() {
        // Each encode runs on a new thread whose heap was first filled with other bytes and
        // freed. x264's AVX-512 code used to read such leftovers (2 to 4 distinct files of 32).
        let dir = tempfile::tempdir().unwrap();
        let files: Vec<Vec<u8>> = (0..32u8)
            .map(|k| {
                let path = dir.path().join(format!("{k}.mp4"));
                std::thread::spawn(move || {
                    let dirt: Vec<Vec<u8>> = (0..4000)
                        .map(|i| {
                            vec![k.wrapping_mul(37).wrapping_add(i as u8); 16 + i * 37 % 20000]
                        })
                        .collect();
                    drop(dirt);
                    x264_file(&path, None)
                })
                .join()
                .unwrap()
            })
            .collect();
        let distinct: std::collections::BTreeSet<&Vec<u8>> = files.iter().collect();
        assert_eq!(
            distinct.len(),
            1,
            "{} different files of 32",
            distinct.len()
        );
    }

    #[test]
    fn x264_bytes_do_not_depend_on_the_cpu() {
        // What this machine runs, a machine without AVX-512, and x264's C code alone.
        let dir = tempfile::tempdir().unwrap();
        let native = x264_file(&dir.path().join("native.mp4"), None);
        let avx2 = "MMX2,SSE,SSE2,SSE2Fast,LZCNT,SSE3,SSSE3,SSE4.1,SSE4.2,AVX,FMA3,BMI1,BMI2,AVX2";
        for asm in [avx2, "0"] {
            let other = x264_file(&dir.path().join("other.mp4"), Some(asm));
            assert!(other == native, "x264 limited to `{asm}` wrote other bytes");
        }
    }

    #[test]
    fn a_stream_dropped_unfinished_is_abandoned_not_flushed() {
        // A build that fails elsewhere drops its encoders; SVT-AV1 1.4 hung in the flush of an
        // encoder that had been sent no frame (and so did the failed build).
        let dir = tempfile::tempdir().unwrap();
        let shape = StreamShape {
            height: 64,
            width: 96,
            fps: 10.0,
        };
        let start = std::time::Instant::now();
        drop(Background::spawn(&dir.path().join("none.mp4"), shape, settings()).unwrap());
        let mut some = Background::spawn(&dir.path().join("some.mp4"), shape, settings()).unwrap();
        some.push(vec![9u8; 64 * 96 * 3 * 3]).unwrap();
        drop(some);
        assert!(start.elapsed() < std::time::Duration::from_secs(20));
    }

    #[test]
    fn mpeg4_encodes_what_svtav1_refuses() {
        // The LeRobot exports' codec for a camera under 64 pixels in a build without x264.
        let dir = tempfile::tempdir().unwrap();
        let shape = StreamShape {
            height: 32,
            width: 32,
            fps: 10.0,
        };
        let mpeg4 = VideoSettings {
            codec: VideoCodec::Mpeg4,
            crf: 3,
            gop: 2,
            ..settings()
        };
        let write = |name: &str| {
            let path = dir.path().join(name);
            let mut s = VideoStream::create(&path, shape, mpeg4).unwrap();
            for i in 0..5u8 {
                s.push(&vec![i * 40; 32 * 32 * 3]).unwrap();
            }
            assert_eq!(s.finish().unwrap(), 5);
            std::fs::read(path).unwrap()
        };
        let (a, b) = (write("a.mp4"), write("b.mp4"));
        assert!(a.len() > 100 && a == b);
        assert!(
            !a.windows(4).any(|w| w == b"Lavc"),
            "no encoder version in the stream"
        );
        let small = VideoStream::create(&dir.path().join("svt.mp4"), shape, settings());
        assert!(small.is_err(), "SVT-AV1 1.4 refuses 32x32 frames");
    }

    #[test]
    fn odd_sizes_are_refused_with_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("odd.mp4");
        let shape = StreamShape {
            height: 63,
            width: 96,
            fps: 10.0,
        };
        let err = VideoStream::create(&path, shape, settings())
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("odd.mp4") && err.contains("even"), "{err}");
    }
}
