//! Replays every checked-in fuzz corpus file (`fuzz/corpus/<target>/`) through the same function
//! the libFuzzer target calls (`chunkc::fuzzing`), on stable Rust with no extra tools: an input
//! that once crashed a parser is kept in the corpus and must not panic again.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

fn replay(target: &str, body: fn(&[u8]) -> bool) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(target);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("readable corpus").path())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{}: the corpus is empty", dir.display());
    let mut panicked = Vec::new();
    for file in &files {
        let data = std::fs::read(file).expect("readable corpus file");
        if catch_unwind(AssertUnwindSafe(|| body(&data))).is_err() {
            panicked.push(file.display().to_string());
        }
    }
    chunkc::fuzzing::remove_scratch(target);
    assert!(
        panicked.is_empty(),
        "{target}: {} of {} corpus inputs panicked:\n{}",
        panicked.len(),
        files.len(),
        panicked.join("\n")
    );
}

#[test]
fn spec_corpus() {
    replay("spec", chunkc::fuzzing::spec);
}

#[test]
fn lerobot_info_corpus() {
    replay("lerobot_info", chunkc::fuzzing::lerobot_info);
}

#[test]
fn zarr_metadata_corpus() {
    replay("zarr_metadata", chunkc::fuzzing::zarr_metadata);
}

#[test]
fn hdf5_attributes_corpus() {
    replay("hdf5_attributes", chunkc::fuzzing::hdf5_attributes);
}

/// The seeds taken from real files get all the way through (the source opens and its episodes
/// read), so the targets reach the adapters' deep code rather than failing early.
#[test]
fn real_seeds_get_through() {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus");
    let read = |rel: &str| std::fs::read(corpus.join(rel)).expect("seed file");
    for spec in [
        "specs_pusht.toml",
        "specs_lerobot_g1.toml",
        "specs_multi_arch.toml",
    ] {
        assert!(
            chunkc::fuzzing::spec(&read(&format!("spec/{spec}"))),
            "{spec}"
        );
    }
    assert!(!chunkc::fuzzing::spec(&read(
        "spec/specs_bad_zero_chunk.toml"
    )));
    for info in ["g1_v2.1.json", "synthetic_v3.0.json"] {
        assert!(
            chunkc::fuzzing::lerobot_info(&read(&format!("lerobot_info/{info}"))),
            "{info}"
        );
    }
    // Each array's own metadata put back in place: the replay buffer reads.
    for seed in ["0_episode_ends.zarray", "1_action.zarray", "4_root.zgroup"] {
        assert!(
            chunkc::fuzzing::zarr_metadata(&read(&format!("zarr_metadata/{seed}"))),
            "{seed}"
        );
    }
    // `action`'s metadata as `episode_ends`: a float array where integers belong.
    assert!(!chunkc::fuzzing::zarr_metadata(&read(
        "zarr_metadata/0_action.zarray"
    )));
    // Inputs (found by random search) that describe a file the adapter opens and reads.
    for seed in ["opens_0", "opens_1"] {
        let data = read(&format!("hdf5_attributes/{seed}"));
        assert!(chunkc::fuzzing::hdf5_attributes(&data), "{seed}");
    }
    chunkc::fuzzing::remove_scratch("hdf5_attributes");
    chunkc::fuzzing::remove_scratch("lerobot_info");
    chunkc::fuzzing::remove_scratch("zarr_metadata");
}

/// A short, bounded fuzz run that needs no extra tools, so that CI (stable Rust, no cargo-fuzz)
/// still fuzzes: every target gets `rounds` inputs made by mutating its corpus files (byte flips,
/// insertions, deletions, duplicated ranges, splices of two files) with a fixed seed, so a
/// failure reproduces. Not coverage-guided: `scripts/fuzz.sh` (libFuzzer) is the real fuzzer.
fn mutate_and_run(target: &str, body: fn(&[u8]) -> bool, rounds: usize) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(target);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("corpus directory")
        .map(|e| e.expect("readable corpus").path())
        .collect();
    files.sort();
    let inputs: Vec<Vec<u8>> = files
        .iter()
        .map(|f| std::fs::read(f).expect("corpus file"))
        .collect();
    // xorshift64*: deterministic, and enough to pick mutations.
    let mut state = 0x9E37_79B9_7F4A_7C15_u64 ^ target.len() as u64;
    let mut next = move |bound: usize| -> usize {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        (state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as usize % bound.max(1)
    };
    for round in 0..rounds {
        let mut data = inputs[next(inputs.len())].clone();
        for _ in 0..1 + next(4) {
            let len = data.len();
            match next(5) {
                0 if len > 0 => {
                    let i = next(len);
                    data[i] ^= 1 << next(8);
                }
                1 => {
                    let i = next(len + 1);
                    data.insert(i, next(256) as u8);
                }
                2 if len > 0 => {
                    let (a, n) = (next(len), 1 + next(16));
                    data.drain(a..(a + n).min(len));
                }
                3 if len > 0 => {
                    let (a, n) = (next(len), 1 + next(32));
                    let piece = data[a..(a + n).min(len)].to_vec();
                    let at = next(len + 1);
                    data.splice(at..at, piece);
                }
                _ => {
                    let other = &inputs[next(inputs.len())];
                    let cut = next(data.len() + 1);
                    let from = next(other.len() + 1);
                    data.truncate(cut);
                    data.extend_from_slice(&other[from..]);
                }
            }
        }
        if catch_unwind(AssertUnwindSafe(|| body(&data))).is_err() {
            let path = std::env::temp_dir().join(format!("chunkc-fuzz-{target}-{round}"));
            std::fs::write(&path, &data).expect("write the crashing input");
            chunkc::fuzzing::remove_scratch(target);
            panic!(
                "{target}: mutated input {round} panicked; saved to {} (add it to fuzz/corpus/{target}/ once fixed)",
                path.display()
            );
        }
    }
    chunkc::fuzzing::remove_scratch(target);
}

#[test]
fn mutated_inputs_do_not_panic() {
    mutate_and_run("spec", chunkc::fuzzing::spec, 3000);
    mutate_and_run("lerobot_info", chunkc::fuzzing::lerobot_info, 300);
    mutate_and_run("zarr_metadata", chunkc::fuzzing::zarr_metadata, 300);
    mutate_and_run("hdf5_attributes", chunkc::fuzzing::hdf5_attributes, 300);
}
