//! Preset expansion: turns a [`ProfileSpec`] as written (and the chain of profiles it `extends`)
//! into a fully explicit [`Profile`], remembering where every value came from.
//!
//! Precedence, highest first: the profile's own keys, the profiles it extends (nearest first),
//! the preset (the nearest one in that chain, its values in [`super::preset_values`]), the
//! defaults. The values and their sources are documented in the book's presets chapter and in
//! `TARGETS.md`.

use std::collections::BTreeMap;

use super::camera;
use super::model::{
    Alignment, Compression, ImageCompression, Layout, LerobotVersion, NormalizeMode, OutputFormat,
    Padding, ProfileSpec, StatsFormat, StatsPopulation, TransformSpec,
};
use super::preset_values::{preset_values, PresetValues};

// The profile and a setting of it, where the spec's checks name them (`preset::Profile`).
pub use super::profile::Profile;
pub use super::video_settings::HAS_X264;

/// Why a profile cannot be expanded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ExpandError {
    /// A value with no default that neither the chain nor the preset gives.
    Missing(&'static str),
    /// `extends` names a profile that does not exist.
    UnknownParent(String),
    /// `extends` goes round in a circle (the names in order).
    Cycle(Vec<String>),
}

/// The profile and the profiles it extends, nearest first.
fn chain<'a>(
    name: &'a str,
    profiles: &'a BTreeMap<String, ProfileSpec>,
) -> Result<Vec<(&'a str, &'a ProfileSpec)>, ExpandError> {
    let mut out: Vec<(&str, &ProfileSpec)> = Vec::new();
    let mut current = name;
    loop {
        if out.iter().any(|(n, _)| *n == current) {
            let mut names: Vec<String> = out.iter().map(|(n, _)| n.to_string()).collect();
            names.push(current.to_string());
            return Err(ExpandError::Cycle(names));
        }
        let spec = profiles
            .get(current)
            .ok_or_else(|| ExpandError::UnknownParent(current.to_string()))?;
        out.push((current, spec));
        match &spec.extends {
            Some(parent) => current = parent,
            None => return Ok(out),
        }
    }
}

/// Expands the profile `name` of `profiles`.
// Long function: one field per profile key, resolved in a fixed order: long, not deep.
pub fn expand(
    name: &str,
    profiles: &BTreeMap<String, ProfileSpec>,
) -> Result<Profile, ExpandError> {
    let chain = chain(name, profiles)?;
    let mut origins = BTreeMap::new();

    // The nearest profile in the chain that sets a key wins.
    macro_rules! pick {
        ($field:ident) => {{
            let found = chain
                .iter()
                .find_map(|(n, p)| p.$field.clone().map(|v| (v, format!("profiles.{n}"))));
            if let Some((_, from)) = &found {
                origins.insert(stringify!($field), from.clone());
            }
            found.map(|(v, _)| v)
        }};
    }

    let preset = pick!(preset);
    let from_preset = preset.map(|p| format!("preset {}", p.name()));
    let base = preset.map(preset_values);

    // A value from the chain, else from the preset, else a default.
    macro_rules! resolve {
        ($field:ident, $preset_value:expr, $default:expr, $wrap:expr) => {{
            match pick!($field) {
                Some(v) => $wrap(v),
                None => match base.as_ref().and_then($preset_value) {
                    Some(v) => {
                        origins.insert(stringify!($field), from_preset.clone().unwrap());
                        v
                    }
                    None => {
                        origins.insert(stringify!($field), "default".to_string());
                        $default
                    }
                },
            }
        }};
    }

    let fps = resolve!(fps, |b: &PresetValues| b.fps.map(Some), None, Some);
    let chunk = match resolve!(chunk, |b: &PresetValues| b.chunk.map(Some), None, Some) {
        Some(c) => c,
        None => return Err(ExpandError::Missing("chunk")),
    };
    let obs_history = resolve!(
        obs_history,
        |b: &PresetValues| Some(b.obs_history),
        1,
        std::convert::identity
    );
    let executes = resolve!(
        executes,
        |b: &PresetValues| b.executes.map(Some),
        None,
        Some
    );
    let env = pick!(env);
    let alignment = resolve!(
        alignment,
        |b: &PresetValues| Some(b.alignment),
        Alignment::Current,
        std::convert::identity
    );
    let padding = resolve!(
        padding,
        |b: &PresetValues| Some(b.padding),
        Padding::Edge,
        std::convert::identity
    );
    let stride = resolve!(stride, |_: &PresetValues| None, 1, std::convert::identity);
    let format = resolve!(
        format,
        |b: &PresetValues| b.format,
        OutputFormat::Hdf5,
        std::convert::identity
    );
    let layout = resolve!(
        layout,
        |_: &PresetValues| None,
        Layout::Index,
        std::convert::identity
    );
    let compression = resolve!(
        compression,
        |_: &PresetValues| None,
        Compression::allowed(format)[0],
        std::convert::identity
    );
    let compression_level = resolve!(compression_level, |_: &PresetValues| None, None, Some);
    let image_compression = resolve!(
        image_compression,
        |_: &PresetValues| None,
        ImageCompression::None,
        std::convert::identity
    );
    let image_compression_level =
        resolve!(image_compression_level, |_: &PresetValues| None, None, Some);
    let image_quality = pick!(image_quality);
    let image_encoding = pick!(image_encoding).or_else(|| {
        let preset = base.as_ref().and_then(|b| b.image_encoding)?;
        (format == OutputFormat::Parquet).then_some(())?;
        origins.insert("image_encoding", from_preset.clone().unwrap());
        Some(preset)
    });
    let video_codec = pick!(video_codec);
    let video_crf = pick!(video_crf);
    let video_gop = pick!(video_gop);
    let video_copy = pick!(video_copy);
    let lerobot_version = resolve!(
        lerobot_version,
        |b: &PresetValues| b.lerobot_version,
        LerobotVersion::V30,
        std::convert::identity
    );
    // The default gets no origin: the plans of profiles that never name it stay as they were.
    if origins
        .get("lerobot_version")
        .is_some_and(|o| o == "default")
    {
        origins.remove("lerobot_version");
    }
    let zarr_version = resolve!(
        zarr_version,
        |_: &PresetValues| None,
        2,
        std::convert::identity
    );
    let stats_formats = resolve!(
        stats_formats,
        |b: &PresetValues| Some(b.stats_formats.to_vec()),
        Vec::new(),
        std::convert::identity
    );
    // A native export carries its codebase's statistics file.
    let mut stats_formats = stats_formats;
    if format == OutputFormat::ActEpisodes && !stats_formats.contains(&StatsFormat::Act) {
        stats_formats.push(StatsFormat::Act);
        stats_formats.sort();
    }
    let transforms = pick!(transforms).unwrap_or_default();
    let abs_action = pick!(abs_action).unwrap_or(false);
    let windowed = transforms.iter().any(TransformSpec::per_window);
    let stats_population = resolve!(
        stats_population,
        |b: &PresetValues| b.stats_population,
        if windowed {
            StatsPopulation::Windows
        } else {
            StatsPopulation::Frames
        },
        std::convert::identity
    );
    let segment = pick!(segment);
    let hierarchy = pick!(hierarchy);
    let extends = profiles[name].extends.clone();

    // Per-channel modes merge along the chain: farthest first, so nearer profiles override.
    let mut normalize = BTreeMap::new();
    for (_, p) in chain.iter().rev() {
        if let Some(map) = &p.normalize {
            normalize.extend(map.iter().map(|(k, v)| (k.clone(), *v)));
        }
    }
    let mut export_keys = BTreeMap::new();
    for (_, p) in chain.iter().rev() {
        if let Some(map) = &p.export_keys {
            export_keys.extend(map.iter().map(|(k, v)| (k.clone(), v.clone())));
        }
    }
    // Farthest first: a nearer profile's parts of a channel replace its parent's.
    let modality = (chain.iter().rev().filter_map(|(_, p)| p.modality.clone()))
        .flatten()
        .collect();
    let relative_actions = pick!(relative_actions).unwrap_or_default();
    let cameras = camera::merged(chain.iter().map(|(_, p)| &p.cameras));
    let (normalize_lowdim, normalize_multidim) = base
        .as_ref()
        .map(|b| (b.normalize_lowdim, b.normalize_multidim))
        .unwrap_or((NormalizeMode::None, NormalizeMode::None));
    origins.insert(
        "normalize",
        from_preset.clone().unwrap_or_else(|| "default".into()),
    );

    Ok(Profile {
        name: name.to_string(),
        preset,
        extends,
        fps,
        chunk,
        obs_history,
        executes,
        env,
        alignment,
        padding,
        stride,
        normalize_lowdim,
        normalize_multidim,
        normalize,
        format,
        export_keys,
        layout,
        compression,
        compression_level,
        image_compression,
        image_compression_level,
        image_quality,
        image_encoding,
        video_codec,
        video_crf,
        video_gop,
        video_copy,
        zarr_version,
        lerobot_version,
        modality,
        relative_actions,
        stats_formats,
        segment,
        hierarchy,
        transforms,
        stats_population,
        abs_action,
        cameras,
        origins,
    })
}

#[cfg(test)]
mod tests;
