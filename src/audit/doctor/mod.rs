// Long file: one pass reads the episodes and every check is judged over the same features; each check's own rules live in its file.
//! The dataset doctor: checks of the action and state values that catch what silently ruins a
//! policy (a frozen or clipped actuator, spikes, actions misaligned with the observations or in
//! another convention or units than the rest, duplicated episodes, shift across the recording,
//! episodes shorter than a chunk), run by `chunkc audit` and so before every `build`.
//!
//! One pass reads each episode's action and state channels ([`Source::read_lowdim`]) and reduces
//! it to features, in parallel; the judgement then runs over all features in source order, so the
//! result does not depend on the thread count. Precision first: an episode's convention and units
//! are judged before anything else ([`convention`]), every other check measures against robust
//! dataset-wide references (medians, MADs), and so one fault does not set off another check.
//!
//! - `features`: what one episode reduces to (read once, in parallel).
//! - `stats`: medians, MAD, mode.
//! - `signal`: frozen, clipped, jump (and the constant dimensions).
//! - `alignment`: the per-episode lag fits.
//! - `convention`: tracked dimensions, lag mode, conventions, units.
//! - `duplicates`, `shift`, `short`.

mod alignment;
mod convention;
mod duplicates;
mod features;
mod shift;
mod short;
mod signal;
mod stats;

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::Serialize;

use super::report::{AuditReport, Flag, Verdict};
use super::timing::Repair;
use crate::error::{Error, Result};
use crate::source::{ChannelKind, Source};
use crate::spec::{DoctorAction, LoadedSpec};
use features::{features, hold_finite, Features};
pub use shift::ShiftDim;

/// `misaligned` needs the dataset's lag to leave at least this many times the unexplained share
/// of the episode's own lag.
pub const MISALIGNED_GAIN: f64 = 2.0;

/// A dimension unchanged from step to step in this share of an episode's steps holds still.
pub const STUCK_UNCHANGED: f64 = 0.8;

/// One doctor flag on one episode, with why and its evidence numbers.
#[derive(Debug, Clone, Serialize)]
pub struct Finding {
    pub flag: Flag,
    pub action: DoctorAction,
    pub detail: String,
    pub evidence: BTreeMap<String, f64>,
}

/// The doctor's dataset-wide results, in `audit.json` under `doctor`.
#[derive(Debug, Clone, Serialize)]
pub struct DoctorSummary {
    pub action_channel: String,
    pub state_channel: Option<String>,
    /// Episodes flagged per flag name.
    pub flagged: BTreeMap<String, u64>,
    /// Action dimensions (shared with the state) the alignment checks used.
    pub tracked_dims: Vec<usize>,
    /// Episodes per lag (steps from an action to the state that first shows it).
    pub lag_histogram: BTreeMap<i32, u64>,
    pub lag_mode: Option<i32>,
    /// (lag, mean R² of the state change over the fitted episodes).
    pub lag_curve: Vec<(i32, f64)>,
    /// The majority convention, `absolute` or `delta`.
    pub convention: Option<String>,
    /// Episodes per convention (`absolute`, `delta`, `unclear`).
    pub conventions: BTreeMap<String, u64>,
    /// Per episode in source order: (id, the action's units factor against the dataset).
    pub units: Vec<(u64, f64)>,
    /// Per action dimension, the reference of the jump check (robust std of step changes).
    pub step_sigma: Vec<f64>,
    /// `channel[dim]` constant over the whole dataset, with the value.
    pub constant: Vec<(String, usize, f64)>,
    /// `channel[dim]` holding still in most episodes, with the share of episodes.
    pub stuck: Vec<(String, usize, f64)>,
    /// Every dimension's quarters (in recording order) as robust deviations.
    pub shift: Vec<ShiftDim>,
    /// (earlier id, later id, RMS difference in spreads).
    pub duplicates: Vec<(u64, u64, f64)>,
    /// The thresholds the charts draw (`[audit.doctor]`).
    pub units_ratio: f64,
    pub shift_threshold: f64,
}

/// Runs the checks and adds their flags, findings, verdicts and summary to `report` (and the
/// exclusions to `repairs`). Does nothing when `[audit.doctor] enabled = false` or the source has
/// no low-dimensional `action` channel.
// Long function: the per-check judgement shares the features and the findings being gathered.
pub fn run(
    spec: &LoadedSpec,
    source: &dyn Source,
    report: &mut AuditReport,
    repairs: &mut [Repair],
) -> Result<()> {
    let cfg = &spec.spec.audit.doctor;
    let manifest = source.manifest();
    let lowdim = |name: &str| {
        manifest
            .channels
            .iter()
            .position(|c| c.name == name && c.kind == ChannelKind::Lowdim)
    };
    let Some(ai) = lowdim("action") else {
        return Ok(());
    };
    if !cfg.enabled || manifest.episodes.is_empty() {
        return Ok(());
    }
    let si = lowdim("observation.state");
    let a_dim = manifest.channels[ai].width();
    let s_dim = si.map_or(0, |c| manifest.channels[c].width());
    if a_dim == 0 {
        return Ok(());
    }
    let wanted: Vec<usize> = std::iter::once(ai).chain(si).collect();
    let shown = &spec.spec.source.path;
    let feats: Vec<Features> =
        crate::error::in_order((0..manifest.episodes.len()).into_par_iter().map(
            |i| -> Result<Features> {
                let mut data = source.read_lowdim(i, &wanted)?;
                let to64 = |v: Vec<f32>| v.into_iter().map(f64::from).collect::<Vec<f64>>();
                let a = to64(std::mem::take(&mut data[0]));
                let s = si.map(|_| to64(std::mem::take(&mut data[1])));
                let n = a.len() / a_dim;
                // Non-finite values are `[audit] non_finite`'s to judge (an error naming the step,
                // or the episode left out) when the build reads the episode: here each is held at
                // the last finite value of its column, so that it sets off no check.
                let mut a = a;
                let mut s = s;
                hold_finite(&mut a, a_dim);
                if let Some(s) = s.as_mut() {
                    hold_finite(s, s_dim);
                }
                Ok(features(&a, s.as_deref(), n, a_dim, s_dim))
            },
        ))?;
    let ids: Vec<u64> = manifest.episodes.iter().map(|e| e.id).collect();
    let episodes = feats.len();
    let mut found: Vec<Vec<Finding>> = vec![Vec::new(); episodes];
    let mut add =
        |e: usize, flag: Flag, action: DoctorAction, detail: String, evidence: &[(&str, f64)]| {
            found[e].push(Finding {
                flag,
                action,
                detail,
                evidence: evidence.iter().map(|(k, v)| (k.to_string(), *v)).collect(),
            });
        };

    // Convention and units first: the other checks are measured in the episode's own units.
    let fits: Vec<Vec<Option<Vec<alignment::LagFit>>>> =
        feats.iter().map(|f| f.fits.clone()).collect();
    let stds: Vec<Vec<f64>> = feats.iter().map(|f| f.stds.clone()).collect();
    let rms: Vec<Vec<f64>> = feats
        .iter()
        .map(|f| {
            f.action_means
                .iter()
                .zip(&f.stds)
                .map(|(m, s)| (m * m + s * s).sqrt())
                .collect()
        })
        .collect();
    let judged = convention::judge(&fits, &rms, &stds, cfg.units_ratio);
    for e in 0..episodes {
        let u = judged.units[e];
        if judged.units_judged[e] && (u > cfg.units_ratio || u < 1.0 / cfg.units_ratio) {
            add(
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
                    add(e, Flag::MixedConvention, cfg.mixed_convention, format!(
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
                add(e, Flag::Misaligned, cfg.misaligned, format!(
                    "the action best predicts the state {} steps later (R² {:.3}), the dataset's mode is {mode} (R² {:.3} here): actions shifted by {} steps",
                    l.lag, 1.0 - l.unexplained[l.best], 1.0 - at_mode, l.lag - mode),
                    &[("lag", f64::from(l.lag)), ("mode", f64::from(mode)), ("r2", 1.0 - l.unexplained[l.best]), ("r2_at_mode", 1.0 - at_mode)]);
            }
        }
    }

    // An episode in other units is measured in the dataset's; any other is taken as it is (a
    // factor near 1 is the fit's noise, and spikes themselves pull the gain it is fitted from).
    let scale: Vec<f64> = (0..episodes)
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
        .collect();
    // Signal quality, per dimension against the dataset.
    let step_sigma: Vec<f64> = (0..a_dim)
        .map(|d| {
            stats::median(
                feats
                    .iter()
                    .zip(&scale)
                    .map(|(f, u)| f.signal[d].step_sigma / u),
            )
        })
        .collect();
    for (d, &sigma) in step_sigma.iter().enumerate() {
        let long = |f: &Features| {
            f.n >= 10 && f.signal[d].run.0 as f64 >= cfg.frozen_fraction * f.n as f64
        };
        let static_share = feats.iter().filter(|f| long(f)).count() as f64 / episodes as f64;
        let clip_median = stats::median(feats.iter().map(|f| f.signal[d].clip.0));
        let lowest = feats
            .iter()
            .map(|f| f.signal[d].min)
            .fold(f64::INFINITY, f64::min);
        let highest = feats
            .iter()
            .map(|f| f.signal[d].max)
            .fold(f64::NEG_INFINITY, f64::max);
        for (e, f) in feats.iter().enumerate() {
            let sig = &f.signal[d];
            let at_limit = sig.run.2 == lowest || sig.run.2 == highest;
            if long(f) && static_share < 0.5 && !at_limit {
                let (len, from, value) = sig.run;
                add(e, Flag::Frozen, cfg.frozen, format!(
                    "action[{d}] holds {value} for {len} of {} steps from step {from}, where it moves in most episodes", f.n),
                    &[("dim", d as f64), ("steps", len as f64), ("from", from as f64), ("value", value)]);
            } else if sig.clip.0 >= cfg.clip_fraction
                && clip_median < cfg.clip_fraction
                && !long(f)
                && sig.clip.1 != lowest
                && sig.clip.1 != highest
            {
                let (share, bound, side) = sig.clip;
                add(
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
                if let Some(&(size, step)) = sig.spikes.first() {
                    // Against the episode's own step changes (the fault is "k of its own
                    // robust std"), never below half the dataset's: a dimension that holds
                    // still in this episode does not turn its sensor noise into spikes.
                    let own = (sig.step_sigma / scale[e]).max(0.5 * sigma);
                    let z = size / scale[e] / own;
                    if z > cfg.jump_threshold {
                        let count = sig
                            .spikes
                            .iter()
                            .filter(|s| s.0 / scale[e] / own > cfg.jump_threshold)
                            .count();
                        add(e, Flag::Jump, cfg.jump, format!(
                            "action[{d}] spikes at step {step} by {z:.1} robust std of its step changes ({count} such steps)"),
                            &[("dim", d as f64), ("step", step as f64), ("z", z)]);
                    }
                }
            }
        }
    }
    let dedupe = |list: &mut Vec<Finding>| {
        // One finding per flag: the first (lowest dimension).
        let mut seen = std::collections::BTreeSet::new();
        list.retain(|f| seen.insert(f.flag));
    };
    let mut constant = Vec::new();
    for d in 0..a_dim {
        let lo = feats
            .iter()
            .map(|f| f.signal[d].min)
            .fold(f64::INFINITY, f64::min);
        let hi = feats
            .iter()
            .map(|f| f.signal[d].max)
            .fold(f64::NEG_INFINITY, f64::max);
        if lo == hi {
            constant.push(("action".to_string(), d, lo));
        }
    }
    for d in 0..s_dim {
        let lo = feats
            .iter()
            .map(|f| f.state_range[d].0)
            .fold(f64::INFINITY, f64::min);
        let hi = feats
            .iter()
            .map(|f| f.state_range[d].1)
            .fold(f64::NEG_INFINITY, f64::max);
        if lo == hi {
            constant.push(("observation.state".to_string(), d, lo));
        }
    }

    // Stuck: not constant, but holding one value for most of most episodes, or unchanged from
    // step to step in STUCK_UNCHANGED of them (an unused or stuck degree of freedom; per-episode
    // `frozen` leaves these dimensions alone).
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
                        (f.signal[d].run.0, f.signal[d].unchanged)
                    } else {
                        f.state_runs[d]
                    };
                    f.n >= 10
                        && (run as f64 >= cfg.frozen_fraction * f.n as f64
                            || unchanged >= STUCK_UNCHANGED)
                })
                .count();
            if 2 * held >= episodes {
                stuck.push((channel.to_string(), d, held as f64 / episodes as f64));
            }
        }
    }

    // Duplicates.
    let spreads: Vec<f64> = (0..a_dim)
        .map(|d| stats::median(feats.iter().map(|f| f.stds[d])))
        .map(|s| if s > 0.0 { s } else { 1.0 })
        .collect();
    let sigs: Vec<Vec<f64>> = feats
        .iter()
        .map(|f| {
            f.signature
                .iter()
                .enumerate()
                .map(|(k, v)| v / spreads[k % a_dim])
                .collect()
        })
        .collect();
    let lengths: Vec<usize> = feats.iter().map(|f| f.n).collect();
    let pairs = duplicates::pairs(&sigs, &lengths, cfg.duplicate_tolerance);
    for &(early, late, rms) in &pairs {
        add(
            late,
            Flag::Duplicate,
            cfg.duplicate,
            format!(
                "a near-copy of episode {} (RMS difference {rms:.2e} of the actions' spread)",
                ids[early]
            ),
            &[("of", ids[early] as f64), ("rms", rms)],
        );
    }

    // Short episodes.
    for (e, f) in feats.iter().enumerate() {
        let mut why = Vec::new();
        let mut evidence = Vec::new();
        for p in &spec.profiles {
            let steps = short::steps_at(f.n, manifest.fps, p);
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
            add(e, Flag::Short, cfg.short, why.join("; "), &ev);
        }
    }

    // Shift (dataset-wide).
    let mut shifts = Vec::new();
    for (channel, width, means) in [
        (
            "action",
            a_dim,
            feats
                .iter()
                .map(|f| f.action_means.clone())
                .collect::<Vec<_>>(),
        ),
        (
            "observation.state",
            s_dim,
            feats
                .iter()
                .map(|f| f.state_means.clone())
                .collect::<Vec<_>>(),
        ),
    ] {
        for d in 0..width {
            let m: Vec<f64> = means.iter().map(|v| v[d]).collect();
            if let Some(dev) = shift::deviations(&m) {
                shifts.push(ShiftDim {
                    channel: channel.into(),
                    dim: d,
                    deviations: dev,
                });
            }
        }
    }

    // Findings into the report; verdicts.
    let mut flagged: BTreeMap<String, u64> = BTreeMap::new();
    let mut error = None;
    for (e, mut list) in found.into_iter().enumerate() {
        dedupe(&mut list);
        let audit = &mut report.episodes[e];
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
                    audit.verdict = Verdict::Exclude;
                    audit.repaired_frames = 0;
                    repairs[e] = Repair::Exclude;
                }
                DoctorAction::Error => {
                    error.get_or_insert_with(|| {
                        format!(
                            "{shown}: episode {}: {}: {} (`[audit.doctor] {} = \"error\"`)",
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
    }
    if let Some(message) = error {
        return Err(Error::source(message));
    }
    report.excluded_fraction = report
        .episodes
        .iter()
        .filter(|e| e.verdict == Verdict::Exclude)
        .count() as f64
        / episodes as f64;
    if !flagged.is_empty() {
        let counts: Vec<String> = flagged.iter().map(|(k, v)| format!("{k} {v}")).collect();
        report.warnings.push(format!(
            "the dataset doctor flagged episodes: {}",
            counts.join(", ")
        ));
    }
    for (channel, d, v) in &constant {
        let mut affected = Vec::new();
        for p in &spec.profiles {
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
    for (channel, d, share) in &stuck {
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
    if let Some(mode) = judged.mode {
        if mode.abs_diff(1) > cfg.lag_tolerance {
            let names: Vec<String> = spec
                .profiles
                .iter()
                .map(|p| format!("`{}` ({})", p.name, p.alignment.name()))
                .collect();
            report.warnings.push(format!(
                "the actions first show in the state {mode} steps later (the dataset's mode), where the profiles' alignment ({}) assumes the action of step t is executed from the observation of step t and shows at t + 1",
                names.join(", ")));
        }
    }
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
        state_channel: si.map(|_| "observation.state".into()),
        flagged,
        tracked_dims: judged.tracked.clone(),
        lag_histogram,
        lag_mode: judged.mode,
        lag_curve: judged.curve.clone(),
        convention: judged.majority.map(|c| c.name().to_string()),
        conventions,
        units: ids
            .iter()
            .copied()
            .zip(judged.units.iter().copied())
            .collect(),
        step_sigma,
        constant,
        stuck,
        shift: shifts,
        duplicates: pairs.iter().map(|&(a, b, r)| (ids[a], ids[b], r)).collect(),
        units_ratio: cfg.units_ratio,
        shift_threshold: cfg.shift_threshold,
    });
    Ok(())
}
