//! The layering rule of `src/lib.rs`, enforced: a module imports only from stages before it and
//! from the leaf modules. Every `crate::<module>` path in `src/` is checked against the order
//! below (which `lib.rs` states); an upward import, or a module missing from the order, fails
//! with the file and line.

use std::path::Path;

mod common;
use common::rust_files;

/// The order, lowest first. Leaf modules (rank 0) may be used by anything; a stage may use the
/// leaves and every stage before it, never one after it.
const LAYERS: &[(&str, u32)] = &[
    // leaves
    ("error", 0),
    ("bytes", 0),
    ("store", 0),
    ("timings", 0),
    ("files", 0),
    ("recycle", 0),
    ("resize", 0),
    ("rotation", 0),
    // the pipeline, in order
    ("spec", 1),
    ("source", 2),
    ("audit", 3),
    ("lock", 4),
    ("window", 5),
    ("transform", 5),
    ("plan", 6),
    ("stats", 7),
    ("sink", 8),
    ("render", 9),
    ("exec", 10),
    // beside the pipeline
    ("analyze", 11),
    ("report", 12),
    ("synth", 12),
    ("fuzzing", 12),
    ("init", 12),
    // the command drivers, on top
    ("commands", 13),
];

fn rank(module: &str) -> Option<u32> {
    LAYERS.iter().find(|(m, _)| *m == module).map(|&(_, r)| r)
}

/// The top-level module a file of `src/` belongs to (`None` for lib.rs and main.rs).
fn owner(src: &Path, file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src).unwrap();
    let first = rel
        .components()
        .next()?
        .as_os_str()
        .to_string_lossy()
        .into_owned();
    let name = first.trim_end_matches(".rs").to_string();
    (name != "lib" && name != "main").then_some(name)
}

/// Every `crate::<module>` a line names, with `use crate::{a, b::c}` groups expanded.
fn named_modules(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let code = line.split("//").next().unwrap_or("");
    let mut rest = code;
    while let Some(i) = rest.find("crate::") {
        rest = &rest[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let end = group.find('}').unwrap_or(group.len());
            for item in group[..end].split(',') {
                let name: String = item
                    .trim()
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    out.push(name);
                }
            }
        } else {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                out.push(name);
            }
        }
    }
    out
}

/// Re-exports at the crate root (`crate::Result`, `crate::Error`) belong to `error`.
fn resolve(name: &str) -> &str {
    match name {
        "Result" | "Error" => "error",
        other => other,
    }
}

fn violations(src: &Path) -> Vec<String> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    files.sort();
    let mut found = Vec::new();
    for file in &files {
        let Some(module) = owner(src, file) else {
            continue;
        };
        let Some(own) = rank(&module) else {
            found.push(format!(
                "{}: module `{module}` is not in the layer order (tests/layering.rs, src/lib.rs)",
                file.display()
            ));
            continue;
        };
        let text = std::fs::read_to_string(file).unwrap();
        for (n, line) in text.lines().enumerate() {
            for name in named_modules(line) {
                let target = resolve(&name);
                if target == module {
                    continue;
                }
                match rank(target) {
                    None => found.push(format!(
                        "{}:{}: `crate::{name}` is not a module in the layer order",
                        file.display(),
                        n + 1
                    )),
                    Some(r) if r != 0 && r >= own => found.push(format!(
                        "{}:{}: `{module}` (layer {own}) imports `{target}` (layer {r}): stages import only from earlier stages and leaves",
                        file.display(),
                        n + 1
                    )),
                    Some(_) => {}
                }
            }
        }
    }
    found
}

#[test]
fn stages_import_only_downward() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let found = violations(&src);
    assert!(
        found.is_empty(),
        "layering violations:\n{}",
        found.join("\n")
    );
}

#[test]
fn lib_rs_states_the_same_order() {
    let lib =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs")).unwrap();
    for (module, _) in LAYERS {
        assert!(
            lib.contains(&format!("pub mod {module};")),
            "lib.rs declares no module `{module}`"
        );
        assert!(
            lib.contains(&format!("[`{module}`]")),
            "lib.rs's map does not name `{module}`"
        );
    }
    // The map lists the stages in the order above.
    let at = |m: &str| lib.find(&format!("[`{m}`]")).unwrap();
    let stages: Vec<&str> = LAYERS
        .iter()
        .filter(|(_, r)| (1..=10).contains(r))
        .map(|(m, _)| *m)
        .collect();
    for pair in stages.windows(2) {
        assert!(
            at(pair[0]) < at(pair[1]),
            "lib.rs names `{}` after `{}`",
            pair[0],
            pair[1]
        );
    }
}

#[test]
fn an_upward_import_is_caught() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    std::fs::create_dir_all(src.join("source")).unwrap();
    std::fs::write(src.join("source/mod.rs"), "use crate::spec::Spec;\n").unwrap();
    std::fs::write(src.join("spec.rs"), "use crate::{error, plan::Plan};\n").unwrap();
    let found = violations(src);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        found[0].contains("spec.rs:1") && found[0].contains("imports `plan`"),
        "{found:?}"
    );
}

#[test]
fn the_books_architecture_page_names_every_module() {
    let page = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("book/src/architecture.md"),
    )
    .unwrap();
    let diagram = &page[page.find("```text").unwrap()..];
    let diagram = &diagram[..diagram[7..].find("```").unwrap() + 7];
    for (module, _) in LAYERS {
        assert!(
            page.contains(&format!("| `{module}` |")),
            "book/src/architecture.md: the table has no row for `{module}`"
        );
        assert!(
            diagram
                .split(|c: char| !c.is_alphanumeric() && c != '_')
                .any(|w| w == *module),
            "book/src/architecture.md: the stage diagram does not name `{module}`"
        );
    }
    // The diagram's pipeline line lists the stages in the order above.
    let line = diagram.lines().find(|l| l.starts_with("spec ")).unwrap();
    let names: Vec<&str> = line.split(" ─▶ ").map(str::trim).collect();
    let stages: Vec<&str> = LAYERS
        .iter()
        .filter(|(_, r)| (1..=10).contains(r))
        .map(|(m, _)| *m)
        .collect();
    assert_eq!(names, stages, "book/src/architecture.md: the pipeline line");
}
