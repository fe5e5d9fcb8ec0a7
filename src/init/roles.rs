//! Decides what each key a source offers is for, and the chunkc channel name it gets: the one
//! `action`, the robot state the presets call `observation.state`, cameras, point clouds, other
//! observations, and the bookkeeping columns a spec never maps (the rows are [`super::key_role`]'s).
//!
//! Which key is the state is [`super::state`]'s to decide.
//!
//! Names follow the sources' own conventions: a LeRobot dataset's keys are already chunkc names
//! and are kept; elsewhere one camera is `observation.image` (Push-T's and Diffusion Policy's
//! name), several are `observation.images.<leaf>` (LeRobot's), the state is
//! `observation.state`, any other observation `observation.<leaf>`.

use super::key_role::{leaf, KeyRole, Role};
use crate::source::mapping::KeyInfo;
use crate::source::{kind_for_shape, ChannelKind};
use crate::spec::SourceFormat;

fn clean(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The channel name a key that is not mapped would take when a user uncomments it: a LeRobot
/// `observation.*` key keeps its name, as mapped ones do.
fn suggested_name(r: &KeyRole, format: SourceFormat) -> String {
    if format == SourceFormat::Lerobot && r.key.starts_with("observation.") {
        r.key.clone()
    } else if r.role.is_camera() {
        format!("observation.images.{}", clean(leaf(&r.key)))
    } else {
        format!("observation.{}", clean(leaf(&r.key)))
    }
}

const BOOKKEEPING: &[&str] = &[
    "timestamp",
    "timestamps",
    "frame_index",
    "episode_index",
    "index",
    "task_index",
    "is_first",
    "is_last",
    "is_terminal",
    "discount",
    "reward",
    "rewards",
    "done",
    "dones",
    "success",
    // ALOHA's JPEG episodes: each frame's compressed length, per camera.
    "compress_len",
];

/// Whether a key sits in an observation group (`obs/…`, `observations/…`,
/// `steps/observation/…`, LeRobot's `observation.…`) or is a Diffusion Policy zarr array (whose
/// arrays are all per-step data).
fn in_observation_group(key: &str, format: SourceFormat) -> bool {
    format == SourceFormat::DiffusionPolicyZarr
        || key
            .split(['/', '.'])
            .any(|p| matches!(p, "obs" | "observation" | "observations"))
}

fn is_point_cloud(shape: &[usize], key: &str) -> bool {
    let named = key.contains("point_cloud") || key.contains("pointcloud") || leaf(key) == "pcd";
    shape.len() == 2 && matches!(shape[1], 3 | 6) && (shape[0] >= 16 || named)
}

/// Decides every key's role and channel name.
// Long function: the action, then the state, then every other channel's name, each pass seeing what the one before took.
pub fn assign(format: SourceFormat, keys: &[KeyInfo], robosuite_clock: bool) -> Vec<KeyRole> {
    let mut rows: Vec<KeyRole> = keys
        .iter()
        .map(|k| KeyRole {
            key: k.key.clone(),
            shape: k.shape.clone(),
            dtype: k.dtype.clone(),
            role: first_role(format, k),
            channel: None,
            suggested: None,
            columns: None,
            note: None,
        })
        .collect();

    // The action: the shortest key whose leaf is `action` / `actions`.
    let action = rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.role == Role::Observation || r.role == Role::Unmapped)
        .filter(|(_, r)| matches!(leaf(&r.key), "action" | "actions"))
        .min_by_key(|(_, r)| r.key.len())
        .map(|(i, _)| i);
    if let Some(i) = action {
        rows[i].role = Role::Action;
        rows[i].channel = Some("action".into());
    }

    // The state by its name, before the other keys take theirs.
    super::state::by_name(&mut rows, robosuite_clock);

    let cameras = rows.iter().filter(|r| r.role.is_camera()).count();
    let lerobot = format == SourceFormat::Lerobot;
    let mut taken: Vec<String> = rows.iter().filter_map(|r| r.channel.clone()).collect();
    for r in rows.iter_mut().filter(|r| r.channel.is_none()) {
        let mappable = matches!(
            r.role,
            Role::Image | Role::Video | Role::PointCloud | Role::Observation
        );
        let name = match r.role {
            _ if !mappable => None,
            _ if lerobot && r.key.starts_with("observation.") => Some(r.key.clone()),
            Role::Image | Role::Video if cameras == 1 => Some("observation.image".into()),
            Role::Image | Role::Video => {
                Some(format!("observation.images.{}", clean(leaf(&r.key))))
            }
            Role::PointCloud => Some(format!("observation.{}", clean(leaf(&r.key)))),
            Role::Observation => Some(format!("observation.{}", clean(leaf(&r.key)))),
            _ => None,
        };
        let Some(mut name) = name else { continue };
        if taken.contains(&name) {
            // Two leaves alike (`obs/a/pos`, `obs/b/pos`): the whole key names it.
            name = format!("observation.{}", clean(&r.key.replace('/', "_")));
        }
        if taken.contains(&name) {
            continue;
        }
        taken.push(name.clone());
        r.channel = Some(name);
    }
    // With no state yet, the one low-dim key left is taken for it (a guess, said in its note).
    super::state::claim_the_only_one(&mut rows);
    for r in rows.iter_mut().filter(|r| r.role == Role::Unmapped) {
        let name = suggested_name(r, format);
        r.note = Some(if robosuite_clock {
            "robosuite records it beside the states; uncomment to observe it".into()
        } else {
            format!("not in an observation group; uncomment to use it as `{name}`")
        });
        r.suggested = Some(name);
    }
    // Everything else a commented line offers (a name two keys wanted, an unusable shape).
    for r in rows.iter_mut().filter(|r| r.role != Role::Bookkeeping) {
        if r.channel.is_none() && r.suggested.is_none() {
            r.suggested = Some(suggested_name(r, format));
        }
    }
    rows
}

/// The role a key has on its own (before the action and the state are picked).
fn first_role(format: SourceFormat, k: &KeyInfo) -> Role {
    if matches!(k.dtype.as_str(), "video") {
        return Role::Video;
    }
    if BOOKKEEPING.contains(&leaf(&k.key)) || k.key.starts_with("next.") {
        return Role::Bookkeeping;
    }
    if k.width() == 0 {
        return Role::Unusable;
    }
    if is_point_cloud(&k.shape, &k.key) {
        return Role::PointCloud;
    }
    match kind_for_shape(&k.shape) {
        Ok(ChannelKind::Image) => Role::Image,
        Ok(ChannelKind::Lowdim) if matches!(leaf(&k.key), "action" | "actions") => {
            Role::Observation
        }
        Ok(ChannelKind::Lowdim) if in_observation_group(&k.key, format) => Role::Observation,
        Ok(ChannelKind::Lowdim) => Role::Unmapped,
        Err(_) => Role::Unusable,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::init::state::STATE;

    fn key(k: &str, shape: &[usize], dtype: &str) -> KeyInfo {
        KeyInfo {
            key: k.into(),
            shape: shape.to_vec(),
            dtype: dtype.into(),
        }
    }

    fn channel(rows: &[KeyRole], k: &str) -> Option<String> {
        rows.iter().find(|r| r.key == k).unwrap().channel.clone()
    }

    #[test]
    fn aloha_keys() {
        let rows = assign(
            SourceFormat::AlohaHdf5,
            &[
                key("action", &[14], "float32"),
                key("observations/qpos", &[14], "float32"),
                key("observations/qvel", &[14], "float32"),
                key("observations/images/top", &[480, 640, 3], "uint8"),
                key("observations/images/left_wrist", &[480, 640, 3], "jpeg"),
            ],
            false,
        );
        assert_eq!(channel(&rows, "action").as_deref(), Some("action"));
        assert_eq!(
            channel(&rows, "observations/qpos").as_deref(),
            Some("observation.state")
        );
        assert_eq!(
            channel(&rows, "observations/qvel").as_deref(),
            Some("observation.qvel")
        );
        assert_eq!(
            channel(&rows, "observations/images/top").as_deref(),
            Some("observation.images.top")
        );
    }

    #[test]
    fn lerobot_keeps_names_and_skips_bookkeeping() {
        let rows = assign(
            SourceFormat::Lerobot,
            &[
                key("action", &[2], "float32"),
                key("observation.state", &[2], "float32"),
                key("observation.image", &[96, 96, 3], "video"),
                key("timestamp", &[1], "float32"),
                key("next.reward", &[1], "float32"),
            ],
            false,
        );
        assert_eq!(
            channel(&rows, "observation.image").as_deref(),
            Some("observation.image")
        );
        assert_eq!(channel(&rows, "timestamp"), None);
        assert_eq!(channel(&rows, "next.reward"), None);
        assert_eq!(rows[2].role, Role::Video);
    }

    #[test]
    fn robomimic_joint_positions_are_the_state() {
        let rows = assign(
            SourceFormat::RobomimicHdf5,
            &[
                key("actions", &[7], "float32"),
                key("obs/robot0_eef_pos", &[3], "float64"),
                key("obs/robot0_joint_pos", &[7], "float64"),
                key("obs/agentview_image", &[84, 84, 3], "uint8"),
            ],
            false,
        );
        assert_eq!(
            channel(&rows, "obs/robot0_joint_pos").as_deref(),
            Some("observation.state")
        );
        assert_eq!(
            channel(&rows, "obs/robot0_eef_pos").as_deref(),
            Some("observation.robot0_eef_pos")
        );
        assert_eq!(
            channel(&rows, "obs/agentview_image").as_deref(),
            Some("observation.image")
        );
    }

    #[test]
    fn robosuite_states_lose_the_clock() {
        let rows = assign(
            SourceFormat::RobomimicHdf5,
            &[
                key("actions", &[7], "float32"),
                key("states", &[32], "float64"),
                key("joint_torques", &[7], "float64"),
            ],
            true,
        );
        let s = rows.iter().find(|r| r.key == "states").unwrap();
        assert_eq!(s.columns, Some([1, 32]));
        assert_eq!(channel(&rows, "joint_torques"), None);
        assert_eq!(rows[2].role, Role::Unmapped);
    }

    // The robot state, as `assign` has `super::state` pick it.

    fn row<'a>(rows: &'a [KeyRole], k: &str) -> &'a KeyRole {
        rows.iter().find(|r| r.key == k).unwrap()
    }

    #[test]
    fn a_state_outside_any_group_is_guessed_and_says_so() {
        // The dexterous hand: LeRobot v3.0 with `actions` / `state` / `image`.
        let rows = assign(
            SourceFormat::Lerobot,
            &[
                key("actions", &[34], "float32"),
                key("state", &[34], "float32"),
                key("image", &[480, 640, 3], "video"),
                key("timestamp", &[1], "float32"),
            ],
            false,
        );
        let s = row(&rows, "state");
        assert_eq!(s.channel.as_deref(), Some(STATE));
        assert_eq!(s.role, Role::State);
        assert!(s.note.as_deref().unwrap().contains("GUESSED"));
        assert_eq!(
            row(&rows, "image").channel.as_deref(),
            Some("observation.image")
        );
    }

    #[test]
    fn the_only_low_dim_key_becomes_the_state() {
        let rows = assign(
            SourceFormat::Lerobot,
            &[
                key("actions", &[6], "float32"),
                key("joints", &[6], "float32"),
                key("frame_index", &[1], "int64"),
            ],
            false,
        );
        let s = row(&rows, "joints");
        assert_eq!(s.channel.as_deref(), Some(STATE));
        assert!(s.note.as_deref().unwrap().contains("only low-dim key"));
        assert_eq!(s.suggested, None);
    }

    #[test]
    fn two_candidates_are_not_guessed_between() {
        let rows = assign(
            SourceFormat::Lerobot,
            &[
                key("actions", &[6], "float32"),
                key("joints", &[6], "float32"),
                key("velocities", &[6], "float32"),
            ],
            false,
        );
        assert!(rows.iter().all(|r| r.channel.as_deref() != Some(STATE)));
        assert_eq!(
            row(&rows, "joints").suggested.as_deref(),
            Some("observation.joints")
        );
    }

    #[test]
    fn a_named_state_in_a_group_is_not_a_guess() {
        let rows = assign(
            SourceFormat::Lerobot,
            &[
                key("action", &[2], "float32"),
                key("observation.state", &[2], "float32"),
                key("observation.environment_state", &[16], "float32"),
            ],
            false,
        );
        let s = row(&rows, "observation.state");
        assert_eq!(
            (s.channel.as_deref(), s.note.as_deref()),
            (Some(STATE), None)
        );
        assert_eq!(
            row(&rows, "observation.environment_state")
                .channel
                .as_deref(),
            Some("observation.environment_state")
        );
    }
}
