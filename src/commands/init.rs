//! `chunkc init`: the dataset inspected, a commented spec drafted from it, checked as `chunkc
//! check` checks a spec, and written only when it passes and no file is in the way.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::init::{self, InitOptions, Inspection};
use crate::spec::LoadedSpec;

/// Inspects `dataset`, writes the spec to `out` (refusing to replace a file), and returns the
/// inspection and the spec as written.
pub fn init(dataset: &Path, out: &Path, options: &InitOptions) -> Result<(Inspection, PathBuf)> {
    if out.exists() {
        return Err(Error::Spec(format!(
            "error: {} already exists; chunkc init never overwrites a spec (remove it, or give --out)",
            out.display()
        )));
    }
    let spec_dir = init::text::spec_dir(out);
    if !spec_dir.is_dir() {
        return Err(Error::Spec(format!(
            "error: the directory of {} does not exist",
            out.display()
        )));
    }
    let inspection = init::inspect(dataset, &spec_dir, options)?;
    let out_dir = output_dir(&inspection);
    let text = init::text::spec(&inspection, &spec_dir, &out_dir);
    let spec = LoadedSpec::parse(&out.display().to_string(), &text, &spec_dir)
        .map_err(|e| Error::Internal(format!("the spec chunkc init wrote does not parse:\n{e}")))?;
    // What `chunkc check` does: the plan, every profile resolved against the opened source.
    super::check(&spec)?;
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(out)
        .map_err(|e| Error::io_path("create", out, e))?;
    file.write_all(text.as_bytes())
        .and_then(|()| file.sync_all())
        .map_err(|e| {
            let _ = std::fs::remove_file(out);
            Error::io_path("write", out, e)
        })?;
    Ok((inspection, out.to_path_buf()))
}

/// `out/<dataset>` beside the spec.
fn output_dir(inspection: &Inspection) -> String {
    format!("out/{}", init::dataset_name(&inspection.path))
}
