//! The doctor's dataset-wide warnings, grouped so that a dataset with many dimensions reads in a
//! few lines: one per flag (how many episodes, which dimensions, the first episodes), one per
//! channel for its constant dimensions and one for its stuck ones, the shift, the lag.
//! `chunkc audit` writes every finding (`audit.json`, `report.html`); these lines point there.

use std::collections::{BTreeMap, BTreeSet};

use super::{Finding, ShiftDim, STUCK_UNCHANGED};
use crate::audit::report::AuditReport;
use crate::spec::LoadedSpec;

/// Episodes listed by name in a warning line; the rest are counted.
const LISTED: usize = 12;

/// One flag's episodes and the dimensions its findings name.
#[derive(Debug, Default)]
pub(super) struct FlagGroup {
    episodes: Vec<u64>,
    dims: BTreeSet<usize>,
}

/// Every flag's group, from the findings per episode (in the order of `ids`).
pub(super) fn flag_groups(
    ids: &[u64],
    found: &[Vec<Finding>],
) -> BTreeMap<&'static str, FlagGroup> {
    let mut groups: BTreeMap<&'static str, FlagGroup> = BTreeMap::new();
    for (e, list) in found.iter().enumerate() {
        for f in list {
            let g = groups.entry(f.flag.name()).or_default();
            if g.episodes.last() != Some(&ids[e]) {
                g.episodes.push(ids[e]);
            }
            if let Some(&d) = f.evidence.get("dim") {
                g.dims.insert(d as usize);
            }
        }
    }
    groups
}

/// `0-3, 7, 9-10`: sorted numbers with their runs joined.
pub fn ranges(values: impl IntoIterator<Item = usize>) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut run: Option<(usize, usize)> = None;
    let close = |(a, b): (usize, usize)| {
        if a == b {
            a.to_string()
        } else {
            format!("{a}-{b}")
        }
    };
    for v in values {
        run = match run {
            Some((a, b)) if v == b + 1 => Some((a, v)),
            Some(r) => {
                parts.push(close(r));
                Some((v, v))
            }
            None => Some((v, v)),
        };
    }
    parts.extend(run.map(close));
    parts.join(", ")
}

/// The first [`LISTED`] of `ids`, and how many more.
fn listed(ids: &[u64]) -> String {
    let shown: Vec<String> = ids.iter().take(LISTED).map(u64::to_string).collect();
    let more = ids.len().saturating_sub(LISTED);
    if more > 0 {
        format!("{} and {more} more", shown.join(", "))
    } else {
        shown.join(", ")
    }
}

/// What the warnings are made of.
pub(super) struct Inputs<'a> {
    pub spec: &'a LoadedSpec,
    pub episodes: usize,
    pub groups: &'a BTreeMap<&'static str, FlagGroup>,
    pub constant: &'a [(String, usize, f64)],
    pub stuck: &'a [(String, usize, f64)],
    pub shifts: &'a [ShiftDim],
    pub lag_mode: Option<i32>,
}

/// The dataset-wide warnings, in the order `chunkc audit` prints them.
pub(super) fn warnings(w: &Inputs, report: &mut AuditReport) {
    let out = &mut report.warnings;
    for (flag, g) in w.groups {
        let dims = if g.dims.is_empty() {
            String::new()
        } else {
            format!(" (`action` dims {})", ranges(g.dims.iter().copied()))
        };
        out.push(format!(
            "dataset doctor: `{flag}` in {} of {} episodes{dims}: episodes {} (`chunkc audit` writes each finding)",
            g.episodes.len(),
            w.episodes,
            listed(&g.episodes)
        ));
    }
    constant(w, out);
    stuck(w, out);
    shift(w, out);
    lag(w, out);
}

/// The channels in the order the doctor reads them.
const CHANNELS: [&str; 2] = ["action", "observation.state"];

/// One line per channel with constant dimensions, their values grouped.
fn constant(w: &Inputs, out: &mut Vec<String>) {
    for channel in CHANNELS {
        let dims: Vec<(usize, f64)> = w
            .constant
            .iter()
            .filter(|(c, _, _)| c == channel)
            .map(|&(_, d, v)| (d, v))
            .collect();
        if dims.is_empty() {
            continue;
        }
        // Dimensions by value (in order of their first dimension).
        let mut by_value: Vec<(f64, Vec<usize>)> = Vec::new();
        for &(d, v) in &dims {
            match by_value
                .iter_mut()
                .find(|(u, _)| u.to_bits() == v.to_bits())
            {
                Some((_, ds)) => ds.push(d),
                None => by_value.push((v, vec![d])),
            }
        }
        let values: Vec<String> = by_value
            .iter()
            .map(|(v, ds)| format!("{} = {v}", ranges(ds.iter().copied())))
            .collect();
        let affected: Vec<String> = w
            .spec
            .profiles
            .iter()
            .map(|p| {
                let mode = p
                    .normalize
                    .get(channel)
                    .copied()
                    .unwrap_or(p.normalize_lowdim);
                format!("`{}` ({mode:?})", p.name)
            })
            .collect();
        let (n, s) = (dims.len(), if dims.len() == 1 { "" } else { "s" });
        out.push(format!(
            "`{channel}`: {n} dimension{s} constant over the whole dataset ({}): std and range 0, so z-score and min-max normalization divide by the floor; profiles {}",
            values.join(", "),
            affected.join(", ")
        ));
    }
}

/// One line per channel with dimensions holding still in most episodes.
fn stuck(w: &Inputs, out: &mut Vec<String>) {
    let cfg = &w.spec.spec.audit.doctor;
    for channel in CHANNELS {
        let dims: Vec<(usize, f64)> = w
            .stuck
            .iter()
            .filter(|(c, _, _)| c == channel)
            .map(|&(_, d, share)| (d, share))
            .collect();
        if dims.is_empty() {
            continue;
        }
        let lo = dims.iter().map(|d| d.1).fold(f64::INFINITY, f64::min);
        let hi = dims.iter().map(|d| d.1).fold(0.0, f64::max);
        let share = if (hi - lo).abs() < 0.005 {
            format!("{:.0}%", 100.0 * hi)
        } else {
            format!("{:.0}-{:.0}%", 100.0 * lo, 100.0 * hi)
        };
        out.push(format!(
            "`{channel}` dims {} hold still (one value for {:.0}% of the steps, or unchanged in {:.0}% of them) in {share} of the episodes: unused or stuck degrees of freedom (there `frozen` flags only an episode holding far longer than the others)",
            ranges(dims.iter().map(|d| d.0)),
            100.0 * cfg.frozen_fraction,
            100.0 * STUCK_UNCHANGED,
        ));
    }
}

/// Distribution shift across the recording, one line per channel.
fn shift(w: &Inputs, out: &mut Vec<String>) {
    let cfg = &w.spec.spec.audit.doctor;
    for channel in CHANNELS {
        let mut dims = Vec::new();
        let mut worst: Option<(usize, usize, f64)> = None;
        for s in w.shifts.iter().filter(|s| s.channel == channel) {
            let Some((q, &dev)) = s
                .deviations
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            else {
                continue;
            };
            if dev.abs() > cfg.shift_threshold {
                dims.push(s.dim);
                if worst.is_none_or(|w| dev.abs() > w.2.abs()) {
                    worst = Some((s.dim, q, dev));
                }
            }
        }
        if let Some((d, q, dev)) = worst {
            out.push(format!(
                "distribution shift across the recording in `{channel}` dims {}: the largest, `{channel}[{d}]`, has its quarter {} of the episodes (recording order) {dev:+.2} robust std from the dataset's median",
                ranges(dims),
                q + 1
            ));
        }
    }
}

/// The dataset's lag, when it is not the one every alignment assumes.
fn lag(w: &Inputs, out: &mut Vec<String>) {
    let cfg = &w.spec.spec.audit.doctor;
    if let Some(mode) = w.lag_mode {
        if mode.abs_diff(1) > cfg.lag_tolerance {
            let names: Vec<String> = w
                .spec
                .profiles
                .iter()
                .map(|p| format!("`{}` ({})", p.name, p.alignment.name()))
                .collect();
            out.push(format!(
                "the actions first show in the state {mode} steps later (the dataset's mode), where the profiles' alignment ({}) assumes the action of step t is executed from the observation of step t and shows at t + 1",
                names.join(", ")));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_join_runs() {
        assert_eq!(ranges([14, 15, 16, 17, 28, 31]), "14-17, 28, 31");
        assert_eq!(ranges([3]), "3");
        assert_eq!(ranges(Vec::<usize>::new()), "");
        assert_eq!(ranges([0, 1, 3, 4, 5, 9]), "0-1, 3-5, 9");
        let ids: Vec<u64> = (0..20).collect();
        assert_eq!(
            listed(&ids),
            "0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11 and 8 more"
        );
    }
}
