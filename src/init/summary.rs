//! The summary `chunkc inspect` prints (and `chunkc init` before it writes the spec).

use std::fmt::Write;

use super::text::{format_name, number, shape};
use super::Inspection;

/// What `chunkc inspect` (and `init`, before it writes) prints.
// Long function: one line per finding, in the order a reader checks them.
pub fn summary(ins: &Inspection) -> String {
    let mut t = String::new();
    let w = &mut t;
    let _ = writeln!(w, "{}", ins.path.display());
    let _ = writeln!(
        w,
        "  format    {} ({})",
        format_name(ins.format),
        ins.evidence
    );
    let _ = writeln!(
        w,
        "  rate      {} Hz, {}",
        number(ins.rate.fps),
        ins.rate.origin
    );
    let _ = writeln!(
        w,
        "  episodes  {} ({} steps, {}..{} per episode)",
        ins.episodes, ins.steps, ins.shortest, ins.longest
    );
    if ins.tasks > 0 {
        let _ = writeln!(w, "  tasks     {} distinct (language)", ins.tasks);
    }
    let _ = writeln!(w, "  keys ({}):", ins.listed_from);
    let width = ins.keys.iter().map(|k| k.key.len()).max().unwrap_or(0);
    let shapes: Vec<String> = ins.keys.iter().map(|k| shape(&k.shape)).collect();
    let sw = shapes.iter().map(String::len).max().unwrap_or(0);
    for (k, s) in ins.keys.iter().zip(&shapes) {
        // The names are the spec's: a mapped channel, or the commented line's.
        let to = match (&k.channel, k.columns, &k.suggested) {
            (Some(c), Some([a, b]), _) => format!("-> {c} (columns {a}..{b})"),
            (Some(c), None, _) => format!("-> {c}"),
            (None, _, Some(s)) => format!("-> {s} (commented out)"),
            (None, _, None) => String::new(),
        };
        let note = k
            .note
            .as_ref()
            .map(|n| format!("  [{n}]"))
            .unwrap_or_default();
        let line = format!(
            "    {:width$}  {s:sw$}  {:8}  {:12} {to}{note}",
            k.key,
            k.dtype,
            k.role.word()
        );
        let _ = writeln!(w, "{}", line.trim_end());
    }
    let timing = &ins.timing;
    if timing.timestamps {
        let _ = writeln!(
            w,
            "  timing    {} ok, {} interpolate, {} resample, {} exclude",
            timing.ok, timing.interpolate, timing.resample, timing.exclude
        );
    } else {
        let _ = writeln!(w, "  timing    no timestamps stored");
    }
    if let Some(a) = &ins.acf {
        match a.suggested_k {
            Some(k) => {
                let _ = writeln!(
                    w,
                    "  chunk     the action's ACF falls below {} at lag {k} ({:.2} s)",
                    a.threshold,
                    k as f64 / ins.rate.fps
                );
            }
            None => {
                let _ = writeln!(
                    w,
                    "  chunk     the action's ACF stays above {} up to lag {}",
                    a.threshold, a.max_lag
                );
            }
        }
    }
    for p in &ins.profiles {
        let fps = p
            .fps
            .map(|f| format!(" @ {} Hz", number(f)))
            .unwrap_or_default();
        let _ = writeln!(
            w,
            "  profile   {}: {}{fps}, K = {}{}",
            p.name,
            p.preset,
            p.chunk,
            p.format
                .as_ref()
                .map(|f| format!(", {f}"))
                .unwrap_or_default()
        );
    }
    let mut warnings: Vec<&String> = ins.warnings.iter().chain(&timing.warnings).collect();
    warnings.sort();
    warnings.dedup();
    for warning in warnings {
        let _ = writeln!(w, "  warning   {warning}");
    }
    t
}
