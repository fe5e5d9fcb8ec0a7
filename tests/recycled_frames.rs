//! Decoded camera frames land in recycled buffers (`chunkc::recycle`) that hold a previous
//! user's bytes; none of those bytes may reach the output. The same LeRobot AV1 source is built
//! with an empty pool and with a pool of buffers filled with a pattern no frame has (0xA5 in
//! every byte, larger than every episode's frames, so the decode takes them): every output file
//! must be the same, byte for byte.

#![cfg(feature = "video")]

use std::path::{Path, PathBuf};

use chunkc::commands::{self, BuildOptions};
use chunkc::recycle;
use chunkc::spec::LoadedSpec;

mod common;

fn build(dir: &Path, name: &str) -> PathBuf {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/lerobot_video_v3_av1");
    let spec = dir.join(format!("{name}.toml"));
    std::fs::write(
        &spec,
        format!(
            r#"version = 1
[source]
format = "lerobot"
path = "{}"
[source.channels]
action = "action"
"observation.state" = "observation.state"
"observation.top" = "observation.images.top"
"observation.wrist" = "observation.images.wrist"
[split]
val_fraction = 0.0
[output]
dir = "out_{name}"
[profiles.h]
preset = "act"
fps = 10
chunk = 5
format = "hdf5"
[profiles.z]
preset = "diffusion_policy"
format = "zarr"
"#,
            source.display()
        ),
    )
    .unwrap();
    let loaded = LoadedSpec::load(&spec).unwrap();
    commands::build(&loaded, &BuildOptions::default()).unwrap();
    dir.join(format!("out_{name}"))
}

#[test]
fn recycled_buffers_leave_no_byte_in_the_output() {
    let tmp = tempfile::tempdir().unwrap();
    recycle::clear();
    let clean = build(tmp.path(), "clean");
    // Fill the pool (it keeps one buffer per thread of rayon's pool).
    for _ in 0..recycle::MAX_BUFFERS_PER_THREAD * rayon::current_num_threads() {
        recycle::give(vec![0xA5; recycle::MIN_BYTES]);
    }
    let poisoned = build(tmp.path(), "poisoned");
    let hashes = |dir: &Path| {
        let mut h = common::file_hashes(dir).unwrap();
        // Each names its own spec.
        h.retain(|p, _| {
            !matches!(
                p.file_name().and_then(|n| n.to_str()),
                Some("README.md" | "meta.json")
            )
        });
        h
    };
    let (a, b) = (hashes(&clean), hashes(&poisoned));
    assert!(a.len() > 10, "the builds wrote too little: {a:?}");
    assert_eq!(a, b, "a recycled buffer's bytes reached the output");
}
