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

/// A JSON document as the golden files keep it: every array of numbers on one line (a
/// statistics vector, one row of `example_qpos`), everything else as written. Only a document
/// exactly as chunkc pretty-prints it is folded, so the folded text still determines the file's
/// bytes; any other text is returned as it is.
pub fn json_text(text: &str) -> String {
    let canonical = serde_json::from_str::<serde_json::Value>(text)
        .ok()
        .and_then(|v| serde_json::to_string_pretty(&v).ok())
        .is_some_and(|pretty| text.strip_suffix('\n') == Some(pretty.as_str()));
    if !canonical {
        return text.to_string();
    }
    let lines: Vec<&str> = text.lines().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < lines.len() {
        match fold_array(&lines[i..]) {
            Some((line, used)) => {
                out.push_str(&line);
                i += used;
            }
            None => {
                out.push_str(lines[i]);
                i += 1;
            }
        }
        out.push('\n');
    }
    out
}

/// `lines[0]` opening an array whose elements are all scalars, one per line, folded onto one
/// line, with the number of lines it took.
fn fold_array(lines: &[&str]) -> Option<(String, usize)> {
    let open = lines[0].strip_suffix('[')?;
    let indent = open.len() - open.trim_start().len();
    let inner = " ".repeat(indent + 2);
    let close = format!("{}]", " ".repeat(indent));
    let scalar = |s: &str| {
        matches!(s, "null" | "true" | "false")
            || (!s.is_empty() && s.bytes().all(|b| b"0123456789+-.eE".contains(&b)))
    };
    let mut items = Vec::new();
    for (n, line) in lines.iter().enumerate().skip(1) {
        if let Some(rest) = line.strip_prefix(close.as_str()) {
            let ended = items.len() == n - 1 && (rest.is_empty() || rest == ",");
            return (ended && !items.is_empty())
                .then(|| (format!("{open}[{}]{rest}", items.join(", ")), n + 1));
        }
        let item = line.strip_prefix(inner.as_str())?;
        let (value, comma) = match item.strip_suffix(',') {
            Some(v) => (v, true),
            None => (item, false),
        };
        // Every element but the last ends with a comma.
        let last = lines
            .get(n + 1)
            .is_some_and(|l| l.starts_with(close.as_str()));
        if !scalar(value) || comma == last {
            return None;
        }
        items.push(value);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::json_text;

    #[test]
    fn arrays_of_numbers_fold_onto_one_line() {
        let doc = serde_json::json!({"a": [1.0, -2.5e-7, 3], "b": [[1, 2], [3, 4]], "c": {"d": []},
            "e": ["x", "y"], "f": [null, true]});
        let text = serde_json::to_string_pretty(&doc).unwrap() + "\n";
        let folded = json_text(&text);
        assert_eq!(
            folded,
            "{\n  \"a\": [1.0, -2.5e-7, 3],\n  \"b\": [\n    [1, 2],\n    [3, 4]\n  ],\n  \
             \"c\": {\n    \"d\": []\n  },\n  \"e\": [\n    \"x\",\n    \"y\"\n  ],\n  \
             \"f\": [null, true]\n}\n"
        );
        // Still the same document.
        let back: serde_json::Value = serde_json::from_str(&folded).unwrap();
        assert_eq!(back, doc);
    }

    #[test]
    fn text_not_pretty_printed_by_chunkc_stays_as_it_is() {
        for text in [
            "{\"a\": [1, 2]}\n",
            "{\n  \"a\": [\n    1,\n    2\n  ]\n}",
            "not json",
        ] {
            assert_eq!(json_text(text), text);
        }
    }
}
