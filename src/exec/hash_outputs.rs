//! The last step of a profile's build: the BLAKE3 of every output file, for the lock, while
//! the files are fsynced. A file the sink hashed as it wrote it (a Zarr store's files, a LeRobot
//! export's parquet files) is not read back.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::error::{Error, IoContext, Result};
use crate::{lock, source};

/// Threads that fsync a profile's outputs while they are hashed (they mostly wait on the disk).
const SYNC_THREADS: usize = 4;

/// The BLAKE3 of every file under `dir`, each fsynced meanwhile: `written`'s (by path) as the
/// sink took it from the bytes it wrote, the others read back.
pub(super) fn hash_and_sync(
    dir: &Path,
    written: &HashMap<PathBuf, blake3::Hash>,
) -> Result<BTreeMap<String, String>> {
    let listed = source::fingerprint::list_files(dir)?;
    // The files start reaching the disk (fsync, which mostly waits) while they are hashed, so
    // the commit need not sync them again. Several syncing threads: an output of many small
    // files (a Zarr store holds one per frame) waits on the disk once per file.
    let paths: Vec<PathBuf> = listed.iter().map(|rel| dir.join(rel)).collect();
    let (files, synced) = std::thread::scope(|scope| {
        let syncing: Vec<_> = (0..SYNC_THREADS)
            .map(|k| {
                let paths = &paths;
                scope.spawn(move || -> Result<()> {
                    for path in paths.iter().skip(k).step_by(SYNC_THREADS) {
                        std::fs::File::open(path)
                            .and_then(|f| f.sync_all())
                            .at("sync", path)?;
                    }
                    Ok(())
                })
            })
            .collect();
        // Small files side by side; a large one is hashed on every thread by `hash_file` itself.
        let hashed: Result<BTreeMap<String, String>> =
            crate::error::in_order(listed.par_iter().map(|rel| -> Result<(String, String)> {
                let name = rel.to_string_lossy().replace('\\', "/");
                let path = dir.join(rel);
                let hash = match written.get(&path) {
                    Some(hash) => hash.to_hex().to_string(),
                    None => lock::hash_file(&path)?,
                };
                Ok((name, hash))
            }))
            .map(|pairs| pairs.into_iter().collect());
        let synced = syncing
            .into_iter()
            .map(|t| {
                t.join()
                    .map_err(|_| Error::Internal("a thread syncing outputs panicked".into()))?
            })
            .collect::<Result<Vec<()>>>();
        (hashed, synced)
    });
    let files = files?;
    synced?;
    Ok(files)
}
