//! Bad input, one case per row of [`cases`]: each builds a small source in a temp directory
//! (zarr v2 stores written by hand, uncompressed; copies of the vendored HDF5 and parquet files,
//! damaged), runs `chunkc build`, and asserts
//! - the message (insta snapshot `tests/snapshots/bad_input__<case>.snap`, temp paths redacted),
//! - the exit code (in the snapshot, and one of the documented codes),
//! - that the output directory is absent, or unchanged when a previous build had filled it.
//!
//! Accept message changes with `INSTA_UPDATE=always cargo test --release --test bad_input`.

use std::collections::BTreeMap;
use std::fs;
use std::path::Path;
use std::process::Command;

mod common;
use common::{copy_dir, file_hashes};

const REPO: &str = env!("CARGO_MANIFEST_DIR");

/// A Diffusion Policy replay buffer: 3 episodes of 20 steps, `action` (2) and `state` (3).
struct Zarr {
    ends: Vec<i64>,
    /// key → (dtype, shape, little-endian bytes)
    data: BTreeMap<String, (String, Vec<usize>, Vec<u8>)>,
}

impl Zarr {
    fn good() -> Self {
        let f32s = |n: usize, scale: f32| -> Vec<u8> {
            (0..n)
                .flat_map(|i| ((i as f32 * 0.37).sin() * scale).to_le_bytes())
                .collect()
        };
        let mut data = BTreeMap::new();
        data.insert("action".into(), ("<f4".into(), vec![60, 2], f32s(120, 1.0)));
        data.insert("state".into(), ("<f4".into(), vec![60, 3], f32s(180, 5.0)));
        Zarr {
            ends: vec![20, 40, 60],
            data,
        }
    }

    /// Sets one f32 value of `key`.
    fn set(mut self, key: &str, index: usize, value: f32) -> Self {
        let bytes = &mut self.data.get_mut(key).unwrap().2;
        bytes[index * 4..index * 4 + 4].copy_from_slice(&value.to_le_bytes());
        self
    }

    fn write(&self, root: &Path) {
        write_array(
            root,
            "meta/episode_ends",
            "<i8",
            &[self.ends.len()],
            &self
                .ends
                .iter()
                .flat_map(|e| e.to_le_bytes())
                .collect::<Vec<_>>(),
        );
        for (key, (dtype, shape, bytes)) in &self.data {
            write_array(root, &format!("data/{key}"), dtype, shape, bytes);
        }
        for group in ["", "data", "meta"] {
            fs::write(root.join(group).join(".zgroup"), "{\"zarr_format\": 2}").unwrap();
        }
    }
}

/// A zarr v2 array in one uncompressed chunk.
fn write_array(root: &Path, key: &str, dtype: &str, shape: &[usize], bytes: &[u8]) {
    let dir = root.join(key);
    fs::create_dir_all(&dir).unwrap();
    let zarray = serde_json::json!({
        "chunks": shape, "compressor": null, "dtype": dtype, "fill_value": 0,
        "filters": null, "order": "C", "shape": shape, "zarr_format": 2,
    });
    fs::write(dir.join(".zarray"), zarray.to_string()).unwrap();
    let chunk = vec!["0"; shape.len()].join(".");
    fs::write(dir.join(chunk), bytes).unwrap();
}

const ZARR_SPEC: &str = r#"version = 1

[source]
format = "diffusion_policy_zarr"
path = "src.zarr"
fps = 10

[source.channels]
action = "action"
"observation.state" = "state"

[split]
val_fraction = 0.34
seed = 0

[output]
dir = "out"

[profiles.dp]
preset = "diffusion_policy"
chunk = 8
format = "hdf5"
"#;

fn truncate_half(path: &Path) {
    let bytes = fs::read(path).unwrap();
    fs::write(path, &bytes[..bytes.len() / 2]).unwrap();
}

/// The robosuite Panda file with column 0 of `states` (simulation time, the timestamps) edited.
fn robosuite_with_time(dir: &Path, edit: impl Fn(&mut [f64], usize)) {
    let path = dir.join("src.hdf5");
    fs::copy(
        Path::new(REPO).join("tests/data/robosuite_panda_lift.hdf5"),
        &path,
    )
    .unwrap();
    let file = hdf5::File::open_rw(&path).unwrap();
    let data = file.group("data").unwrap();
    let demo = data.member_names().unwrap()[0].clone();
    let ds = data.dataset(&format!("{demo}/states")).unwrap();
    let cols = ds.shape()[1];
    let mut all = ds.read_raw::<f64>().unwrap();
    edit(&mut all, cols);
    ds.write_raw(&all).unwrap();
}

/// `[output] follow_symlinks = true` is the way to write through a symlink: the same setup as
/// `output_through_an_unasked_symlink` builds, into the link's target.
#[test]
fn follow_symlinks_opts_in() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let spec =
        zarr(dir, Zarr::good()).replace("dir = \"out\"", "dir = \"out\"\nfollow_symlinks = true");
    assert!(spec.contains("follow_symlinks"));
    fs::write(dir.join("spec.toml"), spec).unwrap();
    fs::create_dir(dir.join("elsewhere")).unwrap();
    std::os::unix::fs::symlink(dir.join("elsewhere"), dir.join("out")).unwrap();
    let output = build(dir);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(dir.join("elsewhere/dp").is_dir());
    assert!(fs::symlink_metadata(dir.join("out")).unwrap().is_symlink());
}

const ROBOSUITE_SPEC: &str = r#"version = 1

[source]
format = "robomimic_hdf5"
path = "src.hdf5"

[source.channels]
action = "actions"
"observation.state" = { key = "states", columns = [1, 32] }

[split]
val_fraction = 0.0

[output]
dir = "out"

[profiles.act]
preset = "act"
fps = 20
chunk = 20
"#;

struct Case {
    name: &'static str,
    /// Writes the source (and anything else) into the case directory; returns the spec text.
    setup: fn(&Path) -> String,
    /// Build once with a good source before `damage`, to check that a failed build leaves the
    /// previous output unchanged.
    damage: Option<fn(&Path)>,
}

fn zarr(dir: &Path, z: Zarr) -> String {
    z.write(&dir.join("src.zarr"));
    ZARR_SPEC.to_string()
}

fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "nan_in_action",
            setup: |d| zarr(d, Zarr::good().set("action", 2 * 25 + 1, f32::NAN)),
            damage: None,
        },
        Case {
            name: "inf_in_state",
            setup: |d| zarr(d, Zarr::good().set("state", 3 * 47, f32::NEG_INFINITY)),
            damage: None,
        },
        Case {
            name: "nan_after_a_good_build",
            setup: |d| zarr(d, Zarr::good()),
            damage: Some(|d| {
                Zarr::good()
                    .set("action", 7, f32::NAN)
                    .write(&d.join("src.zarr"))
            }),
        },
        Case {
            name: "empty_episode",
            setup: |d| {
                let mut z = Zarr::good();
                z.ends = vec![20, 20, 60];
                zarr(d, z)
            },
            damage: None,
        },
        Case {
            name: "episodes_shorter_than_chunk_with_truncate",
            setup: |d| {
                zarr(d, Zarr::good()).replace("chunk = 8", "chunk = 30\npadding = \"truncate\"")
            },
            damage: None,
        },
        Case {
            name: "channel_lengths_differ",
            setup: |d| {
                let mut z = Zarr::good();
                let state = z.data.get_mut("state").unwrap();
                state.1 = vec![59, 3];
                state.2.truncate(59 * 3 * 4);
                zarr(d, z)
            },
            damage: None,
        },
        Case {
            name: "wrong_rank_for_kind",
            setup: |d| {
                let mut z = Zarr::good();
                z.data.get_mut("action").unwrap().1 = vec![60, 1, 1, 1, 2];
                zarr(d, z)
            },
            damage: None,
        },
        Case {
            name: "wrong_dtype",
            setup: |d| {
                let mut z = Zarr::good();
                let a = z.data.get_mut("action").unwrap();
                a.0 = "<c8".into();
                a.1 = vec![60, 1];
                zarr(d, z)
            },
            damage: None,
        },
        Case {
            name: "missing_key",
            setup: |d| {
                let mut z = Zarr::good();
                z.data.remove("state");
                zarr(d, z)
            },
            damage: None,
        },
        Case {
            name: "missing_episode_ends",
            setup: |d| {
                let spec = zarr(d, Zarr::good());
                fs::remove_dir_all(d.join("src.zarr/meta/episode_ends")).unwrap();
                spec
            },
            damage: None,
        },
        Case {
            name: "truncated_zarr_chunk",
            setup: |d| {
                let spec = zarr(d, Zarr::good());
                truncate_half(&d.join("src.zarr/data/state/0.0"));
                spec
            },
            damage: None,
        },
        Case {
            name: "corrupt_zarray",
            setup: |d| {
                let spec = zarr(d, Zarr::good());
                fs::write(
                    d.join("src.zarr/data/action/.zarray"),
                    "{\"zarr_format\": 2, \"sha",
                )
                .unwrap();
                spec
            },
            damage: None,
        },
        Case {
            name: "truncated_hdf5",
            setup: |d| {
                fs::copy(
                    Path::new(REPO).join("tests/data/robosuite_panda_lift.hdf5"),
                    d.join("src.hdf5"),
                )
                .unwrap();
                truncate_half(&d.join("src.hdf5"));
                ROBOSUITE_SPEC.to_string()
            },
            damage: None,
        },
        Case {
            name: "truncated_parquet",
            setup: |d| {
                copy_dir(
                    &Path::new(REPO).join("tests/data/lerobot_v3_synthetic"),
                    &d.join("src"),
                );
                truncate_half(&d.join("src/data/chunk-000/file-001.parquet"));
                fs::read_to_string(Path::new(REPO).join("specs/lerobot_v3.toml"))
                    .unwrap()
                    .replace("../tests/data/lerobot_v3_synthetic", "src")
                    .replace("../out/lerobot_v3", "out")
            },
            damage: None,
        },
        Case {
            name: "duplicate_timestamps",
            setup: |d| {
                robosuite_with_time(d, |t, cols| t[10 * cols] = t[9 * cols]);
                ROBOSUITE_SPEC.replace("[output]", "[audit]\nnon_monotonic = \"error\"\n\n[output]")
            },
            damage: None,
        },
        Case {
            // Every timestamp equal: the audit excludes the only episode.
            name: "all_duplicate_timestamps",
            setup: |d| {
                robosuite_with_time(d, |t, cols| {
                    for row in 0..t.len() / cols {
                        t[row * cols] = 0.5;
                    }
                });
                // With `fps` set (no rate can be derived from equal timestamps).
                ROBOSUITE_SPEC.replace("path = \"src.hdf5\"", "path = \"src.hdf5\"\nfps = 20")
            },
            damage: None,
        },
        Case {
            // Time goes back: `drop_duplicates` cannot repair it, the audit excludes the only
            // episode.
            name: "non_monotonic_timestamps",
            setup: |d| {
                robosuite_with_time(d, |t, cols| t[100 * cols] = 1.0);
                ROBOSUITE_SPEC.to_string()
            },
            damage: None,
        },
        Case {
            name: "unreadable_source_path",
            setup: |d| {
                std::os::unix::fs::symlink(d.join("gone.zarr"), d.join("src.zarr")).unwrap();
                ZARR_SPEC.to_string()
            },
            damage: None,
        },
        Case {
            name: "output_is_the_source",
            setup: |d| zarr(d, Zarr::good()).replace("dir = \"out\"", "dir = \"src.zarr\""),
            damage: None,
        },
        Case {
            name: "output_inside_the_source",
            setup: |d| zarr(d, Zarr::good()).replace("dir = \"out\"", "dir = \"src.zarr/out\""),
            damage: None,
        },
        Case {
            name: "output_symlink_into_the_source",
            setup: |d| {
                let spec = zarr(d, Zarr::good());
                std::os::unix::fs::symlink(d.join("src.zarr/data"), d.join("link")).unwrap();
                spec.replace("dir = \"out\"", "dir = \"link/out\"")
            },
            damage: None,
        },
        Case {
            name: "output_through_an_unasked_symlink",
            setup: |d| {
                let spec = zarr(d, Zarr::good());
                fs::create_dir(d.join("elsewhere")).unwrap();
                std::os::unix::fs::symlink(d.join("elsewhere"), d.join("out")).unwrap();
                spec
            },
            damage: None,
        },
        Case {
            name: "output_profile_dir_is_a_symlink",
            setup: |d| {
                let spec = zarr(d, Zarr::good());
                fs::create_dir_all(d.join("out")).unwrap();
                fs::create_dir(d.join("elsewhere")).unwrap();
                std::os::unix::fs::symlink(d.join("elsewhere"), d.join("out/dp")).unwrap();
                spec
            },
            damage: None,
        },
        Case {
            name: "val_fraction_leaves_no_training_episode",
            setup: |d| {
                zarr(d, Zarr::good())
                    .replace("fps = 10", "fps = 10\nepisodes = [1]")
                    .replace("val_fraction = 0.34", "val_fraction = 0.5")
            },
            damage: None,
        },
    ]
}

fn build(dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_chunkc"))
        .args(["build", "-q", "spec.toml"])
        .current_dir(dir)
        .output()
        .expect("chunkc runs")
}

#[test]
fn bad_input_fails_cleanly() {
    let cases = cases();
    assert!(cases.len() >= 15);
    for case in cases {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let spec = (case.setup)(dir);
        fs::write(dir.join("spec.toml"), spec).unwrap();
        let out = dir.join("out");
        if let Some(damage) = case.damage {
            let first = build(dir);
            assert!(first.status.success(), "{}: first build failed", case.name);
            damage(dir);
        }
        let before = file_hashes(&out);
        let lock_before = fs::read(dir.join("chunkc.lock")).ok();
        let output = build(dir);
        let code = output.status.code();
        let stderr = String::from_utf8_lossy(&output.stderr)
            .replace(&dir.display().to_string(), "[TMP]")
            .replace(&dir.canonicalize().unwrap().display().to_string(), "[TMP]");
        assert!(
            matches!(code, Some(2..=6) | Some(70)),
            "{}: exit {code:?}\n{stderr}",
            case.name
        );
        assert!(!stderr.contains("panicked"), "{}: {stderr}", case.name);
        assert_eq!(
            file_hashes(&out),
            before,
            "{}: the output directory changed",
            case.name
        );
        assert_eq!(
            fs::read(dir.join("chunkc.lock")).ok(),
            lock_before,
            "{}: chunkc.lock changed",
            case.name
        );
        assert_eq!(
            file_hashes(&dir.join("elsewhere")).filter(|files| !files.is_empty()),
            None,
            "{}: wrote through a symlink",
            case.name
        );
        assert!(
            !dir.join("src.zarr/out").exists(),
            "{}: wrote into the source",
            case.name
        );
        insta::with_settings!({ omit_expression => true, prepend_module_to_snapshot => true }, {
            insta::assert_snapshot!(case.name, format!("exit code {}\n{stderr}", code.unwrap()));
        });
    }
}
