//! LeRobot v2.1's layout: where an episode's files go, and the `meta/` folder of one dataset
//! (`info.json`, `episodes.jsonl`, `tasks.jsonl`, `episodes_stats.jsonl`), as lerobot 0.3.3
//! writes them.
//!
//! The export is two datasets: the profile folder itself holds the training episodes, and
//! `val/` the validation episodes (openpi and GR00T train on every episode of the dataset they
//! are given, so the validation episodes cannot share it). A `groot` profile over a mixture
//! writes that pair once per source instead, in `sources/<name>/` (GR00T mixes datasets
//! itself), and none in the profile folder. In each, `episode_index` runs 0..N-1 in stored
//! order, the position LeRobot and GR00T index by; `meta.json` keeps each stored episode's
//! source id beside its dataset and `episode_index`.

use serde_json::{json, Map, Value};

use super::lerobot_episode_stats::FeatureStats;
use super::lerobot_files::DatasetFiles;
use super::lerobot_tasks::Tasks;
use crate::error::Result;

/// Episodes per chunk folder (LeRobot's `DEFAULT_CHUNK_SIZE`).
pub const CHUNKS_SIZE: usize = 1000;
/// LeRobot v2.1's `data_path` and `video_path` templates.
pub const DATA_PATH: &str = "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet";
pub const VIDEO_PATH: &str =
    "videos/chunk-{episode_chunk:03d}/{video_key}/episode_{episode_index:06d}.mp4";
/// The folder of the validation episodes' dataset, in the profile folder.
pub const VAL_DIR: &str = "val";

/// The data file of episode `index`.
pub fn data_file(index: usize) -> String {
    format!(
        "data/chunk-{:03}/episode_{index:06}.parquet",
        index / CHUNKS_SIZE
    )
}

/// The video of camera `key` of episode `index`.
pub fn video_file(key: &str, index: usize) -> String {
    format!(
        "videos/chunk-{:03}/{key}/episode_{index:06}.mp4",
        index / CHUNKS_SIZE
    )
}

/// The export's datasets and where each stored episode goes.
pub struct Layout {
    pub datasets: Vec<Dataset>,
    /// Per stored episode: its dataset and its `episode_index` there.
    pub place: Vec<(usize, usize)>,
}

/// One dataset of the export.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Dataset {
    /// Its name in `meta.json`: `train` and `val`, or a `groot` mixture's `sources/<name>` and
    /// `sources/<name>/val`.
    pub name: String,
    /// Its folder in the profile folder (`""`: the profile folder itself).
    pub dir: String,
    /// A `groot` mixture's: the source whose dataset it is (at the source's own widths).
    pub source: Option<usize>,
    /// Whether it holds training episodes (else validation ones).
    pub train: bool,
}

/// The datasets of a v2.1 export of stored episodes `ids` (mixture ids in a mixture), `is_val`
/// saying which are validation episodes: the profile folder (training) and `val/`; a `groot`
/// profile over a mixture (`per_source`, the sources' names in order, each with the mixture id
/// of its first episode) instead one pair per source in `sources/<name>/`, since GR00T mixes
/// datasets itself. An episode's `episode_index` is its position among its dataset's.
pub fn layout(ids: &[u64], is_val: impl Fn(u64) -> bool, per_source: &[(&str, u64)]) -> Layout {
    let mut datasets = Vec::new();
    if per_source.is_empty() {
        for (train, name, dir) in [(true, "train", ""), (false, "val", VAL_DIR)] {
            let (name, dir) = (name.to_string(), dir.to_string());
            datasets.push(Dataset {
                name,
                dir,
                source: None,
                train,
            });
        }
    }
    for (s, (source, _)) in per_source.iter().enumerate() {
        let dir = format!("sources/{source}");
        for train in [true, false] {
            let dir = if train {
                dir.clone()
            } else {
                format!("{dir}/{VAL_DIR}")
            };
            datasets.push(Dataset {
                name: dir.clone(),
                dir,
                source: Some(s),
                train,
            });
        }
    }
    let mut counts = vec![0usize; datasets.len()];
    let place = ids
        .iter()
        .map(|&id| {
            let source = per_source
                .iter()
                .rposition(|&(_, first)| first <= id)
                .unwrap_or(0);
            let d = 2 * source + usize::from(is_val(id));
            counts[d] += 1;
            (d, counts[d] - 1)
        })
        .collect();
    Layout { datasets, place }
}

/// The layout of `profile`'s export (`sources`: the mixture's, empty for one source).
pub fn layout_of(
    profile: &crate::plan::ProfilePlan,
    sources: &[crate::source::SourcePart],
) -> Layout {
    let ids: Vec<u64> = profile.episodes.iter().map(|e| e.id).collect();
    let val: std::collections::BTreeSet<u64> = (profile.episodes.iter())
        .filter(|e| e.split != "train")
        .map(|e| e.id)
        .collect();
    let per_source: Vec<(&str, u64)> = match profile.values.preset {
        Some(crate::spec::Preset::Groot) => sources
            .iter()
            .map(|s| (s.name.as_str(), s.id_offset))
            .collect(),
        _ => Vec::new(),
    };
    layout(&ids, |id| val.contains(&id), &per_source)
}

/// `meta.json` of a v2.1 export: `data_format` `"lerobot_v2.1"` (chunkc's `loader.py` does not
/// read it: LeRobot's `LeRobotDataset` does), and `lerobot`: the version, each dataset's folder,
/// and per stored episode (`episodes`, the source ids) its dataset and `episode_index`.
pub fn describe(
    doc: &mut Value,
    profile: &crate::plan::ProfilePlan,
    sources: &[crate::source::SourcePart],
) {
    let layout = layout_of(profile, sources);
    let used: Vec<&Dataset> = (layout.datasets.iter().enumerate())
        .filter(|(d, set)| set.dir.is_empty() || layout.place.iter().any(|p| p.0 == *d))
        .map(|(_, set)| set)
        .collect();
    let folders: Map<String, Value> = used
        .iter()
        .map(|set| {
            let dir = if set.dir.is_empty() {
                "."
            } else {
                set.dir.as_str()
            };
            (set.name.clone(), json!(dir))
        })
        .collect();
    doc["data_format"] = json!(DATA_FORMAT);
    doc["lerobot"] = json!({
        "version": "v2.1",
        "datasets": folders,
        "dataset": layout.place.iter().map(|&(d, _)| layout.datasets[d].name.as_str()).collect::<Vec<_>>(),
        "episode_index": layout.place.iter().map(|&(_, i)| i).collect::<Vec<_>>(),
    });
}

/// `meta.json`'s `data_format` of a v2.1 export.
pub const DATA_FORMAT: &str = "lerobot_v2.1";

/// One of the export's datasets as the writer fills it: its place and its episodes.
pub(super) struct Part {
    pub set: Dataset,
    /// The stored positions of its episodes, in order: an episode's `episode_index` is its
    /// position here.
    pub episodes: Vec<usize>,
    pub tasks: Tasks,
}

impl Part {
    /// `rel` (a path in the dataset) as a path in the profile folder.
    pub(super) fn path(&self, rel: &str) -> String {
        match self.set.dir.as_str() {
            "" => rel.to_string(),
            dir => format!("{dir}/{rel}"),
        }
    }
}

/// What a dataset's `meta/` is written from.
pub(super) struct Meta<'a> {
    pub part: &'a Part,
    pub fps: f64,
    /// Rows of each episode.
    pub lengths: Vec<u64>,
    pub features: Map<String, Value>,
    /// Cameras stored as video.
    pub videos: usize,
    /// Per episode, each feature's statistics.
    pub stats: Vec<Vec<(String, FeatureStats)>>,
}

/// `fps` as LeRobot writes it: an integer where the rate is one.
fn fps_value(fps: f64) -> Value {
    if fps.fract() == 0.0 && fps.abs() < 1e15 {
        json!(fps as i64)
    } else {
        json!(fps)
    }
}

impl Meta<'_> {
    /// `meta/info.json`, `episodes.jsonl`, `tasks.jsonl`, `episodes_stats.jsonl`, and with
    /// `with_stats` `meta/stats.json` (the episodes' statistics aggregated, as LeRobot's
    /// `aggregate_stats` does; the training dataset's is chunkc's exact one, written by `exec`).
    pub(super) fn write(&self, files: &DatasetFiles, with_stats: bool) -> Result<()> {
        let files = match self.part.set.dir.as_str() {
            "" => files.clone(),
            dir => files.under(dir),
        };
        let n = self.part.episodes.len();
        let info = json!({
            "codebase_version": "v2.1",
            "robot_type": null,
            "total_episodes": n,
            "total_frames": self.lengths.iter().sum::<u64>(),
            "total_tasks": self.part.tasks.names.len(),
            "total_videos": n * self.videos,
            "total_chunks": n.div_ceil(CHUNKS_SIZE),
            "chunks_size": CHUNKS_SIZE,
            "fps": fps_value(self.fps),
            "splits": {"train": format!("0:{n}")},
            "data_path": DATA_PATH,
            "video_path": if self.videos > 0 { json!(VIDEO_PATH) } else { Value::Null },
            "features": Value::Object(self.features.clone()),
        });
        files.json("meta/info.json", &info)?;
        let tasks = &self.part.tasks;
        files.jsonl(
            "meta/episodes.jsonl",
            self.lengths.iter().enumerate().map(|(i, &length)| {
                json!({"episode_index": i, "tasks": [tasks.names[tasks.of_episode[i]]],
                       "length": length})
            }),
        )?;
        files.jsonl(
            "meta/tasks.jsonl",
            (tasks.names.iter().enumerate())
                .map(|(i, task)| json!({"task_index": i, "task": task})),
        )?;
        let entry = |stats: &[(String, FeatureStats)]| -> Value {
            let map: Map<String, Value> = stats
                .iter()
                .map(|(k, s)| (k.clone(), s.to_json()))
                .collect();
            Value::Object(map)
        };
        files.jsonl(
            "meta/episodes_stats.jsonl",
            self.stats
                .iter()
                .enumerate()
                .map(|(i, s)| json!({"episode_index": i, "stats": entry(s)})),
        )?;
        if with_stats {
            let mut total: Vec<(String, FeatureStats)> = Vec::new();
            for episode in &self.stats {
                for (name, s) in episode {
                    match total.iter_mut().find(|(k, _)| k == name) {
                        Some((_, t)) => t.merge(s),
                        None => total.push((name.clone(), s.clone())),
                    }
                }
            }
            files.json("meta/stats.json", &entry(&total))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn episodes_are_numbered_within_their_dataset_in_stored_order() {
        let l = layout(&[3, 5, 8, 9, 12], |id| id == 5 || id == 12, &[]);
        assert_eq!(l.place, [(0, 0), (1, 0), (0, 1), (0, 2), (1, 1)]);
        assert_eq!(
            (l.datasets[0].dir.as_str(), l.datasets[1].dir.as_str()),
            ("", "val")
        );
    }

    #[test]
    fn a_groot_mixture_has_a_pair_of_datasets_per_source() {
        let l = layout(
            &[0, 1, 2, 100, 101],
            |id| id == 1 || id == 101,
            &[("own", 0), ("sim", 100)],
        );
        let dirs: Vec<&str> = l.datasets.iter().map(|d| d.dir.as_str()).collect();
        assert_eq!(
            dirs,
            [
                "sources/own",
                "sources/own/val",
                "sources/sim",
                "sources/sim/val"
            ]
        );
        assert_eq!(l.place, [(0, 0), (1, 0), (0, 1), (2, 0), (3, 0)]);
        assert_eq!(l.datasets[3].source, Some(1));
    }

    #[test]
    fn paths_are_lerobots() {
        assert_eq!(data_file(7), "data/chunk-000/episode_000007.parquet");
        assert_eq!(data_file(1234), "data/chunk-001/episode_001234.parquet");
        assert_eq!(
            video_file("observation.images.top", 2),
            "videos/chunk-000/observation.images.top/episode_000002.mp4"
        );
        assert_eq!(fps_value(30.0), json!(30));
        assert_eq!(fps_value(7.5), json!(7.5));
    }
}
