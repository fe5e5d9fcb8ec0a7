//! A training mixture's row stores keep each source's own dimensions only: its padding is read
//! back as zeros, never stored. The outputs must not depend on where the rows were kept: a
//! mixture whose stores spill to disk (a budget of 256 bytes) gives the same files, byte for
//! byte, as one kept in memory, in every format and layout that reads the stores.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

const REPO: &str = env!("CARGO_MANIFEST_DIR");

fn spec(out: &Path) -> String {
    let g1 = Path::new(REPO).join("tests/data/lerobot_g1_subset");
    let pusht = Path::new(REPO).join("tests/data/pusht_subset.zarr");
    format!(
        r#"version = 1
[sources.own]
format = "lerobot"
path = "{g1}"
[sources.own.channels]
action = "action"
"observation.state" = "observation.state"
[sources.sim]
format = "diffusion_policy_zarr"
path = "{pusht}"
fps = 10
[sources.sim.channels]
action = "action"
"observation.state" = "state"
[mixture]
pad_to = {{ action = 32, "observation.state" = 32 }}
[output]
dir = "{out}"
[profiles.dp]
preset = "diffusion_policy"
fps = 10
format = "zarr"
[profiles.act]
preset = "act"
fps = 10
chunk = 8
layout = "materialized"
[profiles.robomimic]
preset = "act"
fps = 10
chunk = 8
format = "robomimic_hdf5"
"#,
        g1 = g1.display(),
        pusht = pusht.display(),
        out = out.display(),
    )
}

/// Builds the mixture in `dir` from scratch with `env`; every output file's BLAKE3.
fn build(dir: &Path, env: &[(&str, &str)]) -> BTreeMap<PathBuf, String> {
    let out = dir.join("out");
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_file(dir.join("chunkc.lock"));
    let spec_path = dir.join("spec.toml");
    std::fs::write(&spec_path, spec(&out)).unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_chunkc"))
        .args(["build", "-q", "-j", "2"])
        .arg(&spec_path)
        .envs(env.iter().copied())
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "the mixture build failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let mut hashes = BTreeMap::new();
    let mut stack = vec![out.clone()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path.strip_prefix(&out).unwrap().to_path_buf();
                let hash = blake3::hash(&std::fs::read(&path).unwrap());
                hashes.insert(rel, hash.to_hex().to_string());
            }
        }
    }
    hashes
}

#[test]
fn a_mixture_spilled_or_in_memory_writes_the_same_bytes() {
    // One directory for both: the documents name the output's path.
    let dir = tempfile::tempdir().unwrap();
    let memory = build(dir.path(), &[]);
    let spilled = build(dir.path(), &[("CHUNKC_SPILL_BYTES", "256")]);
    assert!(memory.keys().any(|p| p.starts_with("dp/data.zarr")));
    assert!(memory.keys().any(|p| p.starts_with("robomimic")));
    assert_eq!(
        memory.keys().collect::<Vec<_>>(),
        spilled.keys().collect::<Vec<_>>()
    );
    for (rel, hash) in &memory {
        assert_eq!(
            hash,
            &spilled[rel],
            "{} differs when the mixture's rows spill",
            rel.display()
        );
    }
}
