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
    ("templates", 0),
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

// No import circles between files.
//
// The layering above orders the top-level modules; inside them, files import one another too,
// and two files that import each other are one concept split in two (or two concepts tangled
// into one). The check below builds the graph of file-to-file imports inside `src/` and fails on
// every circle, naming its files and the lines that close it.
//
// An edge is a path that names something in another file: `crate::a::b::…`, `super::…`,
// `self::…`, a child module's name (`roles::assign`), in a `use` (groups expanded) or in the
// code. It points at the file that defines the deepest module the path names: `crate::spec::Spec`
// at `spec/mod.rs`, `super::roles::KeyRole` at `roles.rs`. Not edges: `mod child;` (declaring a
// child is not using it), and a path up to a module enclosing the file (its folder's `mod.rs`,
// `lib.rs`): a folder's `mod.rs` declares and re-exports its children and holds what they share,
// so its children naming it is the tree read upwards, not a circle.

use std::collections::{BTreeMap, BTreeSet};

/// The text with every comment, string and character literal blanked (newlines kept), so that
/// only code is searched for paths.
fn code_only(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let blank = |c: char| if c == '\n' { '\n' } else { ' ' };
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        let after_ident = i > 0 && (chars[i - 1].is_alphanumeric() || chars[i - 1] == '_');
        let end = if c == '/' && next == Some('/') {
            (i..chars.len())
                .find(|&k| chars[k] == '\n')
                .unwrap_or(chars.len())
        } else if c == '/' && next == Some('*') {
            let (mut depth, mut k) = (0, i);
            while k < chars.len() {
                if chars[k] == '/' && chars.get(k + 1) == Some(&'*') {
                    depth += 1;
                    k += 2;
                } else if chars[k] == '*' && chars.get(k + 1) == Some(&'/') {
                    depth -= 1;
                    k += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    k += 1;
                }
            }
            k
        } else if c == 'r' && !after_ident && matches!(next, Some('"' | '#')) {
            // A raw string: `r"…"`, `r#"…"#` (`br…` too: the `b` stays, an identifier).
            let hashes = chars[i + 1..].iter().take_while(|&&h| h == '#').count();
            if chars.get(i + 1 + hashes) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            let close: Vec<char> = std::iter::once('"')
                .chain(std::iter::repeat_n('#', hashes))
                .collect();
            let body = i + 2 + hashes;
            (body..chars.len())
                .find(|&k| chars[k..].starts_with(&close))
                .map_or(chars.len(), |k| k + close.len())
        } else if c == '"' {
            let mut k = i + 1;
            while k < chars.len() && chars[k] != '"' {
                k += if chars[k] == '\\' { 2 } else { 1 };
            }
            k + 1
        } else if c == '\'' && next == Some('\\') {
            // An escaped character literal: `'\n'`, `'\''`, `'\u{7f}'`.
            (i + 3..chars.len())
                .find(|&k| chars[k] == '\'')
                .map_or(chars.len(), |k| k + 1)
        } else if c == '\'' && chars.get(i + 2) == Some(&'\'') {
            i + 3 // `'x'` (a lifetime `'a` has no closing quote)
        } else {
            out.push(c);
            i += 1;
            continue;
        };
        let end = end.min(chars.len());
        out.extend(chars[i..end].iter().map(|&c| blank(c)));
        i = end;
    }
    out
}

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Ident(String),
    /// `::`
    Sep,
    Open,
    Close,
    Comma,
    Semi,
    Other,
}

/// The tokens of code (see [`code_only`]), each with its line.
fn tokens(code: &str) -> Vec<(Tok, usize)> {
    let chars: Vec<char> = code.chars().collect();
    let mut out = Vec::new();
    let (mut i, mut line) = (0, 1);
    while i < chars.len() {
        let c = chars[i];
        let tok = match c {
            '\n' => {
                line += 1;
                i += 1;
                continue;
            }
            c if c.is_whitespace() => {
                i += 1;
                continue;
            }
            // `$crate` (a macro's) is one word, never a path of this crate's files.
            c if c.is_alphabetic() || c == '_' || c == '$' => {
                let n = 1 + chars[i + 1..]
                    .iter()
                    .take_while(|c| c.is_alphanumeric() || **c == '_')
                    .count();
                let word: String = chars[i..i + n].iter().collect();
                i += n;
                out.push((Tok::Ident(word), line));
                continue;
            }
            ':' if chars.get(i + 1) == Some(&':') => {
                i += 2;
                out.push((Tok::Sep, line));
                continue;
            }
            '{' => Tok::Open,
            '}' => Tok::Close,
            ',' => Tok::Comma,
            ';' => Tok::Semi,
            _ => Tok::Other,
        };
        out.push((tok, line));
        i += 1;
    }
    out
}

/// The module a file of `src/` defines: `init/roles.rs` → `["init", "roles"]`, `spec/mod.rs` →
/// `["spec"]`, `lib.rs` → `[]`.
fn module_of(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .with_extension("")
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
        parts.pop();
    }
    parts
}

/// The paths the `use` tree `toks` names (`a::{b, c::d as e}` → `a::b`, `a::c::d`), under
/// `prefix`. `self` in a group names the group's module; a glob names the module it is in.
fn use_paths(toks: &[(Tok, usize)], prefix: &[String], out: &mut Vec<Vec<String>>) {
    let mut path = prefix.to_vec();
    let mut i = 0;
    while i < toks.len() {
        match &toks[i].0 {
            Tok::Ident(word) if word == "as" => break,
            Tok::Ident(word) if word == "self" && !path.is_empty() => {}
            Tok::Ident(word) => path.push(word.clone()),
            Tok::Open => {
                let mut depth = 0;
                let mut from = i + 1;
                for k in i..toks.len() {
                    match toks[k].0 {
                        Tok::Open => depth += 1,
                        Tok::Close => depth -= 1,
                        Tok::Comma if depth == 1 => {
                            use_paths(&toks[from..k], &path, out);
                            from = k + 1;
                        }
                        _ => {}
                    }
                    if depth == 0 {
                        use_paths(&toks[from..k], &path, out);
                        return;
                    }
                }
                return;
            }
            _ => {}
        }
        i += 1;
    }
    if path.len() > prefix.len() {
        out.push(path);
    }
}

/// A path a file names.
struct Named {
    /// The module it is written in: the file's, or an inline `mod x { … }` in it.
    at: Vec<String>,
    path: Vec<String>,
    line: usize,
}

/// Every path a file of module `module` names.
fn paths_in(text: &str, module: &[String]) -> Vec<Named> {
    let toks = tokens(&code_only(text));
    let ident = |k: usize| match toks.get(k) {
        Some((Tok::Ident(w), _)) => Some(w.as_str()),
        _ => None,
    };
    let mut out = Vec::new();
    let mut inline: Vec<(usize, String)> = Vec::new();
    let mut depth = 0;
    let mut i = 0;
    while i < toks.len() {
        let here: Vec<String> = module
            .iter()
            .cloned()
            .chain(inline.iter().map(|(_, m)| m.clone()))
            .collect();
        let line = toks[i].1;
        match &toks[i].0 {
            Tok::Open => {
                depth += 1;
                if i >= 2 && ident(i - 2) == Some("mod") {
                    inline.push((depth, ident(i - 1).unwrap_or("").to_string()));
                }
            }
            Tok::Close => {
                if inline.last().is_some_and(|(d, _)| *d == depth) {
                    inline.pop();
                }
                depth -= 1;
            }
            Tok::Ident(word) if word == "use" => {
                let end = (i..toks.len())
                    .find(|&k| toks[k].0 == Tok::Semi)
                    .unwrap_or(toks.len());
                let mut paths = Vec::new();
                use_paths(&toks[i + 1..end], &[], &mut paths);
                out.extend(paths.into_iter().map(|path| Named {
                    at: here.clone(),
                    path,
                    line,
                }));
                i = end;
            }
            Tok::Ident(first) if i == 0 || toks[i - 1].0 != Tok::Sep => {
                let mut path = vec![first.clone()];
                let mut k = i + 1;
                while toks.get(k).map(|t| &t.0) == Some(&Tok::Sep) {
                    let Some(next) = ident(k + 1) else { break };
                    path.push(next.to_string());
                    k += 2;
                }
                if path.len() > 1 {
                    out.push(Named {
                        at: here,
                        path,
                        line,
                    });
                }
                i = k.max(i + 1);
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    out
}

/// The modules of `src/` (file modules and inline `mod x { … }`), each with the file that
/// defines it, and every file's paths.
struct Files {
    modules: BTreeMap<Vec<String>, String>,
    /// Per file (relative to `src/`): its module and its paths (see [`paths_in`]).
    paths: BTreeMap<String, (Vec<String>, Vec<Named>)>,
}

impl Files {
    fn read(src: &Path) -> Files {
        let mut all = Vec::new();
        rust_files(src, &mut all);
        let mut files = Files {
            modules: BTreeMap::new(),
            paths: BTreeMap::new(),
        };
        for file in all {
            let rel = file.strip_prefix(src).unwrap();
            let shown = rel.to_string_lossy().replace('\\', "/");
            if shown == "main.rs" {
                continue; // the binary: its `crate` is itself
            }
            let module = module_of(rel);
            let paths = paths_in(&std::fs::read_to_string(&file).unwrap(), &module);
            files.modules.insert(module.clone(), shown.clone());
            for named in &paths {
                let inline = named.at.clone();
                files.modules.entry(inline).or_insert(shown.clone());
            }
            files.paths.insert(shown, (module, paths));
        }
        files
    }

    /// The file a path written in module `at` points at: the one defining the deepest module it
    /// names. `None` for paths outside the crate (`std::…`, a dependency's) or naming no module
    /// (`Kind::Tensor`).
    fn resolve(&self, at: &[String], path: &[String]) -> Option<&str> {
        let mut module = at.to_vec();
        let mut rest = path;
        match path.first().map(String::as_str) {
            Some("crate") => {
                module.clear();
                rest = &path[1..];
            }
            Some("super" | "self") => {}
            Some(first) => {
                module.push(first.to_string());
                self.modules.get(&module)?;
                module.pop();
            }
            None => return None,
        }
        for segment in rest {
            match segment.as_str() {
                "super" => {
                    module.pop();
                }
                "self" => {}
                name => {
                    module.push(name.to_string());
                    if !self.modules.contains_key(&module) {
                        module.pop();
                        break;
                    }
                }
            }
        }
        self.modules.get(&module).map(String::as_str)
    }

    /// File → the files it imports, each with the first line that does.
    fn imports(&self) -> BTreeMap<&str, BTreeMap<&str, usize>> {
        let mut graph: BTreeMap<&str, BTreeMap<&str, usize>> = BTreeMap::new();
        for (file, (module, paths)) in &self.paths {
            let enclosing: Vec<&str> = (0..module.len())
                .filter_map(|k| self.modules.get(&module[..k]).map(String::as_str))
                .collect();
            let edges = graph.entry(file.as_str()).or_default();
            for named in paths {
                let Some(target) = self.resolve(&named.at, &named.path) else {
                    continue;
                };
                if target != file && !enclosing.contains(&target) {
                    edges.entry(target).or_insert(named.line);
                }
            }
        }
        graph
    }
}

/// The strongly connected components of more than one file (Tarjan's algorithm), sorted.
fn circles<'a>(graph: &BTreeMap<&'a str, BTreeMap<&'a str, usize>>) -> Vec<Vec<&'a str>> {
    struct Walk<'g, 'a> {
        graph: &'g BTreeMap<&'a str, BTreeMap<&'a str, usize>>,
        index: BTreeMap<&'a str, (usize, usize)>,
        stack: Vec<&'a str>,
        found: Vec<Vec<&'a str>>,
    }
    impl<'a> Walk<'_, 'a> {
        fn visit(&mut self, v: &'a str) {
            let n = self.index.len();
            self.index.insert(v, (n, n));
            self.stack.push(v);
            for &w in self.graph.get(v).into_iter().flat_map(|e| e.keys()) {
                let low = match self.index.get(w) {
                    None => {
                        self.visit(w);
                        self.index[w].1
                    }
                    Some(&(i, _)) if self.stack.contains(&w) => i,
                    Some(_) => continue,
                };
                let entry = self.index.get_mut(v).unwrap();
                entry.1 = entry.1.min(low);
            }
            let (i, low) = self.index[v];
            if i == low {
                let at = self.stack.iter().position(|&x| x == v).unwrap();
                let mut component = self.stack.split_off(at);
                if component.len() > 1 {
                    component.sort();
                    self.found.push(component);
                }
            }
        }
    }
    let mut walk = Walk {
        graph,
        index: BTreeMap::new(),
        stack: Vec::new(),
        found: Vec::new(),
    };
    for &v in graph.keys() {
        if !walk.index.contains_key(v) {
            walk.visit(v);
        }
    }
    walk.found.sort();
    walk.found
}

/// Every circle: its files, and the imports between them with their lines.
fn new_circles(src: &Path) -> Vec<String> {
    let files = Files::read(src);
    let graph = files.imports();
    let mut found = Vec::new();
    for circle in circles(&graph) {
        let members: BTreeSet<&str> = circle.iter().copied().collect();
        let edges: Vec<String> = circle
            .iter()
            .flat_map(|&from| {
                graph[from]
                    .iter()
                    .filter(|(to, _)| members.contains(*to))
                    .map(move |(to, line)| format!("src/{from}:{line} imports src/{to}"))
            })
            .collect();
        found.push(format!(
            "an import circle between {}:\n  {}",
            circle
                .iter()
                .map(|f| format!("src/{f}"))
                .collect::<Vec<_>>()
                .join(", "),
            edges.join("\n  ")
        ));
    }
    found
}

#[test]
fn no_file_imports_in_a_circle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let found = new_circles(&src);
    assert!(
        found.is_empty(),
        "files that import each other are one concept split in two, or two tangled: move what \
         they share to where it belongs (see book/src/architecture.md)\n{}",
        found.join("\n")
    );
}

#[test]
fn a_new_circle_is_caught_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    let write = |rel: &str, text: &str| {
        let path = src.join(rel);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    };
    write("lib.rs", "pub mod a;\npub mod b;\n");
    // a/mod.rs re-exports a child, and the child uses the folder's type: not a circle.
    write(
        "a/mod.rs",
        "mod x;\nmod y;\nmod z;\npub use x::X;\npub struct Shared;\n",
    );
    write("a/x.rs", "use super::Shared;\npub struct X;\n");
    // y ↔ z: through a `use` group one way, a path in an inline test module the other; a
    // comment and a string name x, which is no import.
    write(
        "a/y.rs",
        "// use super::x;\nuse crate::{a::{self, z::Z}, b};\n\
         pub fn f() -> &'static str { \"super::x\" }\n",
    );
    write(
        "a/z.rs",
        "pub struct Z;\n#[cfg(test)]\nmod tests {\n    fn g() { super::super::y::f(); }\n}\n",
    );
    // b → a/x one way: no circle.
    write("b.rs", "use crate::a::x;\n");
    let found = new_circles(src);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        found[0].starts_with("an import circle between src/a/y.rs, src/a/z.rs:"),
        "{found:?}"
    );
    assert!(
        found[0].contains("src/a/y.rs:2 imports src/a/z.rs"),
        "{found:?}"
    );
    assert!(
        found[0].contains("src/a/z.rs:4 imports src/a/y.rs"),
        "{found:?}"
    );
    // A third file in the loop: one circle of three.
    write("b.rs", "use crate::a::{x, z};\n");
    write(
        "a/z.rs",
        "use crate::b;\npub struct Z;\nfn g() { super::y::f(); }\n",
    );
    let found = new_circles(src);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        found[0].starts_with("an import circle between src/a/y.rs, src/a/z.rs, src/b.rs:"),
        "{found:?}"
    );
}
