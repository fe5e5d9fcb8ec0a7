//! LeRobot v3.0's layout (`lerobot/`): many episodes per parquet data file, one row group per
//! episode, as LeRobot's `LeRobotDataset` writes it; cameras (`--cameras N`) are mp4 videos, one
//! file per camera holding every episode, encoded with LeRobot's settings by
//! [`crate::sink::video_encode`] (AV1, yuv420p, g=2, crf=30), each camera on its own thread.
//!
//! ```text
//! data/chunk-000/file-<f>.parquet  action, observation.state: FixedSizeList<float32>;
//!                                  timestamp float32 (seconds: where the timing faults
//!                                  show), frame_index, episode_index, index, task_index int64
//! meta/episodes/chunk-000/file-000.parquet  episode_index, tasks, length,
//!                                  data/chunk_index, data/file_index,
//!                                  dataset_from_index, dataset_to_index
//! meta/tasks.parquet               task_index, the task as pandas' index (as LeRobot writes it)
//! meta/info.json                   codebase_version v3.0, fps, features, totals
//! videos/observation.images.cam<c>/chunk-000/file-000.mp4   row `i` of the dataset at
//!                                  `i / fps`; meta/episodes gains videos/<key>/chunk_index,
//!                                  file_index, from_timestamp, to_timestamp per camera
//! ```
//! Frames follow the rows: a `drop` fault removes a step's frame with its row, so the video's
//! times stay regular while the row timestamps show the gap (what LeRobot's tolerance check
//! then meets).

use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::builder::{ListBuilder, StringBuilder};
use arrow_array::{ArrayRef, FixedSizeListArray, Float32Array, Int64Array, RecordBatch};
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::ArrowWriter;
use parquet::basic::Compression;
use parquet::file::properties::WriterProperties;
use serde_json::json;

use super::{SynthEpisode, SynthOptions, SynthWriter};
use crate::error::{Error, IoContext, Result};
use crate::sink::video_encode::{self, Background, StreamShape};
use crate::spec::{StreamCopy, VideoCodec, VideoSettings, DEFAULT_VIDEO_CRF, DEFAULT_VIDEO_GOP};

/// Data files hold about this many bytes of values, like LeRobot's `data_files_size_in_mb`.
const FILE_BYTES: usize = 100 << 20;
const TASK: &str = "reach the synthetic target";

/// LeRobot's encoder settings (`encode_video_frames`' defaults).
const VIDEO: VideoSettings = VideoSettings {
    codec: VideoCodec::Libsvtav1,
    crf: DEFAULT_VIDEO_CRF,
    gop: DEFAULT_VIDEO_GOP,
    copy: StreamCopy::Never,
    // LeRobot's own files have a keyframe every `g` frames (what its decoders seek to).
    copy_gop: None,
    closed_gop: true,
};

/// The feature name of camera `c`, LeRobot's `observation.images.<camera>`.
pub fn camera_key(c: usize) -> String {
    format!("observation.images.cam{c}")
}

fn video_file(c: usize) -> String {
    format!("videos/{}/chunk-000/file-000.mp4", camera_key(c))
}

fn err(e: impl std::fmt::Display) -> Error {
    Error::output(format!("parquet: {e}"))
}

struct EpisodeMeta {
    id: u64,
    len: usize,
    file: u64,
    from: usize,
}

pub struct LerobotWriter {
    root: PathBuf,
    opts: SynthOptions,
    schema: Arc<Schema>,
    props: WriterProperties,
    writer: Option<ArrowWriter<File>>,
    file_index: u64,
    file_bytes: usize,
    rows: usize,
    episodes: Vec<EpisodeMeta>,
    /// One encoder per camera.
    videos: Vec<Background>,
}

fn item() -> Arc<Field> {
    Arc::new(Field::new("item", DataType::Float32, true))
}

fn list(values: &[f32], width: usize) -> Result<ArrayRef> {
    Ok(Arc::new(
        FixedSizeListArray::try_new(
            item(),
            width as i32,
            Arc::new(Float32Array::from(values.to_vec())),
            None,
        )
        .map_err(err)?,
    ))
}

fn i64s(values: impl IntoIterator<Item = i64>) -> ArrayRef {
    Arc::new(Int64Array::from_iter_values(values))
}

fn write_table(path: &Path, batch: RecordBatch, props: &WriterProperties) -> Result<()> {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).at("create", parent)?;
    }
    let file = File::create(path).at("create", path)?;
    let mut w = ArrowWriter::try_new(file, batch.schema(), Some(props.clone())).map_err(err)?;
    w.write(&batch).map_err(err)?;
    w.close().map_err(err)?;
    Ok(())
}

impl LerobotWriter {
    pub fn create(opts: &SynthOptions, root: &Path) -> Result<Self> {
        std::fs::create_dir_all(root).at("create", root)?;
        let mut fields = vec![
            Field::new(
                "action",
                DataType::FixedSizeList(item(), opts.action_dim as i32),
                false,
            ),
            Field::new(
                "observation.state",
                DataType::FixedSizeList(item(), opts.state_dim as i32),
                false,
            ),
            Field::new("timestamp", DataType::Float32, false),
        ];
        for name in ["frame_index", "episode_index", "index", "task_index"] {
            fields.push(Field::new(name, DataType::Int64, false));
        }
        let shape = StreamShape {
            height: opts.height,
            width: opts.width,
            fps: opts.fps,
        };
        let videos = (0..opts.cameras)
            .map(|c| {
                let path = root.join(video_file(c));
                let dir = path.parent().expect("has parent");
                std::fs::create_dir_all(dir).at("create", dir)?;
                Background::spawn(&path, shape, VIDEO)
            })
            .collect::<Result<_>>()?;
        Ok(LerobotWriter {
            root: root.to_path_buf(),
            opts: opts.clone(),
            schema: Arc::new(Schema::new(fields)),
            props: WriterProperties::builder()
                .set_created_by("chunkc synth".into())
                .set_compression(Compression::SNAPPY)
                .build(),
            writer: None,
            file_index: 0,
            file_bytes: 0,
            rows: 0,
            episodes: Vec::new(),
            videos,
        })
    }

    fn data_path(&self, file: u64) -> PathBuf {
        self.root
            .join(format!("data/chunk-000/file-{file:03}.parquet"))
    }
}

impl SynthWriter for LerobotWriter {
    fn episode(&mut self, ep: &SynthEpisode) -> Result<()> {
        let o = &self.opts;
        let bytes = ep.steps * 4 * (o.action_dim + o.state_dim + 1) + ep.steps * 32;
        if self.writer.is_some() && self.file_bytes + bytes > FILE_BYTES {
            self.writer.take().expect("open").close().map_err(err)?;
            self.file_index += 1;
            self.file_bytes = 0;
        }
        if self.writer.is_none() {
            let path = self.data_path(self.file_index);
            std::fs::create_dir_all(path.parent().expect("has parent")).at("create", &path)?;
            let file = File::create(&path).at("create", &path)?;
            self.writer = Some(
                ArrowWriter::try_new(file, self.schema.clone(), Some(self.props.clone()))
                    .map_err(err)?,
            );
        }
        let n = ep.steps;
        let cols: Vec<ArrayRef> = vec![
            list(&ep.action, o.action_dim)?,
            list(&ep.state, o.state_dim)?,
            Arc::new(Float32Array::from_iter_values(
                ep.timestamps.iter().map(|&t| t as f32),
            )),
            i64s(0..n as i64),
            i64s(std::iter::repeat_n(ep.id as i64, n)),
            i64s(self.rows as i64..(self.rows + n) as i64),
            i64s(std::iter::repeat_n(0, n)),
        ];
        let batch = RecordBatch::try_new(self.schema.clone(), cols).map_err(err)?;
        for (c, video) in self.videos.iter_mut().enumerate() {
            video
                .push(std::sync::Arc::new(ep.frames[c].clone()))
                .map_err(|e| {
                    Error::output(format!("episode {}, camera {}: {e}", ep.id, camera_key(c)))
                })?;
        }
        let w = self.writer.as_mut().expect("open");
        w.write(&batch).map_err(err)?;
        w.flush().map_err(err)?; // one row group per episode
        self.episodes.push(EpisodeMeta {
            id: ep.id,
            len: n,
            file: self.file_index,
            from: self.rows,
        });
        self.rows += n;
        self.file_bytes += bytes;
        Ok(())
    }

    // Long function: LeRobot v3.0's files (data, episodes, info, stats, tasks, videos) written together, in order.
    fn finish(mut self: Box<Self>) -> Result<()> {
        if let Some(w) = self.writer.take() {
            w.close().map_err(err)?;
        }
        for (c, video) in self.videos.iter_mut().enumerate() {
            let frames = video
                .finish()
                .map_err(|e| Error::output(format!("camera {}: {e}", camera_key(c))))?;
            if frames != self.rows as u64 {
                return Err(Error::Internal(format!(
                    "camera {}: {frames} frames for {} rows",
                    camera_key(c),
                    self.rows
                )));
            }
        }
        let eps = &self.episodes;
        let fps = self.opts.fps;
        let seconds = |rows: &mut dyn Iterator<Item = usize>| -> ArrayRef {
            Arc::new(arrow_array::Float64Array::from_iter_values(
                rows.map(|r| r as f64 / fps),
            ))
        };
        let mut tasks = ListBuilder::new(StringBuilder::new());
        for _ in eps {
            tasks.values().append_value(TASK);
            tasks.append(true);
        }
        let mut columns = vec![
            (
                "episode_index".to_string(),
                i64s(eps.iter().map(|e| e.id as i64)),
            ),
            ("tasks".into(), Arc::new(tasks.finish()) as ArrayRef),
            ("length".into(), i64s(eps.iter().map(|e| e.len as i64))),
            ("data/chunk_index".into(), i64s(eps.iter().map(|_| 0))),
            (
                "data/file_index".into(),
                i64s(eps.iter().map(|e| e.file as i64)),
            ),
            (
                "dataset_from_index".into(),
                i64s(eps.iter().map(|e| e.from as i64)),
            ),
            (
                "dataset_to_index".to_string(),
                i64s(eps.iter().map(|e| (e.from + e.len) as i64)),
            ),
        ];
        for c in 0..self.opts.cameras {
            let key = camera_key(c);
            columns.push((
                format!("videos/{key}/chunk_index"),
                i64s(eps.iter().map(|_| 0)),
            ));
            columns.push((
                format!("videos/{key}/file_index"),
                i64s(eps.iter().map(|_| 0)),
            ));
            columns.push((
                format!("videos/{key}/from_timestamp"),
                seconds(&mut eps.iter().map(|e| e.from)),
            ));
            columns.push((
                format!("videos/{key}/to_timestamp"),
                seconds(&mut eps.iter().map(|e| e.from + e.len)),
            ));
        }
        let meta = RecordBatch::try_from_iter(columns).map_err(err)?;
        write_table(
            &self.root.join("meta/episodes/chunk-000/file-000.parquet"),
            meta,
            &self.props,
        )?;
        let (_, tasks) = crate::sink::lerobot::tasks_table(&[TASK.to_string()])?;
        write_table(&self.root.join("meta/tasks.parquet"), tasks, &self.props)?;
        let o = &self.opts;
        let scalar = |dtype: &str| json!({"dtype": dtype, "shape": [1], "names": null});
        let mut cameras = serde_json::Map::new();
        for c in 0..o.cameras {
            cameras.insert(
                camera_key(c),
                json!({
                    "dtype": "video",
                    "shape": [o.height, o.width, 3],
                    "names": ["height", "width", "channels"],
                    "info": {
                        "video.height": o.height,
                        "video.width": o.width,
                        "video.codec": video_encode::codec_name(VIDEO.codec),
                        "video.pix_fmt": video_encode::PIX_FMT,
                        "video.is_depth_map": false,
                        "video.fps": o.fps.round() as u64,
                        "video.channels": 3,
                        "has_audio": false,
                    },
                }),
            );
        }
        let video_path = if o.cameras > 0 {
            json!(crate::sink::lerobot::VIDEO_PATH)
        } else {
            serde_json::Value::Null
        };
        let mut info = json!({
            "codebase_version": "v3.0",
            "robot_type": "chunkc_synth",
            "total_episodes": eps.len(),
            "total_frames": self.rows,
            "total_tasks": 1,
            "chunks_size": 1000,
            "data_files_size_in_mb": FILE_BYTES >> 20,
            "fps": o.fps,
            "splits": {"train": format!("0:{}", eps.len())},
            "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
            "video_path": video_path,
            "features": {
                "action": {"dtype": "float32", "shape": [o.action_dim],
                           "names": (0..o.action_dim).map(|d| format!("joint_{d}")).collect::<Vec<_>>()},
                "observation.state": {"dtype": "float32", "shape": [o.state_dim],
                           "names": (0..o.state_dim).map(|d| format!("joint_{d}")).collect::<Vec<_>>()},
                "timestamp": scalar("float32"),
                "frame_index": scalar("int64"),
                "episode_index": scalar("int64"),
                "index": scalar("int64"),
                "task_index": scalar("int64"),
            },
        });
        info["features"]
            .as_object_mut()
            .expect("an object")
            .extend(cameras);
        let path = self.root.join("meta/info.json");
        let mut text = serde_json::to_string_pretty(&info).expect("JSON serializes");
        text.push('\n');
        std::fs::write(&path, text).at("write", &path)?;
        Ok(())
    }
}
