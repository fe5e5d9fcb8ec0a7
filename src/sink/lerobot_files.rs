//! How the LeRobot exports (v3.0 and v2.1) write their files: parquet with fixed writer
//! properties (created_by, zstd level, no dictionary, chunk statistics, one row group per
//! batch), so the bytes depend only on the contents; pretty JSON and JSON Lines. The parquet
//! files, the export's bulk, are hashed as they are written ([`DatasetFiles::take_written`]).

use std::collections::HashMap;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use arrow_array::RecordBatch;
use arrow_schema::Schema;
use parquet::arrow::ArrowWriter;
use parquet::basic::{Compression as PqCompression, ZstdLevel};
use parquet::file::properties::{EnabledStatistics, WriterProperties};
use serde_json::Value;

use super::lerobot_columns::{err, CREATED_BY};
use crate::error::{IoContext, Result};
use crate::spec::Compression;

const DEFAULT_ZSTD_LEVEL: u32 = 3;

/// Writes a LeRobot dataset's files under one root directory.
#[derive(Clone)]
pub(super) struct DatasetFiles {
    pub dir: PathBuf,
    props: WriterProperties,
    /// The BLAKE3 of each parquet file as last written, by path (shared with [`Self::under`]'s).
    written: Arc<Mutex<HashMap<PathBuf, blake3::Hash>>>,
}

impl DatasetFiles {
    /// Files under `dir`, parquet compressed as the profile says (`compression`, its level).
    pub(super) fn new(dir: &Path, compression: Compression, level: Option<u32>) -> Result<Self> {
        let compression = match compression {
            Compression::None => PqCompression::UNCOMPRESSED,
            _ => PqCompression::ZSTD(
                ZstdLevel::try_new(level.unwrap_or(DEFAULT_ZSTD_LEVEL) as i32).map_err(err)?,
            ),
        };
        let props = WriterProperties::builder()
            .set_created_by(CREATED_BY.into())
            .set_compression(compression)
            .set_dictionary_enabled(false)
            .set_statistics_enabled(EnabledStatistics::Chunk)
            .set_max_row_group_row_count(None)
            .set_max_row_group_bytes(None)
            .build();
        Ok(DatasetFiles {
            dir: dir.to_path_buf(),
            props,
            written: Arc::default(),
        })
    }

    /// The same writer for the dataset in the folder `sub` of this one.
    pub(super) fn under(&self, sub: &str) -> DatasetFiles {
        DatasetFiles {
            dir: self.dir.join(sub),
            props: self.props.clone(),
            written: self.written.clone(),
        }
    }

    /// The BLAKE3 of every parquet file written (here or under a folder of this one), by path,
    /// taken from the bytes as they were written.
    pub(super) fn take_written(&self) -> HashMap<PathBuf, blake3::Hash> {
        std::mem::take(&mut *self.written.lock().unwrap_or_else(|e| e.into_inner()))
    }

    /// `rel` under the root, its directory created.
    fn create(&self, rel: &str) -> Result<PathBuf> {
        let path = self.dir.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).at("create", parent)?;
        }
        Ok(path)
    }

    /// Writes `batches` as they come, one row group each.
    pub(super) fn parquet(
        &self,
        rel: &str,
        schema: Arc<Schema>,
        batches: impl IntoIterator<Item = Result<RecordBatch>>,
    ) -> Result<()> {
        let path = self.create(rel)?;
        let mut out = Hashing {
            file: File::create(&path).at("create", &path)?,
            hasher: blake3::Hasher::new(),
        };
        let mut w =
            ArrowWriter::try_new(&mut out, schema, Some(self.props.clone())).map_err(err)?;
        for b in batches {
            w.write(&b?).map_err(err)?;
            // One row group per batch.
            w.flush().map_err(err)?;
        }
        w.close().map_err(err)?;
        let hash = out.hasher.finalize();
        let mut written = self.written.lock().unwrap_or_else(|e| e.into_inner());
        written.insert(path, hash);
        Ok(())
    }

    /// Pretty JSON with a trailing newline.
    pub(super) fn json(&self, rel: &str, value: &Value) -> Result<()> {
        let path = self.create(rel)?;
        let mut text = serde_json::to_string_pretty(value).expect("JSON serializes");
        text.push('\n');
        std::fs::write(&path, text).at("write", &path)
    }

    /// JSON Lines: one object a line, as LeRobot v2.1's `meta/*.jsonl` are (the `jsonlines`
    /// package: Python's `json.dumps`, with `", "` and `": "` between items).
    pub(super) fn jsonl(&self, rel: &str, rows: impl IntoIterator<Item = Value>) -> Result<()> {
        let path = self.create(rel)?;
        let mut text = Vec::new();
        for row in rows {
            let mut ser = serde_json::Serializer::with_formatter(&mut text, PythonStyle);
            serde::Serialize::serialize(&row, &mut ser).expect("JSON serializes");
            text.push(b'\n');
        }
        std::fs::write(&path, text).at("write", &path)
    }
}

/// A file that hashes what is written to it (the parquet writer writes in order, never seeks).
struct Hashing {
    file: File,
    hasher: blake3::Hasher,
}

impl Write for Hashing {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.file.write(buf)?;
        self.hasher.update(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

/// Python's `json.dumps` layout: one line, `", "` between items and `": "` after keys.
struct PythonStyle;

impl serde_json::ser::Formatter for PythonStyle {
    fn begin_array_value<W: ?Sized + std::io::Write>(
        &mut self,
        w: &mut W,
        first: bool,
    ) -> std::io::Result<()> {
        if first {
            Ok(())
        } else {
            w.write_all(b", ")
        }
    }

    fn begin_object_key<W: ?Sized + std::io::Write>(
        &mut self,
        w: &mut W,
        first: bool,
    ) -> std::io::Result<()> {
        if first {
            Ok(())
        } else {
            w.write_all(b", ")
        }
    }

    fn begin_object_value<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> std::io::Result<()> {
        w.write_all(b": ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_lines_are_laid_out_as_python_writes_them() {
        let dir = tempfile::tempdir().unwrap();
        let files = DatasetFiles::new(dir.path(), Compression::None, None).unwrap();
        let rows = [
            serde_json::json!({"episode_index": 0, "tasks": ["pick", "place"], "length": 3}),
            serde_json::json!({"task_index": 0, "task": "pick"}),
        ];
        files.jsonl("meta/x.jsonl", rows).unwrap();
        let text = std::fs::read_to_string(dir.path().join("meta/x.jsonl")).unwrap();
        assert_eq!(
            text,
            "{\"episode_index\": 0, \"tasks\": [\"pick\", \"place\"], \"length\": 3}\n\
             {\"task_index\": 0, \"task\": \"pick\"}\n"
        );
    }

    /// Parquet files are hashed as written: the hashes are those of the files read back, for
    /// a file written twice (its last bytes), and under a folder (`under`) as at the root.
    #[test]
    fn parquet_hashes_are_the_files_on_disk() {
        use arrow_array::Int64Array;
        use arrow_schema::{DataType, Field};
        let dir = tempfile::tempdir().unwrap();
        let files = DatasetFiles::new(dir.path(), Compression::Zstd, None).unwrap();
        let schema = Arc::new(Schema::new(vec![Field::new("x", DataType::Int64, false)]));
        let batch = |n: i64| {
            let x = Int64Array::from((0..n).collect::<Vec<_>>());
            Ok(RecordBatch::try_new(schema.clone(), vec![Arc::new(x)]).unwrap())
        };
        files
            .parquet("data/a.parquet", schema.clone(), [batch(10), batch(5)])
            .unwrap();
        files
            .parquet("data/a.parquet", schema.clone(), [batch(3000)])
            .unwrap();
        let sub = files.under("part");
        sub.parquet("data/b.parquet", schema.clone(), [batch(7)])
            .unwrap();
        files
            .json("meta/info.json", &serde_json::json!({}))
            .unwrap();
        let written = files.take_written();
        let mut paths: Vec<_> = written.keys().cloned().collect();
        paths.sort();
        assert_eq!(
            paths,
            [
                dir.path().join("data/a.parquet"),
                dir.path().join("part/data/b.parquet")
            ]
        );
        for (path, hash) in &written {
            assert_eq!(
                *hash,
                blake3::hash(&std::fs::read(path).unwrap()),
                "{path:?}"
            );
        }
        assert!(sub.take_written().is_empty());
    }
}
