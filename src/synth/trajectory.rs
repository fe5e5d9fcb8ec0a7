//! What a synthetic episode contains: smooth joint trajectories, a state that follows the action
//! with a lag, camera frames that show the motion, and timestamps with optional timing faults.
//!
//! Everything comes from one seeded SplitMix64 stream per (seed, episode, purpose), so an
//! episode's values do not depend on how many episodes are written or in which order.

use super::injected::Injected;
use super::rng::Rng;
use super::{data_faults, Fault, SynthOptions};

const STREAM_ACTION: u64 = 1;
const STREAM_FRAMES: u64 = 2;
const STREAM_FAULTS: u64 = 3;
const STREAM_PICK: u64 = 4;

/// One generated episode, row-major `(steps, width)` arrays.
pub struct SynthEpisode {
    pub id: u64,
    pub steps: usize,
    /// Commanded joint positions `(steps, action_dim)`.
    pub action: Vec<f32>,
    /// Measured joint positions `(steps, state_dim)`: the action's first `state_dim` joints
    /// through a first-order lag.
    pub state: Vec<f32>,
    /// Finite-difference velocity of `state` `(steps, state_dim)`, per second.
    pub velocity: Vec<f32>,
    /// Per camera, `(steps, height, width, 3)` uint8 frames.
    pub frames: Vec<Vec<u8>>,
    /// Seconds since the episode started (nominal `t / fps` unless a fault changed them).
    pub timestamps: Vec<f64>,
    /// What was injected, for `faults.json`.
    pub injected: Vec<Injected>,
}

/// Smooth, bounded joint targets: a sum of three slow sines per joint.
fn action(opts: &SynthOptions, rng: &mut Rng, steps: usize) -> Vec<f32> {
    let dims = opts.action_dim;
    let params: Vec<[(f64, f64, f64); 3]> = (0..dims)
        .map(|_| {
            [0, 1, 2].map(|k| {
                let freq = rng.range(0.05, 0.4) * (1.0 + k as f64);
                let amp = rng.range(0.1, 0.6) / (1.0 + k as f64);
                let phase = rng.range(0.0, std::f64::consts::TAU);
                (freq, amp, phase)
            })
        })
        .collect();
    let offsets: Vec<f64> = (0..dims).map(|_| rng.range(-0.5, 0.5)).collect();
    let mut out = vec![0f32; steps * dims];
    for t in 0..steps {
        let secs = t as f64 / opts.fps;
        for d in 0..dims {
            let v: f64 = params[d]
                .iter()
                .map(|(f, a, p)| a * (std::f64::consts::TAU * f * secs + p).sin())
                .sum();
            out[t * dims + d] = (offsets[d] + v) as f32;
        }
    }
    out
}

/// The state follows the commanded joints with a first-order lag (joints past the action's
/// width follow joint `d % action_dim`).
fn state(opts: &SynthOptions, action: &[f32], steps: usize) -> Vec<f32> {
    let (a, s) = (opts.action_dim, opts.state_dim);
    let mut out = vec![0f32; steps * s];
    for d in 0..s {
        let src = d % a.max(1);
        let mut x = if a > 0 { action[src] } else { 0.0 };
        for t in 0..steps {
            out[t * s + d] = x;
            if a > 0 {
                x += 0.3 * (action[t * a + src] - x);
            }
        }
    }
    out
}

fn velocity(opts: &SynthOptions, state: &[f32], steps: usize) -> Vec<f32> {
    let s = opts.state_dim;
    let mut out = vec![0f32; steps * s];
    for t in 1..steps {
        for d in 0..s {
            out[t * s + d] = (state[t * s + d] - state[(t - 1) * s + d]) * opts.fps as f32;
        }
    }
    out
}

/// A camera's frames: a vertical gradient background, a bright disc whose position follows two
/// joints, and a little sensor noise (so frames compress like camera images, not like flat
/// colour).
fn frames(opts: &SynthOptions, id: u64, camera: usize, action: &[f32], steps: usize) -> Vec<u8> {
    let (h, w) = (opts.height, opts.width);
    let a = opts.action_dim.max(1);
    let frame_len = h * w * 3;
    let mut out = vec![0u8; steps * frame_len];
    let mut rng = Rng::new(opts.seed, id, STREAM_FRAMES * 1000 + camera as u64);
    let tint = [
        rng.range(0.6, 1.0),
        rng.range(0.6, 1.0),
        rng.range(0.6, 1.0),
    ];
    let radius = (h.min(w) as f64 * 0.15).max(1.0);
    let mut noise = rng.next_u64();
    for t in 0..steps {
        let jx = action.get(t * a + camera % a).copied().unwrap_or(0.0) as f64;
        let jy = action.get(t * a + (camera + 1) % a).copied().unwrap_or(0.0) as f64;
        let cx = (0.5 + 0.35 * jx.clamp(-1.0, 1.0)) * w as f64;
        let cy = (0.5 + 0.35 * jy.clamp(-1.0, 1.0)) * h as f64;
        let frame = &mut out[t * frame_len..(t + 1) * frame_len];
        for y in 0..h {
            let base = 40.0 + 150.0 * y as f64 / h as f64;
            let dy = y as f64 - cy;
            for x in 0..w {
                let dx = x as f64 - cx;
                let inside = dx * dx + dy * dy <= radius * radius;
                // xorshift64 for the noise: two bits per channel, cheap.
                noise ^= noise << 13;
                noise ^= noise >> 7;
                noise ^= noise << 17;
                let px = &mut frame[(y * w + x) * 3..(y * w + x) * 3 + 3];
                for (c, p) in px.iter_mut().enumerate() {
                    let v = if inside {
                        230.0
                    } else {
                        base * tint[c] + 20.0 * (x as f64 / w as f64)
                    };
                    let n = ((noise >> (8 * c)) & 3) as f64 - 1.5;
                    *p = (v + n).clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
    out
}

/// Whether episode `id` gets the timing faults (`fault_fraction` of the episodes, chosen by the
/// seed).
pub fn is_faulty(opts: &SynthOptions, id: u64) -> bool {
    opts.faults.iter().any(|f| !f.is_data())
        && Rng::new(opts.seed, id, STREAM_PICK).unit() < opts.fault_fraction
}

/// Keeps the rows of `values` (width `width`) whose index is in `keep`.
fn keep_rows<T: Copy>(values: &[T], width: usize, keep: &[usize]) -> Vec<T> {
    let mut out = Vec::with_capacity(keep.len() * width);
    for &t in keep {
        out.extend_from_slice(&values[t * width..(t + 1) * width]);
    }
    out
}

/// Generates episode `id`.
pub fn episode(opts: &SynthOptions, id: u64) -> SynthEpisode {
    let steps = opts.steps;
    let mut rng = Rng::new(opts.seed, id, STREAM_ACTION);
    let mut ep = SynthEpisode {
        id,
        steps,
        action: Vec::new(),
        state: Vec::new(),
        velocity: Vec::new(),
        frames: Vec::new(),
        timestamps: (0..steps).map(|t| t as f64 / opts.fps).collect(),
        injected: Vec::new(),
    };
    let fault = data_faults::assigned(opts, id);
    if fault == Some(Fault::Copy) {
        rng = Rng::new(opts.seed, data_faults::copy_of(opts, id), STREAM_ACTION);
    }
    ep.action = action(opts, &mut rng, steps);
    if let Some(f) = fault {
        ep.injected
            .extend(data_faults::physical(opts, id, f, &mut ep.action));
    }
    ep.state = state(opts, &ep.action, steps);
    ep.velocity = velocity(opts, &ep.state, steps);
    ep.frames = (0..opts.cameras)
        .map(|c| frames(opts, id, c, &ep.action, steps))
        .collect();
    if let Some(f) = fault {
        ep.injected.extend(data_faults::recorded(
            opts,
            id,
            f,
            &mut ep.action,
            &ep.state,
        ));
    }
    if is_faulty(opts, id) {
        inject(opts, &mut ep);
    }
    ep
}

/// Applies the timing faults in a fixed order: drop, rate, jitter, duplicate.
fn inject(opts: &SynthOptions, ep: &mut SynthEpisode) {
    let mut rng = Rng::new(opts.seed, ep.id, STREAM_FAULTS);
    let mut ordered = opts.faults.clone();
    ordered.sort_by_key(|f| match f {
        Fault::Drop(_) => 0,
        Fault::Rate(_) => 1,
        Fault::Jitter(_) => 2,
        Fault::Duplicate(_) => 3,
        _ => 4,
    });
    for fault in ordered {
        match fault {
            Fault::Drop(p) => {
                let (keep, dropped): (Vec<usize>, Vec<usize>) =
                    (0..ep.steps).partition(|&t| t == 0 || rng.unit() >= p);
                let frame_len = opts.height * opts.width * 3;
                ep.action = keep_rows(&ep.action, opts.action_dim, &keep);
                ep.state = keep_rows(&ep.state, opts.state_dim, &keep);
                ep.velocity = keep_rows(&ep.velocity, opts.state_dim, &keep);
                for f in &mut ep.frames {
                    *f = keep_rows(f, frame_len, &keep);
                }
                ep.timestamps = keep_rows(&ep.timestamps, 1, &keep);
                ep.steps = keep.len();
                ep.injected.push(Injected::Drop { steps: dropped });
            }
            Fault::Rate(actual) => {
                // Re-time the stored steps, keeping gaps a drop made (in units of steps).
                let scale = opts.fps / actual;
                for t in &mut ep.timestamps {
                    *t *= scale;
                }
                ep.injected.push(Injected::Rate { actual_fps: actual });
            }
            Fault::Jitter(fraction) => {
                for t in ep.timestamps.iter_mut().skip(1) {
                    *t += rng.range(-fraction, fraction) / opts.fps;
                }
                ep.injected.push(Injected::Jitter { fraction });
            }
            Fault::Duplicate(p) => {
                let mut steps = Vec::new();
                for t in 1..ep.steps {
                    if rng.unit() < p {
                        ep.timestamps[t] = ep.timestamps[t - 1];
                        steps.push(t);
                    }
                }
                ep.injected.push(Injected::Duplicate { steps });
            }
            _ => {}
        }
    }
}
