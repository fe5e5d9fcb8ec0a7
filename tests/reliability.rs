//! Interrupted and concurrent builds, panics, exclusion and determinism, on the vendored Push-T
//! subset (`specs/pusht.toml`, copied into a temp directory with its data).
//!
//! - `killed_builds_leave_old_or_no_output`: 30 builds killed with SIGKILL at pseudo-random
//!   delays; after each, every profile directory is absent or identical to a clean build's, and
//!   a rerun completes with the clean build's bytes.
//! - `outputs_do_not_depend_on_thread_count`: BLAKE3 of every output with 1, 2 and 8 threads and
//!   twice with 2, then `--locked` passes, and fails (exit 5) once the spec changes.
//! - `a_second_build_fails_while_one_runs`, `a_panicking_episode_is_an_internal_error`,
//!   `non_finite_episodes_can_be_excluded`.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

mod common;
use common::{copy_dir, file_hashes};

const REPO: &str = env!("CARGO_MANIFEST_DIR");
const PROFILES: [&str; 2] = ["act", "dp"];

/// A scratch copy of `specs/pusht.toml` with its data; returns (tempdir, spec path, out dir).
fn pusht() -> (tempfile::TempDir, PathBuf, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    copy_dir(
        &Path::new(REPO).join("tests/data/pusht_subset.zarr"),
        &tmp.path().join("tests/data/pusht_subset.zarr"),
    );
    fs::create_dir(tmp.path().join("specs")).unwrap();
    let spec = tmp.path().join("specs/pusht.toml");
    fs::copy(Path::new(REPO).join("specs/pusht.toml"), &spec).unwrap();
    let out = tmp.path().join("out/pusht");
    (tmp, spec, out)
}

fn chunkc(spec: &Path, args: &[&str], threads: &str) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_chunkc"));
    cmd.arg("build").arg("-q").args(args).arg(spec);
    cmd.env("RAYON_NUM_THREADS", threads);
    cmd
}

fn build(spec: &Path, threads: &str) -> Output {
    let out = chunkc(spec, &[], threads).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn all_outputs(out: &Path) -> BTreeMap<&'static str, Option<BTreeMap<PathBuf, String>>> {
    PROFILES
        .iter()
        .map(|p| (*p, file_hashes(&out.join(p))))
        .collect()
}

#[test]
fn killed_builds_leave_old_or_no_output() {
    let (_tmp, spec, out) = pusht();
    let lock = spec.with_file_name("chunkc.lock");
    let t0 = Instant::now();
    build(&spec, "2");
    let clean_time = t0.elapsed();
    let clean = all_outputs(&out);
    let clean_lock = fs::read(&lock).unwrap();
    assert!(clean.values().all(Option::is_some));

    let started = Instant::now();
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let (mut none, mut old) = (0, 0);
    for i in 0..30 {
        if i % 2 == 0 {
            // From nothing: the profiles must come out absent or complete.
            fs::remove_dir_all(&out).unwrap();
        }
        // Without the lock every profile is rebuilt, replacing the previous complete output.
        fs::remove_file(&lock).unwrap();
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let delay = clean_time.mul_f64((seed % 1000) as f64 / 1000.0 * 1.2);
        let mut child = chunkc(&spec, &[], "2").spawn().unwrap();
        std::thread::sleep(delay);
        child.kill().unwrap(); // SIGKILL
        child.wait().unwrap();
        for (profile, got) in all_outputs(&out) {
            match got {
                None => none += 1,
                Some(files) => {
                    assert_eq!(
                        Some(&files),
                        clean[profile].as_ref(),
                        "iteration {i}: `{profile}` after SIGKILL at {delay:?} is neither absent nor complete"
                    );
                    old += 1;
                }
            }
        }
        build(&spec, "2");
        assert_eq!(all_outputs(&out), clean, "iteration {i}: the rerun differs");
        assert_eq!(fs::read(&lock).unwrap(), clean_lock, "iteration {i}");
        assert!(!out.join(chunkc::exec::STAGING_DIR).exists());
    }
    eprintln!(
        "30 kills: {none} profile directories absent, {old} complete, in {:?}",
        started.elapsed()
    );
    assert!(started.elapsed() < Duration::from_secs(300));
}

#[test]
fn outputs_do_not_depend_on_thread_count() {
    let mut seen = Vec::new();
    for threads in ["1", "2", "8", "2"] {
        let (_tmp, spec, out) = pusht();
        build(&spec, threads);
        let mut all = all_outputs(&out);
        all.insert(
            "chunkc.lock",
            file_hashes(spec.parent().unwrap()).map(|mut files| {
                files.retain(|p, _| p == Path::new("chunkc.lock"));
                files
            }),
        );
        if threads == "2" && seen.len() == 3 {
            // The second run with 2 threads: also check `--locked`.
            let locked = chunkc(&spec, &["--locked"], "2").output().unwrap();
            assert!(
                locked.status.success(),
                "{}",
                String::from_utf8_lossy(&locked.stderr)
            );
            let text = fs::read_to_string(&spec)
                .unwrap()
                .replace("chunk = 20", "chunk = 10");
            fs::write(&spec, text).unwrap();
            let locked = chunkc(&spec, &["--locked"], "2").output().unwrap();
            assert_eq!(locked.status.code(), Some(5));
            assert_eq!(all_outputs(&out), {
                let mut a = all.clone();
                a.remove("chunkc.lock");
                a
            });
        }
        seen.push((threads, all));
    }
    for (threads, all) in &seen[1..] {
        assert_eq!(
            all, &seen[0].1,
            "RAYON_NUM_THREADS={threads} differs from 1"
        );
    }
}

#[test]
fn a_second_build_fails_while_one_runs() {
    let (_tmp, spec, out) = pusht();
    fs::create_dir_all(&out).unwrap();
    // Hold the lock as a running build would.
    let held = fs::File::create(out.join(chunkc::exec::BUILD_LOCK_FILE)).unwrap();
    held.lock().unwrap();
    let second = chunkc(&spec, &[], "2").output().unwrap();
    let stderr = String::from_utf8_lossy(&second.stderr);
    assert_eq!(second.status.code(), Some(6), "{stderr}");
    assert!(
        stderr.contains("another chunkc build is writing to"),
        "{stderr}"
    );
    assert!(all_outputs(&out).values().all(Option::is_none));
    drop(held);
    build(&spec, "2");
}

#[test]
fn a_panicking_episode_is_an_internal_error() {
    let (_tmp, spec, out) = pusht();
    let output = chunkc(&spec, &[], "2")
        .env("CHUNKC_TEST_PANIC_EPISODE", "3")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(70), "{stderr}");
    assert!(
        stderr.contains("internal error: panic while processing episode 3"),
        "{stderr}"
    );
    assert!(!out.exists(), "a failed first build left {}", out.display());
}

#[test]
fn non_finite_episodes_can_be_excluded() {
    let (_tmp, spec, out) = pusht();
    // Episode 2's first action becomes NaN: rewrite that chunk of the store uncompressed.
    let root = spec
        .parent()
        .unwrap()
        .join("../tests/data/pusht_subset.zarr");
    let action = root.join("data/action");
    let zarray: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(action.join(".zarray")).unwrap()).unwrap();
    let rows = zarray["chunks"][0].as_u64().unwrap();
    let ends: Vec<u64> = {
        let out = Command::new(env!("CARGO_BIN_EXE_chunkc"))
            .args(["plan", "--format", "json"])
            .arg(&spec)
            .output()
            .unwrap();
        let plan: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        plan["profiles"][0]["episodes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["source_len"].as_u64().unwrap())
            .collect()
    };
    let step = ends[0] + ends[1]; // first step of episode 2
    let chunk = step / rows;
    let text = fs::read_to_string(action.join(".zarray")).unwrap();
    let mut meta: serde_json::Value = serde_json::from_str(&text).unwrap();
    meta["compressor"] = serde_json::Value::Null;
    // Decode every chunk with chunkc's own reader is overkill: write all chunks as NaN-free
    // copies is not possible without a decoder, so rewrite the one chunk as all-NaN.
    let width = meta["shape"][1].as_u64().unwrap();
    let nan: Vec<u8> = (0..rows * width)
        .flat_map(|_| f32::NAN.to_le_bytes())
        .collect();
    // Only this chunk changes compression, which zarr v2 cannot express per chunk: move the
    // array to an uncompressed copy whose other chunks are zeros.
    for entry in fs::read_dir(&action).unwrap() {
        let path = entry.unwrap().path();
        if path.file_name().unwrap() != ".zarray" {
            fs::remove_file(path).unwrap();
        }
    }
    fs::write(action.join(".zarray"), meta.to_string()).unwrap();
    fs::write(action.join(format!("{chunk}.0")), nan).unwrap();

    let text = fs::read_to_string(&spec).unwrap();
    fs::write(
        &spec,
        format!("{text}\n[audit]\nnon_finite = \"exclude_episode\"\n"),
    )
    .unwrap();
    let first = build(&spec, "2");
    assert!(first.status.success());
    let meta: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out.join("dp/meta.json")).unwrap()).unwrap();
    let excluded: Vec<u64> = meta["excluded"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["id"].as_u64().unwrap())
        .collect();
    let lo = ends.iter().scan(0, |acc, &l| {
        *acc += l;
        Some(*acc)
    });
    let expected: Vec<u64> = std::iter::once(0)
        .chain(lo)
        .collect::<Vec<_>>()
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0] < (chunk + 1) * rows && w[1] > chunk * rows)
        .map(|(i, _)| i as u64)
        .collect();
    assert_eq!(excluded, expected);
    let stored: Vec<u64> = meta["episodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e.as_u64().unwrap())
        .collect();
    assert!(excluded.iter().all(|e| !stored.contains(e)));
    // Deterministic: another thread count gives the same bytes, and the next build is a no-op.
    let before = all_outputs(&out);
    fs::remove_file(spec.with_file_name("chunkc.lock")).unwrap();
    build(&spec, "8");
    assert_eq!(all_outputs(&out), before);
    let again = build(&spec, "1");
    assert!(String::from_utf8_lossy(&again.stderr).contains("up to date"));
}
