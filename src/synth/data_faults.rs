//! Data faults for `chunkc synth --faults`: what silently ruins a policy without touching the
//! timestamps (a frozen or clipped actuator, spikes, actions recorded late, as deltas or in other
//! units, a duplicated episode), so that the dataset doctor (`audit::doctor`) can be measured
//! against a known truth.
//!
//! Each data fault gets its own disjoint share of the episodes (`fault_fraction` each, exactly
//! `round(fraction × episodes)` of them): the episodes are permuted by a seeded affine map
//! `id → (a·id + b) mod n` and fault `j` takes positions `[j·m, (j+1)·m)`. Physical faults
//! (`frozen`, `clip`, `duplicate`) change the command the simulated robot follows, so the state
//! follows them; recording faults (`jump`, `lag`, `delta`, `scale`) change only what was logged.

use super::injected::Injected;
use super::rng::Rng;
use super::{Fault, SynthOptions};

const STREAM_ASSIGN: u64 = 5;
const STREAM_DATA: u64 = 6;

/// The data fault of episode `id`, if any.
pub fn assigned(opts: &SynthOptions, id: u64) -> Option<Fault> {
    let n = opts.episodes as u64;
    let m = (opts.fault_fraction * n as f64).round() as u64;
    if m == 0 || id >= n {
        return None;
    }
    let mut faults = opts.faults.iter().copied().filter(|f| f.is_data());
    let mut r = Rng::new(opts.seed, 0, STREAM_ASSIGN);
    let b = r.next_u64() % n;
    let mut a = 1 + r.next_u64() % n;
    while gcd(a, n) != 1 {
        a += 1;
    }
    let position = ((a as u128 * id as u128 + b as u128) % n as u128) as u64;
    faults.nth((position / m) as usize)
}

fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// The episode a `duplicate` episode copies: the nearest earlier one without a data fault (else
/// the nearest later one).
pub fn copy_of(opts: &SynthOptions, id: u64) -> u64 {
    let clean = |j: &u64| assigned(opts, *j).is_none();
    (0..id)
        .rev()
        .find(clean)
        .or_else(|| (id + 1..opts.episodes as u64).find(clean))
        .unwrap_or(id)
}

/// Physical faults, applied to the commanded actions before the state is simulated.
pub fn physical(
    opts: &SynthOptions,
    id: u64,
    fault: Fault,
    action: &mut [f32],
) -> Option<Injected> {
    let a = opts.action_dim;
    let steps = action.len() / a;
    let mut rng = Rng::new(opts.seed, id, STREAM_DATA);
    let dim = (rng.next_u64() % a as u64) as usize;
    match fault {
        Fault::Frozen => {
            let from = (rng.unit() * (steps / 4) as f64) as usize;
            let held = action[from * a + dim];
            for t in from..steps {
                action[t * a + dim] = held;
            }
            Some(Injected::Frozen { dim, from })
        }
        Fault::Clip => {
            let upper = rng.unit() < 0.5;
            let mut column: Vec<f32> = (0..steps).map(|t| action[t * a + dim]).collect();
            column.sort_by(f32::total_cmp);
            let q = if upper { 0.7 } else { 0.3 };
            let bound = column[(q * (steps - 1) as f64).round() as usize];
            let mut clipped = 0;
            for t in 0..steps {
                let v = &mut action[t * a + dim];
                if (upper && *v > bound) || (!upper && *v < bound) {
                    *v = bound;
                    clipped += 1;
                }
            }
            let side = if upper { "max" } else { "min" };
            Some(Injected::Clip {
                dim,
                bound: f64::from(bound),
                side,
                steps: clipped,
            })
        }
        Fault::Copy => {
            for v in action.iter_mut() {
                *v += rng.range(-1e-4, 1e-4) as f32;
            }
            Some(Injected::DuplicateEpisode {
                of: copy_of(opts, id),
            })
        }
        _ => None,
    }
}

/// Recording faults, applied to the logged actions after the state was simulated.
pub fn recorded(
    opts: &SynthOptions,
    id: u64,
    fault: Fault,
    action: &mut [f32],
    state: &[f32],
) -> Option<Injected> {
    let (a, s) = (opts.action_dim, opts.state_dim);
    let steps = action.len() / a;
    let mut rng = Rng::new(opts.seed, id, STREAM_DATA + 1);
    match fault {
        Fault::Jump => {
            let dim = (rng.next_u64() % a as u64) as usize;
            let mut at = Vec::new();
            let mut sizes = Vec::new();
            let room = steps.saturating_sub(4).max(1);
            while at.len() < 2.min(room) {
                let t = 2 + (rng.next_u64() % room as u64) as usize;
                if t < steps && at.iter().all(|&u: &usize| u.abs_diff(t) > 2) {
                    let size = rng.range(1.0, 2.0) * if rng.unit() < 0.5 { -1.0 } else { 1.0 };
                    action[t * a + dim] += size as f32;
                    at.push(t);
                    sizes.push(size);
                }
            }
            Some(Injected::Jump {
                dim,
                steps: at,
                sizes,
            })
        }
        Fault::Lag(n) => {
            let before = action.to_vec();
            for t in 0..steps {
                let from = (t as i64 - n as i64).clamp(0, steps as i64 - 1) as usize;
                action[t * a..(t + 1) * a].copy_from_slice(&before[from * a..(from + 1) * a]);
            }
            Some(Injected::Lag { steps: n })
        }
        Fault::Delta => {
            let before = action.to_vec();
            for t in 0..steps {
                for d in 0..a {
                    action[t * a + d] = if d < s {
                        before[t * a + d] - state[t * s + d]
                    } else if t > 0 {
                        before[t * a + d] - before[(t - 1) * a + d]
                    } else {
                        0.0
                    };
                }
            }
            Some(Injected::Delta)
        }
        Fault::Scale(f) => {
            for v in action.iter_mut() {
                *v = (f64::from(*v) * f) as f32;
            }
            Some(Injected::Scale { factor: f })
        }
        _ => None,
    }
}
