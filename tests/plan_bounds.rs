//! `chunkc plan`'s sizes against what `chunkc build` writes, on every vendored source: each
//! example spec in `specs/`, and specs over every fixture in `tests/data` with each way of
//! storing frames (raw, gzip, JPEG, video, Zarr, Parquet with PNG or video, the native exports).
//! A file listed with `<=` (`"bound": true` in the JSON) must not be larger than its bound; a
//! directory's files are summed, and their count is the one the plan gives. Estimates (`~`) are
//! printed beside the real sizes (`cargo test --test plan_bounds -- --nocapture`), not checked.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::copy_dir;

const REPO: &str = env!("CARGO_MANIFEST_DIR");

/// Profiles storing a camera every way chunkc can: `{act}` and `{dp}` are the lines that fit an
/// ACT and a Diffusion Policy profile to the source's rate and episodes.
const STORAGE_PROFILES: &str = r#"
[profiles.raw]
preset = "act"
{act}
chunk = 4
[profiles.gzip]
preset = "act"
{act}
chunk = 4
image_compression = "gzip"
[profiles.jpeg]
preset = "act"
{act}
chunk = 4
image_compression = "jpeg"
image_quality = 75
[profiles.zarr]
preset = "diffusion_policy"
{dp}
format = "zarr"
[profiles.parquet]
preset = "diffusion_policy"
{dp}
format = "parquet"
[profiles.act_episodes]
preset = "act"
{act}
chunk = 4
format = "act_episodes"
[profiles.robomimic]
preset = "diffusion_policy"
{dp}
format = "robomimic_hdf5"
"#;

/// Video storage, for builds with the `video` feature.
const VIDEO_PROFILES: &str = r#"
[profiles.video]
preset = "diffusion_policy"
{dp}
image_compression = "video"
[profiles.video_resized]
preset = "diffusion_policy"
{dp}
image_compression = "video"
[profiles.video_resized.cameras."{camera}"]
size = [32, 32]
[profiles.parquet_video]
preset = "diffusion_policy"
{dp}
format = "parquet"
image_encoding = "video"
{codec}
"#;

/// A fixture source: its `[source]` and `[split]` tables, the lines that fit ACT and Diffusion
/// Policy profiles to it, a camera (if any), and whether reading it needs the `video` feature.
struct Fixture {
    name: &'static str,
    source: &'static str,
    act: &'static str,
    dp: &'static str,
    camera: &'static str,
    /// Frames smaller than SVT-AV1's 64x64: LeRobot's videos are H.264 instead.
    small: bool,
    video: bool,
}

const FIXTURES: &[Fixture] = &[
    Fixture {
        name: "lerobot_video_real_g1",
        source: r#"[source]
format = "lerobot"
path = "../tests/data/lerobot_video_real_g1"
[source.channels]
action = "action"
"observation.state" = "observation.state"
"observation.images.cam_high" = "observation.images.cam_high"
[split]
val_fraction = 0.5
seed = 0"#,
        act: "fps = 30",
        dp: "fps = 30",
        camera: "observation.images.cam_high",
        small: false,
        video: true,
    },
    Fixture {
        name: "lerobot_video_v21",
        source: r#"[source]
format = "lerobot"
path = "../tests/data/lerobot_video_v21"
[source.channels]
action = "action"
"observation.state" = "observation.state"
"observation.images.top" = "observation.images.top"
[split]
val_fraction = 0.34
seed = 0"#,
        act: "fps = 10",
        dp: "",
        camera: "observation.images.top",
        small: false,
        video: true,
    },
    Fixture {
        name: "lerobot_video_v3_av1",
        source: r#"[source]
format = "lerobot"
path = "../tests/data/lerobot_video_v3_av1"
[source.channels]
action = "action"
"observation.state" = "observation.state"
"observation.images.top" = "observation.images.top"
"observation.images.wrist" = "observation.images.wrist"
[split]
val_fraction = 0.34
seed = 0"#,
        act: "fps = 10",
        dp: "",
        camera: "observation.images.wrist",
        small: false,
        video: true,
    },
    Fixture {
        name: "pusht_subset",
        source: r#"[source]
format = "diffusion_policy_zarr"
path = "../tests/data/pusht_subset.zarr"
fps = 10
[source.channels]
action = "action"
"observation.state" = "state"
"observation.image" = "img"
[split]
val_fraction = 0.1
seed = 0"#,
        act: "fps = 10",
        dp: "",
        camera: "observation.image",
        small: false,
        video: false,
    },
    Fixture {
        name: "aloha_sim_jpeg",
        source: r#"[source]
format = "aloha_hdf5"
path = "../tests/data/aloha_sim_jpeg"
[source.channels]
action = "action"
"observation.qpos" = "observations/qpos"
"observation.images.top" = "observations/images/top"
[split]
val_fraction = 0.34
seed = 0"#,
        act: "",
        dp: "",
        camera: "observation.images.top",
        small: true,
        video: false,
    },
    Fixture {
        name: "rlds_bridge",
        source: r#"[source]
format = "rlds"
path = "../tests/data/rlds-bridge/bridge_dataset"
fps = 5
[source.channels]
action = "steps/action"
"observation.state" = "steps/observation/state"
"observation.images.image_0" = "steps/observation/image_0"
[split]
from = "source""#,
        act: "fps = 5",
        dp: "fps = 5\nchunk = 8",
        camera: "observation.images.image_0",
        small: false,
        video: false,
    },
    Fixture {
        name: "robosuite_baxter",
        source: r#"[source]
format = "robomimic_hdf5"
path = "../tests/data/robosuite_baxter_peg_in_hole.hdf5"
fps = 100
[source.channels]
action = { key = "states", columns = [1, 4] }
"observation.state" = { key = "states", columns = [4, 31] }
[split]
val_fraction = 0.5
seed = 0"#,
        act: "fps = 50",
        dp: "",
        camera: "",
        small: false,
        video: false,
    },
];

/// The spec text of a fixture: every storage profile (the video ones with the `video` feature).
fn fixture_spec(f: &Fixture) -> String {
    let mut profiles = STORAGE_PROFILES.to_string();
    if f.camera.is_empty() {
        // No camera: one profile per format.
        profiles = profiles.replace("image_compression = \"gzip\"\n", "");
        profiles = profiles.replace("image_compression = \"jpeg\"\nimage_quality = 75\n", "");
    } else if cfg!(feature = "video") {
        let codec = if f.small {
            "video_codec = \"libx264\""
        } else {
            ""
        };
        profiles += &VIDEO_PROFILES
            .replace("{camera}", f.camera)
            .replace("{codec}", codec);
    }
    let profiles = profiles.replace("{act}", f.act).replace("{dp}", f.dp);
    format!(
        "version = 1\n{}\n[output]\ndir = \"../out/{}\"\n{profiles}",
        f.source, f.name
    )
}

/// Sizes of what `path` names under `root`: a file, a directory (`/`: every file under it) or
/// a glob of files (`*`): (bytes, files).
fn real_size(root: &Path, path: &str) -> (u64, usize) {
    fn walk(dir: &Path, out: &mut (u64, usize)) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else {
                out.0 += std::fs::metadata(&path).unwrap().len();
                out.1 += 1;
            }
        }
    }
    let mut out = (0, 0);
    if let Some(dir) = path.strip_suffix('/') {
        walk(&root.join(dir), &mut out);
    } else if let Some((prefix, suffix)) = path.split_once('*') {
        for entry in std::fs::read_dir(root).unwrap() {
            let name = entry.unwrap().file_name().to_string_lossy().into_owned();
            if name.starts_with(prefix) && name.ends_with(suffix) {
                out.0 += std::fs::metadata(root.join(&name)).unwrap().len();
                out.1 += 1;
            }
        }
    } else {
        out = (std::fs::metadata(root.join(path)).unwrap().len(), 1);
    }
    out
}

fn chunkc(args: &[&str], spec: &Path) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_chunkc"))
        .args(args)
        .arg(spec)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "chunkc {args:?} {} failed: {}",
        spec.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Plans and builds `text` as `specs/<name>.toml` beside a copy of `tests/data`, and checks every
/// bound of the plan against the build.
fn check_bounds(name: &str, text: &str) {
    let scratch = tempfile::tempdir().unwrap();
    copy_dir(
        &Path::new(REPO).join("tests/data"),
        &scratch.path().join("tests/data"),
    );
    std::fs::create_dir(scratch.path().join("specs")).unwrap();
    let spec = scratch.path().join("specs").join(format!("{name}.toml"));
    std::fs::write(&spec, text).unwrap();
    let plan: serde_json::Value =
        serde_json::from_str(&chunkc(&["plan", "--format", "json"], &spec)).unwrap();
    chunkc(&["build", "-q"], &spec);
    let value: toml::Value = toml::from_str(text).unwrap();
    let out: PathBuf = spec
        .parent()
        .unwrap()
        .join(value["output"]["dir"].as_str().unwrap());
    let mut over = Vec::new();
    for p in plan["profiles"].as_array().unwrap() {
        let profile = p["name"].as_str().unwrap();
        for f in p["files"].as_array().unwrap() {
            let path = f["path"].as_str().unwrap();
            let (bytes, files) = real_size(&out.join(profile), path);
            let planned = f["estimated_bytes"].as_u64().unwrap();
            let bound = f["bound"].as_bool().unwrap();
            println!(
                "{name}/{profile}/{path}: {} {planned}, wrote {bytes} ({:.2})",
                if bound { "<=" } else { "~" },
                bytes as f64 / planned.max(1) as f64
            );
            if bound && bytes > planned {
                over.push(format!(
                    "{profile}/{path}: wrote {bytes} bytes, bound {planned}"
                ));
            }
            if let Some(n) = f["files"].as_u64() {
                assert_eq!(
                    n as usize, files,
                    "{name}: {profile}/{path} holds {files} files"
                );
            }
        }
    }
    assert!(
        over.is_empty(),
        "{name}: bounds below the bytes written:\n{}",
        over.join("\n")
    );
}

fn example(stem: &str) {
    let path = Path::new(REPO).join("specs").join(format!("{stem}.toml"));
    check_bounds(stem, &std::fs::read_to_string(path).unwrap());
}

fn fixture(name: &str) {
    let f = FIXTURES.iter().find(|f| f.name == name).unwrap();
    if f.video && !cfg!(feature = "video") {
        eprintln!("{name}: reading its videos needs the `video` feature; skipped");
        return;
    }
    check_bounds(name, &fixture_spec(f));
}

/// One test case per spec in `specs/` and per fixture.
macro_rules! cases {
    (examples: $($stem:ident),* ; fixtures: $($fixture:ident),* $(,)?) => {
        const EXAMPLES: &[&str] = &[$(stringify!($stem)),*];
        const FIXTURE_NAMES: &[&str] = &[$(stringify!($fixture)),*];
        mod example {
            $(
                #[test]
                fn $stem() {
                    super::example(stringify!($stem));
                }
            )*
        }
        mod fixture {
            $(
                #[test]
                fn $fixture() {
                    super::fixture(stringify!($fixture));
                }
            )*
        }
    };
}

cases!(
    examples: aloha_sim, bridge, lerobot_g1, lerobot_v3, multi_arch, pusht, pusht_formats,
        pusht_rollout, robosuite_panda, robosuite_sawyer;
    fixtures: lerobot_video_real_g1, lerobot_video_v21, lerobot_video_v3_av1, pusht_subset, aloha_sim_jpeg, rlds_bridge,
        robosuite_baxter,
);

/// Every spec of `specs/` and every source of `tests/data` has its case.
#[test]
fn every_vendored_source_is_covered() {
    let mut specs: Vec<String> = std::fs::read_dir(Path::new(REPO).join("specs"))
        .unwrap()
        .filter_map(|e| {
            let name = e.unwrap().file_name().to_string_lossy().into_owned();
            name.strip_suffix(".toml").map(str::to_string)
        })
        .collect();
    specs.sort();
    assert_eq!(
        EXAMPLES, specs,
        "add the spec to `cases!` in tests/plan_bounds.rs"
    );
    assert_eq!(FIXTURE_NAMES.len(), FIXTURES.len());
    let read: Vec<&str> = FIXTURES
        .iter()
        .map(|f| f.source.split('"').nth(3).unwrap())
        .chain([
            "../tests/data/lerobot_g1_subset",
            "../tests/data/lerobot_v3_synthetic",
        ])
        .chain([
            "../tests/data/robosuite_panda_lift.hdf5",
            "../tests/data/robosuite_sawyer_lift.hdf5",
        ])
        .collect();
    for entry in std::fs::read_dir(Path::new(REPO).join("tests/data")).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        let is_source = !name.contains('.') || name.ends_with(".zarr") || name.ends_with(".hdf5");
        if is_source {
            assert!(
                read.iter().any(|r| r.contains(&name)),
                "tests/data/{name} is read by no case of tests/plan_bounds.rs"
            );
        }
    }
}
