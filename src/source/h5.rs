//! HDF5 reading shared by the `aloha` and `robomimic` adapters: opening with a clear error,
//! listing the datasets under a group, and reading one as `f32` or `u8`.

use std::path::Path;

use hdf5::types::TypeDescriptor;
use hdf5::{Dataset, File, Group};

use super::mapping::Raw;
use crate::error::{Error, Result};

/// Opens `path`, turning HDF5's error into one that names the file.
pub fn open(path: &Path) -> Result<File> {
    File::open(path).map_err(|e| {
        Error::source(format!(
            "{}: cannot open as HDF5 (corrupt, truncated, or not an HDF5 file): {e}",
            path.display()
        ))
    })
}

/// The group at `name` under `parent`, or an error naming the file and the group.
pub fn group(parent: &Group, name: &str, file: &Path) -> Result<Group> {
    parent.group(name).map_err(|e| {
        Error::source(format!(
            "{}: no group `{name}` under `{}`: {e}",
            file.display(),
            parent.name()
        ))
    })
}

/// The dataset at `name` under `parent`, or an error naming the file and the key.
pub fn dataset(parent: &Group, name: &str, file: &Path) -> Result<Dataset> {
    parent.dataset(name).map_err(|e| {
        Error::source(format!(
            "{}: cannot open dataset `{}/{name}`: {e}",
            file.display(),
            parent.name().trim_end_matches('/')
        ))
    })
}

/// Every dataset under `group`, recursively, as (path relative to `group`, dataset), sorted.
pub fn datasets(group: &Group, file: &Path) -> Result<Vec<(String, Dataset)>> {
    let mut out = Vec::new();
    let mut stack = vec![(String::new(), group.clone())];
    while let Some((prefix, g)) = stack.pop() {
        let names = g.member_names().map_err(|e| {
            Error::source(format!(
                "{}: cannot list `{}`: {e}",
                file.display(),
                g.name()
            ))
        })?;
        for name in names {
            let rel = if prefix.is_empty() {
                name.clone()
            } else {
                format!("{prefix}/{name}")
            };
            if let Ok(ds) = g.dataset(&name) {
                out.push((rel, ds));
            } else if let Ok(child) = g.group(&name) {
                stack.push((rel, child));
            }
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

/// The element type's name (`float32`, `uint8`, …).
pub fn dtype_name(ds: &Dataset) -> String {
    ds.dtype()
        .and_then(|t| t.to_descriptor())
        .map(|d| d.to_string())
        .unwrap_or_else(|_| "unknown".into())
}

/// Whether values of this element type can be read as numbers.
pub fn is_numeric(ds: &Dataset) -> bool {
    matches!(
        ds.dtype().and_then(|t| t.to_descriptor()),
        Ok(TypeDescriptor::Integer(_) | TypeDescriptor::Unsigned(_) | TypeDescriptor::Float(_))
    )
}

/// A dataset's per-step shape (after the time axis); a 1-D array has `[1]`.
pub fn step_shape(ds: &Dataset) -> Vec<usize> {
    let shape = ds.shape();
    if shape.len() <= 1 {
        vec![1]
    } else {
        shape[1..].to_vec()
    }
}

/// Number of steps (the first axis).
pub fn steps(ds: &Dataset) -> usize {
    ds.shape().first().copied().unwrap_or(0)
}

/// Reads a whole dataset: `uint8` as bytes, any other numeric type converted to `f32`.
pub fn read(ds: &Dataset, what: impl Fn() -> String) -> Result<Raw> {
    let fail = |e: hdf5::Error| Error::source(format!("{}: cannot read: {e}", what()));
    if !is_numeric(ds) {
        return Err(Error::source(format!(
            "{}: element type {} is not numeric",
            what(),
            dtype_name(ds)
        )));
    }
    if dtype_name(ds) == "uint8" {
        ds.read_raw::<u8>().map(Raw::U8).map_err(fail)
    } else {
        ds.read_raw::<f32>().map(Raw::F32).map_err(fail)
    }
}

/// Reads a 1-D array of strings (fixed- or variable-length), as robomimic's masks are stored.
pub fn read_strings(ds: &Dataset) -> std::result::Result<Vec<String>, String> {
    use hdf5::types::{FixedAscii, VarLenAscii, VarLenUnicode};
    match ds.dtype().and_then(|t| t.to_descriptor()) {
        Ok(TypeDescriptor::FixedAscii(_) | TypeDescriptor::FixedUnicode(_)) => ds
            .read_raw::<FixedAscii<256>>()
            .map(|v| v.iter().map(|s| s.as_str().to_string()).collect())
            .map_err(|e| e.to_string()),
        Ok(TypeDescriptor::VarLenAscii) => ds
            .read_raw::<VarLenAscii>()
            .map(|v| v.iter().map(|s| s.as_str().to_string()).collect())
            .map_err(|e| e.to_string()),
        Ok(TypeDescriptor::VarLenUnicode) => ds
            .read_raw::<VarLenUnicode>()
            .map(|v| v.iter().map(|s| s.as_str().to_string()).collect())
            .map_err(|e| e.to_string()),
        Ok(other) => Err(format!("expected strings, found {other}")),
        Err(e) => Err(e.to_string()),
    }
}
