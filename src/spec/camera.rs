//! `[profiles.<name>.cameras.<channel>]`: how a profile stores one camera's frames, as written
//! ([`CameraSpec`]) and as resolved ([`Camera`]). Types only: the checks that need no source are
//! in `validate_camera`, the ones against the source's frames in the plan.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// One camera (an image channel of `[source.channels]`, named by the table's key) as this
/// profile stores it. Frames are resized once, as they are read, before they are written
/// and before the image statistics are computed (the statistics describe the stored frames).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// `[H, W]`: the stored frame size in pixels, height first, both positive. Frames are
    /// resized as Diffusion Policy resizes its cameras (`get_image_transform`): scaled to cover
    /// `H × W` keeping the aspect ratio (OpenCV's area interpolation when shrinking, bilinear
    /// when enlarging), then cropped to `H × W` in the middle. Every output's image shapes (its
    /// metadata, `stats.json`, the loader, `chunkc plan`'s estimates) are the stored size.
    pub size: Vec<i64>,
    /// Allow a `size` larger than the source's frames in either dimension (enlarged by bilinear
    /// interpolation). Without it, such a size is an error.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub upscale: bool,
}

/// A camera's stored size, resolved (and checked: see `validate_camera`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Camera {
    /// `[H, W]`.
    pub size: [usize; 2],
    pub upscale: bool,
}

impl CameraSpec {
    /// `[H, W]` when `size` is two positive integers.
    pub fn size_hw(&self) -> Option<[usize; 2]> {
        match self.size.as_slice() {
            &[h, w] if h > 0 && w > 0 => Some([usize::try_from(h).ok()?, usize::try_from(w).ok()?]),
            _ => None,
        }
    }
}

/// The cameras of a chain of profiles (nearest first), merged: a camera's table in a nearer
/// profile replaces a farther one's. Malformed sizes are left out (validation reports them).
pub(crate) fn merged<'a>(
    chain: impl DoubleEndedIterator<Item = &'a Option<BTreeMap<String, CameraSpec>>>,
) -> BTreeMap<String, Camera> {
    let mut out = BTreeMap::new();
    for map in chain.rev().flatten() {
        for (name, spec) in map {
            match spec.size_hw() {
                Some(size) => {
                    out.insert(
                        name.clone(),
                        Camera {
                            size,
                            upscale: spec.upscale,
                        },
                    );
                }
                None => {
                    out.remove(name);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cameras(entries: &[(&str, &[i64], bool)]) -> Option<BTreeMap<String, CameraSpec>> {
        let spec = |size: &[i64], upscale| CameraSpec {
            size: size.to_vec(),
            upscale,
        };
        Some(
            entries
                .iter()
                .map(|&(name, size, upscale)| (name.to_string(), spec(size, upscale)))
                .collect(),
        )
    }

    #[test]
    fn nearer_profiles_replace_a_cameras_table() {
        // Nearest first: the child's `top` replaces the base's; the base's `wrist` stays.
        let child = cameras(&[("top", &[120, 160], true)]);
        let base = cameras(&[("top", &[240, 320], false), ("wrist", &[96, 96], false)]);
        let merged = merged([&child, &base].into_iter());
        let top = Camera {
            size: [120, 160],
            upscale: true,
        };
        let wrist = Camera {
            size: [96, 96],
            upscale: false,
        };
        assert_eq!(
            merged,
            [("top".into(), top), ("wrist".into(), wrist)].into()
        );
    }

    #[test]
    fn only_two_positive_integers_are_a_size() {
        let size = |s: &[i64]| {
            CameraSpec {
                size: s.to_vec(),
                upscale: false,
            }
            .size_hw()
        };
        assert_eq!(size(&[240, 320]), Some([240, 320]));
        for bad in [&[0, 320][..], &[-240, 320], &[240], &[240, 320, 3], &[]] {
            assert_eq!(size(bad), None, "{bad:?}");
        }
    }
}
