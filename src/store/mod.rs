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
//! A training mixture's rows are padded to one width, but only each source's own dimensions are
//! values: a store keeps a row's first `own` values only ([`LowdimStore::push_own`]), in runs
//! of rows of one own width, and reads give back whole rows, their padding zeros, as if stored.
//! A mixture's padding costs neither memory nor disk.
//!
//! The file lives under the staging directory, which is removed whether the build succeeds or
//! fails. The budget is the caller's: exec decides it (`exec::memory`: `--memory`, `[build]
//! memory`, else a share of the available memory) and hands each store its own; nothing here
//! reads the environment.

use std::borrow::Cow;
use std::fs::File;
use std::io::Write;
use std::ops::Range;
use std::path::PathBuf;

use crate::bytes;
use crate::error::{Error, IoContext, Result};

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
    /// Values not on disk (all of them until the store spills), row-major. Its capacity is set
    /// once: every value when they fit in the budget, else one spill block (the store flushes a
    /// block at a time), so pushing never reallocates and copies it.
    mem: Vec<f32>,
    /// Bytes of `mem` that make the store flush.
    flush_at: usize,
    /// The spill file (row-major values, little-endian) once spilled, and how many values it
    /// holds.
    spilled: Option<(File, usize)>,
    /// Rows stored.
    rows: usize,
    /// Runs of rows stored narrower than `width` (empty while every row is whole).
    runs: Vec<Run>,
}

/// Rows from `row` on (to the next run) keep their first `own` values, from value `value` on.
#[derive(Debug, Clone, Copy)]
struct Run {
    row: usize,
    value: usize,
    own: usize,
}

impl LowdimStore {
    /// A store for `rows` rows (a capacity hint: more may be pushed) of `width` values.
    pub fn new(width: usize, budget: usize, dir: PathBuf, rows: usize) -> Self {
        LowdimStore::with_values(width, budget, dir, rows.saturating_mul(width))
    }

    /// A store of rows of `width` values that will hold about `values` values (rows pushed
    /// narrow keep fewer than `width` each).
    pub fn with_values(width: usize, budget: usize, dir: PathBuf, values: usize) -> Self {
        let bytes = values.saturating_mul(4);
        // Values that will spill go a block at a time (at least a row); values that fit stay,
        // in one allocation of their exact size.
        let flush_at = if bytes <= budget {
            budget
        } else {
            SPILL_BLOCK.min(budget / 4).max(4 * width)
        };
        let capacity = if bytes <= budget {
            values
        } else {
            flush_at / 4 + width
        };
        LowdimStore {
            width,
            dir,
            mem: Vec::with_capacity(capacity),
            flush_at,
            spilled: None,
            rows: 0,
            runs: Vec::new(),
        }
    }

    pub fn width(&self) -> usize {
        self.width
    }

    /// Number of rows stored.
    pub fn len(&self) -> usize {
        self.rows
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether any rows went to disk.
    pub fn is_spilled(&self) -> bool {
        self.spilled.is_some()
    }

    fn disk_values(&self) -> usize {
        self.spilled.as_ref().map_or(0, |(_, values)| *values)
    }

    /// Values stored, on disk and in memory.
    fn values(&self) -> usize {
        self.disk_values() + self.mem.len()
    }

    /// Appends whole rows.
    pub fn push(&mut self, values: &[f32]) -> Result<()> {
        self.push_own(values, values.len() / self.width.max(1))
    }

    /// Appends `rows` rows given by their first `values.len() / rows` values each (a mixture
    /// source's own): the rest of each row is its padding, zeros, read back as zeros.
    pub fn push_own(&mut self, values: &[f32], rows: usize) -> Result<()> {
        let width = self.width;
        if width == 0 || rows == 0 {
            return Ok(());
        }
        let own = values.len() / rows;
        debug_assert_eq!(own * rows, values.len());
        debug_assert!(own <= width);
        if own < width || !self.runs.is_empty() {
            if self.runs.is_empty() && self.rows > 0 {
                self.runs.push(Run {
                    row: 0,
                    value: 0,
                    own: width,
                });
            }
            if self.runs.last().is_none_or(|r| r.own != own) {
                let (row, value) = (self.rows, self.values());
                self.runs.push(Run { row, value, own });
            }
        }
        self.mem.extend_from_slice(values);
        self.rows += rows;
        if self.mem.len() * 4 > self.flush_at {
            self.flush()?;
        }
        Ok(())
    }

    /// Appends the values held in memory to the spill file (created on first use).
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
        let path = self.path();
        let values = self.mem.len();
        let (file, on_disk) = self.spilled.as_mut().expect("created above");
        file.write_all(bytes::f32_bytes(&self.mem))
            .at("write", &path)?;
        *on_disk += values;
        self.mem.clear();
        Ok(())
    }

    fn path(&self) -> PathBuf {
        self.dir.join("rows.f32")
    }

    /// Rows `lo..hi`, row-major: borrowed when they are in memory and whole, read back (or
    /// padded) otherwise.
    pub fn rows(&self, lo: usize, hi: usize) -> Result<Cow<'_, [f32]>> {
        self.check_range(lo, hi)?;
        let (width, disk) = (self.width, self.disk_values());
        if self.runs.is_empty() && lo * width >= disk {
            return Ok(Cow::Borrowed(
                &self.mem[lo * width - disk..hi * width - disk],
            ));
        }
        let mut out = vec![0f32; (hi - lo) * width];
        self.rows_into(lo, &mut out)?;
        Ok(Cow::Owned(out))
    }

    /// Rows `lo..hi`, which keep one own width (a mixture source's episode), at that width:
    /// the values as stored, borrowed when they are in memory.
    pub fn own_rows(&self, lo: usize, hi: usize) -> Result<Cow<'_, [f32]>> {
        self.check_range(lo, hi)?;
        let run = self.run_at(lo);
        if hi > run.end {
            return Err(Error::Internal(format!(
                "rows {lo}..{hi} keep more than one width (a run ends at {})",
                run.end
            )));
        }
        let (from, to) = (run.value, run.value + (hi - lo) * run.own);
        let disk = self.disk_values();
        if from >= disk {
            return Ok(Cow::Borrowed(&self.mem[from - disk..to - disk]));
        }
        let mut out = vec![0f32; to - from];
        self.values_into(from, &mut out)?;
        Ok(Cow::Owned(out))
    }

    /// Rows from `lo` into `out` (whole rows, row-major, narrow ones padded with zeros),
    /// wherever they are. Disjoint ranges may be read on several threads at once.
    pub fn rows_into(&self, lo: usize, out: &mut [f32]) -> Result<()> {
        let width = self.width;
        if width == 0 {
            return Ok(());
        }
        let hi = lo + out.len() / width;
        self.check_range(lo, hi)?;
        if self.runs.is_empty() {
            return self.values_into(lo * width, out);
        }
        let first = self.runs.partition_point(|r| r.row <= lo) - 1;
        for (i, run) in self.runs.iter().enumerate().skip(first) {
            let end = self.runs.get(i + 1).map_or(self.rows, |next| next.row);
            let (a, b) = (lo.max(run.row), hi.min(end));
            if a >= b {
                break;
            }
            let part = &mut out[(a - lo) * width..(b - lo) * width];
            let own = run.own;
            self.values_into(run.value + (a - run.row) * own, &mut part[..(b - a) * own])?;
            if own < width {
                // Each row from its compact place to its own, last first (rows only move up).
                for r in (0..b - a).rev() {
                    part.copy_within(r * own..(r + 1) * own, r * width);
                    part[r * width + own..(r + 1) * width].fill(0.0);
                }
            }
        }
        Ok(())
    }

    /// Values from value `lo` into `out`, from the spill file and from memory.
    fn values_into(&self, lo: usize, out: &mut [f32]) -> Result<()> {
        let hi = lo + out.len();
        let disk = self.disk_values();
        let disk_hi = hi.min(disk);
        if lo < disk_hi {
            let (file, _) = self.spilled.as_ref().expect("values on disk");
            let part = &mut out[..disk_hi - lo];
            bytes::read_f32_at(file, part, (lo * 4) as u64).at("read", self.path())?;
        }
        if hi > disk {
            let from = lo.max(disk);
            out[from - lo..].copy_from_slice(&self.mem[from - disk..hi - disk]);
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
        self.for_columns(ranges, 0..self.width, f)
    }

    /// Calls `f` with columns `dims` of the rows of `ranges`, gathered into blocks as
    /// [`LowdimStore::for_rows`] gathers whole rows: `dims.len()` values a row, zeros past a
    /// narrow row's own values. Only the values stored are read: a narrow row's padding is never
    /// made only to be skipped.
    pub fn for_columns(
        &self,
        ranges: &[(usize, usize)],
        dims: Range<usize>,
        f: &mut dyn FnMut(&[f32]),
    ) -> Result<()> {
        let narrow = dims.len();
        if self.width == 0 || narrow == 0 {
            return Ok(());
        }
        let capacity = BLOCK_ROWS.min(self.len()).max(1);
        let mut block = vec![0f32; capacity * narrow];
        let mut stored = Vec::new();
        let mut filled = 0usize;
        for &(lo, hi) in ranges {
            self.check_range(lo, hi)?;
            let mut at = lo;
            while at < hi {
                let run = self.run_at(at);
                let take = (hi.min(run.end) - at).min(capacity - filled);
                let out = &mut block[filled * narrow..(filled + take) * narrow];
                // The columns of `dims` this run holds; the rest of each row is its padding.
                let held = dims.start.min(run.own)..dims.end.min(run.own);
                if held.is_empty() {
                    out.fill(0.0);
                } else if held == (0..narrow) && run.own == narrow {
                    // The rows are stored as `dims` asks: read straight into the block.
                    self.values_into(run.value, out)?;
                } else {
                    stored.resize(take * run.own, 0.0);
                    self.values_into(run.value, &mut stored)?;
                    let rows = stored
                        .chunks_exact(run.own)
                        .zip(out.chunks_exact_mut(narrow));
                    for (row, dst) in rows {
                        dst[..held.len()].copy_from_slice(&row[held.clone()]);
                        dst[held.len()..].fill(0.0);
                    }
                }
                (at, filled) = (at + take, filled + take);
                if filled == capacity {
                    f(&block);
                    filled = 0;
                }
            }
        }
        if filled > 0 {
            f(&block[..filled * narrow]);
        }
        Ok(())
    }

    /// Where row `row`'s values start, how many it keeps, and the row its run ends at.
    fn run_at(&self, row: usize) -> RunAt {
        if self.runs.is_empty() {
            return RunAt {
                value: row * self.width,
                own: self.width,
                end: self.rows,
            };
        }
        let i = self.runs.partition_point(|r| r.row <= row) - 1;
        let run = self.runs[i];
        RunAt {
            value: run.value + (row - run.row) * run.own,
            own: run.own,
            end: self.runs.get(i + 1).map_or(self.rows, |next| next.row),
        }
    }
}

/// A row's place in the store ([`LowdimStore::run_at`]).
struct RunAt {
    value: usize,
    own: usize,
    end: usize,
}

#[cfg(test)]
mod tests;
