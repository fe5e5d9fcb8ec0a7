//! Where each channel's per-step array lives in a profile's data container, decided once here
//! (from the naming rule of [`crate::spec::export_keys`]) so that every sink, `meta.json` and the
//! loader agree.
//!
//! | format | action | other channels |
//! | --- | --- | --- |
//! | `hdf5` | `data/action` | `data/<chunkc name>` |
//! | `parquet` | column `action` | column `<chunkc name>` |
//! | `zarr` | `data/<name>` | `data/<name>` |
//! | `robomimic_hdf5` | `data/demo_<i>/actions` | `data/demo_<i>/obs/<name>` (and `next_obs/<name>`) |
//! | `act_episodes` | `action` | `observations/<name>`, images `observations/images/<name>` |
//!
//! `<name>` is the channel's export name, `<i>` the stored episode position (ACT: in the file
//! `episode_<i>.hdf5`). The spec checks catch collisions by name; this check, with the source's
//! kinds and ACT's state channel known, is the authoritative one.

use super::{ProfileChannel, ProfilePlan};
use crate::error::Result;
use crate::source::ChannelKind;
use crate::spec::{export_keys, LoadedSpec, OutputFormat, Profile};

/// The low-dimensional observation ACT reads as `qpos` (and whose statistics are `qpos_*`):
/// `observation.qpos`, else `observation.state`, else the first vector-valued observation.
pub fn state_channel(channels: &[ProfileChannel]) -> Option<&ProfileChannel> {
    let lowdim = |c: &&ProfileChannel| c.kind == ChannelKind::Lowdim && c.shape.len() <= 1;
    let obs = || {
        channels
            .iter()
            .filter(lowdim)
            .filter(|c| c.name != "action")
    };
    obs()
        .find(|c| c.name == "observation.qpos")
        .or_else(|| obs().find(|c| c.name == "observation.state"))
        .or_else(|| obs().next())
}

impl ProfilePlan {
    /// The profile's robot state, resolved once by [`state_channel`]: the channel ACT calls
    /// `qpos` (and its statistics `qpos_*`), openpi `state`, and the native exports name
    /// after it. Sinks and templates ask here, never decide it themselves.
    pub fn state_channel(&self) -> Option<&ProfileChannel> {
        state_channel(&self.channels)
    }
}

/// Fills in `export` and `array` of every channel of `profile`.
pub fn assign(spec: &LoadedSpec, profile: &Profile, channels: &mut [ProfileChannel]) -> Result<()> {
    let format = profile.format;
    if !export_keys::renames(format) {
        for ch in channels.iter_mut() {
            ch.export = None;
            ch.array = match format {
                OutputFormat::Parquet => ch.name.clone(),
                _ => format!("data/{}", ch.name),
            };
        }
        return Ok(());
    }
    let state = state_channel(channels).map(|c| c.name.clone());
    let mapped = spec.channel_map();
    let names = export_keys::export_names(
        format,
        channels
            .iter()
            .map(|c| (c.name.as_str(), mapped[c.name.as_str()])),
        &profile.export_keys,
        state.as_deref(),
    );
    for (ch, n) in channels.iter_mut().zip(&names) {
        ch.array = match (format, ch.name == "action", ch.kind) {
            (OutputFormat::Zarr, _, _) => format!("data/{}", n.name),
            (OutputFormat::RobomimicHdf5, true, _) => format!("data/demo_<i>/{}", n.name),
            (OutputFormat::RobomimicHdf5, false, _) => format!("data/demo_<i>/obs/{}", n.name),
            (_, true, _) => n.name.clone(),
            (_, false, ChannelKind::Image) => format!("observations/images/{}", n.name),
            (_, false, ChannelKind::Lowdim) => format!("observations/{}", n.name),
        };
        ch.export = Some(n.name.clone());
    }
    // Two arrays at one path, or an array where another one's group is.
    for (i, b) in channels.iter().enumerate() {
        let clash = channels[..i].iter().find(|a| {
            a.array == b.array
                || b.array.starts_with(&format!("{}/", a.array))
                || a.array.starts_with(&format!("{}/", b.array))
        });
        if let Some(a) = clash {
            let name = &profile.name;
            return Err(spec.error_at(
                &["profiles", name, "export_keys", &b.name],
                format!(
                    "profile `{name}` (`{}`) would store `{}` at `{}` and `{}` at `{}`, which cannot both exist",
                    format.name(),
                    a.name,
                    a.array,
                    b.name,
                    b.array
                ),
                Some(format!(
                    "give `{}` its own name in `[profiles.{name}.export_keys]`",
                    b.name
                )),
            ));
        }
    }
    Ok(())
}
