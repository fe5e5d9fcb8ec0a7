//! Every example spec in `specs/` is built, and its outputs are compared with `golden/<spec>/`:
//! text files verbatim, HDF5 files and Zarr directories as canonical dumps (`<file>.txt`), other
//! binary files as
//! size and hash. A missing or an extra file
//! fails. The same builds with 1 and 2 threads must give byte-identical files.
//!
//! Regenerate after an intended change with `CHUNKC_BLESS=1 cargo test --release --test golden`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use chunkc::sink::dump;

const REPO: &str = env!("CARGO_MANIFEST_DIR");

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).unwrap();
        }
    }
}

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

/// What the golden directory should hold for a built output directory.
fn canonical(out_dir: &Path) -> BTreeMap<PathBuf, String> {
    let mut files = BTreeMap::new();
    for rel in files_under_opt(out_dir, true) {
        // The build lock is chunkc's bookkeeping (empty), not an output.
        if rel == Path::new(chunkc::exec::BUILD_LOCK_FILE) {
            continue;
        }
        let path = out_dir.join(&rel);
        if rel.extension().is_some_and(|e| e == "zarr") {
            let mut name = rel.clone().into_os_string();
            name.push(".txt");
            files.insert(PathBuf::from(name), dump::zarr_text(&path).unwrap());
        } else if rel.extension().is_some_and(|e| e == "h5" || e == "hdf5") {
            let mut name = rel.clone().into_os_string();
            name.push(".txt");
            files.insert(PathBuf::from(name), dump::hdf5_text(&path).unwrap());
        } else {
            let bytes = std::fs::read(&path).unwrap();
            match String::from_utf8(bytes) {
                Ok(text) => {
                    files.insert(rel, text);
                }
                Err(e) => {
                    // Other binary files (ACT's pickle): size and hash; their JSON twins carry
                    // the numbers.
                    let bytes = e.into_bytes();
                    let mut name = rel.clone().into_os_string();
                    name.push(".txt");
                    let text = format!(
                        "binary {} bytes blake3 {}\n",
                        bytes.len(),
                        blake3::hash(&bytes)
                    );
                    files.insert(PathBuf::from(name), text);
                }
            }
        }
    }
    files
}

fn example_specs() -> Vec<PathBuf> {
    let mut specs: Vec<PathBuf> = std::fs::read_dir(Path::new(REPO).join("specs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    specs.sort();
    assert!(!specs.is_empty());
    specs
}

#[test]
fn example_specs_match_golden() {
    let bless = std::env::var_os("CHUNKC_BLESS").is_some();
    for spec in example_specs() {
        let stem = spec.file_stem().unwrap().to_string_lossy().into_owned();
        let (_scratch, out_dir) = build(&spec, "2");
        let got = canonical(&out_dir);
        let golden_dir = Path::new(REPO).join("golden").join(&stem);
        if bless {
            let _ = std::fs::remove_dir_all(&golden_dir);
            for (rel, text) in &got {
                let path = golden_dir.join(rel);
                std::fs::create_dir_all(path.parent().unwrap()).unwrap();
                std::fs::write(path, text).unwrap();
            }
            continue;
        }
        let want: Vec<PathBuf> = if golden_dir.exists() {
            files_under(&golden_dir)
        } else {
            vec![]
        };
        let got_names: Vec<PathBuf> = got.keys().cloned().collect();
        assert_eq!(
            got_names, want,
            "{stem}: the set of output files differs from golden/{stem} (missing or extra files); \
             rerun with CHUNKC_BLESS=1 if the change is intended"
        );
        for (rel, text) in &got {
            let expected = std::fs::read_to_string(golden_dir.join(rel)).unwrap();
            assert!(
                *text == expected,
                "{stem}: {} differs from golden; rerun with CHUNKC_BLESS=1 if intended\n--- golden\n{expected}\n--- built\n{text}",
                rel.display()
            );
        }
    }
}

#[test]
fn outputs_are_byte_identical_across_thread_counts() {
    for spec in example_specs() {
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
                "{}: {} differs between 1 and 2 threads",
                spec.display(),
                rel.display()
            );
        }
    }
}

/// Low-dim values spilled to disk (a budget of 256 bytes: every store spills after a few rows,
/// and keeps a few in memory at the end) give the same files, byte for byte, as values kept in
/// memory, in every output format of the example specs.
#[test]
fn spilled_lowdim_values_give_byte_identical_outputs() {
    for spec in example_specs() {
        let (_a, memory) = build(&spec, "2");
        let (_b, spilled) = build_with(&spec, "2", &[("CHUNKC_SPILL_BYTES", "256")]);
        let names = files_under(&memory);
        assert_eq!(names, files_under(&spilled), "{}", spec.display());
        for rel in names {
            let a = blake3::hash(&std::fs::read(memory.join(&rel)).unwrap());
            let b = blake3::hash(&std::fs::read(spilled.join(&rel)).unwrap());
            assert_eq!(
                a,
                b,
                "{}: {} differs when low-dim values spill to disk",
                spec.display(),
                rel.display()
            );
        }
        assert!(
            !spilled.join(chunkc::exec::STAGING_DIR).exists(),
            "{}: the staging directory (and the spilled values) must be gone",
            spec.display()
        );
    }
}
