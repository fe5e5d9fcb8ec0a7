//! serde's errors, rewritten as diagnostics that name the key, its table and the closest valid
//! name (`unknown field`, `unknown variant`, `missing field`, `invalid type`, …), and the
//! `[[array.of.tables]]` typo serde misreads.

use std::ops::Range;

use toml_edit::{Document, Item, TableLike};

use super::diagnostic::{backticked, did_you_mean, Diagnostic};
use super::load::dotted;
use super::reference;

/// Rewrites serde's messages (`unknown field`, `unknown variant`, `invalid type`, …) into ones
/// that name the key, its table, and the closest valid name.
// Long function: one arm per kind of serde message.
pub(super) fn serde_error(err: &toml::de::Error, doc: &Document<String>) -> Diagnostic {
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
pub(super) fn array_of_tables(item: &Item, path: &mut Vec<String>) -> Option<Diagnostic> {
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

/// "in `[profiles.act]`" or "at the top level", for the table that holds a key.
fn in_table(table: &[&str]) -> String {
    if table.is_empty() {
        "at the top level".into()
    } else {
        format!("in `[{}]`", dotted(table))
    }
}
