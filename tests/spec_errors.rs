//! Every spec in `tests/specs_bad/` must fail to load, and its message is a snapshot
//! (`tests/snapshots/spec_errors__<stem>.snap`): these are what a user reads, so review them as
//! such. Add a case by adding a `.toml` file; accept with `INSTA_UPDATE=always` or `cargo insta`.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use chunkc::error::Error;
use chunkc::spec::LoadedSpec;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn bad_specs() -> Vec<PathBuf> {
    let dir = root().join("tests/specs_bad");
    let mut files: Vec<PathBuf> = fs::read_dir(&dir)
        .expect("tests/specs_bad exists")
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
fn bad_specs_fail_with_a_located_message() {
    let files = bad_specs();
    assert!(
        files.len() >= 8,
        "expected the bad-spec fixtures, found {files:?}"
    );
    for path in files {
        let name = format!(
            "tests/specs_bad/{}",
            path.file_name().unwrap().to_string_lossy()
        );
        let text = fs::read_to_string(&path).unwrap();
        let err = match LoadedSpec::parse(&name, &text, path.parent().unwrap()) {
            Ok(_) => panic!("{name} loaded without an error"),
            Err(err) => err,
        };
        assert!(
            matches!(err, Error::Spec(_)),
            "{name}: not a spec error: {err:?}"
        );
        assert_eq!(err.exit_code(), 2);
        let message = err.to_string();
        assert!(
            message.contains(&format!("--> {name}:")),
            "{name}: no location in\n{message}"
        );
        insta::with_settings!({
            input_file => &path,
            omit_expression => true,
            prepend_module_to_snapshot => true,
        }, {
            insta::assert_snapshot!(stem(&path), message);
        });
    }
}

/// A snapshot whose fixture was deleted or renamed would otherwise linger unnoticed.
#[test]
fn every_snapshot_has_a_fixture() {
    let stems: Vec<String> = bad_specs().iter().map(|p| stem(p)).collect();
    let snapshots = root().join("tests/snapshots");
    for entry in fs::read_dir(&snapshots).into_iter().flatten() {
        let file = entry.unwrap().file_name().to_string_lossy().into_owned();
        if let Some(case) = file
            .strip_prefix("spec_errors__")
            .and_then(|f| f.strip_suffix(".snap"))
        {
            assert!(
                stems.iter().any(|s| s == case),
                "tests/snapshots/{file} has no tests/specs_bad/{case}.toml: delete it"
            );
        }
    }
}

#[test]
fn check_reports_the_location_and_writes_nothing() {
    let spec = "tests/specs_bad/misspelled_key.toml";
    let text = fs::read_to_string(root().join(spec)).unwrap();
    let line = text.lines().position(|l| l.starts_with("chunck")).unwrap() + 1;
    let out_dir = root().join("tests/specs_bad/out");
    assert!(text.contains("dir = \"out/should-not-exist\""));
    let _ = fs::remove_dir_all(&out_dir);

    let output = Command::new(env!("CARGO_BIN_EXE_chunkc"))
        .args(["check", spec])
        .current_dir(root())
        .output()
        .expect("chunkc runs");

    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "stderr:\n{stderr}");
    assert!(
        stderr.contains(&format!("misspelled_key.toml:{line}:1")),
        "stderr:\n{stderr}"
    );
    assert!(
        stderr.contains("did you mean `chunk`?"),
        "stderr:\n{stderr}"
    );
    assert!(!out_dir.exists(), "check wrote {}", out_dir.display());
}
