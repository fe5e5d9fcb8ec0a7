//! `[source.channels]`, shared by every adapter: our channel names mapped to source keys, with
//! column slices, concatenation of several keys and a declared kind.
//!
//! An adapter lists the keys it offers ([`KeyInfo`]); [`resolve`] checks the spec's mapping
//! against them once, at open time, and gives the manifest's channels plus a [`Recipe`] per
//! channel. For each episode the adapter reads the keys the recipes name ([`Raw`]) and
//! [`assemble`] turns them into the channels' data.

use std::collections::BTreeMap;
use std::ops::Range;

use super::{image_to_u8, kind_for_shape, ChannelData, ChannelInfo, ChannelKind};
use crate::error::{Error, Result};
use crate::spec::{ChannelKindSpec, ChannelSpec, LoadedSpec};

/// A key a source offers, with its per-step shape (everything after the time axis; a 1-D array
/// has shape `[1]`).
#[derive(Debug, Clone)]
pub struct KeyInfo {
    pub key: String,
    pub shape: Vec<usize>,
    /// The element type as the source names it (`float32`, `uint8`, `jpeg`).
    pub dtype: String,
}

impl KeyInfo {
    pub fn width(&self) -> usize {
        self.shape.iter().product()
    }
}

/// One key's contribution to a channel: the columns `columns` of its flattened steps.
#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    pub key: String,
    /// The key's full per-step width.
    pub width: usize,
    pub columns: Range<usize>,
}

/// How to build one channel from the keys read for an episode.
#[derive(Debug, Clone, PartialEq)]
pub struct Recipe {
    pub parts: Vec<Part>,
}

/// The channels a spec maps, checked against a source.
#[derive(Debug, Clone)]
pub struct Mapped {
    /// In the spec's (sorted) order, zero-width channels left out.
    pub channels: Vec<ChannelInfo>,
    pub recipes: Vec<Recipe>,
    pub warnings: Vec<String>,
}

impl Mapped {
    /// Every key some channel reads, sorted, without repeats.
    pub fn keys(&self) -> Vec<String> {
        let mut keys: Vec<String> = self
            .recipes
            .iter()
            .flat_map(|r| r.parts.iter().map(|p| p.key.clone()))
            .collect();
        keys.sort();
        keys.dedup();
        keys
    }
}

/// One key's values for one episode, time-major, as read.
#[derive(Debug, Clone)]
pub enum Raw {
    F32(Vec<f32>),
    U8(Vec<u8>),
}

impl Raw {
    fn len(&self) -> usize {
        match self {
            Raw::F32(v) => v.len(),
            Raw::U8(v) => v.len(),
        }
    }

    fn get(&self, i: usize) -> f32 {
        match self {
            Raw::F32(v) => v[i],
            Raw::U8(v) => f32::from(v[i]),
        }
    }
}

/// Checks the spec's channel mapping against the keys of the source at `place` (a path shown in
/// messages). A key that is missing is a spec error listing the keys that exist.
///
/// An empty mapping (a valid spec always maps `action`; `chunkc init` and `inspect` open a
/// source so to learn what it holds) stops here with `Error::Offered` and every key.
// Long function: one arm per mapping form (rename, columns, concat, kind), each with its own messages.
pub fn resolve(spec: &LoadedSpec, place: &str, available: &[KeyInfo]) -> Result<Mapped> {
    if spec.source().channels.is_empty() {
        return Err(Error::Offered(Box::new(crate::error::Offer {
            place: place.to_string(),
            keys: available
                .iter()
                .map(|k| (k.key.clone(), k.shape.clone(), k.dtype.clone()))
                .collect(),
        })));
    }
    let mut mapped = Mapped {
        channels: Vec::new(),
        recipes: Vec::new(),
        warnings: Vec::new(),
    };
    for (name, channel) in &spec.source().channels {
        let at = ["source", "channels", name.as_str()];
        let mut parts = Vec::new();
        let mut infos = Vec::new();
        for key in channel.keys() {
            let Some(info) = available.iter().find(|k| k.key == key) else {
                let names: Vec<&str> = available.iter().map(|k| k.key.as_str()).collect();
                let close =
                    crate::spec::suggest_name(key, &names).map(|s| format!("did you mean `{s}`?"));
                return Err(spec.error_at(
                    &at,
                    format!(
                        "channel `{name}` maps to `{key}`, which is not in {place}; the source has: {}",
                        names.join(", ")
                    ),
                    close,
                ));
            };
            infos.push(info);
            if info.width() == 0 {
                if channel.keys().len() > 1 {
                    mapped.warnings.push(format!(
                        "channel `{name}`: `{key}` in {place} has zero width {:?}; it is skipped",
                        info.shape
                    ));
                }
                continue;
            }
            parts.push(Part {
                key: key.to_string(),
                width: info.width(),
                columns: 0..info.width(),
            });
        }
        let table = match channel {
            ChannelSpec::Table(t) => Some(t),
            ChannelSpec::Key(_) => None,
        };
        let total: usize = parts.iter().map(|p| p.width).sum();
        if let Some([a, b]) = table.and_then(|t| t.columns) {
            if b > total {
                return Err(spec.error_at(
                    &[&at[..], &["columns"]].concat(),
                    format!(
                        "channel `{name}` selects columns {a}..{b} of `{}`, which has {total} per step",
                        channel.keys().join(" + ")
                    ),
                    Some(format!("columns are `[start, end)` with end at most {total}")),
                ));
            }
            parts = select(&parts, a..b);
        }
        let width: usize = parts.iter().map(|p| p.columns.len()).sum();
        if width == 0 {
            if name == "action" {
                return Err(spec.error_at(
                    &at,
                    format!(
                        "`action` maps to `{}`, which has no values per step",
                        channel.describe()
                    ),
                    None,
                ));
            }
            mapped.warnings.push(format!(
                "channel `{name}` maps to `{}` in {place}, which has zero width; the channel is skipped",
                channel.describe()
            ));
            continue;
        }

        let whole_single_key = infos.len() == 1 && table.is_none_or(|t| t.columns.is_none());
        let declared = table.and_then(|t| t.kind);
        let (kind, shape) = if whole_single_key {
            let shape = infos[0].shape.clone();
            match declared {
                Some(ChannelKindSpec::Lowdim) => (ChannelKind::Lowdim, vec![width]),
                Some(ChannelKindSpec::Image) | None => {
                    let kind = kind_for_shape(&shape)
                        .map_err(|e| Error::source(format!("{place}: `{}`: {e}", infos[0].key)))?;
                    if declared == Some(ChannelKindSpec::Image) && kind != ChannelKind::Image {
                        return Err(spec.error_at(
                            &[&at[..], &["kind"]].concat(),
                            format!(
                                "channel `{name}` is declared an image, but `{}` has per-step shape {shape:?}, not (H, W, C)",
                                infos[0].key
                            ),
                            None,
                        ));
                    }
                    (kind, shape)
                }
            }
        } else {
            if declared == Some(ChannelKindSpec::Image) {
                return Err(spec.error_at(
                    &[&at[..], &["kind"]].concat(),
                    format!("channel `{name}` selects columns or concatenates keys, so it cannot be an image"),
                    None,
                ));
            }
            if let Some(image) = infos.iter().find(|k| k.shape.len() == 3 && k.width() > 0) {
                return Err(spec.error_at(
                    &at,
                    format!(
                        "channel `{name}` slices or concatenates `{}`, an image of shape {:?}; only vectors can be",
                        image.key, image.shape
                    ),
                    None,
                ));
            }
            (ChannelKind::Lowdim, vec![width])
        };
        if name == "action" && kind != ChannelKind::Lowdim {
            return Err(spec.error_at(
                &at,
                format!(
                    "`action` must be a vector per step, but `{}` is {shape:?}",
                    channel.describe()
                ),
                None,
            ));
        }
        let mut dtypes: Vec<&str> = infos.iter().map(|k| k.dtype.as_str()).collect();
        dtypes.dedup();
        mapped.channels.push(ChannelInfo {
            name: name.clone(),
            key: channel.describe(),
            kind,
            shape,
            source_dtype: dtypes.join("+"),
        });
        mapped.recipes.push(Recipe { parts });
    }
    Ok(mapped)
}

/// The parts restricted to `range` of their concatenated columns.
fn select(parts: &[Part], range: Range<usize>) -> Vec<Part> {
    let mut out = Vec::new();
    let mut offset = 0;
    for p in parts {
        let n = p.columns.len();
        let lo = range.start.max(offset);
        let hi = range.end.min(offset + n);
        if lo < hi {
            let start = p.columns.start + (lo - offset);
            out.push(Part {
                key: p.key.clone(),
                width: p.width,
                columns: start..start + (hi - lo),
            });
        }
        offset += n;
    }
    out
}

/// Builds one episode's channels from the keys read for it. `read` is called once per key;
/// `place` names the episode in messages (`file: episode 3`).
// Long function: one arm per mapping form (rename, columns, concat, kind), the same arms as `resolve`.
pub fn assemble(
    mapped: &Mapped,
    len: usize,
    place: &str,
    mut read: impl FnMut(&str) -> Result<Raw>,
) -> Result<Vec<ChannelData>> {
    let mut cache: BTreeMap<String, Raw> = BTreeMap::new();
    for key in mapped.keys() {
        let raw = read(&key)?;
        cache.insert(key, raw);
    }
    // Whether a channel after the `c`-th reads `key` too (then it cannot be moved out).
    let used_later = |key: &str, c: usize| {
        mapped.recipes[c + 1..]
            .iter()
            .any(|r| r.parts.iter().any(|p| p.key == key))
    };
    let mut out = Vec::with_capacity(mapped.channels.len());
    for (ch, recipe) in mapped.channels.iter().zip(&mapped.recipes) {
        for part in &recipe.parts {
            let got = cache[&part.key].len();
            if got != len * part.width {
                return Err(Error::source(format!(
                    "{place}: `{}` holds {got} values, expected {len} steps of {}",
                    part.key, part.width
                )));
            }
        }
        let data = match ch.kind {
            ChannelKind::Image => {
                let part = &recipe.parts[0];
                match &cache[&part.key] {
                    // Move the frames out unless another channel reads the same key.
                    Raw::U8(_) if !used_later(&part.key, out.len()) => {
                        match cache.remove(&part.key) {
                            Some(Raw::U8(v)) => ChannelData::Image(v),
                            _ => unreachable!("matched above"),
                        }
                    }
                    Raw::U8(v) => ChannelData::Image(v.clone()),
                    Raw::F32(v) => {
                        let per_step = ch.width().max(1);
                        ChannelData::Image(image_to_u8(v, |i| {
                            format!("{place}: `{}` step {}", part.key, i / per_step)
                        })?)
                    }
                }
            }
            ChannelKind::Lowdim => {
                let width = ch.width();
                if let [part] = recipe.parts.as_slice() {
                    if part.columns == (0..part.width) {
                        // The whole key, as it is: moved out (or copied once if another channel
                        // reads it too), not rebuilt value by value.
                        let values = match &cache[&part.key] {
                            Raw::F32(_) if !used_later(&part.key, out.len()) => {
                                match cache.remove(&part.key) {
                                    Some(Raw::F32(v)) => v,
                                    _ => unreachable!("matched above"),
                                }
                            }
                            Raw::F32(v) => v.clone(),
                            Raw::U8(v) => v.iter().map(|&b| f32::from(b)).collect(),
                        };
                        out.push(ChannelData::Lowdim(values));
                        continue;
                    }
                }
                let mut values = Vec::with_capacity(len * width);
                for t in 0..len {
                    for part in &recipe.parts {
                        let raw = &cache[&part.key];
                        let row = t * part.width;
                        for c in part.columns.clone() {
                            // Non-finite values are `check`'s business (`[audit] non_finite`).
                            values.push(raw.get(row + c));
                        }
                    }
                }
                ChannelData::Lowdim(values)
            }
        };
        out.push(data);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(key: &str, width: usize) -> Part {
        Part {
            key: key.into(),
            width,
            columns: 0..width,
        }
    }

    #[test]
    fn select_spans_parts() {
        let parts = [part("a", 3), part("b", 2)];
        let got = select(&parts, 2..4);
        assert_eq!(got.len(), 2);
        assert_eq!((got[0].key.as_str(), got[0].columns.clone()), ("a", 2..3));
        assert_eq!((got[1].key.as_str(), got[1].columns.clone()), ("b", 0..1));
        assert!(select(&parts, 3..3).is_empty());
    }
}
