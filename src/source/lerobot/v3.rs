//! LeRobot v3.0: many episodes per `data/chunk-XXX/file-XXX.parquet`; `meta/episodes/**.parquet`
//! has one row per episode with its `length`, data file (`data/chunk_index`, `data/file_index`)
//! and `tasks` (the first is the episode's task). An episode's rows are found from the data
//! file's `episode_index` column, and must be contiguous.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use arrow_array::cast::AsArray;
use arrow_array::types::Int64Type;
use arrow_array::Array;

use super::info::{fill, Info};
use super::{Listing, VideoRef};
use crate::error::{Error, Result};
use crate::source::mapping::KeyInfo;
use crate::source::parquet_read::{self, read_columns};
use crate::source::{fingerprint, EpisodeInfo};

/// One row of v3.0's `meta/episodes`: the episode, its length, its data file and its videos.
struct EpisodeRow {
    id: u64,
    len: usize,
    chunk: u64,
    file: u64,
    videos: BTreeMap<String, VideoRef>,
}

/// The episodes of a v3.0 dataset and where their rows are in the shared data files.
pub(super) fn list(root: &Path, info: &Info, media: &[&KeyInfo]) -> Result<Listing> {
    let mut l = Listing::default();
    let meta_dir = root.join("meta/episodes");
    let metas: Vec<PathBuf> = fingerprint::list_files(&meta_dir)?
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "parquet"))
        .collect();
    if metas.is_empty() {
        return Err(Error::source(format!(
            "{}: no parquet files; a v3.0 dataset lists its episodes there",
            meta_dir.display()
        )));
    }
    let mut rows: Vec<EpisodeRow> = Vec::new();
    for rel in &metas {
        l.read_files.push(Path::new("meta/episodes").join(rel));
        rows.extend(episode_rows(
            &meta_dir.join(rel),
            info,
            media,
            &mut l.tasks,
        )?);
    }
    rows.sort_by_key(|r| r.id);
    if let Some(w) = rows.windows(2).find(|w| w[0].id == w[1].id) {
        return Err(Error::source(format!(
            "{}: episode {} is listed twice",
            meta_dir.display(),
            w[0].id
        )));
    }
    // Each data file once: where each episode's rows are in it.
    let mut ranges: BTreeMap<PathBuf, BTreeMap<u64, Range<usize>>> = BTreeMap::new();
    for row in rows {
        let rel = data_file(root, &info.data_path, &row, &mut ranges, &mut l.read_files)?;
        let range = ranges[&rel].get(&row.id).cloned().ok_or_else(|| {
            Error::source(format!(
                "{}: no rows of episode {}, which meta/episodes places there",
                root.join(&rel).display(),
                row.id
            ))
        })?;
        if range.len() != row.len {
            return Err(Error::source(format!(
                "{}: episode {} has {} rows, but meta/episodes gives length {}",
                root.join(&rel).display(),
                row.id,
                range.len(),
                row.len
            )));
        }
        l.video_files.push(row.videos);
        l.episodes.push(EpisodeInfo {
            id: row.id,
            len: row.len,
        });
        l.locations.push((rel, Some(range)));
    }
    Ok(l)
}

/// The rows of one `meta/episodes` table; each episode's task goes into `tasks`.
fn episode_rows(
    path: &Path,
    info: &Info,
    media: &[&KeyInfo],
    tasks: &mut BTreeMap<u64, String>,
) -> Result<Vec<EpisodeRow>> {
    let mut names = vec![
        "episode_index",
        "length",
        "data/chunk_index",
        "data/file_index",
    ];
    let video_cols = video_columns(media);
    for (_, cols) in &video_cols {
        names.extend(cols.iter().map(String::as_str));
    }
    // `tasks` read with the rest, when the table has it (hand-made sets may not).
    let has_tasks = parquet_read::has_column(path, "tasks")?;
    if has_tasks {
        names.push("tasks");
    }
    let cols = read_columns(path, &names, None)?;
    let first_tasks = if has_tasks {
        let what = format!("{}: `tasks`", path.display());
        Some(parquet_read::first_strings(&cols[names.len() - 1], &what)?)
    } else {
        None
    };
    let floats = |i: usize| -> Result<Vec<f64>> {
        parquet_read::to_f64_rows(&cols[i], 1, &format!("{}: `{}`", path.display(), names[i]))
    };
    let ints = |i: usize| -> Result<Vec<u64>> {
        floats(i).map(|v| v.into_iter().map(|x| x as u64).collect())
    };
    let (ids, lens, chunk, file) = (ints(0)?, ints(1)?, ints(2)?, ints(3)?);
    let videos: Vec<VideoCols> = (0..video_cols.len())
        .map(|j| {
            let at = 4 + 4 * j;
            Ok((ints(at)?, ints(at + 1)?, floats(at + 2)?, floats(at + 3)?))
        })
        .collect::<Result<_>>()?;
    let mut rows = Vec::with_capacity(ids.len());
    for r in 0..ids.len() {
        if let Some(task) = first_tasks
            .as_ref()
            .and_then(|t| t.get(r).cloned().flatten())
        {
            tasks.insert(ids[r], task);
        }
        rows.push(EpisodeRow {
            id: ids[r],
            len: lens[r] as usize,
            chunk: chunk[r],
            file: file[r],
            videos: video_refs(info, &video_cols, &videos, r),
        });
    }
    Ok(rows)
}

/// A video feature's columns in `meta/episodes`: chunk, file, from and to timestamps.
type VideoCols = (Vec<u64>, Vec<u64>, Vec<f64>, Vec<f64>);

/// Each media feature's key and the names of its four columns.
fn video_columns(media: &[&KeyInfo]) -> Vec<(String, [String; 4])> {
    let cols = [
        "chunk_index",
        "file_index",
        "from_timestamp",
        "to_timestamp",
    ];
    let named = |m: &&KeyInfo| {
        let col = |what: &str| format!("videos/{}/{what}", m.key);
        (m.key.clone(), cols.map(col))
    };
    media.iter().map(named).collect()
}

/// Row `r`'s video of each media feature (none without info.json's `video_path`).
fn video_refs(
    info: &Info,
    video_cols: &[(String, [String; 4])],
    videos: &[VideoCols],
    r: usize,
) -> BTreeMap<String, VideoRef> {
    let mut out = BTreeMap::new();
    let Some(template) = &info.video_path else {
        return out;
    };
    for ((key, _), (chunks, files, from, to)) in video_cols.iter().zip(videos) {
        let v = [
            ("video_key", key.clone()),
            ("chunk_index", chunks[r].to_string()),
            ("file_index", files[r].to_string()),
        ];
        let video = VideoRef {
            file: PathBuf::from(fill(template, &v)),
            from: from[r],
            to: Some(to[r]),
        };
        out.insert(key.clone(), video);
    }
    out
}

/// The data file of `row` (relative to the root), its episodes' row ranges read into `ranges`
/// the first time it is named (and the file added to `read_files`).
fn data_file(
    root: &Path,
    data_path: &str,
    row: &EpisodeRow,
    ranges: &mut BTreeMap<PathBuf, BTreeMap<u64, Range<usize>>>,
    read_files: &mut Vec<PathBuf>,
) -> Result<PathBuf> {
    let values = [
        ("chunk_index", row.chunk.to_string()),
        ("file_index", row.file.to_string()),
    ];
    let rel = PathBuf::from(fill(data_path, &values));
    if !ranges.contains_key(&rel) {
        let path = root.join(&rel);
        if !path.exists() {
            return Err(Error::source(format!(
                "{}: episode {}: data file {} is missing",
                root.display(),
                row.id,
                rel.display()
            )));
        }
        ranges.insert(rel.clone(), episode_ranges(&path)?);
        read_files.push(rel.clone());
    }
    Ok(rel)
}

/// Where each episode's rows are in a v3.0 data file, from its `episode_index` column. An
/// episode whose rows are not contiguous is an error.
fn episode_ranges(path: &Path) -> Result<BTreeMap<u64, Range<usize>>> {
    let cols = read_columns(path, &["episode_index"], None)?;
    let mut out: BTreeMap<u64, Range<usize>> = BTreeMap::new();
    let mut row = 0usize;
    let mut previous: Option<u64> = None;
    for batch in &cols[0] {
        let values: Vec<u64> = match batch.data_type() {
            arrow_schema::DataType::Int64 => batch
                .as_primitive::<Int64Type>()
                .values()
                .iter()
                .map(|&v| v as u64)
                .collect(),
            _ => parquet_read::to_f64_rows(std::slice::from_ref(batch), 1, "episode_index")?
                .into_iter()
                .map(|v| v as u64)
                .collect(),
        };
        for e in values {
            if previous != Some(e) {
                if out.contains_key(&e) {
                    return Err(Error::source(format!(
                        "{}: the rows of episode {e} are not contiguous (again at row {row})",
                        path.display()
                    )));
                }
                out.insert(e, row..row);
            }
            out.get_mut(&e).expect("inserted").end = row + 1;
            previous = Some(e);
            row += 1;
        }
    }
    Ok(out)
}
