//! The row store's tests: spilled and in-memory stores, narrow (padded) rows.
use super::*;
use std::path::Path;

impl LowdimStore {
    fn disk_rows(&self) -> usize {
        self.disk_values() / self.width
    }
}

fn filled(budget: usize, dir: &Path, width: usize, batches: &[usize]) -> LowdimStore {
    let rows: usize = batches.iter().sum();
    let mut store = LowdimStore::new(width, budget, dir.to_path_buf(), rows);
    let mut next = 0f32;
    for &rows in batches {
        let values: Vec<f32> = (0..rows * width)
            .map(|_| {
                next += 1.0;
                next * 0.37 - 5.0
            })
            .collect();
        store.push(&values).unwrap();
    }
    store
}

#[test]
fn spilled_and_in_memory_stores_read_the_same_rows_and_columns() {
    let tmp = tempfile::tempdir().unwrap();
    let batches = [3, 17, 1, 40, 9, 0, 25, 2];
    let width = 3;
    let memory = filled(usize::MAX, &tmp.path().join("m"), width, &batches);
    // 256 bytes (it flushes 64 at a time): a few rows, so most pushes flush and some rows
    // stay in memory at the end.
    let spilled = filled(256, &tmp.path().join("s"), width, &batches);
    assert!(!memory.is_spilled());
    assert!(
        !tmp.path().join("m").exists(),
        "no file for an in-memory store"
    );
    assert!(spilled.is_spilled());
    let n: usize = batches.iter().sum();
    assert_eq!(memory.len(), n);
    assert_eq!(spilled.len(), n);
    let all = memory.rows(0, n).unwrap().into_owned();
    // Row-major as pushed: row r, column d holds the (r * width + d + 1)-th value.
    for (i, &v) in all.iter().enumerate() {
        assert_eq!(v, (i + 1) as f32 * 0.37 - 5.0);
    }
    for (lo, hi) in [(0, n), (0, 1), (5, 30), (n - 2, n), (40, 40), (13, 71)] {
        assert_eq!(
            spilled.rows(lo, hi).unwrap().as_ref(),
            &all[lo * width..hi * width]
        );
    }
    let ranges = [(0, 2), (2, 10), (30, 31), (50, n)];
    let expected: Vec<f32> = ranges
        .iter()
        .flat_map(|&(lo, hi)| all[lo * width..hi * width].iter().copied())
        .collect();
    for store in [&memory, &spilled] {
        let (mut got, mut calls) = (Vec::new(), 0);
        store
            .for_rows(&ranges, &mut |rows| {
                assert_eq!(rows.len() % width, 0, "whole rows");
                calls += 1;
                got.extend_from_slice(rows);
            })
            .unwrap();
        assert_eq!(got, expected);
        assert_eq!(calls, 1, "ranges gathered into one block");
    }
    // Many blocks, ending inside ranges, over rows both on disk and in memory.
    let big: usize = 3 * BLOCK_ROWS + 123;
    let mut store = LowdimStore::new(2, 80_000, tmp.path().join("b"), big);
    let values: Vec<f32> = (0..2 * big).map(|i| i as f32).collect();
    for part in values.chunks(2 * 1000) {
        store.push(part).unwrap();
    }
    assert!(store.is_spilled() && store.disk_rows() < big);
    let ranges = [(5, BLOCK_ROWS + 7), (BLOCK_ROWS + 9, big - 1)];
    let expected: Vec<f32> = ranges
        .iter()
        .flat_map(|&(lo, hi)| values[2 * lo..2 * hi].iter().copied())
        .collect();
    let mut got = Vec::new();
    store
        .for_rows(&ranges, &mut |rows| got.extend_from_slice(rows))
        .unwrap();
    assert_eq!(got, expected);
    assert!(store.for_rows(&[(0, big + 1)], &mut |_| {}).is_err());
    assert!(spilled.rows(0, n + 1).is_err());
    // Every range, including those straddling the rows on disk and those in memory, read
    // into a caller's buffer.
    let disk = spilled.disk_rows();
    assert!(0 < disk && disk < n, "rows both on disk and in memory");
    for (lo, hi) in [(0, n), (disk - 1, disk + 1), (disk, n), (3, disk), (7, 7)] {
        let mut out = vec![f32::NAN; (hi - lo) * width];
        spilled.rows_into(lo, &mut out).unwrap();
        assert_eq!(out, &all[lo * width..hi * width], "rows {lo}..{hi}");
    }
    assert!(spilled.rows_into(n - 1, &mut [0.0; 6]).is_err());
}

#[test]
fn columns_of_whole_rows_whether_spilled_or_not() {
    let tmp = tempfile::tempdir().unwrap();
    let (width, batches) = (3, [3, 17, 1, 40, 9, 0, 25, 2]);
    let memory = filled(usize::MAX, &tmp.path().join("m"), width, &batches);
    let spilled = filled(256, &tmp.path().join("s"), width, &batches);
    assert!(spilled.is_spilled());
    let n: usize = batches.iter().sum();
    let all = memory.rows(0, n).unwrap().into_owned();
    let ranges = [(0, 2), (2, 10), (30, 31), (50, n)];
    let want: Vec<f32> = (ranges.iter())
        .flat_map(|&(lo, hi)| all[lo * width..hi * width].chunks_exact(width))
        .flat_map(|row| row[1..3].iter().copied())
        .collect();
    for store in [&memory, &spilled] {
        let mut columns = Vec::new();
        store
            .for_columns(&ranges, 1..3, &mut |b| columns.extend_from_slice(b))
            .unwrap();
        assert_eq!(columns, want);
    }
}

#[test]
fn narrow_rows_read_back_padded_whether_spilled_or_not() {
    // A mixture's episodes, in source order and interleaved: whole rows, then rows keeping
    // 2 and 1 of 4 values, none (a source without the channel), then whole again.
    let tmp = tempfile::tempdir().unwrap();
    let width = 4;
    let episodes: [(usize, usize); 8] = [
        (5, 4),
        (3, 2),
        (4, 2),
        (6, 1),
        (3, 0),
        (2, 4),
        (7, 2),
        (1, 4),
    ];
    let mut next = 0f32;
    let mut padded = Vec::new();
    let pushed: Vec<(Vec<f32>, usize)> = episodes
        .iter()
        .map(|&(rows, own)| {
            let values: Vec<f32> = (0..rows * width)
                .map(|i| {
                    next += 1.0;
                    if i % width < own {
                        next
                    } else {
                        0.0
                    }
                })
                .collect();
            padded.extend_from_slice(&values);
            (values, own)
        })
        .collect();
    let n: usize = episodes.iter().map(|e| e.0).sum();
    let kept: usize = episodes.iter().map(|&(r, own)| r * own).sum();
    for (name, budget) in [("m", usize::MAX), ("s", 40)] {
        let dir = tmp.path().join(name);
        let mut store = LowdimStore::with_values(width, budget, dir, kept);
        for (values, own) in &pushed {
            let rows = values.len() / width;
            let kept: Vec<f32> = (values.chunks_exact(width))
                .flat_map(|row| row[..*own].iter().copied())
                .collect();
            store.push_own(&kept, rows).unwrap();
        }
        assert_eq!(store.len(), n);
        assert_eq!(store.values(), kept, "padding is not stored");
        assert_eq!(store.is_spilled(), budget < usize::MAX);
        assert_eq!(store.rows(0, n).unwrap().as_ref(), &padded[..]);
        for lo in 0..n {
            for hi in lo..=n {
                let mut out = vec![f32::NAN; (hi - lo) * width];
                store.rows_into(lo, &mut out).unwrap();
                assert_eq!(out, &padded[lo * width..hi * width], "{name}: {lo}..{hi}");
            }
        }
        let ranges = [(1, 4), (6, 13), (20, n)];
        let mut got = Vec::new();
        store
            .for_rows(&ranges, &mut |b| got.extend_from_slice(b))
            .unwrap();
        let want: Vec<f32> = ranges
            .iter()
            .flat_map(|&(lo, hi)| padded[lo * width..hi * width].iter().copied())
            .collect();
        assert_eq!(got, want);
        own_rows_and_columns(&store, &pushed, width, &want, &ranges, name);
    }
}

/// A mixture's store (`pushed`: each episode's padded rows and own width) read back at each
/// episode's own width, and by columns of the padded `want` rows of `ranges`.
fn own_rows_and_columns(
    store: &LowdimStore,
    pushed: &[(Vec<f32>, usize)],
    width: usize,
    want: &[f32],
    ranges: &[(usize, usize)],
    name: &str,
) {
    // Each episode's rows at its own width, as pushed.
    let mut at = 0;
    for (values, own) in pushed {
        let rows = values.len() / width;
        let kept: Vec<f32> = (values.chunks_exact(width))
            .flat_map(|row| row[..*own].iter().copied())
            .collect();
        assert_eq!(store.own_rows(at, at + rows).unwrap().as_ref(), &kept[..]);
        at += rows;
    }
    assert!(store.own_rows(4, 6).is_err(), "rows of two widths");
    // Columns of the padded rows, from inside one source's own values to past every one.
    for dims in [0..width, 0..1, 1..3, 2..width, width - 1..width] {
        let mut got = Vec::new();
        store
            .for_columns(ranges, dims.clone(), &mut |b| got.extend_from_slice(b))
            .unwrap();
        let want: Vec<f32> = want
            .chunks_exact(width)
            .flat_map(|row| row[dims.clone()].iter().copied())
            .collect();
        assert_eq!(got, want, "{name}: columns {dims:?}");
    }
}
