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
    for (ch, values) in manifest.channels.iter().zip(&episode.channels) {
        let width = ch.width().max(1);
        let len = match values {
            ChannelData::Lowdim(v) => v.len(),
            ChannelData::Image(v) => v.len(),
        };
        if len != episode.len * width {
            return Err(Error::source(format!(
                "{place}: channel `{}` (`{}`) has {} steps but the episode has {}",
                ch.name,
                ch.key,
                len / width,
                episode.len
            )));
        }
        if let ChannelData::Lowdim(v) = values {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
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
