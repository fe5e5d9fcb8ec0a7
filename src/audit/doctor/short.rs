//! Episodes shorter than a profile's action chunk: every sample of such an episode needs padding
//! past its end, and what the padding does depends on the profile (`edge` repeats the last
//! action, `zero` pads zeros in raw units, `mask` pads steps masked by `action_is_pad`,
//! `truncate` leaves the episode without a single sample).

use crate::spec::{Padding, Profile};

/// The episode's steps at the profile's rate.
pub fn steps_at(n: usize, source_fps: f64, profile: &Profile) -> usize {
    let fps = profile.fps.unwrap_or(source_fps);
    if n == 0 {
        return 0;
    }
    ((n - 1) as f64 * fps / source_fps + 1e-9).floor() as usize + 1
}

/// What the profile's padding does with an episode of `steps` under a chunk of `chunk`.
pub fn consequence(padding: Padding, steps: usize, chunk: u32) -> String {
    let missing = chunk as usize - steps.min(chunk as usize);
    match padding {
        Padding::Edge => format!("its chunks repeat the last action for up to {missing} steps"),
        Padding::Zero => format!("its chunks end in up to {missing} zero actions (raw units)"),
        Padding::Mask => format!("its chunks end in up to {missing} masked steps"),
        Padding::Truncate => "it gives no samples at all".into(),
    }
}
