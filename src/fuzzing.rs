//! Fuzz entry points: one function per input parser, called by the libFuzzer targets in `fuzz/`
//! (`cargo fuzz run <name>`, see `scripts/fuzz.sh`) and by `tests/fuzz_corpus.rs`, which replays
//! every checked-in corpus file on stable Rust with no extra tools.
//!
//! Each function feeds its bytes through the same code a real run takes: an error is the right
//! answer to bad input, a panic (or a hang) is a bug. They return whether the input got all the
//! way through without an error, so that tests can check the real seeds reach the deep code.
//!
//! - [`spec`]: the spec text through [`LoadedSpec::parse`] (what `chunkc check` runs after
//!   reading the file), in memory.
//! - [`lerobot_info`]: the bytes as `meta/info.json` of a copy of a real LeRobot dataset (v2.1 or
//!   v3.0, by whether the text mentions `v3.0`), opened through the adapter.
//! - [`zarr_metadata`]: the first byte picks a metadata file of a copy of the Push-T replay buffer
//!   (`.zarray`, `.zattrs`, `.zgroup`), the rest replaces it; opened through the adapter.
//! - [`hdf5_attributes`]: structured input ([`arbitrary`]) that says what a robomimic file holds
//!   (demo names, the `num_samples` attribute of any type, array shapes, robosuite `states`,
//!   `mask/*` strings); the file is written with HDF5 and opened through the adapter.
//!
//! The file-based targets work in a scratch directory per process and target under the system's
//! temporary directory; [`remove_scratch`] deletes it.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use arbitrary::{Arbitrary, Unstructured};

use crate::source;
use crate::spec::LoadedSpec;

/// The test data the file-based targets copy (the crate's own `tests/data`).
const TEST_DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data");

/// At most this many values (steps × width) are read per episode; a fuzzed shape can declare
/// arrays far larger than memory, and reading them is not what these targets look at.
const READ_LIMIT: usize = 1 << 20;

/// Parses a spec held in memory, as `chunkc check` does with the file's text. Non-UTF-8 input is
/// refused before parsing (`LoadedSpec::load` reads a string), so it is skipped here.
pub fn spec(data: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(data) else {
        return false;
    };
    match LoadedSpec::parse("fuzz.toml", text, Path::new("/nonexistent")) {
        Ok(spec) => {
            // Later stages point at keys of a valid spec; render a few such errors.
            let _ = spec.error_at(&["source", "path"], "m", None).to_string();
            let _ = spec.error_at(&["output", "dir"], "m", Some("h".into()));
            for profile in &spec.profiles {
                let key = ["profiles", profile.name.as_str(), "chunk"];
                let _ = spec.error_at(&key, "m", None).to_string();
            }
            true
        }
        Err(e) => {
            let _ = e.to_string();
            false
        }
    }
}

/// `meta/info.json` of a LeRobot dataset: parsed on its own, then opened through the adapter
/// together with a real dataset's other files.
pub fn lerobot_info(data: &[u8]) -> bool {
    let _ = source::LerobotInfo::parse(data, "info.json");
    let v3 = data.windows(4).any(|w| w == b"v3.0");
    let name = if v3 {
        "lerobot_v3_synthetic"
    } else {
        "lerobot_g1_subset"
    };
    let scratch = Scratch::lock("lerobot_info", |dir| {
        for name in ["lerobot_v3_synthetic", "lerobot_g1_subset"] {
            copy_dir(&Path::new(TEST_DATA).join(name), &dir.join(name));
        }
    });
    let root = scratch.dir.join(name);
    std::fs::write(root.join("meta/info.json"), data).expect("scratch is writable");
    let spec = fixed_spec(
        &scratch.dir,
        &format!(
            "[source]\nformat = \"lerobot\"\npath = \"{name}\"\n\
             [source.channels]\naction = \"action\"\n\"observation.state\" = \"observation.state\"\n"
        ),
    );
    open_and_read(&spec)
}

/// Which replay-buffer metadata file [`zarr_metadata`]'s first byte replaces.
const ZARR_FILES: [&str; 6] = [
    "meta/episode_ends/.zarray",
    "data/action/.zarray",
    "data/action/.zattrs",
    "meta/episode_ends/.zattrs",
    ".zgroup",
    "data/.zgroup",
];

/// One metadata file of a Diffusion Policy replay buffer (a copy of the Push-T subset's
/// `meta/episode_ends` and `data/action`), replaced by the bytes after the first.
pub fn zarr_metadata(data: &[u8]) -> bool {
    let Some((&which, content)) = data.split_first() else {
        return false;
    };
    let original = Path::new(TEST_DATA).join("pusht_subset.zarr");
    let scratch = Scratch::lock("zarr_metadata", |dir| {
        for rel in ["meta/episode_ends", "data/action"] {
            copy_dir(&original.join(rel), &dir.join("replay.zarr").join(rel));
        }
    });
    // Every metadata file back to the original (or absent, like the `.zattrs`), then the chosen
    // one replaced.
    let root = scratch.dir.join("replay.zarr");
    for rel in ZARR_FILES {
        match std::fs::read(original.join(rel)) {
            Ok(bytes) => std::fs::write(root.join(rel), bytes).expect("scratch is writable"),
            Err(_) => {
                let _ = std::fs::remove_file(root.join(rel));
            }
        }
    }
    let target = ZARR_FILES[which as usize % ZARR_FILES.len()];
    std::fs::write(root.join(target), content).expect("scratch is writable");
    let spec = fixed_spec(
        &scratch.dir,
        "[source]\nformat = \"diffusion_policy_zarr\"\npath = \"replay.zarr\"\nfps = 10\n\
         [source.channels]\naction = \"action\"\n",
    );
    open_and_read(&spec)
}

/// A value of robomimic's `num_samples` attribute, in any of the types a file could hold.
#[derive(Debug, Arbitrary)]
enum AttrValue {
    I64(i64),
    U8(u8),
    F64(f64),
    Text(String),
    Array(Vec<i64>),
}

#[derive(Debug, Arbitrary)]
enum DemoName {
    /// `demo_<n>`.
    Numbered(u16),
    Raw(String),
}

#[derive(Debug, Arbitrary)]
struct Demo {
    name: DemoName,
    num_samples: Option<AttrValue>,
    /// Steps of `actions` (taken modulo 16).
    steps: u8,
    /// Per-step shape of `actions` (each dimension modulo 5, at most 3 of them).
    action_shape: Vec<u8>,
    /// An `obs` group (robomimic) or none (robosuite).
    obs: bool,
    /// robosuite's `states`: rows (modulo 16) and the values, cycled; column 0 is the time.
    states: Option<(u8, Vec<f64>)>,
}

#[derive(Debug, Arbitrary)]
struct Masks {
    train: Option<Vec<String>>,
    valid: Option<Vec<String>>,
    /// Fixed-length strings (longer than the 256 bytes the reader allows for) or variable ones.
    fixed: bool,
}

#[derive(Debug, Arbitrary)]
struct RobomimicInput {
    /// Whether the spec sets `source.fps` (otherwise the rate comes from robosuite's clock).
    fps: bool,
    demos: Vec<Demo>,
    masks: Option<Masks>,
}

/// A robomimic / robosuite HDF5 file described by structured input, written and then opened
/// through the adapter (which reads `num_samples`, the arrays' shapes, `states` and `mask/*`).
pub fn hdf5_attributes(data: &[u8]) -> bool {
    let Ok(input) = RobomimicInput::arbitrary_take_rest(Unstructured::new(data)) else {
        return false;
    };
    let scratch = Scratch::lock("hdf5_attributes", |_| {});
    let path = scratch.dir.join("demo.hdf5");
    if write_robomimic(&path, &input).is_err() {
        return false; // HDF5 refused the input (a name it cannot store): nothing to open.
    }
    let fps = if input.fps { "fps = 20\n" } else { "" };
    let spec = fixed_spec(
        &scratch.dir,
        &format!(
            "[source]\nformat = \"robomimic_hdf5\"\npath = \"demo.hdf5\"\n{fps}\
             [source.channels]\naction = \"actions\"\n"
        ),
    );
    open_and_read(&spec)
}

// Long function: every group of a robomimic file the fuzzer may vary, written in file order.
fn write_robomimic(path: &Path, input: &RobomimicInput) -> hdf5::Result<()> {
    use hdf5::types::{FixedAscii, VarLenUnicode};
    let file = hdf5::File::create(path)?;
    let data = file.create_group("data")?;
    for demo in input.demos.iter().take(4) {
        let name = match &demo.name {
            DemoName::Numbered(n) => format!("demo_{n}"),
            DemoName::Raw(s) => s.clone(),
        };
        let g = data.create_group(&name)?;
        match &demo.num_samples {
            None => {}
            Some(AttrValue::I64(v)) => {
                g.new_attr::<i64>().create("num_samples")?.write_scalar(v)?
            }
            Some(AttrValue::U8(v)) => g.new_attr::<u8>().create("num_samples")?.write_scalar(v)?,
            Some(AttrValue::F64(v)) => {
                g.new_attr::<f64>().create("num_samples")?.write_scalar(v)?
            }
            Some(AttrValue::Text(s)) => {
                let s: VarLenUnicode = s.parse().map_err(|e| hdf5::Error::from(format!("{e}")))?;
                g.new_attr::<VarLenUnicode>()
                    .create("num_samples")?
                    .write_scalar(&s)?
            }
            Some(AttrValue::Array(v)) => g
                .new_attr::<i64>()
                .shape(v.len().min(8))
                .create("num_samples")?
                .write_raw(&v[..v.len().min(8)])?,
        }
        let steps = (demo.steps % 16) as usize;
        let mut shape = vec![steps];
        shape.extend(demo.action_shape.iter().take(3).map(|&d| (d % 5) as usize));
        let n: usize = shape.iter().product();
        let values: Vec<f32> = (0..n).map(|i| i as f32 / 8.0).collect();
        g.new_dataset::<f32>()
            .shape(shape)
            .create("actions")?
            .write_raw(&values)?;
        if demo.obs {
            g.create_group("obs")?
                .new_dataset::<f32>()
                .shape((steps, 2))
                .create("eef_pos")?
                .write_raw(&vec![0.5f32; steps * 2])?;
        }
        if let Some((rows, values)) = &demo.states {
            let (rows, cols) = ((rows % 16) as usize, 3usize);
            let all: Vec<f64> = if values.is_empty() {
                vec![0.0; rows * cols]
            } else {
                values.iter().copied().cycle().take(rows * cols).collect()
            };
            g.new_dataset::<f64>()
                .shape((rows, cols))
                .create("states")?
                .write_raw(&all)?;
        }
    }
    if let Some(masks) = &input.masks {
        let mask = file.create_group("mask")?;
        for (name, list) in [("train", &masks.train), ("valid", &masks.valid)] {
            let Some(list) = list else { continue };
            let list = &list[..list.len().min(8)];
            if masks.fixed {
                let values: Vec<FixedAscii<300>> = list
                    .iter()
                    .filter_map(|s| FixedAscii::from_ascii(s.as_bytes()).ok())
                    .collect();
                mask.new_dataset::<FixedAscii<300>>()
                    .shape(values.len())
                    .create(name)?
                    .write_raw(&values)?;
            } else {
                let values: Vec<VarLenUnicode> =
                    list.iter().filter_map(|s| s.parse().ok()).collect();
                mask.new_dataset::<VarLenUnicode>()
                    .shape(values.len())
                    .create(name)?
                    .write_raw(&values)?;
            }
        }
    }
    Ok(())
}

/// Deletes this process's scratch directory of `target` (one of the file-based targets' names).
pub fn remove_scratch(target: &str) {
    let _guard = lock();
    let _ = std::fs::remove_dir_all(scratch_dir(target));
}

/// One lock for every scratch directory: tests may run targets from several threads.
fn lock() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    // A panic in an earlier input (a finding) must not stop the others from running.
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

fn scratch_dir(target: &str) -> PathBuf {
    std::env::temp_dir().join(format!("chunkc-fuzz-{}-{target}", std::process::id()))
}

/// A target's scratch directory, held (locked) for one input.
struct Scratch {
    dir: PathBuf,
    _guard: MutexGuard<'static, ()>,
}

impl Scratch {
    /// Locks `target`'s directory, creating it with `init` the first time this process uses it.
    fn lock(target: &str, init: impl FnOnce(&Path)) -> Scratch {
        let guard = lock();
        let dir = scratch_dir(target);
        let ready = dir.join(".ready");
        if !ready.exists() {
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).expect("the temporary directory is writable");
            init(&dir);
            std::fs::write(&ready, b"").expect("scratch is writable");
        }
        Scratch { dir, _guard: guard }
    }
}

/// A spec around `source` (a `[source]` table with its channels), with paths relative to `dir`.
fn fixed_spec(dir: &Path, source: &str) -> LoadedSpec {
    let text = format!(
        "version = 1\n{source}\n[output]\ndir = \"out\"\n\n[profiles.act]\npreset = \"act\"\nchunk = 4\n"
    );
    LoadedSpec::parse("fuzz.toml", &text, dir).expect("the fuzz targets' spec is valid")
}

/// Opens the spec's source and reads its first episodes, when they are of a readable size.
/// Whether the source opened and every episode read was read without an error.
fn open_and_read(spec: &LoadedSpec) -> bool {
    let Ok(source) = source::open(spec) else {
        return false;
    };
    let mut ok = true;
    let manifest = source.manifest();
    let width: usize = manifest
        .channels
        .iter()
        .map(|c| c.shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d)))
        .try_fold(0usize, |a, w| a.checked_add(w?))
        .unwrap_or(usize::MAX);
    for (index, episode) in manifest.episodes.iter().enumerate().take(3) {
        if episode.len.saturating_mul(width) <= READ_LIMIT {
            ok &= source.read_episode(index).is_ok();
        }
    }
    ok
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("scratch is writable");
    for entry in std::fs::read_dir(from).expect("the test data is readable") {
        let entry = entry.expect("the test data is readable");
        let target = to.join(entry.file_name());
        if entry.file_type().expect("readable").is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), &target).expect("scratch is writable");
        }
    }
}
