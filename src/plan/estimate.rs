//! The files a profile writes and an upper bound of their sizes, as `chunkc plan` shows them
//! before anything is read.

use super::{PlannedFile, ProfileChannel, SplitCounts, LOADER_FILE, META_FILE, STATS_FILE};
use crate::source::{ChannelKind, Manifest};
use crate::spec::{Layout, OutputFormat, Profile};

/// Bytes one step of a channel takes in the output (a resized camera's at its stored size).
fn step_bytes(ch: &ProfileChannel) -> u64 {
    let width = ch.shape.iter().product::<usize>() as u64;
    match ch.kind {
        ChannelKind::Lowdim => 4 * width,
        ChannelKind::Image => width,
    }
}

/// Entries per statistic: one per dimension, or one per colour channel for images.
fn stats_dims(ch: &ProfileChannel) -> usize {
    match ch.kind {
        ChannelKind::Lowdim => ch.shape.iter().product(),
        ChannelKind::Image => *ch.shape.last().unwrap_or(&1),
    }
}

/// The files of `profile` with their estimated sizes; `channels` are its channels as stored,
/// `steps` and `counts` its steps and samples at its rate.
pub(super) fn planned_files(
    manifest: &Manifest,
    channels: &[ProfileChannel],
    profile: &Profile,
    steps: usize,
    counts: SplitCounts,
) -> Vec<PlannedFile> {
    let data_bytes: u64 = channels
        .iter()
        .map(|c| step_bytes(c) * steps as u64)
        .sum::<u64>()
        + 32 * (counts.train.unwrap_or(steps) + counts.val.unwrap_or(0)) as u64
        + 16 * manifest.episodes.len() as u64;
    let data_path: String = profile.format.files().planned.into();
    vec![
        PlannedFile {
            path: data_path,
            estimated_bytes: data_bytes + chunk_bytes(channels, profile, counts) + 8192,
        },
        PlannedFile {
            path: LOADER_FILE.into(),
            estimated_bytes: 12_000,
        },
        PlannedFile {
            path: META_FILE.into(),
            estimated_bytes: 2048 + 24 * manifest.episodes.len() as u64,
        },
        PlannedFile {
            path: STATS_FILE.into(),
            estimated_bytes: 512
                + channels
                    .iter()
                    .map(|c| 180 * stats_dims(c) as u64)
                    .sum::<u64>(),
        },
    ]
}

/// `/chunks` of the HDF5 layouts that add it: K (or obs_history) rows per window.
fn chunk_bytes(channels: &[ProfileChannel], profile: &Profile, counts: SplitCounts) -> u64 {
    let windows = (counts.train.unwrap_or(0) + counts.val.unwrap_or(0)) as u64;
    let (k, h) = (u64::from(profile.chunk), u64::from(profile.obs_history));
    match (profile.format, profile.layout) {
        (OutputFormat::Hdf5, Layout::Materialized) => channels
            .iter()
            .filter(|c| c.kind == ChannelKind::Lowdim)
            .map(|c| {
                let steps = if c.name == "action" { k } else { h };
                windows * steps * (step_bytes(c) + 1)
            })
            .sum(),
        (OutputFormat::Hdf5, Layout::Virtual) => windows * k / 8 + 4096 * k,
        _ => 0,
    }
}
