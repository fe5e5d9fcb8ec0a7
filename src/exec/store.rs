//! The low-dimensional values of one channel at one rate, for the whole build, in bounded memory.
//!
//! Exact percentiles need every value of a column, and normalized values can only be written once
//! the statistics are known, so exec keeps every low-dim value until the end of the build. A
//! [`LowdimStore`] knows how many rows it will hold: when they fit in a byte budget it keeps them
//! in memory (row-major, as read, one allocation); otherwise it spills from the start to one file
//! per column in the build's staging directory, a quarter budget of rows at a time, and keeps at
//! most that many rows in memory. As training rows are pushed it counts each column's first
//! percentile pass ([`LowdimStore::high_counts`]), so statistics read a column once. Reading is then
//! (a) one column at a time, for statistics ([`LowdimStore::for_column`]), and (b) a block of rows at
//! a time, for moments, the writers and per-episode exports ([`LowdimStore::rows`]), read back
//! from the column files and interleaved. Small builds never touch the disk.
//!
//! The files live under the staging directory, which is removed whether the build succeeds or
//! fails. `CHUNKC_SPILL_BYTES` overrides the budget (the tests force spilling with it).

use std::borrow::Cow;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::bytes;
use crate::error::{Error, IoContext, Result};
use crate::stats::HighCounts;

/// Bytes of values one store keeps in memory before it spills.
pub const DEFAULT_BUDGET: usize = 32 << 20;

/// The budget: `CHUNKC_SPILL_BYTES` if set, else [`DEFAULT_BUDGET`].
pub fn budget_from_env() -> usize {
    std::env::var("CHUNKC_SPILL_BYTES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(DEFAULT_BUDGET)
}

/// Row-major `f32` rows of `width` values, appended in order; see the module docs.
#[derive(Debug)]
pub struct LowdimStore {
    width: usize,
    /// Where the column files go, created when the store first spills.
    dir: PathBuf,
    /// Rows not on disk (all of them until the store spills), row-major. Its capacity is set
    /// once: every row when they fit in the budget, else a quarter of it (the store flushes a
    /// quarter budget at a time), so pushing never reallocates and copies it.
    mem: Vec<f32>,
    /// Bytes of `mem` that make the store flush.
    flush_at: usize,
    /// One file per column once spilled, and how many rows they hold.
    spilled: Option<(Vec<File>, usize)>,
    /// Column-major scratch of one flush (kept: flushing allocates nothing after the first).
    columns: Vec<f32>,
    /// Per column, the first pass of the exact percentiles over the training rows, counted as
    /// they are pushed (see [`crate::stats::percentiles_counted`]): statistics then read each column
    /// once instead of twice.
    high: Vec<HighCounts>,
}

impl LowdimStore {
    /// A store for `rows` rows (a capacity hint: more may be pushed) of `width` values.
    pub fn new(width: usize, budget: usize, dir: PathBuf, rows: usize) -> Self {
        let bytes = rows.saturating_mul(width).saturating_mul(4);
        // Rows that will spill go a quarter budget at a time (at least a row); rows that fit
        // stay, in one allocation of their exact size.
        let flush_at = if bytes <= budget {
            budget
        } else {
            (budget / 4).max(4 * width)
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
            columns: Vec::new(),
            high: (0..width).map(|_| HighCounts::new()).collect(),
        }
    }

    /// Per column, the first pass of the percentiles over the training rows pushed so far.
    pub fn high_counts(&self) -> &[HighCounts] {
        &self.high
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

    /// Appends whole rows; `train`: they are training rows, counted for the percentiles.
    pub fn push(&mut self, values: &[f32], train: bool) -> Result<()> {
        if self.width == 0 {
            return Ok(());
        }
        debug_assert_eq!(values.len() % self.width, 0);
        if train {
            HighCounts::add_rows(&mut self.high, values);
        }
        self.mem.extend_from_slice(values);
        if self.mem.len() * 4 > self.flush_at {
            self.flush()?;
        }
        Ok(())
    }

    /// Appends the rows held in memory to the column files (created on first use).
    fn flush(&mut self) -> Result<()> {
        let width = self.width;
        if self.spilled.is_none() {
            std::fs::create_dir_all(&self.dir).at("create", &self.dir)?;
            let files = (0..width)
                .map(|d| {
                    let path = self.column_path(d);
                    File::options()
                        .create_new(true)
                        .read(true)
                        .write(true)
                        .open(&path)
                        .at("create", &path)
                })
                .collect::<Result<Vec<_>>>()?;
            self.spilled = Some((files, 0));
        }
        let rows = self.mem.len() / width;
        let (files, on_disk) = self.spilled.as_mut().expect("created above");
        transpose(&self.mem, width, &mut self.columns);
        for (d, (file, column)) in files.iter_mut().zip(self.columns.chunks(rows)).enumerate() {
            let path = self.dir.join(format!("{d}.f32"));
            file.write_all(bytes::f32_bytes(column))
                .at("write", &path)?;
        }
        *on_disk += rows;
        self.mem.clear();
        Ok(())
    }

    fn column_path(&self, d: usize) -> PathBuf {
        self.dir.join(format!("{d}.f32"))
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
            let (files, _) = self.spilled.as_ref().expect("rows on disk");
            // One column at a time, scattered into the rows straight from the buffer.
            let mut column = vec![0f32; disk_hi - lo];
            for (d, file) in files.iter().enumerate() {
                bytes::read_f32_at(file, &mut column, lo as u64 * 4)
                    .at("read", self.column_path(d))?;
                for (row, &v) in out.chunks_exact_mut(width).zip(&column) {
                    row[d] = v;
                }
            }
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

    /// Calls `f` with column `d` of each range of rows in `ranges` (each `lo..hi`, in order), one
    /// call per range. Rows on disk are read a large block at a time, whatever the ranges'
    /// lengths, so memory stays at one block.
    pub fn for_column(
        &self,
        d: usize,
        ranges: &[(usize, usize)],
        f: &mut dyn FnMut(&[f32]),
    ) -> Result<()> {
        const BLOCK_ROWS: usize = 1 << 18;
        let width = self.width;
        let disk = self.disk_rows();
        let (mut buf, mut buf_lo) = (Vec::new(), 0usize);
        let mut part = Vec::new();
        for &(lo, hi) in ranges {
            if hi <= disk {
                if lo < buf_lo || hi > buf_lo + buf.len() {
                    let end = disk.min(lo + BLOCK_ROWS).max(hi);
                    self.read_column(d, lo, end, &mut buf)?;
                    buf_lo = lo;
                }
                f(&buf[lo - buf_lo..hi - buf_lo]);
                continue;
            }
            part.clear();
            if lo < disk {
                self.read_column(d, lo, disk, &mut part)?;
            }
            let from = lo.max(disk) - disk;
            let mem = &self.mem[from * width..(hi - disk) * width];
            part.extend(mem.iter().skip(d).step_by(width));
            f(&part);
        }
        Ok(())
    }

    /// Rows `lo..hi` (all on disk) of column `d` into `out`.
    fn read_column(&self, d: usize, lo: usize, hi: usize, out: &mut Vec<f32>) -> Result<()> {
        let (files, _) = self.spilled.as_ref().expect("rows on disk");
        out.clear();
        out.resize(hi - lo, 0.0);
        bytes::read_f32_at(&files[d], out, lo as u64 * 4).at("read", self.column_path(d))
    }

    /// The directory of the column files, for messages.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

/// Row-major `f32` rows of `width` values → `columns`, column-major (one column after another),
/// reusing its allocation. Blocks of rows are transposed in parallel (each block fits in
/// cache); the result does not depend on the thread count.
fn transpose(values: &[f32], width: usize, columns: &mut Vec<f32>) {
    use rayon::prelude::*;
    const BLOCK_ROWS: usize = 4096;
    let rows = values.len() / width;
    columns.clear();
    columns.resize(rows * width, 0.0);
    let mut blocks: Vec<Vec<&mut [f32]>> = (0..rows.div_ceil(BLOCK_ROWS))
        .map(|_| Vec::with_capacity(width))
        .collect();
    for column in columns.chunks_mut(rows.max(1)) {
        for (b, part) in column.chunks_mut(BLOCK_ROWS).enumerate() {
            blocks[b].push(part);
        }
    }
    blocks
        .into_par_iter()
        .enumerate()
        .for_each(|(b, mut parts)| {
            let block = &values[b * BLOCK_ROWS * width..];
            let n = parts[0].len();
            for (r, row) in block.chunks_exact(width).take(n).enumerate() {
                for (part, &v) in parts.iter_mut().zip(row) {
                    part[r] = v;
                }
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

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
            store.push(&values, true).unwrap();
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
        for d in 0..width {
            let expected: Vec<f32> = ranges
                .iter()
                .flat_map(|&(lo, hi)| (lo..hi).map(move |r| r * width + d))
                .map(|i| all[i])
                .collect();
            for store in [&memory, &spilled] {
                let (mut got, mut calls) = (Vec::new(), Vec::new());
                store
                    .for_column(d, &ranges, &mut |part| {
                        calls.push(part.len());
                        got.extend_from_slice(part);
                    })
                    .unwrap();
                assert_eq!(got, expected);
                let lengths: Vec<usize> = ranges.iter().map(|(lo, hi)| hi - lo).collect();
                assert_eq!(calls, lengths, "one call per range");
            }
        }
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
