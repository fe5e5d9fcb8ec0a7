//! Criterion benchmark of the dataset doctor's per-episode work: what one episode of 400 steps
//! of 14-D action and state reduces to ([`Probe::features`]), the part of the doctor every
//! `build` pays for each episode it reads.
//!
//!     cargo bench --bench doctor
//!
//! The episodes come from `chunkc synth` (a tracking system, so the lag fits have a lag to find).

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};

use chunkc::audit::doctor::Probe;
use chunkc::spec::LoadedSpec;
use chunkc::{commands, synth};

const EPISODES: usize = 32;
const STEPS: usize = 400;

fn features(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temp dir");
    let opts = synth::SynthOptions {
        episodes: EPISODES,
        steps: STEPS,
        ..Default::default()
    };
    let spec_path = synth::generate(&opts, &dir.path().join("src")).expect("synth");
    let spec = LoadedSpec::load(&spec_path).expect("spec loads");
    let (source, _) = commands::plan(&spec).expect("plan");
    let probe = Probe::of(&spec, source.manifest()).expect("the doctor is on");
    let episodes: Vec<_> = (0..EPISODES)
        .map(|i| source.read_episode(i).expect("episode"))
        .collect();
    let mut g = c.benchmark_group("doctor");
    g.throughput(Throughput::Elements((EPISODES * STEPS) as u64));
    g.bench_function("features_14d_400steps", |b| {
        b.iter(|| {
            episodes
                .iter()
                .map(|ep| probe.features(ep))
                .collect::<Vec<_>>()
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1));
    targets = features
}
criterion_main!(benches);
