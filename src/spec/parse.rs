//! Reading a spec: TOML text → spanned document → typed [`Spec`] → validated, expanded profiles
//! ([`LoadedSpec::load`], [`LoadedSpec::parse`]). A TOML syntax error, and any message of
//! serde's ([`super::serde_error`]), becomes a diagnostic that names the key.

use std::ops::Range;
use std::path::{Path, PathBuf};

use toml_edit::Document;

use super::diagnostic::Diagnostic;
use super::load::{render_all, LoadedSpec};
use super::model::Spec;
use super::serde_error::{array_of_tables, serde_error};
use super::validate;
use crate::error::{Error, Result};

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

#[cfg(test)]
mod tests {
    use super::super::load::tests::{parse, SPEC};
    use super::*;

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
