//! Stage 4, resolve: spec + source manifest + lock → [`Plan`].
//!
//! The plan is data: serializable, versioned, sorted. It says, for every profile, which episodes
//! it uses and how they split, the rate conversion, the number of windows, the files it writes
//! with estimated sizes, a fingerprint, and whether it must run (and why). Work shared between
//! profiles appears once: the source read, and the statistics of each (rate, channel) pair.
//!
//! - `split`: the deterministic train/validation split.
//! - `export`: where each channel's array lives in the profile's container (native exports
//!   name them as their codebase's configuration does).
//! - `text`: the human-readable rendering of `chunkc plan`.

pub mod export;
pub mod split;
mod text;

use std::collections::BTreeMap;
use std::path::Path;

use serde::Serialize;

pub use split::Split;
pub use text::render_text;

use crate::audit::{AuditReport, Verdict};
use crate::error::Result;
use crate::lock::{self, SpecLock};
use crate::source::{ChannelInfo, ChannelKind, Manifest};
use crate::spec::{LoadedSpec, NormalizeMode, Profile, ResampleMethod, SplitFrom};
use crate::window::segment::SegmentParams;
use crate::window::{decimated_len, Sampling, Window};

pub const PLAN_VERSION: u32 = 1;
pub const TOOL_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Files every profile writes, relative to its directory.
pub const DATA_FILE: &str = "data.h5";
pub const META_FILE: &str = "meta.json";
pub const STATS_FILE: &str = "stats.json";
pub const LOADER_FILE: &str = "loader.py";

#[derive(Debug, Clone, Serialize)]
pub struct Plan {
    pub version: u32,
    pub tool_version: &'static str,
    pub spec_hash: String,
    pub source: SourcePlan,
    pub split: Split,
    /// One job per distinct profile rate: the source is read once and decimated per rate.
    pub rates: Vec<RateJob>,
    /// One job per (rate, channel): statistics over the training split, shared by the profiles
    /// listed.
    pub statistics: Vec<StatsJob>,
    /// The temporal audit, summed up (`chunkc audit` writes the whole of it).
    pub audit: AuditSummary,
    pub profiles: Vec<ProfilePlan>,
}

/// What the temporal audit found and what `build` does about it.
#[derive(Debug, Clone, Default, Serialize)]
pub struct AuditSummary {
    /// Seconds per step the episodes should have: `1 / source.fps`.
    pub expected_interval: f64,
    /// Whether the source stores timestamps (without them every episode is `ok`).
    pub timestamps: bool,
    /// Whether `build` applies the verdicts (`[audit] repair`).
    pub applied: bool,
    /// Episodes per verdict.
    pub verdicts: BTreeMap<&'static str, usize>,
    pub repaired_fraction: f64,
    pub excluded_fraction: f64,
    pub warnings: Vec<String>,
}

/// An episode the audit repaired before anything else happens to it.
#[derive(Debug, Clone, Serialize)]
pub struct RepairedEpisode {
    pub id: u64,
    pub verdict: Verdict,
    /// Steps as recorded.
    pub recorded_len: usize,
    /// Steps after repair, at the source rate.
    pub len: usize,
    pub detail: String,
}

#[derive(Debug, Clone, Serialize)]
pub struct SourcePlan {
    pub format: &'static str,
    /// As written in the spec (relative to the spec file).
    pub path: String,
    pub fps: f64,
    pub episodes: usize,
    pub steps: usize,
    pub fingerprint: String,
    pub channels: Vec<ChannelInfo>,
}

#[derive(Debug, Clone, Serialize)]
pub struct RateJob {
    pub fps: f64,
    pub conversion: Conversion,
    pub steps: usize,
    pub profiles: Vec<String>,
}

#[derive(Debug, Clone, Serialize)]
pub struct StatsJob {
    pub fps: f64,
    pub channel: String,
    pub split: &'static str,
    pub profiles: Vec<String>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ProfilePlan {
    pub name: String,
    /// Every value, fully resolved.
    pub values: Profile,
    pub fps: f64,
    pub conversion: Conversion,
    pub rate: String,
    /// How episodes become samples (window parameters included).
    pub sampling: Sampling,
    pub channels: Vec<ProfileChannel>,
    pub episodes: Vec<ProfileEpisode>,
    pub excluded: Vec<Excluded>,
    /// Episodes the audit repaired (re-gridded or resampled) before they were used.
    pub repaired: Vec<RepairedEpisode>,
    pub warnings: Vec<String>,
    pub num_samples: SplitCounts,
    pub steps: usize,
    pub files: Vec<PlannedFile>,
    pub fingerprint: String,
    pub status: Status,
}

#[derive(Debug, Clone, Serialize)]
pub struct ProfileChannel {
    pub name: String,
    pub kind: ChannelKind,
    pub shape: Vec<usize>,
    pub normalize: NormalizeMode,
    /// The name a native export gives the channel (`None`: the format keeps chunkc's names).
    pub export: Option<String>,
    /// The channel's per-step array in the data container (see [`export`]): `data/img`,
    /// `data/demo_<i>/obs/state`, `observations/qpos`; `<i>` is the stored episode position.
    pub array: String,
}

impl ProfileChannel {
    /// [`ProfileChannel::array`] of the episode stored at position `i`.
    pub fn array_of(&self, i: usize) -> String {
        self.array.replace("<i>", &i.to_string())
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct ProfileEpisode {
    pub id: u64,
    pub split: &'static str,
    pub source_len: usize,
    /// Steps at the profile's rate.
    pub len: usize,
    /// `None` when it depends on the data (segments).
    pub samples: Option<usize>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Excluded {
    pub id: u64,
    pub reason: String,
}

/// Sample counts per split; `None` when they depend on the data (segments).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct SplitCounts {
    pub train: Option<usize>,
    pub val: Option<usize>,
}

#[derive(Debug, Clone, Serialize)]
pub struct PlannedFile {
    pub path: String,
    /// An upper bound: image frames are counted before compression.
    pub estimated_bytes: u64,
}

#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Status {
    pub up_to_date: bool,
    pub reason: String,
}

/// One resolved profile value and where it came from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ResolvedValue {
    pub key: &'static str,
    pub value: String,
    /// `profiles.<name>`, `preset <name>`, `spec` or `default`.
    pub origin: String,
}

impl ProfilePlan {
    pub fn window(&self) -> &Window {
        self.sampling.window()
    }

    /// The values that shape the dataset, as `chunkc plan` and the dataset card show them.
    pub fn resolved_values(&self) -> Vec<ResolvedValue> {
        let v = &self.values;
        let opt = |x: Option<String>| x.unwrap_or_else(|| "none".into());
        [
            ("preset", opt(v.preset.map(|p| p.name().to_string()))),
            ("fps", self.fps.to_string()),
            ("chunk", self.window().chunk.to_string()),
            ("obs_history", v.obs_history.to_string()),
            ("executes", opt(v.executes.map(|e| e.to_string()))),
            ("alignment", v.alignment.name().to_string()),
            ("padding", v.padding.name().to_string()),
            ("stride", v.stride.to_string()),
            ("format", v.format.name().to_string()),
            ("sampling", self.sampling.name().to_string()),
        ]
        .into_iter()
        .map(|(key, value)| {
            let origin = v.origins.get(key).cloned().unwrap_or_else(|| {
                let from_spec = key == "sampling" && (v.segment.is_some() || v.hierarchy.is_some());
                if from_spec { "spec" } else { "default" }.to_string()
            });
            ResolvedValue { key, value, origin }
        })
        .collect()
    }
}

impl Plan {
    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("plan serializes");
        s.push('\n');
        s
    }

    pub fn up_to_date(&self) -> bool {
        self.profiles.iter().all(|p| p.status.up_to_date)
    }
}

/// How a profile's rate is reached from the source's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Conversion {
    /// Keep steps 0, `factor`, 2 `factor`, … of each episode (`factor` 1: the source rate).
    Decimate { factor: usize },
    /// A rate that does not divide the source's: each whole episode of n steps resampled to
    /// round(n × `to` / `from`) steps (`[audit] resample`: Fourier or linear; images take the
    /// nearest frame).
    Resample {
        from: f64,
        to: f64,
        method: ResampleMethod,
    },
}

impl Conversion {
    /// Steps of an episode of `len` source steps after conversion.
    pub fn len(&self, len: usize) -> usize {
        match *self {
            Conversion::Decimate { factor } => decimated_len(len, factor),
            Conversion::Resample { from, to, .. } => {
                ((len as f64 * to / from).round() as usize).max(usize::from(len > 0))
            }
        }
    }

    /// The decimation factor, if this is one.
    pub fn factor(&self) -> Option<usize> {
        match *self {
            Conversion::Decimate { factor } => Some(factor),
            Conversion::Resample { .. } => None,
        }
    }
}

/// How to get from `source_fps` to `fps`: integer decimation when the ratio is an integer, else
/// resampling; or a message saying why neither works.
pub fn conversion(
    source_fps: f64,
    fps: f64,
    method: ResampleMethod,
) -> std::result::Result<Conversion, String> {
    if fps > source_fps * (1.0 + 1e-9) {
        return Err(format!(
            "{fps} Hz is faster than the source's {source_fps} Hz; chunkc does not upsample"
        ));
    }
    let ratio = source_fps / fps;
    let factor = ratio.round();
    if (ratio - factor).abs() > 1e-6 * ratio {
        return Ok(Conversion::Resample {
            from: source_fps,
            to: fps,
            method,
        });
    }
    Ok(Conversion::Decimate {
        factor: factor as usize,
    })
}

/// Orders rates from the fastest: the source rate first, as decimation factors 1, 2, … did.
fn rate_order(fps: f64) -> usize {
    usize::MAX - (fps * 1e6).round() as usize
}

/// Bytes one step of a channel takes in the output.
fn step_bytes(ch: &ChannelInfo) -> u64 {
    let width = ch.width() as u64;
    match ch.kind {
        ChannelKind::Lowdim => 4 * width,
        ChannelKind::Image => width,
    }
}

/// Entries per statistic: one per dimension, or one per colour channel for images.
fn stats_dims(ch: &ChannelInfo) -> usize {
    match ch.kind {
        ChannelKind::Lowdim => ch.width(),
        ChannelKind::Image => *ch.shape.last().unwrap_or(&1),
    }
}

/// Builds the plan. `lock` is the previous build's lock, if any; `out_dir` is the resolved output
/// directory (used to check the files the lock lists).
pub fn resolve(
    spec: &LoadedSpec,
    manifest: &Manifest,
    lock: Option<&SpecLock>,
    out_dir: &Path,
) -> Result<Plan> {
    let ids: Vec<u64> = manifest.episodes.iter().map(|e| e.id).collect();
    let split = match (spec.spec.split.from, &manifest.source_split) {
        (SplitFrom::Source, Some(stored)) => {
            let mut train = stored.train.clone();
            let mut val = stored.val.clone();
            train.sort_unstable();
            val.sort_unstable();
            Split { train, val }
        }
        _ => split::split(&ids, spec.spec.split.val_fraction, spec.spec.split.seed),
    };
    if split.train.is_empty() {
        return Err(spec.error_at(
            &["split", "val_fraction"],
            format!(
                "this leaves no training episode ({} episodes, {} for validation)",
                ids.len(),
                split.val.len()
            ),
            None,
        ));
    }

    let mut profiles = Vec::new();
    for profile in &spec.profiles {
        profiles.push(resolve_profile(
            spec, manifest, &split, profile, lock, out_dir,
        )?);
    }

    let mut rates: Vec<RateJob> = Vec::new();
    let mut statistics: BTreeMap<(usize, String), StatsJob> = BTreeMap::new();
    for p in &profiles {
        let r = match rates.iter().position(|r| r.conversion == p.conversion) {
            Some(r) => r,
            None => {
                rates.push(RateJob {
                    fps: p.fps,
                    conversion: p.conversion,
                    steps: p.steps,
                    profiles: Vec::new(),
                });
                rates.len() - 1
            }
        };
        rates[r].profiles.push(p.name.clone());
        // Highest rate first, as the integer factors used to sort.
        let key = rate_order(p.fps);
        for ch in &p.channels {
            statistics
                .entry((key, ch.name.clone()))
                .or_insert_with(|| StatsJob {
                    fps: p.fps,
                    channel: ch.name.clone(),
                    split: "train",
                    profiles: Vec::new(),
                })
                .profiles
                .push(p.name.clone());
        }
    }

    Ok(Plan {
        version: PLAN_VERSION,
        tool_version: TOOL_VERSION,
        spec_hash: spec.hash.clone(),
        source: SourcePlan {
            format: manifest.format.name(),
            path: spec.spec.source.path.clone(),
            fps: manifest.fps,
            episodes: manifest.episodes.len(),
            steps: manifest.episodes.iter().map(|e| e.len).sum(),
            fingerprint: manifest.fingerprint.clone(),
            channels: manifest.channels.clone(),
        },
        split,
        rates: {
            rates.sort_by_key(|r| rate_order(r.fps));
            rates
        },
        statistics: statistics.into_values().collect(),
        audit: AuditSummary::default(),
        profiles,
    })
}

/// Puts the audit into a resolved plan: the summary, and per profile the episodes it repaired
/// and left out (when `applied`, that is `[audit] repair = true`).
pub fn apply_audit(plan: &mut Plan, report: &AuditReport, applied: bool) {
    plan.audit = AuditSummary {
        expected_interval: report.expected_interval,
        timestamps: report.timestamps,
        applied,
        verdicts: report
            .verdict_counts()
            .into_iter()
            .map(|(v, k)| (v.name(), k))
            .collect(),
        repaired_fraction: report.repaired_fraction,
        excluded_fraction: report.excluded_fraction,
        warnings: report.warnings.clone(),
    };
    if !applied {
        return;
    }
    for p in &mut plan.profiles {
        for e in &report.episodes {
            match e.verdict {
                Verdict::Ok => {}
                Verdict::Exclude => p.excluded.push(Excluded {
                    id: e.id,
                    reason: format!("audit: {}", e.detail),
                }),
                Verdict::Interpolate | Verdict::Resample => p.repaired.push(RepairedEpisode {
                    id: e.id,
                    verdict: e.verdict,
                    recorded_len: e.n_frames,
                    len: e.repaired_frames,
                    detail: e.detail.clone(),
                }),
            }
        }
    }
}

fn resolve_profile(
    spec: &LoadedSpec,
    manifest: &Manifest,
    split: &Split,
    profile: &Profile,
    lock: Option<&SpecLock>,
    out_dir: &Path,
) -> Result<ProfilePlan> {
    let name = &profile.name;
    let fps = profile.fps.unwrap_or(manifest.fps);
    let conv = conversion(manifest.fps, fps, spec.spec.audit.resample).map_err(|msg| {
        spec.error_at(
            &["profiles", name, "fps"],
            format!("profile `{name}` runs at {msg}"),
            Some(format!(
                "set `profiles.{name}.fps` to the source rate ({} Hz) or less",
                manifest.fps
            )),
        )
    })?;
    let rate = match conv {
        Conversion::Decimate { factor: 1 } => {
            format!("{fps} Hz (the source rate, no conversion)")
        }
        Conversion::Decimate { factor } => {
            format!("{} Hz -> {fps} Hz: keep 1 step in {factor}", manifest.fps)
        }
        Conversion::Resample { method, .. } => format!(
            "{} Hz -> {fps} Hz: resample each episode ({}), n -> round(n × {fps} / {})",
            manifest.fps,
            match method {
                ResampleMethod::Fourier => "fourier",
                ResampleMethod::Linear => "linear",
            },
            manifest.fps
        ),
    };

    let mut channels = Vec::new();
    for ch in &manifest.channels {
        let explicit = profile.normalize.get(&ch.name).copied();
        let normalize = match ch.kind {
            ChannelKind::Lowdim if ch.shape.len() >= 2 => {
                explicit.unwrap_or(profile.normalize_multidim)
            }
            ChannelKind::Lowdim => explicit.unwrap_or(profile.normalize_lowdim),
            ChannelKind::Image => {
                let mode = explicit.unwrap_or(NormalizeMode::None);
                if mode != NormalizeMode::None {
                    return Err(spec.error_at(
                        &["profiles", name, "normalize", &ch.name],
                        format!(
                            "`{}` is an image channel; images are stored as uint8 and only `none` is supported",
                            ch.name
                        ),
                        None,
                    ));
                }
                mode
            }
        };
        channels.push(ProfileChannel {
            name: ch.name.clone(),
            kind: ch.kind,
            shape: ch.shape.clone(),
            normalize,
            export: None,
            array: String::new(),
        });
    }
    export::assign(spec, profile, &mut channels)?;

    let sampling = sampling_of(spec, manifest, profile, fps)?;
    let mut episodes = Vec::new();
    let mut warnings = Vec::new();
    let mut counts = SplitCounts {
        train: Some(0),
        val: Some(0),
    };
    let mut steps = 0;
    for e in &manifest.episodes {
        let len = conv.len(e.len);
        let samples = sampling.count(len);
        let is_train = split.is_train(e.id);
        let slot = if is_train {
            &mut counts.train
        } else {
            &mut counts.val
        };
        *slot = slot.zip(samples).map(|(a, b)| a + b);
        if samples == Some(0) {
            warnings.push(format!(
                "episode {} has {len} steps at {fps} Hz and yields no samples with {} padding (chunk {}, obs_history {})",
                e.id,
                profile.padding.name(),
                profile.chunk,
                profile.obs_history
            ));
        }
        steps += len;
        episodes.push(ProfileEpisode {
            id: e.id,
            split: if is_train { "train" } else { "val" },
            source_len: e.len,
            len,
            samples,
        });
    }
    if counts.train == Some(0) {
        let train: Vec<String> = episodes
            .iter()
            .filter(|e| e.split == "train")
            .map(|e| format!("{} ({} steps)", e.id, e.len))
            .collect();
        let more = if train.len() > 10 { ", …" } else { "" };
        return Err(spec.error_at(
            &["profiles", name, "chunk"],
            format!(
                "profile `{name}` yields no training samples: with {} padding, chunk {} and obs_history {} at {fps} Hz, every training episode is too short: {}{more}",
                profile.padding.name(),
                profile.chunk,
                profile.obs_history,
                train.iter().take(10).cloned().collect::<Vec<_>>().join(", ")
            ),
            Some(format!("lower `profiles.{name}.chunk`, or use `padding = \"edge\"` so that short episodes still give windows")),
        ));
    }

    let data_bytes: u64 = manifest
        .channels
        .iter()
        .map(|c| step_bytes(c) * steps as u64)
        .sum::<u64>()
        + 32 * (counts.train.unwrap_or(steps) + counts.val.unwrap_or(0)) as u64
        + 16 * manifest.episodes.len() as u64;
    // `/chunks` of the HDF5 layouts that add it: K (or obs_history) rows per window.
    let windows = (counts.train.unwrap_or(0) + counts.val.unwrap_or(0)) as u64;
    let (k, h) = (u64::from(profile.chunk), u64::from(profile.obs_history));
    let chunk_bytes: u64 = match (profile.format, profile.layout) {
        (crate::spec::OutputFormat::Hdf5, crate::spec::Layout::Materialized) => manifest
            .channels
            .iter()
            .filter(|c| c.kind == ChannelKind::Lowdim)
            .map(|c| {
                let steps = if c.name == "action" { k } else { h };
                windows * steps * (step_bytes(c) + 1)
            })
            .sum(),
        (crate::spec::OutputFormat::Hdf5, crate::spec::Layout::Virtual) => {
            windows * k / 8 + 4096 * k
        }
        _ => 0,
    };
    let files = vec![
        PlannedFile {
            path: match profile.format {
                crate::spec::OutputFormat::Zarr => "data.zarr/".into(),
                crate::spec::OutputFormat::ActEpisodes => "episode_*.hdf5".into(),
                crate::spec::OutputFormat::Parquet => "data/".into(),
                crate::spec::OutputFormat::RobomimicHdf5 => {
                    crate::sink::robomimic::ROBOMIMIC_FILE.into()
                }
                _ => DATA_FILE.into(),
            },
            estimated_bytes: data_bytes + chunk_bytes + 8192,
        },
        PlannedFile {
            path: LOADER_FILE.into(),
            estimated_bytes: 12_000,
        },
        PlannedFile {
            path: META_FILE.into(),
            estimated_bytes: 2048 + 24 * manifest.episodes.len() as u64,
        },
        PlannedFile {
            path: STATS_FILE.into(),
            estimated_bytes: 512
                + manifest
                    .channels
                    .iter()
                    .map(|c| 180 * stats_dims(c) as u64)
                    .sum::<u64>(),
        },
    ];

    let fingerprint = profile_fingerprint(spec, manifest, profile);
    let status = status_of(name, &fingerprint, lock, &out_dir.join(name))?;
    Ok(ProfilePlan {
        name: name.clone(),
        values: profile.clone(),
        fps,
        conversion: conv,
        rate,
        sampling,
        channels,
        episodes,
        excluded: Vec::new(),
        repaired: Vec::new(),
        warnings,
        num_samples: counts,
        steps,
        files,
        fingerprint,
        status,
    })
}

/// The sampling of a profile: windows, segments or hierarchical chunks.
fn sampling_of(
    spec: &LoadedSpec,
    manifest: &Manifest,
    profile: &Profile,
    fps: f64,
) -> Result<Sampling> {
    let name = &profile.name;
    let lead = match profile.alignment {
        crate::spec::Alignment::Current => 0,
        crate::spec::Alignment::DiffusionPolicy => profile.obs_history as usize - 1,
    };
    let mut window = Window {
        chunk: profile.chunk as usize,
        obs_history: profile.obs_history as usize,
        lead,
        padding: profile.padding,
        stride: profile.stride as usize,
        max_pad_after: profile.executes.map(|e| e.saturating_sub(1) as usize),
    };
    if let Some(seg) = &profile.segment {
        let at = |k: &str| {
            [
                "profiles".to_string(),
                name.clone(),
                "segment".into(),
                k.into(),
            ]
        };
        let Some(c) = manifest.channels.iter().position(|c| c.name == seg.channel) else {
            let key = at("channel");
            let key: Vec<&str> = key.iter().map(String::as_str).collect();
            return Err(spec.error_at(&key, format!("no channel `{}`", seg.channel), None));
        };
        let ch = &manifest.channels[c];
        if ch.kind != ChannelKind::Lowdim {
            let key = at("channel");
            let key: Vec<&str> = key.iter().map(String::as_str).collect();
            return Err(spec.error_at(
                &key,
                format!(
                    "`{}` is an image; segment on a low-dimensional channel",
                    ch.name
                ),
                None,
            ));
        }
        let width = ch.width();
        let dims: Vec<usize> = match &seg.dims {
            Some(d) => d.iter().map(|&d| d as usize).collect(),
            None => (0..width).collect(),
        };
        if let Some(&bad) = dims.iter().find(|&&d| d >= width) {
            let key = at("dims");
            let key: Vec<&str> = key.iter().map(String::as_str).collect();
            return Err(spec.error_at(
                &key,
                format!(
                    "dimension {bad} is out of range: `{}` has {width} values per step",
                    ch.name
                ),
                None,
            ));
        }
        let max_length = seg.max_length.unwrap_or(profile.chunk) as usize;
        window.chunk = max_length;
        window.lead = 0;
        window.max_pad_after = None;
        return Ok(Sampling::Segment {
            window,
            params: SegmentParams {
                method: seg.method,
                smoothing: seg.smoothing as usize,
                threshold: seg.threshold,
                min_length: seg.min_length as usize,
                max_length,
            },
            channel: c,
            dims,
        });
    }
    if let Some(h) = &profile.hierarchy {
        let coarse = (h.coarse_seconds * fps).round() as usize;
        if coarse < window.chunk {
            return Err(spec.error_at(
                &["profiles", name, "hierarchy", "coarse_seconds"],
                format!(
                    "{} s is {coarse} steps at {fps} Hz, shorter than the fine chunk ({} steps)",
                    h.coarse_seconds, window.chunk
                ),
                None,
            ));
        }
        window.lead = 0;
        window.max_pad_after = None;
        return Ok(Sampling::Hierarchy { window, coarse });
    }
    Ok(Sampling::Window { window })
}

/// Everything a profile's outputs depend on: the tool, the resolved profile, the source bytes,
/// the channel mapping, the split and the spec's output location. Other profiles' settings are
/// deliberately left out, so editing one profile rebuilds only that one.
fn profile_fingerprint(spec: &LoadedSpec, manifest: &Manifest, profile: &Profile) -> String {
    let mut h = blake3::Hasher::new();
    let parts = [
        TOOL_VERSION.to_string(),
        serde_json::to_string(profile).unwrap(),
        serde_json::to_string(&spec.spec.source).unwrap(),
        serde_json::to_string(&spec.spec.split).unwrap(),
        serde_json::to_string(&spec.spec.audit).unwrap(),
        spec.spec.output.dir.clone(),
        manifest.fingerprint.clone(),
    ];
    for p in parts {
        h.update(&(p.len() as u64).to_le_bytes());
        h.update(p.as_bytes());
    }
    h.finalize().to_hex().to_string()
}

fn status_of(name: &str, fingerprint: &str, lock: Option<&SpecLock>, dir: &Path) -> Result<Status> {
    let build = |reason: String| {
        Ok(Status {
            up_to_date: false,
            reason,
        })
    };
    let Some(lock) = lock else {
        return build("not in chunkc.lock: first build".into());
    };
    let Some(entry) = lock.profiles.get(name) else {
        return build(format!("profile `{name}` is not in chunkc.lock"));
    };
    if lock.tool_version != TOOL_VERSION {
        return build(format!(
            "chunkc changed ({} -> {TOOL_VERSION})",
            lock.tool_version
        ));
    }
    if entry.fingerprint != fingerprint {
        return build("the spec or the source changed".into());
    }
    for (file, hash) in &entry.files {
        let path = dir.join(file);
        if !path.exists() {
            return build(format!("{} is missing", path.display()));
        }
        if &lock::hash_file(&path)? != hash {
            return build(format!("{} was modified", path.display()));
        }
    }
    Ok(Status {
        up_to_date: true,
        reason: "up to date".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::{conversion, Conversion};
    use crate::spec::ResampleMethod::Fourier;

    #[test]
    fn decimate_or_resample() {
        assert_eq!(
            conversion(50.0, 10.0, Fourier),
            Ok(Conversion::Decimate { factor: 5 })
        );
        assert_eq!(
            conversion(10.0, 10.0, Fourier),
            Ok(Conversion::Decimate { factor: 1 })
        );
        let c = conversion(30.0, 20.0, Fourier).unwrap();
        assert_eq!(c.factor(), None);
        assert_eq!(c.len(31), 21);
        assert_eq!(c.len(30), 20);
        assert!(conversion(10.0, 50.0, Fourier).is_err());
    }
}
