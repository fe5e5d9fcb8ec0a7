//! Render: self-contained HTML reports (inline CSS and SVG, no scripts, no external references)
//! for `chunkc audit` and `chunkc analyze`.
//!
//! Entry points: [`audit_html`] for an [`AuditReport`], [`analyze_html`] for an
//! [`AnalyzeReport`]. Both return the page as a string; the commands write it beside their JSON.
//!
//! - `page`: the HTML page builder (escaping, tables, notes, figures).
//! - `plot`: the charts, drawn with `plotters` into SVG.
//! - `doctor_plot`: the dataset doctor's charts (lag, units, shift).
//! - `audit_page`, `analyze_page`: what each page shows, in order.

mod analyze_page;
mod audit_page;
mod doctor_plot;
mod page;
pub mod plot;

use crate::analyze::AnalyzeReport;
use crate::audit::AuditReport;

/// The audit report page: verdict counts, interval histogram, per-episode timing, flagged
/// episodes, before/after charts of repaired episodes.
pub fn audit_html(report: &AuditReport, title: &str) -> String {
    audit_page::render(report, title)
}

/// The chunk-size analysis page: suggested K, ACF curves, each profile's K.
pub fn analyze_html(report: &AnalyzeReport, title: &str) -> String {
    analyze_page::render(report, title)
}

#[cfg(test)]
mod tests;
