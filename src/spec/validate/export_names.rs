//! The `export_keys` table of a profile: the names a native export gives its arrays.

use super::Checker;
use crate::spec::diagnostic::did_you_mean;
use crate::spec::export_keys;
use crate::spec::load::dotted;
use crate::spec::model::ProfileSpec;
use crate::spec::preset::Profile;

impl Checker<'_> {
    /// `export_keys`: channels that exist, names of one component, a format that renames, and no
    /// two channels exported under one name (overridden or by default).
    // Long function: one check per rule in the doc above, over the same maps.
    pub(super) fn export_keys(&mut self, name: &str, own: &ProfileSpec, p: &Profile) {
        let mapped = self.loaded.channel_map();
        let channels: Vec<&str> = mapped.keys().copied().collect();
        let format = p.format.name();
        let at = |channel: &str| {
            [
                "profiles".to_string(),
                name.to_string(),
                "export_keys".into(),
                channel.to_string(),
            ]
        };
        if let Some(map) = &own.export_keys {
            if !export_keys::renames(p.format) {
                let message = format!(
                    "`export_keys` names the arrays of native exports (`zarr`, `robomimic_hdf5`, `act_episodes`); profile `{name}` writes `{format}`, which keeps chunkc's channel names"
                );
                let help = Some("remove `export_keys`: chunkc's loader reads the channels by their chunkc names".into());
                self.key(
                    &["profiles", name, "export_keys"],
                    message,
                    "not for this format",
                    help,
                );
                return;
            }
            for (channel, value) in map {
                let key = at(channel);
                let key: Vec<&str> = key.iter().map(String::as_str).collect();
                if !channels.contains(&channel.as_str()) {
                    let message = format!(
                        "`export_keys` names `{channel}`, which is not a channel in `[source.channels]`"
                    );
                    let help = did_you_mean(channel, &channels, "channel");
                    self.key(&key, message, "unknown channel", help);
                    continue;
                }
                if let Some(fixed) =
                    export_keys::fixed_action(p.format).filter(|_| channel == "action")
                {
                    let message = format!(
                        "`{format}` stores the action channel as `{fixed}`, the name its codebase reads; it cannot be renamed"
                    );
                    self.key(
                        &key,
                        message,
                        "fixed name",
                        Some(format!("remove `{channel}` from `export_keys`")),
                    );
                    continue;
                }
                if let Some(why) = export_keys::invalid_name(value) {
                    let message = format!("export name `{value}` of `{channel}` {why}");
                    self.value(&key, message, "not an array name", None);
                }
            }
        }
        if !export_keys::renames(p.format) {
            return;
        }
        // ACT's state channel, as far as names tell (the plan checks again with the source's kinds).
        let state = ["observation.qpos", "observation.state"]
            .into_iter()
            .find(|c| channels.contains(c));
        let names = export_keys::export_names(
            p.format,
            mapped.iter().map(|(n, c)| (*n, *c)),
            &p.export_keys,
            state,
        );
        let set_here = |n: &export_keys::ExportName| {
            n.overridden
                && own
                    .export_keys
                    .as_ref()
                    .is_some_and(|m| m.contains_key(&n.channel))
        };
        for (a, b) in export_keys::collisions(&names) {
            // Point at the name this profile chose, if it chose one; else at the mapping.
            let (other, culprit) = if set_here(a) && !set_here(b) {
                (b, a)
            } else {
                (a, b)
            };
            let message = format!(
                "profile `{name}` (`{format}`) would export `{}` and `{}` both as `{}`",
                a.channel, b.channel, b.name
            );
            if set_here(culprit) {
                let key = at(&culprit.channel);
                let key: Vec<&str> = key.iter().map(String::as_str).collect();
                let label = format!(
                    "`{}` is already exported as `{}`",
                    other.channel, other.name
                );
                let help = Some(format!("choose another name for `{}`", culprit.channel));
                self.value(&key, message, &label, help);
            } else {
                let help = Some(format!(
                    "give one of them its own name: `{} = \"…\"` in `[profiles.{name}.export_keys]`",
                    dotted(&[&culprit.channel])
                ));
                let label = format!("exported as `{}`, as `{}` is", culprit.name, other.channel);
                self.key(
                    &["source", "channels", &culprit.channel],
                    message,
                    &label,
                    help,
                );
            }
        }
    }
}
