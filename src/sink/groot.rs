//! GR00T's files of one LeRobot v2.1 dataset (`preset = "groot"`), as Isaac-GR00T N1.7 reads
//! them (`gr00t/data/dataset/lerobot_episode_loader.py`, `gr00t/data/stats.py`):
//!
//! - `meta/modality.json`: `state` and `action` parts (`start`, `end`, `original_key`: a slice
//!   of a column's vector), `video` keys (`original_key`: the camera's feature) and the
//!   `annotation` `human.task_description` (`original_key`: `task_index`);
//! - `meta/stats.json`: per float feature of `meta/info.json` (every low-dimensional channel,
//!   and `timestamp`), per dimension over every row of the dataset, GR00T's six statistics:
//!   `mean`, `std` (ddof 0), `min`, `max`, `q01`, `q99` (numpy's linear quantiles). GR00T
//!   computes this file when it is missing or lacks a float feature, and trusts it otherwise;
//!   chunkc's means and stds are exact (GR00T accumulates float32);
//! - `meta/relative_stats.json`, where the profile names `relative_actions`: per relative
//!   action part, the same six statistics of shape (horizon, dims) over every chunk that fits in
//!   its episode (`length - horizon + 1` per episode), each step the action part minus the state
//!   part of the same name at the chunk's first step, as `RelativeActionLoader` makes them.
//!
//! The statistics read the dataset's rows from the row store twice or more (moments, then the
//! exact quantiles a group of columns at a time), never holding them all.

use std::ops::Range;
use std::sync::Arc;

use serde_json::{json, Map, Value};

use super::lerobot_files::DatasetFiles;
use super::lerobot_rows::{timestamp, DataTable};
use crate::error::{Error, Result};
use crate::plan::groot::{GrootModality, GrootPart, TASK_ANNOTATION};
use crate::source::ChannelKind;
use crate::stats::{lowdim_from_rows, shaped, ChannelStats, Moments};
use crate::store::LowdimStore;

/// What one dataset's GR00T files are made from.
pub(super) struct Dataset<'a> {
    pub modality: &'a GrootModality,
    /// The dataset's columns (a mixture source's at its own widths).
    pub table: &'a DataTable<'a>,
    pub raw: &'a [Option<Arc<LowdimStore>>],
    /// The stored rows of each of its episodes, in order.
    pub episodes: Vec<Range<usize>>,
    /// The action chunk (the profile's `chunk`).
    pub horizon: usize,
}

/// Writes the dataset's `meta/modality.json`, `meta/stats.json` and, with relative actions,
/// `meta/relative_stats.json`.
pub(super) fn write(files: &DatasetFiles, d: &Dataset) -> Result<()> {
    files.json("meta/modality.json", &modality(d.modality))?;
    files.json("meta/stats.json", &stats(d)?)?;
    if !d.modality.relative_actions.is_empty() {
        files.json("meta/relative_stats.json", &relative_stats(d)?)?;
    }
    Ok(())
}

/// `meta/modality.json`.
pub(super) fn modality(m: &GrootModality) -> Value {
    let parts = |parts: &[GrootPart]| -> Map<String, Value> {
        parts
            .iter()
            .map(|p| {
                let entry = json!({"start": p.start, "end": p.end, "original_key": p.channel});
                (p.name.clone(), entry)
            })
            .collect()
    };
    let video: Map<String, Value> = (m.video.iter())
        .map(|(key, channel)| (key.clone(), json!({"original_key": channel})))
        .collect();
    json!({
        "state": parts(&m.state),
        "action": parts(&m.action),
        "video": video,
        "annotation": {TASK_ANNOTATION: {"original_key": "task_index"}},
    })
}

/// GR00T's six statistics of `s`, each shaped `shape` (a vector: flat).
fn six(s: &ChannelStats, shape: &[usize]) -> Value {
    let v = |x: &[f64]| shaped::nested(x, shape);
    json!({
        "mean": v(&s.mean), "std": v(&s.std), "min": v(&s.min), "max": v(&s.max),
        "q01": v(&s.q01), "q99": v(&s.q99),
    })
}

/// Exact statistics of `dims` columns over the blocks `pass` gives (the same blocks each call).
fn exact(
    dims: usize,
    mut pass: impl FnMut(&mut dyn FnMut(&[f32])) -> Result<()>,
) -> Result<ChannelStats> {
    let mut m = Moments::new(dims);
    pass(&mut |block| m.merge(&Moments::of_rows(block, dims)))?;
    lowdim_from_rows(m, dims, None, pass)
}

/// `meta/stats.json`: every float feature of `meta/info.json`, in its order.
fn stats(d: &Dataset) -> Result<Value> {
    let mut doc = Map::new();
    for (c, name, shape, kind) in d.table.written() {
        if kind != ChannelKind::Lowdim {
            continue;
        }
        let raw = d.raw[c]
            .as_ref()
            .ok_or_else(|| Error::Internal(format!("no values for {name}")))?;
        let dims = shape.iter().product::<usize>().max(1);
        let s = exact(dims, |f| {
            for r in &d.episodes {
                f(&d.table.rows(raw, c, r.start, r.end)?);
            }
            Ok(())
        })?;
        doc.insert(name.to_string(), six(&s, &[dims]));
    }
    let fps = d.table.fps;
    let s = exact(1, |f| {
        for r in &d.episodes {
            let column: Vec<f32> = (0..r.len()).map(|i| timestamp(i, fps)).collect();
            f(&column);
        }
        Ok(())
    })?;
    doc.insert("timestamp".into(), six(&s, &[1]));
    Ok(Value::Object(doc))
}

/// `meta/relative_stats.json`: the relative action parts in name order (GR00T's `sorted`).
fn relative_stats(d: &Dataset) -> Result<Value> {
    let mut names = d.modality.relative_actions.clone();
    names.sort();
    let mut doc = Map::new();
    for name in names {
        let (action, state) = match (d.modality.action_part(&name), d.modality.state_part(&name)) {
            (Some(a), Some(s)) => (a, s),
            _ => {
                return Err(Error::Internal(format!(
                    "relative action `{name}` unresolved"
                )))
            }
        };
        let column = |channel: &str| -> Result<(usize, &Arc<LowdimStore>, usize)> {
            let c = (d.table.channels.iter())
                .position(|(n, ..)| n == channel)
                .ok_or_else(|| Error::Internal(format!("no channel {channel}")))?;
            let raw = d.raw[c]
                .as_ref()
                .ok_or_else(|| Error::Internal(format!("no values for {channel}")))?;
            let width = d
                .table
                .shape_of(c)
                .map_or(0, |s| s.iter().product::<usize>().max(1));
            Ok((c, raw, width))
        };
        let (ca, ra, wa) = column(&action.channel)?;
        let (cs, rs, ws) = column(&state.channel)?;
        let (h, dims) = (d.horizon, action.end - action.start);
        let chunks: usize = (d.episodes.iter())
            .map(|r| (r.len() + 1).saturating_sub(h))
            .sum();
        if chunks == 0 {
            return Err(Error::output(format!(
                "GR00T's relative statistics of `{name}`: no episode of the dataset is as long \
                 as the action horizon ({h} steps)"
            )));
        }
        let s = exact(h * dims, |f| {
            for r in &d.episodes {
                if r.len() < h {
                    continue;
                }
                let acts = d.table.rows(ra, ca, r.start, r.end)?;
                let states = d.table.rows(rs, cs, r.start, r.end)?;
                let mut block = Vec::with_capacity((r.len() + 1 - h) * h * dims);
                for t in 0..=r.len() - h {
                    let base = &states[t * ws + state.start..t * ws + state.end];
                    for step in t..t + h {
                        let a = &acts[step * wa + action.start..step * wa + action.end];
                        block.extend(a.iter().zip(base).map(|(x, b)| x - b));
                    }
                }
                f(&block);
            }
            Ok(())
        })?;
        doc.insert(name.clone(), six(&s, &[h, dims]));
    }
    Ok(Value::Object(doc))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modality_json_is_groots_schema() {
        let part = |name: &str, channel: &str, start, end| GrootPart {
            name: name.into(),
            channel: channel.into(),
            start,
            end,
        };
        let m = GrootModality {
            state: vec![
                part("arm", "observation.state", 0, 7),
                part("gripper", "observation.state", 7, 8),
            ],
            action: vec![part("action", "action", 0, 8)],
            video: vec![("top".into(), "observation.images.top".into())],
            relative_actions: vec![],
        };
        let v = modality(&m);
        assert_eq!(
            v["state"]["gripper"],
            json!({"start": 7, "end": 8, "original_key": "observation.state"})
        );
        assert_eq!(
            v["video"]["top"],
            json!({"original_key": "observation.images.top"})
        );
        assert_eq!(
            v["annotation"],
            json!({"human.task_description": {"original_key": "task_index"}})
        );
        let keys: Vec<&String> = v.as_object().unwrap().keys().collect();
        assert_eq!(keys, ["state", "action", "video", "annotation"]);
    }
}
