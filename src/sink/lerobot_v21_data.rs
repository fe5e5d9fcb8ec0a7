//! A LeRobot v2.1 dataset's data files, one per episode, and each episode's statistics (what
//! `episodes_stats.jsonl` holds), written side by side on the pool: an episode's file and
//! statistics depend on its own rows alone. Cameras stored as PNG come from the scratch file
//! they were spilled to, in stored order, so their episodes' rows are gathered first, a group
//! at a time.

use std::collections::BTreeMap;
use std::sync::Arc;

use arrow_array::RecordBatch;
use arrow_schema::Schema;
use rayon::prelude::*;

use super::lerobot_episode_stats::FeatureStats;
use super::lerobot_files::DatasetFiles;
use super::lerobot_rows::{
    timestamp, with_hf_features, DataTable, EpisodeRows, INDEX_COLUMNS, SOURCE_COLUMN,
};
use super::lerobot_spill::SpillReader;
use super::lerobot_v21_meta::{data_file, Part};
use crate::error::{Error, Result};
use crate::source::ChannelKind;
use crate::store::LowdimStore;
use crate::window::Ends;

/// Episodes written at once, at most ...
const GROUP: usize = 64;
/// ... and, where their PNG frames are gathered first, those rows' bytes (at least one episode).
const GROUP_BYTES: usize = 64 << 20;

/// Each feature's statistics over one episode, in `features` order.
pub(super) type EpisodeStats = Vec<(String, FeatureStats)>;

/// What the episodes' files are made of: the stored rows and where each episode goes.
pub(super) struct EpisodeData<'a> {
    pub files: &'a DatasetFiles,
    pub ends: &'a Ends,
    pub ids: &'a [u64],
    /// A mixture's: each stored episode's source (empty otherwise).
    pub sources: &'a [usize],
    /// Per channel: its stored values (low-dim channels).
    pub raw: &'a [Option<Arc<LowdimStore>>],
    /// Per stored episode, per channel: the camera's statistics over the episode's frames.
    pub image_stats: &'a [BTreeMap<usize, FeatureStats>],
    pub parts: &'a [Part],
    /// Per part: its data table.
    pub tables: Vec<DataTable<'a>>,
    /// Per stored episode: its part and its `episode_index` there.
    pub place: &'a [(usize, usize)],
}

/// One episode to write: its stored position, its rows, and its batch where it was made first.
type Pending = (usize, EpisodeRows, Option<RecordBatch>);

impl EpisodeData<'_> {
    /// Writes every episode's data file (`frames`: per channel, the PNG frames spilled); returns
    /// each episode's statistics, in stored order.
    pub(super) fn write(&self, frames: &mut [Option<SpillReader>]) -> Result<Vec<EpisodeStats>> {
        let schemas: Vec<_> = self.tables.iter().map(with_hf_features).collect();
        let spilled = frames.iter().any(Option::is_some);
        let mut first_index = vec![0i64; self.parts.len()];
        let mut stats = Vec::with_capacity(self.ends.len());
        let (mut group, mut bytes): (Vec<Pending>, usize) = (Vec::new(), 0);
        for e in 0..self.ends.len() {
            let (p, index) = self.place[e];
            let table = &self.tables[p];
            let ep = EpisodeRows {
                rows: self.ends.range(e),
                episode_index: index as i64,
                first_index: first_index[p],
                task: self.parts[p].tasks.of_episode[index] as i64,
                source: self.sources.get(e).copied().filter(|_| table.mixture),
            };
            first_index[p] += ep.rows.len() as i64;
            let batch = match spilled {
                true => {
                    let batch = table.batch(&schemas[p], self.raw, frames, &ep)?;
                    bytes += batch.get_array_memory_size();
                    Some(batch)
                }
                false => None,
            };
            group.push((e, ep, batch));
            if group.len() == GROUP || bytes >= GROUP_BYTES || e + 1 == self.ends.len() {
                stats.extend(self.write_group(std::mem::take(&mut group), &schemas)?);
                bytes = 0;
            }
        }
        Ok(stats)
    }

    /// Writes the files of `group` side by side; their statistics, in order.
    fn write_group(
        &self,
        group: Vec<Pending>,
        schemas: &[Arc<Schema>],
    ) -> Result<Vec<EpisodeStats>> {
        crate::error::in_order(group.into_par_iter().map(|(e, ep, batch)| {
            let (p, index) = self.place[e];
            let table = &self.tables[p];
            let batch = match batch {
                Some(batch) => batch,
                None => {
                    let mut none: Vec<Option<SpillReader>> =
                        table.channels.iter().map(|_| None).collect();
                    table.batch(&schemas[p], self.raw, &mut none, &ep)?
                }
            };
            let path = self.parts[p].path(&data_file(index));
            self.files.parquet(&path, schemas[p].clone(), [Ok(batch)])?;
            self.stats(e, table, &ep)
        }))
    }

    /// Every feature's statistics over stored episode `e` (its rows `ep`, in `table`), in
    /// `features` order.
    fn stats(&self, e: usize, table: &DataTable, ep: &EpisodeRows) -> Result<EpisodeStats> {
        let mut out = Vec::new();
        for (c, name, shape, kind) in table.written() {
            let name = name.to_string();
            let s = match kind {
                ChannelKind::Lowdim => {
                    let raw = self.raw[c]
                        .as_ref()
                        .ok_or_else(|| Error::Internal(format!("no values for {name}")))?;
                    FeatureStats::of_rows(&table.rows(raw, c, ep.rows.start, ep.rows.end)?, &shape)
                }
                ChannelKind::Image => self.image_stats[e].get(&c).cloned().ok_or_else(|| {
                    Error::Internal(format!("no frames of {name} in episode {}", self.ids[e]))
                })?,
            };
            out.push((name, s));
        }
        let n = ep.rows.len();
        let constant = |v: i64| vec![v as f64; n];
        let columns: [Vec<f64>; 5] = [
            (0..n).map(|i| f64::from(timestamp(i, table.fps))).collect(),
            (0..n).map(|i| i as f64).collect(),
            constant(ep.episode_index),
            (0..n).map(|i| (ep.first_index + i as i64) as f64).collect(),
            constant(ep.task),
        ];
        for ((name, dtype), values) in INDEX_COLUMNS.iter().zip(&columns) {
            let integer = *dtype == "int64";
            out.push((name.to_string(), FeatureStats::of_column(values, integer)));
        }
        if let Some(source) = ep.source {
            let values = constant(source as i64);
            out.push((SOURCE_COLUMN.into(), FeatureStats::of_column(&values, true)));
        }
        Ok(out)
    }
}
