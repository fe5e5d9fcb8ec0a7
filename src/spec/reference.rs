//! The spec reference, read from the JSON Schema so that it cannot drift from the types.
//!
//! [`markdown`] is the book's `reference/spec.md` (`tests/schema.rs` fails when the checked-in
//! copy is stale); [`lookup`] gives diagnostics a key's allowed values and description.

use std::fmt::Write;

use serde_json::Value;

/// One key as documented.
#[derive(Debug, Clone, PartialEq)]
pub struct KeyDoc {
    /// Dotted path with `<name>` for the keys a user chooses, e.g. `profiles.<name>.chunk`.
    pub path: String,
    pub ty: String,
    pub required: bool,
    /// The default as TOML, when the schema gives one for a plain value.
    pub default: Option<String>,
    /// `(value, description)` for enumerations.
    pub allowed: Vec<(String, String)>,
    pub description: String,
}

/// One TOML table: `[source]`, `[profiles.<name>]`, …
#[derive(Debug, Clone, PartialEq)]
pub struct TableDoc {
    /// `[source]`; empty for the top level.
    pub header: String,
    pub description: String,
    pub keys: Vec<KeyDoc>,
    /// For tables whose keys the user names (`[source.channels]`): what each value is.
    pub entries: Option<KeyDoc>,
}

fn schema() -> Value {
    serde_json::from_str(&super::json_schema()).expect("the schema is JSON")
}

/// Follows `$ref` and drops the `null` that schemars adds for `Option`, keeping the outer
/// node's description (the field's doc comment) over the type's.
fn resolve<'a>(node: &'a Value, root: &'a Value) -> &'a Value {
    if let Some(r) = node.get("$ref").and_then(Value::as_str) {
        let name = r.trim_start_matches("#/$defs/");
        return resolve(&root["$defs"][name], root);
    }
    if let Some(any) = node.get("anyOf").and_then(Value::as_array) {
        let is_null = |v: &&Value| v.get("type") == Some(&"null".into());
        // `Option<T>` is `anyOf [T, null]`; a real choice (a string or a table) stays a choice.
        if any.iter().any(|v| is_null(&v)) {
            if let Some(inner) = any.iter().find(|v| !is_null(v)) {
                return resolve(inner, root);
            }
        }
    }
    node
}

/// The types of a choice (`anyOf`), each resolved.
fn variants<'a>(node: &'a Value, root: &'a Value) -> Vec<String> {
    node.get("anyOf")
        .and_then(Value::as_array)
        .map(|any| {
            any.iter()
                .map(|v| type_name(resolve(v, root), root))
                .collect()
        })
        .unwrap_or_default()
}

fn description(node: &Value) -> String {
    node.get("description")
        .and_then(Value::as_str)
        .unwrap_or("")
        .to_string()
}

fn types(node: &Value) -> Vec<&str> {
    match node.get("type") {
        Some(Value::String(t)) => vec![t.as_str()],
        Some(Value::Array(ts)) => ts.iter().filter_map(Value::as_str).collect(),
        _ => Vec::new(),
    }
}

fn is_table(node: &Value) -> bool {
    types(node).contains(&"object")
}

fn allowed(node: &Value) -> Vec<(String, String)> {
    if let Some(values) = node.get("enum").and_then(Value::as_array) {
        return values
            .iter()
            .filter_map(Value::as_str)
            .map(|v| (v.to_string(), String::new()))
            .collect();
    }
    let one_of = node.get("oneOf").and_then(Value::as_array);
    one_of
        .into_iter()
        .flatten()
        .filter_map(|v| Some((v.get("const")?.as_str()?.to_string(), description(v))))
        .collect()
}

fn type_name(node: &Value, root: &Value) -> String {
    if node.get("enum").is_some() || node.get("oneOf").is_some() {
        return "string".into();
    }
    let choice = variants(node, root);
    if !choice.is_empty() {
        return choice.join(" or ");
    }
    let ty = types(node);
    let ty = ty.iter().find(|&&t| t != "null").copied().unwrap_or("any");
    match ty {
        "object" => match node.get("additionalProperties") {
            Some(v @ Value::Object(_)) if node.get("properties").is_none() => {
                let inner = resolve(v, root);
                let choice = variants(inner, root);
                if inner.get("properties").is_some() {
                    "table of tables".into()
                } else if !choice.is_empty() {
                    let plural: Vec<String> = choice.iter().map(|c| format!("{c}s")).collect();
                    format!("table of {}", plural.join(" or "))
                } else {
                    let inner = type_name(inner, root);
                    match inner.ends_with('s') {
                        true => format!("table of {inner}"),
                        false => format!("table of {inner}s"),
                    }
                }
            }
            _ => "table".into(),
        },
        "number" => "number".into(),
        "integer" => "integer".into(),
        "boolean" => "boolean".into(),
        "array" => "array".into(),
        other => other.into(),
    }
}

fn toml_literal(v: &Value) -> Option<String> {
    match v {
        Value::String(s) => Some(format!("{s:?}")),
        Value::Number(n) => Some(n.to_string()),
        Value::Bool(b) => Some(b.to_string()),
        _ => None,
    }
}

fn key_doc(path: String, field: &Value, required: bool, root: &Value) -> KeyDoc {
    let node = resolve(field, root);
    let mut description = description(field);
    if description.is_empty() {
        description = self::description(node);
    }
    KeyDoc {
        path,
        ty: type_name(node, root),
        required,
        default: field.get("default").and_then(toml_literal),
        allowed: allowed(node),
        description,
    }
}

fn join(path: &str, key: &str) -> String {
    if path.is_empty() {
        key.to_string()
    } else {
        format!("{path}.{key}")
    }
}

/// Every table of the spec, depth first, in the schema's (= the struct's) key order.
pub fn tables() -> Vec<TableDoc> {
    let root = schema();
    let mut out = Vec::new();
    collect("", &root, &root, &mut out);
    out
}

fn collect(path: &str, field: &Value, root: &Value, out: &mut Vec<TableDoc>) {
    let node = resolve(field, root);
    let header = if path.is_empty() {
        String::new()
    } else {
        format!("[{path}]")
    };
    // A type's own doc comment describes the table; fall back to the field's.
    let mut table_description = description(node);
    if table_description.is_empty() || path.is_empty() {
        table_description = description(field);
    }
    if let Some(props) = node.get("properties").and_then(Value::as_object) {
        let required = required_keys(node);
        let keys = props
            .iter()
            .map(|(k, v)| key_doc(join(path, k), v, required.contains(&k.as_str()), root))
            .collect();
        out.push(TableDoc {
            header,
            description: table_description,
            keys,
            entries: None,
        });
        for (k, v) in props {
            if is_table(resolve(v, root)) {
                collect(&join(path, k), v, root, out);
            }
        }
    } else if let Some(inner @ Value::Object(_)) = node.get("additionalProperties") {
        let named = join(path, "<name>");
        if is_table(resolve(inner, root)) {
            // `[profiles.<name>]`: the user names the tables; document their shape.
            collect(&named, inner, root, out);
        } else {
            out.push(TableDoc {
                header,
                description: table_description,
                keys: Vec::new(),
                entries: Some(key_doc(named, inner, false, root)),
            });
        }
    }
}

fn required_keys(node: &Value) -> Vec<&str> {
    let required = node.get("required").and_then(Value::as_array);
    required
        .into_iter()
        .flatten()
        .filter_map(Value::as_str)
        .collect()
}

/// The documentation of the key at `path` (table names as written, e.g. `["profiles", "act",
/// "padding"]`), or `None` when the schema has no such key.
pub fn lookup(path: &[&str]) -> Option<KeyDoc> {
    let root = schema();
    let mut field = &root;
    let mut required = true;
    for key in path {
        let node = resolve(field, &root);
        if let Some(f) = node.get("properties").and_then(|p| p.get(*key)) {
            required = required_keys(node).contains(key);
            field = f;
        } else if let Some(f @ Value::Object(_)) = node.get("additionalProperties") {
            required = false;
            field = f;
        } else {
            return None;
        }
    }
    Some(key_doc(path.join("."), field, required, &root))
}

/// The book's spec reference chapter.
pub fn markdown() -> String {
    let root = schema();
    let mut md = String::new();
    md.push_str(
        "<!-- Generated from the spec's JSON Schema by `tests/schema.rs`. Do not edit: run\n     \
         `CHUNKC_BLESS=1 cargo test --release --test schema` after changing `src/spec/model.rs`. -->\n\n",
    );
    md.push_str("# Spec reference\n\n");
    let _ = write!(
        md,
        "{}\n\nPaths are relative to the spec file. The same information as a JSON Schema is in \
         [`spec.schema.json`](spec.schema.json), and `chunkc schema` prints it.\n",
        description(&root)
    );
    for table in tables() {
        write_table(&mut md, &table);
    }
    md
}

fn write_table(md: &mut String, table: &TableDoc) {
    if table.header.is_empty() {
        md.push_str("\n## Top level\n\n");
    } else {
        let _ = write!(md, "\n## `{}`\n\n", table.header);
        let _ = writeln!(
            md,
            "{}\n",
            without_header(&table.description, &table.header)
        );
    }
    if let Some(entry) = &table.entries {
        let _ = writeln!(md, "Each entry is `<name> = <{}>`.", entry.ty);
        write_allowed(md, &entry.allowed);
        return;
    }
    md.push_str("| Key | Type | Default |\n|-----|------|---------|\n");
    for key in &table.keys {
        let name = key.path.rsplit('.').next().unwrap_or(&key.path);
        let _ = writeln!(md, "| `{name}` | {} | {} |", key.ty, default_cell(key));
    }
    for key in &table.keys {
        let _ = write!(md, "\n### `{}`\n\n", key.path);
        let _ = writeln!(md, "*{}, {}*\n", key.ty, default_cell(key));
        if !key.description.is_empty() {
            let _ = writeln!(md, "{}", key.description);
        }
        write_allowed(md, &key.allowed);
    }
}

/// The types' doc comments open with "`[source]`: the dataset …" for readers of the code; under
/// a `[source]` heading that prefix only repeats it.
fn without_header(description: &str, header: &str) -> String {
    let Some(rest) = description.strip_prefix(&format!("`{header}`: ")) else {
        return description.to_string();
    };
    let mut chars = rest.chars();
    chars.next().map_or_else(String::new, |first| {
        first.to_uppercase().chain(chars).collect()
    })
}

fn default_cell(key: &KeyDoc) -> String {
    match (&key.default, key.required) {
        (Some(d), _) => format!("default `{d}`"),
        (None, true) => "required".into(),
        (None, false) => "optional".into(),
    }
}

fn write_allowed(md: &mut String, allowed: &[(String, String)]) {
    if allowed.is_empty() {
        return;
    }
    md.push_str("\nAllowed values:\n\n");
    for (value, doc) in allowed {
        if doc.is_empty() {
            let _ = writeln!(md, "- `\"{value}\"`");
        } else {
            let _ = writeln!(md, "- `\"{value}\"`: {}", doc.replace('\n', " "));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookup_follows_refs_and_maps() {
        let padding = lookup(&["profiles", "act", "padding"]).unwrap();
        let values: Vec<_> = padding.allowed.iter().map(|(v, _)| v.as_str()).collect();
        assert_eq!(values, ["edge", "zero", "mask", "truncate"]);
        let mode = lookup(&["profiles", "act", "normalize", "action"]).unwrap();
        assert_eq!(mode.allowed.len(), 10);
        let path = lookup(&["source", "path"]).unwrap();
        assert!(path.required);
        assert_eq!(path.ty, "string");
        assert!(lookup(&["source", "nope"]).is_none());
    }

    #[test]
    fn every_table_is_documented() {
        let headers: Vec<_> = tables().into_iter().map(|t| t.header).collect();
        assert_eq!(
            headers,
            [
                "",
                "[source]",
                "[source.channels]",
                "[sources.<name>]",
                "[sources.<name>.channels]",
                "[mixture]",
                "[mixture.pad_to]",
                "[split]",
                "[audit]",
                "[audit.doctor]",
                "[output]",
                "[build]",
                "[profiles.<name>]",
                "[profiles.<name>.normalize]",
                "[profiles.<name>.export_keys]",
                "[profiles.<name>.modality.<name>]",
                "[profiles.<name>.segment]",
                "[profiles.<name>.hierarchy]",
                "[profiles.<name>.cameras.<name>]",
            ]
        );
    }
}
