//! The JSON Schema and the book's spec reference are generated from `src/spec/model.rs` and
//! checked in; these tests fail when either is stale. Regenerate both with
//!
//! ```text
//! CHUNKC_BLESS=1 cargo test --release --test schema
//! ```

use std::fs;
use std::path::Path;

use chunkc::spec::{json_schema, reference};

const REGENERATE: &str = "CHUNKC_BLESS=1 cargo test --release --test schema";

/// Passes when `rel` holds `expected`; rewrites it under `CHUNKC_BLESS=1`, fails otherwise.
fn check_generated(rel: &str, expected: &str) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(rel);
    let actual = fs::read_to_string(&path).unwrap_or_default();
    if actual == expected {
        return;
    }
    if std::env::var_os("CHUNKC_BLESS").is_some_and(|v| v == "1") {
        fs::create_dir_all(path.parent().unwrap()).unwrap();
        fs::write(&path, expected).unwrap();
        eprintln!("wrote {rel}");
        return;
    }
    let first_difference = actual
        .lines()
        .zip(expected.lines())
        .position(|(a, e)| a != e)
        .map_or_else(
            || "at the end".to_string(),
            |i| format!("at line {}", i + 1),
        );
    panic!(
        "{rel} is stale (first difference {first_difference}); regenerate it with `{REGENERATE}`"
    );
}

#[test]
fn json_schema_is_current() {
    check_generated("book/src/reference/spec.schema.json", &json_schema());
}

#[test]
fn spec_reference_is_current() {
    check_generated("book/src/reference/spec.md", &reference::markdown());
}

/// The reference must cover every key a user can write, or it is not a reference.
#[test]
fn spec_reference_names_every_key() {
    let md = reference::markdown();
    for table in reference::tables() {
        for key in &table.keys {
            assert!(
                md.contains(&format!("### `{}`", key.path)),
                "{} is undocumented",
                key.path
            );
            assert!(
                !key.description.is_empty(),
                "{} has no doc comment in model.rs",
                key.path
            );
        }
    }
}
