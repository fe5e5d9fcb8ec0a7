//! The staging directory and the build lock.
//!
//! Outputs are written under `<output.dir>/.chunkc-staging/<profile>/` and each profile directory
//! is renamed into place only when every profile succeeded. A rename of a complete directory is
//! atomic on one filesystem, so at any instant (SIGKILL included) every profile directory in
//! `<output.dir>` is either the previous complete one, the new complete one, or absent while it is
//! swapped; it is never half-written. The swap moves the previous directory to
//! `.chunkc-staging/<profile>.old` first; a build killed between the two renames leaves it there,
//! and the next build puts it back before doing anything else ([`Staging::recover`]).
//! `chunkc.lock` is written after the renames: a profile whose files do not match the lock is
//! simply rebuilt by the next build.
//!
//! Dropping a [`Staging`] without committing removes everything it created, so a failed build
//! leaves no partial output behind.
//!
//! [`BuildLock`] is an advisory lock (`flock`) on `<output.dir>/.chunkc-build.lock`, held for the
//! whole build: a second build of the same output directory fails at once instead of
//! interleaving. The kernel releases it when the process dies, however it dies; a build that
//! ends normally removes the file, so only a killed build leaves it (empty) behind.

use std::fs::{File, TryLockError};
use std::path::{Path, PathBuf};

use crate::error::{Error, IoContext, Result};
use crate::files::{BUILD_LOCK_FILE, STAGING_DIR};
const OLD_SUFFIX: &str = ".old";

/// Held for the duration of a build; see the module docs.
pub struct BuildLock {
    out_dir: PathBuf,
    file: Option<File>,
    created_out_dir: bool,
    /// Set once the build produced outputs: from then on the directory is the user's.
    keep: bool,
}

impl BuildLock {
    pub fn acquire(out_dir: &Path) -> Result<Self> {
        use std::os::unix::fs::MetadataExt;
        let created_out_dir = !out_dir.exists();
        std::fs::create_dir_all(out_dir).at("create output directory", out_dir)?;
        let path = out_dir.join(BUILD_LOCK_FILE);
        let mut lock = BuildLock {
            out_dir: out_dir.to_path_buf(),
            file: None,
            created_out_dir,
            keep: false,
        };
        loop {
            let file = File::options()
                .create(true)
                .truncate(false)
                .write(true)
                .open(&path)
                .at("open", &path)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => {
                    lock.keep = true; // the other build owns the directory
                    return Err(Error::Busy(format!(
                        "another chunkc build is writing to {} (it holds {}); wait for it to finish, then build again",
                        out_dir.display(),
                        path.display()
                    )));
                }
                Err(TryLockError::Error(e)) => return Err(Error::io_path("lock", &path, e)),
            }
            // The holder removes the file before it lets go: if the path no longer names the
            // file we locked, that build just finished and we must lock the new file.
            let ours = file.metadata().at("stat", &path)?.ino();
            match std::fs::metadata(&path) {
                Ok(m) if m.ino() == ours => {
                    lock.file = Some(file);
                    return Ok(lock);
                }
                _ => continue,
            }
        }
    }

    /// The build wrote outputs: keep the directory whatever happens next.
    pub fn keep(&mut self) {
        self.keep = true;
    }
}

impl Drop for BuildLock {
    fn drop(&mut self) {
        if let Some(file) = self.file.take() {
            // Removed while still held (see `acquire`), so the output directory holds outputs
            // only; closing the file releases the lock.
            let _ = std::fs::remove_file(self.out_dir.join(BUILD_LOCK_FILE));
            drop(file);
        }
        if self.created_out_dir && !self.keep {
            // Only removes it if nothing else was put there meanwhile.
            let _ = std::fs::remove_dir(&self.out_dir);
        }
    }
}

pub struct Staging {
    out_dir: PathBuf,
    dir: PathBuf,
    committed: bool,
    /// Profiles whose every file is already on disk ([`Staging::files_synced`]).
    synced: std::sync::Mutex<std::collections::BTreeSet<String>>,
}

impl Staging {
    /// Puts back any profile directory an interrupted commit had moved aside, and removes the
    /// rest of a stale staging directory. Call with the build lock held.
    pub fn recover(out_dir: &Path) -> Result<()> {
        let dir = out_dir.join(STAGING_DIR);
        if !dir.exists() {
            return Ok(());
        }
        let mut entries: Vec<PathBuf> = std::fs::read_dir(&dir)
            .at("read", &dir)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .collect();
        entries.sort();
        for old in entries {
            let Some(name) = old
                .file_name()
                .and_then(|n| n.to_str())
                .and_then(|n| n.strip_suffix(OLD_SUFFIX))
            else {
                continue;
            };
            let target = out_dir.join(name);
            if !target.exists() {
                // Killed between "move aside" and "move into place": the previous output is
                // complete, and the lock still describes it.
                std::fs::rename(&old, &target).at("restore", &target)?;
            }
        }
        // Everything else was never in place.
        std::fs::remove_dir_all(&dir).at("remove stale staging directory", &dir)
    }

    pub fn new(out_dir: &Path) -> Result<Self> {
        Self::recover(out_dir)?;
        let dir = out_dir.join(STAGING_DIR);
        std::fs::create_dir(&dir).at("create staging directory", &dir)?;
        Ok(Staging {
            out_dir: out_dir.to_path_buf(),
            dir,
            committed: false,
            synced: Default::default(),
        })
    }

    /// The staging directory of one profile (created).
    pub fn profile_dir(&self, name: &str) -> Result<PathBuf> {
        let dir = self.dir.join(name);
        std::fs::create_dir_all(&dir).at("create", &dir)?;
        Ok(dir)
    }

    /// Scratch space for this build (not created here): low-dim values spilled to disk. It goes
    /// with the staging directory, whether the build succeeds or fails; the leading dot keeps it
    /// apart from every profile name.
    pub fn scratch_dir(&self) -> PathBuf {
        self.dir.join(".spill")
    }

    /// Records that every file of profile `name` has been fsynced (as `exec::finish` does while
    /// it hashes them), so that [`Staging::commit`] need not sync them again: a second `fsync`
    /// of a clean file still costs a system call, and a Zarr output holds one file per frame.
    pub fn files_synced(&self, name: &str) {
        self.synced
            .lock()
            .expect("no panic while holding it")
            .insert(name.to_string());
    }

    /// Moves every staged profile into place, replacing the previous output of that profile.
    pub fn commit(mut self, profiles: &[String]) -> Result<()> {
        // Everything staged reaches the disk before any of it becomes visible.
        let synced = std::mem::take(&mut *self.synced.lock().expect("no panic while holding it"));
        for name in profiles.iter().filter(|n| !synced.contains(*n)) {
            sync_tree(&self.dir.join(name))?;
        }
        for name in profiles {
            let staged = self.dir.join(name);
            let target = self.out_dir.join(name);
            if target.exists() {
                let old = self.dir.join(format!("{name}{OLD_SUFFIX}"));
                std::fs::rename(&target, &old).at("move aside", &target)?;
            }
            std::fs::rename(&staged, &target).at("move into place", &target)?;
        }
        self.committed = true;
        std::fs::remove_dir_all(&self.dir).at("remove", &self.dir)?;
        Ok(())
    }
}

/// fsync of every file under `dir`, so that a power loss after the rename cannot leave a
/// complete-looking directory with empty files.
fn sync_tree(dir: &Path) -> Result<()> {
    for entry in std::fs::read_dir(dir).at("read", dir)? {
        let path = entry.at("read", dir)?.path();
        if path.is_dir() {
            sync_tree(&path)?;
        } else {
            File::open(&path)
                .and_then(|f| f.sync_all())
                .at("sync", &path)?;
        }
    }
    Ok(())
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}
