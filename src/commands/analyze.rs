//! `chunkc analyze`: the chunk-length analysis of one channel, written as
//! `audit/analyze.json` and `audit/analyze.html`.

use std::path::PathBuf;

use crate::analyze::{self, AnalyzeOptions, AnalyzeReport};
use crate::error::Result;
use crate::spec::LoadedSpec;

/// Analyzes the channel `options` names and writes the report; returns it and the two paths.
pub fn analyze(
    spec: &LoadedSpec,
    options: &AnalyzeOptions,
) -> Result<(AnalyzeReport, Vec<PathBuf>)> {
    let result = analyze::analyze(spec, options)?;
    let title = format!("chunkc analyze: {}", spec.file.display());
    let html = crate::report::analyze_html(&result, &title);
    let paths = analyze::write(&analyze::audit_dir(spec), &result, &html)?;
    Ok((result, paths))
}
