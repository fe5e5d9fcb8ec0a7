//! LeRobot's `meta/info.json`: the layout version, rate, features, path templates and splits.

use std::ops::Range;

use serde_json::Value;

use crate::error::{Error, Result};
use crate::source::mapping::KeyInfo;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Version {
    /// v2.0 and v2.1: one file per episode.
    V2,
    /// v3.0: many episodes per file.
    V3,
}

/// The widest zero-padded field a path template may ask for: a `u64` has 20 digits.
pub(super) const MAX_WIDTH: usize = 20;

/// The `{name}` / `{name:spec}` fields of a path template: each one's byte range, name and spec.
pub(super) fn fields(template: &str) -> Vec<(Range<usize>, &str, &str)> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(open) = template[from..].find('{').map(|i| from + i) {
        let Some(close) = template[open..].find('}').map(|i| open + i) else {
            break;
        };
        let inner = &template[open + 1..close];
        let (name, spec) = inner.split_once(':').unwrap_or((inner, ""));
        out.push((open..close + 1, name, spec));
        from = close + 1;
    }
    out
}

/// The zero-padded width a field's spec asks for (`03d` → 3; `` → 0).
pub(super) fn width(spec: &str) -> usize {
    spec.trim_start_matches('0')
        .trim_end_matches('d')
        .parse()
        .unwrap_or(0)
}

/// Python-style `{name}` / `{name:03d}` formatting of info.json's path templates, in one pass
/// (a value is never searched for fields again). A field whose name is not among `values` stays
/// as written. Widths are at most [`MAX_WIDTH`] ([`Info::parse`] refuses wider ones).
pub(super) fn fill(template: &str, values: &[(&str, String)]) -> String {
    let mut out = String::with_capacity(template.len());
    let mut from = 0;
    for (range, name, spec) in fields(template) {
        let Some((_, value)) = values.iter().find(|(n, _)| *n == name) else {
            continue;
        };
        out.push_str(&template[from..range.start]);
        let width = width(spec).min(MAX_WIDTH);
        out.push_str(&format!("{value:0>width$}"));
        from = range.end;
    }
    out.push_str(&template[from..]);
    out
}

/// One feature's per-step shape from info.json (`[]` and `[1]` both mean one value).
pub(super) fn feature_shape(feature: &Value) -> Vec<usize> {
    let shape: Vec<usize> = feature["shape"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|d| d.as_u64())
                .map(|d| d as usize)
                .collect()
        })
        .unwrap_or_default();
    if shape.is_empty() {
        vec![1]
    } else {
        shape
    }
}

/// A video or image feature's frame shape as (height, width, channels). LeRobot writes
/// `[H, W, C]` with `names: ["height", "width", "channels"]`, but other recorders write the frames'
/// tensor shape, `[C, H, W]` with `names: ["channel", "height", "width"]` (an SO-101 set of 25
/// episodes on the Hub does); the pixels in the mp4 are the same, and LeRobot reads either. A
/// shape is taken as channels-first when its names say so, or, with no names, when only its
/// first axis can be a channel count.
pub(super) fn frame_shape(feature: &Value) -> Vec<usize> {
    let shape = feature_shape(feature);
    if shape.len() != 3 {
        return shape;
    }
    let channels = |d: usize| matches!(d, 1 | 3 | 4);
    let names: Vec<&str> = feature["names"]
        .as_array()
        .map(|a| a.iter().filter_map(|n| n.as_str()).collect())
        .unwrap_or_default();
    let first_named_channel = names.len() == 3
        && names[0].to_ascii_lowercase().starts_with("channel")
        && names[1].eq_ignore_ascii_case("height")
        && names[2].eq_ignore_ascii_case("width");
    let unnamed_channel_first = names.is_empty() && !channels(shape[2]);
    if channels(shape[0]) && (first_named_channel || unnamed_channel_first) {
        vec![shape[1], shape[2], shape[0]]
    } else {
        shape
    }
}

/// `"0:100"` → 0..100 (info.json's `splits` values).
pub(super) fn split_range(text: &str) -> Option<Range<u64>> {
    let (a, b) = text.split_once(':')?;
    Some(a.trim().parse().ok()?..b.trim().parse().ok()?)
}

/// What chunkc reads from `meta/info.json`, before any other file is looked at.
#[derive(Debug, Clone)]
pub struct Info {
    pub(super) version: Version,
    /// `fps`, when the file stores it.
    pub fps: Option<f64>,
    /// Every feature, in the file's order, with its per-step shape and dtype.
    pub features: Vec<KeyInfo>,
    /// How many episodes share a `chunk-XXX` directory (v2 paths); at least 1.
    pub chunks_size: u64,
    /// The data file template (`data_path`, or the version's default).
    pub data_path: String,
    /// The video file template, when there is one.
    pub video_path: Option<String>,
    /// `splits` as (name, episode range) pairs; `None` when the file has no `splits` table.
    /// Values that are not `"a:b"` are left out.
    pub splits: Option<Vec<(String, Range<u64>)>>,
    /// Per video feature, the codec its `info` block claims (`video.codec`); the stream wins
    /// when they disagree.
    pub video_codecs: Vec<(String, String)>,
}

impl Info {
    /// Parses the bytes of an `info.json`; `shown` names the file in errors. Only the metadata is
    /// checked here: whether the files the templates name exist is the adapter's business.
    pub fn parse(bytes: &[u8], shown: &str) -> Result<Info> {
        let info: Value = serde_json::from_slice(bytes)
            .map_err(|e| Error::source(format!("{shown}: invalid JSON: {e}")))?;
        let at_info = |what: &str| Error::source(format!("{shown}: {what}"));
        let version = match info["codebase_version"].as_str() {
            Some("v2.0" | "v2.1") => Version::V2,
            Some("v3.0") => Version::V3,
            Some(other) => {
                return Err(at_info(&format!(
                    "codebase_version `{other}` is not one chunkc reads (v2.0, v2.1, v3.0)"
                )))
            }
            None => return Err(at_info("no `codebase_version`")),
        };
        let features = info["features"]
            .as_object()
            .ok_or_else(|| at_info("no `features` table"))?
            .iter()
            .map(|(key, f)| {
                let dtype = f["dtype"].as_str().unwrap_or("unknown").to_string();
                let shape = match dtype.as_str() {
                    "video" | "image" => frame_shape(f),
                    _ => feature_shape(f),
                };
                KeyInfo {
                    key: key.clone(),
                    shape,
                    dtype,
                }
            })
            .collect();
        let data_path = info["data_path"].as_str().unwrap_or(match version {
            Version::V2 => "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet",
            Version::V3 => "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        });
        let video_path = info["video_path"].as_str();
        for (key, template) in [("data_path", Some(data_path)), ("video_path", video_path)] {
            let fields = template.map(fields).unwrap_or_default();
            if let Some((_, name, spec)) = fields.iter().find(|(_, _, s)| width(s) > MAX_WIDTH) {
                return Err(at_info(&format!(
                    "`{key}` pads `{{{name}:{spec}}}` to {} digits; at most {MAX_WIDTH} make sense",
                    width(spec)
                )));
            }
        }
        let video_codecs = info["features"]
            .as_object()
            .into_iter()
            .flatten()
            .filter_map(|(key, f)| {
                Some((key.clone(), f["info"]["video.codec"].as_str()?.to_string()))
            })
            .collect();
        let splits = info["splits"].as_object().map(|splits| {
            splits
                .iter()
                .filter_map(|(k, v)| Some((k.clone(), split_range(v.as_str()?)?)))
                .collect()
        });
        Ok(Info {
            version,
            fps: info["fps"].as_f64(),
            features,
            chunks_size: info["chunks_size"].as_u64().unwrap_or(1000).max(1),
            data_path: data_path.to_string(),
            video_path: video_path.map(str::to_string),
            splits,
            video_codecs,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::{fill, frame_shape, split_range, Info};
    use serde_json::json;

    #[test]
    fn frame_shapes_come_out_height_width_channels() {
        let named = |shape: serde_json::Value, names: serde_json::Value| {
            frame_shape(&json!({"dtype": "video", "shape": shape, "names": names}))
        };
        let hwc = json!(["height", "width", "channels"]);
        let chw = json!(["channel", "height", "width"]);
        assert_eq!(named(json!([480, 640, 3]), hwc.clone()), [480, 640, 3]);
        assert_eq!(named(json!([3, 224, 224]), chw.clone()), [224, 224, 3]);
        assert_eq!(named(json!([3, 480, 640]), json!(null)), [480, 640, 3]);
        // Ambiguous without names (a 3x4 frame of 3 channels?): left as written.
        assert_eq!(named(json!([3, 4, 3]), json!(null)), [3, 4, 3]);
        // Names that do not say channels-first: left as written, for the shape check to judge.
        assert_eq!(named(json!([3, 224, 224]), hwc), [3, 224, 224]);
        assert_eq!(named(json!([4, 4, 224]), chw), [4, 224, 4]);
    }

    #[test]
    fn fills_python_templates() {
        let t = "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet";
        let v = [
            ("episode_chunk", "0".into()),
            ("episode_index", "42".into()),
        ];
        assert_eq!(fill(t, &v), "data/chunk-000/episode_000042.parquet");
        // A v2.1 template naming the chunk `chunk_index` (as a real SO-101 set's does).
        let t = "data/chunk-{chunk_index:03d}/episode_{episode_index:06d}.parquet";
        let v = [
            ("episode_chunk", "0".into()),
            ("chunk_index", "0".into()),
            ("episode_index", "7".into()),
        ];
        assert_eq!(fill(t, &v), "data/chunk-000/episode_000007.parquet");
        let t = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4";
        let v = [
            ("video_key", "observation.images.top".into()),
            ("chunk_index", "1".into()),
            ("file_index", "12".into()),
        ];
        assert_eq!(
            fill(t, &v),
            "videos/observation.images.top/chunk-001/file-012.mp4"
        );
    }

    #[test]
    fn fills_in_one_pass() {
        // A value that looks like a field is not filled again (this looped forever).
        let v = [("video_key", "{video_key:3}".into())];
        assert_eq!(fill("v/{video_key:3}/x", &v), "v/{video_key:3}/x");
        // Unknown fields and a lone brace stay as written.
        let v = [("episode_index", "7".into())];
        assert_eq!(fill("{other}/{episode_index:03d}/{", &v), "{other}/007/{");
    }

    #[test]
    fn refuses_absurd_widths() {
        // Found while writing the `lerobot_info` fuzz target: a 12-digit width made `fill`
        // build a 100 GB path.
        let json = br#"{"codebase_version": "v2.1", "features": {},
            "data_path": "data/episode_{episode_index:999999999999d}.parquet"}"#;
        let err = Info::parse(json, "info.json").unwrap_err().to_string();
        assert!(
            err.contains("`data_path` pads `{episode_index:999999999999d}`"),
            "{err}"
        );
        let json = br#"{"codebase_version": "v2.1", "features": {},
            "data_path": "data/episode_{episode_index:020d}.parquet"}"#;
        assert!(Info::parse(json, "info.json").is_ok());
    }

    #[test]
    fn split_ranges() {
        assert_eq!(split_range("0:100"), Some(0..100));
        assert_eq!(split_range("x"), None);
    }
}
