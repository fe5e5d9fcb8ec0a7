// Long file: the judgement of every check over the episodes' features, one function per check, and the findings put into the report.
//! The judgement: every check over all episodes' [`Features`], in source order, so the result
//! does not depend on how (or in which pass) the features were computed. One function per
//! check; the dataset-wide references they share (the units scale, the step sigmas) are
//! computed once and passed in.

use std::collections::{BTreeMap, BTreeSet};

use super::features::Features;
use super::found::Found;
use super::judge_signal::signal_checks;
use super::{alignment, convention, duplicates, shift, short, signal, stats, warnings};
use super::{DoctorSummary, ShiftDim, MISALIGNED_GAIN, STUCK_UNCHANGED};
use crate::audit::report::{AuditReport, Flag, Verdict};
use crate::error::{Error, Result};
use crate::spec::{DoctorAction, DoctorSpec, LoadedSpec};

/// What the judgement needs besides the features.
pub struct Context<'a> {
    pub spec: &'a LoadedSpec,
    /// The source's rate (the `short` check converts lengths to each profile's rate).
    pub fps: f64,
    /// The episodes' ids, in the order of the features.
    pub ids: &'a [u64],
    pub a_dim: usize,
    pub s_dim: usize,
    pub has_state: bool,
}

/// Episodes flagged, per flag name.
type Flagged = BTreeMap<String, u64>;

/// Judges `feats` and puts the flags, findings, verdicts, warnings and summary into `report`
/// (episodes matched by id). Returns the ids the doctor excludes (`= "exclude"`), with why;
/// an `= "error"` finding is the error.
pub fn judge(
    cx: &Context,
    feats: &[Features],
    report: &mut AuditReport,
) -> Result<Vec<(u64, String)>> {
    let cfg = &cx.spec.spec.audit.doctor;
    let mut found = Found(vec![Vec::new(); feats.len()]);
    let judged = units_and_alignment(cfg, feats, &mut found);
    let scale = units_scale(cfg, &judged);
    let motion_scale = signal_checks(cfg, feats, &scale, cx.a_dim, &mut found);
    let constant = constant_dims(feats, cx.a_dim, cx.s_dim);
    let stuck = stuck_dims(cfg, feats, &constant, cx.a_dim, cx.s_dim);
    let pairs = duplicate_pairs(cfg, feats, cx, &mut found);
    short_episodes(cx, feats, &mut found);
    let shifts = shifts(feats, cx.a_dim, cx.s_dim);
    let groups = warnings::flag_groups(cx.ids, &found.0);
    let (flagged, excluded) = into_report(cx, found, report)?;
    let inputs = warnings::Inputs {
        spec: cx.spec,
        episodes: feats.len(),
        groups: &groups,
        constant: &constant,
        stuck: &stuck,
        shifts: &shifts,
        lag_mode: judged.mode,
    };
    warnings::warnings(&inputs, report);
    let mut conventions: BTreeMap<String, u64> = BTreeMap::new();
    for (c, l) in judged.conventions.iter().zip(&judged.lags) {
        if l.is_some() {
            *conventions
                .entry(c.map_or("unclear", |c| c.name()).to_string())
                .or_insert(0) += 1;
        }
    }
    let mut lag_histogram = BTreeMap::new();
    for l in judged.lags.iter().flatten() {
        *lag_histogram.entry(l.lag).or_insert(0) += 1;
    }
    report.doctor = Some(DoctorSummary {
        action_channel: "action".into(),
        state_channel: cx.has_state.then(|| "observation.state".into()),
        flagged,
        tracked_dims: judged.tracked.clone(),
        lag_histogram,
        lag_mode: judged.mode,
        lag_curve: judged.curve.clone(),
        convention: judged.majority.map(|c| c.name().to_string()),
        conventions,
        units: cx
            .ids
            .iter()
            .copied()
            .zip(judged.units.iter().copied())
            .collect(),
        motion_scale,
        constant,
        stuck,
        shift: shifts,
        duplicates: pairs
            .iter()
            .map(|&(a, b, r)| (cx.ids[a], cx.ids[b], r))
            .collect(),
        units_ratio: cfg.units_ratio,
        shift_threshold: cfg.shift_threshold,
    });
    Ok(excluded)
}

/// Convention and units first (the other checks are measured in the episode's own units), then
/// misalignment against the dataset's lag.
fn units_and_alignment(
    cfg: &DoctorSpec,
    feats: &[Features],
    found: &mut Found,
) -> convention::Judged {
    let fits: Vec<&[Option<alignment::DimFits>]> = feats.iter().map(|f| &f.fits[..]).collect();
    let stds: Vec<Vec<f64>> = feats
        .iter()
        .map(|f| f.action.iter().map(|m| f64::from(m.std)).collect())
        .collect();
    let rms: Vec<Vec<f64>> = feats
        .iter()
        .map(|f| {
            f.action
                .iter()
                .map(|m| {
                    let s = f64::from(m.std);
                    (m.mean * m.mean + s * s).sqrt()
                })
                .collect()
        })
        .collect();
    let judged = convention::judge(&fits, &rms, &stds, cfg.units_ratio);
    for e in 0..feats.len() {
        let u = judged.units[e];
        if judged.units_judged[e] && (u > cfg.units_ratio || u < 1.0 / cfg.units_ratio) {
            found.add(
                e,
                Flag::Units,
                cfg.units,
                format!(
                    "the actions look {u:.3}× the dataset's units (degrees for radians, mm for m?)"
                ),
                &[("factor", u)],
            );
        }
        if let (Some(l), Some(major)) = (&judged.lags[e], judged.majority) {
            if let Some(c) = judged.conventions[e] {
                if c != major {
                    found.add(e, Flag::MixedConvention, cfg.mixed_convention, format!(
                        "the actions behave as {} targets (score {:.2}: |corr(action, next state)| - |corr(action, state change)|) where the dataset's are {}",
                        c.name(), l.score, major.name()), &[("score", l.score)]);
                }
            }
        }
        if let (Some(l), Some(mode)) = (&judged.lags[e], judged.mode) {
            let at_mode = l.unexplained[(mode - alignment::lag_of(0)) as usize];
            // The mode must explain clearly less: neighbouring lags of a noisy fit are close.
            if l.lag.abs_diff(mode) > cfg.lag_tolerance
                && at_mode >= MISALIGNED_GAIN * l.unexplained[l.best]
            {
                found.add(e, Flag::Misaligned, cfg.misaligned, format!(
                    "the action best predicts the state {} steps later (R² {:.3}), the dataset's mode is {mode} (R² {:.3} here): actions shifted by {} steps",
                    l.lag, 1.0 - l.unexplained[l.best], 1.0 - at_mode, l.lag - mode),
                    &[("lag", f64::from(l.lag)), ("mode", f64::from(mode)), ("r2", 1.0 - l.unexplained[l.best]), ("r2_at_mode", 1.0 - at_mode)]);
            }
        }
    }
    judged
}

/// An episode in other units is measured in the dataset's; any other is taken as it is (a
/// factor near 1 is the fit's noise, and spikes themselves pull the gain it is fitted from).
fn units_scale(cfg: &DoctorSpec, judged: &convention::Judged) -> Vec<f64> {
    (0..judged.units.len())
        .map(|e| {
            let u = judged.units[e];
            let other =
                judged.units_judged[e] && (u > cfg.units_ratio || u < 1.0 / cfg.units_ratio);
            if other {
                u
            } else {
                1.0
            }
        })
        .collect()
}

/// `channel[dim]` constant over the whole dataset, with its value.
fn constant_dims(feats: &[Features], a_dim: usize, s_dim: usize) -> Vec<(String, usize, f64)> {
    let mut constant = Vec::new();
    for d in 0..a_dim {
        let (lo, hi) = stats::range(
            feats
                .iter()
                .map(|f| (f64::from(f.signal[d].min), f64::from(f.signal[d].max))),
        );
        if lo == hi {
            constant.push(("action".to_string(), d, lo));
        }
    }
    for d in 0..s_dim {
        let (lo, hi) = stats::range(
            feats
                .iter()
                .map(|f| (f64::from(f.state[d].lo), f64::from(f.state[d].hi))),
        );
        if lo == hi {
            constant.push(("observation.state".to_string(), d, lo));
        }
    }
    constant
}

/// Stuck: not constant, but holding one value for most of most episodes, or unchanged from
/// step to step in STUCK_UNCHANGED of them (an unused or stuck degree of freedom; per-episode
/// `frozen` leaves these dimensions alone).
fn stuck_dims(
    cfg: &DoctorSpec,
    feats: &[Features],
    constant: &[(String, usize, f64)],
    a_dim: usize,
    s_dim: usize,
) -> Vec<(String, usize, f64)> {
    let episodes = feats.len();
    let mut stuck = Vec::new();
    for (channel, width) in [("action", a_dim), ("observation.state", s_dim)] {
        for d in 0..width {
            if constant.iter().any(|(c, k, _)| c == channel && *k == d) {
                continue;
            }
            let held = feats
                .iter()
                .filter(|f| {
                    let (run, unchanged) = if channel == "action" {
                        (f.signal[d].run.len, f.signal[d].unchanged)
                    } else {
                        (f.state[d].run, f.state[d].unchanged)
                    };
                    let unchanged = signal::unchanged_share(unchanged, f.n);
                    f.n >= 10
                        && (f64::from(run) >= cfg.frozen_fraction * f.n as f64
                            || unchanged >= STUCK_UNCHANGED)
                })
                .count();
            if 2 * held >= episodes {
                stuck.push((channel.to_string(), d, held as f64 / episodes as f64));
            }
        }
    }
    stuck
}

/// Near-duplicate pairs (positions), each later episode flagged.
fn duplicate_pairs(
    cfg: &DoctorSpec,
    feats: &[Features],
    cx: &Context,
    found: &mut Found,
) -> Vec<(usize, usize, f64)> {
    // One over each dimension's typical spread.
    let scale: Vec<f64> = (0..cx.a_dim)
        .map(|d| stats::median(feats.iter().map(|f| f64::from(f.action[d].std))))
        .map(|s| if s > 0.0 { 1.0 / s } else { 1.0 })
        .collect();
    let sigs: Vec<&[f32]> = feats.iter().map(|f| &f.signature[..]).collect();
    let lengths: Vec<usize> = feats.iter().map(|f| f.n).collect();
    let pairs = duplicates::pairs(&sigs, &scale, &lengths, cfg.duplicate_tolerance);
    for &(early, late, rms) in &pairs {
        found.add(
            late,
            Flag::Duplicate,
            cfg.duplicate,
            format!(
                "a near-copy of episode {} (RMS difference {rms:.2e} of the actions' spread)",
                cx.ids[early]
            ),
            &[("of", cx.ids[early] as f64), ("rms", rms)],
        );
    }
    pairs
}

/// Episodes shorter than a profile's chunk at its rate.
fn short_episodes(cx: &Context, feats: &[Features], found: &mut Found) {
    let cfg = &cx.spec.spec.audit.doctor;
    for (e, f) in feats.iter().enumerate() {
        let mut why = Vec::new();
        let mut evidence = Vec::new();
        for p in &cx.spec.profiles {
            let steps = short::steps_at(f.n, cx.fps, p);
            if steps < p.chunk as usize {
                why.push(format!(
                    "{} steps at profile `{}`'s rate, under its chunk of {}: {}",
                    steps,
                    p.name,
                    p.chunk,
                    short::consequence(p.padding, steps, p.chunk)
                ));
                evidence.push((format!("{}.steps", p.name), steps as f64));
                evidence.push((format!("{}.chunk", p.name), f64::from(p.chunk)));
            }
        }
        if !why.is_empty() {
            let ev: Vec<(&str, f64)> = evidence.iter().map(|(k, v)| (k.as_str(), *v)).collect();
            found.add(e, Flag::Short, cfg.short, why.join("; "), &ev);
        }
    }
}

/// Every dimension's quarters (recording order) as robust deviations.
fn shifts(feats: &[Features], a_dim: usize, s_dim: usize) -> Vec<ShiftDim> {
    let mut out = Vec::new();
    for (channel, width) in [("action", a_dim), ("observation.state", s_dim)] {
        for d in 0..width {
            let m: Vec<f64> = feats
                .iter()
                .map(|f| {
                    if channel == "action" {
                        f.action[d].mean
                    } else {
                        f.state[d].mean
                    }
                })
                .collect();
            if let Some(dev) = shift::deviations(&m) {
                out.push(ShiftDim {
                    channel: channel.into(),
                    dim: d,
                    deviations: dev,
                });
            }
        }
    }
    out
}

/// The findings into the report's episodes (one per flag: the first, lowest dimension), their
/// verdicts, and the flag counts; the ids excluded, with why. An `= "error"` finding (the first
/// in source order) is the error.
fn into_report(
    cx: &Context,
    found: Found,
    report: &mut AuditReport,
) -> Result<(Flagged, Vec<(u64, String)>)> {
    let position: BTreeMap<u64, usize> = report
        .episodes
        .iter()
        .enumerate()
        .map(|(k, e)| (e.id, k))
        .collect();
    let mut flagged: BTreeMap<String, u64> = BTreeMap::new();
    let mut excluded = Vec::new();
    let mut error = None;
    for (e, mut list) in found.0.into_iter().enumerate() {
        let mut seen = BTreeSet::new();
        list.retain(|f| seen.insert(f.flag));
        let Some(&k) = position.get(&cx.ids[e]) else {
            continue;
        };
        let audit = &mut report.episodes[k];
        for f in &list {
            *flagged.entry(f.flag.name().to_string()).or_insert(0) += 1;
            if !audit.flags.contains(&f.flag) {
                audit.flags.push(f.flag);
            }
            let sentence = format!("{}: {}", f.flag.name(), f.detail);
            audit.detail = if audit.detail.is_empty() {
                sentence
            } else {
                format!("{}; {sentence}", audit.detail)
            };
            match f.action {
                DoctorAction::Warn => {}
                DoctorAction::Exclude => {
                    if audit.verdict != Verdict::Exclude {
                        excluded.push((audit.id, String::new()));
                    }
                    audit.verdict = Verdict::Exclude;
                    audit.repaired_frames = 0;
                }
                DoctorAction::Error => {
                    error.get_or_insert_with(|| {
                        format!(
                            "{}: episode {}: {}: {} (`[audit.doctor] {} = \"error\"`)",
                            cx.spec.source().path,
                            audit.id,
                            f.flag.name(),
                            f.detail,
                            f.flag.name()
                        )
                    });
                }
            }
        }
        // The reason names only what excluded it, not every finding of the episode.
        let causes: Vec<String> = list
            .iter()
            .filter(|f| f.action == DoctorAction::Exclude)
            .map(|f| format!("{}: {}", f.flag.name(), f.detail))
            .collect();
        audit.findings = list;
        if let Some(last) = excluded.last_mut().filter(|x| x.0 == audit.id) {
            last.1 = format!("dataset doctor: {}", causes.join("; "));
        }
    }
    if let Some(message) = error {
        return Err(Error::source(message));
    }
    report.excluded_fraction = report
        .episodes
        .iter()
        .filter(|e| e.verdict == Verdict::Exclude)
        .count() as f64
        / report.episodes.len().max(1) as f64;
    Ok((flagged, excluded))
}
