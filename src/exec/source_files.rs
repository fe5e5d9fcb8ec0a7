//! A training mixture's per-source statistics files: `sources/<name>/stats.json`, LeRobot's
//! `lerobot_stats.json`, and the files of the profile's `stats_formats`, each from the source's
//! own statistics (its own channels, at its own widths).

use std::collections::BTreeMap;
use std::path::Path;

use super::shared::Shared;
use crate::error::{IoContext, Result};
use crate::plan::{ProfilePlan, STATS_FILE};
use crate::render;
use crate::sink::documents;
use crate::source::ChannelKind;
use crate::stats::normalize::Normalizer;
use crate::stats::ChannelStats;

/// A mixture's sources' own statistics beside the pooled ones: `sources/<name>/stats.json`,
/// LeRobot's `lerobot_stats.json`, and the files of the profile's `stats_formats`, each from the
/// source's statistics alone (its own channels, at its own widths).
pub(super) fn write_source_stats(
    shared: &Shared,
    p: &ProfilePlan,
    sources: &[BTreeMap<String, ChannelStats>],
    dir: &Path,
) -> Result<()> {
    for (part, own) in shared.manifest.parts.iter().zip(sources) {
        let sub = dir.join("sources").join(&part.name);
        std::fs::create_dir_all(&sub).at("create", &sub)?;
        let mut narrowed = p.clone();
        narrowed.channels.retain(|ch| own.contains_key(&ch.name));
        for ch in &mut narrowed.channels {
            if ch.kind == ChannelKind::Lowdim && ch.shape.len() == 1 {
                ch.shape = vec![own[&ch.name].mean.len()];
            }
        }
        let normalizers: BTreeMap<String, Normalizer> = narrowed
            .channels
            .iter()
            .map(|ch| {
                (
                    ch.name.clone(),
                    Normalizer::fit(ch.normalize, &own[&ch.name]),
                )
            })
            .collect();
        let inputs = render::codebase::Inputs {
            profile: &narrowed,
            stats: own,
            normalizers: &normalizers,
            example_state: None,
            renderer: shared.renderer,
        };
        let mut files = vec![
            (
                STATS_FILE.to_string(),
                documents::stats_json(&narrowed, own).into_bytes(),
            ),
            (
                "lerobot_stats.json".into(),
                render::codebase::lerobot(&narrowed, own),
            ),
        ];
        for f in render::codebase::files(&p.values.stats_formats, &inputs)? {
            files.push((f.name, f.bytes));
        }
        for (name, bytes) in files {
            let path = sub.join(name);
            std::fs::write(&path, bytes).at("write", &path)?;
        }
    }
    Ok(())
}
