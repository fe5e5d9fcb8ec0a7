//! `chunkc plan` as text: what will be built, from what, and whether it must run.

use std::fmt::Write;

use super::Plan;

pub(super) fn human_bytes(n: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = n as f64;
    let mut u = 0;
    while v >= 1024.0 && u < UNITS.len() - 1 {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{n} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

/// A training mixture's sources, one line each: rate, weight, widths and id offset.
fn mixture_lines(s: &mut String, plan: &Plan) {
    let Some(mixture) = &plan.mixture else {
        return;
    };
    let _ = writeln!(
        s,
        "mixture balance {}, statistics {}, {} sources at {} Hz",
        mixture.balance.name(),
        mixture.stats.name(),
        plan.source.parts.len(),
        plan.source.fps
    );
    for part in &plan.source.parts {
        let widths: Vec<String> = plan
            .source
            .channels
            .iter()
            .zip(&part.widths)
            .map(|(ch, w)| format!("{} {w}", ch.name))
            .collect();
        let _ = writeln!(
            s,
            "        {}: {} {} at {} Hz, weight {}, ids from {}; widths: {}",
            part.name,
            part.format.name(),
            part.path,
            part.fps,
            part.weight,
            part.id_offset,
            widths.join(", ")
        );
    }
}

// Long function: one section per part of the plan, printed in order.
pub fn render_text(plan: &Plan) -> String {
    let mut s = String::new();
    let src = &plan.source;
    let _ = writeln!(
        s,
        "source  {} {} ({} episodes, {} steps, {} Hz)",
        src.format, src.path, src.episodes, src.steps, src.fps
    );
    let fingerprint = src
        .fingerprint
        .hash()
        .unwrap_or_else(|e| format!("(unreadable: {e})"));
    let _ = writeln!(
        s,
        "        fingerprint {}",
        fingerprint.get(..16).unwrap_or(&fingerprint)
    );
    mixture_lines(&mut s, plan);
    for ch in &src.channels {
        let _ = writeln!(
            s,
            "        {:<24} <- {:<12} {:?} {} ({})",
            ch.name,
            ch.key,
            ch.shape,
            ch.source_dtype,
            match ch.kind {
                crate::source::ChannelKind::Lowdim => "lowdim",
                crate::source::ChannelKind::Image => "image",
            }
        );
    }
    let _ = writeln!(
        s,
        "split   {} train / {} val episodes",
        plan.split.train.len(),
        plan.split.val.len()
    );
    let a = &plan.audit;
    let verdicts: Vec<String> = ["ok", "interpolate", "resample", "exclude"]
        .iter()
        .map(|v| format!("{} {}", a.verdicts.get(v).copied().unwrap_or(0), v))
        .collect();
    let _ = writeln!(
        s,
        "audit   {} s steps{}: {}{}",
        // Rounded: 1/30 Hz is `0.0333`, not `0.03333333333333333`.
        format!("{:.4}", a.expected_interval)
            .trim_end_matches('0')
            .trim_end_matches('.'),
        if a.timestamps {
            ""
        } else {
            " (declared, no timestamps)"
        },
        verdicts.join(", "),
        if a.applied {
            ""
        } else {
            " (not applied: `[audit] repair = false`)"
        }
    );
    for w in &a.warnings {
        let _ = writeln!(s, "        warning: {w}");
    }
    let _ = writeln!(s, "read    the source once, for all profiles");
    for r in &plan.rates {
        let _ = writeln!(
            s,
            "rate    {} Hz ({}, {} steps) for {}",
            r.fps,
            match r.conversion {
                super::Conversion::Decimate { factor } => format!("every {factor} step(s)"),
                super::Conversion::Resample { method, .. } => format!(
                    "resampled, {}",
                    match method {
                        crate::spec::ResampleMethod::Fourier => "fourier",
                        crate::spec::ResampleMethod::Linear => "linear",
                    }
                ),
            },
            r.steps,
            r.profiles.join(", ")
        );
        for (camera, [h, w]) in &r.cameras {
            let _ = writeln!(s, "        {camera} stored at {h}x{w}");
        }
    }
    for st in &plan.statistics {
        let size = st
            .size
            .map_or(String::new(), |[h, w]| format!(" ({h}x{w})"));
        let _ = writeln!(
            s,
            "stats   {}{size} @ {} Hz on {} for {}",
            st.channel,
            st.fps,
            st.split,
            st.profiles.join(", ")
        );
    }
    for p in &plan.profiles {
        let v = &p.values;
        let _ = writeln!(s);
        let state = match p.status.reason() {
            None => "up to date".to_string(),
            Some(reason) => format!("build: {reason}"),
        };
        let _ = writeln!(s, "profile {}  [{}]", p.name, state);
        let _ = writeln!(s, "  rate   {}", p.rate);
        for r in p.resolved_values() {
            let _ = writeln!(s, "  {} {} ({})", r.key, r.value, r.origin);
        }
        if let Some(e) = &v.extends {
            let _ = writeln!(s, "  extends {e}");
        }
        for t in &p.transforms {
            let _ = writeln!(s, "  transform {}", t.summary());
        }
        if v.stats_population == crate::spec::StatsPopulation::Windows {
            let _ = writeln!(
                s,
                "  statistics over windows: every training sample's {} action rows",
                p.window().chunk
            );
        }
        for ch in &p.channels {
            let _ = writeln!(s, "  normalize {:<24} {}", ch.name, ch.normalize.name());
        }
        for (k, m) in p.groot.iter().enumerate() {
            let at = match plan.source.parts.get(k) {
                Some(part) if p.groot.len() > 1 => format!(" (sources/{})", part.name),
                _ => String::new(),
            };
            let _ = writeln!(s, "  groot modality{at}: {}", m.summary());
        }
        for (ch, r) in p.channels.iter().filter_map(|c| Some((c, c.resize?))) {
            let [[fh, fw], [sh, sw], [h, w]] = [r.from, r.scaled, r.size];
            let _ = writeln!(
                s,
                "  camera {:<27} {fh}x{fw} -> {h}x{w} ({} to {sh}x{sw}, centre crop)",
                ch.name, r.method
            );
        }
        let train_eps = p.episodes.iter().filter(|e| e.split == "train").count();
        let _ = writeln!(
            s,
            "  episodes {} used ({} train, {} val), {} excluded; {} steps",
            p.episodes.len(),
            train_eps,
            p.episodes.len() - train_eps,
            p.excluded.len(),
            p.steps
        );
        for e in &p.excluded {
            let _ = writeln!(s, "    excluded episode {}: {}", e.id, e.reason);
        }
        for r in p.repaired.iter().take(10) {
            let _ = writeln!(
                s,
                "    repaired episode {} ({}): {} -> {} steps",
                r.id,
                r.verdict.name(),
                r.recorded_len,
                r.len
            );
        }
        if p.repaired.len() > 10 {
            let _ = writeln!(s, "    … {} more repaired episodes", p.repaired.len() - 10);
        }
        let count = |n: Option<usize>| n.map_or("(set by the data)".to_string(), |n| n.to_string());
        let _ = writeln!(
            s,
            "  samples {} train, {} val ({} sampling)",
            count(p.num_samples.train),
            count(p.num_samples.val),
            p.sampling.name()
        );
        for f in &p.files {
            let _ = writeln!(
                s,
                "  write  {}/{}  {} {}{}",
                p.name,
                f.path,
                if f.bound { "<=" } else { "~" },
                human_bytes(f.estimated_bytes),
                planned_note(f)
            );
        }
        for w in &p.warnings {
            let _ = writeln!(s, "  warning: {w}");
        }
    }
    s
}

/// What `chunkc plan` says after an estimate: its files and how it was made.
fn planned_note(f: &super::PlannedFile) -> String {
    let parts: Vec<String> = f
        .files
        .map(|n| format!("{n} file{}", if n == 1 { "" } else { "s" }))
        .into_iter()
        .chain(f.basis.clone())
        .collect();
    if parts.is_empty() {
        String::new()
    } else {
        format!("  ({})", parts.join("; "))
    }
}

/// The rate line of `chunkc plan`.
pub(super) fn rate_line(source_fps: f64, fps: f64, conv: super::Conversion) -> String {
    match conv {
        super::Conversion::Decimate { factor: 1 } => {
            format!("{fps} Hz (the source rate, no conversion)")
        }
        super::Conversion::Decimate { factor } => {
            format!("{source_fps} Hz -> {fps} Hz: keep 1 step in {factor}")
        }
        super::Conversion::Resample { method, .. } => format!(
            "{source_fps} Hz -> {fps} Hz: resample each episode ({}), n -> round(n × {fps} / {source_fps})",
            match method {
                crate::spec::ResampleMethod::Fourier => "fourier",
                crate::spec::ResampleMethod::Linear => "linear",
            },
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::human_bytes;

    #[test]
    fn bytes() {
        assert_eq!(human_bytes(12), "12 B");
        assert_eq!(human_bytes(2048), "2.0 KiB");
        assert_eq!(human_bytes(3 * 1024 * 1024 + 1), "3.0 MiB");
    }
}
