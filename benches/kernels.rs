//! Criterion benchmarks of chunkc's hot kernels: the window index, statistics with exact
//! percentiles, frame compression, and each writer (sink) on a small synthetic dataset.
//!
//!     cargo bench --bench kernels            # about a minute; `-- <filter>` for one group
//!
//! Measurement time is kept short (1 s per benchmark, 10 samples); pass criterion's own flags
//! (`-- --measurement-time 5`) for steadier numbers. The whole-pipeline comparison is
//! `bench/run.py`.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};

use chunkc::source::{ChannelData, ChannelKind};
use chunkc::spec::{LoadedSpec, SourceFormat};
use chunkc::stats::normalize::{Normalizer, RowNormalizer};
use chunkc::{commands, sink, stats, synth};

const EPISODES: usize = 16;
const STEPS: usize = 400;

/// A synthetic ALOHA source with one 96x96 camera and one profile per output format.
struct Fixture {
    _dir: tempfile::TempDir,
    spec: LoadedSpec,
}

fn fixture() -> Fixture {
    let dir = tempfile::tempdir().expect("temp dir");
    let opts = synth::SynthOptions {
        format: SourceFormat::AlohaHdf5,
        episodes: EPISODES,
        steps: STEPS,
        cameras: 1,
        ..Default::default()
    };
    let spec_path = synth::generate(&opts, &dir.path().join("src")).expect("synth");
    let mut text = std::fs::read_to_string(&spec_path).expect("spec");
    for format in ["zarr", "parquet", "act_episodes", "robomimic_hdf5"] {
        text.push_str(&format!(
            "\n[profiles.{format}]\npreset = \"act\"\nfps = 50.0\nformat = \"{format}\"\n"
        ));
    }
    std::fs::write(&spec_path, text).expect("spec");
    let spec = LoadedSpec::load(&spec_path).expect("spec loads");
    Fixture { _dir: dir, spec }
}

fn window_index(c: &mut Criterion) {
    let f = fixture();
    let (_, plan) = commands::plan(&f.spec).expect("plan");
    let p = &plan.profiles[0];
    let mut g = c.benchmark_group("window_index");
    g.throughput(Throughput::Elements((EPISODES * STEPS) as u64));
    g.bench_function("act_k100", |b| {
        b.iter(|| {
            let mut rows = Vec::with_capacity(EPISODES * STEPS);
            for (e, ep) in p.episodes.iter().enumerate() {
                rows.extend(
                    p.sampling
                        .samples(ep.len, None)
                        .into_iter()
                        .map(|s| [e as i64, s.t as i64, s.limit as i64, s.sub as i64]),
                );
            }
            rows
        })
    });
    g.finish();
}

/// Smooth values, like joint trajectories: `rows` x `dims`.
fn lowdim_values(rows: usize, dims: usize) -> Vec<f32> {
    (0..rows * dims)
        .map(|i| {
            let (t, d) = ((i / dims) as f32, (i % dims) as f32);
            (t * 0.01 * (1.0 + d)).sin() + 0.001 * ((i * 7919) % 101) as f32
        })
        .collect()
}

fn statistics(c: &mut Criterion) {
    let mut g = c.benchmark_group("statistics");
    for rows in [100_000usize, 1_000_000] {
        let dims = 14;
        let values = lowdim_values(rows, dims);
        let blocks: Vec<&[f32]> = values.chunks(400 * dims).collect();
        g.throughput(Throughput::Elements((rows * dims) as u64));
        g.bench_with_input(
            BenchmarkId::new("lowdim_exact", rows),
            &blocks,
            |b, blocks| b.iter(|| stats::lowdim(blocks.iter().copied(), dims)),
        );
    }
    let column = lowdim_values(1_000_000, 1);
    let qs = [0.1, 99.9, 1.0, 99.0, 10.0, 50.0, 90.0];
    g.throughput(Throughput::Elements(column.len() as u64));
    g.bench_function("percentiles_all_at_once/1000000", |b| {
        b.iter(|| stats::percentiles(&mut column.clone(), &qs))
    });
    g.bench_function("percentiles_streamed/1000000", |b| {
        b.iter(|| {
            stats::percentiles_streamed::<()>(column.len() as u64, &qs, |f| {
                column.chunks(400).for_each(&mut *f);
                Ok(())
            })
        })
    });
    g.bench_function("percentile_one_by_one/1000000", |b| {
        b.iter(|| {
            let mut v = column.clone();
            qs.iter()
                .map(|&q| stats::percentile(&mut v, q))
                .collect::<Vec<_>>()
        })
    });
    let frames = vec![0u8; 96 * 96 * 3 * 300];
    g.throughput(Throughput::Bytes(frames.len() as u64));
    g.bench_function("image_histogram/300x96x96", |b| {
        b.iter(|| stats::ImagePartial::of_frames(&frames, 300, 3))
    });
    g.finish();
}

fn frames(c: &mut Criterion) {
    let f = fixture();
    let (source, _) = commands::plan(&f.spec).expect("plan");
    let ep = source.read_episode(0).expect("episode");
    let pixels = ep
        .channels
        .iter()
        .find_map(|ch| match ch {
            ChannelData::Image(v) => Some(v.clone()),
            _ => None,
        })
        .expect("a camera");
    let frame = &pixels[..96 * 96 * 3];
    let mut g = c.benchmark_group("encode_frame");
    g.throughput(Throughput::Bytes(frame.len() as u64));
    for (name, enc) in [
        ("raw", sink::FrameEncoding::Raw),
        ("zlib1", sink::FrameEncoding::Zlib(1)),
        ("png", sink::FrameEncoding::Png),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| sink::encode_frame(enc, frame, &[96, 96, 3]))
        });
    }
    g.finish();
}

/// Every writer, fed what `exec` feeds it: per-step low-dim arrays, encoded frames, the index.
fn writers(c: &mut Criterion) {
    let f = fixture();
    let (source, plan) = commands::plan(&f.spec).expect("plan");
    let manifest = source.manifest();
    let episodes: Vec<_> = (0..manifest.episodes.len())
        .map(|i| source.read_episode(i).expect("episode"))
        .collect();
    let mut ends = Vec::new();
    let mut total = 0u64;
    for ep in &episodes {
        total += ep.len as u64;
        ends.push(total);
    }
    let ids: Vec<u64> = episodes.iter().map(|e| e.id).collect();
    let lowdim: Vec<Vec<f32>> = (0..manifest.channels.len())
        .map(|c| {
            episodes
                .iter()
                .flat_map(|ep| match &ep.channels[c] {
                    ChannelData::Lowdim(v) => v.clone(),
                    _ => Vec::new(),
                })
                .collect()
        })
        .collect();
    let stats: Vec<_> = manifest
        .channels
        .iter()
        .zip(&lowdim)
        .map(|(ch, v)| {
            (ch.kind == ChannelKind::Lowdim)
                .then(|| stats::lowdim(std::iter::once(v.as_slice()), ch.width()))
        })
        .collect();
    // In memory (an unlimited budget), as a small build keeps them.
    let stores: Vec<std::sync::Arc<chunkc::store::LowdimStore>> = manifest
        .channels
        .iter()
        .zip(&lowdim)
        .map(|(ch, v)| {
            let width = if ch.kind == ChannelKind::Lowdim {
                ch.width()
            } else {
                0
            };
            let rows = v.len() / width.max(1);
            let mut store =
                chunkc::store::LowdimStore::new(width, usize::MAX, Default::default(), rows);
            store.push(v).expect("in memory");
            std::sync::Arc::new(store)
        })
        .collect();
    let mut g = c.benchmark_group("writer");
    g.throughput(Throughput::Elements(total));
    for p in &plan.profiles {
        let out = tempfile::tempdir().expect("temp dir");
        let enc = {
            let ctx = sink::SinkContext {
                profile: p,
                dir: out.path(),
                scratch: out.path(),
                episode_ends: &ends,
                episode_ids: &ids,
                episode_sources: &[],
                source_parts: &[],
                tasks: &Default::default(),
                spill_budget: chunkc::exec::memory::budget(None),
            };
            sink::create(&ctx).expect("sink").frame_encoding()
        };
        // Frames are encoded in parallel before a sink sees them: not part of the writer's time.
        let encoded: Vec<sink::Frames> = episodes
            .iter()
            .map(|ep| {
                match ep.channels.iter().find_map(|ch| match ch {
                    ChannelData::Image(v) => Some(v),
                    _ => None,
                }) {
                    Some(v) => sink::Frames::encode(enc, v, &[96, 96, 3]),
                    None => sink::Frames::default(),
                }
            })
            .collect();
        let train: Vec<[i64; 4]> = (0..total as i64).map(|t| [0, t, 100, 0]).collect();
        g.bench_function(p.values.format.name(), |b| {
            b.iter(|| {
                let dir = out.path().join("run");
                let _ = std::fs::remove_dir_all(&dir);
                std::fs::create_dir_all(&dir).expect("dir");
                let ctx = sink::SinkContext {
                    profile: p,
                    dir: &dir,
                    scratch: &dir.join(".scratch"),
                    episode_ends: &ends,
                    episode_ids: &ids,
                    episode_sources: &[],
                    source_parts: &[],
                    tasks: &Default::default(),
                    spill_budget: chunkc::exec::memory::budget(None),
                };
                let mut s = sink::create(&ctx).expect("sink");
                for (c, ch) in p.channels.iter().enumerate() {
                    match ch.kind {
                        ChannelKind::Lowdim => {
                            let st = stats[c].as_ref().expect("low-dim stats");
                            s.write_lowdim(
                                c,
                                &stores[c],
                                &RowNormalizer::single(Normalizer::fit(ch.normalize, st)),
                            )
                            .expect("lowdim");
                        }
                        ChannelKind::Image => {
                            for (e, frames) in encoded.iter().enumerate() {
                                let row = if e == 0 { 0 } else { ends[e - 1] as usize };
                                s.write_frames(c, row, frames).expect("frames");
                            }
                        }
                    }
                }
                s.write_index(&(train.as_slice(), &[][..])).expect("index");
                s.finish().expect("finish");
            })
        });
    }
    g.finish();
}

fn config() -> Criterion {
    Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1))
}

criterion_group! {
    name = kernels;
    config = config();
    targets = window_index, statistics, frames, writers
}
criterion_main!(kernels);
