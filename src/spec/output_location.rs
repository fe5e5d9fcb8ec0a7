//! Where chunkc may write (`build`, and `audit`/`analyze` under the output directory too), a
//! rule on the spec's `output.dir` and `source.path`: never into its source (checked on the paths as written and with
//! every symlink resolved), and through a symlink in `output.dir`, or one chunkc would write
//! through directly under it, only when `[output] follow_symlinks = true`.

use std::path::{Component, Path, PathBuf};

use super::LoadedSpec;
use crate::error::Result;
use crate::files::{BUILD_LOCK_FILE, STAGING_DIR};

/// Refuses an output directory inside the source (however it gets there), and one that a symlink
/// the spec did not allow sends somewhere else.
pub fn check_output_location(spec: &LoadedSpec, out_dir: &Path) -> Result<()> {
    for path in spec.source_paths() {
        if let Some((message, help)) = inside_source(out_dir, &spec.resolve(path)) {
            return Err(spec.error_at(&["output", "dir"], message, help));
        }
    }
    let Some((link, target)) = symlink_on_the_way(spec, out_dir) else {
        return Ok(());
    };
    let message = format!(
        "the output path {} is a symlink to {}; chunkc writes through a symlink in `output.dir` only when the spec allows it",
        link.display(),
        target.display()
    );
    let help = Some("set `follow_symlinks = true` in `[output]` to write through it, or point `output.dir` at a directory that is not reached through a symlink".into());
    Err(spec.error_at(&["output", "dir"], message, help))
}

/// Why `out_dir` is inside the source at `source_dir` (as written, or through a symlink).
fn inside_source(out_dir: &Path, source_dir: &Path) -> Option<(String, Option<String>)> {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let (out_real, source_real) = (real_path(out_dir), real_path(source_dir));
    if abs(out_dir).starts_with(abs(source_dir)) {
        let how = if abs(out_dir) == abs(source_dir) {
            "is the source"
        } else {
            "is inside the source"
        };
        Some((
            format!(
                "the output directory {} {how} {}; chunkc never writes into a source",
                out_dir.display(),
                source_dir.display()
            ),
            None,
        ))
    } else if out_real.starts_with(&source_real) {
        // Only symlinks can make this happen: the written path looks harmless.
        Some((
            format!(
                "the output directory {} resolves through a symlink to {}, inside the source {}; chunkc never writes into a source",
                out_dir.display(),
                out_real.display(),
                source_real.display()
            ),
            Some("point `output.dir` at a directory outside the source, or remove the symlink".into()),
        ))
    } else {
        None
    }
}

/// The first symlink among the paths the spec decides: each component of `output.dir` as written
/// (the directories above the spec's own are not its business), then what a build creates
/// directly under the output directory. `None` when `output.follow_symlinks` is set.
fn symlink_on_the_way(spec: &LoadedSpec, out_dir: &Path) -> Option<(PathBuf, PathBuf)> {
    if spec.spec.output.follow_symlinks {
        return None;
    }
    let written = Path::new(&spec.spec.output.dir);
    let mut path = if written.is_absolute() {
        PathBuf::new()
    } else {
        spec.dir.clone()
    };
    let mut candidates = Vec::new();
    for component in written.components() {
        path.push(component);
        if matches!(component, Component::Normal(_)) {
            candidates.push(path.clone());
        }
    }
    let made = [STAGING_DIR, BUILD_LOCK_FILE];
    let profiles = spec.profiles.iter().map(|p| p.name.as_str());
    candidates.extend(made.into_iter().chain(profiles).map(|n| out_dir.join(n)));
    candidates.into_iter().find_map(|p| {
        let is_link = std::fs::symlink_metadata(&p).is_ok_and(|m| m.file_type().is_symlink());
        is_link.then(|| {
            let target = std::fs::read_link(&p).unwrap_or_default();
            (p, target)
        })
    })
}

/// `path` with every symlink resolved, for the part of it that exists.
fn real_path(path: &Path) -> PathBuf {
    let abs = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut rest = Vec::new();
    let mut existing = abs.as_path();
    loop {
        if let Ok(real) = existing.canonicalize() {
            return rest.iter().rev().fold(real, |p, part| p.join(part));
        }
        match (existing.parent(), existing.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_os_string());
                existing = parent;
            }
            _ => return abs,
        }
    }
}
