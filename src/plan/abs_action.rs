//! `abs_action = true` on a Diffusion Policy profile: the rotation of each arm's axis-angle to
//! 6D rows, as Diffusion Policy's robomimic datasets convert their absolute actions.

use super::transform_errors::At;
use crate::error::Result;
use crate::rotation::{Layout6d, RotationKind};
use crate::source::Manifest;
use crate::spec::{Preset, Profile};
use crate::transform::{Op, Transform};

/// `abs_action = true`: Diffusion Policy's rotation per arm, axis-angle to rows 6D.
pub(super) fn transforms(
    at: &At,
    manifest: &Manifest,
    profile: &Profile,
) -> Result<Vec<Transform>> {
    if !profile.abs_action {
        return Ok(Vec::new());
    }
    let dp = matches!(
        profile.preset,
        Some(Preset::DiffusionPolicy | Preset::DiffusionPolicyHighfreq | Preset::Dp3)
    );
    if !dp {
        return Err(at.key(
            &["abs_action"],
            format!(
                "profiles.{}.abs_action is Diffusion Policy's setting: it needs `preset = \"diffusion_policy\"` (or one of its variants)",
                profile.name
            ),
            None,
        ));
    }
    let c = manifest
        .channels
        .iter()
        .position(|c| c.name == "action")
        .expect("every source maps `action`");
    let width = manifest.channels[c].width();
    let arms: &[usize] = match width {
        7 => &[3],
        // The second arm first, so that the first arm's dims still hold.
        14 => &[10, 3],
        _ => {
            return Err(at.key(
                &["abs_action"],
                format!(
                    "profiles.{}.abs_action needs actions of [pos3, axis_angle3, gripper1] per arm, 7 or 14 wide; `action` has {width} values per step",
                    profile.name
                ),
                None,
            ))
        }
    };
    Ok(arms
        .iter()
        .map(|&start| Transform {
            channel: "action".into(),
            channel_index: c,
            sources: None,
            op: Op::Rotation {
                dims: [start, start + 3],
                from: RotationKind::AxisAngle,
                to: RotationKind::Rotation6d,
                euler: None,
                convention: None,
                layout: Layout6d::Rows,
            },
        })
        .collect())
}
