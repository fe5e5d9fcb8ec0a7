//! Checks every episode passes whatever adapter read it: channels as long as the episode,
//! finite values in low-dimensional channels, and finite timestamps, one per step. Runs inside the
//! episode jobs, so a bad step is found during the one read of the source.
//!
//! At open, the adapters that read an episode's keys' lengths from their headers check that
//! they agree ([`same_length`]).

use super::{ChannelData, Episode, Manifest};
use crate::error::{Error, Result};
use crate::spec::NonFinite;

/// What to do with an episode: keep it, or leave it out for the given reason
/// (`[audit] non_finite = "exclude_episode"`).
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    Keep,
    Exclude(String),
}

/// `place` names the source and episode (`data.zarr: episode 3`).
pub fn episode(
    episode: &Episode,
    manifest: &Manifest,
    non_finite: NonFinite,
    place: &str,
) -> Result<Verdict> {
    for (c, (ch, values)) in manifest.channels.iter().zip(&episode.channels).enumerate() {
        // A training mixture's low-dim rows come at their source's own width (unpadded).
        let (len, width) = match values {
            ChannelData::Lowdim(v) => (v.len(), manifest.own_width(c, episode.id)),
            ChannelData::Image(v) => (v.len(), ch.width()),
        };
        if len != episode.len * width {
            return Err(Error::source(format!(
                "{place}: channel `{}` (`{}`) has {} steps but the episode has {}",
                ch.name,
                ch.key,
                len / width.max(1),
                episode.len
            )));
        }
        if let ChannelData::Lowdim(v) = values {
            if let Some(i) = first_non_finite(v) {
                let what = format!(
                    "channel `{}` (`{}`) holds {} at step {}, dimension {}",
                    ch.name,
                    ch.key,
                    v[i],
                    i / width,
                    i % width
                );
                return match non_finite {
                    NonFinite::Error => Err(Error::source(format!(
                        "{place}: {what}; set `[audit] non_finite = \"exclude_episode\"` to leave such episodes out"
                    ))),
                    NonFinite::ExcludeEpisode => Ok(Verdict::Exclude(what)),
                };
            }
        }
    }
    if let Some(t) = &episode.timestamps {
        if t.len() != episode.len {
            return Err(Error::source(format!(
                "{place}: {} timestamps for {} steps",
                t.len(),
                episode.len
            )));
        }
        if let Some(i) = t.iter().position(|x| !x.is_finite()) {
            return Err(Error::source(format!(
                "{place}: timestamp at step {i} is {}",
                t[i]
            )));
        }
        // Repeated or decreasing timestamps are the audit's business (`[audit] non_monotonic`).
    }
    Ok(Verdict::Keep)
}

/// The position of the first value that is not finite. Blocks of values are tested without a
/// branch per value (the test vectorizes), and only a block that holds one is searched.
fn first_non_finite(values: &[f32]) -> Option<usize> {
    const BLOCK: usize = 256;
    let found = |block: &[f32]| block.iter().fold(false, |any, x| any | !x.is_finite());
    let at = values.chunks(BLOCK).position(found)?;
    let start = at * BLOCK;
    (values[start..].iter().position(|x| !x.is_finite())).map(|i| start + i)
}

/// Records the first key's number of steps in `len`; an error when a later key has another.
pub fn same_length<'a>(
    len: &mut Option<(usize, &'a str)>,
    here: &str,
    key: &'a str,
    steps: usize,
) -> Result<()> {
    match *len {
        None => *len = Some((steps, key)),
        Some((n, first_key)) if n != steps => {
            return Err(Error::source(format!(
                "{here}: `{first_key}` has {n} steps but `{key}` has {steps}"
            )))
        }
        Some(_) => {}
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_non_finite_value_wherever_it_is() {
        let clean = vec![1.5f32; 1000];
        assert_eq!(first_non_finite(&clean), None);
        let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
        for (at, value) in [0, 255, 256, 700, 999]
            .into_iter()
            .zip(bad.into_iter().cycle())
        {
            let mut v = clean.clone();
            v[at] = value;
            // A later one in the same block, and one in a later block, do not move it.
            v[(at + 3).min(999)] = f32::NAN;
            v[999] = f32::NAN;
            assert_eq!(first_non_finite(&v), Some(at));
        }
    }
}
