//! Every spec in `tests/sources_bad/` loads but fails against its source: a missing key, a corrupt
//! or inconsistent file, a missing video. `chunkc check` must exit non-zero with a message naming
//! the file and the key; the exit code and message are a snapshot
//! (`tests/snapshots/source_errors__<stem>.snap`). The broken files are made by
//! `tests/sources_bad/make_fixtures.py`. Accept changes with `INSTA_UPDATE=always`.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/sources_bad")
}

fn cases() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = fs::read_dir(dir())
        .expect("tests/sources_bad exists")
        .map(|entry| entry.expect("readable directory").path())
        .filter(|path| path.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    files
}

fn stem(path: &Path) -> String {
    path.file_stem().unwrap().to_string_lossy().into_owned()
}

#[test]
fn bad_sources_fail_with_a_message_naming_file_and_key() {
    let files = cases();
    assert!(
        files.len() >= 3,
        "expected the bad-source fixtures, found {files:?}"
    );
    for path in files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        // Relative paths in messages: run where the spec is.
        let output = Command::new(env!("CARGO_BIN_EXE_chunkc"))
            .args(["check", &name])
            .current_dir(dir())
            .output()
            .expect("chunkc runs");
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        let code = output.status.code();
        assert!(
            matches!(code, Some(2) | Some(3)),
            "{name}: exit {code:?} (want 2 for the spec, 3 for the source):\n{stderr}"
        );
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
        assert!(!dir().join("out").exists(), "{name}: check wrote outputs");
        insta::with_settings!({
            input_file => &path,
            omit_expression => true,
            prepend_module_to_snapshot => true,
        }, {
            insta::assert_snapshot!(stem(&path), format!("exit code {}\n{stderr}", code.unwrap()));
        });
    }
}

/// A snapshot whose fixture was deleted or renamed would otherwise linger unnoticed.
#[test]
fn every_snapshot_has_a_fixture() {
    let stems: Vec<String> = cases().iter().map(|p| stem(p)).collect();
    let snapshots = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/snapshots");
    for entry in fs::read_dir(&snapshots).into_iter().flatten() {
        let file = entry.unwrap().file_name().to_string_lossy().into_owned();
        if let Some(case) = file
            .strip_prefix("source_errors__")
            .and_then(|f| f.strip_suffix(".snap"))
        {
            assert!(
                stems.iter().any(|s| s == case),
                "tests/snapshots/{file} has no tests/sources_bad/{case}.toml: delete it"
            );
        }
    }
}
