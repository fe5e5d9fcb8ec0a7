//! GR00T's keys, `modality` and `relative_actions`: on a `groot` profile only, which writes the
//! LeRobot v2.1 dataset GR00T reads; each channel's parts tile it from 0 without an overlap or
//! a gap (the channel's width, where the tiling must end, is the source's: the plan checks it).

use super::Checker;
use crate::spec::diagnostic::did_you_mean;
use crate::spec::modality;
use crate::spec::model::{OutputFormat, Preset, ProfileSpec};
use crate::spec::preset::Profile;

impl Checker<'_> {
    pub(super) fn groot(&mut self, name: &str, own: &ProfileSpec, p: &Profile) {
        let groot = p.preset == Some(Preset::Groot);
        for (key, set) in [
            ("modality", own.modality.is_some()),
            ("relative_actions", own.relative_actions.is_some()),
        ] {
            if set && !groot {
                let preset = p
                    .preset
                    .map_or("no preset".into(), |x| format!("preset `{}`", x.name()));
                let message = format!(
                    "`{key}` describes GR00T's dataset (`preset = \"groot\"`); profile `{name}` \
                     has {preset}"
                );
                let help = Some("set `preset = \"groot\"` to write GR00T's files".to_string());
                self.key(&["profiles", name, key], message, "GR00T only", help);
            }
        }
        if !groot {
            return;
        }
        if p.format != OutputFormat::Parquet {
            let message = format!(
                "preset `groot` writes the LeRobot v2.1 dataset GR00T reads (`format = \
                 \"parquet\"`); profile `{name}` writes `{}`",
                p.format.name()
            );
            let help = Some("leave `format` out: the preset's is `parquet`".to_string());
            self.value(&["profiles", name, "format"], message, "not GR00T's", help);
        } else if !p.writes_lerobot_v21() {
            let message = format!(
                "preset `groot` writes LeRobot v2.1, the version GR00T reads; profile `{name}` \
                 sets `lerobot_version = \"{}\"`",
                p.lerobot_version.name()
            );
            let help = Some("leave `lerobot_version` out: the preset's is `v2.1`".to_string());
            let at = ["profiles", name, "lerobot_version"];
            self.value(&at, message, "GR00T reads v2.1", help);
        }
        let mapped = self.loaded.channel_map();
        let channels: Vec<&str> = mapped.keys().copied().collect();
        for (channel, parts) in own.modality.iter().flatten() {
            if !channels.contains(&channel.as_str()) {
                let message = format!(
                    "`modality` names `{channel}`, which is not a channel in `[source.channels]`"
                );
                let help = did_you_mean(channel, &channels, "channel");
                let at = ["profiles", name, "modality", channel.as_str()];
                self.key(&at, message, "unknown channel", help);
                continue;
            }
            if parts.is_empty() {
                let message = format!(
                    "`modality.\"{channel}\"` has no part; leave the channel out to make it one"
                );
                let at = ["profiles", name, "modality", channel.as_str()];
                self.value(&at, message, "no part", None);
            }
            for problem in modality::problems(channel, parts, None) {
                let at = ["profiles", name, "modality", channel, &problem.part];
                let help = Some(format!(
                    "give each dimension of `{channel}` to exactly one part, as `[start, end)` \
                     slices from 0: `arm = [0, 7], gripper = [7, 8]`"
                ));
                self.value(&at, problem.message, problem.label, help);
            }
        }
        self.relative_actions(name, own);
    }

    /// `relative_actions` names each part once (the parts themselves are the plan's to find).
    fn relative_actions(&mut self, name: &str, own: &ProfileSpec) {
        let mut seen: Vec<&str> = Vec::new();
        for part in own.relative_actions.iter().flatten() {
            if seen.contains(&part.as_str()) {
                let message = format!("`relative_actions` names `{part}` twice");
                self.value(
                    &["profiles", name, "relative_actions"],
                    message,
                    "twice",
                    None,
                );
            }
            seen.push(part);
        }
    }
}
