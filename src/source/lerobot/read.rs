//! Reading a LeRobot episode once the dataset is open: its parquet columns (each column chunk
//! decoded once, shared by the episodes of a row group), its timestamps, its camera frames; the
//! [`Source`] implementation.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::PathBuf;
use std::sync::Arc;

use super::super::block_cache::{self, DecodeCounts};
use super::super::mapping::{self, Raw};
use super::super::parquet_read::{self, read_columns};
use super::super::{Episode, Manifest, Source, VideoCheck};
use super::{FileRowGroups, LerobotSource};
use crate::error::{Error, Result};
use rayon::prelude::*;

impl Source for LerobotSource {
    fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn read_timestamps(&self, index: usize) -> Result<Option<Vec<f64>>> {
        if !self.has_timestamp {
            return Ok(None);
        }
        if let Some(t) = self.stamps[index].get() {
            return Ok(Some(t.clone()));
        }
        let info = &self.manifest.episodes[index];
        let path = self.root.join(&self.locations[index].0);
        let place = format!("{}: episode {}", path.display(), info.id);
        let t = match self.columns(index, &[("timestamp", 1)]) {
            Ok(mut cols) => cols.pop().expect("timestamp was asked for"),
            Err(_) => self
                .columns_of_episode(index, &[("timestamp", 1)], &place)?
                .remove(0),
        };
        Ok(Some(self.stamps[index].get_or_init(|| t).clone()))
    }

    fn read_episode(&self, index: usize) -> Result<Episode> {
        self.read(index, true)
    }

    /// The low-dim channels only: the videos are not decoded (the doctor reads every episode's
    /// low-dim values before the build).
    fn read_lowdim(&self, index: usize, channels: &[usize]) -> Result<Vec<Vec<f32>>> {
        Ok(self.read(index, false)?.take_lowdim(channels))
    }

    fn video_checks(&self, index: usize) -> Result<Vec<VideoCheck>> {
        if self.videos.keys(index).next().is_none() {
            return Ok(Vec::new());
        }
        let stamps = self.read_timestamps(index)?;
        let times = self.row_times(index, stamps.as_deref());
        Ok(self.videos.checks(index, &times))
    }

    fn decode_counts(&self) -> DecodeCounts {
        let mut out = DecodeCounts::new();
        for ((file, rg, column), n) in self.cache.decodes() {
            out.entry(format!("{}/{column}", file.display()))
                .or_default()
                .insert(vec![rg as u64], n);
        }
        out
    }

    fn only_reading(&mut self, positions: &[usize]) {
        let mut by_file: BTreeMap<PathBuf, Vec<Range<u64>>> = BTreeMap::new();
        for &i in positions {
            if let (rel, Some(r)) = &self.locations[i] {
                by_file
                    .entry(rel.clone())
                    .or_default()
                    .push(r.start as u64..r.end as u64);
            }
        }
        let mut done: BTreeMap<PathBuf, Arc<FileRowGroups>> = BTreeMap::new();
        for i in 0..self.locations.len() {
            let (rel, _) = &self.locations[i];
            let Some(f) = &self.footers[i] else { continue };
            let updated = done.entry(rel.clone()).or_insert_with(|| {
                let mut ranges = by_file.remove(rel).unwrap_or_default();
                ranges.sort_by_key(|r| r.start);
                let users = block_cache::users_per_block(&ranges, &f.0.starts, f.0.rows);
                Arc::new((f.0.clone(), users))
            });
            self.footers[i] = Some(updated.clone());
        }
    }
}

impl LerobotSource {
    /// The time each row of episode `index` looks its frames up at: its `timestamp`, or
    /// `frame_index / fps` in a dataset without the column.
    fn row_times(&self, index: usize, stamps: Option<&[f64]>) -> Vec<f64> {
        match stamps {
            Some(t) => t.to_vec(),
            None => {
                let fps = self.manifest.fps;
                (0..self.manifest.episodes[index].len)
                    .map(|k| k as f64 / fps)
                    .collect()
            }
        }
    }

    /// The columns `wanted` (name, values per step) of episode `index`, as `rows × width`
    /// values each, from its data file's row groups: each row group's column decoded once
    /// (through the cache), however many episodes it holds.
    fn columns(&self, index: usize, wanted: &[(&str, usize)]) -> Result<Vec<Vec<f64>>> {
        let (rel, rows) = &self.locations[index];
        let path = self.root.join(rel);
        let loaded;
        let (footer, users): (&parquet_read::Footer, Option<&[u32]>) = match &self.footers[index] {
            Some(f) => (&f.0, Some(&f.1)),
            None => {
                loaded = parquet_read::footer(&path)?;
                (&loaded, None)
            }
        };
        let rows = match rows {
            Some(r) => r.start as u64..r.end as u64,
            None => 0..footer.rows,
        };
        let mut out = Vec::with_capacity(wanted.len());
        for &(name, width) in wanted {
            let mut values = vec![0f64; (rows.end - rows.start) as usize * width];
            let first = footer
                .starts
                .partition_point(|&s| s <= rows.start)
                .saturating_sub(1);
            for rg in first..footer.starts.len() {
                let lo = footer.starts[rg];
                if lo >= rows.end {
                    break;
                }
                let hi = footer.starts.get(rg + 1).copied().unwrap_or(footer.rows);
                let n = users.and_then(|u| u.get(rg).copied()).unwrap_or(1);
                let what = format!("{}: `{name}`", path.display());
                let decoded = self
                    .cache
                    .get(&(rel.clone(), rg, name.to_string()), n, || {
                        let v =
                            parquet_read::row_group_column(&path, footer, rg, name, width, &what)?;
                        let bytes = v.len() * 8;
                        Ok::<_, Error>((v, bytes))
                    })?;
                let (a, b) = (rows.start.max(lo), rows.end.min(hi));
                if a < b {
                    let src = &decoded[(a - lo) as usize * width..(b - lo) as usize * width];
                    let at = (a - rows.start) as usize * width;
                    values[at..at + src.len()].copy_from_slice(src);
                }
            }
            out.push(values);
        }
        Ok(out)
    }

    /// The columns `wanted` of episode `index` read from its own rows alone (not cached): the
    /// way to a message that names the bad step within the episode.
    fn columns_of_episode(
        &self,
        index: usize,
        wanted: &[(&str, usize)],
        place: &str,
    ) -> Result<Vec<Vec<f64>>> {
        let (rel, rows) = &self.locations[index];
        let names: Vec<&str> = wanted.iter().map(|(n, _)| *n).collect();
        let cols = read_columns(&self.root.join(rel), &names, rows.clone())?;
        cols.iter()
            .zip(wanted)
            .map(|(batches, (name, width))| {
                parquet_read::to_f64_rows(batches, *width, &format!("{place}: `{name}`"))
            })
            .collect()
    }
}

impl LerobotSource {
    /// Reads episode `index`; without `decode_video` its video channels are zeros.
    // Long function: the parquet columns, the cameras and the channel assembly of one episode.
    fn read(&self, index: usize, decode_video: bool) -> Result<Episode> {
        let info = &self.manifest.episodes[index];
        let (rel, _) = &self.locations[index];
        let path = self.root.join(rel);
        let place = format!("{}: episode {}", path.display(), info.id);
        let all_keys = self.mapped.keys();
        let (video_keys, keys): (Vec<String>, Vec<String>) =
            all_keys.into_iter().partition(|k| self.videos.is_video(k));
        let widths: BTreeMap<&str, usize> = self
            .mapped
            .recipes
            .iter()
            .flat_map(|r| r.parts.iter().map(|p| (p.key.as_str(), p.width)))
            .collect();
        let mut wanted: Vec<(&str, usize)> = keys
            .iter()
            .map(|k| (k.as_str(), widths[k.as_str()]))
            .collect();
        let kept = self.stamps[index].get();
        if self.has_timestamp && kept.is_none() {
            wanted.push(("timestamp", 1));
        }
        // Through the decoded row groups; on a bad value, read the episode's own rows again the
        // plain way, so that the message names the step in this episode (or, when the bad row
        // is another episode's, this one reads fine).
        let mut cols = match self.columns(index, &wanted) {
            Ok(cols) => cols,
            Err(_) => self.columns_of_episode(index, &wanted, &place)?,
        };
        let timestamps = match kept {
            Some(t) => Some(t.clone()),
            None if self.has_timestamp => cols.pop(),
            None => None,
        };
        let mut by_key: BTreeMap<&str, Vec<f64>> =
            keys.iter().map(String::as_str).zip(cols).collect();
        // Cameras side by side, each file decoded sequentially (see `video`).
        let mut frames: BTreeMap<&str, Vec<u8>> = BTreeMap::new();
        let mut packets = BTreeMap::new();
        if !video_keys.is_empty() && !decode_video {
            // Frames of the right size, never decoded: the caller keeps only the low-dim values.
            for c in self.mapped.channels.iter().filter(|c| c.shape.len() == 3) {
                if video_keys.contains(&c.key) {
                    frames.insert(
                        c.key.as_str(),
                        vec![0u8; info.len * c.shape.iter().product::<usize>()],
                    );
                }
            }
        } else if !video_keys.is_empty() {
            let stamps = self.row_times(index, timestamps.as_deref());
            let shapes: BTreeMap<&str, [usize; 3]> = self
                .mapped
                .channels
                .iter()
                .filter(|c| c.shape.len() == 3)
                .map(|c| (c.key.as_str(), [c.shape[0], c.shape[1], c.shape[2]]))
                .collect();
            let decoded: Vec<Result<Vec<u8>>> = video_keys
                .par_iter()
                .map(|k| {
                    let shape = shapes.get(k.as_str()).copied().ok_or_else(|| {
                        Error::source(format!("{place}: `{k}` is not an (H, W, C) video"))
                    })?;
                    self.videos.decode(index, info.id, k, &stamps, shape)
                })
                .collect();
            for (k, d) in video_keys.iter().zip(decoded) {
                frames.insert(k.as_str(), d?);
                // The channel that is this camera's frames as they are.
                let channel = self
                    .mapped
                    .recipes
                    .iter()
                    .position(|r| matches!(r.parts.as_slice(), [p] if p.key == *k));
                let is_image = |c: usize| self.mapped.channels[c].shape.len() == 3;
                if let Some(c) = channel.filter(|&c| is_image(c)) {
                    if let Some(span) = self.videos.span(index, k, &stamps) {
                        packets.insert(c, span);
                    }
                }
            }
        }
        let channels = mapping::assemble(&self.mapped, info.len, &place, |key| {
            if let Some(f) = frames.remove(key) {
                return Ok(Raw::U8(f));
            }
            let values = by_key.remove(key).expect("every mapped key was read");
            Ok(Raw::F32(values.into_iter().map(|v| v as f32).collect()))
        })?;
        Ok(Episode {
            id: info.id,
            len: info.len,
            timestamps,
            channels,
            packets,
        })
    }
}
