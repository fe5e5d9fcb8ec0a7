//! A fingerprint completed later than the source's opening, so that a build need not wait for
//! it before it reads.
//!
//! An adapter that reads whole files through code of its own (a zarr store's chunk files) need
//! not read its source twice: it opens with a [`SourcePrint::pending`] fingerprint, hashes each
//! file's bytes as the pass reads them ([`Seen::saw`]), and the first caller that needs
//! the value ([`SourcePrint::get`]: the lock, `meta.json`, a rebuild's freshness) hashes only the
//! files the pass did not read. The value is the same as hashing every file at open.
//!
//! An adapter whose files are read in parts (HDF5 datasets, parquet row groups, videos) opens
//! with a [`SourcePrint::beside`] fingerprint instead: one thread of its own, at the lowest
//! scheduling priority, hashes the files while the build reads them, on the cores the pass
//! leaves idle (an image build waits on its reads and writes), and the first caller waits for it.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use super::{combine, name_of, Fingerprint};
use crate::error::{Error, IoContext, Result};

/// A source's fingerprint, known at open or completed on first use from the hashes its pass
/// recorded. Clones share one value.
#[derive(Clone)]
pub struct SourcePrint(Arc<Print>);

struct Print {
    /// Once known.
    done: Mutex<Option<Arc<Fingerprint>>>,
    /// The files it covers, when it was not known at open.
    pending: Option<Pending>,
}

struct Pending {
    root: PathBuf,
    files: Vec<PathBuf>,
    seen: Seen,
    /// The thread hashing every file, for a [`SourcePrint::beside`] fingerprint.
    hashing: Mutex<Option<std::thread::JoinHandle<Result<Fingerprint>>>>,
}

/// The hashes of whole files as an adapter's own reads saw them, by name in the fingerprint
/// ([`name_of`]). Clones share one record; once the fingerprint is complete it records nothing.
#[derive(Clone, Default)]
pub struct Seen(Arc<SeenFiles>);

#[derive(Default)]
struct SeenFiles {
    closed: AtomicBool,
    hashes: Mutex<HashMap<String, blake3::Hash>>,
}

impl Seen {
    /// Records `bytes`, the whole contents of file `name` (its path in the source, `/`
    /// separators), as read.
    pub fn saw(&self, name: &str, bytes: &[u8]) {
        if self.0.closed.load(Ordering::Relaxed) {
            return;
        }
        let hash = blake3::hash(bytes);
        lock(&self.0.hashes).insert(name.to_string(), hash);
    }

    /// What was recorded; nothing is recorded after.
    fn close(&self) -> HashMap<String, blake3::Hash> {
        self.0.closed.store(true, Ordering::Relaxed);
        std::mem::take(&mut *lock(&self.0.hashes))
    }
}

impl SourcePrint {
    /// A fingerprint computed at open.
    pub fn known(fingerprint: Fingerprint) -> SourcePrint {
        SourcePrint(Arc::new(Print {
            done: Mutex::new(Some(Arc::new(fingerprint))),
            pending: None,
        }))
    }

    /// The fingerprint of `files` (relative to `root`, sorted), computed when first asked for:
    /// from the hashes `seen` recorded, and by reading the files it did not.
    pub fn pending(root: &Path, files: Vec<PathBuf>, seen: Seen) -> SourcePrint {
        SourcePrint(Arc::new(Print {
            done: Mutex::new(None),
            pending: Some(Pending {
                root: root.to_path_buf(),
                files,
                seen,
                hashing: Mutex::new(None),
            }),
        }))
    }

    /// The fingerprint of `files` (relative to `root`, sorted), hashed by a thread of its own at
    /// the lowest priority from now on, beside the build (see the module's text).
    pub fn beside(root: &Path, files: Vec<PathBuf>) -> SourcePrint {
        let print = SourcePrint::pending(root, files.clone(), Seen::default());
        let root = root.to_path_buf();
        let spawned = std::thread::Builder::new()
            .name("chunkc-fingerprint".into())
            .spawn(move || {
                lowest_priority();
                let hashes: Result<Vec<blake3::Hash>> = files
                    .iter()
                    .map(|rel| hash_file_here(&root.join(rel)))
                    .collect();
                Ok(combine(&files, &hashes?))
            });
        // Without a thread, the first caller hashes the files.
        if let (Ok(thread), Some(pending)) = (spawned, &print.0.pending) {
            *lock(&pending.hashing) = Some(thread);
        }
        print
    }

    /// The fingerprint: the value known, or (the first time) the hashes the pass recorded and
    /// those of the files it did not read.
    pub fn get(&self) -> Result<Arc<Fingerprint>> {
        let mut done = lock(&self.0.done);
        if let Some(known) = &*done {
            return Ok(known.clone());
        }
        let pending = self
            .0
            .pending
            .as_ref()
            .expect("a print is known or pending");
        if let Some(thread) = lock(&pending.hashing).take() {
            let _waiting = crate::timings::phase("fingerprint source (waiting for its thread)");
            // An error (a file gone or unreadable) is found again below, and reported there.
            if let Ok(Ok(value)) = thread.join() {
                let value = Arc::new(value);
                *done = Some(value.clone());
                return Ok(value);
            }
        }
        let seen = pending.seen.close();
        let _rest = crate::timings::phase("fingerprint source (files the pass did not read)");
        let hashes = hash_all(&pending.root, &pending.files, &seen)?;
        let value = Arc::new(combine(&pending.files, &hashes));
        *done = Some(value.clone());
        Ok(value)
    }

    /// The fingerprint's value ([`SourcePrint::get`]).
    pub fn hash(&self) -> Result<String> {
        Ok(self.get()?.hash.clone())
    }
}

impl From<Fingerprint> for SourcePrint {
    fn from(fingerprint: Fingerprint) -> SourcePrint {
        SourcePrint::known(fingerprint)
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    // A panic while the lock was held left plain values behind: still usable.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl std::fmt::Debug for SourcePrint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &*lock(&self.0.done) {
            Some(known) => write!(f, "SourcePrint({})", known.hash),
            None => write!(f, "SourcePrint(pending)"),
        }
    }
}

/// Serialized as its value (computed if it is still pending).
impl serde::Serialize for SourcePrint {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        let hash = self.hash().map_err(serde::ser::Error::custom)?;
        s.serialize_str(&hash)
    }
}

/// The hashes of `files` (under `root`), in order: those `seen` recorded, the others read.
///
/// On plain threads, as many as the pool has, not on the pool: the caller holds the print's
/// lock, and may be one of the pool's threads. A pool thread that waited for its own parallel
/// job could take up another job meanwhile, one that asks for this same print, and wait on the
/// lock it holds itself.
fn hash_all(
    root: &Path,
    files: &[PathBuf],
    seen: &HashMap<String, blake3::Hash>,
) -> Result<Vec<blake3::Hash>> {
    let threads = rayon::current_num_threads().clamp(1, files.len().max(1));
    let one = |rel: &PathBuf| match seen.get(&name_of(rel)) {
        Some(h) => Ok(*h),
        None => hash_file_here(&root.join(rel)),
    };
    let parts: Vec<Vec<Result<blake3::Hash>>> = std::thread::scope(|scope| {
        let running: Vec<_> = (0..threads)
            .map(|k| scope.spawn(move || files.iter().skip(k).step_by(threads).map(one).collect()))
            .collect();
        running
            .into_iter()
            .map(|t| t.join().unwrap_or_default())
            .collect()
    });
    // Back in file order; the first error in that order is the one reported.
    let mut parts: Vec<_> = parts.into_iter().map(Vec::into_iter).collect();
    let mut hashes = Vec::with_capacity(files.len());
    for i in 0..files.len() {
        let hash = parts[i % threads].next().ok_or_else(|| {
            Error::Internal("a thread hashing the source's fingerprint panicked".into())
        })?;
        hashes.push(hash?);
    }
    Ok(hashes)
}

/// BLAKE3 of a file's contents on the calling thread alone (a large file is not split over the
/// pool's threads, as [`hash_file`] does).
fn hash_file_here(path: &Path) -> Result<blake3::Hash> {
    super::hash_opened(std::fs::File::open(path).at("open", path)?, path)
}

/// Lowers the calling thread to the lowest scheduling priority (Linux keeps a nice value per
/// thread), so that it runs only where the build leaves a core idle.
fn lowest_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: `setpriority` only changes the calling thread's nice value (`who` 0 is the caller).
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, 19);
    }
}

#[cfg(test)]
mod tests {
    use super::super::{list_files, of_files};
    use super::*;

    /// A pending fingerprint takes the hashes of the files the pass read from what it saw (a
    /// file deleted after it was read is not read again) and reads the rest; the value is the
    /// one of hashing every file at open. Once complete, it records nothing more.
    #[test]
    fn pending_takes_what_the_pass_saw_and_reads_the_rest() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("c")).unwrap();
        for (name, bytes) in [("c/0", b"zero".as_slice()), ("c/1", b"one"), ("meta", b"m")] {
            std::fs::write(dir.path().join(name), bytes).unwrap();
        }
        let files = list_files(dir.path()).unwrap();
        let at_open = of_files(dir.path(), &files).unwrap();
        let seen = Seen::default();
        let print = SourcePrint::pending(dir.path(), files, seen.clone());
        seen.saw("c/0", b"zero");
        std::fs::remove_file(dir.path().join("c/0")).unwrap();
        assert_eq!(*print.get().unwrap(), at_open);
        assert_eq!(print.hash().unwrap(), at_open.hash);
        assert!(seen.close().is_empty());
        seen.saw("c/1", b"one");
        assert!(seen.close().is_empty());
        // A file neither seen nor on disk is an error naming it.
        let seen = Seen::default();
        let files = vec![PathBuf::from("c/0")];
        let err = SourcePrint::pending(dir.path(), files, seen)
            .get()
            .unwrap_err();
        assert!(err.to_string().contains("c/0"), "{err}");
    }

    /// A fingerprint hashed beside the build has the value of hashing at open; a file that
    /// cannot be read is an error naming it, at the first call that needs the value.
    #[test]
    fn beside_equals_hashing_at_open_and_names_a_missing_file() {
        let dir = tempfile::tempdir().unwrap();
        for (name, len) in [("a", 10usize), ("b", (8 << 20) * 2 + 7), ("c", 0)] {
            let bytes: Vec<u8> = (0..len).map(|i| (i * 13 + i / 977) as u8).collect();
            std::fs::write(dir.path().join(name), bytes).unwrap();
        }
        let files = list_files(dir.path()).unwrap();
        let at_open = of_files(dir.path(), &files).unwrap();
        let print = SourcePrint::beside(dir.path(), files.clone());
        assert_eq!(*print.get().unwrap(), at_open);
        assert_eq!(*print.clone().get().unwrap(), at_open);
        let gone = [files, vec![PathBuf::from("gone")]].concat();
        let err = SourcePrint::beside(dir.path(), gone).get().unwrap_err();
        assert!(err.to_string().contains("gone"), "{err}");
    }

    /// Many files, a third of them seen: the hashes come back in file order from every thread.
    #[test]
    fn many_files_come_back_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let seen = Seen::default();
        for i in 0..37 {
            let bytes = format!("file {i}").repeat(i);
            std::fs::write(dir.path().join(format!("f{i:02}")), &bytes).unwrap();
            if i % 3 == 0 {
                seen.saw(&format!("f{i:02}"), bytes.as_bytes());
            }
        }
        let files = list_files(dir.path()).unwrap();
        let at_open = of_files(dir.path(), &files).unwrap();
        let print = SourcePrint::pending(dir.path(), files, seen);
        assert_eq!(*print.get().unwrap(), at_open);
    }
}
