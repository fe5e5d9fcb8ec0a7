//! What one episode reduces to for the doctor: per-dimension signal features, the alignment fits,
//! moments, the state's ranges and runs, and the duplicate signature. Computed once per episode,
//! in parallel; every check then judges these, never the raw values.

use super::columns::{self, Columns};
use super::{alignment, duplicates, signal};

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

/// What an episode of `n` steps reduces to, from its action rows (`a_dim` wide) and state rows
/// (`s_dim` wide).
pub(super) fn features(
    action: &[f32],
    state: Option<&[f32]>,
    n: usize,
    a_dim: usize,
    s_dim: usize,
) -> Features {
    let a = Columns::of(action, n, a_dim);
    let s = state.map(|s| Columns::of(s, n, s_dim));
    let mut scratch = signal::Scratch::default();
    let signal = (0..a_dim)
        .map(|d| signal::dim_signal(a.col(d), &mut scratch))
        .collect();
    let mut scratch = alignment::Scratch::default();
    let fits = match &s {
        Some(s) => (0..a_dim.min(s_dim))
            .map(|d| alignment::fit_dim(a.col(d), s.col(d), &mut scratch))
            .collect(),
        None => Box::default(),
    };
    let action_moments = (0..a_dim).map(|d| moments(a.col(d))).collect();
    let state = match &s {
        Some(s) => (0..s_dim)
            .map(|d| {
                let x = s.col(d);
                let (lo, hi) = signal::bounds(x);
                let (run, unchanged) = signal::held(x);
                StateDim {
                    mean: moments(x).mean,
                    lo,
                    hi,
                    run,
                    unchanged,
                }
            })
            .collect(),
        None => Box::default(),
    };
    Features {
        n,
        signal,
        fits,
        action: action_moments,
        state,
        signature: duplicates::signature(&a).into_boxed_slice(),
    }
}
