//! The cameras of the LeRobot v3.0 export stored as video (`image_encoding = "video"`), in one
//! of the two ways v3.0's `meta/episodes` can locate an episode's frames:
//!
//! - **shared** (the default, LeRobot's own layout): one file of every episode per camera,
//!   `videos/<camera>/chunk-000/file-000.mp4`, always encoded, stored row `i` at `i / fps`;
//! - **per episode** (`video_copy = true`): one file per episode, `videos/<camera>/chunk-<e /
//!   1000>/file-<e % 1000>.mp4` from time 0, the source's packets copied where they are the
//!   episode's frames unchanged ([`super::video_episodes`]): a LeRobot v2.1 source (or a v3.0
//!   one whose episodes start on keyframes) becomes v3.0 without a second generation of
//!   compression loss, and back.

use std::path::Path;

use serde_json::{json, Value};

use super::lerobot_cameras::camera;
use super::lerobot_columns::Channel;
use super::video_encode::{self, Background, PIX_FMT};
use super::video_episodes::{Encoders, EpisodeCamera};
use super::{Frames, SinkContext};
use crate::error::{Error, IoContext, Result};
use crate::source::ChannelKind;
use crate::window::Ends;

/// Episodes per chunk folder (LeRobot's `chunks_size`).
const FILES_PER_CHUNK: usize = 1000;

/// The one file of camera `name` of every episode (shared videos).
pub fn shared_file(name: &str) -> String {
    format!("videos/{name}/chunk-000/file-000.mp4")
}

/// The file of camera `name` of stored episode `e` (per-episode videos).
pub fn episode_file(name: &str, e: usize) -> String {
    format!(
        "videos/{name}/chunk-{:03}/file-{:03}.mp4",
        e / FILES_PER_CHUNK,
        e % FILES_PER_CHUNK
    )
}

/// Where a camera's frames go.
enum Storage {
    /// Its file's encoder and the frames sent to it.
    Shared(Background, usize),
    /// Its episodes' files.
    PerEpisode,
}

/// The export's video cameras.
pub(super) struct V3Videos {
    /// Per channel: the camera and its storage (cameras stored as video only).
    cameras: Vec<Option<(EpisodeCamera, Storage)>>,
    encoders: Encoders,
    ends: Ends,
    per_episode: bool,
}

impl V3Videos {
    /// The video cameras of `channels`, when the profile stores frames as video.
    pub(super) fn create(ctx: &SinkContext, channels: &[Channel]) -> Result<Option<Self>> {
        let v = &ctx.profile.values;
        let Some(settings) = v.video() else {
            return Ok(None);
        };
        let per_episode = v.video_copy == Some(true);
        let cameras = channels
            .iter()
            .map(|(name, shape, kind)| {
                if *kind != ChannelKind::Image {
                    return Ok(None);
                }
                let at = (name.as_str(), shape.as_slice(), ctx.profile.fps);
                let cam = camera(v, at, settings, per_episode)?;
                if per_episode {
                    return Ok(Some((cam, Storage::PerEpisode)));
                }
                let path = ctx.dir.join(shared_file(name));
                if let Some(parent) = path.parent() {
                    std::fs::create_dir_all(parent).at("create", parent)?;
                }
                let stream = Background::spawn(&path, cam.shape, cam.settings)?;
                Ok(Some((cam, Storage::Shared(stream, 0))))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Some(V3Videos {
            cameras,
            encoders: Encoders::new(ctx.dir),
            ends: Ends::new(ctx.episode_ends.to_vec()),
            per_episode,
        }))
    }

    /// Whether channel `c` is a camera stored as video.
    pub(super) fn has(&self, c: usize) -> bool {
        self.cameras.get(c).is_some_and(Option::is_some)
    }

    /// An episode's frames of channel `c`, from stored row `row`.
    pub(super) fn push(&mut self, c: usize, row: usize, frames: &Frames) -> Result<()> {
        let Some((cam, storage)) = self.cameras[c].as_mut() else {
            return Err(Error::Internal(format!("channel {c} is not a video")));
        };
        match storage {
            Storage::Shared(encoder, sent) => {
                if *sent != row {
                    return Err(Error::Internal(format!(
                        "frames out of order: row {row}, have {sent}"
                    )));
                }
                *sent += frames.len();
                let name = &cam.name;
                encoder
                    .push(frames.shared())
                    .map_err(|e| Error::output(format!("channel `{name}`, rows from {row}: {e}")))
            }
            Storage::PerEpisode => {
                let e = self.ends.partition_point(|&end| end <= row as u64);
                if e >= self.ends.len() || self.ends.start(e) != row {
                    return Err(Error::Internal(format!("row {row} starts no episode")));
                }
                let file = episode_file(&cam.name, e);
                self.encoders.start((c, cam), (e as u64, &file), frames)
            }
        }
    }

    /// Completes every file; each shared file must hold every stored row.
    pub(super) fn finish(&mut self) -> Result<()> {
        let rows = self.ends.last().copied().unwrap_or(0);
        self.encoders.finish()?;
        for (cam, storage) in self.cameras.iter_mut().flatten() {
            if let Storage::Shared(encoder, sent) = storage {
                let name = &cam.name;
                let written = encoder
                    .finish()
                    .map_err(|e| Error::output(format!("channel `{name}`: {e}")))?;
                if written != rows || *sent as u64 != rows {
                    return Err(Error::Internal(format!(
                        "video of `{name}` has {written} frames for {rows} rows"
                    )));
                }
            }
        }
        Ok(())
    }

    /// `meta/episodes`' columns for a camera's episode `e`: `chunk_index`, `file_index`,
    /// `from_timestamp`, `to_timestamp` (a shared file holds row `i` at `i / fps`).
    pub(super) fn location(&self, e: usize, fps: f64) -> (i64, i64, f64, f64) {
        let (start, end) = (self.ends.start(e) as f64, self.ends.range(e).end as f64);
        match self.per_episode {
            true => (
                (e / FILES_PER_CHUNK) as i64,
                (e % FILES_PER_CHUNK) as i64,
                0.0,
                (end - start) / fps,
            ),
            false => (0, 0, start / fps, end / fps),
        }
    }

    /// The `info` block of camera `c` (`shape`): a shared file's encoder, or what the first
    /// episode's file holds (copied files keep the source's codec).
    pub(super) fn info(&self, dir: &Path, c: usize, shape: &[usize], fps: f64) -> Value {
        let Some((cam, _)) = &self.cameras[c] else {
            return Value::Null;
        };
        let encoded = (
            video_encode::codec_name(cam.settings.codec).to_string(),
            PIX_FMT.to_string(),
        );
        let (codec, pix_fmt) = match self.per_episode && !self.ends.is_empty() {
            true => super::video_info::stream_format(&dir.join(episode_file(&cam.name, 0)))
                .map_or(encoded, |f| (f.codec, f.pix_fmt)),
            false => encoded,
        };
        json!({
            "video.height": shape[0],
            "video.width": shape[1],
            "video.codec": codec,
            "video.pix_fmt": pix_fmt,
            "video.is_depth_map": false,
            "video.fps": fps.round() as u64,
            "video.channels": shape[2],
            "has_audio": false,
        })
    }
}
