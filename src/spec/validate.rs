// Long file: every rule a spec must meet before any data is read, in one list.
//! Semantic checks that need no source data: ranges, names, references between keys, and what
//! this version of chunkc can build. Every error points at the key it is about.
//!
//! All problems are reported at once (in file order), so that fixing a spec takes one round.

use super::diagnostic::{backticked, did_you_mean, suggest, Diagnostic};
use super::load::{dotted, LoadedSpec, Target};
use super::model::{
    ChannelKindSpec, ChannelSpec, ChannelTable, Compression, Layout, OutputFormat, Preset,
    ProfileSpec, SourceFormat,
};
use super::preset::{self, ExpandError, Profile};

mod export_names;
mod frames;
mod groot;
mod lerobot_version;
mod mixture;

/// Checks the spec and expands its profiles (in name order).
pub(crate) fn check(loaded: &LoadedSpec) -> Result<Vec<Profile>, Vec<Diagnostic>> {
    let mut c = Checker {
        loaded,
        found: Vec::new(),
    };
    c.top_level();
    c.sources();
    let profiles: Vec<Profile> = loaded
        .spec
        .profiles
        .iter()
        .filter_map(|(name, profile)| c.profile(name, profile))
        .collect();
    if c.found.is_empty() {
        return Ok(profiles);
    }
    c.found.sort_by_key(|d| d.span.as_ref().map(|s| s.start));
    Err(c.found)
}

struct Checker<'a> {
    loaded: &'a LoadedSpec,
    found: Vec<Diagnostic>,
}

impl Checker<'_> {
    /// A problem with the value of `key` (or, when it is absent, with its table).
    fn value(&mut self, key: &[&str], message: String, label: &str, help: Option<String>) {
        let d = self.loaded.diagnostic(key, Target::Value, message, label);
        self.found.push(d.with_help(help));
    }

    /// A problem with the name of `key` itself.
    fn key(&mut self, key: &[&str], message: String, label: &str, help: Option<String>) {
        let d = self.loaded.diagnostic(key, Target::Key, message, label);
        self.found.push(d.with_help(help));
    }

    /// `[audit.doctor]` thresholds in range.
    fn doctor_thresholds(&mut self, doctor: &crate::spec::DoctorSpec) {
        let fractions = [
            ("frozen_fraction", doctor.frozen_fraction, 0.0, 1.0),
            ("clip_fraction", doctor.clip_fraction, 0.0, 1.0),
            ("jump_threshold", doctor.jump_threshold, 0.0, f64::INFINITY),
            ("jump_range", doctor.jump_range, 0.0, 1.0),
            (
                "duplicate_tolerance",
                doctor.duplicate_tolerance,
                0.0,
                f64::INFINITY,
            ),
            ("units_ratio", doctor.units_ratio, 1.0, f64::INFINITY),
            (
                "shift_threshold",
                doctor.shift_threshold,
                0.0,
                f64::INFINITY,
            ),
        ];
        for (k, value, above, most) in fractions {
            if !(value.is_finite() && value > above && value <= most) {
                let what = if most.is_finite() {
                    format!("in ({above}, {most}]")
                } else {
                    format!("greater than {above}")
                };
                let message = format!("`audit.doctor.{k}` must be {what}, not {value}");
                self.value(&["audit", "doctor", k], message, "out of range", None);
            }
        }
    }

    fn top_level(&mut self) {
        let spec = &self.loaded.spec;
        if spec.version != 1 {
            let message = format!("unsupported spec version {}", spec.version);
            let help = Some("this chunkc reads version 1 specs".into());
            self.value(&["version"], message, "expected 1", help);
        }
        let val = spec.split.val_fraction;
        if !(0.0..1.0).contains(&val) {
            let message =
                format!("`split.val_fraction` must be at least 0 and less than 1, not {val}");
            // 10 meaning 10% is the likely mistake.
            let help = (1.0..=100.0).contains(&val).then(|| {
                let fraction = val / 100.0;
                format!("a fraction, not a percentage: {val}% is `val_fraction = {fraction}`")
            });
            self.value(&["split", "val_fraction"], message, "out of range", help);
        }
        let audit = &spec.audit;
        let thresholds = [
            (
                "jitter_threshold",
                audit.jitter_threshold,
                0.0,
                "greater than 0",
            ),
            ("gap_threshold", audit.gap_threshold, 1.0, "greater than 1"),
            (
                "count_threshold",
                audit.count_threshold,
                0.0,
                "greater than 0",
            ),
        ];
        for (k, value, above, what) in thresholds {
            if !(value.is_finite() && value > above) {
                let message = format!("`audit.{k}` must be {what}, not {value}");
                self.value(&["audit", k], message, "out of range", None);
            }
        }
        self.doctor_thresholds(&audit.doctor);
        if spec.profiles.is_empty() {
            let message = "the spec has no profiles".to_string();
            let help = Some(
                "add a `[profiles.<name>]` table, e.g. `[profiles.act]` with `preset = \"act\"`"
                    .into(),
            );
            self.value(
                &["profiles"],
                message,
                "no `[profiles.<name>]` tables",
                help,
            );
        }
    }

    fn source(&mut self) {
        let source = self.loaded.source();
        self.fps(&["source", "fps"], source.fps);
        if source.format == SourceFormat::Rlds && source.fps.is_none() {
            let message =
                "`source.fps` is required for `format = \"rlds\"`: RLDS stores no rate".to_string();
            let help = Some("add `fps = <control rate in Hz>` to `[source]`; Open X-Embodiment's dataset table lists each dataset's rate".into());
            self.value(&["source", "fps"], message, "no `fps` here", help);
        }
        if source.episodes.as_ref().is_some_and(|e| e.is_empty()) {
            let message = "`source.episodes` is empty".to_string();
            let help = Some("leave it out to read every episode".into());
            self.value(&["source", "episodes"], message, "no episodes", help);
        }
        for (name, channel) in &source.channels {
            if let ChannelSpec::Table(table) = channel {
                self.channel_table(name, table);
            }
        }

        // Exactly one `action` (the map's keys are unique); everything else an observation.
        let mut has_action = false;
        for name in source.channels.keys() {
            let is_observation = name
                .strip_prefix("observation.")
                .is_some_and(|rest| !rest.is_empty());
            if name == "action" {
                has_action = true;
            } else if !is_observation {
                let message = format!("invalid channel name `{name}`");
                let label = "not `action` or `observation.<name>`";
                let help = Some(channel_help(name));
                self.key(&["source", "channels", name], message, label, help);
            }
        }
        if !has_action {
            let message = "no `action` channel".to_string();
            let help = Some("map the action to chunkc's name: `action = \"<source key>\"`".into());
            self.value(&["source", "channels", "action"], message, "", help);
        }
    }

    /// The table form of a channel: exactly one of `key` and `concat`, a non-empty column range,
    /// and no image kind on a slice or a concatenation.
    fn channel_table(&mut self, name: &str, table: &ChannelTable) {
        let at = ["source", "channels", name];
        match (&table.key, &table.concat) {
            (Some(_), Some(_)) => {
                let message = format!("channel `{name}` has both `key` and `concat`");
                let help = Some("read one key with `key = \"…\"`, or join several with `concat = [\"…\", \"…\"]`".into());
                self.value(
                    &[&at[..], &["concat"]].concat(),
                    message,
                    "give one of `key` and `concat`",
                    help,
                );
            }
            (None, None) => {
                let message = format!("channel `{name}` names no source key");
                let help = Some("add `key = \"<source key>\"` or `concat = [\"<key>\", …]`".into());
                self.value(&at, message, "no `key` or `concat`", help);
            }
            (None, Some(keys)) if keys.is_empty() => {
                let message = format!("channel `{name}` concatenates nothing");
                self.value(
                    &[&at[..], &["concat"]].concat(),
                    message,
                    "empty list",
                    None,
                );
            }
            _ => {}
        }
        if let Some([a, b]) = table.columns {
            if a >= b {
                let message =
                    format!("channel `{name}` selects columns [{a}, {b}), which is empty");
                let help = Some("columns are `[start, end)`, as Python's `x[:, start:end]`: end must exceed start".into());
                self.value(
                    &[&at[..], &["columns"]].concat(),
                    message,
                    "empty range",
                    help,
                );
            }
        }
        let sliced = table.columns.is_some() || table.concat.is_some();
        if sliced && table.kind == Some(ChannelKindSpec::Image) {
            let message =
                format!("channel `{name}` slices or concatenates keys, so it cannot be an image");
            self.value(
                &[&at[..], &["kind"]].concat(),
                message,
                "only whole keys are images",
                None,
            );
        }
    }

    /// Checks one profile and, when nothing is missing, expands it.
    // Long function: one check per profile key, in the spec reference's order.
    fn profile(&mut self, name: &str, profile: &ProfileSpec) -> Option<Profile> {
        let key = |k: &'static str| ["profiles", name, k];
        if !is_profile_name(name) {
            let message = format!("invalid profile name `{name}`");
            let help =
                Some("profile names become directory names: use letters, digits, `_` and `-`");
            let label = "not a valid profile name";
            self.key(&["profiles", name], message, label, help.map(String::from));
        }
        if name == "audit" {
            let message =
                "`audit` is not a profile name: `chunkc audit` writes `<output.dir>/audit/`"
                    .to_string();
            let label = "reserved";
            self.key(
                &["profiles", name],
                message,
                label,
                Some("rename the profile".into()),
            );
        }
        self.fps(&key("fps"), profile.fps);
        if let Some(id) = &profile.env {
            if let Err((message, help)) = super::env::check(id) {
                self.value(&key("env"), message, "not a gymnasium id", help);
            }
        }
        let counts = [
            ("chunk", profile.chunk),
            ("obs_history", profile.obs_history),
            ("stride", profile.stride),
        ];
        for (k, value) in counts {
            if value == Some(0) {
                let message = format!("`{}` must be at least 1", dotted(&key(k)));
                self.value(&key(k), message, "must be at least 1", None);
            }
        }

        let channels: Vec<&str> = self.loaded.channel_map().into_keys().collect();
        for channel in profile.normalize.iter().flat_map(|n| n.keys()) {
            if !channels.contains(&channel.as_str()) {
                let message = format!(
                    "`normalize` names `{channel}`, which is not a channel in `[source.channels]`"
                );
                let help = did_you_mean(channel, &channels, "channel");
                let at = ["profiles", name, "normalize", channel];
                self.key(&at, message, "unknown channel", help);
            }
        }

        if let Some(segment) = &profile.segment {
            if !channels.contains(&segment.channel.as_str()) {
                let message = format!(
                    "`segment.channel` names `{}`, which is not a channel in `[source.channels]`",
                    segment.channel
                );
                let help = did_you_mean(&segment.channel, &channels, "channel");
                let at = ["profiles", name, "segment", "channel"];
                self.value(&at, message, "unknown channel", help);
            }
            for (k, value) in [
                ("smoothing", Some(segment.smoothing)),
                ("min_length", Some(segment.min_length)),
                ("max_length", segment.max_length),
            ] {
                if value == Some(0) {
                    let at = ["profiles", name, "segment", k];
                    let message = format!("`{}` must be at least 1", dotted(&at));
                    self.value(&at, message, "must be at least 1", None);
                }
            }
            if !(segment.threshold.is_finite() && segment.threshold >= 0.0) {
                let at = ["profiles", name, "segment", "threshold"];
                let message = format!("`{}` must be a finite number >= 0", dotted(&at));
                self.value(&at, message, "must be >= 0", None);
            }
            if profile.hierarchy.is_some() {
                let at = ["profiles", name, "hierarchy"];
                let message =
                    format!("profile `{name}` has both `segment` and `hierarchy`; choose one");
                self.key(&at, message, "conflicts with `segment`", None);
            }
        }
        if let Some(h) = &profile.hierarchy {
            if !(h.coarse_seconds.is_finite() && h.coarse_seconds > 0.0) {
                let at = ["profiles", name, "hierarchy", "coarse_seconds"];
                let message = format!("`{}` must be a positive number of seconds", dotted(&at));
                self.value(&at, message, "must be > 0", None);
            }
        }

        let cameras = super::validate_camera::check(self.loaded, name, profile);
        self.found.extend(cameras);
        match preset::expand(name, &self.loaded.spec.profiles) {
            Ok(expanded) => {
                self.output_options(name, &expanded);
                self.export_keys(name, profile, &expanded);
                self.lerobot_version(name, profile, &expanded);
                self.groot(name, profile, &expanded);
                Some(expanded)
            }
            Err(ExpandError::Missing(missing)) => {
                let message =
                    format!("profile `{name}` has no `{missing}` and no preset to take it from");
                let presets = Preset::ALL.map(Preset::name);
                let help = format!("set `{missing} = …` or a preset: {}", backticked(&presets));
                self.value(&key(missing), message, "", Some(help));
                None
            }
            Err(ExpandError::UnknownParent(parent)) => {
                let message = format!(
                    "profile `{name}` extends `{parent}`, which is not a profile of this spec"
                );
                let names: Vec<&str> = self
                    .loaded
                    .spec
                    .profiles
                    .keys()
                    .map(String::as_str)
                    .collect();
                let help = did_you_mean(&parent, &names, "profile");
                self.value(&key("extends"), message, "unknown profile", help);
                None
            }
            Err(ExpandError::Cycle(names)) => {
                let message = format!("`extends` goes round in a circle: {}", names.join(" -> "));
                self.value(&key("extends"), message, "circular", None);
                None
            }
        }
    }

    /// `layout`, `compression`, `compression_level` and `zarr_version` against the format (all
    /// resolved, so an inherited value is checked against this profile's format too).
    fn output_options(&mut self, name: &str, p: &Profile) {
        let key = |k: &'static str| ["profiles", name, k];
        let format = p.format.name();
        if p.layout != Layout::Index && p.format != OutputFormat::Hdf5 {
            let message = format!(
                "`layout = \"{}\"` needs `format = \"hdf5\"`, but profile `{name}` writes `{format}`",
                p.layout.name()
            );
            self.value(&key("layout"), message, "only for hdf5", None);
        }
        if p.layout != Layout::Index && (p.segment.is_some() || p.hierarchy.is_some()) {
            let message = format!(
                "`layout = \"{}\"` needs fixed windows; profile `{name}` uses {}",
                p.layout.name(),
                if p.segment.is_some() {
                    "`segment`"
                } else {
                    "`hierarchy`"
                }
            );
            let help = Some("use `layout = \"index\"`, which stores every sampling".into());
            self.value(&key("layout"), message, "fixed windows only", help);
        }
        let allowed = Compression::allowed(p.format);
        if !allowed.contains(&p.compression) {
            let names: Vec<&str> = allowed.iter().map(|c| c.name()).collect();
            let message = format!(
                "format `{format}` does not support `compression = \"{}\"`",
                p.compression.name()
            );
            let help = Some(format!("`{format}` accepts {}", backticked(&names)));
            self.value(&key("compression"), message, "not for this format", help);
        }
        if let Some(level) = p.compression_level {
            let range = match p.compression {
                Compression::Gzip => Some(0..=9),
                Compression::Lz4 => Some(1..=9),
                Compression::Zstd if p.format == OutputFormat::Zarr => Some(1..=9),
                Compression::Zstd => Some(1..=22),
                Compression::None | Compression::Lzf => None,
            };
            match range {
                Some(r) if !r.contains(&level) => {
                    let message = format!(
                        "`compression_level` {level} is out of range for {} ({}..={})",
                        p.compression.name(),
                        r.start(),
                        r.end()
                    );
                    self.value(&key("compression_level"), message, "out of range", None);
                }
                None => {
                    let message = format!(
                        "`compression = \"{}\"` takes no `compression_level`",
                        p.compression.name()
                    );
                    self.value(&key("compression_level"), message, "has no level", None);
                }
                Some(_) => {}
            }
        }
        self.image_options(name, p);
        self.video_options(name, p);
        if !matches!(p.zarr_version, 2 | 3) {
            let message = format!("`zarr_version` must be 2 or 3, not {}", p.zarr_version);
            self.value(&key("zarr_version"), message, "expected 2 or 3", None);
        } else if p.zarr_version != 2 && p.format != OutputFormat::Zarr {
            let message = format!("`zarr_version` needs `format = \"zarr\"`, not `{format}`");
            self.value(&key("zarr_version"), message, "only for zarr", None);
        }
    }

    fn fps(&mut self, key: &[&str], fps: Option<f64>) {
        if let Some(fps) = fps.filter(|f| !(f.is_finite() && *f > 0.0)) {
            let what = dotted(key);
            let message =
                format!("`{what}` must be a positive number of frames per second, not {fps}");
            self.value(key, message, "must be > 0", None);
        }
    }
}

fn channel_help(name: &str) -> String {
    if suggest(name, &["action"]).is_some() {
        return "did you mean `action`? The action channel is called exactly that".into();
    }
    // `obs.state`, `observations.state`, `state`: keep the user's last word.
    let base = name
        .rsplit('.')
        .next()
        .filter(|s| !s.is_empty())
        .unwrap_or("name");
    format!(
        "the action channel is `action`; observations are `observation.<name>`, \
         e.g. `\"observation.{base}\"`"
    )
}

pub(super) fn is_profile_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
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
