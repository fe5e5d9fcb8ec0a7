//! `chunkc synth`: realistic synthetic sources in every input layout chunkc reads, for the
//! benchmarks and the tests.
//!
//! [`trajectory`] makes the values (smooth joint trajectories, a lagging state, camera frames
//! that show the motion, timestamps and optional timing faults); one writer per layout stores
//! them the way the original tools do ([`aloha`], [`robomimic`], [`dp_zarr`], [`lerobot`],
//! [`rlds`]).
//! [`generate`] also writes `spec.toml` (so `chunkc build <dir>/spec.toml` works directly) and,
//! when faults were asked for, `faults.json` listing exactly what was injected where.
//!
//! The same options give the same bytes: values come from seeded SplitMix64 streams per episode,
//! and every writer stores no time stamps of its own.

pub mod aloha;
pub mod data_faults;
pub mod dp_zarr;
pub mod injected;
pub mod lerobot;
pub mod rlds;
pub mod rng;
pub mod robomimic;
pub mod trajectory;

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde_json::json;

use crate::error::{Error, IoContext, Result};
use crate::spec::SourceFormat;
pub use trajectory::SynthEpisode;

/// A fault to inject into the affected episodes (see [`injected::Injected`]): timing faults
/// (`drop`, `rate`, `jitter`, `dup`) change the timestamps of one `fault_fraction` of the
/// episodes; data faults (the rest) change the recorded actions, each in its own disjoint
/// `fault_fraction` of the episodes, so that every episode has at most one data fault.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fault {
    /// `drop:P`: each step after the first is removed (data and time) with probability P.
    Drop(f64),
    /// `rate:HZ`: the steps are HZ apart in time while the dataset claims `fps`.
    Rate(f64),
    /// `jitter:F`: each timestamp after the first moves by U(-F, F) / fps.
    Jitter(f64),
    /// `dup:P`: each step after the first repeats the previous timestamp with probability P.
    Duplicate(f64),
    /// `frozen`: one action dimension holds its value from an early step to the end (the state
    /// follows the frozen command).
    Frozen,
    /// `clip`: one action dimension saturates at its 70th (or 30th) percentile.
    Clip,
    /// `jump`: two one-step spikes (1 to 2 in size, about the dimension's range) in one action
    /// dimension (a logging glitch: the state does not
    /// follow them).
    Jump,
    /// `lag:N`: the recorded actions are N steps late against the state (`action[t] = a[t-N]`;
    /// negative N: early).
    Lag(i32),
    /// `delta`: the episode's actions are recorded as deltas, target minus current state.
    Delta,
    /// `scale:F`: the episode's actions are in other units (multiplied by F).
    Scale(f64),
    /// `duplicate`: the episode is a near-copy (noise of 1e-4) of an earlier clean episode.
    Copy,
}

/// The kinds `--faults` accepts, for messages.
const FAULT_KINDS: &str =
    "drop:P, rate:HZ, jitter:F, dup:P, frozen, clip, jump, lag:N, delta, scale:F, duplicate";

impl Fault {
    /// Whether the fault changes the recorded values (not the timestamps).
    pub fn is_data(self) -> bool {
        !matches!(
            self,
            Fault::Drop(_) | Fault::Rate(_) | Fault::Jitter(_) | Fault::Duplicate(_)
        )
    }
}

impl std::str::FromStr for Fault {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "frozen" => return Ok(Fault::Frozen),
            "clip" => return Ok(Fault::Clip),
            "jump" => return Ok(Fault::Jump),
            "delta" => return Ok(Fault::Delta),
            "duplicate" => return Ok(Fault::Copy),
            _ => {}
        }
        let (kind, value) = s
            .split_once(':')
            .ok_or_else(|| format!("fault `{s}`: expected one of {FAULT_KINDS}"))?;
        if kind == "lag" {
            let n: i32 = value
                .parse()
                .map_err(|_| format!("fault `{s}`: `{value}` is not a whole number of steps"))?;
            if n == 0 || n.abs() > 20 {
                return Err(format!(
                    "fault `{s}`: the lag must be 1..=20 steps (or -20..=-1)"
                ));
            }
            return Ok(Fault::Lag(n));
        }
        let v: f64 = value
            .parse()
            .map_err(|_| format!("fault `{s}`: `{value}` is not a number"))?;
        let fault = match kind {
            "drop" => Fault::Drop(v),
            "rate" => Fault::Rate(v),
            "jitter" => Fault::Jitter(v),
            "dup" => Fault::Duplicate(v),
            "scale" => Fault::Scale(v),
            _ => {
                return Err(format!(
                    "fault `{s}`: unknown kind `{kind}` ({FAULT_KINDS})"
                ))
            }
        };
        let ok = match fault {
            Fault::Drop(p) | Fault::Duplicate(p) => (0.0..1.0).contains(&p),
            Fault::Rate(hz) => hz > 0.0 && hz.is_finite(),
            Fault::Jitter(f) => (0.0..0.5).contains(&f),
            Fault::Scale(f) => f.is_finite() && f > 0.0 && f != 1.0,
            _ => true,
        };
        if !ok {
            return Err(format!(
                "fault `{s}`: out of range (drop/dup in [0, 1), rate > 0, jitter in [0, 0.5), scale > 0 and not 1)"
            ));
        }
        Ok(fault)
    }
}

/// What to generate.
#[derive(Debug, Clone)]
pub struct SynthOptions {
    pub format: SourceFormat,
    pub episodes: usize,
    pub steps: usize,
    pub action_dim: usize,
    pub state_dim: usize,
    pub cameras: usize,
    pub height: usize,
    pub width: usize,
    pub fps: f64,
    pub seed: u64,
    pub faults: Vec<Fault>,
    /// The fraction of episodes that get the faults.
    pub fault_fraction: f64,
    /// robomimic only: write robosuite's older layout (no `obs` group; `states[:, 0]` is the
    /// simulation time chunkc reads as timestamps, the state follows in columns 1..).
    pub robosuite: bool,
    /// diffusion_policy_zarr only: the arrays' chunking and zarr format.
    pub zarr: dp_zarr::ZarrLayout,
}

impl Default for SynthOptions {
    fn default() -> Self {
        SynthOptions {
            format: SourceFormat::AlohaHdf5,
            episodes: 10,
            steps: 100,
            action_dim: 14,
            state_dim: 14,
            cameras: 0,
            height: 96,
            width: 96,
            fps: 50.0,
            seed: 0,
            faults: Vec::new(),
            fault_fraction: 0.2,
            robosuite: false,
            zarr: dp_zarr::ZarrLayout::default(),
        }
    }
}

/// Episodes generated at once (in parallel), then written in order: bounds memory.
const BATCH: usize = 16;

/// A layout writer: receives the episodes in order, then finishes.
pub trait SynthWriter {
    fn episode(&mut self, ep: &SynthEpisode) -> Result<()>;
    fn finish(self: Box<Self>) -> Result<()>;
}

/// The source's path inside the output directory, as the spec names it.
pub fn source_name(format: SourceFormat) -> &'static str {
    match format {
        SourceFormat::AlohaHdf5 => "episodes",
        SourceFormat::RobomimicHdf5 => "demos.hdf5",
        SourceFormat::DiffusionPolicyZarr => "replay.zarr",
        SourceFormat::Lerobot => "lerobot",
        SourceFormat::Rlds => "rlds",
    }
}

fn check(opts: &SynthOptions) -> Result<()> {
    let usage = |m: String| Err(Error::Spec(format!("chunkc synth: {m}")));
    if opts.episodes == 0 || opts.steps < 2 {
        return usage("needs at least 1 episode of at least 2 steps".into());
    }
    if opts.action_dim == 0 {
        return usage("--action-dim must be at least 1".into());
    }
    if opts.cameras > 0 && (opts.height == 0 || opts.width == 0) {
        return usage("--resolution must be at least 1x1".into());
    }
    if opts.cameras > 0 && opts.format == SourceFormat::Lerobot && !cfg!(feature = "video") {
        return usage("lerobot sources keep cameras in mp4 videos, which needs a chunkc built with the `video` cargo feature; use --cameras 0".into());
    }
    if opts.cameras > 0
        && opts.format == SourceFormat::Lerobot
        && (!opts.height.is_multiple_of(2) || !opts.width.is_multiple_of(2))
    {
        return usage(format!(
            "lerobot cameras are yuv420p videos, whose height and width must be even, not {}x{}",
            opts.height, opts.width
        ));
    }
    if opts.cameras > 0 && opts.robosuite {
        return usage("--robosuite files have no images; use --cameras 0".into());
    }
    if !(0.0..=1.0).contains(&opts.fault_fraction) {
        return usage("--fault-fraction must be in [0, 1]".into());
    }
    let data = opts.faults.iter().filter(|f| f.is_data()).count();
    if data as f64 * opts.fault_fraction > 1.0 {
        return usage(format!(
            "{data} data faults of {} each do not fit in the episodes (each gets its own share); lower --fault-fraction",
            opts.fault_fraction
        ));
    }
    if !(opts.fps > 0.0 && opts.fps.is_finite()) {
        return usage("--fps must be positive".into());
    }
    Ok(())
}

/// Writes the source, `spec.toml` and (with faults) `faults.json` into `dir`, which must not
/// exist yet or be empty.
pub fn generate(opts: &SynthOptions, dir: &Path) -> Result<PathBuf> {
    check(opts)?;
    if dir.exists() && std::fs::read_dir(dir).at("list", dir)?.next().is_some() {
        return Err(Error::output(format!(
            "{}: exists and is not empty; chunkc synth writes into a new directory",
            dir.display()
        )));
    }
    std::fs::create_dir_all(dir).at("create", dir)?;
    let source = dir.join(source_name(opts.format));
    let mut writer: Box<dyn SynthWriter> = match opts.format {
        SourceFormat::AlohaHdf5 => Box::new(aloha::AlohaWriter::create(opts, &source)?),
        SourceFormat::RobomimicHdf5 => Box::new(robomimic::RobomimicWriter::create(opts, &source)?),
        SourceFormat::DiffusionPolicyZarr => {
            Box::new(dp_zarr::DpZarrWriter::create(opts, &source)?)
        }
        SourceFormat::Lerobot => Box::new(lerobot::LerobotWriter::create(opts, &source)?),
        SourceFormat::Rlds => Box::new(rlds::RldsWriter::create(opts, &source)?),
    };
    let mut faults = serde_json::Map::new();
    let ids: Vec<u64> = (0..opts.episodes as u64).collect();
    for batch in ids.chunks(BATCH) {
        let episodes: Vec<SynthEpisode> = batch
            .par_iter()
            .map(|&id| trajectory::episode(opts, id))
            .collect();
        for ep in &episodes {
            writer.episode(ep)?;
            if !ep.injected.is_empty() {
                faults.insert(ep.id.to_string(), json!(ep.injected));
            }
        }
    }
    writer.finish()?;
    if !opts.faults.is_empty() {
        let path = dir.join("faults.json");
        let doc = json!({
            "fps": opts.fps,
            "timestamps_in": timestamps_in(opts),
            "episodes": faults,
        });
        let mut text = serde_json::to_string_pretty(&doc).expect("JSON serializes");
        text.push('\n');
        std::fs::write(&path, text).at("write", &path)?;
    }
    let spec = dir.join("spec.toml");
    std::fs::write(&spec, spec_text(opts)).at("write", &spec)?;
    Ok(spec)
}

/// Where the layout keeps the timestamps the faults change (None: it stores none, so only a
/// `drop` fault leaves a trace, as missing data).
fn timestamps_in(opts: &SynthOptions) -> Option<&'static str> {
    match opts.format {
        SourceFormat::RobomimicHdf5 => Some("data/demo_<i>/states[:, 0]"),
        SourceFormat::Lerobot => Some("timestamp"),
        _ => None,
    }
}

/// The channel keys of each layout: (action, state, camera prefix/suffix).
fn keys(opts: &SynthOptions) -> (String, String, Vec<String>) {
    let cams = |f: &dyn Fn(usize) -> String| (0..opts.cameras).map(f).collect::<Vec<_>>();
    match opts.format {
        SourceFormat::AlohaHdf5 => (
            "\"action\"".into(),
            "\"observations/qpos\"".into(),
            cams(&|c| format!("observations/images/cam{c}")),
        ),
        SourceFormat::RobomimicHdf5 if opts.robosuite => (
            "\"actions\"".into(),
            format!(
                "{{ key = \"states\", columns = [1, {}] }}",
                1 + opts.state_dim
            ),
            Vec::new(),
        ),
        SourceFormat::RobomimicHdf5 => (
            "\"actions\"".into(),
            "\"obs/robot0_joint_pos\"".into(),
            cams(&|c| format!("obs/cam{c}_image")),
        ),
        SourceFormat::DiffusionPolicyZarr => (
            "\"action\"".into(),
            "\"state\"".into(),
            cams(&|c| format!("cam{c}")),
        ),
        SourceFormat::Rlds => (
            "\"steps/action\"".into(),
            "\"steps/observation/state\"".into(),
            cams(&|c| format!("steps/observation/cam{c}")),
        ),
        SourceFormat::Lerobot => (
            "\"action\"".into(),
            "\"observation.state\"".into(),
            cams(&lerobot::camera_key),
        ),
    }
}

/// A spec that builds the generated source with the `act` preset at the source's rate.
pub fn spec_text(opts: &SynthOptions) -> String {
    let (action, state, cams) = keys(opts);
    let mut s = String::new();
    s.push_str("# Written by `chunkc synth`.\nversion = 1\n\n[source]\n");
    s.push_str(&format!("format = \"{}\"\n", opts.format.name()));
    s.push_str(&format!("path = \"{}\"\n", source_name(opts.format)));
    if opts.format != SourceFormat::Lerobot {
        s.push_str(&format!("fps = {:?}\n", opts.fps));
    }
    s.push_str("\n[source.channels]\n");
    s.push_str(&format!(
        "action = {action}\n\"observation.state\" = {state}\n"
    ));
    for (c, key) in cams.iter().enumerate() {
        s.push_str(&format!("\"observation.cam{c}\" = \"{key}\"\n"));
    }
    s.push_str("\n[split]\nval_fraction = 0.1\nseed = 0\n\n[output]\ndir = \"out\"\n\n");
    s.push_str(&format!(
        "[profiles.act]\npreset = \"act\"\nfps = {:?}\nformat = \"hdf5\"\n",
        opts.fps
    ));
    s
}
