// Long file: parsing and its diagnostics (spans, serde messages, did-you-mean) are one step.
//! Reading a spec: TOML text → spanned document → typed [`Spec`] → validated, expanded profiles.
//!
//! The spanned `toml_edit` document is kept next to the typed spec (cargo's habit), so any later
//! stage can turn "this key is wrong" into a `file:line:col` excerpt with [`LoadedSpec::error_at`].
//! serde's error messages are rewritten here into ones that name the key and its table and
//! suggest the closest valid name.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use toml_edit::{Document, Item, TableLike};

use super::diagnostic::{backticked, did_you_mean, Diagnostic};
use super::model::{ChannelSpec, SourceSpec, Spec};
use super::preset::Profile;
use super::{reference, validate};
use crate::error::{Error, Result};

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
    doc: Document<String>,
    /// Where this spec's `[source]` is written: `["source"]`, or `["sources", name]` in a view of
    /// one source of a mixture (see [`LoadedSpec::source_views`]); errors at `source.…` keys
    /// point there.
    source_at: Vec<String>,
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
    pub fn load(path: &Path) -> Result<LoadedSpec> {
        // A spec that cannot be read is the user's input error (exit 2), not an output failure.
        let text = std::fs::read_to_string(path)
            .map_err(|e| Error::Spec(format!("error: cannot read spec {}: {e}", path.display())))?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut loaded = Self::parse(&path.display().to_string(), &text, &dir)?;
        loaded.file = path.to_path_buf();
        Ok(loaded)
    }

    /// Parses `text`; `name` stands for the file in messages, `dir` anchors relative paths.
    pub fn parse(name: &str, text: &str, dir: &Path) -> Result<LoadedSpec> {
        let fail = |diagnostics: &[Diagnostic]| Error::Spec(render_all(diagnostics, name, text));
        let doc = Document::parse(text.to_string())
            .map_err(|e| fail(&[syntax_error(e.message(), e.span(), text)]))?;
        let spec: Spec = toml::from_str(text).map_err(|e| {
            // serde reads `[[x]]` as a sequence of structs and complains about something else.
            let diagnostic = array_of_tables(doc.as_item(), &mut Vec::new())
                .unwrap_or_else(|| serde_error(&e, &doc));
            fail(&[diagnostic])
        })?;
        let canonical = serde_json::to_string(&spec).expect("a spec serializes to JSON");
        let mut loaded = LoadedSpec {
            hash: blake3::hash(canonical.as_bytes()).to_hex().to_string(),
            spec,
            profiles: Vec::new(),
            file: PathBuf::from(name),
            dir: dir.to_path_buf(),
            text: text.to_string(),
            doc,
            source_at: vec!["source".to_string()],
        };
        loaded.profiles = validate::check(&loaded).map_err(|d| fail(&d))?;
        Ok(loaded)
    }

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

fn render_all(diagnostics: &[Diagnostic], file: &str, text: &str) -> String {
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

/// "in `[profiles.act]`" or "at the top level", for the table that holds a key.
fn in_table(table: &[&str]) -> String {
    if table.is_empty() {
        "at the top level".into()
    } else {
        format!("in `[{}]`", dotted(table))
    }
}

fn syntax_error(message: &str, span: Option<Range<usize>>, text: &str) -> Diagnostic {
    let span = span.unwrap_or(0..0);
    let diagnostic = if message == "duplicate key" {
        let key = text.get(span.clone()).unwrap_or("");
        Diagnostic::new(format!("duplicate key `{key}`")).at(span, "defined a second time here")
    } else {
        // "unclosed table, expected `]`": the first half says what is wrong, the second what
        // belongs under the caret.
        let (what, expected) = message
            .split_once(", expected ")
            .unwrap_or((message, "nothing"));
        let label = if expected == "nothing" {
            String::new()
        } else {
            format!("expected {expected}")
        };
        Diagnostic::new(format!("invalid TOML: {what}")).at(span, label)
    };
    diagnostic.with_help(Some("see https://toml.io for the TOML syntax".into()))
}

/// Rewrites serde's messages (`unknown field`, `unknown variant`, `invalid type`, …) into ones
/// that name the key, its table, and the closest valid name.
// Long function: one arm per kind of serde message.
fn serde_error(err: &toml::de::Error, doc: &Document<String>) -> Diagnostic {
    let message = err.message();
    let span = err.span().unwrap_or(0..0);
    let names = ticked(message);
    // `missing field` points at the table (or, for the top level, at 0..0 inside the first
    // key), so its key path is the table's.
    let path = if span.is_empty() {
        Vec::new()
    } else {
        path_at(doc.as_item(), &span)
    };
    let path: Vec<&str> = path.iter().map(String::as_str).collect();
    let key = dotted(&path);

    if let Some(d) = transform_error(message, &names, &span, doc) {
        return d;
    }
    if message.starts_with("unknown field") {
        let (given, valid) = names.split_first().unwrap_or((&"", &[]));
        let table = &path[..path.len().saturating_sub(1)];
        return Diagnostic::new(format!("unknown key `{given}` {}", in_table(table)))
            .at(span, "unknown key")
            .with_help(did_you_mean(given, valid, "key"));
    }
    if message.starts_with("unknown variant") {
        let (given, valid) = names.split_first().unwrap_or((&"", &[]));
        return Diagnostic::new(format!("unknown value `{given}`{}", for_key(&key)))
            .at(span, "unknown value")
            .with_help(did_you_mean(given, valid, "value"));
    }
    if message.starts_with("missing field") {
        let field = names.first().copied().unwrap_or("");
        let mut full = path.clone();
        full.push(field);
        let help = reference::lookup(&full)
            .filter(|doc| !doc.description.is_empty())
            .map(|doc| {
                // Written the way it would appear in the file: `[output]` or `source.path`.
                let name = if doc.ty.starts_with("table") {
                    format!("[{}]", dotted(&full))
                } else {
                    dotted(&full)
                };
                format!("`{name}`: {}", doc.description.replace('\n', " "))
            });
        let place = if path.is_empty() {
            "at the top level"
        } else {
            "in this table"
        };
        return Diagnostic::new(format!("missing key `{field}` {}", in_table(&path)))
            .at(span, format!("`{field}` is missing {place}"))
            .with_help(help);
    }
    if let Some(rest) = message.strip_prefix("invalid type: ") {
        let (found, expected) = rest.split_once(", expected ").unwrap_or((rest, ""));
        let expected = describe_expected(expected);
        return Diagnostic::new(format!(
            "wrong type{}: expected {expected}, found {}",
            for_key(&key),
            describe_found(found)
        ))
        .at(span, format!("expected {expected}"));
    }
    if let Some(rest) = message.strip_prefix("invalid value: ") {
        let (found, expected) = rest.split_once(", expected ").unwrap_or((rest, ""));
        let found = names.first().copied().unwrap_or(found);
        let expected = match describe_expected(expected) {
            e if e.contains("non-negative") && !found.starts_with('-') => {
                "a smaller integer".into()
            }
            e => e,
        };
        return Diagnostic::new(format!(
            "invalid value{}: expected {expected}, found `{found}`",
            for_key(&key)
        ))
        .at(span, format!("expected {expected}"));
    }
    // toml's own message for an enum given something other than a string.
    if message == "wanted string or table" {
        let allowed: Vec<String> = reference::lookup(&path)
            .map(|doc| doc.allowed.into_iter().map(|(v, _)| v).collect())
            .unwrap_or_default();
        let allowed: Vec<&str> = allowed.iter().map(String::as_str).collect();
        let help = (!allowed.is_empty()).then(|| format!("valid values: {}", backticked(&allowed)));
        return Diagnostic::new(format!("wrong type{}: expected a string", for_key(&key)))
            .at(span, "expected a string")
            .with_help(help);
    }
    let label = if key.is_empty() {
        String::new()
    } else {
        format!("in `{key}`")
    };
    Diagnostic::new(message.to_string()).at(span, label)
}

/// " for `profiles.act.chunk`", or nothing when the error is not inside a key.
fn for_key(key: &str) -> String {
    if key.is_empty() {
        String::new()
    } else {
        format!(" for `{key}`")
    }
}

/// The `ticked` names in a serde message, in order.
fn ticked(message: &str) -> Vec<&str> {
    message.split('`').skip(1).step_by(2).collect()
}

fn describe_expected(serde: &str) -> String {
    match serde {
        "u8" | "u16" | "u32" | "u64" | "usize" => "a non-negative integer".into(),
        "i8" | "i16" | "i32" | "i64" | "isize" => "an integer".into(),
        "f32" | "f64" => "a number".into(),
        "a map" | "map" => "a table".into(),
        "a sequence" => "an array".into(),
        s if s.starts_with("struct ") => "a table".into(),
        s => s.into(),
    }
}

/// An unknown key or value inside a `[[profiles.<name>.transforms]]` table: serde reads the
/// table whole (its `op` picks the type) and points at the array's header, so the key is found
/// here and named with the table's index (`profiles.x.transforms[1].from`). `span` is kept for
/// a table that holds no such key (the diagnostic then underlines what serde did).
fn transform_error(
    message: &str,
    names: &[&str],
    span: &Range<usize>,
    doc: &Document<String>,
) -> Option<Diagnostic> {
    let field = message.starts_with("unknown field");
    if !field && !message.starts_with("unknown variant") {
        return None;
    }
    let (given, valid) = names.split_first()?;
    let profiles = doc.as_table().get("profiles")?.as_table_like()?;
    for (profile, item) in profiles.iter() {
        let Some(tables) = item
            .as_table_like()
            .and_then(|t| t.get("transforms"))
            .and_then(Item::as_array_of_tables)
        else {
            continue;
        };
        // serde points at the array's first header or at the value: the table is the one
        // holding the key (or the value) it names.
        for (i, table) in tables.iter().enumerate() {
            let Some((key, value)) = table.iter().find(|(k, v)| {
                if field {
                    k == given
                } else {
                    v.as_str() == Some(given)
                }
            }) else {
                continue;
            };
            let at = if field {
                table.key(key).and_then(|k| k.span())
            } else {
                value.span()
            };
            let place = format!("profiles.{profile}.transforms[{i}]");
            let (text, label, kind) = if field {
                (
                    format!("{place}: unknown key `{given}`"),
                    "unknown key",
                    "key",
                )
            } else {
                (
                    format!("{place}.{key}: unknown value `{given}`"),
                    "unknown value",
                    "value",
                )
            };
            return Some(
                Diagnostic::new(text)
                    .at(at.unwrap_or(span.clone()), label)
                    .with_help(did_you_mean(given, valid, kind)),
            );
        }
    }
    None
}

/// serde's `Unexpected` as a TOML user would say it.
fn describe_found(serde: &str) -> String {
    let kinds = [
        ("string", "a string"),
        ("integer", "an integer"),
        ("unsigned integer", "an integer"),
        ("floating point", "a float"),
        ("boolean", "a boolean"),
        ("map", "a table"),
        ("sequence", "an array"),
    ];
    kinds
        .iter()
        .find(|(prefix, _)| serde.starts_with(prefix))
        .map_or_else(|| serde.to_string(), |(_, said)| said.to_string())
}

/// The first `[[array.of.tables]]` other than `[[profiles.<name>.transforms]]`, the spec's only
/// one: always a typo for `[table]`.
fn array_of_tables(item: &Item, path: &mut Vec<String>) -> Option<Diagnostic> {
    let transforms = path.len() == 3 && path[0] == "profiles" && path[2] == "transforms";
    if transforms {
        return None;
    }
    if let Some(array) = item.as_array_of_tables() {
        let header = dotted(&path.iter().map(String::as_str).collect::<Vec<_>>());
        let span = array.get(0).and_then(|t| t.span()).unwrap_or(0..0);
        let message = format!("`[[{header}]]` is an array of tables, which a spec never has");
        let help = Some(format!("use single brackets: `[{header}]`"));
        return Some(
            Diagnostic::new(message)
                .at(span, "double brackets")
                .with_help(help),
        );
    }
    for (name, inner) in item.as_table_like()?.iter() {
        path.push(name.to_string());
        let found = array_of_tables(inner, path);
        path.pop();
        if found.is_some() {
            return found;
        }
    }
    None
}

/// The deepest key whose name or value contains `span`.
fn path_at(root: &Item, span: &Range<usize>) -> Vec<String> {
    fn walk(
        table: &dyn TableLike,
        span: &Range<usize>,
        path: &mut Vec<String>,
        best: &mut Vec<String>,
    ) {
        let contains =
            |r: Option<Range<usize>>| r.is_some_and(|r| r.start <= span.start && span.end <= r.end);
        for (name, item) in table.iter() {
            let key_span = table.get_key_value(name).and_then(|(k, _)| k.span());
            path.push(name.to_string());
            if (contains(key_span) || contains(item.span())) && path.len() > best.len() {
                *best = path.clone();
            }
            if let Some(inner) = item.as_table_like() {
                walk(inner, span, path, best);
            }
            for inner in item.as_array_of_tables().into_iter().flat_map(|a| a.iter()) {
                walk(inner, span, path, best);
            }
            path.pop();
        }
    }
    let mut best = Vec::new();
    if let Some(table) = root.as_table_like() {
        walk(table, span, &mut Vec::new(), &mut best);
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPEC: &str = r#"version = 1

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

    fn parse(text: &str) -> Result<LoadedSpec> {
        LoadedSpec::parse("t.toml", text, Path::new("specs"))
    }

    #[test]
    fn broken_toml_is_an_error_not_a_panic() {
        // Found by the `spec` fuzz target: toml_edit 0.23 panicked ("all items have spans") on
        // this; 0.25 reports it.
        for text in ["={[]\n.", "\r"] {
            let err = LoadedSpec::parse("f.toml", text, Path::new(".")).unwrap_err();
            assert!(err.to_string().contains("invalid TOML"), "{err}");
        }
    }

    #[test]
    fn loads_and_expands_in_name_order() {
        let loaded = parse(SPEC).unwrap();
        let names: Vec<_> = loaded.profiles.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["act", "dp"]);
        assert_eq!(loaded.profiles[0].chunk, 20);
        assert_eq!(
            loaded.resolve("data/x.zarr"),
            Path::new("specs/data/x.zarr")
        );
        assert_eq!(loaded.file, Path::new("t.toml"));
    }

    #[test]
    fn hash_ignores_comments_and_layout() {
        let a = parse(SPEC).unwrap().hash;
        let reformatted = SPEC.replace("fps = 10", "# the recording rate\nfps   =   10.0");
        assert_eq!(parse(&reformatted).unwrap().hash, a);
        let changed = SPEC.replace("chunk = 20", "chunk = 21");
        assert_ne!(parse(&changed).unwrap().hash, a);
        assert_eq!(a.len(), 64);
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

    #[test]
    fn serde_messages_are_rewritten() {
        let err = parse(&SPEC.replace("chunk = 20", "chunk = -3"))
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("error: invalid value for `profiles.act.chunk`: expected a non-negative integer, found `-3`"), "{err}");
        let err = parse(&SPEC.replace("chunk = 20", "padding = 3"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("valid values: `edge`, `zero`, `mask`, `truncate`"),
            "{err}"
        );
        let err = parse(&SPEC.replace("path = \"data/x.zarr\"\n", ""))
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("error: missing key `path` in `[source]`"),
            "{err}"
        );
        assert!(err.contains("t.toml:3:1"), "{err}");
    }
}
