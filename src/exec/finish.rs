//! The end of a profile's build, once the source has been read and the statistics reduced:
//! normalizers, the window index, the container's last writes, and every document and generated
//! file beside it. Returns the BLAKE3 of each file, for the lock.

use std::collections::BTreeMap;
use std::path::Path;

use super::RateState;
use crate::chunk::Sampling;
use crate::error::{IoContext, Result};
use crate::lock;
use crate::plan::{Plan, ProfilePlan, META_FILE, STATS_FILE};
use crate::render;
use crate::sink::{self, documents, Sink};
use crate::source::{self, ChannelKind, Manifest};
use crate::spec::LoadedSpec;
use crate::stats::{normalize::Normalizer, ChannelStats};

/// What every profile of a build shares.
pub(super) struct Shared<'a> {
    pub spec: &'a LoadedSpec,
    pub plan: &'a Plan,
    pub manifest: &'a Manifest,
    pub renderer: &'a render::Renderer,
}

pub(super) fn profile(
    shared: &Shared,
    p: &ProfilePlan,
    rate: &RateState,
    stats: &BTreeMap<String, ChannelStats>,
    mut sink: Box<dyn Sink>,
    dir: &Path,
) -> Result<BTreeMap<String, String>> {
    let (manifest, plan, spec, renderer) =
        (shared.manifest, shared.plan, shared.spec, shared.renderer);
    let mut normalizers = BTreeMap::new();
    for (c, ch) in p.channels.iter().enumerate() {
        let n = Normalizer::fit(ch.normalize, &stats[&ch.name]);
        if ch.kind == ChannelKind::Lowdim {
            sink.write_lowdim(c, &rate.lowdim[c], &n)?;
        }
        normalizers.insert(ch.name.clone(), n);
    }
    let mut train = Vec::new();
    let mut val = Vec::new();
    let mut segments = Vec::new();
    for (e, ep) in p.episodes.iter().enumerate() {
        let start = if e == 0 { 0 } else { rate.ends[e - 1] as usize };
        let watched = match &p.sampling {
            Sampling::Segment { channel, .. } => {
                let width = manifest.channels[*channel].width();
                Some((rate.lowdim[*channel].rows(start, start + ep.len)?, width))
            }
            _ => None,
        };
        let samples = p
            .sampling
            .samples(ep.len, watched.as_ref().map(|(v, w)| (v.as_ref(), *w)));
        if matches!(p.sampling, Sampling::Segment { .. }) {
            segments.push(
                samples
                    .iter()
                    .map(|s| [s.t, s.t + s.limit])
                    .collect::<Vec<_>>(),
            );
        }
        let rows = if ep.split == "train" {
            &mut train
        } else {
            &mut val
        };
        rows.extend(
            samples
                .into_iter()
                .map(|s| [e as i64, s.t as i64, s.limit as i64, s.sub as i64]),
        );
    }
    sink.write_index(&train, &val)?;
    let data_file = sink.data_file().to_string();
    let normalized = sink.stores_normalized();
    sink.finish()?;

    let write = |name: &str, text: String| -> Result<()> {
        let path = dir.join(name);
        std::fs::write(&path, text).at("write", &path)
    };
    write(
        META_FILE,
        documents::meta_json(
            plan,
            p,
            &documents::Built {
                episode_ends: &rate.ends,
                normalizers: &normalizers,
                num_samples: [train.len(), val.len()],
                segments: &segments,
            },
            &data_file,
            normalized,
        ),
    )?;
    write(STATS_FILE, documents::stats_json(stats))?;
    if p.values.format == crate::spec::OutputFormat::Parquet {
        // LeRobot v3.0 reads its statistics from `meta/stats.json`.
        let path = dir.join(sink::lerobot::STATS_PATH);
        std::fs::write(&path, render::codebase::lerobot(p, stats)).at("write", &path)?;
    }
    let mut stats_files = Vec::new();
    if !p.values.stats_formats.is_empty() {
        // ACT's `example_qpos`: the state of the first training episode, in raw units.
        let example_state = render::codebase::state_channel(p)
            .and_then(|state| {
                let c = p.channels.iter().position(|ch| ch.name == state.name)?;
                let e = p.episodes.iter().position(|ep| ep.split == "train")?;
                let width = manifest.channels[c].width();
                let start = if e == 0 { 0 } else { rate.ends[e - 1] as usize };
                let end = rate.ends[e] as usize;
                Some(rate.lowdim[c].rows(start, end).map(|v| (v, width)))
            })
            .transpose()?;
        let inputs = render::codebase::Inputs {
            profile: p,
            stats,
            normalizers: &normalizers,
            example_state: example_state.as_ref().map(|(v, w)| (v.as_ref(), *w)),
            renderer,
        };
        for f in render::codebase::files(&p.values.stats_formats, &inputs)? {
            let path = dir.join(&f.name);
            std::fs::write(&path, f.bytes).at("write", &path)?;
            stats_files.push((f.name, f.what));
        }
    }
    let hint = Path::new(&spec.spec.output.dir).join(&p.name);
    let generated = render::profile_files(
        renderer,
        &render::ProfileContext {
            plan,
            profile: p,
            spec_file: &spec.file.file_name().unwrap_or_default().to_string_lossy(),
            output_hint: &hint.to_string_lossy(),
            data_file: &data_file,
            num_samples: [train.len(), val.len()],
            stats_files: &stats_files,
        },
    )?;
    for (name, text) in generated {
        write(name, text)?;
    }

    let mut files = BTreeMap::new();
    for rel in source::fingerprint::list_files(dir)? {
        let name = rel.to_string_lossy().replace('\\', "/");
        files.insert(name, lock::hash_file(&dir.join(&rel))?);
    }
    Ok(files)
}
