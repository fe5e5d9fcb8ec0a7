//! `image_compression = "video"` in chunkc's HDF5 layout: one mp4 per episode and camera beside
//! the data file, which names each episode's file and frame count.
//!
//! ```text
//! videos/<camera>/episode_<id:06>.mp4     yuv420p, a keyframe every `video_gop` frames,
//!                                         frame i at time i / fps
//! /videos/<camera>/path    (E,) str       each stored episode's file, relative to the profile
//! /videos/<camera>/frames  (E,) int64     its frame count (= the episode's stored steps)
//! /videos/<camera>/copied  (E,) uint8     1 where the file is the source video's own packets
//!     attrs: encoding = "video", codec, crf, gop, pix_fmt, frame_shape = [H, W, 3]
//!            (the encoder's; a copied file keeps the source's codec and pixel format: when
//!            every file is copied, codec is the source's, crf and gop -1), stored = "copied" |
//!            "encoded" | "mixed", copy_refused (why copies were refused, when any was)
//! ```
//! Where the episode's frames are a source video's own, unchanged, its packets are copied
//! ([`super::video_copy`], `video_copy`); otherwise each file is encoded on a thread of its own
//! with a single-threaded encoder ([`super::video_encode`]). Either way its bytes do not depend
//! on `-j`; up to `-j` episodes are copied or encoded side by side while the build goes on, each
//! holding its episode's frames.

use std::collections::{BTreeMap, VecDeque};
use std::path::{Path, PathBuf};
use std::thread::JoinHandle;

use hdf5::types::VarLenUnicode;
use hdf5::{Dataset, Group};

use super::video_copy::{self, CopyOutcome, COPIED_CODECS};
use super::video_encode::{codec_name, StreamShape, VideoStream, PIX_FMT};
use super::Frames;
use crate::error::{Error, Result};
use crate::source::video::PacketSpan;
use crate::spec::{StreamCopy, VideoSettings};

/// The file of episode `id`'s frames of `camera`, relative to the profile directory.
pub fn episode_path(camera: &str, id: u64) -> String {
    format!("videos/{camera}/episode_{id:06}.mp4")
}

/// What a built `data.h5` records of one video camera's files: how many episodes were copied
/// from the source's stream, of how many, and why the others were not (`copy_refused`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CopyRecord {
    pub camera: String,
    pub copied: usize,
    pub episodes: usize,
    pub refused: Option<String>,
}

/// Every video camera's [`CopyRecord`] in a built `data.h5` (none without video storage).
pub fn copy_records(data_file: &Path) -> Result<Vec<CopyRecord>> {
    let file = hdf5::File::open(data_file)
        .map_err(|e| Error::output(format!("cannot open {}: {e}", data_file.display())))?;
    let Ok(videos) = file.group("videos") else {
        return Ok(Vec::new());
    };
    let mut records = Vec::new();
    for camera in videos.member_names()? {
        let group = videos.group(&camera)?;
        let copied: Vec<u8> = group.dataset("copied")?.read_raw()?;
        let refused = match group.attr("copy_refused") {
            Ok(a) => Some(a.read_scalar::<VarLenUnicode>()?.to_string()),
            Err(_) => None,
        };
        records.push(CopyRecord {
            camera,
            copied: copied.iter().filter(|&&c| c != 0).count(),
            episodes: copied.len(),
            refused,
        });
    }
    Ok(records)
}

/// One camera's per-episode videos.
pub(super) struct VideoChannel {
    name: String,
    shape: StreamShape,
    settings: VideoSettings,
    frames: Dataset,
    copied: Dataset,
}

fn text(s: &str) -> Result<VarLenUnicode> {
    s.parse::<VarLenUnicode>()
        .map_err(|e| Error::Internal(format!("text {s:?}: {e}")))
}

/// The attributes of `/videos/<camera>`: how its files were encoded.
fn describe(group: &Group, settings: VideoSettings, shape: &[usize]) -> Result<()> {
    let attrs: [(&str, String); 3] = [
        ("encoding", "video".into()),
        ("codec", settings.codec.name().into()),
        ("pix_fmt", PIX_FMT.into()),
    ];
    for (k, v) in attrs {
        group
            .new_attr::<VarLenUnicode>()
            .create(k)?
            .write_scalar(&text(&v)?)?;
    }
    for (k, v) in [("crf", settings.crf), ("gop", settings.gop)] {
        group
            .new_attr::<i64>()
            .create(k)?
            .write_scalar(&i64::from(v))?;
    }
    let dims: Vec<i64> = shape.iter().map(|&d| d as i64).collect();
    group
        .new_attr::<i64>()
        .shape([3])
        .create("frame_shape")?
        .write_raw(&dims)?;
    Ok(())
}

impl VideoChannel {
    /// Creates `/videos/<camera>` for the stored episodes (`ends`, `ids`) and the camera's
    /// directory under `dir`.
    pub(super) fn create(
        root: &Group,
        dir: &Path,
        name: &str,
        shape: &[usize],
        fps: f64,
        settings: VideoSettings,
        (ends, ids): (&[u64], &[u64]),
    ) -> Result<Self> {
        let [height, width, 3] = *shape else {
            return Err(Error::output(format!(
                "channel `{name}`: `image_compression = \"video\"` stores (height, width, 3) RGB \
                 frames, and this channel's frames are {shape:?}; use `image_compression = \"jpeg\"`"
            )));
        };
        let videos = dir.join("videos").join(name);
        std::fs::create_dir_all(&videos)
            .map_err(|e| Error::output(format!("cannot create {}: {e}", videos.display())))?;
        let top = match root.group("videos") {
            Ok(g) => g,
            Err(_) => root
                .create_group_builder()
                .obj_track_times(false)
                .create("videos")?,
        };
        let group = top
            .create_group_builder()
            .obj_track_times(false)
            .create(name)?;
        let paths: Vec<VarLenUnicode> = ids
            .iter()
            .map(|&id| text(&episode_path(name, id)))
            .collect::<Result<_>>()?;
        group
            .new_dataset::<VarLenUnicode>()
            .shape([paths.len()])
            .obj_track_times(false)
            .create("path")?
            .write_raw(&paths)?;
        let counts: Vec<i64> = ends
            .iter()
            .scan(0u64, |start, &end| {
                let n = end - *start;
                *start = end;
                Some(n as i64)
            })
            .collect();
        let frames = group
            .new_dataset::<i64>()
            .shape([counts.len()])
            .obj_track_times(false)
            .create("frames")?;
        frames.write_raw(&counts)?;
        let copied = group
            .new_dataset::<u8>()
            .shape([counts.len()])
            .obj_track_times(false)
            .create("copied")?;
        describe(&group, settings, shape)?;
        Ok(VideoChannel {
            name: name.to_string(),
            shape: StreamShape { height, width, fps },
            settings,
            frames,
            copied,
        })
    }

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

    /// The longest keyframe interval a copy of the source's stream may have (`video_gop` when
    /// the spec sets it, else the source's own).
    fn copy_gop(&self) -> u32 {
        self.settings.copy_gop.unwrap_or(u32::MAX)
    }

    /// Writes `/videos/<camera>/copied`: per stored episode, whether its file was copied; and
    /// when every file was copied, the group's attributes describe the stored streams (the
    /// source's codec, `crf` and `gop` -1: nothing was encoded), not the encoder's settings.
    pub(super) fn record_copies(
        &self,
        copied: &[u8],
        source_codec: Option<&str>,
        refused: &[String],
    ) -> Result<()> {
        self.copied.write_raw(copied)?;
        let group = self
            .copied
            .file()?
            .group(&format!("videos/{}", self.name))?;
        let stored = match (copied.iter().all(|&c| c == 1), copied.contains(&1)) {
            (true, _) if !copied.is_empty() => "copied",
            (_, true) => "mixed",
            _ => "encoded",
        };
        group
            .new_attr::<VarLenUnicode>()
            .create("stored")?
            .write_scalar(&text(stored)?)?;
        if !refused.is_empty() {
            group
                .new_attr::<VarLenUnicode>()
                .create("copy_refused")?
                .write_scalar(&text(&refused.join("; "))?)?;
        }
        if let (Some(codec), "copied") = (source_codec, stored) {
            group.attr("codec")?.write_scalar(&text(codec)?)?;
            group.attr("crf")?.write_scalar(&-1i64)?;
            group.attr("gop")?.write_scalar(&-1i64)?;
        }
        Ok(())
    }

    /// The dataset `/videos/<camera>/frames`.
    pub(super) fn dataset(&self) -> Dataset {
        self.frames.clone()
    }
}

/// One episode's file being written: (frames written, whether they were copied).
struct Running {
    path: PathBuf,
    frames: u64,
    /// (channel position, episode id).
    of: (usize, u64),
    thread: JoinHandle<Result<(u64, bool)>>,
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
    /// Per channel position, the codec of the streams copied.
    codecs: BTreeMap<usize, String>,
}

impl Encoders {
    pub(super) fn new(dir: &Path) -> Encoders {
        Encoders {
            dir: dir.to_path_buf(),
            limit: rayon::current_num_threads().max(1),
            running: VecDeque::new(),
            copied: BTreeMap::new(),
            refusals: BTreeMap::new(),
            codecs: BTreeMap::new(),
        }
    }

    /// Starts writing episode `id`'s frames of `channel` (position `at`), copied from the
    /// source or encoded, waiting for the oldest writer first when `limit` are running.
    pub(super) fn start(
        &mut self,
        (at, channel): (usize, &VideoChannel),
        id: u64,
        frames: &Frames,
    ) -> Result<()> {
        while self.running.len() >= self.limit {
            self.wait_oldest()?;
        }
        let path = self.dir.join(episode_path(&channel.name, id));
        let (shape, settings) = (channel.shape, channel.settings);
        // A copy reads packets, not pixels: it runs here, and only a refused one keeps a copy
        // of the episode's frames for its encoder (an episode of 640x480 frames is 400 MB).
        if let Some(span) = channel.to_copy(frames) {
            match video_copy::copy(&span, &path, shape.fps, channel.copy_gop())? {
                CopyOutcome::Copied(n) => {
                    self.copied.insert((at, id), true);
                    self.codecs.insert(at, span.probe.codec.clone());
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
        let pixels = frames.bytes().to_vec();
        let file = path.clone();
        let thread = std::thread::Builder::new()
            .name("chunkc-video".into())
            .spawn(move || {
                let mut stream = VideoStream::create(&file, shape, settings)?;
                stream.push_all(&pixels)?;
                Ok((stream.finish()?, false))
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
        let (got, copied) = thread.join().map_err(|_| {
            Error::Internal(format!("the encoder of {} panicked", path.display()))
        })??;
        self.copied.insert(of, copied);
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

    /// The codec of the streams copied for the channel at position `at`, if any was.
    pub(super) fn copied_codec(&self, at: usize) -> Option<&str> {
        self.codecs.get(&at).map(String::as_str)
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
