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
            hash_file(&path)
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

/// BLAKE3 of one file's contents, read in 1 MiB pieces: a multi-gigabyte source file (one
/// robomimic HDF5 holds every episode) never sits in memory whole.
fn hash_file(path: &Path) -> Result<blake3::Hash> {
    use std::io::Read;
    let mut file = std::fs::File::open(path).at("open", path)?;
    let mut hasher = blake3::Hasher::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = match file.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e).at("read", path),
        };
        // Pieces this large hash faster across threads (the result is the same either way).
        hasher.update_rayon(&buf[..n]);
    }
    Ok(hasher.finalize())
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

    #[test]
    fn streamed_hash_equals_the_whole_file_hash() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big");
        // Larger than one read, and not a multiple of it.
        let bytes: Vec<u8> = (0..(3u32 << 20) + 12345)
            .map(|i| (i * 7 % 251) as u8)
            .collect();
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(hash_file(&path).unwrap(), blake3::hash(&bytes));
        std::fs::write(&path, b"").unwrap();
        assert_eq!(hash_file(&path).unwrap(), blake3::hash(b""));
    }
}
