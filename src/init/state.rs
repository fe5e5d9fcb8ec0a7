//! Which key is the robot state, the `observation.state` every preset's policy reads.
//!
//! In order, the first that finds one wins:
//! 1. a key in an observation group named like a state (`state`, `qpos`, `joint_positions`, …);
//! 2. one in a group whose name ends like one (robomimic's `obs/robot0_joint_pos`);
//! 3. robosuite's `states` without its clock column;
//! 4. a key named like a state outside any group (a LeRobot set whose keys are `actions` /
//!    `state`);
//! 5. once every other key has its name ([`claim_the_only_one`]), the one low-dimensional key
//!    besides the action.
//!
//! 4 and 5 are guesses, and the key's note says so (`GUESSED`): better a guess the spec points
//! at than a spec without observations, which trains a policy on nothing but its own actions.

use super::key_role::{leaf, KeyRole, Role};

/// The presets' name of the robot state.
pub const STATE: &str = "observation.state";

const STATE_NAMES: &[&str] = &[
    "state",
    "qpos",
    "proprio",
    "proprioception",
    "robot_state",
    "joint_positions",
    "joint_pos",
    "joint_position",
];

fn make_state(r: &mut KeyRole, note: Option<&str>) {
    r.role = Role::State;
    r.channel = Some(STATE.into());
    r.suggested = None;
    r.note = note.map(str::to_string);
}

/// The shortest vector key of one of `roles` whose leaf is a state name (`exact`) or ends like
/// one (`_joint_pos`).
fn named_like_a_state(rows: &[KeyRole], roles: &[Role], exact: bool) -> Option<usize> {
    rows.iter()
        .enumerate()
        .filter(|(_, r)| roles.contains(&r.role) && r.shape.len() == 1)
        .filter(|(_, r)| {
            let l = leaf(&r.key);
            if exact {
                STATE_NAMES.contains(&l)
            } else {
                STATE_NAMES.iter().any(|s| l.ends_with(&format!("_{s}")))
            }
        })
        .min_by_key(|(_, r)| r.key.len())
        .map(|(i, _)| i)
}

/// Steps 1 to 4: the state by its name (or robosuite's clocked `states`), before the other keys
/// are named.
pub fn by_name(rows: &mut [KeyRole], robosuite_clock: bool) {
    if let Some(i) = named_like_a_state(rows, &[Role::Observation], true) {
        make_state(&mut rows[i], None);
    } else if let Some(i) = named_like_a_state(rows, &[Role::Observation], false) {
        make_state(
            &mut rows[i],
            Some("guessed as the robot state from its name"),
        );
    } else if let Some(r) = rows
        .iter_mut()
        .find(|r| robosuite_clock && r.key == "states" && r.shape.len() == 1)
    {
        make_state(
            r,
            Some("robosuite's simulator state without its clock (column 0 is the time chunkc reads as timestamps)"),
        );
        r.columns = Some([1, r.shape[0]]);
    } else if let Some(i) = named_like_a_state(rows, &[Role::Unmapped], true) {
        make_state(
            &mut rows[i],
            Some("GUESSED as the robot state: named like one, though in no observation group"),
        );
    }
}

/// Step 5: with no key the state yet, the only low-dimensional key besides the action becomes
/// `observation.state` (whatever name it had), so that the policy observes something.
pub fn claim_the_only_one(rows: &mut [KeyRole]) {
    if rows.iter().any(|r| r.channel.as_deref() == Some(STATE)) {
        return;
    }
    let low_dim: Vec<usize> = rows
        .iter()
        .enumerate()
        .filter(|(_, r)| matches!(r.role, Role::Observation | Role::Unmapped))
        .map(|(i, _)| i)
        .collect();
    let &[i] = low_dim.as_slice() else {
        return;
    };
    if rows[i].shape.len() != 1 {
        return;
    }
    make_state(
        &mut rows[i],
        Some("GUESSED as the robot state: the only low-dim key besides the action"),
    );
}
