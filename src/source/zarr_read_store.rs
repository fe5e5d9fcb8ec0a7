//! The store a zarr source is read through: zarrs' filesystem store, with the hash of every
//! whole file it reads recorded for the source's fingerprint ([`fingerprint::Seen`]), so that a
//! build reads each chunk file once, not once to fingerprint it and again to decode it.

use zarrs::filesystem::FilesystemStore;
use zarrs::storage::{
    byte_range::ByteRangeIterator, MaybeBytes, MaybeBytesIterator, ReadableStorageTraits,
    StorageError, StoreKey,
};

use super::fingerprint::Seen;

pub struct ReadStore {
    inner: FilesystemStore,
    seen: Seen,
}

impl ReadStore {
    pub fn new(inner: FilesystemStore, seen: Seen) -> ReadStore {
        ReadStore { inner, seen }
    }
}

impl ReadableStorageTraits for ReadStore {
    /// A whole file (a chunk, an array's metadata): its bytes are hashed as read. A store key
    /// is the file's path under the root with `/` separators, as the fingerprint names it.
    fn get(&self, key: &StoreKey) -> Result<MaybeBytes, StorageError> {
        let bytes = self.inner.get(key)?;
        if let Some(bytes) = &bytes {
            self.seen.saw(key.as_str(), bytes);
        }
        Ok(bytes)
    }

    /// Parts of a file (a shard's index and inner chunks) are not hashed: the fingerprint
    /// reads such a file whole when it is completed.
    fn get_partial_many<'a>(
        &'a self,
        key: &StoreKey,
        byte_ranges: ByteRangeIterator<'a>,
    ) -> Result<MaybeBytesIterator<'a>, StorageError> {
        self.inner.get_partial_many(key, byte_ranges)
    }

    fn size_key(&self, key: &StoreKey) -> Result<Option<u64>, StorageError> {
        self.inner.size_key(key)
    }

    fn supports_get_partial(&self) -> bool {
        self.inner.supports_get_partial()
    }
}
