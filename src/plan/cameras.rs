//! `[profiles.<name>.cameras.<channel>]` against the source: the camera must be an image
//! channel, and its `size` may enlarge the source's frames only with `upscale = true`. A resized
//! camera's [`ProfileChannel`] takes the stored shape, which every output then shows (container
//! metadata, `stats.json`, the loader, the estimates), and the [`CameraResize`] that `exec`
//! applies to each frame as it is read.

use serde::Serialize;

use super::ProfileChannel;
use crate::error::Result;
use crate::resize::Resize;
use crate::source::{ChannelKind, Manifest};
use crate::spec::{dotted_key, LoadedSpec, Profile};

/// How one camera's frames are resized: Diffusion Policy's cover-and-crop (see
/// [`crate::resize`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct CameraResize {
    /// The source's frames, `[H, W]`.
    pub from: [usize; 2],
    /// The stored frames, `[H, W]`.
    pub size: [usize; 2],
    /// The size that covers `size` keeping the aspect ratio, before the centre crop.
    pub scaled: [usize; 2],
    /// `area` (shrinking), `linear` (enlarging) or `copy` (only cropped).
    pub method: &'static str,
}

impl CameraResize {
    /// The resize of frames with `colors` values per pixel.
    pub fn resize(&self, colors: usize) -> Resize {
        Resize::cover(self.from, self.size, colors)
    }
}

/// Applies the profile's cameras to its `channels` (manifest order), or says which key is wrong.
pub(super) fn apply(
    spec: &LoadedSpec,
    manifest: &Manifest,
    profile: &Profile,
    channels: &mut [ProfileChannel],
) -> Result<()> {
    let name = &profile.name;
    let images: Vec<&str> = manifest
        .channels
        .iter()
        .filter(|c| c.kind == ChannelKind::Image)
        .map(|c| c.name.as_str())
        .collect();
    for (camera, wanted) in &profile.cameras {
        let at = ["profiles", name.as_str(), "cameras", camera.as_str()];
        let found = manifest.channels.iter().position(|c| &c.name == camera);
        let Some(c) = found.filter(|&c| manifest.channels[c].kind == ChannelKind::Image) else {
            let what = match found {
                Some(c) => format!(
                    "a low-dimensional channel of the source (per-step shape {:?})",
                    manifest.channels[c].shape
                ),
                None => "not a channel of the source".into(),
            };
            let help = if images.is_empty() {
                "the source has no image channel to resize".to_string()
            } else {
                format!("image channels: `{}`", images.join("`, `"))
            };
            return Err(spec.error_at(
                &at,
                format!(
                    "`{}` names `{camera}`, which is {what}: only image channels (H, W, C) can be resized",
                    dotted_key(&at)
                ),
                Some(help),
            ));
        };
        let shape = &manifest.channels[c].shape;
        let (from, colors) = ([shape[0], shape[1]], shape[2]);
        let size = wanted.size;
        if (size[0] > from[0] || size[1] > from[1]) && !wanted.upscale {
            let key = [
                "profiles",
                name.as_str(),
                "cameras",
                camera.as_str(),
                "size",
            ];
            return Err(spec.error_at(
                &key,
                format!(
                    "`{}` = {size:?} is larger than the source's `{camera}` frames, {from:?} (H, W): frames are only enlarged with `upscale = true`",
                    dotted_key(&key)
                ),
                Some(format!(
                    "choose a size of at most {from:?}, or set `upscale = true` in `[{}]`",
                    dotted_key(&at)
                )),
            ));
        }
        if size == from {
            continue;
        }
        let resize = Resize::cover(from, size, colors);
        let ch = &mut channels[c];
        ch.shape = resize.shape().to_vec();
        ch.resize = Some(CameraResize {
            from,
            size,
            scaled: resize.scaled(),
            method: resize.method(),
        });
    }
    Ok(())
}
