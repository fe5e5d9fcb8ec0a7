//! `chunkc.lock`: what the last successful build of each spec produced, written next to the
//! specs. One lock serves every spec of a directory: entries are keyed by the spec's file name, and
//! a build rewrites only its own entry.
//!
//! JSON with sorted keys and no timestamps, so that it is itself reproducible and diffs well in
//! code review. The plan compares it with the current spec, source and output files to decide
//! which profiles are up to date, and why not ([`crate::plan::freshness`]): for that it keeps the
//! spec values each profile was built from and the hash of every source file. Both are optional
//! when read, so locks written before them still read (their changes are then named less
//! precisely).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, IoContext, Result};

pub const LOCK_VERSION: u32 = 2;
pub const LOCK_FILE: &str = "chunkc.lock";

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Lock {
    pub version: u32,
    /// By spec file name.
    pub specs: BTreeMap<String, SpecLock>,
}

/// What one spec's last build produced.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SpecLock {
    pub tool_version: String,
    pub spec_hash: String,
    pub source_fingerprint: String,
    /// BLAKE3 of every source file, by path in the source, so that a changed source names the
    /// file (absent from locks written before chunkc recorded it).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub source_files: BTreeMap<String, String>,
    pub profiles: BTreeMap<String, LockedProfile>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LockedProfile {
    /// Fingerprint of everything the profile's outputs depend on.
    pub fingerprint: String,
    /// BLAKE3 of every output file, by path relative to the profile directory.
    pub files: BTreeMap<String, String>,
    /// The spec values the fingerprint covers, by dotted key as JSON text, so that a changed
    /// fingerprint names the value (absent from locks written before chunkc recorded them).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub inputs: BTreeMap<String, String>,
    /// The lossy encoder of the profile's camera frames (JPEG or video), when it has one: the
    /// bytes it writes depend on the library version, which the spec cannot pin.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoder: Option<LockedEncoder>,
}

/// A frame encoder as `chunkc.lock` records it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LockedEncoder {
    /// The encoder (`libjpeg-turbo`, `libx264`, `libsvtav1`).
    pub name: String,
    /// The library version it ran with.
    pub version: String,
    /// Every setting that changes its bytes.
    pub settings: BTreeMap<String, String>,
}

/// Where the lock of a spec lives.
pub fn path_for(spec_file: &Path) -> PathBuf {
    spec_file
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default()
        .join(LOCK_FILE)
}

/// The key of a spec's entry in its lock.
pub fn key_for(spec_file: &Path) -> String {
    spec_file
        .file_name()
        .unwrap_or_default()
        .to_string_lossy()
        .into_owned()
}

impl Lock {
    /// Reads a lock; a missing file is `Ok(None)`, an unreadable one an error.
    pub fn read(path: &Path) -> Result<Option<Lock>> {
        match std::fs::read_to_string(path) {
            Ok(text) => serde_json::from_str::<Lock>(&text)
                .ok()
                .filter(|l| l.version == LOCK_VERSION)
                .map(Some)
                .ok_or_else(|| {
                    Error::output(format!(
                        "{} is not a chunkc lock file of version {LOCK_VERSION}; delete it to rebuild everything",
                        path.display()
                    ))
                }),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(Error::io_path("read", path, e)),
        }
    }

    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("lock serializes");
        s.push('\n');
        s
    }

    /// Writes atomically (temporary file + rename).
    pub fn write(&self, path: &Path) -> Result<()> {
        let tmp = path.with_extension("lock.tmp");
        std::fs::write(&tmp, self.to_json()).at("write", &tmp)?;
        std::fs::rename(&tmp, path).at("rename into place", path)
    }
}

/// BLAKE3 of a file's contents, hex ([`crate::source::fingerprint::hash_file`]).
pub fn hash_file(path: &Path) -> Result<String> {
    Ok(crate::source::fingerprint::hash_file(path)?
        .to_hex()
        .to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hash_file_equals_hashing_the_bytes_whole() {
        let dir = tempfile::tempdir().unwrap();
        // Small (streamed) and large (blocks hashed on every thread, a partial last block).
        for (name, len) in [
            ("small", 1000usize),
            ("large", (8 << 20) * 2 + 12345),
            ("whole blocks", (8 << 20) * 3),
        ] {
            let bytes: Vec<u8> = (0..len).map(|i| (i * 31 + i / 4093) as u8).collect();
            let path = dir.path().join(name);
            std::fs::write(&path, &bytes).unwrap();
            let want = blake3::hash(&bytes).to_hex().to_string();
            assert_eq!(hash_file(&path).unwrap(), want, "{name}");
        }
    }
}
