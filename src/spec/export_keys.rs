//! The names a native export gives its arrays (`[profiles.<name>.export_keys]`).
//!
//! Native exports (`zarr`, `robomimic_hdf5`, `act_episodes`) are opened by the codebases' own
//! dataset classes, whose configurations name arrays by the keys of the data they were written
//! for: Diffusion Policy's `PushTImageDataset` reads `data/img`, `data/state`, `data/action`.
//! So by default a channel exports under the key it was read from, not under chunkc's name.
//!
//! The rule, decided here once for the spec checks and the plan:
//! - a channel read whole from one key takes that key's last `/` component (`img`; an ALOHA
//!   `observations/images/top` gives `top`): one path component, so that every array sits
//!   directly under `data/` (Diffusion Policy's `ReplayBuffer` walks `data/` and expects arrays
//!   there, never groups) or `obs/` (robomimic's `obs_keys` are flat names);
//! - a channel built with `concat` or `columns` has no key of its own and takes its chunkc name
//!   without `observation.`;
//! - `export_keys` overrides either, per channel, with a name of one path component;
//! - where the codebase fixes a name, it is fixed: robomimic's `actions`, ACT's `action`, and
//!   ACT's state channel, which it reads as `observations/qpos`, is `qpos` unless overridden.
//!
//! `hdf5` and `parquet` are read by chunkc's loader and keep chunkc's names.

use std::collections::BTreeMap;

use super::model::{ChannelSpec, ChannelTable, OutputFormat};

/// Whether `format` names its arrays as a codebase's configuration does.
pub fn renames(format: OutputFormat) -> bool {
    matches!(
        format,
        OutputFormat::Zarr | OutputFormat::RobomimicHdf5 | OutputFormat::ActEpisodes
    )
}

/// The name of the action array where the codebase hard-codes it (it then lives apart from the
/// observations and cannot be renamed).
pub fn fixed_action(format: OutputFormat) -> Option<&'static str> {
    match format {
        OutputFormat::RobomimicHdf5 => Some("actions"),
        OutputFormat::ActEpisodes => Some("action"),
        _ => None,
    }
}

/// The export name of channel `name` mapped as `channel`, before any override.
pub fn default_name(name: &str, channel: &ChannelSpec) -> String {
    let whole_key = match channel {
        ChannelSpec::Key(k) => Some(k.as_str()),
        ChannelSpec::Table(ChannelTable {
            key: Some(k),
            columns: None,
            ..
        }) => Some(k.as_str()),
        ChannelSpec::Table(_) => None,
    };
    match whole_key {
        Some(key) => last_component(key).to_string(),
        None => name
            .strip_prefix("observation.")
            .unwrap_or(name)
            .to_string(),
    }
}

/// `observations/images/top` → `top`; a key without a usable last component stays whole.
fn last_component(key: &str) -> &str {
    match key.trim_end_matches('/').rsplit('/').next() {
        Some(last) if !last.is_empty() => last,
        _ => key,
    }
}

/// Why `value` cannot name an array, if it cannot.
pub fn invalid_name(value: &str) -> Option<&'static str> {
    if value.is_empty() {
        Some("is empty")
    } else if value.contains('/') {
        Some("contains `/`; a name is one path component")
    } else if value == "." || value == ".." {
        Some("is not a name")
    } else {
        None
    }
}

/// One channel's export name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExportName {
    pub channel: String,
    pub name: String,
    /// Set by `export_keys` (else the default rule, or the codebase's fixed name).
    pub overridden: bool,
    /// Whether it shares the observations' namespace (not a fixed action name).
    pub in_namespace: bool,
}

/// The export name of every channel of `channels` (in their order) in `format`. `state` is the
/// channel ACT reads as `qpos`, when known.
pub fn export_names<'a>(
    format: OutputFormat,
    channels: impl IntoIterator<Item = (&'a str, &'a ChannelSpec)>,
    overrides: &BTreeMap<String, String>,
    state: Option<&str>,
) -> Vec<ExportName> {
    channels
        .into_iter()
        .map(|(channel, spec)| {
            let fixed = fixed_action(format).filter(|_| channel == "action");
            let given = overrides.get(channel).filter(|_| fixed.is_none());
            let name = match (fixed, given) {
                (Some(fixed), _) => fixed.to_string(),
                (None, Some(given)) => given.clone(),
                (None, None) if format == OutputFormat::ActEpisodes && Some(channel) == state => {
                    "qpos".to_string()
                }
                (None, None) => default_name(channel, spec),
            };
            ExportName {
                channel: channel.to_string(),
                name,
                overridden: given.is_some(),
                in_namespace: fixed.is_none(),
            }
        })
        .collect()
}

/// Every channel exported under a name an earlier channel already has: (the earlier, it).
pub fn collisions(names: &[ExportName]) -> Vec<(&ExportName, &ExportName)> {
    let mut out = Vec::new();
    for (i, b) in names.iter().enumerate() {
        if !b.in_namespace {
            continue;
        }
        if let Some(a) = names[..i]
            .iter()
            .find(|a| a.in_namespace && a.name == b.name)
        {
            out.push((a, b));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(k: &str) -> ChannelSpec {
        ChannelSpec::Key(k.into())
    }

    fn table(
        key: Option<&str>,
        concat: Option<&[&str]>,
        columns: Option<[usize; 2]>,
    ) -> ChannelSpec {
        ChannelSpec::Table(ChannelTable {
            key: key.map(String::from),
            concat: concat.map(|c| c.iter().map(|s| s.to_string()).collect()),
            columns,
            kind: None,
        })
    }

    #[test]
    fn defaults_follow_the_source_key() {
        assert_eq!(default_name("observation.image", &key("img")), "img");
        assert_eq!(
            default_name("observation.images.top", &key("observations/images/top")),
            "top"
        );
        assert_eq!(
            default_name("observation.s", &table(Some("state"), None, None)),
            "state"
        );
        let cols = table(Some("state"), None, Some([0, 2]));
        assert_eq!(default_name("observation.pos", &cols), "pos");
        let cat = table(None, Some(&["a", "b"]), None);
        assert_eq!(default_name("observation.ab", &cat), "ab");
        assert_eq!(default_name("action", &cat), "action");
    }

    #[test]
    fn fixed_names_and_overrides() {
        let channels = [
            ("action".to_string(), key("actions")),
            ("observation.state".to_string(), key("state")),
            ("observation.image".to_string(), key("img")),
        ];
        let iter = || channels.iter().map(|(n, c)| (n.as_str(), c));
        let over: BTreeMap<String, String> = [
            ("observation.image".to_string(), "camera_0".to_string()),
            ("action".to_string(), "act".to_string()),
        ]
        .into();
        let zarr = export_names(OutputFormat::Zarr, iter(), &over, None);
        let names: Vec<&str> = zarr.iter().map(|n| n.name.as_str()).collect();
        assert_eq!(names, ["act", "state", "camera_0"]);
        let robomimic = export_names(OutputFormat::RobomimicHdf5, iter(), &over, None);
        assert_eq!(robomimic[0].name, "actions");
        let act = export_names(
            OutputFormat::ActEpisodes,
            iter(),
            &BTreeMap::new(),
            Some("observation.state"),
        );
        let names: Vec<&str> = act.iter().map(|n| n.name.as_str()).collect();
        assert_eq!(names, ["action", "qpos", "img"]);
    }

    #[test]
    fn collisions_name_both_channels() {
        let channels = [
            ("action".to_string(), key("action")),
            ("observation.a".to_string(), key("state")),
            ("observation.b".to_string(), key("robot/state")),
        ];
        let iter = || channels.iter().map(|(n, c)| (n.as_str(), c));
        let names = export_names(OutputFormat::Zarr, iter(), &BTreeMap::new(), None);
        let found = collisions(&names);
        assert_eq!(found.len(), 1);
        assert_eq!(
            (found[0].0.channel.as_str(), found[0].1.channel.as_str()),
            ("observation.a", "observation.b")
        );
        // robomimic's `actions` lives apart: an observation may be called `action`.
        let channels = [
            ("action".to_string(), key("actions")),
            ("observation.action".to_string(), key("actions")),
        ];
        let iter = channels.iter().map(|(n, c)| (n.as_str(), c));
        let over = [("observation.action".to_string(), "actions".to_string())].into();
        let names = export_names(OutputFormat::RobomimicHdf5, iter, &over, None);
        assert!(collisions(&names).is_empty());
    }

    #[test]
    fn names_are_one_component() {
        assert!(invalid_name("camera_0").is_none());
        assert!(invalid_name("a/b").is_some());
        assert!(invalid_name("").is_some());
        assert!(invalid_name("..").is_some());
    }
}
