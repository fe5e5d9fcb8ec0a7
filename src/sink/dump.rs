//! Canonical text dumps of HDF5 files, for golden tests and reviews: every group, dataset and
//! attribute in sorted order, with shapes, element types, chunking, filters and a BLAKE3 hash of
//! each dataset's contents (little-endian element bytes). Independent of the file's byte layout,
//! so a library upgrade that moves bytes around does not change the dump, but any change of
//! content does.

use std::fmt::Write;
use std::path::Path;

use hdf5::types::{FloatSize, IntSize, TypeDescriptor, VarLenUnicode};
use hdf5::{Dataset, Group, Location};

use crate::error::{Error, Result};

pub fn hdf5_text(path: &Path) -> Result<String> {
    let file = hdf5::File::open(path)
        .map_err(|e| Error::output(format!("cannot open {}: {e}", path.display())))?;
    let mut out = String::new();
    group(&file, "/", &mut out)?;
    Ok(out)
}

fn type_name(t: &TypeDescriptor) -> String {
    match t {
        TypeDescriptor::Integer(s) => format!("int{}", int_bits(*s)),
        TypeDescriptor::Unsigned(s) => format!("uint{}", int_bits(*s)),
        TypeDescriptor::Float(FloatSize::U4) => "float32".into(),
        TypeDescriptor::Float(FloatSize::U8) => "float64".into(),
        TypeDescriptor::VarLenUnicode => "string".into(),
        TypeDescriptor::Boolean => "bool".into(),
        other => format!("{other:?}"),
    }
}

fn int_bits(s: IntSize) -> usize {
    match s {
        IntSize::U1 => 8,
        IntSize::U2 => 16,
        IntSize::U4 => 32,
        IntSize::U8 => 64,
    }
}

fn attributes(loc: &Location, indent: &str, out: &mut String) -> Result<()> {
    let mut names = loc.attr_names()?;
    names.sort();
    for name in names {
        let attr = loc.attr(&name)?;
        let value = match attr.dtype()?.to_descriptor()? {
            TypeDescriptor::Integer(_) => attr.read_scalar::<i64>()?.to_string(),
            TypeDescriptor::Unsigned(_) => attr.read_scalar::<u64>()?.to_string(),
            TypeDescriptor::Float(_) => format!("{:?}", attr.read_scalar::<f64>()?),
            TypeDescriptor::VarLenUnicode => {
                format!("{:?}", attr.read_scalar::<VarLenUnicode>()?.as_str())
            }
            other => format!("<{other:?}>"),
        };
        let _ = writeln!(out, "{indent}@{name} = {value}");
    }
    Ok(())
}

fn content_hash(ds: &Dataset, t: &TypeDescriptor) -> Result<String> {
    macro_rules! bytes {
        ($ty:ty) => {
            ds.read_raw::<$ty>()?
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect::<Vec<u8>>()
        };
    }
    let bytes = match t {
        TypeDescriptor::Float(FloatSize::U4) => bytes!(f32),
        TypeDescriptor::Float(FloatSize::U8) => bytes!(f64),
        TypeDescriptor::Unsigned(IntSize::U1) => ds.read_raw::<u8>()?,
        TypeDescriptor::Integer(IntSize::U8) => bytes!(i64),
        TypeDescriptor::Integer(IntSize::U4) => bytes!(i32),
        TypeDescriptor::Boolean => ds
            .read_raw::<bool>()?
            .iter()
            .map(|&b| u8::from(b))
            .collect(),
        other => return Ok(format!("<unhashed {other:?}>")),
    };
    Ok(blake3::hash(&bytes).to_hex().to_string())
}

fn group(g: &Group, path: &str, out: &mut String) -> Result<()> {
    let _ = writeln!(out, "group {path}");
    attributes(g, "  ", out)?;
    let mut names = g.member_names()?;
    names.sort();
    for name in names {
        let child = if path == "/" {
            format!("/{name}")
        } else {
            format!("{path}/{name}")
        };
        if let Ok(ds) = g.dataset(&name) {
            let t = ds.dtype()?.to_descriptor()?;
            let chunks = ds
                .chunk()
                .map(|c| format!("{c:?}"))
                .unwrap_or_else(|| "contiguous".into());
            let filters: Vec<String> = ds.filters().iter().map(|f| format!("{f:?}")).collect();
            let _ = writeln!(
                out,
                "dataset {child} {} {:?} chunks {chunks} filters [{}]",
                type_name(&t),
                ds.shape(),
                filters.join(", ")
            );
            attributes(&ds, "  ", out)?;
            let _ = writeln!(out, "  blake3 {}", content_hash(&ds, &t)?);
        } else {
            group(&g.group(&name)?, &child, out)?;
        }
    }
    Ok(())
}

/// A canonical dump of a Zarr directory (v2 or v3): every metadata document verbatim, and per
/// array the number of stored chunk files and a BLAKE3 hash over their keys and bytes (sorted).
pub fn zarr_text(root: &Path) -> Result<String> {
    let mut files = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).map_err(|e| Error::output(e.to_string()))? {
            let path = entry.map_err(|e| Error::output(e.to_string()))?.path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path.strip_prefix(root).expect("under root");
                files.push(rel.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    files.sort();
    let is_meta = |f: &str| {
        let name = f.rsplit('/').next().unwrap_or(f);
        matches!(name, ".zarray" | ".zgroup" | ".zattrs" | "zarr.json")
    };
    let arrays: Vec<String> = files
        .iter()
        .filter(|f| f.ends_with(".zarray") || f.ends_with("zarr.json"))
        .map(|f| {
            f.rsplit_once('/')
                .map_or(String::new(), |(d, _)| d.to_string())
        })
        .collect();
    let mut out = String::new();
    for f in files.iter().filter(|f| is_meta(f)) {
        let text =
            std::fs::read_to_string(root.join(f)).map_err(|e| Error::output(e.to_string()))?;
        let _ = writeln!(out, "--- {f}\n{}", text.trim_end());
    }
    for array in &arrays {
        let prefix = if array.is_empty() {
            String::new()
        } else {
            format!("{array}/")
        };
        let mut hasher = blake3::Hasher::new();
        let mut count = 0;
        for f in files.iter().filter(|f| !is_meta(f)) {
            let Some(key) = f.strip_prefix(&prefix) else {
                continue;
            };
            // A chunk of this array, not of an array nested below it.
            if arrays
                .iter()
                .any(|a| a.len() > array.len() && f.starts_with(&format!("{a}/")))
            {
                continue;
            }
            let bytes = std::fs::read(root.join(f)).map_err(|e| Error::output(e.to_string()))?;
            hasher.update(key.as_bytes());
            hasher.update(&(bytes.len() as u64).to_le_bytes());
            hasher.update(&bytes);
            count += 1;
        }
        if count > 0 {
            let _ = writeln!(
                out,
                "chunks {array}: {count} files blake3 {}",
                hasher.finalize()
            );
        }
    }
    Ok(out)
}
