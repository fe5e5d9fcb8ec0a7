//! `chunkc plan` (and the start of `check` and `build`): the audited source and the plan
//! resolved against the lock.

use super::audit::audit;
use std::sync::Arc;

use crate::audit::sources_doctor::SourcesDoctor;
use crate::audit::{AuditReport, Audited};
use crate::error::{Error, Result};
use crate::lock::{self, Lock};
use crate::plan::{self, Plan};
use crate::source::Source;
use crate::spec::{self, LoadedSpec, SplitFrom};

/// Opens the source, audits it (the dataset doctor included), and resolves the plan against the
/// lock (what `chunkc plan` shows), with the sizes of lossily stored frames measured
/// ([`super::measure`]). The source returned is the audited one: exclusions gone,
/// repairs applied on read.
pub fn plan(spec: &LoadedSpec) -> Result<(Box<dyn Source>, Plan)> {
    plan_reported(spec).map(|(source, plan, _)| (source, plan))
}

/// [`plan`], and the audit's report.
pub fn plan_reported(spec: &LoadedSpec) -> Result<(Box<dyn Source>, Plan, AuditReport)> {
    let (source, mut plan, report, _) = plan_audited(spec, true)?;
    // Lossily stored frames: sizes from what is measured here (`build` does not need them; a
    // mixture's are estimated).
    if !spec.is_mixture() {
        let measured = super::measure::frames(spec, source.as_ref(), &plan, &report);
        plan::estimate::fill(&mut plan, &measured);
    }
    Ok((source, plan, report))
}

/// A plan with its source, the audit's report and a mixture's sources' doctor still to judge.
pub type Planned = (
    Box<dyn Source>,
    Plan,
    AuditReport,
    Option<Arc<SourcesDoctor>>,
);

/// [`plan`], with the dataset doctor only when `doctor` is set (`build` folds it into its
/// read: a mixture's sources' doctor, still to judge, comes back with it), and the audit's
/// report.
pub fn plan_audited(spec: &LoadedSpec, doctor: bool) -> Result<Planned> {
    let (source, report, riding) = match spec.is_mixture() {
        true => super::mixture::open(spec, !doctor)?,
        false => {
            let (source, report) = audited_source(spec, doctor)?;
            (source, report, None)
        }
    };
    let out_dir = spec.resolve(&spec.spec.output.dir);
    spec::check_output_location(spec, &out_dir)?;
    let lock = Lock::read(&lock::path_for(&spec.file))?;
    let entry = lock
        .as_ref()
        .and_then(|l| l.specs.get(&lock::key_for(&spec.file)));
    let mut plan = plan::resolve(spec, source.manifest(), entry, &out_dir)?;
    plan::apply_audit(&mut plan, &report, spec.spec.audit.repair);
    Ok((source, plan, report, riding))
}

/// The one source of `spec`, audited (the doctor too when `doctor` is set), and its report.
fn audited_source(spec: &LoadedSpec, doctor: bool) -> Result<(Box<dyn Source>, AuditReport)> {
    let audited = audit(spec, doctor)?;
    let report = audited.report;
    let applied = spec.spec.audit.repair;
    let source: Box<dyn Source> = Box::new(Audited::new(
        audited.source,
        &report,
        audited.repairs,
        applied,
    ));
    let manifest = source.manifest();
    if manifest.episodes.is_empty() {
        return Err(Error::source(format!(
            "{}: the audit excluded every episode ({}); see `chunkc audit`, or relax `[audit]`",
            spec.source().path,
            report
                .episodes
                .first()
                .map(|e| format!("episode {}: {}", e.id, e.detail))
                .unwrap_or_default()
        )));
    }
    for warning in &manifest.warnings {
        eprintln!("warning: {warning}");
    }
    if spec.spec.split.from == SplitFrom::Source && manifest.source_split.is_none() {
        eprintln!(
            "warning: `split.from = \"source\"`, but {} stores no split; using `val_fraction` and `seed`",
            spec.source().path
        );
    }
    Ok((source, report))
}
