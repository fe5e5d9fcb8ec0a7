// Long file: one writer: LeRobot v3.0's data, episodes, info and stats files are written together.
//! LeRobot v3.0's dataset layout (`format = "parquet"`), plus chunkc's window index.
//!
//! ```text
//! data/chunk-000/file-000.parquet   one row per stored step, one row group per episode:
//!                                   <channel> FixedSizeList<float32> raw (low-dim) or
//!                                   struct {bytes: PNG, path: null} (images), timestamp
//!                                   float32 = frame_index / fps, frame_index, episode_index
//!                                   (source id), index (global row), task_index (int64);
//!                                   a training mixture's `source_index` (int64)
//! meta/info.json                    codebase_version "v3.0", fps, features, totals, paths
//! meta/episodes/chunk-000/file-000.parquet  one row per episode
//! meta/tasks.parquet                task_index, the task strings as pandas' index (LeRobot's
//!                                   `tasks.iloc[task_index].name`): each episode's task from
//!                                   the source (an RLDS language instruction, a LeRobot
//!                                   source's own task), else "chunkc"
//! meta/stats.json                   written by `exec` (LeRobot's statistics layout)
//! chunkc_index.parquet              chunkc's window index: split, episode, t, limit, sub
//! videos/<channel>/chunk-000/file-000.mp4   with `image_encoding = "video"`: every frame of
//!                                   the camera, stored row `i` at time `i / fps`
//! ```
//! Values are raw: LeRobot normalizes in its policy with `meta/stats.json`, and chunkc's loader
//! normalizes on read. Writer properties are fixed (created_by, zstd level, no dictionary,
//! chunk statistics), so the bytes depend only on the contents.
//!
//! Frames arrive PNG-encoded (in `exec`'s parallel stage) episode by episode, before the low-dim
//! channels the same row groups need: they wait in a scratch file per camera, and `finish`
//! writes the data file one episode (one row group) at a time, so memory holds one episode.
//!
//! With `image_encoding = "video"` frames arrive raw and go straight to one encoder per camera,
//! each on its own thread ([`super::video_encode::Background`]): the camera is a `dtype:
//! "video"` feature of `meta/info.json` (with the `info` block LeRobot's `get_video_info`
//! writes), has no column in the data file, and `meta/episodes` locates each episode in its mp4
//! (`videos/<channel>/{chunk_index, file_index, from_timestamp, to_timestamp}`), as LeRobot's
//! own writer does.

use std::sync::Arc;

use arrow_array::builder::{ListBuilder, StringBuilder};
use arrow_array::{ArrayRef, RecordBatch};
use arrow_schema::{DataType, Field, Schema};
use serde_json::{json, Value};

use super::lerobot_columns::{err, i64_col, Channel};
use super::lerobot_features::features;
use super::lerobot_files::DatasetFiles;
use super::lerobot_rows::{DataTable, EpisodeRows};
use super::lerobot_spill::{FrameSpill, SpillReader};
pub use super::lerobot_tasks::tasks_table;
use super::lerobot_tasks::Tasks;
use super::lerobot_v3_videos::V3Videos;
use super::{FrameEncoding, Frames, Sink, SinkContext, Split, WindowIndex};
use crate::error::{Error, Result};
use crate::source::ChannelKind;
use crate::stats::normalize::RowNormalizer;
use crate::store::LowdimStore;

pub const DATA_PATH: &str = crate::spec::OutputFormat::Parquet.files().data;
pub const INDEX_FILE: &str = "chunkc_index.parquet";
pub const STATS_PATH: &str = "meta/stats.json";
/// LeRobot's `video_path` template (v3.0).
pub const VIDEO_PATH: &str = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4";

/// Where camera `name`'s video goes (the one file of [`VIDEO_PATH`] chunkc writes by default).
pub fn video_file(name: &str) -> String {
    super::lerobot_v3_videos::shared_file(name)
}

pub struct LerobotWriter {
    files: DatasetFiles,
    fps: f64,
    ends: Vec<u64>,
    ids: Vec<u64>,
    /// A mixture's: each stored episode's source, the `source_index` column (empty: none).
    sources: Vec<usize>,
    /// The tasks, in the order their first episode is stored, and each stored episode's.
    tasks: Tasks,
    /// Per channel: the name, its shape, its kind.
    channels: Vec<Channel>,
    raw: Vec<Option<Arc<LowdimStore>>>,
    /// Per channel: its PNG frames by stored row (images stored as PNG only).
    frames: Vec<Option<FrameSpill>>,
    /// The cameras, when images are stored as video.
    videos: Option<V3Videos>,
    train: Vec<[i64; 4]>,
    val: Vec<[i64; 4]>,
}

impl LerobotWriter {
    /// Whether channels of `kind` are stored as video.
    fn is_video(&self, kind: ChannelKind) -> bool {
        kind == ChannelKind::Image && self.videos.is_some()
    }

    /// The channels stored as video: (name, shape).
    fn video_channels(&self) -> impl Iterator<Item = (&str, &[usize])> + '_ {
        self.channels
            .iter()
            .filter(|(_, _, k)| self.is_video(*k))
            .map(|(n, s, _)| (n.as_str(), s.as_slice()))
    }

    pub fn create(ctx: &SinkContext) -> Result<Self> {
        let v = &ctx.profile.values;
        let files = DatasetFiles::new(ctx.dir, v.compression, v.compression_level)?;
        let channels: Vec<Channel> = ctx
            .profile
            .channels
            .iter()
            .map(|c| (c.name.clone(), c.shape.clone(), c.kind))
            .collect();
        let steps = *ctx.episode_ends.last().unwrap_or(&0) as usize;
        let videos = V3Videos::create(ctx, &channels)?;
        let video = videos.is_some();
        Ok(LerobotWriter {
            files,
            fps: ctx.profile.fps,
            ends: ctx.episode_ends.to_vec(),
            ids: ctx.episode_ids.to_vec(),
            sources: ctx.episode_sources.to_vec(),
            tasks: Tasks::of(ctx.episode_ids, ctx.tasks),
            raw: channels.iter().map(|_| None).collect(),
            frames: channels
                .iter()
                .enumerate()
                .map(|(c, (_, _, k))| match k {
                    ChannelKind::Image if !video => {
                        let file = format!("{}-frames-{c}", ctx.profile.name);
                        FrameSpill::create(ctx.scratch.join(file), steps).map(Some)
                    }
                    _ => Ok(None),
                })
                .collect::<Result<_>>()?,
            videos,
            channels,
            train: Vec::new(),
            val: Vec::new(),
        })
    }

    /// The data table's layout.
    fn table(&self) -> DataTable<'_> {
        DataTable {
            channels: &self.channels,
            video: self.videos.is_some(),
            fps: self.fps,
            mixture: !self.sources.is_empty(),
            own: None,
        }
    }

    fn data(&mut self) -> Result<()> {
        let mut frames: Vec<Option<SpillReader>> = std::mem::take(&mut self.frames)
            .into_iter()
            .map(|f| f.map(FrameSpill::into_reader).transpose())
            .collect::<Result<_>>()?;
        let table = self.table();
        let schema = table.schema();
        let mut start = 0usize;
        let batches = self.ends.iter().enumerate().map(|(e, &end)| {
            let rows = start..end as usize;
            start = rows.end;
            let ep = EpisodeRows {
                first_index: rows.start as i64,
                rows,
                episode_index: self.ids[e] as i64,
                task: self.tasks.of_episode[e] as i64,
                source: self.sources.get(e).copied(),
            };
            table.batch(&schema, &self.raw, &mut frames, &ep)
        });
        self.files.parquet(DATA_PATH, schema.clone(), batches)
    }

    fn episodes(&self) -> Result<()> {
        let mut fields = vec![
            Field::new("episode_index", DataType::Int64, false),
            Field::new(
                "tasks",
                DataType::List(Arc::new(Field::new("item", DataType::Utf8, true))),
                false,
            ),
            Field::new("length", DataType::Int64, false),
            Field::new("dataset_from_index", DataType::Int64, false),
            Field::new("dataset_to_index", DataType::Int64, false),
            Field::new("data/chunk_index", DataType::Int64, false),
            Field::new("data/file_index", DataType::Int64, false),
        ];
        for (name, _) in self.video_channels() {
            for (column, dt) in [
                ("chunk_index", DataType::Int64),
                ("file_index", DataType::Int64),
                ("from_timestamp", DataType::Float64),
                ("to_timestamp", DataType::Float64),
            ] {
                fields.push(Field::new(format!("videos/{name}/{column}"), dt, false));
            }
        }
        let schema = Arc::new(Schema::new(fields));
        let n = self.ends.len();
        let starts: Vec<i64> = std::iter::once(0)
            .chain(self.ends.iter().map(|&e| e as i64))
            .take(n)
            .collect();
        let mut tasks = ListBuilder::new(StringBuilder::new());
        for &t in &self.tasks.of_episode {
            tasks.values().append_value(&self.tasks.names[t]);
            tasks.append(true);
        }
        let tasks = tasks.finish();
        let mut cols: Vec<ArrayRef> = vec![
            i64_col(self.ids.iter().map(|&i| i as i64)),
            Arc::new(tasks),
            i64_col(self.ends.iter().zip(&starts).map(|(&e, &s)| e as i64 - s)),
            i64_col(starts.iter().copied()),
            i64_col(self.ends.iter().map(|&e| e as i64)),
            i64_col((0..n).map(|_| 0)),
            i64_col((0..n).map(|_| 0)),
        ];
        // Where each episode's frames are in its camera's file(s).
        if let Some(videos) = &self.videos {
            let at: Vec<(i64, i64, f64, f64)> =
                (0..n).map(|e| videos.location(e, self.fps)).collect();
            let seconds = |f: fn(&(i64, i64, f64, f64)) -> f64| -> ArrayRef {
                Arc::new(arrow_array::Float64Array::from_iter_values(
                    at.iter().map(f),
                ))
            };
            for _ in self.video_channels() {
                cols.push(i64_col(at.iter().map(|a| a.0)));
                cols.push(i64_col(at.iter().map(|a| a.1)));
                cols.push(seconds(|a| a.2));
                cols.push(seconds(|a| a.3));
            }
        }
        let batch = RecordBatch::try_new(schema.clone(), cols).map_err(err)?;
        self.files.parquet(
            "meta/episodes/chunk-000/file-000.parquet",
            schema,
            [Ok(batch)],
        )?;

        let (schema, batch) = tasks_table(&self.tasks.names)?;
        self.files
            .parquet("meta/tasks.parquet", schema, [Ok(batch)])
    }

    fn info(&self) -> Result<()> {
        let video_info = |name: &str, shape: &[usize]| {
            let c = self.channels.iter().position(|(n, ..)| n == name);
            match (&self.videos, c) {
                (Some(videos), Some(c)) => videos.info(&self.files.dir, c, shape, self.fps),
                _ => Value::Null,
            }
        };
        let features = features(&self.table(), false, video_info);
        let n = self.ends.len();
        let video_path = self
            .video_channels()
            .next()
            .map(|_| Value::String(VIDEO_PATH.into()))
            .unwrap_or(Value::Null);
        let doc = json!({
            "codebase_version": "v3.0",
            "robot_type": null,
            "total_episodes": n,
            "total_frames": self.ends.last().copied().unwrap_or(0),
            "total_tasks": self.tasks.names.len(),
            "chunks_size": 1000,
            "fps": self.fps,
            "splits": {"train": format!("0:{n}")},
            "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
            "video_path": video_path,
            "features": Value::Object(features),
        });
        self.files.json("meta/info.json", &doc)
    }

    /// `chunkc_index.parquet`: every window, the training ones first. The windows are let go as
    /// their columns are built (2 million windows are 64 MB, and the columns as much again).
    fn chunkc_index(&mut self) -> Result<()> {
        let schema = Arc::new(Schema::new(vec![
            Field::new("split", DataType::Utf8, false),
            Field::new("episode", DataType::Int64, false),
            Field::new("t", DataType::Int64, false),
            Field::new("limit", DataType::Int64, false),
            Field::new("sub", DataType::Int64, false),
        ]));
        let (train, val) = (
            std::mem::take(&mut self.train),
            std::mem::take(&mut self.val),
        );
        let names = [("train", train.len()), ("val", val.len())];
        let bytes = names.iter().map(|(name, n)| name.len() * n).sum();
        let mut split = StringBuilder::with_capacity(train.len() + val.len(), bytes);
        for (name, n) in names {
            (0..n).for_each(|_| split.append_value(name));
        }
        let mut cols: Vec<ArrayRef> = vec![Arc::new(split.finish())];
        for k in 0..4 {
            cols.push(i64_col(train.iter().chain(&val).map(|r| r[k])));
        }
        drop((train, val));
        let batch = RecordBatch::try_new(schema.clone(), cols).map_err(err)?;
        self.files.parquet(INDEX_FILE, schema, [Ok(batch)])
    }
}

impl Sink for LerobotWriter {
    fn data_file(&self) -> &str {
        DATA_PATH
    }

    fn frame_encoding(&self) -> FrameEncoding {
        match self.videos {
            Some(_) => FrameEncoding::Raw,
            None => FrameEncoding::Png,
        }
    }

    fn stores_normalized(&self) -> bool {
        false
    }

    fn write_frames(&mut self, channel: usize, row: usize, frames: &Frames) -> Result<()> {
        if let Some(videos) = self.videos.as_mut().filter(|v| v.has(channel)) {
            return videos.push(channel, row, frames);
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
        spill.push(frames)
    }

    /// Raw values: LeRobot normalizes with `meta/stats.json`.
    fn write_lowdim(
        &mut self,
        channel: usize,
        raw: &Arc<LowdimStore>,
        _: &RowNormalizer,
    ) -> Result<()> {
        self.raw[channel] = Some(Arc::clone(raw));
        Ok(())
    }

    fn write_index(&mut self, index: &dyn WindowIndex) -> Result<()> {
        self.train = index.all(Split::Train)?;
        self.val = index.all(Split::Val)?;
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<super::Finished> {
        if let Some(videos) = self.videos.as_mut() {
            videos.finish()?;
        }
        self.data()?;
        self.episodes()?;
        self.info()?;
        self.chunkc_index()?;
        Ok(super::Finished {
            written: self.files.take_written(),
            ..Default::default()
        })
    }
}
