//! Opening a training mixture (`[sources.<name>]`): each source opened, audited and repaired on
//! its own, then joined into one source at the mixture's rate ([`crate::audit::Mixture`]). Each
//! source's dataset doctor runs at its own rate: in a pass of its own for `plan`, `check` and
//! `audit`, on the build's one read for `build` ([`SourcesDoctor`]).

use std::sync::Arc;

use super::audit::audit;
use crate::audit::doctor::Probe;
use crate::audit::joined_report::joined_report;
use crate::audit::mixture::{id_offsets, Part};
use crate::audit::sources_doctor::{SourceDoctor, SourcesDoctor};
use crate::audit::{AuditReport, Audited, Mixture};
use crate::error::{Error, Result};
use crate::source::Source;
use crate::spec::LoadedSpec;

/// A mixture as `open` leaves it: the joined source, the sources' audits as one report (mixture
/// ids), and the sources' doctor when it rides on the build's read.
pub(super) type Opened = (Box<dyn Source>, AuditReport, Option<Arc<SourcesDoctor>>);

/// The joined, audited sources of a mixture. `ride`: each source's doctor judges what the build
/// reads (returned, still to judge) instead of reading the source in a pass of its own.
pub(super) fn open(spec: &LoadedSpec, ride: bool) -> Result<Opened> {
    let mut opened = Vec::new();
    for view in spec.source_views() {
        let audited = audit(&view.spec, !ride)?;
        opened.push((view, audited));
    }
    let offsets = id_offsets(opened.iter().map(|(_, a)| a.source.manifest()));
    let applied = spec.spec.audit.repair;
    let mut parts = Vec::new();
    let mut reports = Vec::new();
    let mut doctors = Vec::new();
    for ((view, audited), id_offset) in opened.into_iter().zip(offsets) {
        let source_split = audited.source.manifest().source_split.clone();
        let report = audited.report;
        let source = Audited::new(audited.source, &report, audited.repairs, applied);
        if source.manifest().episodes.is_empty() {
            return Err(Error::source(format!(
                "sources.{} ({}): the audit excluded every episode; see `chunkc audit`, or relax `[audit]`",
                view.name,
                view.spec.source().path
            )));
        }
        if ride {
            let probe = Probe::of(&view.spec, source.manifest());
            let name = |c: usize| source.manifest().channels[c].name.clone();
            let channels =
                (probe.as_ref()).map(|p| (name(p.action_channel()), p.state_channel().map(name)));
            doctors.push((
                SourceDoctor {
                    probe,
                    fps: source.manifest().fps,
                    view: view.clone(),
                    id_offset,
                    report: report.clone(),
                    stored: None,
                },
                channels,
            ));
        }
        reports.push((view.name.clone(), id_offset, report));
        parts.push(Part {
            view,
            source: Box::new(source),
            id_offset,
            source_split,
        });
    }
    let fps = rate(spec, &parts)?;
    let mut mixture = Mixture::new(spec, parts, fps)?;
    for warning in &mixture.manifest().warnings {
        eprintln!("warning: {warning}");
    }
    let doctors = stored_channels(doctors, &mixture);
    let doctor = (ride && doctors.iter().any(|d| d.probe.is_some()))
        .then(|| Arc::new(SourcesDoctor::new(doctors, mixture.manifest())));
    if let Some(d) = &doctor {
        mixture.ride(Arc::clone(d));
    }
    Ok((Box::new(mixture), joined_report(reports), doctor))
}

/// A probe's action channel and state channel, by name.
type ProbeChannels = (String, Option<String>);

/// Each source's doctor, told where the build stores its probe's channels when the mixture's
/// rate keeps the source's steps (`channels`: the probe's action and state channel names).
fn stored_channels(
    doctors: Vec<(SourceDoctor, Option<ProbeChannels>)>,
    mixture: &Mixture,
) -> Vec<SourceDoctor> {
    let at = |name: &str| {
        let channels = &mixture.manifest().channels;
        channels.iter().position(|c| c.name == name)
    };
    let keeps = mixture.keeps_steps();
    (doctors.into_iter().zip(keeps))
        .map(|((mut doctor, channels), keeps)| {
            doctor.stored = channels.filter(|_| keeps).and_then(|(action, state)| {
                let state = match state {
                    Some(s) => Some(at(&s)?),
                    None => None,
                };
                Some((at(&action)?, state))
            });
            doctor
        })
        .collect()
}

/// The mixture's rate: the fastest profile's `fps`, or the sources' common rate when they share
/// one (a profile without `fps` then runs at it).
fn rate(spec: &LoadedSpec, parts: &[Part]) -> Result<f64> {
    let rates: Vec<f64> = parts.iter().map(|p| p.source.manifest().fps).collect();
    let common = rates.iter().all(|&r| r == rates[0]).then_some(rates[0]);
    let given = spec.profiles.iter().filter_map(|p| p.fps);
    let fastest = given.fold(None, |m: Option<f64>, f| Some(m.map_or(f, |m| m.max(f))));
    let Some(unset) = spec.profiles.iter().find(|p| p.fps.is_none()) else {
        return Ok(fastest.unwrap_or(rates[0]));
    };
    if let Some(common) = common {
        return Ok(common);
    }
    let each: Vec<String> = parts
        .iter()
        .zip(&rates)
        .map(|(p, r)| format!("{r} Hz ({})", p.view.name))
        .collect();
    let name = &unset.name;
    Err(spec.error_at(
        &["profiles", name, "fps"],
        format!(
            "profile `{name}` has no `fps`, and the mixture's sources run at {}",
            each.join(", ")
        ),
        Some(format!(
            "set `profiles.{name}.fps`: every source is converted to it"
        )),
    ))
}
