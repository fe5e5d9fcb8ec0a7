// Long file: the judgement of every check over the episodes' features, one function per check, and the findings put into the report.
//! The judgement: every check over all episodes' [`Features`], in source order, so the result
//! does not depend on how (or in which pass) the features were computed. One function per
//! check; the dataset-wide references they share (the units scale, the step sigmas) are
//! computed once and passed in.

use std::collections::{BTreeMap, BTreeSet};

use super::features::Features;
use super::{alignment, convention, duplicates, shift, short, signal, stats};
use super::{DoctorSummary, Finding, ShiftDim, MISALIGNED_GAIN, STUCK_UNCHANGED};
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

/// The findings being gathered, per episode (in the features' order).
struct Found(Vec<Vec<Finding>>);

impl Found {
    fn add(
        &mut self,
        e: usize,
        flag: Flag,
        action: DoctorAction,
        detail: String,
        ev: &[(&str, f64)],
    ) {
        self.0[e].push(Finding {
            flag,
            action,
            detail,
            evidence: ev.iter().map(|(k, v)| (k.to_string(), *v)).collect(),
        });
    }
}

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
    let step_sigma = signal_checks(cfg, feats, &scale, cx.a_dim, &mut found);
    let constant = constant_dims(feats, cx.a_dim, cx.s_dim);
    let stuck = stuck_dims(cfg, feats, &constant, cx.a_dim, cx.s_dim);
    let pairs = duplicate_pairs(cfg, feats, cx, &mut found);
    short_episodes(cx, feats, &mut found);
    let shifts = shifts(feats, cx.a_dim, cx.s_dim);
    let (flagged, excluded) = into_report(cx, found, report)?;
    warnings(
        cx,
        report,
        &flagged,
        &constant,
        &stuck,
        &shifts,
        judged.mode,
    );
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
        step_sigma,
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

/// Frozen, clipped and jump, per action dimension against the dataset. Returns the step sigmas
/// (the jump check's reference, per dimension).
// Long function: the three signal checks share the per-dimension references they compute.
fn signal_checks(
    cfg: &DoctorSpec,
    feats: &[Features],
    scale: &[f64],
    a_dim: usize,
    found: &mut Found,
) -> Vec<f64> {
    let episodes = feats.len();
    let step_sigma: Vec<f64> = (0..a_dim)
        .map(|d| {
            stats::median(
                feats
                    .iter()
                    .zip(scale)
                    .map(|(f, u)| f64::from(f.signal[d].step_sigma) / u),
            )
        })
        .collect();
    for (d, &sigma) in step_sigma.iter().enumerate() {
        let long = |f: &Features| {
            f.n >= 10 && f64::from(f.signal[d].run.len) >= cfg.frozen_fraction * f.n as f64
        };
        let static_share = feats.iter().filter(|f| long(f)).count() as f64 / episodes as f64;
        let clip_median = stats::median(feats.iter().map(|f| f.signal[d].clip(f.n).0));
        let (lowest, highest) = range(
            feats
                .iter()
                .map(|f| (f64::from(f.signal[d].min), f64::from(f.signal[d].max))),
        );
        for (e, f) in feats.iter().enumerate() {
            let sig = &f.signal[d];
            let clip = sig.clip(f.n);
            let value = f64::from(sig.run.value);
            let at_limit = value == lowest || value == highest;
            if long(f) && static_share < 0.5 && !at_limit {
                let (len, from) = (sig.run.len, sig.run.start);
                found.add(e, Flag::Frozen, cfg.frozen, format!(
                    "action[{d}] holds {value} for {len} of {} steps from step {from}, where it moves in most episodes", f.n),
                    &[("dim", d as f64), ("steps", len as f64), ("from", from as f64), ("value", value)]);
            } else if clip.0 >= cfg.clip_fraction
                && clip_median < cfg.clip_fraction
                && !long(f)
                && clip.1 != lowest
                && clip.1 != highest
            {
                let (share, bound, side) = clip;
                found.add(
                    e,
                    Flag::Clipped,
                    cfg.clipped,
                    format!(
                        "action[{d}] sits at its {side} {bound} for {:.0}% of the steps",
                        100.0 * share
                    ),
                    &[("dim", d as f64), ("share", share), ("bound", bound)],
                );
            }
            if sigma > 0.0 {
                let (size, step) = (f64::from(sig.spikes[0].size), sig.spikes[0].step);
                // Against the episode's own step changes (the fault is "k of its own robust
                // std"), never below half the dataset's: a dimension that holds still in this
                // episode does not turn its sensor noise into spikes.
                let own = (f64::from(sig.step_sigma) / scale[e]).max(0.5 * sigma);
                let z = size / scale[e] / own;
                if z > cfg.jump_threshold {
                    let count = sig
                        .spikes
                        .iter()
                        .filter(|s| f64::from(s.size) / scale[e] / own > cfg.jump_threshold)
                        .count();
                    found.add(e, Flag::Jump, cfg.jump, format!(
                        "action[{d}] spikes at step {step} by {z:.1} robust std of its step changes ({count} such steps)"),
                        &[("dim", d as f64), ("step", f64::from(step)), ("z", z)]);
                }
            }
        }
    }
    step_sigma
}

/// The lowest and highest of `(min, max)` pairs.
fn range(pairs: impl Iterator<Item = (f64, f64)>) -> (f64, f64) {
    pairs.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (a, b)| {
        (lo.min(a), hi.max(b))
    })
}

/// `channel[dim]` constant over the whole dataset, with its value.
fn constant_dims(feats: &[Features], a_dim: usize, s_dim: usize) -> Vec<(String, usize, f64)> {
    let mut constant = Vec::new();
    for d in 0..a_dim {
        let (lo, hi) = range(
            feats
                .iter()
                .map(|f| (f64::from(f.signal[d].min), f64::from(f.signal[d].max))),
        );
        if lo == hi {
            constant.push(("action".to_string(), d, lo));
        }
    }
    for d in 0..s_dim {
        let (lo, hi) = range(
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
                            cx.spec.spec.source.path,
                            audit.id,
                            f.flag.name(),
                            f.detail,
                            f.flag.name()
                        )
                    });
                }
            }
        }
        audit.findings = list;
        if let Some(last) = excluded.last_mut().filter(|x| x.0 == audit.id) {
            last.1 = format!("audit: {}", audit.detail);
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

/// The dataset-wide warnings: flag counts, constant and stuck dimensions, shift, the lag.
// Long function: one paragraph per warning, in the order `chunkc audit` prints them.
fn warnings(
    cx: &Context,
    report: &mut AuditReport,
    flagged: &BTreeMap<String, u64>,
    constant: &[(String, usize, f64)],
    stuck: &[(String, usize, f64)],
    shifts: &[ShiftDim],
    lag_mode: Option<i32>,
) {
    let cfg = &cx.spec.spec.audit.doctor;
    if !flagged.is_empty() {
        let counts: Vec<String> = flagged.iter().map(|(k, v)| format!("{k} {v}")).collect();
        report.warnings.push(format!(
            "the dataset doctor flagged episodes: {}",
            counts.join(", ")
        ));
    }
    for (channel, d, v) in constant {
        let mut affected = Vec::new();
        for p in &cx.spec.profiles {
            let mode = p
                .normalize
                .get(channel)
                .copied()
                .unwrap_or(p.normalize_lowdim);
            affected.push(format!("`{}` ({mode:?})", p.name));
        }
        report.warnings.push(format!(
            "`{channel}[{d}]` is constant ({v}) over the whole dataset: its std and range are 0, so z-score and min-max normalization divide by the floor; profiles {}",
            affected.join(", ")
        ));
    }
    for (channel, d, share) in stuck {
        report.warnings.push(format!(
            "`{channel}[{d}]` holds still (one value for {:.0}% of the steps, or unchanged in {:.0}% of them) in {:.0}% of the episodes: an unused or stuck degree of freedom",
            100.0 * cfg.frozen_fraction,
            100.0 * STUCK_UNCHANGED,
            100.0 * share
        ));
    }
    for channel in ["action", "observation.state"] {
        let mut dims = Vec::new();
        let mut worst: Option<(usize, usize, f64)> = None;
        for s in shifts.iter().filter(|s| s.channel == channel) {
            let Some((q, &dev)) = s
                .deviations
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            else {
                continue;
            };
            if dev.abs() > cfg.shift_threshold {
                dims.push(s.dim.to_string());
                if worst.is_none_or(|w| dev.abs() > w.2.abs()) {
                    worst = Some((s.dim, q, dev));
                }
            }
        }
        if let Some((d, q, dev)) = worst {
            report.warnings.push(format!(
                "distribution shift across the recording in `{channel}` dimensions {}: the largest, `{channel}[{d}]`, has its quarter {} of the episodes (recording order) {dev:+.2} robust std from the dataset's median",
                dims.join(", "),
                q + 1
            ));
        }
    }
    if let Some(mode) = lag_mode {
        if mode.abs_diff(1) > cfg.lag_tolerance {
            let names: Vec<String> = cx
                .spec
                .profiles
                .iter()
                .map(|p| format!("`{}` ({})", p.name, p.alignment.name()))
                .collect();
            report.warnings.push(format!(
                "the actions first show in the state {mode} steps later (the dataset's mode), where the profiles' alignment ({}) assumes the action of step t is executed from the observation of step t and shows at t + 1",
                names.join(", ")));
        }
    }
}
