//! Which on-disk layout a path holds (`chunkc init`, `chunkc inspect`), decided from the files
//! each adapter needs, and the keys a source offers before any channel is mapped.
//!
//! Detection looks at names and the few bytes that identify a layout; it never trusts an
//! extension alone. When nothing fits, the error says what was looked for and what was found, so
//! that a LeRobot folder with a missing `meta/info.json` is told so, not "unknown format".

use std::path::{Path, PathBuf};

use super::mapping::KeyInfo;
use crate::error::{Error, Result};
use crate::spec::{LoadedSpec, SourceFormat};

/// A path recognized as one source format.
#[derive(Debug, Clone)]
pub struct Detected {
    pub format: SourceFormat,
    /// The path the spec's `source.path` should name (the path given, or the RLDS dataset
    /// directory above a version directory).
    pub path: PathBuf,
    /// Why: the files that gave the format away.
    pub evidence: String,
}

/// The first 8 bytes of every HDF5 file (at offset 0 for the files robot datasets use).
const HDF5_SIGNATURE: &[u8; 8] = b"\x89HDF\r\n\x1a\n";

fn is_hdf5(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && &head == HDF5_SIGNATURE
}

fn names(dir: &Path) -> Result<Vec<String>> {
    let mut out: Vec<String> = std::fs::read_dir(dir)
        .map_err(|e| Error::source(format!("{}: cannot list: {e}", dir.display())))?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    out.sort();
    Ok(out)
}

/// `episode_12.hdf5` (ALOHA / ACT's naming).
fn is_episode_file(name: &str) -> bool {
    name.strip_prefix("episode_")
        .and_then(|r| r.strip_suffix(".hdf5").or_else(|| r.strip_suffix(".h5")))
        .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
}

/// A TFDS version directory: `dataset_info.json` beside `features.json`.
fn is_tfds_version(dir: &Path) -> bool {
    dir.join("dataset_info.json").is_file() && dir.join("features.json").is_file()
}

/// Decides the format of `path`, or says why none fits.
// Long function: one check per layout, in the order that keeps look-alikes apart (a zarr store also has meta/ and data/).
pub fn detect(path: &Path) -> Result<Detected> {
    let shown = path.display();
    if !path.exists() {
        return Err(Error::source(format!("{shown} does not exist")));
    }
    let found = |format, evidence: String| {
        Ok(Detected {
            format,
            path: path.to_path_buf(),
            evidence,
        })
    };
    if path.is_file() {
        if !is_hdf5(path) {
            return Err(Error::source(format!(
                "{shown} is a file but not an HDF5 file (no HDF5 signature); chunkc reads one-file \
                 datasets only as robomimic / robosuite HDF5. Give the dataset's directory for the \
                 other formats (LeRobot, Diffusion Policy zarr, ALOHA episodes, RLDS)"
            )));
        }
        return found(
            SourceFormat::RobomimicHdf5,
            "an HDF5 file (robomimic / robosuite: `data/demo_<n>` groups)".into(),
        );
    }
    let entries = names(path)?;
    if entries.is_empty() {
        return Err(Error::source(format!(
            "{shown} is an empty directory: no dataset to read"
        )));
    }
    let has = |name: &str| entries.iter().any(|e| e == name);
    // LeRobot: meta/info.json names the version; a folder with LeRobot's other parts but no
    // info.json is a LeRobot dataset that lost its main metadata file.
    if path.join("meta/info.json").is_file() {
        return found(SourceFormat::Lerobot, "meta/info.json (LeRobot)".into());
    }
    // Diffusion Policy's ReplayBuffer: data/<key> arrays and meta/episode_ends, zarr v2 or v3.
    let zarr_node = |p: &Path| {
        [".zarray", ".zgroup", "zarr.json"]
            .iter()
            .any(|f| p.join(f).is_file())
    };
    if path.join("meta/episode_ends").is_dir() && zarr_node(&path.join("meta/episode_ends")) {
        return found(
            SourceFormat::DiffusionPolicyZarr,
            "a zarr store with meta/episode_ends (Diffusion Policy replay buffer)".into(),
        );
    }
    if has("meta") && (has("data") || has("videos")) && !zarr_node(path) {
        return Err(Error::source(format!(
            "{shown} looks like a LeRobot dataset (meta/ and {}/) but has no meta/info.json, \
             which holds its version, rate and features; copy it back from the dataset's source",
            if has("data") { "data" } else { "videos" }
        )));
    }
    if zarr_node(path) {
        return Err(Error::source(format!(
            "{shown} is a zarr store but has no meta/episode_ends array; chunkc reads zarr in \
             Diffusion Policy's ReplayBuffer layout (data/<key> arrays, meta/episode_ends)"
        )));
    }
    // ALOHA / ACT: a directory of episode_<i>.hdf5.
    let episodes = entries.iter().filter(|n| is_episode_file(n)).count();
    if episodes > 0 {
        return found(
            SourceFormat::AlohaHdf5,
            format!("{episodes} episode_<i>.hdf5 files (ALOHA / ACT)"),
        );
    }
    // RLDS: a TFDS version directory, or a dataset directory holding version directories.
    if is_tfds_version(path) {
        let parent = path.parent().filter(|p| !p.as_os_str().is_empty());
        return Ok(Detected {
            format: SourceFormat::Rlds,
            path: parent.map_or_else(|| path.to_path_buf(), Path::to_path_buf),
            evidence: "dataset_info.json and features.json (a TFDS / RLDS version directory)"
                .into(),
        });
    }
    let versions: Vec<&String> = entries
        .iter()
        .filter(|n| is_tfds_version(&path.join(n)))
        .collect();
    if let Some(v) = versions.last() {
        return found(
            SourceFormat::Rlds,
            format!("{v}/dataset_info.json and features.json (TFDS / RLDS)"),
        );
    }
    let hdf5: Vec<&String> = entries.iter().filter(|n| is_hdf5(&path.join(n))).collect();
    let hint = match hdf5.first() {
        Some(f) => format!(
            "; it holds HDF5 files ({f}{}): give one robomimic file's path, or name ALOHA episodes episode_<i>.hdf5",
            if hdf5.len() > 1 { ", ..." } else { "" }
        ),
        None => String::new(),
    };
    let listed: Vec<&str> = entries.iter().take(6).map(String::as_str).collect();
    Err(Error::source(format!(
        "{shown}: no dataset chunkc reads: looked for meta/info.json (LeRobot), meta/episode_ends \
         (Diffusion Policy zarr), episode_<i>.hdf5 files (ALOHA), dataset_info.json + features.json \
         (RLDS), and found {}{}{hint}",
        listed.join(", "),
        if entries.len() > listed.len() { ", ..." } else { "" }
    )))
}

/// Every key the source of `spec` offers (its channels are ignored): the source is opened with
/// an empty mapping, and stops where it would map them. Returns where they were listed from.
pub fn offered(spec: &LoadedSpec) -> Result<(String, Vec<KeyInfo>)> {
    let mut probe = spec.clone();
    if let Some(source) = probe.spec.source.as_mut() {
        source.channels.clear();
    }
    match super::open(&probe) {
        Err(Error::Offered(offer)) => Ok((
            offer.place,
            offer
                .keys
                .into_iter()
                .map(|(key, shape, dtype)| KeyInfo { key, shape, dtype })
                .collect(),
        )),
        Err(e) => Err(e),
        Ok(_) => Err(Error::Internal(
            "a source opened with no channels mapped did not list its keys".into(),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn episode_file_names() {
        assert!(is_episode_file("episode_0.hdf5"));
        assert!(is_episode_file("episode_12.h5"));
        assert!(!is_episode_file("episode_.hdf5"));
        assert!(!is_episode_file("episode_1a.hdf5"));
        assert!(!is_episode_file("demo_1.hdf5"));
    }
}
