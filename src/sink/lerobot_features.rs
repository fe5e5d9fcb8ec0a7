//! `features` of a LeRobot `meta/info.json`: each channel's dtype, shape and names, a video
//! camera's `info` block, then the index columns.
//!
//! v3.0 (chunkc's v3.0 export, as before) leaves a channel's `names` null. v2.1 names every
//! channel, because GR00T's loader reads `names` of every feature (`KeyError: 'names'`):
//! cameras `["height", "width", "channels"]` as LeRobot writes them, a vector its elements
//! (`<channel>_<i>`, from the channel's last dotted part: `state_0`), anything else its axes.

use serde_json::{json, Map, Value};

use super::lerobot_rows::{DataTable, INDEX_COLUMNS, SOURCE_COLUMN};
use crate::source::ChannelKind;

/// The names of a camera's axes, as LeRobot writes them.
pub(super) const CAMERA_AXES: [&str; 3] = ["height", "width", "channels"];

/// `features`: `named` says whether channels get names (v2.1) or `null` (v3.0); `video_info`
/// gives the `info` block of a camera stored as video.
pub(super) fn features(
    table: &DataTable,
    named: bool,
    video_info: impl Fn(&str, &[usize]) -> Value,
) -> Map<String, Value> {
    let mut features = Map::new();
    for (_, name, shape, kind) in table.written() {
        let name = name.to_string();
        if !table.has_column(kind) {
            let info = video_info(&name, &shape);
            features.insert(
                name,
                json!({"dtype": "video", "shape": shape,
                       "names": CAMERA_AXES, "info": info}),
            );
            continue;
        }
        let dtype = match kind {
            ChannelKind::Lowdim => "float32",
            ChannelKind::Image => "image",
        };
        let shape = if shape.is_empty() { vec![1] } else { shape };
        let names = if named {
            names_of(&name, &shape, kind)
        } else {
            Value::Null
        };
        features.insert(
            name,
            json!({"dtype": dtype, "shape": shape, "names": names}),
        );
    }
    for (name, dtype) in INDEX_COLUMNS {
        features.insert(
            name.into(),
            json!({"dtype": dtype, "shape": [1], "names": null}),
        );
    }
    if table.mixture {
        features.insert(
            SOURCE_COLUMN.into(),
            json!({"dtype": "int64", "shape": [1], "names": null}),
        );
    }
    features
}

/// A channel's names: a camera's axes, a vector's elements, another shape's axes.
fn names_of(name: &str, shape: &[usize], kind: ChannelKind) -> Value {
    if kind == ChannelKind::Image && shape.len() == 3 {
        return json!(CAMERA_AXES);
    }
    let base = name.rsplit('.').next().unwrap_or(name);
    match shape {
        [d] => json!((0..*d).map(|i| format!("{base}_{i}")).collect::<Vec<_>>()),
        _ => json!((0..shape.len())
            .map(|a| format!("{base}_axis{a}"))
            .collect::<Vec<_>>()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_channel_is_named_in_v21() {
        let channels = vec![
            ("action".to_string(), vec![2], ChannelKind::Lowdim),
            ("observation.state".to_string(), vec![], ChannelKind::Lowdim),
            (
                "observation.keypoint".to_string(),
                vec![9, 2],
                ChannelKind::Lowdim,
            ),
            (
                "observation.image".to_string(),
                vec![4, 6, 3],
                ChannelKind::Image,
            ),
        ];
        let table = DataTable {
            channels: &channels,
            video: false,
            fps: 10.0,
            mixture: false,
            own: None,
        };
        let f = features(&table, true, |_, _| Value::Null);
        assert_eq!(f["action"]["names"], json!(["action_0", "action_1"]));
        assert_eq!(f["observation.state"]["shape"], json!([1]));
        assert_eq!(f["observation.state"]["names"], json!(["state_0"]));
        assert_eq!(
            f["observation.keypoint"]["names"],
            json!(["keypoint_axis0", "keypoint_axis1"])
        );
        assert_eq!(f["observation.image"]["names"], json!(CAMERA_AXES));
        assert_eq!(f["timestamp"]["names"], Value::Null);
        let v3 = features(&table, false, |_, _| Value::Null);
        assert_eq!(v3["action"]["names"], Value::Null);
        assert!(v3.contains_key("task_index") && !v3.contains_key(SOURCE_COLUMN));
    }
}
