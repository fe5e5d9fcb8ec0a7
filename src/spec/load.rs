//! A spec as loaded ([`LoadedSpec`]): the typed spec, its expanded profiles, and the spanned
//! `toml_edit` document kept next to them (cargo's habit), so that any later stage can turn
//! "this key is wrong" into a `file:line:col` excerpt ([`LoadedSpec::error_at`]); and a
//! mixture's sources, each seen as a one-source spec ([`SourceView`]).
//!
//! Reading one from TOML is [`super::parse`]'s.

use std::collections::BTreeMap;
use std::path::PathBuf;

use toml_edit::{Document, Item, TableLike};

use super::diagnostic::Diagnostic;
use super::model::{ChannelSpec, SourceSpec, Spec};
use super::profile::Profile;
use crate::error::Error;

/// A parsed, validated spec with every profile expanded, and the text it came from.
#[derive(Debug, Clone)]
pub struct LoadedSpec {
    pub spec: Spec,
    /// The expanded profiles, sorted by name.
    pub profiles: Vec<Profile>,
    /// The spec's path as given (shown in messages).
    pub file: PathBuf,
    /// The directory relative paths in the spec are resolved against.
    pub dir: PathBuf,
    pub text: String,
    /// BLAKE3 of the canonical JSON of `spec`: comments and formatting do not change it.
    pub hash: String,
    pub(super) doc: Document<String>,
    /// Where this spec's `[source]` is written: `["source"]`, or `["sources", name]` in a view of
    /// one source of a mixture (see [`LoadedSpec::source_views`]); errors at `source.…` keys
    /// point there.
    pub(super) source_at: Vec<String>,
}

/// One source of a mixture, seen as a one-source spec.
#[derive(Debug, Clone)]
pub struct SourceView {
    /// `[sources.<name>]`'s name.
    pub name: String,
    /// Its weight (1 when not given).
    pub weight: f64,
    /// The spec with `[source]` = this source: every stage that reads one source reads it, and its
    /// errors name `sources.<name>.…`.
    pub spec: LoadedSpec,
}

/// Which part of a `key = value` line a diagnostic underlines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Target {
    Key,
    Value,
}

impl LoadedSpec {
    /// A spec error at the value of `key` (e.g. `&["profiles", "act", "fps"]`). When the key is
    /// not in the file, it points at the closest table that is and says the key is missing there.
    pub fn error_at(
        &self,
        key: &[&str],
        message: impl Into<String>,
        help: Option<String>,
    ) -> Error {
        self.error(&[self
            .diagnostic(key, Target::Value, message, "")
            .with_help(help)])
    }

    pub fn resolve(&self, rel: &str) -> PathBuf {
        self.dir.join(rel)
    }

    /// The one source (`[source]`, or the source of a view). A mixture has none: its stages go
    /// through [`LoadedSpec::source_views`].
    pub fn source(&self) -> &SourceSpec {
        self.spec
            .source
            .as_ref()
            .expect("a one-source spec (a mixture is read through its source views)")
    }

    /// Whether the spec is a training mixture (`[sources.<name>]`).
    pub fn is_mixture(&self) -> bool {
        self.spec.source.is_none() && !self.spec.sources.is_empty()
    }

    /// Each source as a one-source spec, in name order (`[source]` alone is one view named "").
    pub fn source_views(&self) -> Vec<SourceView> {
        if !self.is_mixture() {
            return vec![SourceView {
                name: String::new(),
                weight: 1.0,
                spec: self.clone(),
            }];
        }
        self.spec
            .sources
            .iter()
            .map(|(name, source)| {
                let mut spec = self.clone();
                spec.spec.source = Some(source.clone());
                spec.spec.sources = BTreeMap::new();
                spec.source_at = vec!["sources".to_string(), name.clone()];
                SourceView {
                    name: name.clone(),
                    weight: source.weight.unwrap_or(1.0),
                    spec,
                }
            })
            .collect()
    }

    /// Every mapped channel and its mapping: the source's, or in a mixture the union of the
    /// sources' (the first source in name order that maps a channel gives its mapping).
    pub fn channel_map(&self) -> BTreeMap<&str, &ChannelSpec> {
        let mut map = BTreeMap::new();
        for source in self.spec.source.iter().chain(self.spec.sources.values()) {
            for (name, channel) in &source.channels {
                map.entry(name.as_str()).or_insert(channel);
            }
        }
        map
    }

    /// The path of every source, as written.
    pub fn source_paths(&self) -> Vec<&str> {
        let all = self.spec.source.iter().chain(self.spec.sources.values());
        all.map(|s| s.path.as_str()).collect()
    }

    pub(crate) fn error(&self, diagnostics: &[Diagnostic]) -> Error {
        Error::Spec(render_all(
            diagnostics,
            &self.file.display().to_string(),
            &self.text,
        ))
    }

    /// A diagnostic underlining `key`'s name or value, or, when the key is absent, the header of
    /// its closest ancestor in the file.
    pub(crate) fn diagnostic(
        &self,
        key: &[&str],
        target: Target,
        message: impl Into<String>,
        label: impl Into<String>,
    ) -> Diagnostic {
        let diagnostic = Diagnostic::new(message);
        // In a view of one source of a mixture, `source.…` is `sources.<name>.…`.
        let rewritten: Vec<&str>;
        let key = if key.first() == Some(&"source") && self.source_at.len() > 1 {
            rewritten = self
                .source_at
                .iter()
                .map(String::as_str)
                .chain(key[1..].iter().copied())
                .collect();
            &rewritten[..]
        } else {
            key
        };
        let mut item = self.doc.as_item();
        // The root has no span of its own; its "header" is the start of the file.
        let mut ancestor = 0..0;
        // An element of an array of tables (`[[profiles.x.transforms]]`), named by its index.
        let mut element: Option<&toml_edit::Table> = None;
        for (depth, segment) in key.iter().enumerate() {
            if let (None, Item::ArrayOfTables(tables), Ok(i)) =
                (element, item, segment.parse::<usize>())
            {
                if let Some(t) = tables.get(i) {
                    ancestor = t.span().unwrap_or(ancestor);
                    element = Some(t);
                    if depth + 1 == key.len() {
                        return diagnostic.at(ancestor, label);
                    }
                    continue;
                }
            }
            let table: Option<&dyn TableLike> = match element.take() {
                Some(t) => Some(t),
                None => item.as_table_like(),
            };
            let found = table.and_then(|t| t.get_key_value(segment));
            let Some((k, child)) = found else {
                let missing = dotted(&key[depth..]);
                let place = if depth == 0 {
                    "at the top level"
                } else {
                    "in this table"
                };
                return diagnostic.at(ancestor, format!("`{missing}` is missing {place}"));
            };
            let key_span = k.span().unwrap_or(ancestor.clone());
            // A `[table]`'s span is its header; an implicit table (`profiles` in
            // `[profiles.act]`) has none, so its key stands for it.
            ancestor = child.span().unwrap_or(key_span.clone());
            if depth + 1 == key.len() && target == Target::Key {
                return diagnostic.at(key_span, label);
            }
            item = child;
        }
        diagnostic.at(ancestor, label)
    }
}

pub(super) fn render_all(diagnostics: &[Diagnostic], file: &str, text: &str) -> String {
    let rendered: Vec<String> = diagnostics.iter().map(|d| d.render(file, text)).collect();
    rendered.join("\n\n")
}

/// `profiles.act.normalize."observation.state"`: the key as it could be written in TOML.
pub(crate) fn dotted(path: &[&str]) -> String {
    let bare = |s: &str| {
        !s.is_empty()
            && s.chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    };
    let quoted: Vec<String> = path
        .iter()
        .map(|s| {
            if bare(s) {
                s.to_string()
            } else {
                format!("{s:?}")
            }
        })
        .collect();
    quoted.join(".")
}

#[cfg(test)]
pub(super) mod tests {
    use std::path::Path;

    use super::*;

    pub(in crate::spec) const SPEC: &str = r#"version = 1

[source]
format = "diffusion_policy_zarr"
path = "data/x.zarr"
fps = 10

[source.channels]
action = "action"
"observation.state" = "state"

[output]
dir = "out/x"

[profiles.dp]
preset = "diffusion_policy"

[profiles.act]
preset = "act"
chunk = 20
"#;

    pub(in crate::spec) fn parse(text: &str) -> crate::error::Result<LoadedSpec> {
        LoadedSpec::parse("t.toml", text, Path::new("specs"))
    }

    #[test]
    fn lerobot_version_comes_from_the_chain_then_the_preset() {
        let text = SPEC.replace("[profiles.dp]", "[profiles.v21]\npreset = \"pi0\"\nformat = \"parquet\"\nlerobot_version = \"v2.1\"\n[profiles.child]\nextends = \"v21\"\n[profiles.g]\npreset = \"groot\"\n[profiles.dp]");
        let spec = parse(&text).unwrap();
        let p = |name: &str| spec.profiles.iter().find(|p| p.name == name).unwrap();
        let origin = |name: &str| p(name).origins.get("lerobot_version").cloned();
        assert!(p("child").writes_lerobot_v21() && p("g").writes_lerobot_v21());
        assert_eq!(origin("child").as_deref(), Some("profiles.v21"));
        assert_eq!(origin("g").as_deref(), Some("preset groot"));
        assert_eq!(p("act").lerobot_version, crate::spec::LerobotVersion::V30);
        assert_eq!(origin("act"), None);
    }

    #[test]
    fn error_at_points_at_the_value() {
        let loaded = parse(SPEC).unwrap();
        let err = loaded.error_at(
            &["profiles", "act", "chunk"],
            "too long",
            Some("shorter".into()),
        );
        let text = err.to_string();
        assert!(text.contains("t.toml:20:9"), "{text}");
        assert!(text.contains("chunk = 20\n   |         ^^"), "{text}");
        assert!(text.contains("= help: shorter"), "{text}");
    }

    #[test]
    fn error_at_a_missing_key_points_at_its_table() {
        let loaded = parse(SPEC).unwrap();
        let text = loaded
            .error_at(&["profiles", "dp", "stride"], "no stride", None)
            .to_string();
        assert!(text.contains("t.toml:15:1"), "{text}");
        assert!(
            text.contains("^^^^^^^^^^^^^ `stride` is missing in this table"),
            "{text}"
        );
        let text = loaded.error_at(&["nope", "x"], "no", None).to_string();
        assert!(text.contains("t.toml:1:1"), "{text}");
        assert!(
            text.contains("`nope.x` is missing at the top level"),
            "{text}"
        );
    }

    #[test]
    fn keys_are_quoted_when_needed() {
        assert_eq!(
            dotted(&["profiles", "act", "normalize", "observation.state"]),
            "profiles.act.normalize.\"observation.state\""
        );
    }
}
