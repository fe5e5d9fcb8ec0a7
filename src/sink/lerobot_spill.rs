//! A camera's PNG frames waiting for the LeRobot export's data file: they arrive episode by
//! episode before the low-dim channels the same row groups need, so they are spilled to a scratch
//! file and read back one episode at a time.

use std::fs::File;
use std::io::{BufWriter, Read, Seek, Write};
use std::path::PathBuf;
use std::sync::Arc;

use arrow_array::builder::{BinaryBuilder, StringBuilder};
use arrow_array::StructArray;

use super::lerobot_columns::{err, image_fields};
use super::Frames;
use crate::error::{Error, IoContext, Result};
use crate::window::Ends;

/// One camera's PNG frames in stored-row order, back to back in a scratch file.
pub(super) struct FrameSpill {
    path: PathBuf,
    file: BufWriter<File>,
    /// Exclusive end of each frame in the file.
    pub ends: Vec<u64>,
}

impl FrameSpill {
    pub(super) fn create(path: PathBuf, frames: usize) -> Result<Self> {
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).at("create", parent)?;
        }
        let file = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)
            .at("create", &path)?;
        Ok(FrameSpill {
            file: BufWriter::with_capacity(1 << 20, file),
            path,
            ends: Vec::with_capacity(frames),
        })
    }

    pub(super) fn push(&mut self, frames: &Frames) -> Result<()> {
        self.file
            .write_all(frames.bytes())
            .at("write", &self.path)?;
        let mut end = self.ends.last().copied().unwrap_or(0);
        for f in frames.iter() {
            end += f.len() as u64;
            self.ends.push(end);
        }
        Ok(())
    }

    /// Reads the frames back in order, `rows` at a time, and deletes the file.
    pub(super) fn into_reader(self) -> Result<SpillReader> {
        let mut file = self
            .file
            .into_inner()
            .map_err(|e| e.into_error())
            .at("write", &self.path)?;
        file.rewind().at("read", &self.path)?;
        Ok(SpillReader {
            file: std::io::BufReader::with_capacity(1 << 20, file),
            path: self.path,
            ends: Ends::new(self.ends),
            row: 0,
        })
    }
}

pub(super) struct SpillReader {
    path: PathBuf,
    file: std::io::BufReader<File>,
    ends: Ends,
    row: usize,
}

impl SpillReader {
    /// The next `n` frames (rows `row..row + n`) as a LeRobot image column.
    pub(super) fn next(&mut self, n: usize, name: &str) -> Result<StructArray> {
        let (lo, hi) = (self.row, self.row + n);
        if hi > self.ends.len() {
            return Err(Error::Internal(format!("missing frames of {name}")));
        }
        let (start, end) = {
            let r = self.ends.rows(lo..hi);
            (r.start as u64, r.end as u64)
        };
        let mut bytes = vec![0u8; (end - start) as usize];
        self.file.read_exact(&mut bytes).at("read", &self.path)?;
        let mut column = BinaryBuilder::with_capacity(n, bytes.len());
        let mut paths = StringBuilder::new();
        let mut at = start;
        for &end in &self.ends[lo..hi] {
            column.append_value(&bytes[(at - start) as usize..(end - start) as usize]);
            paths.append_null();
            at = end;
        }
        self.row = hi;
        StructArray::try_new(
            image_fields(),
            vec![Arc::new(column.finish()), Arc::new(paths.finish())],
            None,
        )
        .map_err(err)
    }
}

impl Drop for SpillReader {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}
