//! Many profiles at different rates read the source once, and share their statistics.

use chunkc::commands::{self, BuildOptions};
use chunkc::spec::LoadedSpec;

fn spec_text(source: &str) -> String {
    format!(
        r#"
version = 1
[source]
format = "diffusion_policy_zarr"
path = "{source}"
fps = 10
[source.channels]
action = "action"
"observation.state" = "state"
"observation.image" = "img"
[output]
dir = "out"
[profiles.act]
preset = "act"
fps = 10
chunk = 20
[profiles.dp]
preset = "diffusion_policy"
[profiles.dp_5hz]
extends = "dp"
fps = 5
chunk = 8
[profiles.openpi_2hz]
preset = "openpi"
fps = 2
chunk = 4
[profiles.lerobot]
preset = "lerobot_diffusion"
fps = 5
"#
    )
}

#[test]
fn five_profiles_at_three_rates_read_each_episode_once() {
    let dir = tempfile::tempdir().unwrap();
    let source =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/pusht_subset.zarr");
    let text = spec_text(&source.to_string_lossy());
    let spec_path = dir.path().join("spec.toml");
    std::fs::write(&spec_path, &text).unwrap();
    let spec = LoadedSpec::load(&spec_path).unwrap();

    let (_, plan) = commands::plan(&spec).unwrap();
    let rates: Vec<f64> = plan.rates.iter().map(|r| r.fps).collect();
    assert_eq!(rates, vec![10.0, 5.0, 2.0]);
    // Statistics are planned once per (rate, channel), not once per profile.
    assert_eq!(plan.statistics.len(), 3 * 3);
    let shared = plan
        .statistics
        .iter()
        .find(|s| s.fps == 5.0 && s.channel == "action")
        .unwrap();
    assert_eq!(shared.profiles, vec!["dp_5hz", "lerobot"]);

    let report = commands::build(&spec, &BuildOptions::default()).unwrap();
    assert_eq!(report.built.len(), 5);
    assert_eq!(report.episode_reads.len(), plan.source.episodes);
    assert!(
        report.episode_reads.iter().all(|&n| n == 1),
        "episodes read {:?} times",
        report.episode_reads
    );

    // A second build reads nothing.
    let again = commands::build(&spec, &BuildOptions::default()).unwrap();
    assert!(again.built.is_empty() && again.episode_reads.is_empty());
}

#[test]
fn extends_shows_resolved_values_and_origins_in_the_plan() {
    let dir = tempfile::tempdir().unwrap();
    let source =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/pusht_subset.zarr");
    let spec_path = dir.path().join("spec.toml");
    std::fs::write(&spec_path, spec_text(&source.to_string_lossy())).unwrap();
    let spec = LoadedSpec::load(&spec_path).unwrap();
    let (_, plan) = commands::plan(&spec).unwrap();
    let p = plan.profiles.iter().find(|p| p.name == "dp_5hz").unwrap();
    assert_eq!(p.values.chunk, 8);
    assert_eq!(p.values.obs_history, 2);
    assert_eq!(p.values.origins["chunk"], "profiles.dp_5hz");
    assert_eq!(p.values.origins["preset"], "profiles.dp");
    assert_eq!(p.values.origins["obs_history"], "preset diffusion_policy");
    let text = chunkc::plan::render_text(&plan);
    assert!(
        text.contains("obs_history 2 (preset diffusion_policy)"),
        "{text}"
    );
}

/// A training mixture's sources are read once too: each source's dataset doctor rides on the
/// build's read (at the source's own rate) instead of reading the source in a pass of its own,
/// so every storage chunk of every source is decoded once.
#[test]
fn a_mixtures_doctor_rides_on_the_one_read() {
    let dir = tempfile::tempdir().unwrap();
    let source =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/pusht_subset.zarr");
    let source = source.to_string_lossy();
    let text = format!(
        r#"
version = 1
[sources.a]
format = "diffusion_policy_zarr"
path = "{source}"
fps = 10
[sources.a.channels]
action = "action"
"observation.state" = "state"
[sources.b]
format = "diffusion_policy_zarr"
path = "{source}"
fps = 10
[sources.b.channels]
action = "action"
"observation.state" = "state"
[output]
dir = "out"
[profiles.act]
preset = "act"
fps = 10
chunk = 8
"#
    );
    let spec_path = dir.path().join("spec.toml");
    std::fs::write(&spec_path, &text).unwrap();
    let spec = LoadedSpec::load(&spec_path).unwrap();
    let report = commands::build(&spec, &BuildOptions::default()).unwrap();
    assert!(report.doctor_seconds.is_some(), "the doctor ran");
    assert!(!report.block_decodes.is_empty());
    for (array, counts) in &report.block_decodes {
        assert!(
            counts.values().all(|&n| n == 1),
            "{array}: blocks decoded {counts:?} times"
        );
    }
    assert!(report.episode_reads.iter().all(|&n| n == 1));
}
