//! The audits of a mixture's sources joined into one report, in mixture ids: each source's
//! episodes and videos with its id offset, its warnings prefixed with `sources.<name>`, the
//! repaired and excluded fractions over the union.

use super::{AuditReport, Verdict};

/// The audits of a mixture's sources as one report, with mixture ids: `reports` are each
/// source's name, id offset and audit, in order. Rates, thresholds and the histogram are the
/// first source's (each source's own report says more); warnings name their source.
pub fn joined_report(reports: Vec<(String, u64, AuditReport)>) -> AuditReport {
    let mut joined = reports[0].2.clone();
    joined.episodes.clear();
    joined.video.clear();
    joined.warnings.clear();
    joined.examples.clear();
    joined.doctor = None;
    joined.doctor_seconds = None;
    for (name, offset, report) in reports {
        joined.timestamps |= report.timestamps;
        for mut e in report.episodes {
            e.id += offset;
            joined.episodes.push(e);
        }
        for mut v in report.video {
            v.episode += offset;
            joined.video.push(v);
        }
        let warnings = report
            .warnings
            .iter()
            .map(|w| format!("sources.{name}: {w}"));
        joined.warnings.extend(warnings);
        if let Some(s) = report.doctor_seconds {
            joined.doctor_seconds = Some(joined.doctor_seconds.unwrap_or(0.0) + s);
        }
    }
    let n = joined.episodes.len().max(1) as f64;
    let count = |f: fn(&Verdict) -> bool| {
        joined.episodes.iter().filter(|e| f(&e.verdict)).count() as f64 / n
    };
    joined.repaired_fraction = count(|v| matches!(v, Verdict::Interpolate | Verdict::Resample));
    joined.excluded_fraction = count(|v| *v == Verdict::Exclude);
    joined
}
