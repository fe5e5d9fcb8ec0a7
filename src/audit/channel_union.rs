//! A mixture's channels: the union of its sources', each low-dim channel named in
//! `[mixture] pad_to` widened to that width, every other one the same in every source.

use std::collections::BTreeMap;

use crate::error::Result;
use crate::source::{ChannelInfo, ChannelKind};
use crate::spec::LoadedSpec;

/// The mixture's channels: the union of the sources', in name order, with their widths checked
/// against `[mixture] pad_to`.
/// `parts`: each source's name and channels, in mixture order.
pub(super) fn joined(
    spec: &LoadedSpec,
    parts: &[(&str, &[ChannelInfo])],
) -> Result<Vec<ChannelInfo>> {
    let pad_to = spec
        .spec
        .mixture
        .as_ref()
        .map(|m| m.pad_to.clone())
        .unwrap_or_default();
    let mut union: BTreeMap<&str, Vec<Option<&ChannelInfo>>> = BTreeMap::new();
    for (s, (_, channels)) in parts.iter().enumerate() {
        for ch in channels.iter() {
            union
                .entry(&ch.name)
                .or_insert_with(|| vec![None; parts.len()])[s] = Some(ch);
        }
    }
    let name_of = |s: usize| parts[s].0;
    let mut out = Vec::new();
    for (name, per_source) in union {
        let (first, info) = per_source
            .iter()
            .enumerate()
            .find_map(|(s, c)| c.map(|c| (s, c)))
            .expect("a channel some source has");
        let Some(&width) = pad_to.get(name) else {
            same_everywhere(spec, name, &per_source, first, name_of)?;
            out.push(info.clone());
            continue;
        };
        if info.kind == ChannelKind::Image {
            return Err(spec.error_at(
                &["mixture", "pad_to", name],
                format!("`{name}` is an image channel; `pad_to` pads low-dimensional channels"),
                None,
            ));
        }
        for (s, ch) in per_source.iter().enumerate() {
            let Some(ch) = ch else { continue };
            if ch.kind != ChannelKind::Lowdim || ch.width() > width {
                return Err(spec.error_at(
                    &["mixture", "pad_to", name],
                    format!(
                        "`mixture.pad_to.{name} = {width}` is narrower than source `{}`'s `{name}`, which has {} values per step",
                        name_of(s),
                        ch.width()
                    ),
                    Some(format!("pad to at least {}", ch.width())),
                ));
            }
        }
        let mut padded = info.clone();
        padded.shape = vec![width];
        out.push(padded);
    }
    Ok(out)
}

/// A channel not padded: every source maps it, with one kind and one shape.
fn same_everywhere<'a>(
    spec: &LoadedSpec,
    name: &str,
    per_source: &[Option<&ChannelInfo>],
    first: usize,
    name_of: impl Fn(usize) -> &'a str,
) -> Result<()> {
    let info = per_source[first].expect("the first source that has it");
    for (s, ch) in per_source.iter().enumerate() {
        let Some(ch) = ch else {
            return Err(spec.error_at(
                &["sources", name_of(s), "channels"],
                format!(
                    "source `{}` maps no `{name}`, which source `{}` maps; every source of a mixture needs every channel",
                    name_of(s),
                    name_of(first)
                ),
                Some(format!("map `{name}` in `[sources.{}.channels]`, or zero-pad it: `[mixture] pad_to = {{ \"{name}\" = <width> }}`", name_of(s))),
            ));
        };
        if ch.kind != info.kind || ch.shape != info.shape {
            let help = match info.kind {
                ChannelKind::Lowdim => Some(format!(
                    "zero-pad it to a common width: `[mixture] pad_to = {{ \"{name}\" = {} }}`",
                    ch.width().max(info.width())
                )),
                ChannelKind::Image => None,
            };
            return Err(spec.error_at(
                &["sources", name_of(s), "channels", name],
                format!(
                    "`{name}` has per-step shape {:?} in source `{}` but {:?} in source `{}`",
                    ch.shape,
                    name_of(s),
                    info.shape,
                    name_of(first)
                ),
                help,
            ));
        }
    }
    Ok(())
}
