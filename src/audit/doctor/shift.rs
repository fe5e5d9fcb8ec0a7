//! Distribution shift across the recording: the episodes of one session (a recalibrated sensor,
//! another operator, a moved camera rig) differ from the rest, so a random split hides what a
//! deployment will see.
//!
//! Per channel dimension, each episode's mean; the episodes in recording order cut into four
//! quarters; a quarter whose median episode mean lies more than `shift_threshold` robust
//! standard deviations (1.4826 × MAD of the episode means) from the median of all episodes is a
//! shift. It is a dataset-wide finding (a warning and the report's plot), not a per-episode flag.
//! Needs at least [`MIN_EPISODES`].

pub const MIN_EPISODES: usize = 40;
pub const QUARTERS: usize = 4;

/// The quarters' deviations of one dimension's episode means (in recording order), or None when
/// there are too few episodes or the means do not vary.
pub fn deviations(means: &[f64]) -> Option<Vec<f64>> {
    let n = means.len();
    if n < MIN_EPISODES {
        return None;
    }
    let centre = super::stats::median(means.iter().copied());
    let sigma = super::stats::mad_sigma(means);
    if sigma.is_nan() || sigma <= 0.0 {
        return None;
    }
    Some(
        (0..QUARTERS)
            .map(|q| {
                let part = &means[q * n / QUARTERS..(q + 1) * n / QUARTERS];
                (super::stats::median(part.iter().copied()) - centre) / sigma
            })
            .collect(),
    )
}
