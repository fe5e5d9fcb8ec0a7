//! The dataset card (`README.md`): what was built, from what and with which values; what the
//! build's audit judged (the timing verdicts, the episodes left out and why, the dataset
//! doctor's findings by kind); and how every channel is stored.
//!
//! The card is written once the build knows all of it: after the dataset doctor has judged
//! (which runs beside the profiles' last writes) and the frames are stored (whether a video was
//! copied is decided per episode), so `commands` renders it into the staging directory just
//! before the commit, from what the build left there.

use std::collections::BTreeMap;

use minijinja::{context, Value};

use super::Renderer;
use crate::audit::{AuditReport, Flag, Verdict};
use crate::error::Result;
use crate::plan::{Plan, ProfilePlan, TOOL_VERSION};
use crate::source::ChannelKind;
use crate::spec::{
    Compression, ImageCompression, ImageEncoding, OutputFormat, StatsFormat, DEFAULT_IMAGE_QUALITY,
};

/// Episode ids listed per finding before the rest are counted.
const LISTED: usize = 20;

/// How many episodes' video files of a camera are the source's own packets, and why the sink
/// refused to copy the others (when it did).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Copies {
    pub copied: usize,
    pub episodes: usize,
    pub refused: Option<String>,
}

/// What the card of one profile is rendered from.
pub struct CardContext<'a> {
    pub plan: &'a Plan,
    pub profile: &'a ProfilePlan,
    pub spec_file: &'a str,
    pub output_hint: &'a str,
    pub data_file: &'a str,
    pub num_samples: [usize; 2],
    /// (file name, what it is) of the codebase statistics files written.
    pub stats_files: &'a [(String, String)],
    /// The audit the build applied, with the dataset doctor's judgement when it ran.
    pub audit: &'a AuditReport,
    /// Per camera stored as video in chunkc's HDF5: its files copied from the source.
    pub copies: &'a BTreeMap<String, Copies>,
}

/// `ids` as the card lists them: the first [`LISTED`], then how many more.
fn listed(ids: &[u64]) -> String {
    let shown: Vec<String> = ids.iter().take(LISTED).map(|id| id.to_string()).collect();
    match ids.len().saturating_sub(LISTED) {
        0 => shown.join(", "),
        more => format!("{}, and {more} more", shown.join(", ")),
    }
}

/// Episodes per flag, over the episodes the audit judged: (flag, episode ids), flags in their
/// order, for the doctor's flags or the timing audit's.
fn flagged(report: &AuditReport, doctor: bool) -> Vec<(Flag, Vec<u64>)> {
    let mut by_flag: BTreeMap<Flag, Vec<u64>> = BTreeMap::new();
    for e in &report.episodes {
        let flags: Vec<Flag> = if doctor {
            e.findings.iter().map(|f| f.flag).collect()
        } else {
            let found: Vec<Flag> = e.findings.iter().map(|f| f.flag).collect();
            e.flags
                .iter()
                .copied()
                .filter(|f| !found.contains(f))
                .collect()
        };
        for flag in flags {
            let ids = by_flag.entry(flag).or_default();
            if ids.last() != Some(&e.id) {
                ids.push(e.id);
            }
        }
    }
    by_flag.into_iter().collect()
}

/// The card's audit section: verdicts, exclusions, findings.
fn audit(c: &CardContext) -> Value {
    let report = c.audit;
    let summary = &c.plan.audit;
    let judged = report.episodes.len();
    let verdicts: Vec<String> = report
        .verdict_counts()
        .into_iter()
        .map(|(v, n)| format!("{n} {}", v.name()))
        .collect();
    // The doctor judges the episodes the timing audit kept (those it leaves out have findings).
    let doctored = report
        .episodes
        .iter()
        .filter(|e| e.verdict != Verdict::Exclude || !e.findings.is_empty())
        .count();
    let rows = |doctor: bool| -> Vec<Value> {
        let of = if doctor { doctored } else { judged };
        flagged(report, doctor)
            .into_iter()
            .map(|(flag, ids)| {
                context! { flag => flag.name(), count => ids.len(), of, episodes => listed(&ids) }
            })
            .collect()
    };
    let excluded: Vec<Value> = c
        .profile
        .excluded
        .iter()
        .map(|e| context! { id => e.id, reason => e.reason.replace('|', "\\|") })
        .collect();
    context! {
        judged,
        verdicts => verdicts.join(", "),
        timestamps => report.timestamps,
        applied => summary.applied,
        repaired => c.profile.repaired.len(),
        timing_flags => rows(false),
        excluded,
        doctor => report.doctor.is_some(),
        findings => rows(true),
    }
}

/// How a camera's frames are stored, in words.
fn camera_storage(c: &CardContext, name: &str, shape: &[usize]) -> String {
    let v = &c.profile.values;
    let dims = shape
        .iter()
        .map(|d| d.to_string())
        .collect::<Vec<_>>()
        .join("x");
    let codec = |s: crate::spec::VideoSettings| {
        format!(
            "{} crf {}, a keyframe every {} frames",
            s.codec.name(),
            s.crf,
            s.gop
        )
    };
    match (v.format, v.image_compression, v.video()) {
        (OutputFormat::Hdf5, ImageCompression::Video, Some(s)) => {
            let Copies {
                copied,
                episodes,
                refused,
            } = c.copies.get(name).cloned().unwrap_or_default();
            let refused = refused.map_or(String::new(), |why| format!(" (copy refused: {why})"));
            let mut codecs: Vec<&str> = c
                .audit
                .video
                .iter()
                .filter(|a| a.check.channel == name && !a.check.codec.is_empty())
                .map(|a| a.check.codec.as_str())
                .collect();
            codecs.sort_unstable();
            codecs.dedup();
            let head = format!("video, one mp4 per episode in `videos/{name}/` ({dims})");
            let encoded = format!("encoded with {}", codec(s));
            let source = codecs.join(", ");
            match copied {
                0 if codecs.is_empty() => format!("{head}, {encoded}"),
                0 => format!("{head}, {encoded}; no episode's {source} packets copied{refused}"),
                n if n == episodes => format!(
                    "{head}: every episode's file ({n}) is the source's own {source} packets, \
                     copied, not encoded again"
                ),
                n => format!(
                    "{head}: {n} of {episodes} episodes' files are the source's own {source} \
                     packets, copied; the other {} {encoded}{refused}",
                    episodes - n
                ),
            }
        }
        (OutputFormat::Hdf5, ImageCompression::Jpeg, _) => format!(
            "a JPEG per frame ({dims}) at quality {} (libjpeg-turbo, 4:2:0)",
            v.image_quality.unwrap_or(DEFAULT_IMAGE_QUALITY)
        ),
        (OutputFormat::Hdf5, ImageCompression::Gzip, _) => {
            format!("uint8 frames ({dims}), each deflated (gzip)")
        }
        (OutputFormat::Parquet, _, Some(s)) if c.profile.writes_lerobot_v21() => format!(
            "video, one mp4 per episode in `videos/chunk-*/{name}/` ({dims}), the source's \
             packets copied where they are the episode's frames unchanged, else {}",
            codec(s)
        ),
        (OutputFormat::Parquet, _, Some(s)) => format!(
            "video, one mp4 of every episode in `videos/{name}/` ({dims}): {}",
            codec(s)
        ),
        (OutputFormat::Parquet, ..) if v.image_encoding != Some(ImageEncoding::Video) => {
            format!("a PNG per frame ({dims}) in the parquet rows")
        }
        (OutputFormat::Zarr, ..) if v.compression != Compression::None => format!(
            "uint8 frames ({dims}), one per chunk, Blosc {}",
            v.compression.name()
        ),
        _ => format!("uint8 frames ({dims}), one per chunk, uncompressed"),
    }
}

/// The card's storage section: the container and each camera.
fn storage(c: &CardContext) -> Value {
    let v = &c.profile.values;
    let cameras: Vec<Value> = c
        .profile
        .channels
        .iter()
        .filter(|ch| ch.kind == ChannelKind::Image)
        .map(|ch| context! { name => ch.name, stored => camera_storage(c, &ch.name, &ch.shape) })
        .collect();
    let video = v.video().filter(|_| {
        v.image_compression == ImageCompression::Video
            || v.image_encoding == Some(ImageEncoding::Video)
    });
    context! {
        format => v.format.name(),
        data_file => c.data_file,
        compression => v.compression.name(),
        image_compression => v.image_compression.name(),
        image_encoding => v.image_encoding.map(|e| e.name()),
        codec => video.map(|s| s.codec.name()),
        cameras,
    }
}

/// Where each target codebase finds its statistics.
fn stats_hints(formats: &[StatsFormat]) -> Vec<&'static str> {
    formats
        .iter()
        .map(|f| match f {
            StatsFormat::Act => {
                "ACT: copy `dataset_stats.pkl` into the checkpoint directory; `imitate_episodes.py` reads it"
            }
            StatsFormat::DiffusionPolicy => {
                "Diffusion Policy: `dp_normalizer.load_state_dict()` gives the policy's LinearNormalizer state"
            }
            StatsFormat::Lerobot => "LeRobot: `lerobot_stats.json` has the layout of `meta/stats.json`",
            StatsFormat::Openpi => {
                "openpi: `norm_stats.json` goes in the assets directory of the training config"
            }
            StatsFormat::Robomimic => {
                "robomimic: `robomimic_stats.json` holds `obs_normalization_stats` (v0.5 and v0.4 forms)"
            }
        })
        .collect()
}

/// The profile's tasks (RLDS language instructions), each with its number of episodes.
fn tasks(c: &CardContext) -> Vec<Value> {
    let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
    for e in &c.profile.episodes {
        if let Some(t) = c.plan.source.tasks.get(&e.id) {
            *counts.entry(t.as_str()).or_default() += 1;
        }
    }
    counts
        .into_iter()
        .map(|(task, episodes)| context! { task, episodes })
        .collect()
}

/// `README.md` of one profile.
pub fn card(r: &Renderer, c: &CardContext) -> Result<String> {
    let p = c.profile;
    let values: Vec<Value> = p
        .resolved_values()
        .into_iter()
        .map(|r| context! { key => r.key, value => r.value, origin => r.origin })
        .collect();
    let channels: Vec<Value> = p
        .channels
        .iter()
        .map(|ch| {
            context! {
                name => ch.name,
                kind => format!("{:?}", ch.kind).to_lowercase(),
                shape => format!("{:?}", ch.shape),
                normalize => ch.normalize.name(),
            }
        })
        .collect();
    let stats_files: Vec<Value> = c
        .stats_files
        .iter()
        .map(|(name, what)| context! { name, what })
        .collect();
    let ctx = context! {
        profile => p.name,
        tasks => tasks(c),
        version => TOOL_VERSION,
        spec_file => c.spec_file,
        spec_hash => c.plan.spec_hash,
        source => c.plan.source,
        values,
        rate => p.rate,
        sampling => p.sampling.name(),
        train_episodes => p.episodes.iter().filter(|e| e.split == "train").count(),
        val_episodes => p.episodes.iter().filter(|e| e.split == "val").count(),
        num_samples => context! { train => c.num_samples[0], val => c.num_samples[1] },
        warnings => p.warnings,
        transforms => p.transforms.iter().map(|t| t.summary()).collect::<Vec<_>>(),
        windows => p.values.stats_population == crate::spec::StatsPopulation::Windows,
        channels,
        audit => audit(c),
        storage => storage(c),
        data_file => c.data_file,
        stats_files,
        stats_hints => stats_hints(&p.values.stats_formats),
        output_hint => c.output_hint,
        chunk => p.window().chunk,
        lerobot => p.writes_lerobot_v21().then(|| lerobot(c)),
        groot => p.values.is_groot(),
    };
    r.render("README.md", ctx)
}

/// A v2.1 profile's datasets as the card shows them: (repo id, folder) of each training
/// dataset (its validation one is `<folder>/val`; a `groot` mixture's per source).
fn lerobot(c: &CardContext) -> Value {
    let p = c.profile;
    let datasets: Vec<Value> = match p.groot.len() {
        0 | 1 => vec![context! { repo_id => p.name, root => c.output_hint }],
        _ => (c.plan.source.parts.iter())
            .map(|s| {
                context! {
                    repo_id => format!("{}-{}", p.name, s.name),
                    root => format!("{}/sources/{}", c.output_hint, s.name),
                }
            })
            .collect(),
    };
    context! { fps => p.fps, datasets }
}
