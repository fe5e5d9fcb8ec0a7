//! The rows of a LeRobot data file (v3.0's shared file, v2.1's file per episode): the stored
//! channels (a camera stored as video has no column), then LeRobot's `timestamp`,
//! `frame_index`, `episode_index`, `index` and `task_index`, and a mixture's `source_index`.

use std::ops::Range;
use std::sync::Arc;

use arrow_array::{ArrayRef, Float32Array, RecordBatch};
use arrow_schema::{DataType, Field, Schema};
use serde_json::{json, Value};

use super::lerobot_columns::{err, i64_col, image_fields, lowdim_column, lowdim_type, Channel};
use super::lerobot_spill::SpillReader;
use crate::error::{Error, Result};
use crate::source::ChannelKind;
use crate::store::LowdimStore;

/// LeRobot's columns after the channels, with their `info.json` dtypes.
pub(super) const INDEX_COLUMNS: [(&str, &str); 5] = [
    ("timestamp", "float32"),
    ("frame_index", "int64"),
    ("episode_index", "int64"),
    ("index", "int64"),
    ("task_index", "int64"),
];

/// The column of a training mixture's episodes' source.
pub(super) const SOURCE_COLUMN: &str = "source_index";

/// The layout of a data file.
pub(super) struct DataTable<'a> {
    pub channels: &'a [Channel],
    /// Whether cameras are stored as video (then they have no column).
    pub video: bool,
    pub fps: f64,
    /// A training mixture's (a `source_index` column).
    pub mixture: bool,
    /// A mixture source's dataset of its own: per channel, the source's own width (the first
    /// values of each stored row; 0: the source lacks the channel, which has no column).
    /// `None`: every channel as stored.
    pub own: Option<&'a [usize]>,
}

/// One episode's rows: where they are in the stored arrays and the values of its index columns.
pub(super) struct EpisodeRows {
    /// Its stored rows.
    pub rows: Range<usize>,
    /// `episode_index`.
    pub episode_index: i64,
    /// `index` of its first row.
    pub first_index: i64,
    pub task: i64,
    /// A mixture's: the episode's source.
    pub source: Option<usize>,
}

impl DataTable<'_> {
    /// Whether channel `kind` has a column.
    pub(super) fn has_column(&self, kind: ChannelKind) -> bool {
        !(self.video && kind == ChannelKind::Image)
    }

    /// The per-step shape channel `c` is written at: a mixture source's own width of a padded
    /// vector; `None` where the source lacks the channel.
    pub(super) fn shape_of(&self, c: usize) -> Option<Vec<usize>> {
        let (_, shape, kind) = &self.channels[c];
        match (self.own, kind) {
            (Some(own), ChannelKind::Lowdim) => match own[c] {
                0 => None,
                w if w != shape.iter().product::<usize>() => Some(vec![w]),
                _ => Some(shape.clone()),
            },
            _ => Some(shape.clone()),
        }
    }

    /// The channels written, with the shapes they are written at, by channel position.
    pub(super) fn written(&self) -> impl Iterator<Item = (usize, &str, Vec<usize>, ChannelKind)> {
        self.channels
            .iter()
            .enumerate()
            .filter_map(|(c, (name, _, kind))| Some((c, name.as_str(), self.shape_of(c)?, *kind)))
    }

    /// Stored rows `lo..hi` of low-dim channel `c` at its written width.
    pub(super) fn rows(
        &self,
        raw: &LowdimStore,
        c: usize,
        lo: usize,
        hi: usize,
    ) -> Result<Vec<f32>> {
        let rows = raw.rows(lo, hi)?;
        let stored = raw.width();
        let width = self
            .shape_of(c)
            .map_or(0, |s| s.iter().product::<usize>().max(1));
        if width >= stored || stored == 0 {
            return Ok(rows.into_owned());
        }
        Ok(rows
            .chunks_exact(stored)
            .flat_map(|row| &row[..width])
            .copied()
            .collect())
    }

    pub(super) fn schema(&self) -> Arc<Schema> {
        let mut fields = Vec::new();
        for (_, name, shape, kind) in self.written() {
            if !self.has_column(kind) {
                continue;
            }
            let dt = match kind {
                ChannelKind::Lowdim => lowdim_type(&shape),
                ChannelKind::Image => DataType::Struct(image_fields()),
            };
            fields.push(Field::new(name, dt, false));
        }
        for (name, dtype) in INDEX_COLUMNS {
            let dt = match dtype {
                "float32" => DataType::Float32,
                _ => DataType::Int64,
            };
            fields.push(Field::new(name, dt, false));
        }
        if self.mixture {
            fields.push(Field::new(SOURCE_COLUMN, DataType::Int64, false));
        }
        Arc::new(Schema::new(fields))
    }

    /// One episode's rows as a batch of `schema`: low-dim values from `raw`, frames read on from
    /// `frames` (per channel, the PNG frames of a camera with a column).
    pub(super) fn batch(
        &self,
        schema: &Arc<Schema>,
        raw: &[Option<Arc<LowdimStore>>],
        frames: &mut [Option<SpillReader>],
        ep: &EpisodeRows,
    ) -> Result<RecordBatch> {
        let (lo, hi) = (ep.rows.start, ep.rows.end);
        let mut cols: Vec<ArrayRef> = Vec::new();
        for (c, ((name, _, kind), (raw, frames))) in
            (self.channels.iter().zip(raw.iter().zip(frames.iter_mut()))).enumerate()
        {
            let Some(shape) = self.shape_of(c) else {
                continue;
            };
            if !self.has_column(*kind) {
                continue;
            }
            match (kind, frames) {
                (ChannelKind::Lowdim, _) => {
                    let raw = raw
                        .as_ref()
                        .ok_or_else(|| Error::Internal(format!("no values for {name}")))?;
                    cols.push(lowdim_column(self.rows(raw, c, lo, hi)?, &shape)?);
                }
                (ChannelKind::Image, Some(frames)) => {
                    cols.push(Arc::new(frames.next(hi - lo, name)?));
                }
                (ChannelKind::Image, None) => {
                    return Err(Error::Internal(format!("no frames of {name}")));
                }
            }
        }
        let n = hi - lo;
        cols.push(Arc::new(Float32Array::from_iter_values(
            (0..n).map(|i| timestamp(i, self.fps)),
        )));
        cols.push(i64_col((0..n).map(|i| i as i64)));
        cols.push(i64_col((0..n).map(|_| ep.episode_index)));
        cols.push(i64_col((0..n).map(|i| ep.first_index + i as i64)));
        cols.push(i64_col((0..n).map(|_| ep.task)));
        if let Some(source) = ep.source {
            cols.push(i64_col((0..n).map(|_| source as i64)));
        }
        RecordBatch::try_new(schema.clone(), cols).map_err(err)
    }
}

/// The `timestamp` of an episode's row `i`: `i / fps`, as float32.
pub(super) fn timestamp(i: usize, fps: f64) -> f32 {
    (i as f64 / fps) as f32
}

/// The data files' schema: nullable columns, as `datasets` writes them, with its features in
/// the `huggingface` metadata, so that lerobot 0.3.3 (which reads the files with
/// `load_dataset("parquet")`, no features given) gets PNG frames as images.
pub(super) fn with_hf_features(table: &DataTable) -> Arc<Schema> {
    let schema = table.schema();
    let mut features = serde_json::Map::new();
    let fields: Vec<arrow_schema::Field> = schema
        .fields()
        .iter()
        .map(|f| {
            features.insert(f.name().clone(), hf_feature(f.data_type()));
            f.as_ref().clone().with_nullable(true)
        })
        .collect();
    let info = json!({"info": {"features": Value::Object(features)}});
    let metadata = [("huggingface".to_string(), info.to_string())].into();
    Arc::new(Schema::new_with_metadata(fields, metadata))
}

/// The `datasets` feature of a column of arrow type `dt`.
fn hf_feature(dt: &arrow_schema::DataType) -> Value {
    use arrow_schema::DataType as D;
    match dt {
        D::Float32 => json!({"dtype": "float32", "_type": "Value"}),
        D::Int64 => json!({"dtype": "int64", "_type": "Value"}),
        D::FixedSizeList(item, n) => {
            json!({"feature": hf_feature(item.data_type()), "length": n, "_type": "Sequence"})
        }
        _ => json!({"_type": "Image"}),
    }
}
