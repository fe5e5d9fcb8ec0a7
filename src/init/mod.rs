//! `chunkc init` and `chunkc inspect`: from a dataset folder to a first spec.
//!
//! [`inspect`] detects the layout ([`crate::source::detect`]), lists every key the source offers
//! and decides what each is for ([`roles`], filling [`key_role`]'s rows; [`state`] picks the
//! robot state, guessing when it must so that the spec observes something), finds the rate
//! (stored, from timestamps, or a guess it says is one: [`propose::rate_guess`]), checks that
//! each camera the spec would name can be read ([`cameras`]: a LeRobot camera whose videos are
//! missing for some episodes is kept and those episodes excluded; one that cannot be read is
//! left out, with the reason), runs the timing audit and the action's autocorrelation, and
//! proposes a profile per target with the numbers behind each choice ([`propose`]). [`text`]
//! writes that as a commented spec, [`summary`] as what both commands print. Nothing here
//! writes a file: the `init` driver in `commands` checks the spec as `chunkc check` would and
//! writes it.

pub mod cameras;
pub mod key_role;
pub mod propose;
pub mod roles;
pub mod state;
pub mod summary;
pub mod text;

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::analyze::{self, AnalyzeOptions};
use crate::audit::{self, Verdict};
use crate::error::{Error, Result};
use crate::source::{self, detect};
use crate::spec::{LoadedSpec, SourceFormat};

pub use cameras::MissingVideos;
pub use key_role::{KeyRole, Role};
pub use propose::{AcfSummary, ProposedProfile, Rate};

/// What `init` needs besides the dataset's path.
#[derive(Debug, Clone, Default)]
pub struct InitOptions {
    /// The rate, for a source that stores none (overrides the guess).
    pub fps: Option<f64>,
}

/// The timing audit, counted.
#[derive(Debug, Clone, Serialize)]
pub struct TimingSummary {
    /// Whether the source stores timestamps (without, every interval is the declared one).
    pub timestamps: bool,
    pub ok: usize,
    pub interpolate: usize,
    pub resample: usize,
    pub exclude: usize,
    /// Camera videos whose frames disagree with their rows.
    pub video_problems: usize,
    pub warnings: Vec<String>,
}

/// Everything `chunkc inspect` prints and `chunkc init` writes a spec from.
#[derive(Debug, Clone, Serialize)]
pub struct Inspection {
    /// The dataset as the spec names it (absolute).
    pub path: PathBuf,
    pub format: SourceFormat,
    /// Why the format was decided.
    pub evidence: String,
    /// Where the keys were listed from.
    pub listed_from: String,
    pub rate: Rate,
    /// `source.fps` as the spec sets it: the rate, where the source stores none.
    pub spec_fps: Option<f64>,
    /// The split the source stores, where it holds validation episodes (`[split] from`).
    pub split_origin: Option<String>,
    pub episodes: usize,
    pub steps: usize,
    pub shortest: usize,
    pub longest: usize,
    pub keys: Vec<KeyRole>,
    /// Cameras kept although some episodes have no video for them (the spec excludes those
    /// episodes: `[audit] video = "exclude_episode"`).
    pub missing_videos: Vec<MissingVideos>,
    /// Distinct tasks (language instructions) the source stores per episode.
    pub tasks: usize,
    pub timing: TimingSummary,
    pub acf: Option<AcfSummary>,
    pub profiles: Vec<ProposedProfile>,
    /// The source's own warnings (gaps in ids, disagreeing metadata).
    pub warnings: Vec<String>,
}

impl Inspection {
    /// The keys the spec maps, in the spec's order of mention.
    pub fn mapped(&self) -> impl Iterator<Item = &KeyRole> {
        self.keys.iter().filter(|k| k.channel.is_some())
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("an inspection serializes") + "\n"
    }
}

/// The dataset's name, for the output directory: the file stem or directory name.
pub fn dataset_name(path: &Path) -> String {
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "dataset".into());
    let name = name.trim_end_matches(".zarr").to_string();
    let clean: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if clean.is_empty() {
        "dataset".into()
    } else {
        clean
    }
}

/// Parses a spec `init` made; a failure here is chunkc's fault, not the user's.
fn parse(text: &str, spec_dir: &Path, what: &str) -> Result<LoadedSpec> {
    LoadedSpec::parse(what, text, spec_dir).map_err(|e| {
        Error::Internal(format!(
            "the spec chunkc init drafted does not parse:\n{e}\n{text}"
        ))
    })
}

/// Inspects the dataset at `path` for a spec to be written in `spec_dir`.
// Long function: one sequence (detect, list, classify, check cameras, open, audit, analyze, propose), each step feeding the next.
pub fn inspect(path: &Path, spec_dir: &Path, options: &InitOptions) -> Result<Inspection> {
    let found = detect::detect(path)?;
    let root =
        std::path::absolute(&found.path).map_err(|e| Error::io_path("resolve", &found.path, e))?;
    let spec_dir =
        std::path::absolute(spec_dir).map_err(|e| Error::io_path("resolve", spec_dir, e))?;
    let name = dataset_name(&root);
    if let (SourceFormat::Lerobot, Some(given)) = (found.format, options.fps) {
        stored_rate_agrees(&root, given)?;
    }
    let draft = text::Draft {
        format: found.format,
        path: &root,
        fps: None,
        out_dir: &format!("out/{name}"),
        spec_dir: &spec_dir,
        exclude_bad_videos: false,
    };

    // The keys, with a rate where the adapter needs one before it lists them.
    let early_fps = options.fps.or_else(|| {
        propose::rate_guess(found.format, &name, false)
            .filter(|_| found.format != SourceFormat::RobomimicHdf5)
            .map(|r| r.fps)
    });
    let probe_channels = vec![("action".to_string(), "action".to_string(), None)];
    let probe = parse(
        &draft.with_fps(early_fps).render_minimal(&probe_channels),
        &spec_dir,
        "(init probe)",
    )?;
    let (listed_from, keys) = detect::offered(&probe)?;
    let robosuite_clock = found.format == SourceFormat::RobomimicHdf5
        && !keys.iter().any(|k| k.key.starts_with("obs/"))
        && keys.iter().any(|k| k.key == "states" && k.shape.len() == 1);
    let rate = match options.fps {
        Some(fps) => Some(Rate {
            fps,
            origin: "--fps".into(),
            guessed: false,
        }),
        None => propose::rate_guess(found.format, &name, robosuite_clock),
    };
    let spec_fps = rate.as_ref().map(|r| r.fps);
    let draft = draft.with_fps(spec_fps);

    let mut roles = roles::assign(found.format, &keys, robosuite_clock);
    let Some(action) = roles.iter().find(|r| r.role == Role::Action).cloned() else {
        let listed: Vec<String> = keys
            .iter()
            .map(|k| format!("{} {:?}", k.key, k.shape))
            .collect();
        return Err(Error::source(format!(
            "{}: no action key: looked for a low-dimensional key named `action` or `actions` in {listed_from}, which has: {}; write the spec by hand (book: Writing a spec)",
            found.path.display(),
            listed.join(", ")
        )));
    };

    let missing_videos = if found.format == SourceFormat::Lerobot {
        cameras::check(&mut roles, &action, &draft, &spec_dir)?
    } else {
        Vec::new()
    };
    let draft = draft.excluding_bad_videos(!missing_videos.is_empty());

    // The mapped channels, opened as the build will open them.
    let channels: Vec<_> = roles
        .iter()
        .filter(|r| r.channel.is_some())
        .map(text::mapping_of)
        .collect();
    let spec = parse(&draft.render_minimal(&channels), &spec_dir, "(init draft)")?;
    let opened = source::open(&spec)?;
    let manifest = opened.manifest().clone();
    let rate = rate.unwrap_or_else(|| Rate {
        fps: manifest.fps,
        origin: if found.format == SourceFormat::Lerobot {
            "meta/info.json `fps`".into()
        } else {
            "the timestamps (one over the median interval)".into()
        },
        guessed: false,
    });
    let timing = timing(&spec, opened.as_ref(), &root)?;
    drop(opened);

    let lens: Vec<usize> = manifest.episodes.iter().map(|e| e.len).collect();
    let shortest = lens.iter().copied().min().unwrap_or(0);
    let longest = lens.iter().copied().max().unwrap_or(0);
    let acf = if longest >= 2 {
        Some(action_acf(&draft, &action, &spec_dir)?)
    } else {
        None
    };
    let point_clouds = roles
        .iter()
        .any(|r| r.role == Role::PointCloud && r.channel.is_some());
    let profiles = propose::profiles(
        found.format,
        manifest.fps,
        shortest,
        acf.as_ref(),
        point_clouds,
    );
    let mut tasks: Vec<&String> = manifest.tasks.values().collect();
    tasks.sort();
    tasks.dedup();
    Ok(Inspection {
        path: root,
        format: found.format,
        evidence: found.evidence,
        listed_from,
        rate,
        spec_fps,
        split_origin: manifest
            .source_split
            .as_ref()
            .filter(|s| !s.val.is_empty())
            .map(|s| s.origin.clone()),
        episodes: lens.len(),
        steps: lens.iter().sum(),
        shortest,
        longest,
        keys: roles,
        missing_videos,
        tasks: tasks.len(),
        timing,
        acf,
        profiles,
        warnings: manifest.warnings,
    })
}

/// The timing audit of the opened source, counted (a missing video is not counted as one that
/// disagrees with its rows: [`cameras`] lists those).
fn timing(spec: &LoadedSpec, opened: &dyn source::Source, root: &Path) -> Result<TimingSummary> {
    let (report, _) = audit::run(spec, opened, true)?;
    let count = |v: Verdict| report.episodes.iter().filter(|e| e.verdict == v).count();
    Ok(TimingSummary {
        timestamps: report.timestamps,
        ok: count(Verdict::Ok),
        interpolate: count(Verdict::Interpolate),
        resample: count(Verdict::Resample),
        exclude: count(Verdict::Exclude),
        video_problems: report
            .video
            .iter()
            .filter(|v| v.check.problem.is_some() && root.join(&v.check.file).exists())
            .count(),
        warnings: report.warnings,
    })
}

/// `chunkc analyze`'s autocorrelation of the action, at the source rate.
fn action_acf(draft: &text::Draft, action: &KeyRole, spec_dir: &Path) -> Result<AcfSummary> {
    let spec = parse(
        &draft.render_minimal(&[text::mapping_of(action)]),
        spec_dir,
        "(init analysis)",
    )?;
    let a = analyze::analyze(&spec, &AnalyzeOptions::default())?;
    Ok(AcfSummary {
        suggested_k: a.suggested_k,
        threshold: a.threshold,
        max_lag: a.max_lag,
        mean_acf: a.mean_acf,
    })
}

/// `--fps` on a LeRobot dataset must be the rate its `meta/info.json` stores.
fn stored_rate_agrees(root: &Path, given: f64) -> Result<()> {
    let path = root.join("meta/info.json");
    let bytes = std::fs::read(&path).map_err(|e| Error::io_path("read", &path, e))?;
    let info = source::LerobotInfo::parse(&bytes, &path.display().to_string())?;
    match info.fps {
        Some(stored) if (stored - given).abs() > 1e-9 => Err(Error::Spec(format!(
            "error: --fps {given} disagrees with {}, which stores {stored} Hz; LeRobot datasets store their rate: leave --fps out",
            path.display()
        ))),
        _ => Ok(()),
    }
}
