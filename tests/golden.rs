//! Every example spec in `specs/` is built, and its outputs are compared with `golden/<spec>/`:
//! text files verbatim (JSON with each array of numbers on one line: `dump::json_text`), HDF5
//! files and Zarr directories as canonical dumps (`<file>.txt`), other binary files as size and
//! hash. The generated scripts that are the same file in every profile directory are kept once in
//! `golden/_generated/`; a profile's `<script>.txt` says that its copy is that file. Its
//! `loader.py` and `validate.py`, generated for the profile from the parts it reads, are kept
//! verbatim (and `golden/_generated/` holds them with every part). A missing or an extra file
//! fails. The same builds with 1 and 2 threads, and with low-dim values spilled to
//! disk, must give byte-identical files.
//!
//! Each spec is its own test case (`golden::<spec>::matches_golden`, `::thread_counts`,
//! `::spilled`), so that one failure does not hide the others; a mismatch shows the first lines
//! that differ. Regenerate after an intended change with
//! `CHUNKC_BLESS=1 cargo test --release --test golden`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use chunkc::sink::dump;

mod common;
use common::copy_dir;

const REPO: &str = env!("CARGO_MANIFEST_DIR");

fn files_under(root: &Path) -> Vec<PathBuf> {
    files_under_opt(root, false)
}

/// Files under `root`; with `zarr_as_files`, a `*.zarr` directory counts as one entry.
fn files_under_opt(root: &Path, zarr_as_files: bool) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if zarr_as_files && path.is_dir() && path.extension().is_some_and(|e| e == "zarr") {
                out.push(path.strip_prefix(root).unwrap().to_path_buf());
            } else if path.is_dir() {
                stack.push(path);
            } else {
                out.push(path.strip_prefix(root).unwrap().to_path_buf());
            }
        }
    }
    out.sort();
    out
}

/// Builds `spec` inside a scratch copy of the repository layout the specs expect
/// (`specs/` next to `tests/data/`), and returns the output directory.
fn build(spec: &Path, threads: &str) -> (tempfile::TempDir, PathBuf) {
    build_with(spec, threads, &[])
}

/// [`build`] with extra environment variables.
fn build_with(spec: &Path, threads: &str, env: &[(&str, &str)]) -> (tempfile::TempDir, PathBuf) {
    let scratch = tempfile::tempdir().unwrap();
    copy_dir(
        &Path::new(REPO).join("tests/data"),
        &scratch.path().join("tests/data"),
    );
    std::fs::create_dir(scratch.path().join("specs")).unwrap();
    let copied = scratch.path().join("specs").join(spec.file_name().unwrap());
    std::fs::copy(spec, &copied).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_chunkc"))
        .args(["build", "-q"])
        .arg(&copied)
        .env("RAYON_NUM_THREADS", threads)
        .envs(env.iter().copied())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "building {} failed: {}",
        spec.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&copied).unwrap();
    let dir: toml::Value = toml::from_str(&text).unwrap();
    let rel = dir["output"]["dir"].as_str().unwrap().to_string();
    let out_dir = scratch.path().join("specs").join(rel);
    (scratch, out_dir)
}

/// Where the one copy of each generated script lives.
const GENERATED: &str = "_generated";

/// The generated scripts as the embedded templates render them (the same for every profile).
fn shared_scripts() -> BTreeMap<&'static str, String> {
    let r = chunkc::render::Renderer::new(None).unwrap();
    chunkc::render::SHARED_SCRIPTS
        .iter()
        .map(|&name| (name, chunkc::render::shared_script(&r, name).unwrap()))
        .collect()
}

/// What `golden/_generated/` holds: the shared scripts, and the scripts generated per profile
/// with every part.
fn generated_files() -> BTreeMap<&'static str, String> {
    let r = chunkc::render::Renderer::new(None).unwrap();
    let mut files = shared_scripts();
    let every = chunkc::render::parts::Parts::every();
    for name in chunkc::render::PROFILE_SCRIPTS {
        files.insert(name, chunkc::render::script_with(&r, name, every).unwrap());
    }
    files
}

/// What the golden directory should hold for a built output directory.
fn canonical(out_dir: &Path, shared: &BTreeMap<&str, String>) -> BTreeMap<PathBuf, String> {
    let mut files = BTreeMap::new();
    for rel in files_under_opt(out_dir, true) {
        // The build lock is chunkc's bookkeeping (empty), not an output.
        if rel == Path::new(chunkc::exec::BUILD_LOCK_FILE) {
            continue;
        }
        let path = out_dir.join(&rel);
        let with_txt = |rel: &Path| {
            let mut name = rel.as_os_str().to_owned();
            name.push(".txt");
            PathBuf::from(name)
        };
        let file_name = rel.file_name().unwrap().to_string_lossy().into_owned();
        if rel.extension().is_some_and(|e| e == "zarr") {
            files.insert(with_txt(&rel), dump::zarr_text(&path).unwrap());
        } else if rel.extension().is_some_and(|e| e == "h5" || e == "hdf5") {
            files.insert(with_txt(&rel), dump::hdf5_text(&path).unwrap());
        } else if let Some(want) = shared.get(file_name.as_str()) {
            let got = std::fs::read_to_string(&path).unwrap();
            let text = if got == *want {
                format!("same as golden/{GENERATED}/{file_name}\n")
            } else {
                format!(
                    "differs from golden/{GENERATED}/{file_name}:\n{}",
                    first_difference(want, &got)
                )
            };
            files.insert(with_txt(&rel), text);
        } else {
            let bytes = std::fs::read(&path).unwrap();
            match String::from_utf8(bytes) {
                Ok(text) if rel.extension().is_some_and(|e| e == "json") => {
                    files.insert(rel, dump::json_text(&text));
                }
                Ok(text) => {
                    files.insert(rel, text);
                }
                Err(e) => {
                    // Other binary files (ACT's pickle): size and hash; their JSON twins carry
                    // the numbers.
                    let bytes = e.into_bytes();
                    let text = format!(
                        "binary {} bytes blake3 {}\n",
                        bytes.len(),
                        blake3::hash(&bytes)
                    );
                    files.insert(with_txt(&rel), text);
                }
            }
        }
    }
    files
}

/// The first lines where `got` differs from `want`, with a few lines of context, numbered;
/// `>` marks the lines that differ.
fn first_difference(want: &str, got: &str) -> String {
    const BEFORE: usize = 3;
    const SHOWN: usize = 12;
    let (w, g): (Vec<&str>, Vec<&str>) = (want.lines().collect(), got.lines().collect());
    let first = (0..w.len().max(g.len()))
        .find(|&i| w.get(i) != g.get(i))
        .unwrap_or(w.len());
    let from = first.saturating_sub(BEFORE);
    let mut out = format!(
        "first difference at line {} ({} lines golden, {} built)\n",
        first + 1,
        w.len(),
        g.len()
    );
    for (label, lines) in [("golden", &w), ("built", &g)] {
        out.push_str(&format!("--- {label}\n"));
        for (i, line) in lines.iter().enumerate().skip(from).take(BEFORE + SHOWN) {
            let mark = if w.get(i) == g.get(i) { ' ' } else { '>' };
            out.push_str(&format!("{mark}{:>6} {line}\n", i + 1));
        }
    }
    out
}

/// Writes `text` to `path` unless it holds it already (several test cases bless at once).
fn bless_file(path: &Path, text: &str) {
    if std::fs::read_to_string(path).is_ok_and(|old| old == text) {
        return;
    }
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    std::fs::write(&tmp, text).unwrap();
    std::fs::rename(tmp, path).unwrap();
}

fn blessing() -> bool {
    std::env::var_os("CHUNKC_BLESS").is_some()
}

fn spec_path(stem: &str) -> PathBuf {
    Path::new(REPO).join("specs").join(format!("{stem}.toml"))
}

fn example_specs() -> Vec<String> {
    let mut specs: Vec<String> = std::fs::read_dir(Path::new(REPO).join("specs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    specs.sort();
    assert!(!specs.is_empty());
    specs
}

/// Builds `stem` and compares its outputs with `golden/<stem>/` (or rewrites it when blessing).
fn check_golden(stem: &str) {
    let (_scratch, out_dir) = build(&spec_path(stem), "2");
    let got = canonical(&out_dir, &shared_scripts());
    let golden_dir = Path::new(REPO).join("golden").join(stem);
    if blessing() {
        let stale: Vec<PathBuf> = if golden_dir.exists() {
            files_under(&golden_dir)
        } else {
            vec![]
        };
        for rel in stale.iter().filter(|r| !got.contains_key(*r)) {
            std::fs::remove_file(golden_dir.join(rel)).unwrap();
        }
        for (rel, text) in &got {
            bless_file(&golden_dir.join(rel), text);
        }
        return;
    }
    let want: Vec<PathBuf> = if golden_dir.exists() {
        files_under(&golden_dir)
    } else {
        vec![]
    };
    let missing: Vec<String> = want
        .iter()
        .filter(|r| !got.contains_key(*r))
        .map(|r| r.display().to_string())
        .collect();
    let extra: Vec<String> = got
        .keys()
        .filter(|r| !want.contains(r))
        .map(|r| r.display().to_string())
        .collect();
    assert!(
        missing.is_empty() && extra.is_empty(),
        "{stem}: the set of output files differs from golden/{stem}: in golden but not built \
         {missing:?}, built but not in golden {extra:?}; rerun with CHUNKC_BLESS=1 if the change is intended"
    );
    let mut failures = Vec::new();
    for (rel, text) in &got {
        let expected = std::fs::read_to_string(golden_dir.join(rel)).unwrap();
        if *text != expected {
            failures.push(format!(
                "golden/{stem}/{}: {}",
                rel.display(),
                first_difference(&expected, text)
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{stem}: {} file(s) differ from golden; rerun with CHUNKC_BLESS=1 if intended\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The same files, byte for byte, with 1 and 2 threads.
fn check_thread_counts(stem: &str) {
    let spec = spec_path(stem);
    let (_a, one) = build(&spec, "1");
    let (_b, two) = build(&spec, "2");
    let names = files_under(&one);
    assert_eq!(names, files_under(&two));
    for rel in names {
        let a = blake3::hash(&std::fs::read(one.join(&rel)).unwrap());
        let b = blake3::hash(&std::fs::read(two.join(&rel)).unwrap());
        assert_eq!(
            a,
            b,
            "{stem}: {} differs between 1 and 2 threads",
            rel.display()
        );
    }
}

/// Low-dim values spilled to disk (a budget of 256 bytes: every store spills after a few rows,
/// and keeps a few in memory at the end) give the same files, byte for byte, as values kept in
/// memory, in every output format of the example specs.
fn check_spilled(stem: &str) {
    let spec = spec_path(stem);
    let (_a, memory) = build(&spec, "2");
    let (_b, spilled) = build_with(&spec, "2", &[("CHUNKC_SPILL_BYTES", "256")]);
    let names = files_under(&memory);
    assert_eq!(names, files_under(&spilled), "{stem}");
    for rel in names {
        let a = blake3::hash(&std::fs::read(memory.join(&rel)).unwrap());
        let b = blake3::hash(&std::fs::read(spilled.join(&rel)).unwrap());
        assert_eq!(
            a,
            b,
            "{stem}: {} differs when low-dim values spill to disk",
            rel.display()
        );
    }
    assert!(
        !spilled.join(chunkc::exec::STAGING_DIR).exists(),
        "{stem}: the staging directory (and the spilled values) must be gone"
    );
}

/// One module of test cases per example spec: `<spec>::matches_golden`, `::thread_counts`,
/// `::spilled`.
macro_rules! example_specs {
    ($($stem:ident),* $(,)?) => {
        const LISTED: &[&str] = &[$(stringify!($stem)),*];
        $(
            mod $stem {
                #[test]
                fn matches_golden() {
                    super::check_golden(stringify!($stem));
                }

                #[test]
                fn thread_counts() {
                    super::check_thread_counts(stringify!($stem));
                }

                #[test]
                fn spilled() {
                    super::check_spilled(stringify!($stem));
                }
            }
        )*
    };
}

example_specs!(
    aloha_sim,
    bridge,
    lerobot_g1,
    lerobot_v3,
    multi_arch,
    pusht,
    pusht_formats,
    pusht_rollout,
    robosuite_panda,
    robosuite_sawyer,
);

/// Every spec in `specs/` has its test cases above, and `golden/` holds no other spec.
#[test]
fn every_example_spec_is_listed() {
    assert_eq!(
        LISTED,
        example_specs(),
        "add the spec to `example_specs!` in tests/golden.rs"
    );
    let mut dirs: Vec<String> = std::fs::read_dir(Path::new(REPO).join("golden"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name != GENERATED)
        .collect();
    dirs.sort();
    assert_eq!(
        dirs,
        example_specs(),
        "golden/ holds a spec that specs/ does not"
    );
}

/// `golden/_generated/` holds exactly the shared scripts and the per-profile scripts with every
/// part, as the embedded templates render them.
#[test]
fn generated_scripts_match_golden() {
    let dir = Path::new(REPO).join("golden").join(GENERATED);
    let shared = generated_files();
    if blessing() {
        for (name, text) in &shared {
            bless_file(&dir.join(name), text);
        }
        for stale in files_under(&dir) {
            if !shared.contains_key(stale.to_str().unwrap()) {
                std::fs::remove_file(dir.join(stale)).unwrap();
            }
        }
    }
    let names: Vec<PathBuf> = shared.keys().map(PathBuf::from).collect();
    assert_eq!(
        files_under(&dir),
        names,
        "golden/{GENERATED} holds other files than the generated scripts"
    );
    for (name, text) in &shared {
        let expected = std::fs::read_to_string(dir.join(name)).unwrap();
        assert!(
            *text == expected,
            "golden/{GENERATED}/{name}: {}; rerun with CHUNKC_BLESS=1 if intended",
            first_difference(&expected, text)
        );
    }
}
