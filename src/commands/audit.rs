//! `chunkc audit`: the source opened and every episode's timing judged; the report written
//! beside the outputs as `audit/audit.json` and `audit/report.html`.

use std::path::PathBuf;

use crate::audit::{self, AuditReport};
use crate::error::Result;
use crate::files;
use crate::source::{self, Source};
use crate::spec::{self, LoadedSpec};
use crate::timings;

/// The source as read, its audit, and each episode's repair.
pub struct Audit {
    pub source: Box<dyn Source>,
    pub report: AuditReport,
    pub repairs: Vec<audit::Repair>,
}

/// Opens the source and audits it (after checking where the outputs would go); with `doctor`,
/// the dataset doctor too (see [`audit::run`]).
pub fn audit(spec: &LoadedSpec, doctor: bool) -> Result<Audit> {
    spec::check_output_location(spec, &spec.resolve(&spec.spec.output.dir))?;
    let opened = timings::phase("open source");
    let source = source::open(spec)?;
    drop(opened);
    let _audit = timings::phase("audit");
    let (report, repairs) = audit::run(spec, source.as_ref(), doctor)?;
    Ok(Audit {
        source,
        report,
        repairs,
    })
}

/// One source's audit as `chunkc audit` wrote it: the source's name in a mixture (empty for
/// `[source]`), the report, and the JSON and HTML paths.
pub type Written = (String, AuditReport, Vec<PathBuf>);

/// `chunkc audit`: the audit with its repair examples, written as JSON and HTML, under
/// `audit/` (a mixture: each source's under `audit/<name>/`).
pub fn audit_report(spec: &LoadedSpec) -> Result<Vec<Written>> {
    let mut out = Vec::new();
    for view in spec.source_views() {
        let dir = match spec.is_mixture() {
            true => crate::analyze::audit_dir(spec).join(&view.name),
            false => crate::analyze::audit_dir(spec),
        };
        let (report, paths) = audit_one(&view.spec, &dir)?;
        out.push((view.name, report, paths));
    }
    Ok(out)
}

/// The audit of one source, written into `dir`.
fn audit_one(spec: &LoadedSpec, dir: &std::path::Path) -> Result<(AuditReport, Vec<PathBuf>)> {
    let Audit {
        source,
        mut report,
        repairs,
    } = audit(spec, true)?;
    report.examples = audit::examples(source.as_ref(), &report, &repairs)?;
    let title = format!("chunkc audit: {}", spec.file.display());
    let html = crate::report::audit_html(&report, &title);
    let paths = files::write_files(
        dir,
        &[
            ("audit.json", report.to_json().into_bytes()),
            ("report.html", html.into_bytes()),
        ],
    )?;
    Ok((report, paths))
}
