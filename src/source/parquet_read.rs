//! Reading parquet columns (through arrow) as the flat `f32` rows the mapping expects: scalar
//! columns, fixed-size lists and variable-size lists whose every row has the expected width.

use std::fs::File;
use std::ops::Range;
use std::path::Path;

use arrow_array::cast::AsArray;
use arrow_array::types::*;
use arrow_array::{Array, ArrayRef, RecordBatch};
use arrow_schema::DataType;
use parquet::arrow::arrow_reader::{ParquetRecordBatchReaderBuilder, RowSelection, RowSelector};
use parquet::arrow::ProjectionMask;

use crate::error::{Error, Result};

fn builder(path: &Path) -> Result<ParquetRecordBatchReaderBuilder<File>> {
    let file = File::open(path)
        .map_err(|e| Error::source(format!("{}: cannot open: {e}", path.display())))?;
    ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| {
        Error::source(format!(
            "{}: cannot read as parquet (corrupt or not a parquet file): {e}",
            path.display()
        ))
    })
}

/// Number of rows in a parquet file, from its footer.
pub fn num_rows(path: &Path) -> Result<usize> {
    Ok(builder(path)?.metadata().file_metadata().num_rows() as usize)
}

/// The named columns of rows `rows` (all rows when `None`): per name, in order, the column's
/// arrays (one per record batch). A name the file lacks is an error listing the columns it has.
pub fn read_columns(
    path: &Path,
    names: &[&str],
    rows: Option<Range<usize>>,
) -> Result<Vec<Vec<ArrayRef>>> {
    let b = builder(path)?;
    let schema = b.schema().clone();
    let mut indices = Vec::with_capacity(names.len());
    for name in names {
        let Ok(i) = schema.index_of(name) else {
            let have: Vec<&str> = schema.fields().iter().map(|f| f.name().as_str()).collect();
            return Err(Error::source(format!(
                "{}: no column `{name}`; the file has: {}",
                path.display(),
                have.join(", ")
            )));
        };
        indices.push(i);
    }
    let mut sorted = indices.clone();
    sorted.sort_unstable();
    sorted.dedup();
    let mask = ProjectionMask::roots(b.parquet_schema(), sorted.iter().copied());
    let mut b = b.with_projection(mask).with_batch_size(64 * 1024);
    if let Some(r) = rows {
        b = b.with_row_selection(RowSelection::from(vec![
            RowSelector::skip(r.start),
            RowSelector::select(r.len()),
        ]));
    }
    let reader = b
        .build()
        .map_err(|e| Error::source(format!("{}: {e}", path.display())))?;
    let batches: Vec<RecordBatch> = reader
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| Error::source(format!("{}: cannot read: {e}", path.display())))?;
    Ok(names
        .iter()
        .map(|name| {
            batches
                .iter()
                .map(|b| b.column_by_name(name).expect("projected").clone())
                .collect()
        })
        .collect())
}

/// Whether the parquet file has a column `name` (from its footer).
pub fn has_column(path: &Path, name: &str) -> Result<bool> {
    Ok(builder(path)?.schema().index_of(name).is_ok())
}

/// Per row of a column (its batches, in order), the first string of each list of strings
/// (LeRobot's `tasks` in `meta/episodes`), or the string itself in a string column; `None` for
/// a row whose list is empty or null. `what` names the column in messages.
pub fn first_strings(batches: &[ArrayRef], what: &str) -> Result<Vec<Option<String>>> {
    let first = |a: &dyn Array| -> Result<Option<String>> {
        let at = (0..a.len()).find(|&i| a.is_valid(i));
        Ok(match (a.data_type(), at) {
            (_, None) => None,
            (DataType::Utf8, Some(i)) => Some(a.as_string::<i32>().value(i).to_string()),
            (DataType::LargeUtf8, Some(i)) => Some(a.as_string::<i64>().value(i).to_string()),
            (DataType::Utf8View, Some(i)) => Some(a.as_string_view().value(i).to_string()),
            (t, _) => {
                return Err(Error::source(format!(
                    "{what} is {t}, not a list of strings"
                )))
            }
        })
    };
    let mut out = Vec::new();
    for a in batches {
        for i in 0..a.len() {
            out.push(match a.data_type() {
                _ if a.is_null(i) => None,
                DataType::List(_) => first(a.as_list::<i32>().value(i).as_ref())?,
                DataType::LargeList(_) => first(a.as_list::<i64>().value(i).as_ref())?,
                _ => first(a.slice(i, 1).as_ref())?,
            });
        }
    }
    Ok(out)
}

/// A scalar numeric array's values as `f64` (`None` for an unsupported type).
fn scalars(a: &dyn Array) -> Option<Vec<f64>> {
    macro_rules! prim {
        ($t:ty) => {
            a.as_primitive::<$t>()
                .values()
                .iter()
                .map(|&v| v as f64)
                .collect()
        };
    }
    Some(match a.data_type() {
        DataType::Float32 => prim!(Float32Type),
        DataType::Float64 => prim!(Float64Type),
        DataType::Int8 => prim!(Int8Type),
        DataType::Int16 => prim!(Int16Type),
        DataType::Int32 => prim!(Int32Type),
        DataType::Int64 => prim!(Int64Type),
        DataType::UInt8 => prim!(UInt8Type),
        DataType::UInt16 => prim!(UInt16Type),
        DataType::UInt32 => prim!(UInt32Type),
        DataType::UInt64 => prim!(UInt64Type),
        DataType::Boolean => a
            .as_boolean()
            .iter()
            .map(|v| f64::from(u8::from(v.unwrap_or(false))))
            .collect(),
        _ => return None,
    })
}

/// A column (its batches, in order) as `rows × width` values, row-major. `what` names the column
/// in messages; a row's position is reported as a step.
pub fn to_f64_rows(batches: &[ArrayRef], width: usize, what: &str) -> Result<Vec<f64>> {
    let mut out = Vec::new();
    let mut first_step = 0;
    for a in batches {
        rows_of(a.as_ref(), width, what, first_step, &mut out)?;
        first_step += a.len();
    }
    Ok(out)
}

fn rows_of(
    a: &dyn Array,
    width: usize,
    what: &str,
    first: usize,
    out: &mut Vec<f64>,
) -> Result<()> {
    if a.null_count() > 0 {
        let t = (0..a.len()).find(|&i| a.is_null(i)).unwrap_or(0);
        return Err(Error::source(format!("{what}: step {} is null", first + t)));
    }
    let unsupported = || {
        Error::source(format!(
            "{what}: column type {} is not a number or a list of numbers",
            a.data_type()
        ))
    };
    let row = |i: usize, v: ArrayRef| -> Result<Vec<f64>> {
        if v.len() != width {
            return Err(Error::source(format!(
                "{what}: step {} has {} values, expected {width}",
                first + i,
                v.len()
            )));
        }
        if v.null_count() > 0 {
            return Err(Error::source(format!(
                "{what}: step {} holds a null",
                first + i
            )));
        }
        scalars(v.as_ref()).ok_or_else(unsupported)
    };
    match a.data_type() {
        DataType::FixedSizeList(_, _) => {
            let list = a.as_fixed_size_list();
            for i in 0..list.len() {
                out.extend(row(i, list.value(i))?);
            }
        }
        DataType::List(_) => {
            let list = a.as_list::<i32>();
            for i in 0..list.len() {
                out.extend(row(i, list.value(i))?);
            }
        }
        DataType::LargeList(_) => {
            let list = a.as_list::<i64>();
            for i in 0..list.len() {
                out.extend(row(i, list.value(i))?);
            }
        }
        _ => {
            if width != 1 {
                return Err(Error::source(format!(
                    "{what}: a scalar column, but the feature has {width} values per step"
                )));
            }
            out.extend(scalars(a).ok_or_else(unsupported)?);
        }
    }
    Ok(())
}

/// A parquet file's footer, parsed once, and where its row groups start.
#[derive(Clone)]
pub struct Footer {
    meta: parquet::arrow::arrow_reader::ArrowReaderMetadata,
    /// The first row of each row group.
    pub starts: Vec<u64>,
    /// Rows in the file.
    pub rows: u64,
}

/// Reads the footer of `path`.
pub fn footer(path: &Path) -> Result<Footer> {
    let file = File::open(path)
        .map_err(|e| Error::source(format!("{}: cannot open: {e}", path.display())))?;
    let meta = parquet::arrow::arrow_reader::ArrowReaderMetadata::load(&file, Default::default())
        .map_err(|e| {
        Error::source(format!(
            "{}: cannot read as parquet (corrupt or not a parquet file): {e}",
            path.display()
        ))
    })?;
    let mut starts = Vec::new();
    let mut rows = 0u64;
    for rg in meta.metadata().row_groups() {
        starts.push(rows);
        rows += rg.num_rows() as u64;
    }
    Ok(Footer { meta, starts, rows })
}

/// Column `name` of row group `rg` of `path` (whose footer is `footer`), decoded, as
/// `rows × width` values (see [`to_f64_rows`]; `what` names the column in messages).
pub fn row_group_column(
    path: &Path,
    footer: &Footer,
    rg: usize,
    name: &str,
    width: usize,
    what: &str,
) -> Result<Vec<f64>> {
    let file = File::open(path)
        .map_err(|e| Error::source(format!("{}: cannot open: {e}", path.display())))?;
    let b = ParquetRecordBatchReaderBuilder::new_with_metadata(file, footer.meta.clone());
    let Ok(i) = b.schema().index_of(name) else {
        let have: Vec<&str> = b
            .schema()
            .fields()
            .iter()
            .map(|f| f.name().as_str())
            .collect();
        return Err(Error::source(format!(
            "{}: no column `{name}`; the file has: {}",
            path.display(),
            have.join(", ")
        )));
    };
    let mask = ProjectionMask::roots(b.parquet_schema(), [i]);
    let reader = b
        .with_projection(mask)
        .with_row_groups(vec![rg])
        .with_batch_size(64 * 1024)
        .build()
        .map_err(|e| Error::source(format!("{}: {e}", path.display())))?;
    let batches: Vec<ArrayRef> = reader
        .map(|b| b.map(|b| b.column(0).clone()))
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| Error::source(format!("{}: cannot read: {e}", path.display())))?;
    to_f64_rows(&batches, width, what)
}
