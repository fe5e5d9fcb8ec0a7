//! Every storage chunk of the source is decoded exactly once per build, whatever the source's
//! chunking: zarr (v2 and v3) with one chunk per episode, chunks spanning several episodes, and
//! zarr-python's default chunking that also splits the columns; robomimic's chunked frames and
//! robosuite's `states` (read for the timestamps and as a channel); LeRobot v3.0 row groups that
//! hold several episodes.
//!
//! The oracle for "every chunk" is the files themselves: the chunk files a zarr array has on disk,
//! the chunks HDF5 lists for each dataset, the row groups in each parquet footer.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use chunkc::commands::{self, BuildOptions};
use chunkc::source::DecodeCounts;
use chunkc::spec::{LoadedSpec, SourceFormat};
use chunkc::synth::{self, dp_zarr::ZarrLayout, SynthOptions};

const EPISODES: usize = 24;
const STEPS: usize = 40;

fn build(spec_path: &Path) -> DecodeCounts {
    // The default spec: the dataset doctor (on by default) computes its features from the
    // episodes the build's one pass reads, so it decodes nothing of its own.
    let spec = LoadedSpec::load(spec_path).unwrap();
    let report = commands::build(&spec, &BuildOptions::default()).unwrap();
    assert!(report.episode_reads.iter().all(|&n| n == 1));
    report.block_decodes
}

/// Fails on any chunk decoded twice, and on any chunk of `expected` never decoded (or any
/// decoded chunk that is not in `expected`).
fn assert_once(decodes: &DecodeCounts, expected: &BTreeMap<String, BTreeSet<Vec<u64>>>) {
    let twice: Vec<String> = decodes
        .iter()
        .flat_map(|(a, chunks)| {
            chunks
                .iter()
                .filter(|(_, &n)| n != 1)
                .map(move |(c, n)| format!("{a} {c:?}: {n} decodes"))
        })
        .collect();
    assert!(twice.is_empty(), "decoded more than once: {twice:?}");
    let got: BTreeMap<String, BTreeSet<Vec<u64>>> = decodes
        .iter()
        .map(|(a, chunks)| (a.clone(), chunks.keys().cloned().collect()))
        .collect();
    assert_eq!(
        &got, expected,
        "the chunks decoded are not the source's chunks"
    );
}

fn zarr_source(dir: &Path, layout: ZarrLayout) -> PathBuf {
    let opts = SynthOptions {
        format: SourceFormat::DiffusionPolicyZarr,
        episodes: EPISODES,
        steps: STEPS,
        action_dim: 14,
        state_dim: 14,
        fps: 10.0,
        zarr: layout,
        ..Default::default()
    };
    synth::generate(&opts, dir).unwrap()
}

/// The chunks of a zarr array, from its chunk files: v2 `0.3`, v3 `c/0/3`.
fn zarr_chunks(array: &Path, v3: bool) -> BTreeSet<Vec<u64>> {
    let mut out = BTreeSet::new();
    let mut stack = vec![array.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
                continue;
            }
            let rel = p
                .strip_prefix(array)
                .unwrap()
                .to_string_lossy()
                .into_owned();
            let idx = if v3 {
                match rel.strip_prefix("c/") {
                    Some(r) => r,
                    None => continue, // zarr.json
                }
                .split('/')
                .map(|x| x.parse().unwrap())
                .collect()
            } else if rel.starts_with('.') {
                continue; // .zarray, .zattrs
            } else {
                rel.split('.').map(|x| x.parse().unwrap()).collect()
            };
            out.insert(idx);
        }
    }
    out
}

fn check_zarr(layout: ZarrLayout, chunks_per_array: usize) {
    let dir = tempfile::tempdir().unwrap();
    let spec = zarr_source(&dir.path().join("src"), layout);
    let root = spec.parent().unwrap().join("replay.zarr");
    let root = if root.exists() {
        root
    } else {
        // Wherever the synth spec points.
        let text = std::fs::read_to_string(&spec).unwrap();
        let path = text
            .lines()
            .find_map(|l| l.strip_prefix("path = \""))
            .unwrap()
            .trim_end_matches('"');
        spec.parent().unwrap().join(path)
    };
    let v3 = layout.format == 3;
    let expected: BTreeMap<String, BTreeSet<Vec<u64>>> = ["action", "state"]
        .iter()
        .map(|k| {
            (
                format!("data/{k}"),
                zarr_chunks(&root.join("data").join(k), v3),
            )
        })
        .collect();
    assert_eq!(
        expected["data/action"].len(),
        chunks_per_array,
        "{layout:?}"
    );
    assert_once(&build(&spec), &expected);
}

#[test]
fn zarr_one_chunk_per_episode() {
    for format in [2, 3] {
        let layout = ZarrLayout {
            chunk_rows: Some(STEPS),
            chunk_cols: None,
            format,
        };
        check_zarr(layout, EPISODES);
    }
}

#[test]
fn zarr_chunks_spanning_several_episodes() {
    // 3.5 episodes a chunk: chunks start and end inside episodes.
    for format in [2, 3] {
        let layout = ZarrLayout {
            chunk_rows: Some(STEPS * 7 / 2),
            chunk_cols: None,
            format,
        };
        check_zarr(layout, (EPISODES * STEPS).div_ceil(STEPS * 7 / 2));
    }
}

#[test]
fn zarr_python_default_like_chunking_splits_the_columns() {
    // As zarr-python chunks (N, 14) float32: (125000, 2); here 300 rows and 2 of 14 columns.
    for format in [2, 3] {
        let layout = ZarrLayout {
            chunk_rows: Some(300),
            chunk_cols: Some(2),
            format,
        };
        check_zarr(layout, (EPISODES * STEPS).div_ceil(300) * 7);
    }
}

/// The chunks of every dataset a robomimic build reads, as HDF5 lists them.
fn hdf5_chunks(file: &Path, keys: &[&str]) -> BTreeMap<String, BTreeSet<Vec<u64>>> {
    let f = hdf5::File::open(file).unwrap();
    let data = f.group("data").unwrap();
    let mut out = BTreeMap::new();
    for demo in data.member_names().unwrap() {
        for key in keys {
            let ds = data.dataset(&format!("{demo}/{key}")).unwrap();
            let n = if ds.is_chunked() {
                ds.num_chunks().unwrap() as u64
            } else {
                1
            };
            out.insert(
                format!("data/{demo}/{key}"),
                (0..n).map(|i| vec![i]).collect(),
            );
        }
    }
    out
}

#[test]
fn robomimic_chunked_frames_and_robosuite_states_decode_once() {
    for robosuite in [false, true] {
        let dir = tempfile::tempdir().unwrap();
        let opts = SynthOptions {
            format: SourceFormat::RobomimicHdf5,
            episodes: 6,
            steps: STEPS,
            cameras: if robosuite { 0 } else { 1 },
            height: 8,
            width: 8,
            fps: 20.0,
            robosuite,
            ..Default::default()
        };
        let spec = synth::generate(&opts, &dir.path().join("src")).unwrap();
        let file = spec.parent().unwrap().join("demos.hdf5");
        let keys: &[&str] = if robosuite {
            // `states` is read at open for the timestamps (column 0) and as the state channel.
            &["actions", "states"]
        } else {
            &["actions", "obs/cam0_image", "obs/robot0_joint_pos"]
        };
        let expected = hdf5_chunks(&file, keys);
        if !robosuite {
            let frames = &expected["data/demo_0/obs/cam0_image"];
            assert_eq!(frames.len(), STEPS, "one chunk per frame");
        }
        assert_once(&build(&spec), &expected);
    }
}

/// Rewrites a parquet file with row groups of `rows` rows.
fn regroup(path: &Path, rows: usize) {
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
    use parquet::arrow::ArrowWriter;
    use parquet::file::properties::WriterProperties;
    let reader = ParquetRecordBatchReaderBuilder::try_new(std::fs::File::open(path).unwrap())
        .unwrap()
        .build()
        .unwrap();
    let batches: Vec<_> = reader.map(|b| b.unwrap()).collect();
    let props = WriterProperties::builder()
        .set_max_row_group_row_count(Some(rows))
        .build();
    let tmp = path.with_extension("tmp");
    let mut w = ArrowWriter::try_new(
        std::fs::File::create(&tmp).unwrap(),
        batches[0].schema(),
        Some(props),
    )
    .unwrap();
    for b in &batches {
        w.write(b).unwrap();
    }
    w.close().unwrap();
    std::fs::rename(&tmp, path).unwrap();
}

#[test]
fn lerobot_row_groups_holding_several_episodes_decode_once() {
    let dir = tempfile::tempdir().unwrap();
    let opts = SynthOptions {
        format: SourceFormat::Lerobot,
        episodes: 12,
        steps: STEPS,
        fps: 10.0,
        ..Default::default()
    };
    let spec = synth::generate(&opts, &dir.path().join("src")).unwrap();
    let root = spec.parent().unwrap().join("lerobot");
    let data = root.join("data/chunk-000");
    let mut expected = BTreeMap::new();
    for e in std::fs::read_dir(&data).unwrap() {
        let path = e.unwrap().path();
        // 2.5 episodes a row group: row groups start and end inside episodes.
        regroup(&path, STEPS * 5 / 2);
        let meta = parquet::file::reader::FileReader::metadata(
            &parquet::file::serialized_reader::SerializedFileReader::new(
                std::fs::File::open(&path).unwrap(),
            )
            .unwrap(),
        )
        .clone();
        let groups = meta.num_row_groups() as u64;
        assert!(groups > 1);
        let rel = path.strip_prefix(&root).unwrap().display().to_string();
        // The mapped columns, and `timestamp` (read by the audit, kept for the build).
        for column in ["action", "observation.state", "timestamp"] {
            expected.insert(
                format!("{rel}/{column}"),
                (0..groups).map(|g| vec![g]).collect::<BTreeSet<_>>(),
            );
        }
    }
    assert_once(&build(&spec), &expected);
}
