//! Statistics files in the target codebases' own formats (keys and math in TARGETS.md), written
//! beside chunkc's `stats.json` so each codebase trains from numbers computed exactly its way.

use std::collections::BTreeMap;

use serde_json::{json, Value};

use super::pickle::{self, Array};
use crate::plan::ProfilePlan;
use crate::source::ChannelKind;
use crate::spec::StatsFormat;
use crate::stats::normalize::{Normalizer, ZSCORE_STD_FLOOR};
use crate::stats::{shaped, ChannelStats};

/// ACT's action_min/action_max margin (act-plus-plus).
const ACT_MINMAX_EPS: f64 = 1e-4;
/// robomimic adds this to the observation std.
const ROBOMIMIC_STD_EPS: f64 = 1e-3;
/// robomimic's min_max action range and the threshold under which a dimension is constant.
const ROBOMIMIC_OUT: f64 = 0.999999;
const ROBOMIMIC_RANGE_EPS: f64 = 1e-4;

/// What the codebase files are made from.
pub struct Inputs<'a> {
    pub profile: &'a ProfilePlan,
    pub stats: &'a BTreeMap<String, ChannelStats>,
    pub normalizers: &'a BTreeMap<String, Normalizer>,
    /// Raw values (row-major, width) of the state channel over the first training episode.
    pub example_state: Option<(&'a [f32], usize)>,
    pub renderer: &'a super::Renderer,
}

fn pretty(v: &Value) -> Vec<u8> {
    let mut s = serde_json::to_string_pretty(v).expect("JSON serializes");
    s.push('\n');
    s.into_bytes()
}

/// A generated file: name, contents, and what it is (for the dataset card).
pub struct File {
    pub name: String,
    pub bytes: Vec<u8>,
    pub what: String,
}

/// Every statistics file of each format, with what it is (as the dataset card lists them).
const DESCRIBED: &[(StatsFormat, &str, &str)] = &[
    (
        StatsFormat::Act,
        "dataset_stats.pkl",
        "ACT `dataset_stats.pkl` (pickle of numpy arrays)",
    ),
    (
        StatsFormat::Act,
        "dataset_stats.json",
        "the same numbers as JSON",
    ),
    (
        StatsFormat::DiffusionPolicy,
        "dp_normalizer.json",
        "Diffusion Policy LinearNormalizer parameters",
    ),
    (
        StatsFormat::DiffusionPolicy,
        "dp_normalizer.py",
        "builds the LinearNormalizer state dict",
    ),
    (
        StatsFormat::Lerobot,
        "lerobot_stats.json",
        "LeRobot `meta/stats.json` layout",
    ),
    (
        StatsFormat::Openpi,
        "norm_stats.json",
        "openpi `norm_stats.json`",
    ),
    (
        StatsFormat::Robomimic,
        "robomimic_stats.json",
        "robomimic normalization stats (v0.5 and v0.4)",
    ),
];

/// (name, what it is) of every file [`files`] writes for `formats`, in its order.
pub fn described(formats: &[StatsFormat]) -> Vec<(String, String)> {
    formats
        .iter()
        .flat_map(|f| DESCRIBED.iter().filter(move |(of, ..)| of == f))
        .map(|(_, name, what)| (name.to_string(), what.to_string()))
        .collect()
}

fn file(name: &str, bytes: Vec<u8>) -> File {
    let what = DESCRIBED
        .iter()
        .find(|(_, n, _)| *n == name)
        .map_or("", |(.., what)| what);
    File {
        name: name.into(),
        bytes,
        what: what.into(),
    }
}

/// The files for every requested format.
pub fn files(formats: &[StatsFormat], inputs: &Inputs) -> crate::Result<Vec<File>> {
    let mut out = Vec::new();
    for f in formats {
        match f {
            StatsFormat::Act => out.extend(act(inputs)),
            StatsFormat::DiffusionPolicy => out.extend(diffusion_policy(inputs)?),
            StatsFormat::Lerobot => out.push(file(
                "lerobot_stats.json",
                lerobot(inputs.profile, inputs.stats),
            )),
            StatsFormat::Openpi => out.push(file("norm_stats.json", openpi(inputs))),
            StatsFormat::Robomimic => out.push(file("robomimic_stats.json", robomimic(inputs))),
        }
    }
    Ok(out)
}

/// ACT's `get_norm_stats`: mean, unbiased std clipped to >= 1e-2; act-plus-plus adds min/max
/// with a 1e-4 margin; `example_qpos` is one episode's qpos.
fn act(inputs: &Inputs) -> Vec<File> {
    let mut items: Vec<(String, Array)> = Vec::new();
    let vector = |v: Vec<f64>| Array {
        shape: vec![v.len()],
        values: v,
    };
    let mut add = |prefix: &str, s: &ChannelStats, minmax: bool| {
        let std = s
            .unbiased_std()
            .into_iter()
            .map(|x| x.max(ZSCORE_STD_FLOOR))
            .collect();
        items.push((format!("{prefix}_mean"), vector(s.mean.clone())));
        items.push((format!("{prefix}_std"), vector(std)));
        if minmax {
            let lo = s.min.iter().map(|x| x - ACT_MINMAX_EPS).collect();
            let hi = s.max.iter().map(|x| x + ACT_MINMAX_EPS).collect();
            items.push((format!("{prefix}_min"), vector(lo)));
            items.push((format!("{prefix}_max"), vector(hi)));
        }
    };
    add("action", &inputs.stats["action"], true);
    if let Some(state) = inputs.profile.state_channel() {
        add("qpos", &inputs.stats[&state.name], false);
    }
    if let Some((values, width)) = inputs.example_state {
        let rows = values.len() / width.max(1);
        items.push((
            "example_qpos".into(),
            Array {
                shape: vec![rows, width],
                values: values.iter().map(|&v| f64::from(v)).collect(),
            },
        ));
    }
    let json: serde_json::Map<String, Value> = items
        .iter()
        .map(|(k, a)| {
            let v = if a.shape.len() == 2 {
                json!(a.values.chunks(a.shape[1].max(1)).collect::<Vec<_>>())
            } else {
                json!(a.values)
            };
            (k.clone(), v)
        })
        .collect();
    vec![
        file("dataset_stats.pkl", pickle::dict_of_arrays(&items)),
        file("dataset_stats.json", pretty(&Value::Object(json))),
    ]
}

/// Diffusion Policy's key for a channel: `action`, or the observation's own name.
fn dp_key(name: &str) -> &str {
    name.strip_prefix("observation.").unwrap_or(name)
}

/// `LinearNormalizer` parameters: forward `x * scale + offset`, the same map as the profile's
/// normalizer (`(x - center) / s`), so `scale = 1/s`, `offset = -center/s`. Images use Diffusion
/// Policy's image range normalizer (scale 2, offset -1 on [0, 1] input).
fn diffusion_policy(inputs: &Inputs) -> crate::Result<Vec<File>> {
    let mut params = serde_json::Map::new();
    for ch in &inputs.profile.channels {
        let entry = if ch.kind == ChannelKind::Image {
            json!({
                "scale": [2.0], "offset": [-1.0],
                "input_stats": { "min": [0.0], "max": [1.0], "mean": [0.5], "std": [(1.0f64 / 12.0).sqrt()] },
            })
        } else {
            let n = &inputs.normalizers[&ch.name];
            let s = &inputs.stats[&ch.name];
            let scale: Vec<f64> = n.scale.iter().map(|s| 1.0 / s).collect();
            let offset: Vec<f64> = n.center.iter().zip(&n.scale).map(|(c, s)| -c / s).collect();
            // `LinearNormalizer.fit` stores torch's `std`, which is unbiased (ddof = 1); the
            // abs-action normalizer takes numpy's (`array_to_stats`: ddof = 0).
            let std = if n.mode == crate::spec::NormalizeMode::DpAbsAction {
                s.std.clone()
            } else {
                s.unbiased_std()
            };
            json!({
                "scale": scale, "offset": offset,
                "input_stats": { "min": s.min, "max": s.max, "mean": s.mean, "std": std },
            })
        };
        params.insert(dp_key(&ch.name).to_string(), entry);
    }
    let helper = super::shared_script(inputs.renderer, "dp_normalizer.py")?;
    Ok(vec![
        file("dp_normalizer.json", pretty(&Value::Object(params))),
        file("dp_normalizer.py", helper.into_bytes()),
    ])
}

/// LeRobot's `meta/stats.json`: per feature min, max, mean, std, count and quantiles. Images are
/// per colour channel with shape (3, 1, 1), in [0, 1] units.
pub fn lerobot(profile: &ProfilePlan, stats: &BTreeMap<String, ChannelStats>) -> Vec<u8> {
    let mut doc = serde_json::Map::new();
    for ch in &profile.channels {
        let s = &stats[&ch.name];
        let entry = if ch.kind == ChannelKind::Image {
            let img = |v: &Vec<f64>, div: f64| -> Value {
                json!(v.iter().map(|x| vec![vec![x / div]]).collect::<Vec<_>>())
            };
            json!({
                "min": img(&s.min, 255.0), "max": img(&s.max, 255.0), "mean": img(&s.mean, 255.0),
                "std": img(&s.std, 255.0), "count": [s.count],
                "q01": img(&s.q01, 255.0), "q10": img(&s.q10, 255.0), "q50": img(&s.q50, 255.0),
                "q90": img(&s.q90, 255.0), "q99": img(&s.q99, 255.0),
            })
        } else {
            // LeRobot keeps the feature's shape: a (9, 2) feature has (9, 2) statistics.
            let v = |values: &Vec<f64>| shaped::nested(values, &ch.shape);
            json!({
                "min": v(&s.min), "max": v(&s.max), "mean": v(&s.mean), "std": v(&s.std),
                "count": [s.count],
                "q01": v(&s.q01), "q10": v(&s.q10), "q50": v(&s.q50), "q90": v(&s.q90),
                "q99": v(&s.q99),
            })
        };
        doc.insert(ch.name.clone(), entry);
    }
    pretty(&Value::Object(doc))
}

/// openpi's `norm_stats.json`: `state` and `actions`, each mean, std, q01, q99.
fn openpi(inputs: &Inputs) -> Vec<u8> {
    let entry =
        |s: &ChannelStats| json!({ "mean": s.mean, "std": s.std, "q01": s.q01, "q99": s.q99 });
    let mut norm = serde_json::Map::new();
    if let Some(state) = inputs.profile.state_channel() {
        norm.insert("state".into(), entry(&inputs.stats[&state.name]));
    }
    norm.insert("actions".into(), entry(&inputs.stats["action"]));
    pretty(&json!({ "norm_stats": norm }))
}

/// robomimic: v0.5 `{offset, scale}` of shape (1, D) with `(x - offset) / scale` (observations:
/// mean and population std + 1e-3; actions: min_max to ±0.999999), and the v0.4 `{mean, std}`.
fn robomimic(inputs: &Inputs) -> Vec<u8> {
    let row = |v: Vec<f64>| json!([v]);
    // robomimic's `compute_traj_stats` keeps the observation's shape behind a leading 1.
    let obs_row = |v: Vec<f64>, shape: &[usize]| {
        let mut full = vec![1];
        full.extend_from_slice(shape);
        if shape.len() < 2 {
            row(v)
        } else {
            shaped::nested(&v, &full)
        }
    };
    let mut obs_v05 = serde_json::Map::new();
    let mut obs_v04 = serde_json::Map::new();
    for ch in &inputs.profile.channels {
        if ch.name == "action" || ch.kind != ChannelKind::Lowdim {
            continue;
        }
        let s = &inputs.stats[&ch.name];
        let std: Vec<f64> = s.std.iter().map(|x| x + ROBOMIMIC_STD_EPS).collect();
        let key = dp_key(&ch.name).to_string();
        let shape = &ch.shape;
        obs_v05.insert(
            key.clone(),
            json!({ "offset": obs_row(s.mean.clone(), shape), "scale": obs_row(std.clone(), shape) }),
        );
        obs_v04.insert(
            key,
            json!({ "mean": obs_row(s.mean.clone(), shape), "std": obs_row(std, shape) }),
        );
    }
    let a = &inputs.stats["action"];
    let (mut offset, mut scale) = (Vec::new(), Vec::new());
    for (&lo, &hi) in a.min.iter().zip(&a.max) {
        let range = hi - lo;
        if range < ROBOMIMIC_RANGE_EPS {
            scale.push(1.0);
            offset.push(lo);
        } else {
            let s = range / (2.0 * ROBOMIMIC_OUT);
            scale.push(s);
            offset.push(lo + s * ROBOMIMIC_OUT);
        }
    }
    pretty(&json!({
        "v0.5": {
            "obs_normalization_stats": obs_v05,
            "action_normalization_stats": { "actions": { "offset": row(offset), "scale": row(scale) } },
        },
        "v0.4": { "obs_normalization_stats": obs_v04 },
    }))
}
