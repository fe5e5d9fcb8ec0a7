//! Size limits of `src/`, with their escape written where the code is: a file over 400 lines
//! starts with `// Long file: <why>.`, a function over 80 lines has `// Long function: <why>.` on
//! the line above its `fn`. A long file or function is usually two concepts; the reason says why
//! this one is not.

use std::path::Path;

mod common;
use common::rust_files;

const FILE_LINES: usize = 400;
const FN_LINES: usize = 80;

/// `(line of the fn, its name, its length in lines)` for every function with a body.
fn functions(lines: &[&str]) -> Vec<(usize, String, usize)> {
    let mut found = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let body = line.trim_start();
        let indent = &line[..line.len() - body.len()];
        let body = body
            .strip_prefix("pub(crate) ")
            .or_else(|| body.strip_prefix("pub(super) "))
            .or_else(|| body.strip_prefix("pub "))
            .unwrap_or(body);
        let Some(rest) = body.strip_prefix("fn ") else {
            continue;
        };
        let name: String = rest
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        // The signature ends at the first `{` (a body) or `;` (a trait's declaration).
        let Some(open) = lines[i..]
            .iter()
            .position(|l| l.contains('{') || l.trim_end().ends_with(';'))
            .map(|k| i + k)
        else {
            continue;
        };
        let depth: i64 = lines[i..=open]
            .iter()
            .map(|l| l.matches('{').count() as i64 - l.matches('}').count() as i64)
            .sum();
        if depth <= 0 {
            continue; // a declaration, or a body on one line
        }
        let close = format!("{indent}}}");
        let Some(end) = lines[open + 1..].iter().position(|l| l.trim_end() == close) else {
            continue;
        };
        let end = open + 1 + end - i;
        found.push((i, name, end + 1));
    }
    found
}

fn offences(src: &Path) -> Vec<String> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    files.sort();
    let mut found = Vec::new();
    for file in files {
        let text = std::fs::read_to_string(&file).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let shown = file.strip_prefix(src).unwrap().display();
        if lines.len() > FILE_LINES && !lines[0].starts_with("// Long file: ") {
            found.push(format!(
                "src/{shown}: {} lines and no `// Long file: <why>.` on line 1",
                lines.len()
            ));
        }
        for (at, name, len) in functions(&lines) {
            let above = at.checked_sub(1).map_or("", |k| lines[k].trim_start());
            if len > FN_LINES && !above.starts_with("// Long function: ") {
                found.push(format!(
                    "src/{shown}:{}: fn {name} is {len} lines and has no `// Long function: <why>.` above it",
                    at + 1
                ));
            }
        }
    }
    found
}

#[test]
fn long_files_and_functions_say_why() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let found = offences(&src);
    assert!(found.is_empty(), "{}", found.join("\n"));
}

#[test]
fn a_long_function_without_a_reason_is_caught() {
    let dir = tempfile::tempdir().unwrap();
    let long = |reason: &str| {
        let body = "    let x = 1;\n".repeat(FN_LINES);
        format!("{reason}pub fn big() {{\n{body}}}\n\npub trait T {{\n    fn f(&self);\n}}\n")
    };
    std::fs::write(dir.path().join("a.rs"), long("")).unwrap();
    std::fs::write(
        dir.path().join("b.rs"),
        long("// Long function: a table.\n"),
    )
    .unwrap();
    std::fs::write(
        dir.path().join("c.rs"),
        "fn x() {}\n".repeat(FILE_LINES + 1),
    )
    .unwrap();
    let found = offences(dir.path());
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(
        found[0].starts_with("src/a.rs:1: fn big is 82 lines"),
        "{found:?}"
    );
    assert!(found[1].starts_with("src/c.rs: 401 lines"), "{found:?}");
}
