//! What one episode reduces to for the doctor: per-dimension signal features, the alignment fits,
//! moments, the state's ranges and runs, and the duplicate signature. Computed once per episode,
//! in parallel; every check then judges these, never the raw values.

use super::columns::{self, Columns};
use super::{alignment, duplicates, returns, signal};

/// What one episode reduces to: a fixed size per channel dimension, whatever the episode's
/// length (about 5 KB for 14-D action and state), in a few exact-size allocations: every
/// episode's are kept until the judgement.
#[derive(Debug, Clone)]
pub struct Features {
    pub(super) n: usize,
    /// Per action dimension.
    pub(super) signal: Box<[signal::DimSignal]>,
    /// Per action dimension shared with the state: its fits, None when it has none.
    pub(super) fits: Box<[Option<alignment::DimFits>]>,
    /// Per action dimension.
    pub(super) action: Box<[Moments]>,
    /// Per state dimension.
    pub(super) state: Box<[StateDim]>,
    /// The duplicate signature ([`duplicates::signature`]), in single precision: the
    /// tolerance it is compared at is far above its rounding.
    pub(super) signature: Box<[f32]>,
}

/// A column's mean and (population) standard deviation.
#[derive(Debug, Clone, Copy)]
pub struct Moments {
    pub mean: f64,
    pub std: f32,
}

/// What the checks read of one state dimension.
#[derive(Debug, Clone, Copy)]
pub struct StateDim {
    pub mean: f64,
    pub lo: f32,
    pub hi: f32,
    /// The longest run of one exact value (steps).
    pub run: u32,
    /// Steps equal to the step before.
    pub unchanged: u32,
}

/// The mean and the (population) standard deviation of a column, in two passes.
#[inline(always)]
fn moments(x: &[f32]) -> Moments {
    if x.is_empty() {
        return Moments {
            mean: 0.0,
            std: 0.0,
        };
    }
    let mean = columns::sum(x) / x.len() as f64;
    let std = (columns::squares_about(x, mean) / x.len() as f64).sqrt() as f32;
    Moments { mean, std }
}

/// An episode's steps and its action's and state's widths.
#[derive(Debug, Clone, Copy)]
pub(super) struct Shape {
    pub n: usize,
    pub a_dim: usize,
    pub s_dim: usize,
}

/// What an episode reduces to, from its action rows and state rows (`shape`).
///
/// Compiled twice, for the build's baseline target and for AVX2 (chosen at run time): every
/// per-dimension loop is inlined into both, so that the AVX2 copy runs them twice as wide. The
/// two compute the same bits (no FMA, and the compiler reorders no floating-point operation:
/// the lanes of every sum are written out), so the report does not depend on the machine.
pub(super) fn features(action: &[f32], state: Option<&[f32]>, shape: Shape) -> Features {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        return unsafe { features_avx2(action, state, shape) };
    }
    reduce(action, state, shape)
}

/// [`reduce`] compiled for AVX2 (without FMA: a fused multiply-add rounds once where the
/// baseline rounds twice).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn features_avx2(action: &[f32], state: Option<&[f32]>, shape: Shape) -> Features {
    reduce(action, state, shape)
}

/// [`features`], for whichever target its caller is compiled for.
#[inline(always)]
fn reduce(action: &[f32], state: Option<&[f32]>, shape: Shape) -> Features {
    let Shape { n, a_dim, s_dim } = shape;
    // Plain loops, no iterator adapters: a closure is a function of its own, compiled for the
    // baseline even when its caller is the AVX2 copy.
    let a = Columns::of(action, n, a_dim);
    let mut scratch = signal::Scratch::default();
    let mut signal = Vec::with_capacity(a_dim);
    let mut action_moments = Vec::with_capacity(a_dim);
    let mut cols = Vec::with_capacity(a_dim);
    for d in 0..a_dim {
        cols.push(a.col(d));
    }
    // Where the action's dimensions leave a rest together (a teleoperator's input starting).
    let onsets = returns::onsets(&cols, n);
    for d in 0..a_dim {
        signal.push(signal::dim_signal(a.col(d), &onsets, &mut scratch));
        action_moments.push(moments(a.col(d)));
    }
    let mut fits = Vec::new();
    let mut state_dims = Vec::new();
    if let Some(state) = state {
        let s = Columns::of(state, n, s_dim);
        let mut scratch = alignment::Scratch::default();
        fits.reserve_exact(a_dim.min(s_dim));
        for d in 0..a_dim.min(s_dim) {
            fits.push(alignment::fit_dim(a.col(d), s.col(d), &mut scratch));
        }
        state_dims.reserve_exact(s_dim);
        for d in 0..s_dim {
            let x = s.col(d);
            let (lo, hi) = signal::bounds(x);
            let (run, unchanged) = signal::held(x);
            state_dims.push(StateDim {
                mean: columns::sum(x) / n.max(1) as f64,
                lo,
                hi,
                run,
                unchanged,
            });
        }
    }
    let signature = duplicates::signature(&a).into_boxed_slice();
    Features {
        n,
        signal: signal.into_boxed_slice(),
        fits: fits.into_boxed_slice(),
        action: action_moments.into_boxed_slice(),
        state: state_dims.into_boxed_slice(),
        signature,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tracking episode with a frozen stretch, a spike and a non-finite value.
    fn episode(n: usize, dims: usize, seed: u64) -> (Vec<f32>, Vec<f32>) {
        let mut r = seed;
        let mut noise = move || {
            r = r
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (r >> 40) as f32 / (1u64 << 24) as f32 - 0.5
        };
        let mut action = vec![0.0f32; n * dims];
        let mut state = vec![0.0f32; n * dims];
        for d in 0..dims {
            let mut x = 0.0f32;
            for t in 0..n {
                let a = (t as f32 * 0.05 * (d + 1) as f32).sin() + 0.01 * noise();
                action[t * dims + d] = if d == 1 && (100..200).contains(&t) {
                    0.25
                } else {
                    a
                };
                state[t * dims + d] = x;
                x += 0.3 * (a - x);
            }
        }
        action[(n / 3) * dims] += 3.0;
        action[(n / 2) * dims + dims - 1] = f32::NAN;
        (action, state)
    }

    /// The AVX2 copy and the baseline reduce an episode to the same bits.
    #[test]
    fn avx2_and_baseline_agree_bit_for_bit() {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            for (n, dims, seed) in [(400, 14, 1), (157, 3, 2), (41, 1, 3), (7, 2, 4)] {
                let (a, s) = episode(n, dims, seed);
                let shape = Shape {
                    n,
                    a_dim: dims,
                    s_dim: dims,
                };
                let base = reduce(&a, Some(&s), shape);
                // SAFETY: the CPU has AVX2 (checked just above).
                let avx2 = unsafe { features_avx2(&a, Some(&s), shape) };
                // Debug prints every float exactly (the shortest text that reads back the
                // same bits, with its sign).
                assert_eq!(format!("{base:?}"), format!("{avx2:?}"), "n {n}");
            }
        }
    }
}
