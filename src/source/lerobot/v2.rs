//! LeRobot v2.0 / v2.1: one parquet file per episode (`data_path` in info.json), episodes listed
//! in `meta/episodes.jsonl` (`episode_index`, `length`, and `tasks`, whose first is the
//! episode's task).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde_json::Value;

use super::info::{fill, Info};
use super::{Listing, VideoRef};
use crate::error::{Error, Result};
use crate::source::mapping::KeyInfo;
use crate::source::parquet_read::num_rows;
use crate::source::EpisodeInfo;

/// The episodes of a v2 dataset, each with its own data file.
pub(super) fn list(root: &Path, info: &Info, media: &[&KeyInfo]) -> Result<Listing> {
    let shown = root.display().to_string();
    let (chunks_size, data_path) = (info.chunks_size, info.data_path.as_str());
    let mut l = Listing::default();
    let (read_files, episodes, locations, video_files) = (
        &mut l.read_files,
        &mut l.episodes,
        &mut l.locations,
        &mut l.video_files,
    );
    let list = root.join("meta/episodes.jsonl");
    read_files.push(PathBuf::from("meta/episodes.jsonl"));
    let (mut rows, tasks) = episodes_jsonl(&list)?;
    l.tasks = tasks;
    rows.sort();
    for (e, len) in rows {
        // Some v2.1 writers name the chunk `chunk_index` (v3.0's word) in their templates.
        let chunk = (e / chunks_size).to_string();
        let values = [
            ("episode_chunk", chunk.clone()),
            ("chunk_index", chunk),
            ("episode_index", e.to_string()),
        ];
        let rel = PathBuf::from(fill(data_path, &values));
        let file = root.join(&rel);
        if !file.exists() {
            return Err(Error::source(format!(
                "{shown}: episode {e}: data file {} is missing",
                rel.display()
            )));
        }
        let n = num_rows(&file)?;
        if n != len {
            return Err(Error::source(format!(
                "{}: {n} rows, but meta/episodes.jsonl gives episode {e} length {len}",
                file.display()
            )));
        }
        let mut videos = BTreeMap::new();
        if let Some(template) = &info.video_path {
            for m in media {
                let mut v = values.to_vec();
                v.push(("video_key", m.key.clone()));
                let file = PathBuf::from(fill(template, &v));
                let video = VideoRef {
                    file,
                    from: 0.0,
                    to: None,
                };
                videos.insert(m.key.clone(), video);
            }
        }
        video_files.push(videos);
        read_files.push(rel.clone());
        episodes.push(EpisodeInfo { id: e, len });
        locations.push((rel, None));
    }
    Ok(l)
}

/// `meta/episodes.jsonl`: each episode's id and length, and its task (the first of `tasks`).
type Listed = (Vec<(u64, usize)>, BTreeMap<u64, String>);

fn episodes_jsonl(list: &Path) -> Result<Listed> {
    let text = std::fs::read_to_string(list)
        .map_err(|e| Error::source(format!("{}: cannot read: {e}", list.display())))?;
    let (mut rows, mut tasks) = (Vec::new(), BTreeMap::new());
    for (n, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        let v: Value = serde_json::from_str(line).map_err(|e| {
            Error::source(format!("{}:{}: invalid JSON: {e}", list.display(), n + 1))
        })?;
        let (Some(e), Some(len)) = (v["episode_index"].as_u64(), v["length"].as_u64()) else {
            return Err(Error::source(format!(
                "{}:{}: needs `episode_index` and `length`",
                list.display(),
                n + 1
            )));
        };
        rows.push((e, len as usize));
        if let Some(task) = v["tasks"].get(0).and_then(Value::as_str) {
            tasks.insert(e, task.to_string());
        }
    }
    Ok((rows, tasks))
}
