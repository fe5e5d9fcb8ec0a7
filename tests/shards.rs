//! Sharded builds (`build --shard I/N --partials DIR`, then `merge`): the merged outputs are the
//! single-machine build's bytes for any N and thread count; a retried shard writes the same
//! partial; a missing, damaged or stale partial fails the merge naming the shard, and nothing is
//! written.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;
use common::{copy_dir, file_hashes};

const REPO: &str = env!("CARGO_MANIFEST_DIR");

/// A scratch copy of `specs/<name>.toml` and the data it reads: (tempdir, spec, out dir).
fn scratch(name: &str, data: &str) -> (tempfile::TempDir, PathBuf, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let from = Path::new(REPO).join("tests/data").join(data);
    let to = tmp.path().join("tests/data").join(data);
    if from.is_dir() {
        copy_dir(&from, &to);
    } else {
        fs::create_dir_all(to.parent().unwrap()).unwrap();
        fs::copy(&from, &to).unwrap();
    }
    fs::create_dir(tmp.path().join("specs")).unwrap();
    let spec = tmp.path().join(format!("specs/{name}.toml"));
    fs::copy(Path::new(REPO).join(format!("specs/{name}.toml")), &spec).unwrap();
    let out = tmp.path().join("out").join(name);
    (tmp, spec, out)
}

fn chunkc(args: &[&str], spec: &Path, threads: usize) -> Output {
    Command::new(env!("CARGO_BIN_EXE_chunkc"))
        .args(["-j", &threads.to_string()])
        .args(args)
        .arg(spec)
        .output()
        .unwrap()
}

fn ok(out: Output) -> Output {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn run_shards(spec: &Path, parts: &Path, n: usize) {
    for i in 0..n {
        let shard = format!("{i}/{n}");
        let parts = parts.to_str().unwrap();
        // Shards at different thread counts: the partial does not depend on them.
        ok(chunkc(
            &["build", "-q", "--shard", &shard, "--partials", parts],
            spec,
            1 + i % 2,
        ));
    }
}

fn merge(spec: &Path, parts: &Path) -> Output {
    chunkc(
        &["merge", "-q", "--partials", parts.to_str().unwrap()],
        spec,
        2,
    )
}

fn reset(spec: &Path, out: &Path, parts: &Path) {
    for dir in [out, parts] {
        if dir.exists() {
            fs::remove_dir_all(dir).unwrap();
        }
    }
    let lock = spec.with_file_name("chunkc.lock");
    if lock.exists() {
        fs::remove_file(lock).unwrap();
    }
}

#[test]
fn shards_merge_to_the_single_machine_bytes() {
    for (name, data) in [
        ("multi_arch", "robosuite_panda_lift.hdf5"),
        ("pusht", "pusht_subset.zarr"),
    ] {
        let (tmp, spec, out) = scratch(name, data);
        ok(chunkc(&["build", "-q"], &spec, 2));
        let reference = file_hashes(&out).unwrap();
        assert!(reference.len() > 5, "{name}: {reference:?}");
        let parts = tmp.path().join("partials");
        for n in [1, 2, 3, 7] {
            reset(&spec, &out, &parts);
            run_shards(&spec, &parts, n);
            ok(merge(&spec, &parts));
            let merged = file_hashes(&out).unwrap();
            for (path, hash) in &reference {
                assert_eq!(
                    merged.get(path),
                    Some(hash),
                    "{name}, {n} shards: {}",
                    path.display()
                );
            }
            assert_eq!(merged.len(), reference.len(), "{name}, {n} shards");
            // The merge wrote the lock as a build does: the next build has nothing to do.
            let again = ok(chunkc(&["build", "-q", "--locked"], &spec, 2));
            assert!(String::from_utf8_lossy(&again.stderr).contains("up to date"));
        }
    }
}

#[test]
fn a_retried_shard_writes_the_same_partial() {
    let (tmp, spec, _) = scratch("pusht", "pusht_subset.zarr");
    let parts = tmp.path().join("partials");
    let path = parts.join("shard-00001-of-00003.partial");
    ok(chunkc(
        &[
            "build",
            "-q",
            "--shard",
            "1/3",
            "--partials",
            parts.to_str().unwrap(),
        ],
        &spec,
        2,
    ));
    let first = fs::read(&path).unwrap();
    // A retry finds its own scratch directory and partial, and replaces them.
    fs::create_dir_all(parts.join(".work-00001-of-00003/leftover")).unwrap();
    ok(chunkc(
        &[
            "build",
            "-q",
            "--shard",
            "1/3",
            "--partials",
            parts.to_str().unwrap(),
        ],
        &spec,
        1,
    ));
    assert!(
        fs::read(&path).unwrap() == first,
        "a retried shard changed its partial"
    );
    let names: Vec<String> = fs::read_dir(&parts)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        vec!["shard-00001-of-00003.partial"],
        "scratch left behind"
    );
}

#[test]
fn a_missing_damaged_or_stale_partial_fails_and_writes_nothing() {
    let (tmp, spec, out) = scratch("pusht", "pusht_subset.zarr");
    let parts = tmp.path().join("partials");
    run_shards(&spec, &parts, 3);
    let shard = |i: usize| parts.join(format!("shard-{i:05}-of-00003.partial"));
    let fails = |want: &[&str]| {
        let r = merge(&spec, &parts);
        let err = String::from_utf8_lossy(&r.stderr).into_owned();
        assert!(!r.status.success(), "merge succeeded");
        for w in want {
            assert!(err.contains(w), "`{w}` not in: {err}");
        }
        assert!(!out.exists(), "the failed merge left {}", out.display());
        assert!(!spec.with_file_name("chunkc.lock").exists());
    };
    // Missing.
    let kept = fs::read(shard(1)).unwrap();
    fs::remove_file(shard(1)).unwrap();
    fails(&["shard 1/3 is missing", "--shard 1/3"]);
    // Damaged (one flipped byte), then truncated.
    let mut bad = kept.clone();
    let at = bad.len() / 2;
    bad[at] ^= 0x40;
    fs::write(shard(1), &bad).unwrap();
    fails(&["shard-00001-of-00003.partial", "checksum mismatch"]);
    fs::write(shard(1), &kept[..kept.len() - 100]).unwrap();
    fails(&["shard-00001-of-00003.partial", "checksum mismatch"]);
    // Stale: the spec changed after the shards ran.
    fs::write(shard(1), &kept).unwrap();
    let text = fs::read_to_string(&spec)
        .unwrap()
        .replace("chunk = 20", "chunk = 10");
    fs::write(&spec, text).unwrap();
    fails(&["shard 0/3", "is stale", "plan differs"]);
    // Partials of two runs with different N.
    run_shards(&spec, &parts, 2);
    fails(&["different shard counts (2, 3)"]);
}

#[test]
fn plan_shows_every_episode_in_one_shard() {
    let (_tmp, spec, _) = scratch("pusht", "pusht_subset.zarr");
    let out = ok(chunkc(
        &["plan", "--shards", "3", "--format", "json"],
        &spec,
        2,
    ));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let shards = v["shards"]["shards"].as_array().unwrap();
    assert_eq!(shards.len(), 3);
    let mut next = 0;
    let mut steps = 0;
    for s in shards {
        assert_eq!(s["episodes"][0].as_u64().unwrap(), next);
        next = s["episodes"][1].as_u64().unwrap();
        steps += s["steps"].as_u64().unwrap();
        assert!(s["read_seconds"].as_f64().unwrap() >= 0.0);
    }
    assert_eq!(next, v["source"]["episodes"].as_u64().unwrap());
    assert_eq!(steps, v["source"]["steps"].as_u64().unwrap());
    let text = ok(chunkc(&["plan", "--shards", "3"], &spec, 2));
    assert!(String::from_utf8_lossy(&text.stdout).contains("--shard I/3"));
}
