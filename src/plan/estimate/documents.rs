//! Upper bounds of the JSON documents (`meta.json`, `stats.json`) and the generated scripts,
//! and an estimate of the dataset card.
//!
//! The documents are pretty-printed JSON (serde_json: one array element per line, two spaces per
//! level), so a bound follows their structure: every number takes at most its indentation, the
//! longest text of its type and `,\n`; every string at most six bytes per character (`\u001f`)
//! and its quotes. What only the build knows (normalization parameters, episode ends, segments)
//! is counted at its longest.

use crate::plan::{ProfileChannel, ProfilePlan, SourcePlan, Split};
use crate::source::ChannelKind;
use crate::window::Sampling;

/// The longest text of an `f64` as serde_json writes it (`-1.2345678901234567e-308`).
const F64_CHARS: u64 = 24;
/// The longest text of a 64-bit integer.
const INT_CHARS: u64 = 20;
/// Every scalar field of `meta.json` with its key (versions, names, window parameters, rate),
/// beside what is counted per channel, episode and string: measured at about 1.2 KiB.
const META_FIXED: u64 = 3 * 1024;
/// Per channel of `meta.json`: its keys, kind, dtype and storage (without its names and shape).
const META_CHANNEL: u64 = 640;

/// A source fingerprint as `meta.json` writes it (BLAKE3, hex), before it is known.
const FINGERPRINT_HEX: &str = "0000000000000000000000000000000000000000000000000000000000000000";
/// Statistics per dimension in `stats.json`: mean, std, min, max, p001, p999, q01, q99, q10,
/// q50, q90.
const STATS_ARRAYS: u64 = 11;

/// A JSON string holding `s`, at its longest.
fn string(s: &str) -> u64 {
    2 + 6 * s.chars().count() as u64
}

/// `n` numbers of at most `chars` characters as a pretty-printed array whose elements sit at
/// `depth` (two spaces each).
fn numbers(n: usize, depth: u64, chars: u64) -> u64 {
    n as u64 * (2 * depth + chars + 2) + 2 * depth + 4
}

/// A value of `shape` laid out as nested arrays (`stats::shaped`), elements at `depth`.
fn nested(shape: &[usize], depth: u64, chars: u64) -> u64 {
    match shape {
        [] => numbers(1, depth, chars),
        [n] => numbers(*n, depth, chars),
        [first, rest @ ..] => {
            *first as u64 * (nested(rest, depth + 1, chars) + 2 * depth + 2) + 2 * depth + 4
        }
    }
}

/// The per-dimension shape of a channel's statistics (a camera's: one per colour channel).
fn stats_shape(ch: &ProfileChannel) -> Vec<usize> {
    match ch.kind {
        ChannelKind::Lowdim => ch.shape.clone(),
        ChannelKind::Image => vec![*ch.shape.last().unwrap_or(&1)],
    }
}

/// Digits of `n`.
fn digits(n: usize) -> u64 {
    n.max(1).ilog10() as u64 + 1
}

/// An upper bound of `meta.json`.
pub(super) fn meta_json(source: &SourcePlan, split: &Split, p: &ProfilePlan) -> u64 {
    let mut bytes = META_FIXED + string(&p.name) + string(&source.path) + string(FINGERPRINT_HEX);
    bytes += p.values.env.as_deref().map_or(0, string);
    let episodes = p.episodes.len();
    // episode_ends, episodes, split (every episode of the source)
    bytes += numbers(episodes, 2, digits(p.steps));
    bytes += numbers(episodes, 2, INT_CHARS);
    bytes += numbers(split.train.len(), 3, INT_CHARS) + numbers(split.val.len(), 3, INT_CHARS);
    for (ch, src) in p.channels.iter().zip(&source.channels) {
        bytes += META_CHANNEL + string(&ch.name) + string(&src.key) + string(&src.source_dtype);
        bytes += string(&ch.array) + numbers(ch.shape.len(), 4, INT_CHARS);
        // normalization: center and scale
        bytes += string(&ch.name) + 64 + 2 * nested(&stats_shape(ch), 4, F64_CHARS);
    }
    bytes += p
        .excluded
        .iter()
        .map(|e| 64 + INT_CHARS + string(&e.reason))
        .sum::<u64>();
    bytes += p
        .repaired
        .iter()
        .map(|r| 160 + 3 * INT_CHARS + string(&r.detail))
        .sum::<u64>();
    bytes += p.warnings.iter().map(|w| 8 + string(w)).sum::<u64>();
    bytes += p
        .episodes
        .iter()
        .filter_map(|e| source.tasks.get(&e.id))
        .map(|t| 8 + INT_CHARS + string(t))
        .sum::<u64>();
    bytes + sampling(p)
}

/// `sampling` of `meta.json`: its parameters, and with segments each one's `[start, end)`.
fn sampling(p: &ProfilePlan) -> u64 {
    match &p.sampling {
        Sampling::Segment { dims, .. } => {
            // At most one segment per step of each episode.
            let pair = numbers(2, 5, digits(p.steps)) + 2 * 4 + 2;
            1024 + numbers(dims.len(), 3, INT_CHARS)
                + p.episodes
                    .iter()
                    .map(|e| e.len as u64 * pair + 16)
                    .sum::<u64>()
        }
        _ => 256,
    }
}

/// An upper bound of `stats.json`.
pub(super) fn stats_json(channels: &[ProfileChannel]) -> u64 {
    4 + channels
        .iter()
        .map(|ch| {
            let per_array = 16 + nested(&stats_shape(ch), 3, F64_CHARS);
            16 + string(&ch.name) + STATS_ARRAYS * per_array + 32
        })
        .sum::<u64>()
}

/// The generated scripts, by file name; their templates are [`crate::templates::FILES`].
pub const SCRIPTS: &[&str] = &[
    "loader.py",
    "policy.py",
    "validate.py",
    "smoke_train.py",
    "rollout.py",
    "dp_normalizer.py",
];

/// Bytes a `{{ … }}` may write at most: the version, a list of the loader's parts by name.
const EXPRESSION_BYTES: u64 = 256;

/// An upper bound of a script rendered from `template` (and the `parts` it may include, each at
/// most once): the text of each, with each `{{ … }}` replaced by at most [`EXPRESSION_BYTES`].
/// Conditions only leave text out; the loader's loops run over its storage formats (three at
/// most), their bodies short expressions.
pub fn script_bound<'a>(template: &'a str, parts: impl IntoIterator<Item = &'a str>) -> u64 {
    std::iter::once(template)
        .chain(parts)
        .map(|t| t.len() as u64 + EXPRESSION_BYTES * t.matches("{{").count() as u64)
        .sum()
}

/// An estimate of the dataset card: its fixed text (about 3 KiB), a row per channel, camera,
/// statistics file, exclusion and warning, and the tasks. What the build's audit finds is not
/// known yet.
pub(super) fn card(source: &SourcePlan, p: &ProfilePlan) -> u64 {
    let cameras = p
        .channels
        .iter()
        .filter(|c| c.kind == ChannelKind::Image)
        .count() as u64;
    let tasks: u64 = p
        .episodes
        .iter()
        .filter_map(|e| source.tasks.get(&e.id))
        .collect::<std::collections::BTreeSet<_>>()
        .iter()
        .map(|t| 16 + t.len() as u64)
        .sum();
    3 * 1024
        + 64 * p.channels.len() as u64
        + 256 * cameras
        + 96 * p.values.stats_formats.len() as u64
        + p.excluded
            .iter()
            .map(|e| 48 + e.reason.len() as u64)
            .sum::<u64>()
        + p.warnings.iter().map(|w| 8 + w.len() as u64).sum::<u64>()
        + tasks
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pretty_arrays_are_bounded() {
        fn array(shape: &[usize]) -> serde_json::Value {
            match shape {
                [] => serde_json::json!(-1.234_567_890_123_456_7e-300),
                [n, rest @ ..] => serde_json::Value::Array((0..*n).map(|_| array(rest)).collect()),
            }
        }
        for shape in [vec![12], vec![3, 4], vec![2, 3, 2]] {
            let v = serde_json::json!({"a": {"b": array(&shape)}});
            let text = serde_json::to_string_pretty(&v).unwrap();
            assert!(
                text.len() as u64 <= 24 + nested(&shape, 3, F64_CHARS),
                "{shape:?}: {} > {}",
                text.len(),
                nested(&shape, 3, F64_CHARS)
            );
        }
    }

    #[test]
    fn scripts_are_bounded_by_their_templates() {
        let text = "a{{ version }}b";
        assert!(script_bound(text, []) >= "a99.99.99-rc.1b".len() as u64);
    }
}
