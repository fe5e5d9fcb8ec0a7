//! One video file per episode and camera, each copied from the source's packets where the
//! episode's frames are a source video's own ([`super::video_copy`]) or else encoded
//! ([`super::video_encode`]) on a thread of its own with a single-threaded encoder: what hdf5's
//! `image_compression = "video"` and LeRobot v2.1's `videos/` store. Either way a file's bytes
//! do not depend on `-j`; up to `-j` episodes are copied or encoded side by side while the build
//! goes on, each holding its episode's frames.

use std::collections::{BTreeMap, VecDeque};
use std::path::{Path, PathBuf};
use std::thread::JoinHandle;

use super::video_copy::{self, CopyOutcome, COPIED_CODECS};
use super::video_encode::{codec_name, StreamShape, VideoStream, Yuv420p};
use super::video_info::StreamFormat;
use super::Frames;
use crate::error::{Error, IoContext, Result};
use crate::source::video::PacketSpan;
use crate::spec::{StreamCopy, VideoSettings};

/// A camera stored as one video per episode: its name, stream shape and encoder settings.
#[derive(Debug, Clone)]
pub(super) struct EpisodeCamera {
    pub name: String,
    pub shape: StreamShape,
    pub settings: VideoSettings,
}

impl EpisodeCamera {
    /// The source packets to copy for `frames` instead of encoding them: when they are a
    /// video's own frames, at this camera's size, in a codec the profile lets it keep.
    fn to_copy(&self, frames: &Frames) -> Option<PacketSpan> {
        let span = frames.packets()?;
        let codec = span.probe.codec.as_str();
        let kept = match self.settings.copy {
            StreamCopy::Never => false,
            StreamCopy::AnyCodec => COPIED_CODECS.contains(&codec),
            StreamCopy::SameCodec => codec == codec_name(self.settings.codec),
        };
        let size = (span.probe.height, span.probe.width) == (self.shape.height, self.shape.width);
        (kept && size && span.frames == frames.len()).then(|| span.clone())
    }

    /// Whether [`Encoders::start`] will copy `frames` from their video packets, reading no
    /// pixel (the packets are read and checked as the copy checks them).
    pub(super) fn will_copy(&self, frames: &Frames) -> Result<bool> {
        match self.to_copy(frames) {
            None => Ok(false),
            Some(span) => Ok(video_copy::check(&span, self.shape.fps, self.copy_gop())?.is_none()),
        }
    }

    /// The longest keyframe interval a copy of the source's stream may have (`video_gop` when
    /// the spec sets it, else the source's own).
    fn copy_gop(&self) -> u32 {
        self.settings.copy_gop.unwrap_or(u32::MAX)
    }
}

/// One episode's file being encoded: its frames, and the format of the stream written.
struct Running {
    path: PathBuf,
    frames: u64,
    /// (channel position, episode id).
    of: (usize, u64),
    thread: JoinHandle<Result<(u64, StreamFormat)>>,
}

/// The episodes being copied or encoded, oldest first; at most `limit` at a time.
pub(super) struct Encoders {
    dir: PathBuf,
    limit: usize,
    running: VecDeque<Running>,
    /// Per (channel position, episode id) written: whether its file was copied.
    copied: BTreeMap<(usize, u64), bool>,
    /// Why copies were refused, with the episodes.
    refusals: BTreeMap<(usize, String), Vec<u64>>,
    /// Per channel position and format of the stream written (as FFmpeg reads it back), how
    /// many episodes' files hold it.
    formats: BTreeMap<(usize, StreamFormat), usize>,
}

impl Encoders {
    pub(super) fn new(dir: &Path) -> Encoders {
        Encoders {
            dir: dir.to_path_buf(),
            limit: rayon::current_num_threads().max(1),
            running: VecDeque::new(),
            copied: BTreeMap::new(),
            refusals: BTreeMap::new(),
            formats: BTreeMap::new(),
        }
    }

    /// Starts writing episode `id`'s frames of `channel` (position `at`) into `file` (relative
    /// to the directory), copied from the source or encoded, waiting for the oldest writer first
    /// when `limit` are running.
    pub(super) fn start(
        &mut self,
        (at, channel): (usize, &EpisodeCamera),
        (id, file): (u64, &str),
        frames: &Frames,
    ) -> Result<()> {
        while self.running.len() >= self.limit {
            self.wait_oldest()?;
        }
        let path = self.dir.join(file);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).at("create", parent)?;
        }
        let (shape, settings) = (channel.shape, channel.settings);
        // A copy reads packets, not pixels: it runs here, and only a refused one keeps a copy
        // of the episode's frames for its encoder (an episode of 640x480 frames is 400 MB).
        if let Some(span) = channel.to_copy(frames) {
            match video_copy::copy(&span, &path, shape.fps, channel.copy_gop())? {
                CopyOutcome::Copied { frames: n, format } => {
                    self.copied.insert((at, id), true);
                    *self.formats.entry((at, format)).or_default() += 1;
                    if n != frames.len() as u64 {
                        return Err(Error::Internal(format!(
                            "{}: {n} frames copied, {} expected",
                            path.display(),
                            frames.len()
                        )));
                    }
                    return Ok(());
                }
                CopyOutcome::Refused(why) => {
                    self.refusals.entry((at, why)).or_default().push(id);
                }
            }
        }
        if !frames.has_pixels() {
            // A shard checked the copy and left the pixels behind: the source changed since.
            let source = frames.packets().map(|s| s.file.display().to_string());
            return Err(Error::source(format!(
                "{}: episode {id}'s shard left its frames to a copy of the source's packets, \
                 which cannot be made now; the source video changed since the shards ran: run \
                 them again",
                source.unwrap_or_else(|| path.display().to_string())
            )));
        }
        // Converted here, so that the encoder holds half the memory of the frames, which stay
        // with the pass (the next episode's decode reuses them).
        let yuv = Yuv420p::of(frames.bytes(), shape)?;
        let file = path.clone();
        let thread = std::thread::Builder::new()
            .name("chunkc-video".into())
            .spawn(move || {
                let mut stream = VideoStream::create(&file, shape, settings)?;
                stream.push_yuv(&yuv)?;
                drop(yuv);
                // What the file holds, from the encoder's stream configuration (nothing is
                // read back, no decoder runs beside the encoders).
                let format = stream.format()?;
                Ok((stream.finish()?, format))
            })
            .map_err(|e| Error::Internal(format!("cannot start a video encoder thread: {e}")))?;
        self.running.push_back(Running {
            path,
            frames: frames.len() as u64,
            of: (at, id),
            thread,
        });
        Ok(())
    }

    fn wait_oldest(&mut self) -> Result<()> {
        let Some(Running {
            path,
            frames: want,
            of,
            thread,
        }) = self.running.pop_front()
        else {
            return Ok(());
        };
        let (got, format) = thread.join().map_err(|_| {
            Error::Internal(format!("the encoder of {} panicked", path.display()))
        })??;
        self.copied.insert(of, false);
        *self.formats.entry((of.0, format)).or_default() += 1;
        if got != want {
            return Err(Error::Internal(format!(
                "{}: {got} frames encoded, {want} expected",
                path.display()
            )));
        }
        Ok(())
    }

    /// Waits for every file to be complete.
    pub(super) fn finish(&mut self) -> Result<()> {
        while !self.running.is_empty() {
            self.wait_oldest()?;
        }
        Ok(())
    }

    /// The formats of the files written for the channel at position `at`, each with how many
    /// episodes' files hold it, in order.
    pub(super) fn formats(&self, at: usize) -> Vec<(StreamFormat, usize)> {
        (self.formats.iter())
            .filter(|((a, _), _)| *a == at)
            .map(|((_, f), &n)| (f.clone(), n))
            .collect()
    }

    /// Why copies of the channel at position `at` were refused: one line per reason, with its
    /// episodes.
    pub(super) fn refusals(&self, at: usize) -> Vec<String> {
        self.refusals
            .iter()
            .filter(|((a, _), _)| *a == at)
            .map(|((_, why), ids)| {
                let ids: Vec<String> = ids.iter().map(u64::to_string).collect();
                format!("{why}: episodes {}", ids.join(", "))
            })
            .collect()
    }

    /// Whether episode `id`'s file of the channel at position `at` was copied.
    pub(super) fn copied(&self, at: usize, id: u64) -> bool {
        self.copied.get(&(at, id)).copied().unwrap_or(false)
    }
}
