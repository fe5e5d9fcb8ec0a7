//! LeRobot v2.1's dataset layout (`format = "parquet"`, `lerobot_version = "v2.1"`): what
//! openpi's pinned lerobot, PyPI lerobot <= 0.3.3 and GR00T read.
//!
//! ```text
//! data/chunk-000/episode_000000.parquet     one file per episode (one row group): <channel>
//!                                           columns as in v3.0 (raw), timestamp = frame_index
//!                                           / fps, frame_index, episode_index (0..N-1 in file
//!                                           order), index (the dataset's row), task_index;
//!                                           a mixture's source_index; datasets' `huggingface`
//!                                           features in the schema metadata
//! videos/chunk-000/<camera>/episode_000000.mp4   image_encoding = "video": one frame per row,
//!                                           frame i at i / fps, the source's packets copied
//!                                           where they are the episode's frames unchanged
//! meta/info.json, episodes.jsonl, tasks.jsonl, episodes_stats.jsonl   (lerobot_v21_meta)
//! meta/stats.json                           written by `exec`: chunkc's training statistics
//! val/…                                     the validation episodes, a v2.1 dataset of their own
//! ```
//! A `groot` profile adds GR00T's `meta/modality.json` and `meta/relative_stats.json` to each
//! dataset and writes GR00T's `meta/stats.json` itself ([`super::groot`]); over a mixture, each
//! source is a pair of datasets of its own, `sources/<name>/` and `sources/<name>/val/`, at its
//! own widths (GR00T mixes datasets itself), and the profile folder holds none.
//! Frames arrive raw: their per-episode statistics are taken here, then they go to the
//! episode's video (copied or encoded, [`super::video_episodes`]) or, PNG-encoded, to a scratch
//! file until `finish` writes the episode's data file. A camera whose frames are not one per
//! row is an error naming the camera and the episode.

use std::collections::BTreeMap;
use std::sync::Arc;

use serde_json::{json, Value};

use super::lerobot_cameras::camera;
use super::lerobot_columns::Channel;
use super::lerobot_episode_stats::FeatureStats;
use super::lerobot_features::features;
use super::lerobot_files::DatasetFiles;
use super::lerobot_rows::DataTable;
use super::lerobot_spill::{FrameSpill, SpillReader};
use super::lerobot_tasks::Tasks;
use super::lerobot_v21_data::{EpisodeData, EpisodeStats};
use super::lerobot_v21_meta::{data_file, layout_of, video_file, Meta, Part};
use super::video_episodes::{Encoders, EpisodeCamera};
use super::{FrameEncoding, Frames, Sink, SinkContext, WindowIndex};
use crate::error::{Error, Result};
use crate::source::ChannelKind;
use crate::stats::normalize::RowNormalizer;
use crate::store::LowdimStore;
use crate::window::Ends;

pub struct LerobotV21Writer {
    files: DatasetFiles,
    fps: f64,
    ends: Ends,
    ids: Vec<u64>,
    sources: Vec<usize>,
    channels: Vec<Channel>,
    raw: Vec<Option<Arc<LowdimStore>>>,
    /// Per channel: its PNG frames by stored row (cameras stored as PNG only).
    frames: Vec<Option<FrameSpill>>,
    /// Per channel: the camera's videos (cameras stored as video only).
    cameras: Vec<Option<EpisodeCamera>>,
    encoders: Encoders,
    /// The datasets: the training one (the profile folder) and the validation one (`val/`), or
    /// a `groot` mixture's pair per source.
    parts: Vec<Part>,
    /// Per mixture source, per channel: its own width (for a source's dataset of its own).
    own: Vec<Vec<usize>>,
    /// A `groot` profile's modality per source, and its action horizon.
    groot: Vec<crate::plan::groot::GrootModality>,
    horizon: usize,
    /// The file `meta.json` names as the data.
    first_file: String,
    /// Per stored episode: its part and its `episode_index` there.
    place: Vec<(usize, usize)>,
    /// Per stored episode, per channel: the camera's statistics over the episode's frames.
    image_stats: Vec<BTreeMap<usize, FeatureStats>>,
}

impl LerobotV21Writer {
    pub fn create(ctx: &SinkContext) -> Result<Self> {
        let v = &ctx.profile.values;
        let files = DatasetFiles::new(ctx.dir, v.compression, v.compression_level)?;
        let channels: Vec<Channel> = ctx
            .profile
            .channels
            .iter()
            .map(|c| (c.name.clone(), c.shape.clone(), c.kind))
            .collect();
        let video = v.video();
        let cameras = channels
            .iter()
            .map(|(name, shape, kind)| match (kind, video) {
                (ChannelKind::Image, Some(settings)) => {
                    let at = (name.as_str(), shape.as_slice(), ctx.profile.fps);
                    camera(v, at, settings, true).map(Some)
                }
                _ => Ok(None),
            })
            .collect::<Result<Vec<_>>>()?;
        let steps = *ctx.episode_ends.last().unwrap_or(&0) as usize;
        let frames = channels
            .iter()
            .enumerate()
            .map(|(c, (_, _, k))| match k {
                ChannelKind::Image if video.is_none() => {
                    let file = format!("{}-frames-{c}", ctx.profile.name);
                    FrameSpill::create(ctx.scratch.join(file), steps).map(Some)
                }
                _ => Ok(None),
            })
            .collect::<Result<_>>()?;
        let (parts, place) = parts(ctx);
        let first = parts
            .iter()
            .find(|p| !p.episodes.is_empty())
            .unwrap_or(&parts[0]);
        Ok(LerobotV21Writer {
            first_file: first.path(&data_file(0)),
            own: ctx.source_parts.iter().map(|s| s.widths.clone()).collect(),
            groot: ctx.profile.groot.clone(),
            horizon: ctx.profile.window().chunk,
            files,
            fps: ctx.profile.fps,
            ends: Ends::new(ctx.episode_ends.to_vec()),
            ids: ctx.episode_ids.to_vec(),
            sources: ctx.episode_sources.to_vec(),
            raw: channels.iter().map(|_| None).collect(),
            frames,
            cameras,
            encoders: Encoders::new(ctx.dir),
            image_stats: vec![BTreeMap::new(); ctx.episode_ids.len()],
            channels,
            parts,
            place,
        })
    }

    /// The data table of part `p`: a source's dataset of its own has the source's widths and no
    /// `source_index`.
    fn table(&self, p: usize) -> DataTable<'_> {
        let own = self.parts[p].set.source.map(|s| self.own[s].as_slice());
        DataTable {
            channels: &self.channels,
            video: self.cameras.iter().any(Option::is_some),
            fps: self.fps,
            mixture: !self.sources.is_empty() && own.is_none(),
            own,
        }
    }

    /// The stored episode whose rows start at `row`.
    fn episode_at(&self, channel: usize, row: usize) -> Result<usize> {
        let e = self.ends.partition_point(|&end| end <= row as u64);
        match e < self.ends.len() && self.ends.start(e) == row {
            true => Ok(e),
            false => Err(Error::Internal(format!(
                "channel {channel}: row {row} starts no episode"
            ))),
        }
    }

    /// Writes every episode's data file, side by side; returns each episode's statistics, in
    /// stored order.
    fn data(&mut self) -> Result<Vec<EpisodeStats>> {
        let mut frames: Vec<Option<SpillReader>> = std::mem::take(&mut self.frames)
            .into_iter()
            .map(|f| f.map(FrameSpill::into_reader).transpose())
            .collect::<Result<_>>()?;
        let data = EpisodeData {
            files: &self.files,
            ends: &self.ends,
            ids: &self.ids,
            sources: &self.sources,
            raw: &self.raw,
            image_stats: &self.image_stats,
            parts: &self.parts,
            tables: (0..self.parts.len()).map(|p| self.table(p)).collect(),
            place: &self.place,
        };
        data.write(&mut frames)
    }

    /// The `info` block of camera `name` in `part`: what its first episode's file holds.
    fn video_info(&self, part: &Part, name: &str, shape: &[usize]) -> Value {
        let (codec, pix_fmt) = part
            .episodes
            .first()
            .and_then(|_| {
                let path = self.files.dir.join(part.path(&video_file(name, 0)));
                super::video_info::stream_format(&path).ok()
            })
            .map_or_else(
                || ("unknown".into(), "unknown".into()),
                |f| (f.codec, f.pix_fmt),
            );
        json!({
            "video.height": shape[0],
            "video.width": shape[1],
            "video.codec": codec,
            "video.pix_fmt": pix_fmt,
            "video.is_depth_map": false,
            "video.fps": self.fps.round() as u64,
            "video.channels": shape[2],
            "has_audio": false,
        })
    }
}

/// The export's datasets (see [`layout_of`]), each with its episodes and tasks; per stored
/// episode, its dataset and `episode_index`.
fn parts(ctx: &SinkContext) -> (Vec<Part>, Vec<(usize, usize)>) {
    let layout = layout_of(ctx.profile, ctx.source_parts);
    let place = layout.place;
    let parts = (layout.datasets.into_iter().enumerate())
        .map(|(p, set)| {
            let episodes: Vec<usize> = (0..place.len()).filter(|&e| place[e].0 == p).collect();
            let ids: Vec<u64> = episodes.iter().map(|&e| ctx.episode_ids[e]).collect();
            Part {
                set,
                tasks: Tasks::of(&ids, ctx.tasks),
                episodes,
            }
        })
        .collect();
    (parts, place)
}

impl Sink for LerobotV21Writer {
    /// The first dataset's first episode (a `groot` mixture's first source's).
    fn data_file(&self) -> &str {
        &self.first_file
    }

    fn frame_encoding(&self) -> FrameEncoding {
        FrameEncoding::Raw
    }

    fn stores_normalized(&self) -> bool {
        false
    }

    fn write_frames(&mut self, channel: usize, row: usize, frames: &Frames) -> Result<()> {
        let e = self.episode_at(channel, row)?;
        let (name, shape, _) = &self.channels[channel];
        let rows = self.ends.range(e).len();
        if frames.len() != rows {
            return Err(Error::output(format!(
                "camera `{name}`, episode {}: {} frames for {rows} rows; a LeRobot v2.1 video \
                 holds exactly one frame per row",
                self.ids[e],
                frames.len()
            )));
        }
        let colors = *shape.last().unwrap_or(&1);
        let stats = FeatureStats::of_frames(frames.bytes(), frames.len(), colors);
        self.image_stats[e].insert(channel, stats);
        if let Some(camera) = &self.cameras[channel] {
            let (p, index) = self.place[e];
            let file = self.parts[p].path(&video_file(name, index));
            return self
                .encoders
                .start((channel, camera), (e as u64, &file), frames);
        }
        let spill = self.frames[channel]
            .as_mut()
            .ok_or_else(|| Error::Internal(format!("channel {channel} has no frames")))?;
        if spill.ends.len() != row {
            return Err(Error::Internal(format!(
                "frames out of order: row {row}, have {}",
                spill.ends.len()
            )));
        }
        spill.push(&Frames::encode(FrameEncoding::Png, frames.bytes(), shape))
    }

    /// Raw values: LeRobot normalizes with the episodes' statistics.
    fn write_lowdim(
        &mut self,
        channel: usize,
        raw: &Arc<LowdimStore>,
        _: &RowNormalizer,
    ) -> Result<()> {
        self.raw[channel] = Some(Arc::clone(raw));
        Ok(())
    }

    /// LeRobot makes its own windows (`delta_timestamps`); chunkc's index is not stored.
    fn write_index(&mut self, _: &dyn WindowIndex) -> Result<()> {
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<super::Finished> {
        self.encoders.finish()?;
        let stats = self.data()?;
        let videos = self.cameras.iter().flatten().count();
        let groot = !self.groot.is_empty();
        for (p, part) in self.parts.iter().enumerate() {
            // The profile folder, when it is a dataset, is one even without an episode; another
            // folder only when it has episodes.
            if part.episodes.is_empty() && !part.set.dir.is_empty() {
                continue;
            }
            let table = self.table(p);
            let info = |name: &str, shape: &[usize]| self.video_info(part, name, shape);
            let meta = Meta {
                part,
                fps: self.fps,
                lengths: (part.episodes.iter())
                    .map(|&e| self.ends.range(e).len() as u64)
                    .collect(),
                features: features(&table, true, info),
                videos,
                stats: part.episodes.iter().map(|&e| stats[e].clone()).collect(),
            };
            // The training dataset's `meta/stats.json` is chunkc's (written by `exec`); a
            // `groot` dataset's is GR00T's.
            meta.write(&self.files, !part.set.dir.is_empty() && !groot)?;
            if groot {
                let dataset = super::groot::Dataset {
                    modality: &self.groot[part.set.source.unwrap_or(0)],
                    table: &table,
                    raw: &self.raw,
                    episodes: part.episodes.iter().map(|&e| self.ends.range(e)).collect(),
                    horizon: self.horizon,
                };
                let files = match part.set.dir.as_str() {
                    "" => self.files.clone(),
                    dir => self.files.under(dir),
                };
                super::groot::write(&files, &dataset)?;
            }
        }
        Ok(super::Finished {
            written: self.files.take_written(),
            ..Default::default()
        })
    }
}
