//! The row store (a leaf): the low-dimensional values of one channel at one rate, for the whole
//! build, in bounded memory.
//!
//! Exact percentiles need every value of a column, and normalized values can only be written once
//! the statistics are known, so exec keeps every low-dim value until the end of the build, and the
//! sinks read them back from here (a leaf, so that neither depends on the other). A
//! [`LowdimStore`] knows how many rows it will hold: when they fit in a byte budget it keeps them
//! in memory (row-major, as read, one allocation); otherwise it spills from the start, appending
//! 8 MiB of rows at a time (a quarter budget if less) to one file in the build's staging
//! directory, row-major as they are, and keeps at most that many rows in memory. Reading is then (a) the
//! training rows a block at a time, every column at once, for the percentiles' second pass
//! ([`LowdimStore::for_rows`]), and (b) a range of rows, for the writers and per-episode exports
//! ([`LowdimStore::rows`], [`LowdimStore::rows_into`]): one read each, nothing to reorder.
//! Small builds never touch the disk.
//!
//! The file lives under the staging directory, which is removed whether the build succeeds or
//! fails. The budget is the caller's: exec decides it (`CHUNKC_SPILL_BYTES`, else
//! [`DEFAULT_BUDGET`]) and hands it to whoever needs it; nothing here reads the environment.

use std::borrow::Cow;
use std::fs::File;
use std::io::Write;
use std::path::PathBuf;

use crate::bytes;
use crate::error::{Error, IoContext, Result};

/// Bytes of values one store keeps in memory rather than spill: a channel of up to about 1.2
/// million rows of 14 values. A spec's lower rates mostly fit (the 25, 10 and 5 Hz stores of
/// 5,000 episodes of 400 steps at 50 Hz do), so a spec with several rates spills only its
/// largest stores; memory stays bounded by the budget times the number of stores.
pub const DEFAULT_BUDGET: usize = 64 << 20;

/// Bytes of rows a spilling store keeps in memory before it appends them to its file (a
/// quarter of the budget when that is smaller).
const SPILL_BLOCK: usize = 8 << 20;

/// Rows [`LowdimStore::for_rows`] hands over at once.
const BLOCK_ROWS: usize = 1 << 14;

/// Row-major `f32` rows of `width` values, appended in order; see the module docs.
#[derive(Debug)]
pub struct LowdimStore {
    width: usize,
    /// Where the spill file goes, created when the store first spills.
    dir: PathBuf,
    /// Rows not on disk (all of them until the store spills), row-major. Its capacity is set
    /// once: every row when they fit in the budget, else one spill block (the store flushes a
    /// block at a time), so pushing never reallocates and copies it.
    mem: Vec<f32>,
    /// Bytes of `mem` that make the store flush.
    flush_at: usize,
    /// The spill file (row-major rows, little-endian) once spilled, and how many rows it holds.
    spilled: Option<(File, usize)>,
}

impl LowdimStore {
    /// A store for `rows` rows (a capacity hint: more may be pushed) of `width` values.
    pub fn new(width: usize, budget: usize, dir: PathBuf, rows: usize) -> Self {
        let bytes = rows.saturating_mul(width).saturating_mul(4);
        // Rows that will spill go a block at a time (at least a row); rows that fit stay, in
        // one allocation of their exact size.
        let flush_at = if bytes <= budget {
            budget
        } else {
            SPILL_BLOCK.min(budget / 4).max(4 * width)
        };
        let capacity = if bytes <= budget {
            rows * width
        } else {
            flush_at / 4 + width
        };
        LowdimStore {
            width,
            dir,
            mem: Vec::with_capacity(capacity),
            flush_at,
            spilled: None,
        }
    }

    pub fn width(&self) -> usize {
        self.width
    }

    /// Number of rows stored.
    pub fn len(&self) -> usize {
        self.disk_rows() + self.mem.len() / self.width.max(1)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether any rows went to disk.
    pub fn is_spilled(&self) -> bool {
        self.spilled.is_some()
    }

    fn disk_rows(&self) -> usize {
        self.spilled.as_ref().map_or(0, |(_, rows)| *rows)
    }

    /// Appends whole rows.
    pub fn push(&mut self, values: &[f32]) -> Result<()> {
        if self.width == 0 {
            return Ok(());
        }
        debug_assert_eq!(values.len() % self.width, 0);
        self.mem.extend_from_slice(values);
        if self.mem.len() * 4 > self.flush_at {
            self.flush()?;
        }
        Ok(())
    }

    /// Appends the rows held in memory to the spill file (created on first use).
    fn flush(&mut self) -> Result<()> {
        if self.spilled.is_none() {
            std::fs::create_dir_all(&self.dir).at("create", &self.dir)?;
            let path = self.path();
            let file = File::options()
                .create_new(true)
                .read(true)
                .write(true)
                .open(&path)
                .at("create", &path)?;
            self.spilled = Some((file, 0));
        }
        let rows = self.mem.len() / self.width;
        let path = self.path();
        let (file, on_disk) = self.spilled.as_mut().expect("created above");
        file.write_all(bytes::f32_bytes(&self.mem))
            .at("write", &path)?;
        *on_disk += rows;
        self.mem.clear();
        Ok(())
    }

    fn path(&self) -> PathBuf {
        self.dir.join("rows.f32")
    }

    /// Rows `lo..hi`, row-major: borrowed when they are in memory, read back otherwise.
    pub fn rows(&self, lo: usize, hi: usize) -> Result<Cow<'_, [f32]>> {
        self.check_range(lo, hi)?;
        let disk = self.disk_rows();
        if lo >= disk {
            let width = self.width;
            return Ok(Cow::Borrowed(
                &self.mem[(lo - disk) * width..(hi - disk) * width],
            ));
        }
        let mut out = vec![0f32; (hi - lo) * self.width];
        self.rows_into(lo, &mut out)?;
        Ok(Cow::Owned(out))
    }

    /// Rows from `lo` into `out` (whole rows, row-major), wherever they are. Disjoint ranges
    /// may be read on several threads at once.
    pub fn rows_into(&self, lo: usize, out: &mut [f32]) -> Result<()> {
        let width = self.width;
        if width == 0 {
            return Ok(());
        }
        let hi = lo + out.len() / width;
        self.check_range(lo, hi)?;
        let disk = self.disk_rows();
        let disk_hi = hi.min(disk);
        if lo < disk_hi {
            let (file, _) = self.spilled.as_ref().expect("rows on disk");
            let part = &mut out[..(disk_hi - lo) * width];
            bytes::read_f32_at(file, part, (lo * width * 4) as u64).at("read", self.path())?;
        }
        if hi > disk {
            let from = lo.max(disk);
            out[(from - lo) * width..]
                .copy_from_slice(&self.mem[(from - disk) * width..(hi - disk) * width]);
        }
        Ok(())
    }

    fn check_range(&self, lo: usize, hi: usize) -> Result<()> {
        if hi > self.len() || lo > hi {
            return Err(Error::Internal(format!(
                "rows {lo}..{hi} of a store of {} rows",
                self.len()
            )));
        }
        Ok(())
    }

    /// Calls `f` with the rows of `ranges` (each `lo..hi`, in order), row-major, gathered into
    /// blocks of up to [`BLOCK_ROWS`] whole rows (ranges are not kept apart: a block may end
    /// inside one and hold several). Memory stays at one block.
    pub fn for_rows(&self, ranges: &[(usize, usize)], f: &mut dyn FnMut(&[f32])) -> Result<()> {
        let width = self.width;
        if width == 0 {
            return Ok(());
        }
        let capacity = BLOCK_ROWS.min(self.len()).max(1);
        let mut block = vec![0f32; capacity * width];
        let mut filled = 0usize;
        for &(lo, hi) in ranges {
            self.check_range(lo, hi)?;
            let mut at = lo;
            while at < hi {
                let take = (hi - at).min(capacity - filled);
                self.rows_into(at, &mut block[filled * width..(filled + take) * width])?;
                (at, filled) = (at + take, filled + take);
                if filled == capacity {
                    f(&block);
                    filled = 0;
                }
            }
        }
        if filled > 0 {
            f(&block[..filled * width]);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

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
}
