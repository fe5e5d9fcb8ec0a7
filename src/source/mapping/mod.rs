//! `[source.channels]`, shared by every adapter: our channel names mapped to source keys, with
//! column slices, concatenation of several keys and a declared kind.
//!
//! An adapter lists the keys it offers ([`KeyInfo`]); [`resolve`] checks the spec's mapping
//! against them once, at open time, and gives the manifest's channels plus a [`Recipe`] per
//! channel. For each episode the adapter reads the keys the recipes name ([`Raw`]) and
//! [`assemble`] turns them into the channels' data.
//!
//! - `channel`: one channel of the spec checked against the keys (the keys it names, its
//!   columns, its kind and shape).

use std::collections::BTreeMap;
use std::ops::Range;

use super::{image_to_u8, ChannelData, ChannelInfo, ChannelKind};
use crate::error::{Error, Result};
use crate::spec::LoadedSpec;

mod channel;

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
        let one = channel::OneChannel {
            spec,
            place,
            name,
            channel,
        };
        if let Some((info, recipe)) = one.resolve(available, &mut mapped.warnings)? {
            mapped.channels.push(info);
            mapped.recipes.push(recipe);
        }
    }
    Ok(mapped)
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
