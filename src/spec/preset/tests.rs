//! Expansion of profiles over presets and `extends` chains: precedence, origins, merges, errors.

use super::*;
use crate::spec::Preset;

fn profiles(items: &[(&str, ProfileSpec)]) -> BTreeMap<String, ProfileSpec> {
    items
        .iter()
        .map(|(n, p)| (n.to_string(), p.clone()))
        .collect()
}

#[test]
fn override_wins_over_preset() {
    let spec = ProfileSpec {
        preset: Some(Preset::Act),
        fps: Some(10.0),
        chunk: Some(20),
        ..Default::default()
    };
    let p = expand("act", &profiles(&[("act", spec)])).unwrap();
    assert_eq!((p.fps, p.chunk, p.obs_history), (Some(10.0), 20, 1));
    assert_eq!(p.normalize_lowdim, NormalizeMode::Zscore);
    assert_eq!(p.origins["chunk"], "profiles.act");
    assert_eq!(p.origins["obs_history"], "preset act");
    assert_eq!(p.origins["stride"], "default");
}

#[test]
fn no_preset_needs_chunk() {
    let all = profiles(&[("x", ProfileSpec::default())]);
    assert_eq!(expand("x", &all), Err(ExpandError::Missing("chunk")));
}

#[test]
fn extends_inherits_and_overrides() {
    let base = ProfileSpec {
        preset: Some(Preset::DiffusionPolicy),
        chunk: Some(24),
        normalize: Some([("action".to_string(), NormalizeMode::Minmax)].into()),
        ..Default::default()
    };
    let child = ProfileSpec {
        extends: Some("base".into()),
        stride: Some(4),
        ..Default::default()
    };
    let all = profiles(&[("base", base), ("child", child)]);
    let p = expand("child", &all).unwrap();
    assert_eq!((p.chunk, p.stride, p.obs_history), (24, 4, 2));
    assert_eq!(p.preset, Some(Preset::DiffusionPolicy));
    assert_eq!(p.alignment, Alignment::DiffusionPolicy);
    assert_eq!(p.normalize["action"], NormalizeMode::Minmax);
    assert_eq!(p.origins["chunk"], "profiles.base");
    assert_eq!(p.origins["stride"], "profiles.child");
    assert_eq!(p.origins["obs_history"], "preset diffusion_policy");
}

#[test]
fn export_keys_merge_along_extends() {
    let map = |pairs: &[(&str, &str)]| {
        Some(
            pairs
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
        )
    };
    let base = ProfileSpec {
        preset: Some(Preset::DiffusionPolicy),
        format: Some(OutputFormat::Zarr),
        export_keys: map(&[("observation.image", "camera_0"), ("action", "act")]),
        ..Default::default()
    };
    let child = ProfileSpec {
        extends: Some("base".into()),
        export_keys: map(&[("action", "action")]),
        ..Default::default()
    };
    let all = profiles(&[("base", base), ("child", child)]);
    let p = expand("child", &all).unwrap();
    assert_eq!(p.export_keys["observation.image"], "camera_0");
    assert_eq!(p.export_keys["action"], "action");
    assert_eq!(p.export_keys.len(), 2);
}

#[test]
fn extends_cycles_and_unknown_parents_are_errors() {
    let a = ProfileSpec {
        extends: Some("b".into()),
        ..Default::default()
    };
    let b = ProfileSpec {
        extends: Some("a".into()),
        ..Default::default()
    };
    let all = profiles(&[("a", a), ("b", b)]);
    assert_eq!(
        expand("a", &all),
        Err(ExpandError::Cycle(vec!["a".into(), "b".into(), "a".into()]))
    );
    let orphan = ProfileSpec {
        extends: Some("nope".into()),
        ..Default::default()
    };
    let all = profiles(&[("x", orphan)]);
    assert_eq!(
        expand("x", &all),
        Err(ExpandError::UnknownParent("nope".into()))
    );
}
