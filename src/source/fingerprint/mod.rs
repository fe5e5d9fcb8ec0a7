//! Content fingerprints of source files.
//!
//! A fingerprint is BLAKE3 over the sorted list of (relative path, BLAKE3 of contents) of every
//! file an adapter reads. File names are sorted bytewise so the result is independent of the
//! directory listing order and of the thread count.
//!
//! A build need not wait for the fingerprint before it reads: see [`later`].

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::error::{IoContext, Result};

mod later;
pub use later::{Seen, SourcePrint};

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

/// A source's content fingerprint, and the hash of each file it covers.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Fingerprint {
    pub hash: String,
    /// BLAKE3 (hex) of each file, by its path relative to the source root with `/` separators.
    pub files: BTreeMap<String, String>,
}

/// Fingerprint of the given files (relative to `root`).
pub fn of_files(root: &Path, files: &[PathBuf]) -> Result<Fingerprint> {
    let hashes = crate::error::in_order(files.par_iter().map(|rel| hash_file(&root.join(rel))))?;
    Ok(combine(files, &hashes))
}

/// The fingerprint of `files` (sorted) whose contents hash to `hashes`.
pub(super) fn combine(files: &[PathBuf], hashes: &[blake3::Hash]) -> Fingerprint {
    let mut all = blake3::Hasher::new();
    let mut each = BTreeMap::new();
    for (rel, h) in files.iter().zip(hashes) {
        let name = name_of(rel);
        all.update(&(name.len() as u64).to_le_bytes());
        all.update(name.as_bytes());
        all.update(h.as_bytes());
        each.insert(name, h.to_hex().to_string());
    }
    Fingerprint {
        hash: all.finalize().to_hex().to_string(),
        files: each,
    }
}

/// A file's name in a fingerprint: its path relative to the source root, `/` separators.
fn name_of(rel: &Path) -> String {
    rel.to_string_lossy().replace('\\', "/")
}

/// BLAKE3 of a file's contents (sources for their fingerprint, outputs for the lock). Streams
/// the file (no mmap, never whole in memory: one robomimic HDF5 holds every episode), so hashing
/// large files does not show up as resident memory. A large file is read a block at a time
/// while the block before is hashed on every thread (BLAKE3's tree gives the same hash however
/// it is split).
pub fn hash_file(path: &Path) -> Result<blake3::Hash> {
    const BLOCK: usize = 8 << 20;
    let mut file = std::fs::File::open(path).at("open", path)?;
    let size = file.metadata().at("stat", path)?.len();
    if size < 2 * BLOCK as u64 {
        return hash_opened(file, path);
    }
    let mut h = blake3::Hasher::new();
    let (mut this, mut next) = (vec![0u8; BLOCK], vec![0u8; BLOCK]);
    let mut filled = fill(&mut file, &mut this).at("hash", path)?;
    while filled > 0 {
        let (_, read) = rayon::join(
            || h.update_rayon(&this[..filled]),
            || fill(&mut file, &mut next),
        );
        filled = read.at("hash", path)?;
        std::mem::swap(&mut this, &mut next);
    }
    Ok(h.finalize())
}

/// BLAKE3 of an opened file's contents (`path`, for errors), on the calling thread.
pub(super) fn hash_opened(file: std::fs::File, path: &Path) -> Result<blake3::Hash> {
    let mut h = blake3::Hasher::new();
    h.update_reader(file).at("hash", path)?;
    Ok(h.finalize())
}

/// Reads from `file` until `buf` is full or the file ends; how many bytes were read.
fn fill(file: &mut std::fs::File, buf: &mut [u8]) -> std::io::Result<usize> {
    use std::io::Read;
    let mut filled = 0;
    while filled < buf.len() {
        match file.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
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
        // Several blocks (the double-buffered path), and not a multiple of one.
        let bytes: Vec<u8> = (0..(33u32 << 20) + 12345)
            .map(|i| (i * 7 % 251) as u8)
            .collect();
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(hash_file(&path).unwrap(), blake3::hash(&bytes));
        // Small files are hashed in one go.
        std::fs::write(&path, &bytes[..1000]).unwrap();
        assert_eq!(hash_file(&path).unwrap(), blake3::hash(&bytes[..1000]));
        std::fs::write(&path, b"").unwrap();
        assert_eq!(hash_file(&path).unwrap(), blake3::hash(b""));
    }
}
