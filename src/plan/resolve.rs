//! Resolution: spec + audited manifest + lock → [`Plan`]. Per profile: the rate conversion, the
//! channels and their normalization, the sampling, the episodes used and their sample counts,
//! the files with estimated sizes, and the freshness; then the work profiles share.

use std::collections::BTreeMap;
use std::path::Path;

use super::estimate;
use super::freshness;
use super::sampling::sampling_of;
use super::{
    cameras, conversion, export, rate_order, split, AuditSummary, Conversion, Excluded, Plan,
    ProfileChannel, ProfileEpisode, ProfilePlan, RateJob, RepairedEpisode, SourcePlan, Split,
    SplitCounts, StatsJob, PLAN_VERSION, TOOL_VERSION,
};
use crate::audit::{AuditReport, Verdict};
use crate::error::Result;
use crate::lock::SpecLock;
use crate::source::{ChannelKind, Manifest};
use crate::spec::{LoadedSpec, NormalizeMode, Profile, SplitFrom};
use crate::window::Sampling;

/// Builds the plan. `lock` is the previous build's lock, if any; `out_dir` is the resolved output
/// directory (used to check the files the lock lists).
pub fn resolve(
    spec: &LoadedSpec,
    manifest: &Manifest,
    lock: Option<&SpecLock>,
    out_dir: &Path,
) -> Result<Plan> {
    let split = split_of(spec, manifest)?;
    let mut profiles = Vec::new();
    for profile in &spec.profiles {
        profiles.push(resolve_profile(
            spec, manifest, &split, profile, lock, out_dir,
        )?);
    }
    let (rates, statistics) = shared_jobs(&profiles);
    let mut plan = Plan {
        version: PLAN_VERSION,
        tool_version: TOOL_VERSION,
        spec_hash: spec.hash.clone(),
        source: SourcePlan {
            format: super::mixture::format_name(manifest),
            path: spec.source_paths().join(", "),
            fps: manifest.fps,
            episodes: manifest.episodes.len(),
            steps: manifest.episodes.iter().map(|e| e.len).sum(),
            fingerprint: manifest.fingerprint.clone(),
            channels: manifest.channels.clone(),
            parts: manifest.parts.clone(),
            tasks: manifest.tasks.clone(),
        },
        mixture: (!manifest.parts.is_empty())
            .then(|| spec.spec.mixture.clone().unwrap_or_default()),
        split,
        rates,
        statistics,
        audit: AuditSummary::default(),
        profiles,
        scripts: estimate::script_sizes(spec)?,
        memory: spec.spec.build.memory.map(|m| m.0),
    };
    estimate::fill(&mut plan, &estimate::FrameMeasures::new());
    Ok(plan)
}

/// The train/validation split: the source's own (`[split] from = "source"`), else the seeded one.
fn split_of(spec: &LoadedSpec, manifest: &Manifest) -> Result<Split> {
    if !manifest.parts.is_empty() {
        return super::mixture::split(spec, manifest);
    }
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

    Ok(split)
}

/// The work profiles share: one job per distinct rate (and stored camera sizes), one statistics
/// job per (rate, channel, stored frame size).
fn shared_jobs(profiles: &[ProfilePlan]) -> (Vec<RateJob>, Vec<StatsJob>) {
    let mut rates: Vec<RateJob> = Vec::new();
    type StatsKey = (usize, String, Option<[usize; 2]>);
    let mut statistics: BTreeMap<StatsKey, StatsJob> = BTreeMap::new();
    for p in profiles {
        let r = match rates.iter().position(|r| p.uses(r)) {
            Some(r) => r,
            None => {
                rates.push(RateJob {
                    fps: p.fps,
                    conversion: p.conversion,
                    steps: p.steps,
                    cameras: p.cameras(),
                    profiles: Vec::new(),
                });
                rates.len() - 1
            }
        };
        rates[r].profiles.push(p.name.clone());
        // Highest rate first, as the integer factors used to sort.
        let key = rate_order(p.fps);
        for ch in &p.channels {
            let size = ch.resize.map(|r| r.size);
            statistics
                .entry((key, ch.name.clone(), size))
                .or_insert_with(|| StatsJob {
                    fps: p.fps,
                    channel: ch.name.clone(),
                    size,
                    split: "train",
                    profiles: Vec::new(),
                })
                .profiles
                .push(p.name.clone());
        }
    }

    rates.sort_by_key(|r| rate_order(r.fps));
    (rates, statistics.into_values().collect())
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
        doctor_seconds: report.doctor_seconds,
    };
    for p in &mut plan.profiles {
        for e in &report.episodes {
            // `[audit] repair = false` keeps every verdict but one: an episode left out for a
            // bad video (`[audit] video`) cannot be read at all.
            if !applied && !e.flags.contains(&crate::audit::Flag::Video) {
                continue;
            }
            match e.verdict {
                Verdict::Ok => {}
                Verdict::Exclude => p.excluded.push(Excluded {
                    id: e.id,
                    reason: e.exclusion_reason(),
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
    // `meta.json` lists the exclusions and repairs.
    let measured = estimate::FrameMeasures::new();
    estimate::fill(plan, &measured);
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
    let mut channels = channels_of(spec, manifest, profile)?;
    cameras::apply(spec, manifest, profile, &mut channels)?;
    export::assign(spec, profile, &mut channels)?;
    let sampling = sampling_of(spec, manifest, profile, fps)?;
    let (transforms, widths) = super::transforms::resolve(spec, manifest, profile, &sampling)?;
    if profile.abs_action && !profile.normalize.contains_key("action") {
        if let Some(action) = channels.iter_mut().find(|c| c.name == "action") {
            action.normalize = NormalizeMode::DpAbsAction;
        }
    }
    let groot = super::groot::resolve(spec, manifest, profile, &channels, &widths)?;
    let used = episodes_of(spec, manifest, split, profile, fps, conv, &sampling)?;

    let fingerprint = freshness::profile_fingerprint(spec, manifest, profile);
    let inputs = freshness::inputs(spec, profile);
    let current = freshness::Current {
        name,
        fingerprint: &fingerprint,
        inputs: &inputs,
        manifest,
        dir: &out_dir.join(name),
    };
    let status = freshness::status_of(&current, lock)?;
    Ok(ProfilePlan {
        name: name.clone(),
        values: profile.clone(),
        fps,
        conversion: conv,
        rate: super::text::rate_line(manifest.fps, fps, conv),
        sampling,
        channels,
        transforms,
        widths,
        groot,
        episodes: used.episodes,
        excluded: Vec::new(),
        repaired: Vec::new(),
        warnings: used.warnings,
        num_samples: used.counts,
        steps: used.steps,
        files: Vec::new(),
        fingerprint,
        inputs,
        status,
    })
}

/// The profile's channels with their normalization (images only `none`).
fn channels_of(
    spec: &LoadedSpec,
    manifest: &Manifest,
    profile: &Profile,
) -> Result<Vec<ProfileChannel>> {
    let name = &profile.name;
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
            resize: None,
        });
    }
    Ok(channels)
}

/// The episodes a profile uses, at its rate, with their samples.
struct Used {
    episodes: Vec<ProfileEpisode>,
    warnings: Vec<String>,
    counts: SplitCounts,
    steps: usize,
}

/// Every episode at the profile's rate, its split and sample count; an error naming
/// `profiles.<name>.chunk` when no training episode yields a sample.
fn episodes_of(
    spec: &LoadedSpec,
    manifest: &Manifest,
    split: &Split,
    profile: &Profile,
    fps: f64,
    conv: Conversion,
    sampling: &Sampling,
) -> Result<Used> {
    let mut used = Used {
        episodes: Vec::new(),
        warnings: Vec::new(),
        counts: SplitCounts {
            train: Some(0),
            val: Some(0),
        },
        steps: 0,
    };
    for e in &manifest.episodes {
        let len = conv.len(e.len);
        let samples = sampling.count(len);
        let is_train = split.is_train(e.id);
        let slot = if is_train {
            &mut used.counts.train
        } else {
            &mut used.counts.val
        };
        *slot = slot.zip(samples).map(|(a, b)| a + b);
        if samples == Some(0) {
            used.warnings.push(format!(
                "episode {} has {len} steps at {fps} Hz and yields no samples with {} padding (chunk {}, obs_history {})",
                e.id,
                profile.padding.name(),
                profile.chunk,
                profile.obs_history
            ));
        }
        used.steps += len;
        used.episodes.push(ProfileEpisode {
            id: e.id,
            split: if is_train { "train" } else { "val" },
            source_len: e.len,
            len,
            samples,
        });
    }
    if used.counts.train == Some(0) {
        return Err(no_training_samples(spec, profile, fps, &used.episodes));
    }
    Ok(used)
}

fn no_training_samples(
    spec: &LoadedSpec,
    profile: &Profile,
    fps: f64,
    episodes: &[ProfileEpisode],
) -> crate::Error {
    let name = &profile.name;
    let train: Vec<String> = episodes
        .iter()
        .filter(|e| e.split == "train")
        .map(|e| format!("{} ({} steps)", e.id, e.len))
        .collect();
    let more = if train.len() > 10 { ", …" } else { "" };
    spec.error_at(
        &["profiles", name, "chunk"],
        format!(
            "profile `{name}` yields no training samples: with {} padding, chunk {} and obs_history {} at {fps} Hz, every training episode is too short: {}{more}",
            profile.padding.name(),
            profile.chunk,
            profile.obs_history,
            train.iter().take(10).cloned().collect::<Vec<_>>().join(", ")
        ),
        Some(format!("lower `profiles.{name}.chunk`, or use `padding = \"edge\"` so that short episodes still give windows")),
    )
}
