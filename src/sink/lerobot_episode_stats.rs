//! LeRobot v2.1's per-episode statistics (`meta/episodes_stats.jsonl`), and their aggregate (a
//! dataset's `meta/stats.json`), as lerobot 0.3.3's `compute_episode_stats` and
//! `aggregate_stats` lay them out.
//!
//! LeRobot v2.1's reader does not read `meta/stats.json`: it aggregates `episodes_stats.jsonl`
//! (count-weighted means, the parallel variance formula), so these numbers are what a LeRobot
//! policy normalizes with. chunkc computes them exactly, over every row and every pixel of the
//! episode (LeRobot samples at most 100 frames of a camera and downsamples them):
//!
//! - a low-dim feature: per dimension `min`, `max`, `mean`, `std` (population, ddof 0) in the
//!   feature's shape (a one-value feature `[v]`), `count` `[rows]`;
//! - a camera: per colour channel, in [0, 1] units (pixel / 255), shape (3, 1, 1), `count`
//!   `[frames]`;
//! - the index columns (`timestamp`, `frame_index`, `episode_index`, `index`, `task_index`, a
//!   mixture's `source_index`): shape (1,), the integer columns' `min` and `max` integers, as
//!   numpy gives them for int64 columns.

use serde_json::{json, Map, Value};

use crate::stats::shaped;
use crate::stats::{ImagePartial, Moments};

/// What kind of values a feature holds (how its statistics are written).
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Kind {
    /// Float values of this per-step shape.
    Values(Vec<usize>),
    /// An integer index column.
    Integer,
    /// Camera frames (`u8` pixels).
    Image,
}

/// One feature's statistics over an episode, or over several merged.
#[derive(Debug, Clone)]
pub(super) struct FeatureStats {
    kind: Kind,
    moments: Moments,
    /// Rows (frames of a camera).
    count: u64,
}

impl FeatureStats {
    /// Over `rows` of row-major `values` of per-step `shape`.
    pub(super) fn of_rows(values: &[f32], shape: &[usize]) -> Self {
        let width = shape.iter().product::<usize>().max(1);
        let moments = Moments::of_rows(values, width);
        FeatureStats {
            kind: Kind::Values(shape.to_vec()),
            count: moments.count,
            moments,
        }
    }

    /// Over the values of one index column (`integer`: an int64 column).
    pub(super) fn of_column(values: &[f64], integer: bool) -> Self {
        let mut moments = Moments::new(1);
        let n = values.len();
        if n > 0 {
            let mean = values.iter().sum::<f64>() / n as f64;
            moments.count = n as u64;
            moments.mean[0] = mean;
            moments.m2[0] = values.iter().map(|v| (v - mean) * (v - mean)).sum();
            moments.min[0] = values.iter().copied().fold(f64::INFINITY, f64::min);
            moments.max[0] = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        }
        FeatureStats {
            kind: if integer {
                Kind::Integer
            } else {
                Kind::Values(vec![1])
            },
            moments,
            count: n as u64,
        }
    }

    /// Over `frames` HWC frames of `colors` channels.
    pub(super) fn of_frames(pixels: &[u8], frames: usize, colors: usize) -> Self {
        let partial = ImagePartial::of_frames(pixels, frames, colors);
        FeatureStats {
            kind: Kind::Image,
            moments: partial.moments,
            count: frames as u64,
        }
    }

    /// Folds `other` (the same feature over other rows) into `self`: LeRobot's
    /// `aggregate_feature_stats`, exactly.
    pub(super) fn merge(&mut self, other: &FeatureStats) {
        self.moments.merge(&other.moments);
        self.count += other.count;
    }

    /// The feature's entry: `min`, `max`, `mean`, `std`, `count`.
    pub(super) fn to_json(&self) -> Value {
        let m = &self.moments;
        let std = m.std(0);
        let mut out = Map::new();
        let columns: [(&str, &[f64]); 4] = [
            ("min", &m.min),
            ("max", &m.max),
            ("mean", &m.mean),
            ("std", &std),
        ];
        for (key, values) in columns {
            let value = match &self.kind {
                Kind::Values(shape) if shape.len() >= 2 => shaped::nested(values, shape),
                Kind::Values(_) => json!(values),
                Kind::Image => json!(values
                    .iter()
                    .map(|v| vec![vec![v / 255.0]])
                    .collect::<Vec<_>>()),
                Kind::Integer if key == "min" || key == "max" => {
                    json!(values.iter().map(|&v| v as i64).collect::<Vec<_>>())
                }
                Kind::Integer => json!(values),
            };
            out.insert(key.into(), value);
        }
        out.insert("count".into(), json!([self.count]));
        Value::Object(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merged_episodes_are_the_dataset_as_lerobot_aggregates_it() {
        let a = FeatureStats::of_rows(&[1.0, 10.0, 2.0, 20.0], &[2]);
        let b = FeatureStats::of_rows(&[4.0, 40.0], &[2]);
        let mut ab = a.clone();
        ab.merge(&b);
        let whole = FeatureStats::of_rows(&[1.0, 10.0, 2.0, 20.0, 4.0, 40.0], &[2]);
        let (ab, whole) = (ab.to_json(), whole.to_json());
        assert_eq!(ab["count"], json!([3]));
        assert_eq!(ab["min"], whole["min"]);
        for d in 0..2 {
            let (x, y) = (
                ab["std"][d].as_f64().unwrap(),
                whole["std"][d].as_f64().unwrap(),
            );
            assert!((x - y).abs() < 1e-12);
        }
        assert_eq!(a.to_json()["mean"], json!([1.5, 15.0]));
    }

    #[test]
    fn shapes_follow_lerobot() {
        let scalar = FeatureStats::of_rows(&[1.0, 3.0], &[]);
        assert_eq!(scalar.to_json()["mean"], json!([2.0]));
        let matrix = FeatureStats::of_rows(&[1.0, 2.0, 3.0, 4.0], &[2, 2]);
        assert_eq!(matrix.to_json()["max"], json!([[1.0, 2.0], [3.0, 4.0]]));
        let frames = FeatureStats::of_frames(&[0, 255, 51, 0, 255, 51], 2, 3);
        let j = frames.to_json();
        assert_eq!(j["max"], json!([[[0.0]], [[1.0]], [[0.2]]]));
        assert_eq!(j["count"], json!([2]));
        let index = FeatureStats::of_column(&[5.0, 6.0, 7.0], true).to_json();
        assert_eq!(index["min"], json!([5]));
        assert_eq!(index["mean"], json!([6.0]));
    }
}
