//! The files a profile writes and their sizes, as `chunkc plan` shows them: an upper bound where
//! one can be known before the build (`<=`), an estimate where it cannot (`~`).
//!
//! Everything stored as is has a bound: low-dim values, raw or deflated frames (compression
//! that gains nothing still adds its headers), the documents and the generated scripts. Frames
//! stored lossily (JPEG, video) take what the encoder makes of them: their sizes are estimates,
//! from what `chunkc plan` measured ([`FrameMeasure`]: the source's own video files where their
//! packets would be copied, else sample frames encoded as the profile stores them), or a rough
//! bits-per-pixel guess when nothing was measured. `tests/plan_bounds.rs` builds every vendored
//! source and checks each bound against the bytes written.
//!
//! - `containers`: the data container of each output format.
//! - `documents`: `meta.json`, `stats.json`, the scripts and the dataset card.

mod containers;
mod documents;

use std::collections::BTreeMap;

use serde::Serialize;

use super::{
    Plan, PlannedFile, ProfilePlan, SourcePlan, Split, LOADER_FILE, META_FILE, STATS_FILE,
};
use crate::error::{IoContext, Result};
use crate::source::ChannelKind;
use crate::spec::{ImageCompression, LoadedSpec, OutputFormat, StatsFormat, DEFAULT_IMAGE_QUALITY};
pub use containers::{MP4_FILE, MP4_FRAME};
pub use documents::{script_bound, SCRIPTS};

/// What `chunkc plan` measured of one camera's lossily stored frames in one profile.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameMeasure {
    /// Bytes per stored frame (a video's share of its stream).
    pub per_frame: f64,
    /// Per episode id, the bytes of its video where the source's own packets would be copied.
    pub copied: BTreeMap<u64, u64>,
    /// How it was measured, as the plan's text says it.
    pub basis: String,
}

/// By (profile, channel).
pub type FrameMeasures = BTreeMap<(String, String), FrameMeasure>;

/// How a generated script's size is known: the embedded template's bound, or a template of the
/// user's (which may loop: an estimate).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScriptSize {
    pub bytes: u64,
    pub bound: bool,
}

/// The size of each generated script: the embedded template's, or the one of the spec's
/// `[output] templates` directory that replaces it (and the parts it may include, the user's
/// where the directory replaces them).
pub fn script_sizes(spec: &LoadedSpec) -> Result<BTreeMap<String, ScriptSize>> {
    let dir = spec
        .spec
        .output
        .templates
        .as_deref()
        .map(|d| spec.resolve(d));
    let user = |name: &str| -> Result<Option<String>> {
        match dir.as_ref().map(|d| d.join(format!("{name}.j2"))) {
            Some(path) if path.is_file() => Ok(Some(
                std::fs::read_to_string(&path).at("read template", &path)?,
            )),
            _ => Ok(None),
        }
    };
    let mut sizes = BTreeMap::new();
    for name in SCRIPTS {
        let embedded = crate::templates::file(name).expect("every script has a template");
        let template = user(name)?;
        let mut bound = template.is_none();
        let mut parts = Vec::new();
        for (part, text) in crate::templates::parts_of(name) {
            let mine = user(part)?;
            bound &= mine.is_none();
            parts.push(mine.unwrap_or_else(|| text.to_string()));
        }
        let bytes = script_bound(
            template.as_deref().unwrap_or(embedded),
            parts.iter().map(String::as_str),
        );
        sizes.insert(name.to_string(), ScriptSize { bytes, bound });
    }
    Ok(sizes)
}

/// Fills in the files of every profile of `plan`, with what was `measured` of lossy frames.
pub fn fill(plan: &mut Plan, measured: &FrameMeasures) {
    let (source, split, scripts) = (&plan.source, &plan.split, &plan.scripts);
    for p in &mut plan.profiles {
        p.files = files(source, split, scripts, p, measured);
    }
}

/// A file (or a directory, or a glob of files) of the profile.
fn file(path: &str, bytes: u64, bound: bool) -> PlannedFile {
    PlannedFile {
        path: path.to_string(),
        estimated_bytes: bytes,
        bound,
        files: None,
        basis: None,
    }
}

fn files(
    source: &SourcePlan,
    split: &Split,
    scripts: &BTreeMap<String, ScriptSize>,
    p: &ProfilePlan,
    measured: &FrameMeasures,
) -> Vec<PlannedFile> {
    let lossy = Lossy { p, measured };
    let mut out = vec![containers::data(p, &lossy)];
    out.extend(lossy.videos());
    out.push(file(
        META_FILE,
        documents::meta_json(source, split, p),
        true,
    ));
    out.push(file(STATS_FILE, documents::stats_json(&p.channels), true));
    let mut names = vec![LOADER_FILE, "policy.py", "validate.py", "smoke_train.py"];
    if p.values.env.is_some() {
        names.push("rollout.py");
    }
    if p.values
        .stats_formats
        .contains(&StatsFormat::DiffusionPolicy)
    {
        names.push("dp_normalizer.py");
    }
    for name in names {
        if let Some(s) = scripts.get(name) {
            out.push(file(name, s.bytes, s.bound));
        }
    }
    out.push(file("README.md", documents::card(source, p), false));
    out
}

/// The lossy frames of one profile: measured, or guessed.
struct Lossy<'a> {
    p: &'a ProfilePlan,
    measured: &'a FrameMeasures,
}

impl Lossy<'_> {
    fn measure(&self, channel: &str) -> Option<&FrameMeasure> {
        self.measured
            .get(&(self.p.name.clone(), channel.to_string()))
    }

    /// Bytes per stored frame of `channel`: measured, or a rough bits-per-pixel guess.
    fn per_frame(&self, channel: &str) -> f64 {
        if let Some(m) = self.measure(channel) {
            return m.per_frame;
        }
        let v = &self.p.values;
        let shape = self
            .p
            .channels
            .iter()
            .find(|c| c.name == channel)
            .map_or(&[][..], |c| c.shape.as_slice());
        let pixels = shape.iter().take(2).product::<usize>() as f64;
        match v.video() {
            Some(s) => pixels * guess::video_bits(s.crf) / 8.0,
            None => {
                let q = v.image_quality.unwrap_or(DEFAULT_IMAGE_QUALITY);
                pixels * guess::jpeg_bits(q) / 8.0 + guess::JPEG_HEADERS
            }
        }
    }

    fn basis(&self, channel: &str) -> String {
        self.measure(channel).map_or_else(
            || "a rough guess: no frame was measured".to_string(),
            |m| m.basis.clone(),
        )
    }

    /// The video files of each camera stored as video: `videos/<camera>/`, one file per
    /// episode (chunkc's HDF5, LeRobot v2.1's) or one for every episode (LeRobot v3.0's).
    fn videos(&self) -> Vec<PlannedFile> {
        let p = self.p;
        let one_file = match (p.values.format, p.values.video()) {
            (OutputFormat::Hdf5, Some(_))
                if p.values.image_compression == ImageCompression::Video =>
            {
                false
            }
            (OutputFormat::Parquet, Some(_)) => !p.writes_lerobot_v21(),
            _ => return Vec::new(),
        };
        p.channels
            .iter()
            .filter(|c| c.kind == ChannelKind::Image)
            .map(|c| {
                let copied = self.measure(&c.name).map(|m| &m.copied);
                let stream = |frames: usize| {
                    let frames = frames as u64;
                    (self.per_frame(&c.name) * frames as f64).ceil() as u64
                        + containers::MP4_FILE
                        + containers::MP4_FRAME * frames
                };
                let (bytes, count) = if one_file {
                    (stream(p.steps), 1)
                } else {
                    let bytes = p
                        .episodes
                        .iter()
                        .map(|e| match copied.and_then(|m| m.get(&e.id)) {
                            Some(&b) => b,
                            None => stream(e.len),
                        })
                        .sum();
                    (bytes, p.episodes.len())
                };
                // LeRobot v2.1's are in its chunk folders (and the validation episodes' in
                // `val/`'s).
                let path = match p.writes_lerobot_v21() {
                    true => format!("videos/chunk-*/{}/", c.name),
                    false => format!("videos/{}/", c.name),
                };
                PlannedFile {
                    path,
                    estimated_bytes: bytes,
                    bound: false,
                    files: Some(count),
                    basis: Some(self.basis(&c.name)),
                }
            })
            .collect()
    }
}

impl containers::Frames for Lossy<'_> {
    fn lossy(&self, channel: &str, frames: u64) -> u64 {
        (self.per_frame(channel) * frames as f64).ceil() as u64
    }

    fn basis(&self, channel: &str) -> String {
        Lossy::basis(self, channel)
    }
}

/// Rough sizes of lossy frames when none was measured: typical of camera footage.
mod guess {
    /// Bits per pixel of an H.264 / AV1 stream at `crf` (about 0.15 at x264's default 23,
    /// halving every 6 steps of crf).
    pub fn video_bits(crf: u32) -> f64 {
        0.15 * 2f64.powf((23.0 - crf as f64) / 6.0)
    }

    /// Bits per pixel of a JPEG at `quality` (about 1.2 at 85, 2.2 at 95).
    pub fn jpeg_bits(quality: u32) -> f64 {
        let q = quality.min(100) as f64 / 100.0;
        0.3 + 2.4 * q.powi(6)
    }

    /// A JPEG's headers and tables.
    pub const JPEG_HEADERS: f64 = 600.0;
}
