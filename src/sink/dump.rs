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
