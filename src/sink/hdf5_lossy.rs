//! The lossy frame storages of chunkc's HDF5 layout, behind one type for the writer:
//! `image_compression = "jpeg"` ([`super::hdf5_jpeg`]) and `"video"` ([`super::hdf5_video`]).

use std::collections::BTreeMap;

use hdf5::{Dataset, Group};

use super::hdf5_jpeg::JpegChannel;
use super::hdf5_video::{Encoders, VideoChannel};
use super::video_info::StoredVideo;
use super::{Frames, SinkContext};
use crate::error::{Error, Result};
use crate::spec::{ImageCompression, DEFAULT_IMAGE_QUALITY};

enum Channel {
    Jpeg(JpegChannel),
    Video(VideoChannel),
}

/// Every camera stored lossily, by channel position.
pub(super) struct LossyFrames {
    channels: Vec<Option<Channel>>,
    encoders: Encoders,
    /// (first stored row, source id) of every episode, in stored order.
    episodes: Vec<(u64, u64)>,
}

impl LossyFrames {
    pub(super) fn new(ctx: &SinkContext) -> LossyFrames {
        let starts = std::iter::once(0).chain(ctx.episode_ends.iter().copied());
        LossyFrames {
            channels: Vec::new(),
            encoders: Encoders::new(ctx.dir),
            episodes: starts.zip(ctx.episode_ids.iter().copied()).collect(),
        }
    }

    /// Whether the profile stores its frames lossily.
    pub(super) fn wanted(ctx: &SinkContext) -> bool {
        matches!(
            ctx.profile.values.image_compression,
            ImageCompression::Jpeg | ImageCompression::Video
        )
    }

    /// The JPEG quality the profile stores frames at.
    pub(super) fn quality(ctx: &SinkContext) -> u8 {
        let q = ctx.profile.values.image_quality;
        q.unwrap_or(DEFAULT_IMAGE_QUALITY).clamp(1, 100) as u8
    }

    /// Creates the datasets of image channel `name` (the next channel) and returns the one the
    /// writer keeps for it.
    pub(super) fn add(
        &mut self,
        ctx: &SinkContext,
        root: &Group,
        name: &str,
        shape: &[usize],
    ) -> Result<Dataset> {
        let channel = self.channels.len();
        let steps = *ctx.episode_ends.last().unwrap_or(&0) as usize;
        let v = &ctx.profile.values;
        let made = match v.image_compression {
            ImageCompression::Jpeg => {
                let quality = Self::quality(ctx);
                Channel::Jpeg(JpegChannel::create(root, name, shape, steps, quality)?)
            }
            _ => {
                let settings = v.video().ok_or_else(|| {
                    Error::Internal(format!("channel {channel}: video storage without settings"))
                })?;
                let episodes = (ctx.episode_ends, ctx.episode_ids);
                let fps = ctx.profile.fps;
                Channel::Video(VideoChannel::create(
                    root, ctx.dir, name, shape, fps, settings, episodes,
                )?)
            }
        };
        let ds = match &made {
            Channel::Jpeg(j) => j.dataset(),
            Channel::Video(v) => v.dataset(),
        };
        self.channels.push(Some(made));
        Ok(ds)
    }

    /// Low-dim channels take no lossy storage; called in channel order with [`Self::add`].
    pub(super) fn skip(&mut self) {
        self.channels.push(None);
    }

    /// Whether `frames` of `channel` will be stored as a copy of their video packets.
    pub(super) fn copies(&self, channel: usize, frames: &Frames) -> Result<bool> {
        match self.channels.get(channel).and_then(Option::as_ref) {
            Some(Channel::Video(v)) => v.camera.will_copy(frames),
            _ => Ok(false),
        }
    }

    /// Stores one episode's frames of `channel` from stored row `row`; false when the channel
    /// is not stored lossily.
    pub(super) fn write(&mut self, channel: usize, row: usize, frames: &Frames) -> Result<bool> {
        match self.channels.get_mut(channel).and_then(Option::as_mut) {
            None => Ok(false),
            Some(Channel::Jpeg(j)) => j.push(row, frames).map(|_| true),
            Some(Channel::Video(v)) => {
                let at = self
                    .episodes
                    .partition_point(|&(start, _)| start < row as u64);
                let id = match self.episodes.get(at) {
                    Some(&(start, id)) if start == row as u64 => id,
                    _ => {
                        return Err(Error::Internal(format!(
                            "channel {channel}: row {row} starts no episode"
                        )))
                    }
                };
                let file = super::hdf5_video::episode_path(&v.camera.name, id);
                self.encoders
                    .start((channel, &v.camera), (id, &file), frames)?;
                Ok(true)
            }
        }
    }

    /// Waits for every video to be complete, and records which were copied and what the files
    /// hold: per video camera, by name.
    pub(super) fn finish(&mut self) -> Result<BTreeMap<String, StoredVideo>> {
        self.encoders.finish()?;
        let mut videos = BTreeMap::new();
        for (at, channel) in self.channels.iter().enumerate() {
            if let Some(Channel::Video(v)) = channel {
                let copied: Vec<u8> = self
                    .episodes
                    .iter()
                    .map(|&(_, id)| u8::from(self.encoders.copied(at, id)))
                    .collect();
                let stored = StoredVideo {
                    copied: copied.iter().filter(|&&c| c == 1).count(),
                    episodes: copied.len(),
                    formats: self.encoders.formats(at),
                };
                v.record_copies(&copied, &stored, &self.encoders.refusals(at))?;
                videos.insert(v.name().to_string(), stored);
            }
        }
        Ok(videos)
    }
}
