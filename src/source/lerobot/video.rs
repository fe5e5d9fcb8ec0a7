//! The camera videos of a LeRobot dataset: which file and which span of it each episode's
//! camera is, their checks for the audit, and the decode of an episode's frames.
//!
//! The file comes from info.json's `video_path` template (authoritative, in both layouts); in
//! v3.0 `meta/episodes` places the episode in a shared file with `from_timestamp` and
//! `to_timestamp`, and row `k` looks for the frame nearest `from_timestamp + timestamp[k]`
//! (v2: `timestamp[k]`), as LeRobot does. The decoding itself is `source::video`'s.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use super::VideoRef;
use crate::error::{Error, Result};
use crate::recycle;
use crate::source::video::{
    self, DecodeFailure, Miss, PacketSpan, Timeline, VideoCheck, TOLERANCE_S,
};

/// The videos of the episodes a source reads.
pub(super) struct Videos {
    root: PathBuf,
    /// Per episode, per mapped video key (sorted), its file and span.
    refs: Vec<BTreeMap<String, VideoRef>>,
    /// Our channel name of each video key.
    channels: BTreeMap<String, String>,
    /// Each file's packet times, demuxed once whatever the number of episodes in it.
    timelines: BTreeMap<PathBuf, OnceLock<std::result::Result<Arc<Timeline>, String>>>,
    fps: f64,
}

impl Videos {
    pub(super) fn new(
        root: &Path,
        refs: Vec<BTreeMap<String, VideoRef>>,
        channels: BTreeMap<String, String>,
        fps: f64,
    ) -> Videos {
        let timelines = refs
            .iter()
            .flat_map(|m| m.values().map(|v| (v.file.clone(), OnceLock::new())))
            .collect();
        Videos {
            root: root.to_path_buf(),
            refs,
            channels,
            timelines,
            fps,
        }
    }

    /// Whether an episode has any video.
    pub(super) fn keys(&self, index: usize) -> impl Iterator<Item = &String> {
        self.refs[index].keys()
    }

    pub(super) fn is_video(&self, key: &str) -> bool {
        self.channels.contains_key(key)
    }

    /// The times row `k` looks for: `from_timestamp + timestamp[k]`.
    fn targets(r: &VideoRef, stamps: &[f64]) -> Vec<f64> {
        stamps.iter().map(|&t| r.from + t).collect()
    }

    /// `episode E, camera `key` (channel `name`), file F` for messages.
    fn place(&self, id: u64, key: &str, r: &VideoRef) -> String {
        format!(
            "{}: episode {id}, camera `{key}` (channel `{}`), file {}",
            self.root.display(),
            self.channels[key],
            r.file.display()
        )
    }

    fn timeline(&self, file: &Path) -> std::result::Result<Arc<Timeline>, String> {
        self.timelines[file]
            .get_or_init(|| video::timeline(&self.root.join(file)).map(Arc::new))
            .clone()
    }

    /// The checks of one episode's cameras, from the files' packet times and the rows' times
    /// (`stamps`: the episode's `timestamp` column).
    pub(super) fn checks(&self, index: usize, stamps: &[f64]) -> Vec<VideoCheck> {
        self.refs[index]
            .iter()
            .map(|(key, r)| self.check(key, r, stamps))
            .collect()
    }

    fn check(&self, key: &str, r: &VideoRef, stamps: &[f64]) -> VideoCheck {
        let mut out = VideoCheck {
            channel: self.channels[key].clone(),
            camera: key.to_string(),
            file: r.file.display().to_string(),
            codec: String::new(),
            rows: stamps.len(),
            frames: 0,
            interval_min: 0.0,
            interval_max: 0.0,
            worst_gap: 0.0,
            problem: None,
        };
        if !self.root.join(&r.file).exists() {
            out.problem = Some("the file is missing".into());
            return out;
        }
        let timeline = match self.timeline(&r.file) {
            Ok(t) => t,
            Err(e) => {
                out.problem = Some(e);
                return out;
            }
        };
        out.codec = timeline.probe.codec.clone();
        // The episode's span: v3.0 `[from, to)`, v2 the whole file (a half-tolerance margin,
        // so that a frame on the boundary counts once).
        let lo = r.from - TOLERANCE_S / 2.0;
        let span: Vec<f64> = timeline
            .times
            .iter()
            .copied()
            .filter(|&t| t >= lo && r.to.is_none_or(|to| t < to - TOLERANCE_S / 2.0))
            .collect();
        out.frames = span.len();
        let dts: Vec<f64> = span.windows(2).map(|w| w[1] - w[0]).collect();
        if !dts.is_empty() {
            out.interval_min = dts.iter().copied().fold(f64::INFINITY, f64::min);
            out.interval_max = dts.iter().copied().fold(0.0, f64::max);
        }
        // Every frame of the file is a candidate, as for LeRobot (which decodes from the
        // keyframe before the row).
        let (_, selector) = video::select::over_times(&timeline.times, &Self::targets(r, stamps));
        out.worst_gap = selector.worst_gap();
        if let Some(miss) = selector.first_miss() {
            let mut problem = miss_sentence(&miss);
            if let Some(cut) = &timeline.cut {
                problem = format!("{cut}; {problem}");
            } else if span.len() < stamps.len() {
                problem = format!(
                    "{} frames for {} rows at {} fps; {problem}",
                    span.len(),
                    stamps.len(),
                    self.fps
                );
            }
            out.problem = Some(problem);
        }
        out
    }

    /// The frames of its file that one episode's camera `key` takes, when its rows take the
    /// file's frames one by one (from the demuxed packet times; nothing decoded).
    pub(super) fn span(&self, index: usize, key: &str, stamps: &[f64]) -> Option<PacketSpan> {
        let r = self.refs[index].get(key)?;
        let timeline = self.timeline(&r.file).ok()?;
        if timeline.cut.is_some() {
            return None;
        }
        let (picks, selector) =
            video::select::over_times(&timeline.times, &Self::targets(r, stamps));
        if selector.first_miss().is_some() {
            return None;
        }
        let (first, last) = video::consecutive(&picks)?;
        Some(PacketSpan {
            file: self.root.join(&r.file),
            probe: timeline.probe.clone(),
            first: timeline.times[first],
            last: timeline.times[last],
            frames: stamps.len(),
        })
    }

    /// Decodes one episode's camera `key` into `rows × h × w × 3` bytes.
    pub(super) fn decode(
        &self,
        index: usize,
        id: u64,
        key: &str,
        stamps: &[f64],
        shape: [usize; 3],
    ) -> Result<Vec<u8>> {
        let r = &self.refs[index][key];
        let place = self.place(id, key, r);
        let path = self.root.join(&r.file);
        if !path.exists() {
            return Err(Error::source(format!("{place}: the file is missing")));
        }
        // A recycled buffer: a successful decode writes every row (each row gets its frame or
        // the episode fails), so no byte of a previous episode survives into this one.
        let mut out = recycle::take(stamps.len() * shape.iter().product::<usize>());
        match video::decode_rows(&path, &Self::targets(r, stamps), shape, &mut out) {
            Ok(()) => Ok(out),
            Err(f) => {
                recycle::give(out);
                Err(Error::source(match f {
                    DecodeFailure::Unreadable(why) => format!("{place}: {why}"),
                    DecodeFailure::Miss(miss) => format!("{place}: {}", miss_sentence(&miss)),
                }))
            }
        }
    }
}

/// `row 19: the nearest frame to 1.900000 s is at 1.800000 s, 0.100000 s away (tolerance_s =
/// 0.0001 s)`.
pub(super) fn miss_sentence(miss: &Miss) -> String {
    match miss.nearest {
        Some(at) => format!(
            "row {}: the nearest frame to {:.6} s is at {:.6} s, {:.6} s away (tolerance_s = {TOLERANCE_S} s; LeRobot raises FrameTimestampError here)",
            miss.row, miss.target, at, miss.gap
        ),
        None => format!(
            "row {}: the stream gave no frame at all (looking for {:.6} s)",
            miss.row, miss.target
        ),
    }
}
