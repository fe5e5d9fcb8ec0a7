//! RLDS sources from the command line, without Python: the Bridge fixture builds with TFDS's
//! splits and the episodes' tasks; a missing `source.fps` is a spec error at its table; a
//! corrupt record fails with the shard, the record offset and "checksum", leaving no output.
//! (The values themselves are checked against an independent reader in
//! tests/python/test_rlds.py.)

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const REPO: &str = env!("CARGO_MANIFEST_DIR");
const SHARD: &str = "bridge_dataset-train.tfrecord-00000-of-00001";

fn bridge() -> PathBuf {
    Path::new(REPO).join("tests/data/rlds-bridge/bridge_dataset")
}

fn spec(dir: &Path, source: &Path, fps: Option<u32>) -> PathBuf {
    let fps = fps.map(|f| format!("fps = {f}\n")).unwrap_or_default();
    let text = format!(
        "version = 1\n\n[source]\nformat = \"rlds\"\npath = \"{}\"\n{fps}\n[source.channels]\n\
         action = \"steps/action\"\n\"observation.state\" = \"steps/observation/state\"\n\
         \"observation.image\" = \"steps/observation/image_0\"\n\n[split]\nfrom = \"source\"\n\n\
         [output]\ndir = \"out\"\n\n[profiles.act]\npreset = \"act\"\nfps = 5\nchunk = 4\n",
        source.display()
    );
    let path = dir.join("spec.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn chunkc(args: &[&str], spec: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_chunkc"))
        .args(args)
        .arg(spec)
        .output()
        .unwrap()
}

#[test]
fn bridge_builds_with_the_tfds_splits_and_tasks() {
    let dir = tempfile::tempdir().unwrap();
    let out = chunkc(&["build", "-q"], &spec(dir.path(), &bridge(), Some(5)));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("out/act/meta.json")).unwrap())
            .unwrap();
    let ids = |s: &str| meta["split"][s].as_array().unwrap().len();
    assert_eq!((ids("train"), ids("val")), (25, 25));
    assert_eq!(meta["source"]["format"], "rlds");
    let tasks = meta["tasks"].as_object().unwrap();
    assert_eq!(tasks.len(), 50);
    assert!(tasks
        .values()
        .all(|t| t.as_str().is_some_and(|t| !t.is_empty())));
}

#[test]
fn a_missing_fps_is_a_spec_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = chunkc(&["check"], &spec(dir.path(), &bridge(), None));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("`source.fps` is required") && err.contains("spec.toml:3"),
        "{err}"
    );
}

#[test]
fn a_flipped_byte_names_the_shard_and_record() {
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("bridge/1.0.0");
    std::fs::create_dir_all(&copy).unwrap();
    for entry in std::fs::read_dir(bridge().join("1.0.0")).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), copy.join(entry.file_name())).unwrap();
    }
    let shard = copy.join(SHARD);
    let mut bytes = std::fs::read(&shard).unwrap();
    // The second record's header starts after the first record (12 + len + 4 bytes).
    let first = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let second = 16 + first;
    bytes[second + 12 + 7] ^= 0x01;
    std::fs::write(&shard, &bytes).unwrap();
    let out = chunkc(
        &["build", "-q"],
        &spec(dir.path(), &dir.path().join("bridge"), Some(5)),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains(SHARD)
            && err.contains(&format!("record 1 at byte offset {second}"))
            && err.contains("checksum"),
        "{err}"
    );
    assert!(!dir.path().join("out/act/meta.json").exists());
}

#[test]
fn the_doctors_low_dim_read_equals_the_episodes_values() {
    // The doctor reads `read_lowdim` (no JPEG decoded) before the build's `read_episode`: the
    // same values, every channel, every episode of both splits.
    let dir = tempfile::tempdir().unwrap();
    let spec = chunkc::spec::LoadedSpec::load(&spec(dir.path(), &bridge(), Some(5))).unwrap();
    let source = chunkc::source::open(&spec).unwrap();
    let manifest = source.manifest();
    let lowdim: Vec<usize> = (0..manifest.channels.len())
        .filter(|&c| manifest.channels[c].shape.len() < 3)
        .collect();
    assert_eq!(lowdim.len(), 2);
    assert_eq!(manifest.episodes.len(), 50);
    for i in 0..manifest.episodes.len() {
        let read = source.read_lowdim(i, &lowdim).unwrap();
        let whole = source.read_episode(i).unwrap().take_lowdim(&lowdim);
        assert_eq!(read, whole, "episode {i}");
        assert!(read.iter().all(|v| !v.is_empty()), "episode {i}");
    }
}
