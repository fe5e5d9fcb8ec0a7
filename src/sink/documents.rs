//! `meta.json` and `stats.json`: the JSON documents every profile directory holds.
//!
//! Key order is fixed by construction (serde_json's `preserve_order`), floats are printed in
//! their shortest round-trip form, and nothing depends on the clock: the bytes are a function
//! of the plan and the data.

use std::collections::BTreeMap;

use serde_json::{json, Value};

use super::shapes::{normalization_json, shape_of};
use super::video_info::StoredVideo;
use crate::plan::{Plan, ProfilePlan, TOOL_VERSION};
use crate::source::ChannelKind;
use crate::spec::{ImageCompression, OutputFormat, DEFAULT_IMAGE_QUALITY};
use crate::stats::normalize::Normalizer;
use crate::stats::{shaped, ChannelStats};
use crate::window::Sampling;

pub const META_FORMAT_VERSION: u32 = 1;

fn pretty(v: &Value) -> String {
    let mut s = serde_json::to_string_pretty(v).expect("JSON serializes");
    s.push('\n');
    s
}

/// What the build found out that the plan could not know.
pub struct Built<'a> {
    pub episode_ends: &'a [u64],
    pub normalizers: &'a BTreeMap<String, Normalizer>,
    /// Samples in the train and val index.
    pub num_samples: [usize; 2],
    /// Per episode, the `[start, end)` steps of its segments (segment sampling only).
    pub segments: &'a [Vec<[usize; 2]>],
    /// A training mixture's normalizers, per source (empty for one source).
    pub source_normalizers: &'a [BTreeMap<String, Normalizer>],
    /// What each camera stored as one video per episode holds (`image_compression = "video"`).
    pub videos: &'a BTreeMap<String, StoredVideo>,
}

/// `meta.json`: everything the loader needs, and the provenance of the dataset.
///
/// `data_file` and `normalized` come from the sink: where the data is, and whether its
/// low-dimensional values are stored normalized (chunkc's HDF5) or raw (Zarr, Parquet; the loader
/// then normalizes on read).
// Long function: meta.json's fields in document order.
pub fn meta_json(
    plan: &Plan,
    profile: &ProfilePlan,
    built: &Built,
    data_file: &str,
    normalized: bool,
) -> crate::error::Result<String> {
    let v = &profile.values;
    let window = profile.window();
    let mut sampling = serde_json::Map::new();
    sampling.insert("mode".into(), json!(profile.sampling.name()));
    match &profile.sampling {
        Sampling::Segment { params, dims, .. } => {
            let seg = v
                .segment
                .as_ref()
                .expect("segment sampling has a segment spec");
            sampling.insert("channel".into(), json!(seg.channel));
            sampling.insert("dims".into(), json!(dims));
            sampling.insert("params".into(), json!(params));
            sampling.insert("segments".into(), json!(built.segments));
        }
        Sampling::Hierarchy { coarse, .. } => {
            sampling.insert("coarse_chunk".into(), json!(coarse));
            sampling.insert("fine_chunk".into(), json!(window.chunk));
        }
        Sampling::Window { .. } => {}
    }
    let mut channels = serde_json::Map::new();
    for (ch, src) in profile.channels.iter().zip(&plan.source.channels) {
        channels.insert(
            ch.name.clone(),
            json!({
                "kind": ch.kind,
                "shape": ch.shape,
                "dtype": match ch.kind { ChannelKind::Lowdim => "float32", ChannelKind::Image => "uint8" },
                "source_key": src.key,
                "source_dtype": src.source_dtype,
                "array": ch.array,
            }),
        );
        if let Some(storage) = frame_storage(profile, ch.kind, &ch.name, built.videos) {
            channels[&ch.name]["storage"] = storage;
        }
    }
    // A transformed channel's width after its transforms (its normalization's).
    for (c, ch) in profile.channels.iter().enumerate() {
        if profile.transforms_of(c).next().is_some() {
            channels[&ch.name]["transformed_shape"] = json!([profile.widths[c].after]);
        }
    }
    let normalization = normalization_json(profile, built.normalizers);
    let ids: Vec<u64> = profile.episodes.iter().map(|e| e.id).collect();
    let fingerprint = plan.source.fingerprint.hash()?;
    let doc = json!({
        "format_version": META_FORMAT_VERSION,
        "chunkc_version": TOOL_VERSION,
        "profile": profile.name,
        "preset": v.preset.map(|p| p.name()),
        "chunk_size": window.chunk,
        "obs_history": v.obs_history,
        "padding": v.padding.name(),
        "stride": v.stride,
        "fps": profile.fps,
        "alignment": v.alignment.name(),
        "action_lead": window.lead,
        "executes": v.executes,
        "max_pad_after": window.max_pad_after,
        "sampling": sampling,
        "layout": match v.format {
            OutputFormat::Hdf5 => v.layout.name(),
            other => other.name(),
        },
        "data_format": v.format.name(),
        "data_file": data_file,
        "stored_values": if normalized { "normalized" } else { "raw" },
        "rate": {
            "source_fps": plan.source.fps,
            "factor": profile.conversion.factor(),
            "conversion": profile.conversion,
        },
        "episode_ends": built.episode_ends,
        "episodes": ids,
        "split": { "train": plan.split.train, "val": plan.split.val },
        "num_samples": { "train": built.num_samples[0], "val": built.num_samples[1] },
        "channels": channels,
        "normalization": normalization,
        "stats_population": v.stats_population.name(),
        "excluded": profile.excluded,
        "repaired": profile.repaired,
        "warnings": profile.warnings,
        "source": {
            "format": plan.source.format,
            "path": plan.source.path,
            "fingerprint": fingerprint,
        },
        "spec_hash": plan.spec_hash,
    });
    let mut doc = doc;
    // Each episode's task (the language instruction of an RLDS episode), by source id.
    let tasks: serde_json::Map<String, serde_json::Value> = ids
        .iter()
        .filter_map(|id| {
            plan.source
                .tasks
                .get(id)
                .map(|t| (id.to_string(), json!(t)))
        })
        .collect();
    if !tasks.is_empty() {
        doc["tasks"] = serde_json::Value::Object(tasks);
    }
    if !profile.transforms.is_empty() {
        // What the loader applies on read, in order, before normalizing.
        let list: Vec<Value> = profile.transforms.iter().map(|t| t.describe()).collect();
        doc["transforms"] = Value::Array(list);
    }
    if let (Some(env), Some(map)) = (&v.env, doc.as_object_mut()) {
        // Only profiles that name a simulator carry it (and get `rollout.py`).
        map.insert("env".into(), json!(env));
    }
    if !plan.source.parts.is_empty() {
        super::meta_sources::add(
            &mut doc,
            plan,
            &fingerprint,
            profile,
            built.source_normalizers,
        );
    }
    if profile.writes_lerobot_v21() {
        super::lerobot_v21_meta::describe(&mut doc, profile, &plan.source.parts);
    }
    Ok(pretty(&doc))
}

/// How an image channel of chunkc's HDF5 layout stores its frames when not as pixels
/// (`image_compression = "jpeg"` / `"video"`): what the loader decodes on read. A video camera's
/// `codec`, `profile` and `pix_fmt` are what its files hold, as FFmpeg reads them back (null
/// where the files differ; `streams` lists each format with its number of files); `encoder`,
/// `crf` and `gop` are the encoder's settings when any file was encoded (null when every file
/// is a copy of the source's stream).
fn frame_storage(
    profile: &ProfilePlan,
    kind: ChannelKind,
    name: &str,
    videos: &BTreeMap<String, StoredVideo>,
) -> Option<Value> {
    let v = &profile.values;
    if kind != ChannelKind::Image || v.format != OutputFormat::Hdf5 {
        return None;
    }
    match v.image_compression {
        ImageCompression::Jpeg => Some(json!({
            "encoding": "jpeg",
            "quality": v.image_quality.unwrap_or(DEFAULT_IMAGE_QUALITY),
        })),
        ImageCompression::Video => v.video().map(|s| {
            let stored = videos.get(name).cloned().unwrap_or_default();
            let encoded = stored.copied < stored.episodes;
            let streams: Vec<Value> = (stored.formats.iter())
                .map(|(f, n)| json!({ "codec": f.codec, "profile": f.profile, "pix_fmt": f.pix_fmt, "episodes": n }))
                .collect();
            json!({
                "encoding": "video",
                "group": format!("videos/{name}"),
                "codec": stored.shared(|f| f.codec.clone()),
                "profile": stored.shared(|f| f.profile.clone()).flatten(),
                "pix_fmt": stored.shared(|f| f.pix_fmt.clone()),
                "streams": streams,
                "stored": stored.stored(),
                "encoder": encoded.then(|| s.codec.name()),
                "crf": encoded.then_some(s.crf),
                "gop": encoded.then_some(s.gop),
            })
        }),
        ImageCompression::None | ImageCompression::Gzip => None,
    }
}

/// `stats.json`: per channel, per dimension statistics of the training split in raw units, laid
/// out in the channel's per-step shape (`(a, b)` channels as `a` lists of `b`).
pub fn stats_json(profile: &ProfilePlan, stats: &BTreeMap<String, ChannelStats>) -> String {
    let mut doc = serde_json::to_value(stats).expect("stats serialize");
    if let Value::Object(channels) = &mut doc {
        for (name, entry) in channels.iter_mut() {
            shaped::nest_members(entry, shape_of(profile, name));
        }
    }
    pretty(&doc)
}
