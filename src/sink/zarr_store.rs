//! The store the Zarr writer writes through: each key a plain file under the root, written
//! without the `fsync` that zarrs' `FilesystemStore` issues after every file. A replay buffer of
//! frames is one file per frame (120,000 for 200 episodes of 300 steps and 2 cameras), and the
//! build fsyncs the whole staging directory once before it commits (`exec::staging`), so a
//! second sync per file only made the writer wait on the disk. Write-back errors still surface:
//! that fsync reports them, and the build fails.

use std::path::PathBuf;

use zarrs::storage::{
    Bytes, OffsetBytesIterator, StorageError, StoreKey, StorePrefix, WritableStorageTraits,
};

pub struct DirStore {
    root: PathBuf,
}

impl DirStore {
    pub fn new(root: PathBuf) -> DirStore {
        DirStore { root }
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
        std::fs::write(&path, &value)?;
        Ok(())
    }

    fn set_partial_many(&self, key: &StoreKey, _: OffsetBytesIterator) -> Result<(), StorageError> {
        Err(StorageError::Other(format!(
            "{}: partial writes are not supported (chunkc writes whole chunks)",
            key.as_str()
        )))
    }

    fn erase(&self, key: &StoreKey) -> Result<(), StorageError> {
        not_found_is_ok(std::fs::remove_file(self.root.join(key.as_str())))
    }

    fn erase_prefix(&self, prefix: &StorePrefix) -> Result<(), StorageError> {
        not_found_is_ok(std::fs::remove_dir_all(self.root.join(prefix.as_str())))
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
        store.set(&key, Bytes::from_static(b"abc")).unwrap();
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
        store.erase(&key).unwrap();
        store.erase(&key).unwrap();
        assert!(!dir.path().join("data/cam0/c/3/0").exists());
        store
            .erase_prefix(&StorePrefix::new("data/").unwrap())
            .unwrap();
        assert!(!dir.path().join("data").exists());
        assert!(store
            .set_partial_many(&key, Box::new(std::iter::empty()))
            .is_err());
    }
}
