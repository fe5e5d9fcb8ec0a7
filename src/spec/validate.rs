//! Semantic checks that need no source data: ranges, names, references between keys, and what
//! this version of chunkc can build. Every error points at the key it is about.
//!
//! All problems are reported at once (in file order), so that fixing a spec takes one round.

use super::diagnostic::{backticked, did_you_mean, suggest, Diagnostic};
use super::load::{dotted, LoadedSpec, Target};
use super::model::{OutputFormat, Preset, SourceFormat};
use super::preset::{self, Profile};

/// Checks the spec and expands its profiles (in name order).
pub(crate) fn check(loaded: &LoadedSpec) -> Result<Vec<Profile>, Vec<Diagnostic>> {
    let mut found = Vec::new();
    let spec = &loaded.spec;
    let mut at = |key: &[&str], target, message: String, label: &str, help: Option<String>| {
        found.push(loaded.diagnostic(key, target, message, label).with_help(help));
    };

    if spec.version != 1 {
        let message = format!("unsupported spec version {}", spec.version);
        at(&["version"], Target::Value, message, "expected 1", Some("this chunkc reads version 1 specs".into()));
    }

    if spec.source.format != SourceFormat::DiffusionPolicyZarr {
        let message = format!("source format `{}` is not supported yet", spec.source.format.name());
        let help = Some("this version of chunkc reads `diffusion_policy_zarr`".to_string());
        at(&["source", "format"], Target::Value, message, "not supported yet", help);
    }
    check_fps(&mut at, &["source", "fps"], spec.source.fps);
    check_channels(&mut at, spec.source.channels.keys().map(String::as_str));

    let val = spec.split.val_fraction;
    if !(0.0..1.0).contains(&val) {
        let message = format!("`split.val_fraction` must be at least 0 and less than 1, not {val}");
        // 10 for 10% is the likely mistake.
        let help = (1.0..=100.0)
            .contains(&val)
            .then(|| format!("a fraction, not a percentage: {val}% is `val_fraction = {}`", val / 100.0));
        at(&["split", "val_fraction"], Target::Value, message, "out of range", help);
    }

    if spec.profiles.is_empty() {
        let help = Some("add a `[profiles.<name>]` table, e.g. `[profiles.act]` with `preset = \"act\"`".into());
        at(&["profiles"], Target::Value, "the spec has no profiles".into(), "no `[profiles.<name>]` tables", help);
    }
    let channels: Vec<&str> = spec.source.channels.keys().map(String::as_str).collect();
    let mut profiles = Vec::new();
    for (name, profile) in &spec.profiles {
        let key = |k: &'static str| ["profiles", name.as_str(), k];
        if !is_profile_name(name) {
            let message = format!("invalid profile name `{name}`");
            let help = Some("profile names become directory names: use letters, digits, `_` and `-`".into());
            at(&["profiles", name.as_str()], Target::Key, message, "not a valid profile name", help);
        }
        check_fps(&mut at, &key("fps"), profile.fps);
        for (k, value) in [("chunk", profile.chunk), ("obs_history", profile.obs_history), ("stride", profile.stride)] {
            if value == Some(0) {
                let message = format!("`{}` must be at least 1", dotted(&key(k)));
                at(&key(k), Target::Value, message, "must be at least 1", None);
            }
        }
        for channel in profile.normalize.iter().flat_map(|n| n.keys()) {
            if !channels.contains(&channel.as_str()) {
                let message = format!("`normalize` names `{channel}`, which is not a channel in `[source.channels]`");
                let help = did_you_mean(channel, &channels, "channel");
                at(&["profiles", name.as_str(), "normalize", channel.as_str()], Target::Key, message, "unknown channel", help);
            }
        }
        if let Some(format) = profile.format.filter(|&f| f != OutputFormat::Hdf5) {
            let message = format!("output format `{}` is not supported yet", format.name());
            let help = Some("use `format = \"hdf5\"` (the default) for now".to_string());
            at(&key("format"), Target::Value, message, "not supported yet", help);
        }
        match preset::expand(name, profile) {
            Ok(expanded) => profiles.push(expanded),
            Err(missing) => {
                let message = format!("profile `{name}` has no `{missing}` and no preset to take it from");
                let presets = [Preset::Act, Preset::DiffusionPolicy].map(Preset::name);
                let help = Some(format!("set `{missing} = …` or a preset: {}", backticked(&presets)));
                at(&key(missing), Target::Value, message, "", help);
            }
        }
    }

    if found.is_empty() {
        return Ok(profiles);
    }
    found.sort_by_key(|d| d.span.as_ref().map(|s| s.start));
    Err(found)
}

type At<'a> = dyn FnMut(&[&str], Target, String, &str, Option<String>) + 'a;

fn check_fps(at: &mut At<'_>, key: &[&str], fps: Option<f64>) {
    if let Some(fps) = fps.filter(|f| !(f.is_finite() && *f > 0.0)) {
        let message = format!("`{}` must be a positive number of frames per second, not {fps}", dotted(key));
        at(key, Target::Value, message, "must be > 0", None);
    }
}

/// Exactly one `action`; everything else `observation.<name>`.
fn check_channels<'a>(at: &mut At<'_>, names: impl Iterator<Item = &'a str>) {
    let mut has_action = false;
    for name in names {
        if name == "action" {
            has_action = true;
            continue;
        }
        if name.strip_prefix("observation.").is_some_and(|rest| !rest.is_empty()) {
            continue;
        }
        let message = format!("invalid channel name `{name}`");
        let help = Some(channel_help(name));
        at(&["source", "channels", name], Target::Key, message, "not `action` or `observation.<name>`", help);
    }
    if !has_action {
        let help = Some("map the action to chunkc's name: `action = \"<source key>\"`".into());
        at(&["source", "channels", "action"], Target::Value, "no `action` channel".into(), "", help);
    }
}

fn channel_help(name: &str) -> String {
    if suggest(name, &["action"]).is_some() {
        return "did you mean `action`? The action channel is called exactly that".into();
    }
    // `obs.state`, `observations.state`, `state`: keep the user's last word.
    let base = name.rsplit('.').next().filter(|s| !s.is_empty()).unwrap_or("name");
    format!(
        "the action channel is `action`; observations are `observation.<name>`, e.g. `\"observation.{base}\"`"
    )
}

fn is_profile_name(name: &str) -> bool {
    !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_names() {
        assert!(is_profile_name("act_v2-small"));
        assert!(!is_profile_name("act v2"));
        assert!(!is_profile_name("act.v2"));
        assert!(!is_profile_name(""));
    }

    #[test]
    fn channel_hints_keep_the_users_word() {
        assert!(channel_help("obs.state").contains("`\"observation.state\"`"));
        assert!(channel_help("actions").starts_with("did you mean `action`?"));
        assert!(channel_help("observation.").contains("`\"observation.name\"`"));
    }
}
