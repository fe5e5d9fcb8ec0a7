//! Every cause of a rebuild, produced on the vendored Push-T subset (`specs/pusht.toml`, copied
//! into a temp directory with its data) and shown by `chunkc plan` (text), `chunkc plan --format
//! json` (`status.reason.cause`) and `chunkc build --locked` (exit 5, the reason on stderr).
//!
//! One build; each case changes one thing, checks the three views, and undoes the change, so the
//! next case starts from an up-to-date build again.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::json;

mod common;
use common::copy_dir;

const REPO: &str = env!("CARGO_MANIFEST_DIR");

struct Scratch {
    _tmp: tempfile::TempDir,
    root: PathBuf,
    spec: PathBuf,
}

impl Scratch {
    fn new() -> Scratch {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path().to_path_buf();
        copy_dir(
            &Path::new(REPO).join("tests/data/pusht_subset.zarr"),
            &root.join("tests/data/pusht_subset.zarr"),
        );
        fs::create_dir(root.join("specs")).unwrap();
        let spec = root.join("specs/pusht.toml");
        fs::copy(Path::new(REPO).join("specs/pusht.toml"), &spec).unwrap();
        Scratch {
            _tmp: tmp,
            root,
            spec,
        }
    }

    fn run(&self, args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_chunkc"))
            .args(args)
            .arg(&self.spec)
            .env("RAYON_NUM_THREADS", "2")
            .output()
            .unwrap()
    }

    /// `chunkc build -q`, which must succeed.
    fn build(&self) {
        let built = self.run(&["build", "-q"]);
        assert!(
            built.status.success(),
            "{}",
            String::from_utf8_lossy(&built.stderr)
        );
    }

    fn plan_text(&self) -> String {
        let out = self.run(&["plan"]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap()
    }

    /// `status` of every profile in `plan --format json`, by name.
    fn statuses(&self) -> serde_json::Map<String, serde_json::Value> {
        let out = self.run(&["plan", "--format", "json"]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let plan: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        plan["profiles"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| (p["name"].as_str().unwrap().to_string(), p["status"].clone()))
            .collect()
    }

    fn lock(&self) -> PathBuf {
        self.root.join("specs/chunkc.lock")
    }

    /// An output file, as the plan names it: the spec's `output.dir` joined to the spec's folder.
    fn out(&self, rel: &str) -> PathBuf {
        self.root.join("specs/../out/pusht").join(rel)
    }

    fn source(&self, rel: &str) -> PathBuf {
        self.root.join("tests/data/pusht_subset.zarr").join(rel)
    }
}

/// The profile is stale for `cause` (JSON), its plan line reads `text`, and `build --locked`
/// names it; profiles in `fresh` are up to date.
fn expect(s: &Scratch, profile: &str, cause: serde_json::Value, text: &str, fresh: &[&str]) {
    let statuses = s.statuses();
    assert_eq!(
        statuses[profile]["state"], "stale",
        "{profile}: {statuses:?}"
    );
    assert_eq!(statuses[profile]["reason"], cause, "{profile}");
    for f in fresh {
        assert_eq!(statuses[*f]["state"], "up_to_date", "{f}: {statuses:?}");
    }
    let plan = s.plan_text();
    let line = format!("profile {profile}  [build: {text}]");
    assert!(plan.contains(&line), "want `{line}` in:\n{plan}");
    let locked = s.run(&["build", "--locked", "-q"]);
    assert_eq!(locked.status.code(), Some(5));
    let stderr = String::from_utf8_lossy(&locked.stderr);
    assert!(stderr.contains(&format!("  {profile}: {text}")), "{stderr}");
}

fn up_to_date(s: &Scratch) {
    for (name, status) in s.statuses() {
        assert_eq!(status, serde_json::json!({"state": "up_to_date"}), "{name}");
    }
    assert!(s.run(&["build", "--locked", "-q"]).status.success());
}

#[test]
fn every_cause_is_distinct_in_text_json_and_locked() {
    let s = Scratch::new();

    expect(
        &s,
        "dp",
        json!({"cause": "never_built"}),
        "not in chunkc.lock: first build",
        &[],
    );
    s.build();
    // The first build completes the source's fingerprint from its own reads of the chunk files;
    // `plan` hashes every file from disk: the same value in the lock, `meta.json` and the plan.
    let plan: serde_json::Value =
        serde_json::from_slice(&s.run(&["plan", "--format", "json"]).stdout).unwrap();
    let lock: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(s.lock()).unwrap()).unwrap();
    let meta: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(s.out("dp/meta.json")).unwrap()).unwrap();
    let from_disk = &plan["source"]["fingerprint"];
    assert_eq!(from_disk.as_str().map(str::len), Some(64));
    assert_eq!(
        &lock["specs"]["pusht.toml"]["source_fingerprint"],
        from_disk
    );
    assert_eq!(&meta["source"]["fingerprint"], from_disk);
    up_to_date(&s);

    // A spec value: only the profile it belongs to, with the key and both values.
    let spec = fs::read_to_string(&s.spec).unwrap();
    fs::write(&s.spec, spec.replace("chunk = 20", "chunk = 10")).unwrap();
    expect(
        &s,
        "act",
        json!({"cause": "spec_value_changed", "key": "profiles.act.chunk", "old": "20", "new": "10"}),
        "spec value `profiles.act.chunk` changed (20 -> 10)",
        &["dp"],
    );
    // A value shared by every profile, set where it was unset.
    fs::write(
        &s.spec,
        spec.replace("seed = 0", "seed = 0\nfrom = \"source\""),
    )
    .unwrap();
    let statuses = s.statuses();
    assert_eq!(statuses["dp"]["reason"]["key"], "split.from");
    // A new profile.
    fs::write(
        &s.spec,
        format!(
            "{spec}\n[profiles.extra]\npreset = \"act\"\nfps = 10\nchunk = 8\nformat = \"hdf5\"\n"
        ),
    )
    .unwrap();
    expect(
        &s,
        "extra",
        json!({"cause": "new_profile", "profile": "extra"}),
        "profile `extra` is not in chunkc.lock",
        &["act", "dp"],
    );
    fs::write(&s.spec, &spec).unwrap();
    up_to_date(&s);

    // Source files: modified (still valid JSON) and added.
    let zarray = s.source("data/action/.zarray");
    let before = fs::read(&zarray).unwrap();
    fs::write(&zarray, [before.as_slice(), b"\n"].concat()).unwrap();
    expect(
        &s,
        "dp",
        json!({"cause": "source_file_changed", "file": "data/action/.zarray", "change": "modified"}),
        "source file `data/action/.zarray` was modified",
        &[],
    );
    fs::write(&zarray, &before).unwrap();
    let extra = s.source("meta/notes.txt");
    fs::write(&extra, "a file the adapter now hashes").unwrap();
    let statuses = s.statuses();
    assert_eq!(
        statuses["act"]["reason"],
        json!({"cause": "source_file_changed", "file": "meta/notes.txt", "change": "added"})
    );
    fs::remove_file(&extra).unwrap();
    up_to_date(&s);

    // Outputs: missing, then modified.
    let stats = s.out("dp/stats.json");
    let stats_bytes = fs::read(&stats).unwrap();
    fs::remove_file(&stats).unwrap();
    let shown = stats.display().to_string();
    expect(
        &s,
        "dp",
        json!({"cause": "output_missing", "path": shown}),
        &format!("{shown} is missing"),
        &["act"],
    );
    fs::write(&stats, [stats_bytes.as_slice(), b" "].concat()).unwrap();
    expect(
        &s,
        "dp",
        json!({"cause": "output_modified", "path": shown}),
        &format!("{shown} was modified"),
        &["act"],
    );
    fs::write(&stats, &stats_bytes).unwrap();
    up_to_date(&s);

    // The tool version, as a lock written by another chunkc.
    let lock_bytes = fs::read_to_string(s.lock()).unwrap();
    let mut lock: serde_json::Value = serde_json::from_str(&lock_bytes).unwrap();
    let entry = &mut lock["specs"]["pusht.toml"];
    entry["tool_version"] = json!("0.0.1");
    fs::write(s.lock(), lock.to_string()).unwrap();
    expect(
        &s,
        "act",
        json!({"cause": "tool_version_changed", "old": "0.0.1", "new": env!("CARGO_PKG_VERSION")}),
        &format!("chunkc changed (0.0.1 -> {})", env!("CARGO_PKG_VERSION")),
        &[],
    );

    // A lock from before the per-value and per-file records still reads; a change it cannot
    // place is named as well as it can be.
    let mut old: serde_json::Value = serde_json::from_str(&lock_bytes).unwrap();
    let entry = old["specs"]["pusht.toml"].as_object_mut().unwrap();
    entry
        .remove("source_files")
        .expect("the lock records source files");
    for p in entry["profiles"].as_object_mut().unwrap().values_mut() {
        p.as_object_mut()
            .unwrap()
            .remove("inputs")
            .expect("the lock records inputs");
    }
    fs::write(s.lock(), old.to_string()).unwrap();
    up_to_date(&s);
    fs::write(&s.spec, spec.replace("chunk = 20", "chunk = 10")).unwrap();
    expect(
        &s,
        "act",
        json!({"cause": "fingerprint_changed"}),
        "the spec or the source changed",
        &["dp"],
    );
    fs::write(&s.spec, &spec).unwrap();
    fs::write(&zarray, [before.as_slice(), b"\n"].concat()).unwrap();
    expect(
        &s,
        "dp",
        json!({"cause": "source_changed"}),
        "the source changed",
        &[],
    );
}

/// A Zarr store's chunk files are hashed from the bytes as they are written, not read back: the
/// lock's hash of every output file is that of the file on disk, and a rebuild finds them all
/// up to date.
#[test]
fn files_hashed_as_written_are_the_files_on_disk() {
    let s = Scratch::new();
    let spec = fs::read_to_string(&s.spec).unwrap();
    let zarr = spec.replacen("format = \"hdf5\"", "format = \"zarr\"", 1);
    assert_ne!(zarr, spec);
    fs::write(&s.spec, zarr).unwrap();
    s.build();
    let lock: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(s.lock()).unwrap()).unwrap();
    let files = lock["specs"]["pusht.toml"]["profiles"]["dp"]["files"]
        .as_object()
        .unwrap();
    // Chunk files (not `.zarray`, `.zgroup` or `zarr.json`) of the store's arrays.
    let chunks = files
        .keys()
        .filter(|f| f.starts_with("data.zarr/") && !f.rsplit('/').next().unwrap().contains('z'))
        .count();
    assert!(chunks >= 4, "{} files, {chunks} chunks", files.len());
    for (rel, hash) in files {
        let bytes = fs::read(s.out(&format!("dp/{rel}"))).unwrap();
        assert_eq!(hash, &blake3::hash(&bytes).to_hex().to_string(), "{rel}");
    }
    up_to_date(&s);
}
