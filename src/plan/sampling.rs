//! How a profile turns episodes into samples: fixed windows, segments or hierarchical chunks,
//! with their spec values checked against the source's channels.

use crate::error::Result;
use crate::source::{ChannelKind, Manifest};
use crate::spec::{LoadedSpec, Profile, SegmentSpec};
use crate::window::segment::SegmentParams;
use crate::window::{Sampling, Window};

/// The sampling of a profile: windows, segments or hierarchical chunks.
pub(super) fn sampling_of(
    spec: &LoadedSpec,
    manifest: &Manifest,
    profile: &Profile,
    fps: f64,
) -> Result<Sampling> {
    let name = &profile.name;
    let lead = match profile.alignment {
        crate::spec::Alignment::Current => 0,
        crate::spec::Alignment::DiffusionPolicy => profile.obs_history as usize - 1,
    };
    let mut window = Window {
        chunk: profile.chunk as usize,
        obs_history: profile.obs_history as usize,
        lead,
        padding: profile.padding,
        stride: profile.stride as usize,
        max_pad_after: profile.executes.map(|e| e.saturating_sub(1) as usize),
    };
    if let Some(seg) = &profile.segment {
        return segment_sampling(spec, manifest, profile, seg, window);
    }
    if let Some(h) = &profile.hierarchy {
        let coarse = (h.coarse_seconds * fps).round() as usize;
        if coarse < window.chunk {
            return Err(spec.error_at(
                &["profiles", name, "hierarchy", "coarse_seconds"],
                format!(
                    "{} s is {coarse} steps at {fps} Hz, shorter than the fine chunk ({} steps)",
                    h.coarse_seconds, window.chunk
                ),
                None,
            ));
        }
        window.lead = 0;
        window.max_pad_after = None;
        return Ok(Sampling::Hierarchy { window, coarse });
    }
    Ok(Sampling::Window { window })
}

/// `[profiles.<name>.segment]`: one sample per segment of the watched channel, padded to the
/// maximum segment length.
fn segment_sampling(
    spec: &LoadedSpec,
    manifest: &Manifest,
    profile: &Profile,
    seg: &SegmentSpec,
    mut window: Window,
) -> Result<Sampling> {
    let name = &profile.name;
    let at = |k: &str| {
        [
            "profiles".to_string(),
            name.clone(),
            "segment".into(),
            k.into(),
        ]
    };
    let Some(c) = manifest.channels.iter().position(|c| c.name == seg.channel) else {
        let key = at("channel");
        let key: Vec<&str> = key.iter().map(String::as_str).collect();
        return Err(spec.error_at(&key, format!("no channel `{}`", seg.channel), None));
    };
    let ch = &manifest.channels[c];
    if ch.kind != ChannelKind::Lowdim {
        let key = at("channel");
        let key: Vec<&str> = key.iter().map(String::as_str).collect();
        return Err(spec.error_at(
            &key,
            format!(
                "`{}` is an image; segment on a low-dimensional channel",
                ch.name
            ),
            None,
        ));
    }
    let width = ch.width();
    let dims: Vec<usize> = match &seg.dims {
        Some(d) => d.iter().map(|&d| d as usize).collect(),
        None => (0..width).collect(),
    };
    if let Some(&bad) = dims.iter().find(|&&d| d >= width) {
        let key = at("dims");
        let key: Vec<&str> = key.iter().map(String::as_str).collect();
        return Err(spec.error_at(
            &key,
            format!(
                "dimension {bad} is out of range: `{}` has {width} values per step",
                ch.name
            ),
            None,
        ));
    }
    let max_length = seg.max_length.unwrap_or(profile.chunk) as usize;
    window.chunk = max_length;
    window.lead = 0;
    window.max_pad_after = None;
    Ok(Sampling::Segment {
        window,
        params: SegmentParams {
            method: seg.method,
            smoothing: seg.smoothing as usize,
            threshold: seg.threshold,
            min_length: seg.min_length as usize,
            max_length,
        },
        channel: c,
        dims,
    })
}
