//! A profile whose preset trains a policy on observations, in a spec that maps none.
//!
//! Such a spec is valid and builds: its windows hold the action alone. But ACT, Diffusion Policy,
//! DP3 and pi0 all condition on the robot's state or its cameras, and a policy given neither
//! sees nothing but its own past actions. `chunkc check` says so as a warning (exit status 0):
//! it is usually a state key `chunkc init` or the user left unmapped.

use super::{LoadedSpec, Preset};

/// Whether the policies of `preset` read observations (every preset chunkc has does; the match
/// makes a new preset decide).
fn needs_observations(preset: Preset) -> bool {
    match preset {
        Preset::Act
        | Preset::DiffusionPolicy
        | Preset::Dp3
        | Preset::DiffusionPolicyHighfreq
        | Preset::LerobotAct
        | Preset::LerobotDiffusion
        | Preset::Pi0
        | Preset::Pi05
        | Preset::Pi0Fast
        | Preset::Openpi
        | Preset::Groot => true,
    }
}

/// One warning per profile whose preset needs observations, when `[source.channels]` maps none
/// (no `observation.*` channel: neither low-dim nor a camera).
pub fn missing_observations(spec: &LoadedSpec) -> Vec<String> {
    let channels = spec.channel_map();
    if channels.keys().any(|c| *c != "action") {
        return Vec::new();
    }
    let mut out = Vec::new();
    for p in &spec.profiles {
        let Some(preset) = p.preset.filter(|&preset| needs_observations(preset)) else {
            continue;
        };
        out.push(format!(
            "profile `{}` (preset `{}`) has no observation: [source.channels] maps only `action`, so the policy would train on no state and no camera; map one, e.g. `\"observation.state\" = \"<state key>\"` (`chunkc inspect {}` lists the keys)",
            p.name,
            preset.name(),
            spec.source_paths().join(" ")
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(channels: &str, profiles: &str) -> LoadedSpec {
        let text = format!(
            "version = 1\n[source]\nformat = \"diffusion_policy_zarr\"\npath = \"d.zarr\"\nfps = 10\n[source.channels]\n{channels}\n[output]\ndir = \"out\"\n{profiles}"
        );
        LoadedSpec::parse("t.toml", &text, std::path::Path::new(".")).unwrap()
    }

    #[test]
    fn an_action_only_spec_warns_for_each_preset_profile() {
        let s = spec(
            "action = \"action\"",
            "[profiles.act]\npreset = \"act\"\n[profiles.dp]\npreset = \"diffusion_policy\"\n[profiles.raw]\nchunk = 8\n",
        );
        let w = missing_observations(&s);
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(w[0].contains("profile `act` (preset `act`)"), "{}", w[0]);
        assert!(w[1].contains("profile `dp` (preset `diffusion_policy`)"));
    }

    #[test]
    fn any_observation_silences_it() {
        let s = spec(
            "action = \"action\"\n\"observation.image\" = \"img\"",
            "[profiles.act]\npreset = \"act\"\n",
        );
        assert!(missing_observations(&s).is_empty());
    }
}
