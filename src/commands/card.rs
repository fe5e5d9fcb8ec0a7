//! The dataset cards of a build, written into the staging directory once the build's audit is
//! final (the dataset doctor judges beside the profiles' last writes) and before the commit:
//! each card from the plan, that audit, and what the build left in the profile's directory
//! (`meta.json`'s sample counts and data file, which video files were copied).

use std::collections::BTreeMap;
use std::path::Path;

use crate::audit::AuditReport;
use crate::error::{Error, IoContext, Result};
use crate::exec::{FileHashes, Staging};
use crate::lock;
use crate::plan::{Plan, ProfilePlan, META_FILE};
use crate::render::{self, card::Copies};
use crate::spec::{ImageCompression, LoadedSpec, OutputFormat};

/// The card's file in a profile's directory.
pub const CARD_FILE: &str = "README.md";

/// Writes the card of every profile `names` of `plan` into `staging`, and adds its hash.
pub fn write_cards(
    spec: &LoadedSpec,
    plan: &Plan,
    names: &[String],
    staging: &Staging,
    hashes: &mut FileHashes,
    audit: &AuditReport,
) -> Result<()> {
    let overrides = spec
        .spec
        .output
        .templates
        .as_deref()
        .map(|t| spec.resolve(t));
    let renderer = render::Renderer::new(overrides.as_deref())?;
    let spec_file = spec.file.file_name().unwrap_or_default().to_string_lossy();
    for p in plan.profiles.iter().filter(|p| names.contains(&p.name)) {
        let dir = staging.profile_dir(&p.name)?;
        let meta: serde_json::Value = {
            let path = dir.join(META_FILE);
            let text = std::fs::read_to_string(&path).at("read", &path)?;
            serde_json::from_str(&text)
                .map_err(|e| Error::Internal(format!("{}: {e}", path.display())))?
        };
        let count = |split: &str| meta["num_samples"][split].as_u64().unwrap_or(0) as usize;
        let hint = Path::new(&spec.spec.output.dir).join(&p.name);
        let stats_files = render::codebase::described(&p.values.stats_formats);
        let copies = copies(&dir, p)?;
        let text = render::card::card(
            &renderer,
            &render::card::CardContext {
                plan,
                profile: p,
                spec_file: &spec_file,
                output_hint: &hint.to_string_lossy(),
                data_file: meta["data_file"].as_str().unwrap_or_default(),
                num_samples: [count("train"), count("val")],
                stats_files: &stats_files,
                audit,
                copies: &copies,
            },
        )?;
        let path = dir.join(CARD_FILE);
        std::fs::write(&path, text).at("write", &path)?;
        std::fs::File::open(&path)
            .and_then(|f| f.sync_all())
            .at("sync", &path)?;
        hashes
            .entry(p.name.clone())
            .or_default()
            .insert(CARD_FILE.to_string(), lock::hash_file(&path)?);
    }
    Ok(())
}

/// Per camera of a profile storing video in chunkc's HDF5: how many of its episodes' files the
/// build copied from the source (`/videos/<camera>/copied`), and why it refused the others.
fn copies(dir: &Path, p: &ProfilePlan) -> Result<BTreeMap<String, Copies>> {
    let v = &p.values;
    if v.format != OutputFormat::Hdf5 || v.image_compression != ImageCompression::Video {
        return Ok(BTreeMap::new());
    }
    let path = dir.join(v.format.files().data);
    let records = crate::sink::hdf5_video::copy_records(&path)?;
    let out = records
        .into_iter()
        .map(|r| {
            let copies = Copies {
                copied: r.copied,
                episodes: r.episodes,
                refused: r.refused,
            };
            (r.camera, copies)
        })
        .collect();
    Ok(out)
}
