//! `meta.json`'s fields for a training mixture: which source each stored episode is from
//! (`episode_sources`), the mixture's settings and the sampling probabilities of each split
//! (`mixture`), and per source its rate, episodes, split, widths, samples and normalization
//! (`sources`). The top-level `source` names the mixture.

use serde_json::{json, Map, Value};

use std::collections::BTreeMap;

use super::shapes::normalization_json;
use crate::plan::mixture::{balanced, windows};
use crate::plan::{conversion, Conversion, Plan, ProfilePlan};
use crate::source::SourcePart;
use crate::spec::ResampleMethod;
use crate::stats::normalize::Normalizer;

/// Adds the mixture's fields to `doc` (a one-source `meta.json` has none of them);
/// `fingerprint` is the mixture's.
pub fn add(
    doc: &mut Value,
    plan: &Plan,
    fingerprint: &str,
    profile: &ProfilePlan,
    normalizers: &[BTreeMap<String, Normalizer>],
) {
    let parts = &plan.source.parts;
    let mixture = plan.mixture.clone().unwrap_or_default();
    let episode_sources: Vec<usize> = profile
        .episodes
        .iter()
        .map(|e| SourcePart::index_of(parts, e.id))
        .collect();
    let weights: Vec<f64> = parts.iter().map(|p| p.weight).collect();
    let (train, val) = (
        windows(profile, parts, true),
        windows(profile, parts, false),
    );
    let mut sources = Map::new();
    for (s, part) in parts.iter().enumerate() {
        let counts = (train[s], val[s]);
        let entry = source_entry(plan, profile, normalizers, s, counts);
        sources.insert(part.name.clone(), entry);
    }
    let names: Vec<&str> = parts.iter().map(|p| p.name.as_str()).collect();
    let Some(map) = doc.as_object_mut() else {
        return;
    };
    map.insert(
        "source".into(),
        json!({ "format": "mixture", "path": Value::Null, "fingerprint": fingerprint }),
    );
    map.insert("episode_sources".into(), json!(episode_sources));
    map.insert(
        "mixture".into(),
        json!({
            "balance": mixture.balance.name(),
            "stats": mixture.stats.name(),
            "pad_to": mixture.pad_to,
            "source_names": names,
            "weights": {
                "train": balanced(mixture.balance, &weights, &train),
                "val": balanced(mixture.balance, &weights, &val),
            },
        }),
    );
    map.insert("sources".into(), Value::Object(sources));
}

/// `sources.<name>` of `meta.json`: source `s`'s rate, episodes and split (its own ids), widths,
/// samples (`counts`: train, val) and normalization.
fn source_entry(
    plan: &Plan,
    profile: &ProfilePlan,
    normalizers: &[BTreeMap<String, Normalizer>],
    s: usize,
    counts: (usize, usize),
) -> Value {
    let parts = &plan.source.parts;
    let part = &parts[s];
    let method = match profile.conversion {
        Conversion::Resample { method, .. } => method,
        Conversion::Decimate { .. } => ResampleMethod::Fourier,
    };
    let local = |ids: &[u64]| -> Vec<u64> {
        let own = ids
            .iter()
            .filter(|&&id| SourcePart::index_of(parts, id) == s);
        own.map(|id| id - part.id_offset).collect()
    };
    let stored: Vec<u64> = profile.episodes.iter().map(|e| e.id).collect();
    // From the source's own rate straight to the profile's (the rows are the same as through
    // the mixture's rate when both steps decimate).
    let rate = conversion(part.fps, profile.fps, method).ok();
    let widths: Map<String, Value> = plan
        .source
        .channels
        .iter()
        .zip(&part.widths)
        .map(|(ch, w)| (ch.name.clone(), json!(w)))
        .collect();
    // A channel whose transforms change this source's width: its own dimensions after them
    // (the loader's dim mask and `to_source` need both).
    let transformed: Map<String, Value> = plan
        .source
        .channels
        .iter()
        .enumerate()
        .filter(|&(c, _)| profile.transforms_of(c).next().is_some())
        .map(|(c, ch)| (ch.name.clone(), json!(profile.widths[c].own_after[s])))
        .collect();
    let normalization = normalizers
        .get(s)
        .map(|n| normalization_json(profile, n))
        .unwrap_or_default();
    let mut entry = json!({
        "index": s,
        "format": part.format.name(),
        "path": part.path,
        "fingerprint": part.fingerprint,
        "weight": part.weight,
        "fps": part.fps,
        "id_offset": part.id_offset,
        "rate": {
            "source_fps": part.fps,
            "factor": rate.and_then(|r| r.factor()),
            "conversion": rate,
        },
        "episodes": local(&stored),
        "split": { "train": local(&plan.split.train), "val": local(&plan.split.val) },
        "widths": widths,
        "num_samples": { "train": counts.0, "val": counts.1 },
        "normalization": normalization,
    });
    if !transformed.is_empty() {
        entry["transformed_widths"] = Value::Object(transformed);
    }
    entry
}
