//! Preset expansion: turns a [`ProfileSpec`] as written into a fully explicit [`Profile`].
//!
//! The values and where they come from are documented in the book's presets chapter and in
//! `TARGETS.md` ("Default chunk parameters").

use std::collections::BTreeMap;

use serde::Serialize;

use super::model::{NormalizeMode, OutputFormat, Padding, Preset, ProfileSpec};

/// A profile with every value decided. Later stages never look at presets again.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Profile {
    pub name: String,
    pub preset: Option<Preset>,
    /// Control rate in Hz; `None` means "the source's rate".
    pub fps: Option<f64>,
    pub chunk: u32,
    pub obs_history: u32,
    pub padding: Padding,
    pub stride: u32,
    /// Window alignment convention. Only `current` (actions start at the sample's step t, the
    /// observation history ends at t) exists so far.
    pub alignment: &'static str,
    /// Mode for low-dimensional channels not named in `normalize`.
    pub normalize_lowdim: NormalizeMode,
    /// Explicit per-channel modes from the spec.
    pub normalize: BTreeMap<String, NormalizeMode>,
    pub format: OutputFormat,
}

/// The values a preset supplies.
struct PresetValues {
    fps: Option<f64>,
    chunk: Option<u32>,
    obs_history: u32,
    padding: Padding,
    normalize_lowdim: NormalizeMode,
}

fn preset_values(preset: Option<Preset>) -> PresetValues {
    match preset {
        // ACT: K=100 at 50 Hz, the current observation only, z-score (TARGETS.md).
        Some(Preset::Act) => PresetValues {
            fps: Some(50.0),
            chunk: Some(100),
            obs_history: 1,
            padding: Padding::Edge,
            normalize_lowdim: NormalizeMode::Zscore,
        },
        // Diffusion Policy: K=16 at 10 Hz, two observations, percentile min-max.
        Some(Preset::DiffusionPolicy) => PresetValues {
            fps: Some(10.0),
            chunk: Some(16),
            obs_history: 2,
            padding: Padding::Edge,
            normalize_lowdim: NormalizeMode::Minmax,
        },
        None => PresetValues {
            fps: None,
            chunk: None,
            obs_history: 1,
            padding: Padding::Edge,
            normalize_lowdim: NormalizeMode::None,
        },
    }
}

/// Expands one profile. Returns the name of the missing key when neither the spec nor the preset
/// gives a value that has no default (only `chunk`).
pub fn expand(name: &str, spec: &ProfileSpec) -> Result<Profile, &'static str> {
    let base = preset_values(spec.preset);
    let chunk = spec.chunk.or(base.chunk).ok_or("chunk")?;
    Ok(Profile {
        name: name.to_string(),
        preset: spec.preset,
        fps: spec.fps.or(base.fps),
        chunk,
        obs_history: spec.obs_history.unwrap_or(base.obs_history),
        padding: spec.padding.unwrap_or(base.padding),
        stride: spec.stride.unwrap_or(1),
        alignment: "current",
        normalize_lowdim: base.normalize_lowdim,
        normalize: spec.normalize.clone().unwrap_or_default(),
        format: spec.format.unwrap_or(OutputFormat::Hdf5),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn override_wins_over_preset() {
        let spec = ProfileSpec {
            preset: Some(Preset::Act),
            fps: Some(10.0),
            chunk: Some(20),
            ..Default::default()
        };
        let p = expand("act", &spec).unwrap();
        assert_eq!((p.fps, p.chunk, p.obs_history), (Some(10.0), 20, 1));
        assert_eq!(p.normalize_lowdim, NormalizeMode::Zscore);
    }

    #[test]
    fn no_preset_needs_chunk() {
        assert_eq!(expand("x", &ProfileSpec::default()), Err("chunk"));
    }
}
