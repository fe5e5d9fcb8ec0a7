//! Several files written as one: each to a temporary name first, all renamed into place only
//! once every one was written, so a failure never leaves a new file beside an old one's
//! companion (the JSON of one run beside the page of another).

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Writes `files` (name, bytes) into `dir` (created if missing) as described above; returns
/// their paths, in order.
pub fn write_files(dir: &Path, files: &[(&str, Vec<u8>)]) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io_path("create", dir, e))?;
    let tmp_of = |name: &str| dir.join(format!(".{name}.tmp"));
    for (name, bytes) in files {
        let tmp = tmp_of(name);
        std::fs::write(&tmp, bytes).map_err(|e| Error::io_path("write", &tmp, e))?;
    }
    let mut paths = Vec::new();
    for (name, _) in files {
        let (tmp, path) = (tmp_of(name), dir.join(name));
        std::fs::rename(&tmp, &path).map_err(|e| Error::io_path("rename", &tmp, e))?;
        paths.push(path);
    }
    Ok(paths)
}
