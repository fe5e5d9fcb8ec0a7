//! Content fingerprints of source files.
//!
//! A fingerprint is BLAKE3 over the sorted list of (relative path, BLAKE3 of contents) of every
//! file an adapter reads. File names are sorted bytewise so the result is independent of the
//! directory listing order and of the thread count.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::error::{IoContext, Result};

/// Every regular file under `root` (recursively), as paths relative to `root`, sorted.
pub fn list_files(root: &Path) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    let mut stack = vec![PathBuf::new()];
    while let Some(rel) = stack.pop() {
        let dir = root.join(&rel);
        for entry in std::fs::read_dir(&dir).at("list", &dir)? {
            let entry = entry.at("list", &dir)?;
            let ty = entry.file_type().at("stat", entry.path())?;
            let child = rel.join(entry.file_name());
            if ty.is_dir() {
                stack.push(child);
            } else {
                out.push(child);
            }
        }
    }
    out.sort();
    Ok(out)
}

/// Fingerprint of the given files (relative to `root`).
pub fn of_files(root: &Path, files: &[PathBuf]) -> Result<String> {
    let hashes = files
        .par_iter()
        .map(|rel| {
            let path = root.join(rel);
            let bytes = std::fs::read(&path).at("read", &path)?;
            Ok(blake3::hash(&bytes))
        })
        .collect::<Result<Vec<_>>>()?;
    let mut all = blake3::Hasher::new();
    for (rel, h) in files.iter().zip(&hashes) {
        let name = rel.to_string_lossy().replace('\\', "/");
        all.update(&(name.len() as u64).to_le_bytes());
        all.update(name.as_bytes());
        all.update(h.as_bytes());
    }
    Ok(all.finalize().to_hex().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn changes_with_content_and_not_with_order() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("a")).unwrap();
        std::fs::write(dir.path().join("a/x"), b"1").unwrap();
        std::fs::write(dir.path().join("y"), b"2").unwrap();
        let files = list_files(dir.path()).unwrap();
        assert_eq!(files, vec![PathBuf::from("a/x"), PathBuf::from("y")]);
        let before = of_files(dir.path(), &files).unwrap();
        std::fs::write(dir.path().join("y"), b"3").unwrap();
        assert_ne!(before, of_files(dir.path(), &files).unwrap());
    }
}
