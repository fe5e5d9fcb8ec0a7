//! What `chunkc plan` measures before it estimates the bytes of lossily stored frames (JPEG,
//! video), which no bound can know (see `plan::estimate`).
//!
//! - Where the profile would copy a source video's packets (chunkc's HDF5 video storage, the
//!   source's rate, no resize, a codec that is copied), each episode's share of its source file
//!   is what the copy writes.
//! - A video stored again from a source video: the source's bytes per frame, scaled by the
//!   stored pixels.
//! - Otherwise sample frames of the first episode are encoded as the profile stores them: a few
//!   frames spread over it as JPEG, or its first keyframe intervals as video.
//!
//! `build` skips this (it reads every episode once, and shows no estimate); `plan`, `check` and
//! the sharded build's shards and merge measure the same way, so their plans agree.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::audit::AuditReport;
use crate::plan::estimate::{FrameMeasure, FrameMeasures, MP4_FILE, MP4_FRAME};
use crate::plan::{Conversion, Plan, ProfileChannel, ProfilePlan};
use crate::resize::Resize;
use crate::sink::video_copy::COPIED_CODECS;
use crate::sink::{jpeg, video_encode};
use crate::source::{ChannelData, ChannelKind, Episode, Source};
use crate::spec::{
    ImageCompression, LoadedSpec, OutputFormat, StreamCopy, VideoSettings, DEFAULT_IMAGE_QUALITY,
};

/// JPEG frames encoded per camera, spread over the first episode.
const JPEG_SAMPLES: usize = 8;
/// Keyframe intervals of video encoded per camera (at least this many frames are encoded).
const VIDEO_GOPS: usize = 2;
const VIDEO_MIN_FRAMES: usize = 16;

/// How a camera's frames are stored lossily in a profile, if they are.
enum Lossy {
    Jpeg(u8),
    Video(VideoSettings),
}

fn lossy(p: &ProfilePlan) -> Option<Lossy> {
    let v = &p.values;
    match (v.format, v.image_compression) {
        (OutputFormat::Hdf5, ImageCompression::Jpeg) => Some(Lossy::Jpeg(
            v.image_quality.unwrap_or(DEFAULT_IMAGE_QUALITY).min(100) as u8,
        )),
        (OutputFormat::Hdf5, ImageCompression::Video) | (OutputFormat::Parquet, _) => {
            v.video().map(Lossy::Video)
        }
        _ => None,
    }
}

/// One camera of the source as a video: per episode id, its share of its file (bytes) and its
/// frames; the codec.
#[derive(Default)]
struct SourceVideo {
    episodes: BTreeMap<u64, (u64, usize)>,
    codec: String,
}

impl SourceVideo {
    fn per_frame(&self) -> Option<f64> {
        let (bytes, frames) = self
            .episodes
            .values()
            .fold((0u64, 0usize), |(b, f), &(eb, ef)| (b + eb, f + ef));
        (frames > 0).then(|| bytes as f64 / frames as f64)
    }
}

/// The source's camera videos, by channel, from the audit's video checks: each episode's share
/// of its file, by frames (a LeRobot v3.0 file holds many episodes).
fn source_videos(root: &Path, report: &AuditReport) -> BTreeMap<String, SourceVideo> {
    let mut frames_in: BTreeMap<&str, usize> = BTreeMap::new();
    for v in report.video.iter().filter(|v| v.check.problem.is_none()) {
        *frames_in.entry(v.check.file.as_str()).or_default() += v.check.frames;
    }
    let mut out: BTreeMap<String, SourceVideo> = BTreeMap::new();
    for v in report.video.iter().filter(|v| v.check.problem.is_none()) {
        let Ok(meta) = std::fs::metadata(root.join(&v.check.file)) else {
            continue;
        };
        let total = frames_in[v.check.file.as_str()].max(1) as u64;
        let share = meta.len() * v.check.frames as u64 / total;
        let camera = out.entry(v.check.channel.clone()).or_default();
        camera.codec = v.check.codec.clone();
        camera.episodes.insert(v.episode, (share, v.check.frames));
    }
    out
}

/// Whether a video storage would copy the source's packets of `ch` (the sink decides per
/// episode, from the keyframes; this is the plan's expectation).
fn copies(p: &ProfilePlan, ch: &ProfileChannel, s: &VideoSettings, codec: &str) -> bool {
    let same_rate = p.conversion == Conversion::Decimate { factor: 1 };
    let resized = ch.resize.is_some_and(|r| r.size != r.from);
    let codec_ok = match s.copy {
        StreamCopy::Never => false,
        StreamCopy::AnyCodec => COPIED_CODECS.contains(&codec),
        StreamCopy::SameCodec => video_encode::codec_name(s.codec) == codec,
    };
    p.values.format == OutputFormat::Hdf5 && same_rate && !resized && codec_ok
}

/// What is measured for every camera a profile of `plan` stores lossily.
pub fn frames(
    spec: &LoadedSpec,
    source: &dyn Source,
    plan: &Plan,
    report: &AuditReport,
) -> FrameMeasures {
    let videos = source_videos(&spec.resolve(&spec.source().path), report);
    let mut sampler = Sampler {
        source,
        first: None,
    };
    let mut out = FrameMeasures::new();
    for p in &plan.profiles {
        let Some(storage) = lossy(p) else { continue };
        for (c, ch) in p.channels.iter().enumerate() {
            if ch.kind != ChannelKind::Image {
                continue;
            }
            let video = videos.get(&ch.name);
            let measure = match (&storage, video) {
                (Lossy::Video(s), Some(v)) => Some(from_source(p, ch, s, v)),
                (Lossy::Video(s), None) => sampler.video(p, c, ch, *s),
                (Lossy::Jpeg(q), _) => sampler.jpeg(p, c, ch, *q),
            };
            if let Some(m) = measure {
                out.insert((p.name.clone(), ch.name.clone()), m);
            }
        }
    }
    out
}

/// A video stored from a source video: copied, or at the source's bytes per pixel.
fn from_source(
    p: &ProfilePlan,
    ch: &ProfileChannel,
    s: &VideoSettings,
    v: &SourceVideo,
) -> FrameMeasure {
    let per_frame = v.per_frame().unwrap_or(0.0);
    if copies(p, ch, s, &v.codec) {
        let copied: BTreeMap<u64, u64> = p
            .episodes
            .iter()
            .filter(|e| !p.repaired.iter().any(|r| r.id == e.id))
            .filter_map(|e| Some((e.id, v.episodes.get(&e.id)?.0)))
            .collect();
        return FrameMeasure {
            per_frame,
            copied,
            basis: format!(
                "the source's {} files, copied where their keyframes allow",
                v.codec
            ),
        };
    }
    let scale = ch.resize.map_or(1.0, |r| {
        (r.size[0] * r.size[1]) as f64 / (r.from[0] * r.from[1]).max(1) as f64
    });
    FrameMeasure {
        per_frame: per_frame * scale,
        copied: BTreeMap::new(),
        basis: format!(
            "the source's {} bitrate{}",
            v.codec,
            if scale == 1.0 {
                ""
            } else {
                ", scaled to the stored size"
            }
        ),
    }
}

/// Frames of the first episode, read once, encoded as each profile stores them.
struct Sampler<'a> {
    source: &'a dyn Source,
    /// The first episode, once read (`None` inside: it could not be).
    first: Option<Option<Episode>>,
}

impl Sampler<'_> {
    /// Frames `steps` of the first episode's camera `c`, as `ch` stores them (resized).
    fn frames(&mut self, c: usize, ch: &ProfileChannel, steps: &[usize]) -> Option<Vec<u8>> {
        let source = self.source;
        let episode = self
            .first
            .get_or_insert_with(|| source.read_episode(0).ok())
            .as_ref()?;
        let ChannelData::Image(all) = episode.channels.get(c)? else {
            return None;
        };
        let shape = &source.manifest().channels.get(c)?.shape;
        let &[h, w, colors] = shape.as_slice() else {
            return None;
        };
        let size = h * w * colors;
        let mut picked = Vec::with_capacity(steps.len() * size);
        for &t in steps {
            picked.extend_from_slice(all.get(t * size..(t + 1) * size)?);
        }
        Some(match ch.resize {
            Some(r) => Resize::cover([h, w], r.size, colors).frames(&picked),
            None => picked,
        })
    }

    /// The first episode's steps at the profile's rate: every `factor`-th.
    fn steps(&self, p: &ProfilePlan) -> Vec<usize> {
        let len = self.source.manifest().episodes.first().map_or(0, |e| e.len);
        let factor = p.conversion.factor().unwrap_or(1).max(1);
        (0..len).step_by(factor).collect()
    }

    fn jpeg(
        &mut self,
        p: &ProfilePlan,
        c: usize,
        ch: &ProfileChannel,
        quality: u8,
    ) -> Option<FrameMeasure> {
        let steps = self.steps(p);
        let every = steps.len().div_ceil(JPEG_SAMPLES).max(1);
        let picked: Vec<usize> = steps.iter().copied().step_by(every).collect();
        let frames = self.frames(c, ch, &picked)?;
        jpeg::check_shape(&ch.shape).ok()?;
        let size: usize = ch.shape.iter().product();
        let bytes: usize = frames
            .chunks_exact(size)
            .map(|f| jpeg::encode(f, &ch.shape, quality).len())
            .sum();
        Some(FrameMeasure {
            per_frame: bytes as f64 / picked.len().max(1) as f64,
            copied: BTreeMap::new(),
            basis: format!(
                "{} frames of episode {} encoded at quality {quality}",
                picked.len(),
                self.first_id()
            ),
        })
    }

    fn video(
        &mut self,
        p: &ProfilePlan,
        c: usize,
        ch: &ProfileChannel,
        s: VideoSettings,
    ) -> Option<FrameMeasure> {
        let n = (s.gop as usize * VIDEO_GOPS).max(VIDEO_MIN_FRAMES);
        let steps: Vec<usize> = self.steps(p).into_iter().take(n).collect();
        let frames = self.frames(c, ch, &steps)?;
        let &[height, width, _] = ch.shape.as_slice() else {
            return None;
        };
        let shape = video_encode::StreamShape {
            height,
            width,
            fps: p.fps,
        };
        let path = scratch_file();
        let encoded = (|| -> crate::Result<u64> {
            let mut stream = video_encode::VideoStream::create(&path, shape, s)?;
            stream.push_all(&frames)?;
            stream.finish()?;
            Ok(std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0))
        })();
        let _ = std::fs::remove_file(&path);
        let bytes = encoded.ok()?;
        // The container's own bytes are counted apart by the estimate.
        let container = MP4_FILE + MP4_FRAME * steps.len() as u64;
        let stream = bytes.saturating_sub(container);
        Some(FrameMeasure {
            per_frame: stream as f64 / steps.len().max(1) as f64,
            copied: BTreeMap::new(),
            basis: format!(
                "the first {} frames of episode {} encoded ({} crf {}, keyframe every {})",
                steps.len(),
                self.first_id(),
                s.codec.name(),
                s.crf,
                s.gop
            ),
        })
    }

    fn first_id(&self) -> u64 {
        self.source.manifest().episodes.first().map_or(0, |e| e.id)
    }
}

/// A file name of this process's own for one sample encode (removed after).
fn scratch_file() -> PathBuf {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    std::env::temp_dir().join(format!("chunkc-measure-{}-{n}.mp4", std::process::id()))
}
