//! The store the Zarr writer writes through: each key a plain file under the root, written
//! without the `fsync` that zarrs' `FilesystemStore` issues after every file. A replay buffer of
//! frames is one file per frame (120,000 for 200 episodes of 300 steps and 2 cameras), and the
//! build fsyncs the whole staging directory once before it commits (`exec::staging`), so a
//! second sync per file only made the writer wait on the disk. Write-back errors still surface:
//! that fsync reports them, and the build fails.
//!
//! Each file's BLAKE3 is taken from the bytes as they are written ([`DirStore::take_written`]):
//! the lock records the hash of every output file, and the build need not read these back.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Mutex;

use zarrs::storage::{
    Bytes, OffsetBytesIterator, StorageError, StoreKey, StorePrefix, WritableStorageTraits,
};

pub struct DirStore {
    root: PathBuf,
    /// The BLAKE3 of each file as `set` last wrote it, by path (an erased file's is dropped).
    written: Mutex<HashMap<PathBuf, blake3::Hash>>,
}

impl DirStore {
    pub fn new(root: PathBuf) -> DirStore {
        DirStore {
            root,
            written: Mutex::default(),
        }
    }

    /// The BLAKE3 of every file the store wrote and did not erase, by path, taken from the
    /// bytes written (the store forgets them).
    pub fn take_written(&self) -> HashMap<PathBuf, blake3::Hash> {
        std::mem::take(&mut *self.written())
    }

    fn written(&self) -> std::sync::MutexGuard<'_, HashMap<PathBuf, blake3::Hash>> {
        // A writer that panicked left the map whole (each change is one insert or removal).
        self.written.lock().unwrap_or_else(|e| e.into_inner())
    }
}

fn not_found_is_ok(r: std::io::Result<()>) -> Result<(), StorageError> {
    match r {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e.into()),
        _ => Ok(()),
    }
}

impl WritableStorageTraits for DirStore {
    fn set(&self, key: &StoreKey, value: Bytes) -> Result<(), StorageError> {
        let path = self.root.join(key.as_str());
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)?;
        }
        let hash = blake3::hash(&value);
        std::fs::write(&path, &value)?;
        self.written().insert(path, hash);
        Ok(())
    }

    fn set_partial_many(&self, key: &StoreKey, _: OffsetBytesIterator) -> Result<(), StorageError> {
        Err(StorageError::Other(format!(
            "{}: partial writes are not supported (chunkc writes whole chunks)",
            key.as_str()
        )))
    }

    fn erase(&self, key: &StoreKey) -> Result<(), StorageError> {
        let path = self.root.join(key.as_str());
        self.written().remove(&path);
        not_found_is_ok(std::fs::remove_file(path))
    }

    fn erase_prefix(&self, prefix: &StorePrefix) -> Result<(), StorageError> {
        let dir = self.root.join(prefix.as_str());
        self.written().retain(|path, _| !path.starts_with(&dir));
        not_found_is_ok(std::fs::remove_dir_all(dir))
    }

    fn supports_set_partial(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_become_files_under_the_root() {
        let dir = tempfile::tempdir().unwrap();
        let store = DirStore::new(dir.path().to_path_buf());
        let key = StoreKey::new("data/cam0/c/3/0").unwrap();
        let other = StoreKey::new("meta/ends/c/0").unwrap();
        store.set(&key, Bytes::from_static(b"abc")).unwrap();
        store.set(&other, Bytes::from_static(b"12")).unwrap();
        assert_eq!(
            std::fs::read(dir.path().join("data/cam0/c/3/0")).unwrap(),
            b"abc"
        );
        // Overwriting truncates.
        store.set(&key, Bytes::from_static(b"z")).unwrap();
        assert_eq!(
            std::fs::read(dir.path().join("data/cam0/c/3/0")).unwrap(),
            b"z"
        );
        // The hashes are those of the files as they are on disk, read back.
        let written = store.take_written();
        assert_eq!(written.len(), 2);
        for (path, hash) in &written {
            assert_eq!(
                *hash,
                blake3::hash(&std::fs::read(path).unwrap()),
                "{path:?}"
            );
        }
        assert!(store.take_written().is_empty());
        store.set(&key, Bytes::from_static(b"y")).unwrap();
        store.set(&other, Bytes::from_static(b"3")).unwrap();
        store.erase(&other).unwrap();
        assert_eq!(
            store.take_written().into_keys().collect::<Vec<_>>(),
            [dir.path().join("data/cam0/c/3/0")]
        );
        store.set(&key, Bytes::from_static(b"x")).unwrap();
        store.erase(&key).unwrap();
        assert!(!dir.path().join("data/cam0/c/3/0").exists());
        store.set(&key, Bytes::from_static(b"w")).unwrap();
        store
            .erase_prefix(&StorePrefix::new("data/").unwrap())
            .unwrap();
        assert!(!dir.path().join("data").exists());
        assert!(store.take_written().is_empty());
        assert!(store
            .set_partial_many(&key, Box::new(std::iter::empty()))
            .is_err());
    }
}
