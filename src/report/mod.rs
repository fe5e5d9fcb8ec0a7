//! Render: self-contained HTML reports (inline CSS and SVG, no scripts, no external references)
//! for `chunkc audit` and `chunkc analyze`.
//!
//! Entry points: [`audit_html`] for an [`AuditReport`], [`analyze_html`] for an
//! [`AnalyzeReport`]. Both return the page as a string; the commands write it beside their JSON.
//!
//! - `page`: the HTML page builder (escaping, tables, notes, figures).
//! - `plot`: the charts, drawn with `plotters` into SVG.
//! - `audit_page`, `analyze_page`: what each page shows, in order.

mod analyze_page;
mod audit_page;
mod page;
pub mod plot;

use std::path::{Path, PathBuf};

use crate::analyze::AnalyzeReport;
use crate::audit::AuditReport;
use crate::error::{Error, Result};

/// The audit report page: verdict counts, interval histogram, per-episode timing, flagged
/// episodes, before/after charts of repaired episodes.
pub fn audit_html(report: &AuditReport, title: &str) -> String {
    audit_page::render(report, title)
}

/// The chunk-size analysis page: suggested K, ACF curves, each profile's K.
pub fn analyze_html(report: &AnalyzeReport, title: &str) -> String {
    analyze_page::render(report, title)
}

/// Writes report files (`audit.json` + `report.html`, `analyze.json` + `analyze.html`) into
/// `dir`: each to a temporary name first, all renamed into place only once all were written, so a
/// failure never leaves a JSON file beside the page of an older run. Returns the paths.
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

#[cfg(test)]
mod tests;
