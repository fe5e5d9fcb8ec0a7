//! Without the `video` feature: every entry point fails, naming the feature.

use std::path::Path;

use super::{DecodeFailure, Probe, Timeline, DISABLED};

pub fn probe(_path: &Path) -> Result<Probe, String> {
    Err(DISABLED.into())
}

pub fn timeline(_path: &Path) -> Result<Timeline, String> {
    Err(DISABLED.into())
}

pub fn decode_rows(
    _path: &Path,
    _targets: &[f64],
    _shape: [usize; 3],
    _out: &mut [u8],
) -> Result<(), DecodeFailure> {
    Err(DecodeFailure::Unreadable(DISABLED.into()))
}
