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
//!
//! - `settings`: what every stream is encoded with (pixel format, codec options, the muxer's
//!   flags) and what the documents say of it.
//! - `ffmpeg`: the encode loop on FFmpeg's side (set-up, frame conversion, packets to the mp4).
//! - here: a stream on the calling thread ([`VideoStream`]) or on its own ([`Background`]).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};

use crate::error::{Error, Result};
use crate::spec::VideoSettings;

#[cfg(feature = "video")]
mod ffmpeg;
mod settings;

pub use settings::{codec_name, library_version, StreamShape, PIX_FMT, SVTAV1_PRESET, X264_PARAMS};

/// Frames (episodes) queued for a [`Background`] encoder before `push` waits.
const QUEUE: usize = 2;

/// One mp4 being written, frame by frame, on the calling thread.
pub struct VideoStream {
    path: PathBuf,
    shape: StreamShape,
    frames: u64,
    #[cfg(feature = "video")]
    inner: ffmpeg::Inner,
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
            let inner = ffmpeg::Inner::create(path, shape, settings, asm).map_err(fail)?;
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

    /// Encodes frames already converted by [`Yuv420p::of`], in order.
    pub fn push_yuv(&mut self, frames: &Yuv420p) -> Result<()> {
        let frame = yuv_frame_bytes(self.shape);
        if frames.shape != (self.shape.height, self.shape.width) {
            return Err(Error::Internal(format!(
                "{}: frames of {:?}, expected {}x{}",
                self.path.display(),
                frames.shape,
                self.shape.height,
                self.shape.width
            )));
        }
        for f in frames.planes.chunks(frame.max(1)) {
            #[cfg(feature = "video")]
            self.inner
                .push_yuv(f, self.frames as i64)
                .map_err(|e| Error::output(format!("{}: {e}", self.path.display())))?;
            #[cfg(not(feature = "video"))]
            let _ = f;
            self.frames += 1;
        }
        Ok(())
    }

    /// What the file holds (codec, profile, pixel format), from the encoder's own stream
    /// configuration.
    pub fn format(&self) -> Result<crate::sink::video_info::StreamFormat> {
        #[cfg(feature = "video")]
        {
            Ok(self.inner.format())
        }
        #[cfg(not(feature = "video"))]
        {
            Err(Error::output(format!(
                "{}: writing video needs a chunkc built with the `video` cargo feature",
                self.path.display()
            )))
        }
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

/// Bytes of one frame's yuv420p planes (no padding).
fn yuv_frame_bytes(shape: StreamShape) -> usize {
    shape.height * shape.width * 3 / 2
}

/// An episode's frames converted to yuv420p planes (each frame's Y, U and V back to back), as a
/// stream converts what it is pushed: half the memory of the RGB24 frames, so that an encoder
/// that waits for its thread holds half an episode, and the RGB24 frames go back to the pass.
pub struct Yuv420p {
    shape: (usize, usize),
    planes: Vec<u8>,
}

impl Yuv420p {
    /// Converts RGB24 `frames` (back to back) of `shape`, in parallel over blocks of frames.
    pub fn of(frames: &[u8], shape: StreamShape) -> Result<Yuv420p> {
        #[cfg(feature = "video")]
        {
            use rayon::prelude::*;
            const BLOCK: usize = 16;
            let (rgb, yuv) = (shape.frame_bytes().max(1), yuv_frame_bytes(shape).max(1));
            let mut planes = vec![0u8; frames.len() / rgb * yuv];
            let (w, h) = (shape.width as u32, shape.height as u32);
            frames
                .par_chunks(rgb * BLOCK)
                .zip(planes.par_chunks_mut(yuv * BLOCK))
                .try_for_each(|(src, out)| ffmpeg::to_yuv420p(src, w, h, out))
                .map_err(Error::output)?;
            Ok(Yuv420p {
                shape: (shape.height, shape.width),
                planes,
            })
        }
        #[cfg(not(feature = "video"))]
        {
            let _ = frames;
            Err(Error::output(format!(
                "{}x{} frames: writing video needs a chunkc built with the `video` cargo feature",
                shape.height, shape.width
            )))
        }
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
    send: Option<mpsc::SyncSender<Arc<Vec<u8>>>>,
    thread: Option<std::thread::JoinHandle<Result<u64>>>,
    abandoned: Arc<AtomicBool>,
}

impl Background {
    pub fn spawn(path: &Path, shape: StreamShape, settings: VideoSettings) -> Result<Self> {
        let mut stream = VideoStream::create(path, shape, settings)?;
        let (send, recv) = mpsc::sync_channel::<Arc<Vec<u8>>>(QUEUE);
        let abandoned = Arc::new(AtomicBool::new(false));
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

    /// Queues frames (back to back, shared with the caller rather than copied) for encoding;
    /// waits while the queue is full. An encoder that failed reports its error here.
    pub fn push(&mut self, frames: Arc<Vec<u8>>) -> Result<()> {
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
        self.abandoned.store(true, Ordering::SeqCst);
        drop(self.send.take());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(all(test, feature = "video"))]
mod tests;
