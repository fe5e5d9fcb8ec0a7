//! A channel's per-step shape in the documents: the normalization tables and statistics of a
//! `(a, b)` channel are laid out as `a` lists of `b`, a transformed channel's flat.

use std::collections::BTreeMap;

use serde_json::{json, Value};

use crate::plan::ProfilePlan;
use crate::source::ChannelKind;
use crate::stats::normalize::Normalizer;
use crate::stats::shaped;

/// `meta.json`'s `normalization`: per channel, laid out in its per-step shape.
pub(super) fn normalization_json(
    profile: &ProfilePlan,
    normalizers: &BTreeMap<String, Normalizer>,
) -> serde_json::Map<String, Value> {
    let mut normalization = serde_json::Map::new();
    for (name, n) in normalizers {
        let shape = shape_of(profile, name);
        normalization.insert(
            name.clone(),
            json!({
                "mode": n.mode,
                "center": shaped::nested(&n.center, shape),
                "scale": shaped::nested(&n.scale, shape),
                "clip": n.clip,
            }),
        );
    }
    normalization
}

/// The per-step shape of a low-dim channel of the profile (empty for images, whose statistics
/// are per colour channel).
pub(super) fn shape_of<'p>(profile: &'p ProfilePlan, name: &str) -> &'p [usize] {
    profile
        .channels
        .iter()
        .enumerate()
        .find(|(c, ch)| {
            ch.name == name
                && ch.kind == ChannelKind::Lowdim
                && profile.transforms_of(*c).next().is_none()
        })
        .map_or(&[], |(_, c)| c.shape.as_slice())
}
