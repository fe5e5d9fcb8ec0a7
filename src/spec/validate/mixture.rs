//! `[source]` or `[sources.<name>]` (a training mixture), and `[mixture]`. The rules that need
//! the sources' data (widths, a channel a source lacks) are the mixture source's
//! (`source::mixture`).

use super::{is_profile_name, Checker};
use crate::spec::diagnostic::did_you_mean;

impl Checker<'_> {
    /// Exactly one of `[source]` and `[sources.<name>]`, each source's own rules, the weights
    /// and `[mixture]`.
    pub(super) fn sources(&mut self) {
        let spec = &self.loaded.spec;
        match (&spec.source, spec.sources.is_empty()) {
            (Some(source), true) => {
                self.source();
                if source.weight.is_some() {
                    let message = "`source.weight` weighs a source of a mixture; `[source]` is the only source".to_string();
                    let help = Some("remove it, or name the source: `[sources.<name>]`".into());
                    self.key(&["source", "weight"], message, "one source", help);
                }
                if spec.mixture.is_some() {
                    let message =
                        "`[mixture]` needs several sources: `[sources.<name>]`, not `[source]`"
                            .to_string();
                    self.key(&["mixture"], message, "no mixture", None);
                }
            }
            (Some(_), false) => {
                let message = "give either `[source]` (one dataset) or `[sources.<name>]` (a mixture), not both".to_string();
                self.key(&["source"], message, "and `[sources]`", None);
            }
            (None, true) => {
                let message = "the spec has no source".to_string();
                let help = Some("add `[source]` (one dataset), or `[sources.<name>]` tables (a training mixture)".into());
                self.value(&["source"], message, "", help);
            }
            (None, false) => self.mixture(),
        }
    }

    fn mixture(&mut self) {
        let spec = &self.loaded.spec;
        let views = self.loaded.source_views();
        for view in &views {
            let mut checker = Checker {
                loaded: &view.spec,
                found: Vec::new(),
            };
            checker.source();
            self.found.extend(checker.found);
            let name = view.name.as_str();
            if !is_profile_name(name) {
                let message = format!("invalid source name `{name}`");
                let help = Some("source names become directory names (`sources/<name>/`): use letters, digits, `_` and `-`".into());
                self.key(&["sources", name], message, "not a valid name", help);
            }
            if !(view.weight.is_finite() && view.weight >= 0.0) {
                let message = format!(
                    "`sources.{name}.weight` must be a finite number at least 0, not {}",
                    view.weight
                );
                self.value(&["sources", name, "weight"], message, "out of range", None);
            }
        }
        if views.iter().all(|v| v.weight == 0.0) {
            let last = &views[views.len() - 1].name;
            let message = "every source's weight is 0: the sampler would draw nothing".to_string();
            let help =
                Some("give at least one source a positive `weight` (1 when left out)".into());
            self.value(&["sources", last, "weight"], message, "all 0", help);
        }
        let mixture = spec.mixture.clone().unwrap_or_default();
        let channels: Vec<&str> = self.loaded.channel_map().into_keys().collect();
        for (channel, &width) in &mixture.pad_to {
            let at = ["mixture", "pad_to", channel.as_str()];
            if !channels.contains(&channel.as_str()) {
                let message = format!(
                    "`mixture.pad_to` names `{channel}`, which no source maps in `[sources.<name>.channels]`"
                );
                let help = did_you_mean(channel, &channels, "channel");
                self.key(&at, message, "unknown channel", help);
            } else if width == 0 {
                let message = format!("`mixture.pad_to.{channel}` must be at least 1");
                self.value(&at, message, "must be at least 1", None);
            }
        }
    }
}
